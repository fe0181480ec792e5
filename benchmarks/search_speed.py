"""Candidate evaluations per second of the design search (issue 12's speed target).

Scores one beam step (200 parents x every move) of a 30-min search at 40 s dwells
and reports evaluations per wall second and per CPU second of this process (on a
shared machine the CPU figure is the one that says what the code costs). The
beam ranks walks without the ``--with`` terms, so the figure is the same with and
without ``--with all``.

    python benchmarks/search_speed.py navigation-gm
"""
from __future__ import annotations

import math
import sys
import time

from calib.profiles import load_profile
from seqdesign.design import Constraints, SearchModel


def main() -> None:
    prof = load_profile(sys.argv[1] if len(sys.argv) > 1 else "navigation-gm")
    c = Constraints(budget_s=1800.0, max_flips=30, max_quarters=5, min_dwell_s=10.0)
    t = time.perf_counter()
    model = SearchModel.build(c, 40.0, math.radians(40.0), 0.0, prof)
    build = time.perf_counter() - t
    parents = [model.start_candidate()]
    for _ in range(2):  # two steps to get a realistic beam of 200 distinct parents
        kids = sorted(model.extend(parents, "worst"), key=lambda k: k.score)
        parents = kids[:200]
    wall, cpu = time.perf_counter(), time.process_time()
    kids = model.extend(parents, "worst")
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(f"{prof.name}: {len(kids)} candidates in {wall:.2f} s wall ({len(kids) / wall:.0f}/s), "
          f"{cpu:.2f} s CPU ({len(kids) / cpu:.0f}/s); model built in {build:.1f} s")


if __name__ == "__main__":
    main()
