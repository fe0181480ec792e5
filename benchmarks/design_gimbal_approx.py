"""How far the design search's constant-rate segments move the score of an accelerating design.

    PYTHONPATH=. python benchmarks/design_gimbal_approx.py sequences/designed-30min-cable-wrap.toml

With ``design --gimbal`` every move is a trapezoid (the gimbal's acceleration
limit). The search's segment algebra keeps a constant-rate turn with the
trapezoid's duration (the mean rate). This analyses the written sequence
exactly (trapezoids, as ``seqdesign analyze`` does) and the same sequence
with each move replaced by that constant-rate turn, and prints both worst
ratios (nominal mounting and worst over the +-3 deg box) and the change.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import calib  # noqa: F401  (BLAS threads)
from calib.sequence.definition import Step, load_sequence
from seqdesign.analysis import analyze


def constant_rate_twin(seq):
    """Each move at the constant rate that lasts as long as its real (accelerating) profile."""
    steps = tuple(Step(s.axis, s.angle_deg, abs(s.angle_deg) / s.duration_s, s.dwell_s) for s in seq.steps)
    return replace(seq, steps=steps, name=seq.name + "-constant-rate")


def worst(a) -> tuple[float, float]:
    rob = a.robustness
    return float(rob.nominal.ratio.max()), float(rob.per_parameter_worst_ratio.max())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence")
    ap.add_argument("--profile", default="navigation")
    args = ap.parse_args()
    seq = load_sequence(args.sequence)
    twin = constant_rate_twin(seq)
    assert abs(twin.duration_s - seq.duration_s) < 1e-6  # same timeline, only the profile differs
    (n1, b1), (n2, b2) = (worst(analyze(s, args.profile)) for s in (seq, twin))
    print(f"{seq.name}: {seq.duration_s:.1f} s, profile {args.profile}")
    print(f"  exact (accelerating moves):     nominal {n1:.4f}, worst over the box {b1:.4f}")
    print(f"  search model (constant rate):   nominal {n2:.4f}, worst over the box {b2:.4f}")
    print(f"  change: nominal {100 * (n2 / n1 - 1):+.2f} %, box {100 * (b2 / b1 - 1):+.2f} %")


if __name__ == "__main__":
    main()
