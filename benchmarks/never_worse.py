"""More effort never gives a worse answer (issue 12, point 6), at 10, 15 and 30 min.

Runs ``seqdesign design`` three ways at each budget, as a user would: the default
(beams of 200 and 20, IPOPT refinement), ``--beam-width 20`` and ``--no-refine``,
and prints each one's exact worst ratio (worst over +-3 deg, by the design's own
final check) and the CPU time it took. The default must be no worse than either.

    PYTHONPATH=. python benchmarks/never_worse.py [--budgets 10,15,30] [--profile navigation]
"""

from __future__ import annotations

import argparse
import sys
import time

from seqdesign.search import DesignOptions, design_budgets

VARIANTS = {"default": {}, "--beam-width 20": {"beam_width": 20}, "--no-refine": {"refine": False}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--budgets", default="10,15,30")
    ap.add_argument("--profile", default="navigation")
    ap.add_argument("--with", dest="with_terms", default=None)
    ap.add_argument(
        "--save-dir",
        default=None,
        help="Also write each budget's default design there (with its provenance).",
    )
    args = ap.parse_args()
    print(f"profile {args.profile}, --with {args.with_terms or 'none'}; worst ratio over +-3 deg")
    print(f"{'budget':>6}  {'variant':<16} {'worst':>7}  {'CPU s':>6}  moves")
    for b in (float(x) for x in args.budgets.split(",")):
        worst = {}
        for label, kw in VARIANTS.items():
            cpu = time.process_time()
            rep = design_budgets([b], {}, args.profile, DesignOptions(extras=args.with_terms, **kw))
            cpu = time.process_time() - cpu
            r = rep.rows[0].result
            worst[label] = r.worst_ratio
            if args.save_dir and label == "default":
                from seqdesign.cli.tools import provenance

                cmd = (
                    f"PYTHONPATH=. python benchmarks/never_worse.py {' '.join(sys.argv[1:])} "
                    f"(its default run: the defaults of seqdesign design --budget-min {b:g})"
                )
                rep.save_design(
                    rep.rows[0], f"{args.save_dir}/designed-{b:g}min.toml", provenance() | {"command": cmd}
                )
            print(
                f"{b:5g}m  {label:<16} {r.worst_ratio:7.4f}  {cpu:6.0f}  "
                f"{len(r.sequence.steps)} ({r.worst_name})",
                flush=True,
            )
        ok = all(worst["default"] <= v + 1e-12 for v in worst.values())
        print(f"{b:5g}m  default never worse: {'yes' if ok else 'NO'}", flush=True)


if __name__ == "__main__":
    main()
