"""Candidate evaluations per second of the design search (issue 12's speed target).

Scores one beam step (200 parents x every move) of a 30-min search at 40 s dwells
and reports evaluations per wall second and per CPU second of this process (on a
shared machine the CPU figure is the one that says what the code costs). The
beam ranks walks without the ``--with`` terms (their moments are not in the segment
algebra; the exact re-scoring fits them), so ``--with all`` runs the very same
candidate evaluations: the script accepts it to say so.

    PYTHONPATH=. python benchmarks/search_speed.py navigation-gm [--with all]
"""

from __future__ import annotations

import math
import sys
import time

from calib.nav.site import Site
from calib.noise.profiles import load_profile
from seqdesign.search import Constraints, SearchModel


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    prof = load_profile(args[0] if args else "navigation-gm")
    terms = "all" if "--with" in sys.argv else "none"
    c = Constraints(budget_s=1800.0, max_flips=30, max_quarters=5, min_dwell_s=10.0)
    t = time.perf_counter()
    model = SearchModel.build(c, 40.0, Site.at(math.radians(40.0)), prof)
    build = time.perf_counter() - t
    parents = [model.start_candidate()]
    for _ in range(2):  # two steps to get a realistic beam of 200 distinct parents
        kids = sorted(model.extend(parents, "worst"), key=lambda k: k.score)
        parents = kids[:200]
    wall, cpu = time.perf_counter(), time.process_time()
    kids = model.extend(parents, "worst")
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(
        f"{prof.name} (--with {terms}; the beam ranks without the terms): "
        f"{len(kids)} candidates in {wall:.2f} s wall ({len(kids) / wall:.0f}/s), "
        f"{cpu:.2f} s CPU ({len(kids) / cpu:.0f}/s); model built in {build:.1f} s"
    )


if __name__ == "__main__":
    main()
