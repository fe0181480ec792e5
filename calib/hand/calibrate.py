"""Calibrate a run placed by hand: the fit of :mod:`calib.hand.joint_fit` as a calibration result.

Around the fit: the setup checked (:mod:`calib.hand.setup`), the rest finder's
thresholds loosened for poses held in the hand, the gyro g-sensitivity and the
accelerometers' and gyros' bias drifts chosen by the data (or forced), and a wrong rate told by
the scale factors. The result carries the 21 (and the optional terms fitted) with their sigmas,
Birge-checked like a gimbal run's, the first rest's attitude, and a
:class:`calib.hand.summary.HandSummary` of the rests and moves used, the model
chosen and the weights earned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial as partial_fit
from typing import Any

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from calib.errors import CalibError
from calib.fit.solution import Fit
from calib.model import params as P
from calib.model.optional_terms import (
    ACCEL_BIAS_DRIFT,
    BIAS_DRIFT_SI_PER_UNIT,
    GROUPS,
    GYRO_BIAS_DRIFT,
    GYRO_DRIFT_SI_PER_UNIT,
    OptionalTerms,
)
from calib.nav.site import Site
from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import NoiseProfile, white_part
from calib.runlog import Run
from calib.runlog.clipping import describe_clipping

from .fit_options import HandFitOptions, HandSamples
from .joint_fit import N_DRIFT, N_GS, HandFit, fit_by_hand
from .rests import brief_pose_lines
from .rounding import rounding_lines
from .setup import check_setup, fixed, rate_mistake
from .summary import HandSummary
from .weights import Weights

G_SENSITIVITY = "g-sensitivity"
# The optional terms a hand-placed run can fit, in the order they are tested: the fit's option
# that switches each on, and its count of unknowns.
TERMS = {
    G_SENSITIVITY: ("g_sensitivity", N_GS),
    ACCEL_BIAS_DRIFT: ("bias_drift", N_DRIFT),
    GYRO_BIAS_DRIFT: ("gyro_drift", N_DRIFT),
}
# A term is chosen when its likelihood ratio passes this false-alarm rate: one recording in a
# thousand without the effect gets it (and loses nothing but a little precision).
CHOICE_ALPHA = 1e-3
LOOSENINGS = (1.0, 2.0, 4.0, 8.0)  # the rest finder's thresholds, times the profile's noise
MORE_REST = 1.5  # a looser factor is taken on while it finds this much more rest time


@dataclass(frozen=True)
class TermChoice:
    """Whether an optional term was fitted, and why.

    ``how`` is ``"forced in"`` (``--with``), ``"forced out"`` (``--without``) or ``"tested"``:
    then ``statistic`` is twice the log-likelihood the term gains, each model at the weights its
    own residuals earn, and ``p`` its chance under no such effect (a chi2 on ``dof``, the
    term's count); ``wald`` the term's own size against its covariance and ``p_wald`` its
    chance. Both must pass `CHOICE_ALPHA`.
    """

    term: str
    chosen: bool
    how: str
    statistic: float = float("nan")
    dof: tuple = (0,)
    p: float = float("nan")
    wald: float = float("nan")
    p_wald: float = float("nan")

    def line(self) -> str:
        verdict = "fitted" if self.chosen else "not fitted"
        if self.how != "tested":
            flag = "--with" if self.chosen else "--without"
            return f"model: {self.term} {verdict} ({self.how} by {flag})"
        both = self.p < CHOICE_ALPHA and self.p_wald < CHOICE_ALPHA
        return (
            f"model: {self.term} {verdict}: likelihood ratio {self.statistic:.3g} for {self.dof[0]} terms, "
            f"p = {self.p:.2g}; its own size {self.wald:.3g}, p = {self.p_wald:.2g} "
            f"({'both' if both else 'not both'} below {CHOICE_ALPHA:g}; "
            f"--with/--without {self.term} forces it)"
        )

    def to_json(self) -> dict:
        doc = {"term": self.term, "fitted": self.chosen, "how": self.how}
        if self.how == "tested":
            doc |= {
                "likelihood_ratio": self.statistic,
                "dof": self.dof[0],
                "p": self.p,
                "wald": self.wald,
                "p_wald": self.p_wald,
                "alpha": CHOICE_ALPHA,
            }
        return doc


def hand_fit_of(
    run: Run,
    site: Site,
    profile: NoiseProfile,
    extras: OptionalTerms,
    partial: bool,
    req,
    without: tuple = (),
    earn_weights: bool = True,
) -> tuple[HandFit, OptionalTerms, tuple[TermChoice, ...]]:
    """The fit of a run placed by hand, read as it is, with its optional terms chosen by the data.

    Unless ``extras`` forces a term in or ``without`` out, each of `TERMS` in turn (the gyro
    g-sensitivity, then the accelerometers' bias drift, then the gyros') is fitted when the
    likelihood ratio of the fit with it against the fit without, each at the weights its own
    residuals earn, and the term's own Wald size both pass `CHOICE_ALPHA`. Returns the fit, the optional terms
    it carries and the choices.
    """
    unsupported = [g for g in (*extras.groups, *without) if g not in TERMS]
    if unsupported:
        raise CalibError(
            f"--with/--without {','.join(unsupported)} is not fitted on a run placed by hand",
            run.source,
            f"leave them out ({' and '.join(TERMS)} are the terms a hand-placed run can fit)",
        )
    samples = HandSamples.of_run(run)
    base = HandFitOptions(requirements=req)

    def fit_at(loosen: float, weights: Weights | None = None, **changes) -> HandFit:
        options = replace(base, loosen=loosen, **changes)
        return fit_by_hand(samples, site, profile, options, weights=weights, where=run.source)

    flags: dict[str, Any] = {TERMS[g][0]: True for g in extras.groups}
    loosen, found = base.loosen, None
    if earn_weights:  # poses held in the hand: the rest finder's thresholds chosen by the fit
        loosen, found = _loosening(fit_at, flags)
    fit = partial_fit(fit_at, loosen)
    # The loosening's fit at its factor is this model's fit (the same inputs): not made again,
    # unless a refusal of what it leaves unestimated is owed.
    first = found if found is not None and (partial or found.estimable.all()) else None
    current = first or fit(partial=partial, earn_weights=earn_weights, **flags)
    choices = [
        TermChoice(g, g in extras.groups, "forced in" if g in extras.groups else "forced out")
        for g in TERMS
        if g in extras.groups or g in without
    ]
    chosen = set(extras.groups)
    for term, (flag, dof) in TERMS.items():
        if term in extras.groups or term in without:
            continue
        # Each model with the weights its own residuals earn: a term the data need shrinks the
        # noise the other model must call a floor, and the likelihood says so (a test at the
        # plain fit's weights would let that floor hide the term).
        trial = flags | {flag: True}
        test = fit(partial=True, earn_weights=earn_weights, weights=current.weights, **trial)
        ratio = max(2.0 * (test.log_likelihood - current.log_likelihood), 0.0)
        p = float(chi2_distribution.sf(ratio, dof))
        wald = _wald(test, term)
        p_wald = float(chi2_distribution.sf(wald, dof))
        fitted = p < CHOICE_ALPHA and p_wald < CHOICE_ALPHA
        choices.append(TermChoice(term, fitted, "tested", ratio, (dof,), p, wald, p_wald))
        if fitted:
            if not partial and not test.estimable.all():
                test = fit(partial=False, earn_weights=earn_weights, weights=current.weights, **trial)
            flags, current = trial, test
            chosen.add(term)
    return current, OptionalTerms(tuple(g for g in GROUPS if g in chosen)), tuple(choices)


def _wald(fit: HandFit, term: str) -> float:
    """The term's own size against its covariance, ``x^T C^-1 x`` (chi2 on its count under none).

    The likelihood ratio compares the two models each at the weights its residuals earn: a term
    the run cannot pin down may still change those weights, and the ratio with them (on the
    Ferraris session's first two thirds the drift gained 48 while no component of it was
    beyond 1.6 sigma). So the term must also stand on its own.
    """
    lay = fit.layout
    cols, x = {
        G_SENSITIVITY: (lay.gs, fit.g_sensitivity),
        ACCEL_BIAS_DRIFT: (lay.drift, fit.bias_drift),
        GYRO_BIAS_DRIFT: (lay.gdrift, fit.gyro_drift),
    }[term]
    if x is None or x.size == 0:
        return 0.0
    x = x.reshape(-1)
    C = fit.covariance[cols, cols]
    return float(x @ np.linalg.pinv(C) @ x)


def _loosening(fit, flags: dict) -> tuple[float, HandFit | None]:
    """The factor on the rest finder's thresholds (the profile's, loosened only as far as needed),
    and the fit made at it (None where no factor serves).

    A pose held in the hand trembles beyond the profile's noise: thresholds from the
    profile then find too few rests, or parts of them, and the fit refuses the run as not
    separating every parameter. Looser thresholds find them, but also let in the starts and
    ends of moves: on the real recordings whose poses lie on a table (Xsens, Ferraris,
    MPU-9150) looser thresholds lowered the fit's own sigmas yet carried the gravity
    direction worse from pose to pose out of sample (benchmarks/by_hand_cv.py). So the
    profile's thresholds stand wherever their rests separate the 21; else the least factor
    whose rests do, and a looser one still while it finds `MORE_REST` times the rest time
    (trembling poses found whole, not a few still moments of them).
    """
    chosen: tuple[float, HandFit] | None = None
    rest_time = 0.0
    for loosen in LOOSENINGS:
        try:
            hand = fit(loosen, partial=True, earn_weights=True, **flags)
        except CalibError:  # too few rests at these thresholds
            continue
        if not hand.estimable[: P.N_PARAMS].all():
            continue
        if loosen == 1.0:
            return 1.0, hand  # the profile's thresholds serve: they stand
        total = float(hand.data.rest_time_s.sum())
        if chosen is not None and total < MORE_REST * rest_time:
            break
        chosen, rest_time = (loosen, hand), total
    return (1.0, None) if chosen is None else chosen


def fit_checked(
    run: Run,
    site: Site,
    profile: NoiseProfile,
    terms: tuple,
    partial: bool,
    req,
    fix_units: bool = False,
) -> tuple[HandFit, OptionalTerms, tuple[TermChoice, ...], Run, list]:
    """The setup checked (:mod:`calib.hand.setup`), the fit with its model chosen, the rate checked.

    ``terms`` is the optional terms forced in (OptionalTerms) and out (names). Returns the fit, its
    terms, the choice, the run as fitted (put right under ``fix_units``) and what was put right.
    """
    extras, without = terms
    run, notes = check_setup(run, site.gravity_mps2, fix_units)
    if profile.has_gauss_markov:
        notes.append(
            f"profile {profile.name}: its white part weights the fit (a hand fit does not model a "
            "Gauss-Markov bias; one that wanders between rests shows as the rests' floor below)"
        )
        profile = white_part(profile)
    hand, used, choices = hand_fit_of(run, site, profile, extras, partial, req, without)
    sigma = np.sqrt(np.diag(hand.covariance))[P.GYRO_SCALE] * math.sqrt(max(hand.chi2_per_dof, 1.0))
    period = float(np.median(sample_intervals(run.time_s)))
    at_stamps = run.clock is not None and run.clock.rule == "stamps"
    counts = run.conversion is not None
    mistake = rate_mistake(hand.values[P.GYRO_SCALE], sigma, period, at_stamps, counts)
    if mistake is not None:
        if not fix_units:
            put_right = "correct the gyro's conversion or unit" if at_stamps else "give the IMU's own rate"
            raise CalibError(
                mistake.what,
                run.source,
                f"{put_right}, or --fix-units to calibrate it as the data say (three scale factors truly "
                "this alike cannot be told from it)",
            )
        run = fixed(run, [mistake])
        notes.append(f"fixed: {mistake.what}")
        hand, used, choices = hand_fit_of(run, site, profile, extras, partial, req, without)
    return hand, used, choices, run, notes


def as_fit(hand: HandFit, extras: OptionalTerms) -> Fit:
    """The estimator's :class:`calib.fit.solution.Fit` of a hand fit (what the result is built from)."""
    lay = hand.layout
    n_keep = lay.gdrift.stop
    cov = np.zeros((P.N_PARAMS + 3 + extras.n,) * 2)
    keep = np.r_[0 : P.N_PARAMS, lay.gs, lay.drift, lay.gdrift]
    out = np.r_[0 : P.N_PARAMS, P.N_PARAMS + 3 : P.N_PARAMS + 3 + extras.n]
    cov[np.ix_(out, out)] = hand.covariance[np.ix_(keep, keep)]
    tilt = lay.columns(0)[0]
    cov[P.N_PARAMS : P.N_PARAMS + 2, P.N_PARAMS : P.N_PARAMS + 2] = hand.covariance[np.ix_(tilt, tilt)]
    cov[P.N_PARAMS + 2, P.N_PARAMS + 2] = np.pi**2  # the heading of the first rest: the frame's, not fitted
    estimable = np.ones(P.N_PARAMS + extras.n, dtype=bool)
    estimable[:n_keep] = hand.estimable
    return Fit(
        values=hand.values,
        C_b_n0=hand.C_rest[0],
        covariance=cov,
        converged=hand.converged,
        iterations=hand.iterations,
        residual_rms_mps=hand.residual_rms_mps2,
        chi2_per_dof=hand.chi2_per_dof,
        n_observations=hand.n_observations,
        history=hand.history,
        extras=extras,
        extra_values=np.concatenate(
            [
                hand.g_sensitivity.reshape(9) if hand.g_sensitivity is not None else np.zeros(0),
                hand.bias_drift if hand.bias_drift is not None else np.zeros(0),
                hand.gyro_drift if hand.gyro_drift is not None else np.zeros(0),
            ]
        ),
        estimable=estimable,
        null_directions=hand.null_directions,
    )


