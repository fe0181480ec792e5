"""Where the information saturates as dwells shrink under Gauss-Markov bias (issue 12).

A fixed budget is filled with turns of 450 deg cycling Z, Y, X (the class the GM
search found: ``designed-30min-gm``) and a uniform dwell between them; as the dwell
shrinks, more turns fit and gravity reverses on each axis more often. Each
sequence is analysed at the nominal mounting under the white ``navigation``
profile and under ``navigation-gm``; the accelerometer scale factors' worst ratio
is set against the white-noise bound of the conventions and the coloured-noise
bound at the gimbal's rate (``accel_scale_bound(..., rate_dps)``, docs/design.md).

    python benchmarks/gm_bound.py --budgets 15,30 --rates 10,20
"""

from __future__ import annotations

import argparse
import math
import time

from calib.analysis.bounds import accel_scale_bound
from calib.analysis.mounting import analyze
from calib.model import params as P
from calib.nav import earth
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.sequence.definition import Sequence, Step

LAT = math.radians(40.0)
# designed-30min-gm's first six turns: +Z +Y -X -Z -Y +X (each axis both ways)
MOTIF = (("Z", 450.0), ("Y", 450.0), ("X", -450.0), ("Z", -450.0), ("Y", -450.0), ("X", 450.0))
FIRST_DWELL_S = 10.0  # the estimator aligns on the first rest: keep it usable


def cycling_sequence(budget_s: float, dwell_s: float, rate_dps: float) -> Sequence:
    """As many motif turns as fit the budget with ``dwell_s`` after each."""
    turn_s = 450.0 / rate_dps
    n = int((budget_s - max(dwell_s, FIRST_DWELL_S)) // (turn_s + dwell_s))
    steps = tuple(Step(*MOTIF[k % len(MOTIF)], rate_dps=rate_dps, dwell_s=dwell_s) for k in range(n))
    return Sequence(
        name=f"cycle-{dwell_s:g}s",
        start=("east", "up", "south"),
        steps=steps,
        initial_dwell_s=max(dwell_s, FIRST_DWELL_S),
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--budgets", default="15,30", help="minutes")
    ap.add_argument("--rates", default="10", help="deg/s")
    ap.add_argument("--dwells", default="120,60,40,30,20,15,10,6,3", help="s")
    args = ap.parse_args()
    white, gm = load_profile("navigation"), load_profile("navigation-gm")
    g = earth.gravity(LAT)
    print(
        "budget rate  dwell moves  T_min | white: worst  sa   bound | GM: worst  sa  "
        "rate_bound  sa/rate_bound"
    )
    t0 = time.process_time()
    for budget in (float(b) for b in args.budgets.split(",")):
        for rate in (float(r) for r in args.rates.split(",")):
            for dwell in (float(d) for d in args.dwells.split(",")):
                seq = cycling_sequence(budget * 60.0, dwell, rate)
                T = seq.duration_s
                ow, og = analyze(seq, white, Site.at(LAT)), analyze(seq, gm, Site.at(LAT))
                sa_w = max(ow.ratio[P.ACCEL_SCALE])
                sa_g = max(og.ratio[P.ACCEL_SCALE])
                b_w = accel_scale_bound(T, white, g)
                b_g = accel_scale_bound(T, gm, g, rate_dps=rate)
                print(
                    f"{budget:5g}m {rate:4g} {dwell:6g} {len(seq.steps):5d} {T / 60:6.1f} | "
                    f"{ow.worst[1]:6.3f} {sa_w:6.3f} {b_w:6.3f} | {og.worst[1]:6.3f} "
                    f"{sa_g:6.3f} {b_g:6.3f} {sa_g / b_g:8.3f}",
                    flush=True,
                )
    print(f"CPU {time.process_time() - t0:.0f} s")


if __name__ == "__main__":
    main()
