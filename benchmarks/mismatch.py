"""Mismatch report (issue 8): what ignoring a real unit's extra terms costs, and what fitting them buys.

    python benchmarks/mismatch.py [--n 30] [--sequence designed-30min-9moves] [--workers 2]

Simulates runs with each extra term on (lever arms, accelerometer K2, a
gyro-accelerometer time offset, Gauss-Markov bias instability, then all of
them), and calibrates every run twice: with the 21-parameter model and the
white-noise profile ("off"), and with the terms fitted (``--with``) and the
bias instability in the profile ("on"). Prints, per case, the largest bias of
the 21 in units of the reported sigma, the largest bias in units of the
requirement, and the mean NEES of the 21 (21 expected when the sigmas are
honest); then the per-parameter biases of the all-terms case.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import calib  # noqa: F401  (BLAS threads)
from calib.model import params as P
from calib.model.optional_terms import GROUP_NAMES, OptionalTerms, OptionalTermValues
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from seqdesign.montecarlo import TrialConfig, run_trials

LEVER = {
    "rxx": 3.0,
    "rxy": -2.0,
    "rxz": 1.5,
    "ryx": 1.0,
    "ryy": -4.0,
    "ryz": 2.0,
    "rzx": -1.0,
    "rzy": 2.5,
    "rzz": 3.5,
}  # cm: a few cm, as in a real cluster
K2 = {"k2x": 20.0, "k2y": 20.0, "k2z": 20.0}  # ug/g^2: quartz accelerometers
OFFSET = {"dt_ga": 0.5}  # ms
GM_PROFILE = "navigation-gm"

# label: (simulated extra values, groups fitted "on", bias instability on)
CASES = {
    "none": ({}, (), False),
    "lever arms (1-4 cm)": (LEVER, ("lever-arm",), False),
    "K2 20 ug/g^2": (K2, ("k2",), False),
    "time offset 0.5 ms": (OFFSET, ("time-offset",), False),
    "bias instability (GM)": ({}, (), True),
    "all of them": ({**LEVER, **K2, **OFFSET}, GROUP_NAMES, True),
}


def summary(trials):
    sig = np.sqrt(np.einsum("nii->ni", trials.covariances))
    bias_sigma = np.mean(trials.errors / sig, axis=0)
    bias_req = np.mean(trials.errors, axis=0) / P.REQUIREMENTS_SI
    return bias_sigma, bias_req, float(trials.nees.mean()), int(trials.converged.sum())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--sequence", default="designed-30min-9moves")  # docs/mismatch.md
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    seq = load_sequence(args.sequence)
    white, gm = load_profile("navigation"), load_profile(GM_PROFILE)
    rows = {}
    t0 = time.perf_counter()
    for label, (values, groups, with_gm) in CASES.items():
        extra = OptionalTermValues.from_units(values) if values else None
        sim_profile = gm if with_gm else white
        off = run_trials(
            seq, sim_profile, args.n, 2000, TrialConfig(extra=extra, fit_profile=white), args.workers
        )
        fitted_config = TrialConfig(extra=extra, extras=OptionalTerms(groups), fit_profile=sim_profile)
        on = run_trials(seq, sim_profile, args.n, 2000, fitted_config, args.workers)
        rows[label] = (summary(off), summary(on), groups, with_gm)
    elapsed = time.perf_counter() - t0
    print(
        f"{args.sequence}, Table 2 errors, random mounting within +-3 deg, flip errors within "
        f"+-0.5 deg, N = {args.n} runs per case (the same runs off and on); "
        f"{elapsed / 60:.1f} min with {args.workers} workers"
    )
    print()
    print(
        "off: the 21-parameter model, white-noise profile `navigation`. on: the terms fitted "
        f"(`calibrate --with ...`) and, for bias instability, profile `{GM_PROFILE}`."
    )
    print()
    print(
        "| simulated | fitted on | off: max abs bias/sigma | off: max abs bias/req | off: mean NEES "
        "| on: max abs bias/sigma | on: max abs bias/req | on: mean NEES |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for label, (off, on, groups, with_gm) in rows.items():
        fitted = ", ".join(list(groups) + ([f"profile {GM_PROFILE}"] if with_gm else [])) or "-"
        cells = []
        for bs, br, nees, conv in (off, on):
            i, j = int(np.argmax(np.abs(bs))), int(np.argmax(np.abs(br)))
            cells += [
                f"{bs[i]:+.1f} ({P.NAMES[i]})",
                f"{br[j]:+.2f} ({P.NAMES[j]})",
                f"**{nees:.1f}**" + ("" if conv == args.n else f" ({conv} converged)"),
            ]
        print(f"| {label} | {fitted} | " + " | ".join(cells) + " |")
    print()
    off, on, _, _ = rows["all of them"]
    print("All terms simulated, per parameter: mean error / reported sigma, off and on.")
    print()
    print("| param | off | on |")
    print("|---|---|---|")
    for p in P.PARAMETERS:
        print(f"| {p.name} | {off[0][p.index]:+.2f} | {on[0][p.index]:+.2f} |")


if __name__ == "__main__":
    main()