def _lost_in_moves(hand: HandFit, run: Run) -> dict:
    """Samples lost and guessed in each move, by move index (those moves are left out)."""
    if run.guessed is None:
        return {}
    counts = {k: int(run.guessed[s].sum()) for k, s in enumerate(hand.data.move_slices)}
    return {k: c for k, c in counts.items() if c}


def summary_of(hand: HandFit, run: Run, choices: tuple = (), notes: tuple = ()) -> HandSummary:
    """Rests and moves in seconds from the log's start, the weights earned and the model chosen."""
    t0 = float(run.time_s[0] - sample_intervals(run.time_s)[0])
    t = np.concatenate([[t0], run.time_s]) - t0  # sample i spans t[i] .. t[i + 1]
    rests = hand.data.rests
    rest_s = np.column_stack([t[rests.start], t[rests.end]])
    move_s = np.column_stack([t[rests.end[:-1]], t[rests.start[1:]]])
    rounded = rounding_lines(hand.data.reading_steps, hand.data.rest_rate_rounding)
    brief = brief_pose_lines(rests, t[:-1])
    brief_s = np.column_stack([t[rests.brief_start], t[rests.brief_end]]).tolist()
    drift = []
    for sensor, rate, unit, per_unit in (
        ("accelerometer", hand.bias_drift, "ug/min", BIAS_DRIFT_SI_PER_UNIT),
        ("gyro", hand.gyro_drift, "deg/h/min", GYRO_DRIFT_SI_PER_UNIT),
    ):
        if rate is not None:  # the biases are then a time's: said, with the drift
            per_min = ", ".join(f"{d / per_unit:+.3g}" for d in rate)
            drift.append(
                f"{sensor} biases: the last rest's, at {float(np.mean(rest_s[-1])):.1f} s; they drift by "
                f"({per_min}) {unit} over the run (a correction applies the last rest's; "
                "correct --carry-drift carries the drift over this log)"
            )
    return HandSummary(
        rest_s=rest_s,
        move_s=move_s,
        move_used=hand.data.move_used,
        rest_chi2=hand.rest_chi2,
        move_chi2=hand.move_chi2,
        clipped=tuple(describe_clipping(run)),
        lost=_lost_in_moves(hand, run),
        chi2_per_dof=hand.chi2_per_dof,
        notes=(
            *notes,
            *rounded,
            *(c.line() for c in choices),
            *drift,
            *hand.weights.lines(hand.weight_sizes),
            *hand.loose_rests,
            *brief,
        ),
        choices={"weights": hand.weights.to_json(hand.weight_sizes), "loose_rests": list(hand.loose_rests)}
        | ({"model": [c.to_json() for c in choices]} if choices else {})
        | ({"rounding": rounded} if rounded else {})
        | ({"brief_poses_s": brief_s} if brief else {}),
    )
