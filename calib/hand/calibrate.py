"""Calibrate a run placed by hand: the fit of :mod:`calib.hand.joint_fit` as a calibration result.

Around the fit: the setup checked (:mod:`calib.hand.setup`), the rest finder's
thresholds loosened for poses held in the hand, the gyro g-sensitivity chosen by
the data (or forced), and a wrong rate told by the scale factors. The result
carries the 21 (and the g-sensitivity when fitted) with their sigmas,
Birge-checked like a gimbal run's, the first rest's attitude, and a
:class:`calib.hand.summary.HandSummary` of the rests and moves used, the model
chosen and the weights earned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial as partial_fit

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from calib.errors import CalibError
from calib.fit.solution import Fit
from calib.model import params as P
from calib.model.optional_terms import OptionalTerms
from calib.nav.site import Site
from calib.nav.strapdown import sample_intervals
from calib.noise.profiles import NoiseProfile, white_part
from calib.runlog import Run
from calib.runlog.clipping import describe_clipping

from .fit_options import HandFitOptions, HandSamples
from .joint_fit import N_GS, HandFit, fit_by_hand
from .setup import check_setup, fixed, rate_mistake
from .summary import HandSummary
from .weights import Weights

G_SENSITIVITY = "g-sensitivity"  # the optional term a hand-placed run can fit
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
    term's count).
    """

    term: str
    chosen: bool
    how: str
    statistic: float = float("nan")
    dof: tuple = (0,)
    p: float = float("nan")

    def line(self) -> str:
        verdict = "fitted" if self.chosen else "not fitted"
        if self.how != "tested":
            flag = "--with" if self.chosen else "--without"
            return f"model: {self.term} {verdict} ({self.how} by {flag})"
        return (
            f"model: {self.term} {verdict}: likelihood ratio {self.statistic:.3g} for {self.dof[0]} terms, "
            f"p = {self.p:.2g} ({'below' if self.chosen else 'not below'} {CHOICE_ALPHA:g}; "
            f"--with/--without {self.term} forces it)"
        )

    def to_json(self) -> dict:
        doc = {"term": self.term, "fitted": self.chosen, "how": self.how}
        if self.how == "tested":
            doc |= {
                "likelihood_ratio": self.statistic,
                "dof": self.dof[0],
                "p": self.p,
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
) -> tuple[HandFit, OptionalTerms, TermChoice]:
    """The fit of a run placed by hand, read as it is, with the g-sensitivity chosen by the data.

    Unless ``extras`` forces it in or ``without`` out, the gyro g-sensitivity is
    fitted when an F test at the weights of the fit without it says the data
    need it (`CHOICE_ALPHA`). Returns the fit, the optional terms it carries and
    the choice.
    """
    unsupported = [g for g in (*extras.groups, *without) if g != G_SENSITIVITY]
    if unsupported:
        raise CalibError(
            f"--with/--without {','.join(unsupported)} is not fitted on a run placed by hand",
            run.source,
            "leave them out (g-sensitivity is the term a hand-placed run can fit)",
        )
    forced = G_SENSITIVITY in extras.groups or G_SENSITIVITY in without
    chosen = G_SENSITIVITY in extras.groups
    samples = HandSamples.of_run(run)
    base = HandFitOptions(requirements=req)

    def fit_at(loosen: float, weights: Weights | None = None, **changes) -> HandFit:
        options = replace(base, loosen=loosen, **changes)
        return fit_by_hand(samples, site, profile, options, weights=weights, where=run.source)

    loosen, found = base.loosen, None
    if earn_weights:  # poses held in the hand: the rest finder's thresholds chosen by the fit
        loosen, found = _loosening(fit_at, chosen)
    fit = partial_fit(fit_at, loosen)
    # The loosening's fit at its factor is this model's fit (the same inputs): not made again,
    # unless a refusal of what it leaves unestimated is owed.
    first = found if found is not None and (partial or found.estimable.all()) else None
    if forced:
        how = "forced in" if chosen else "forced out"
        hand = first or fit(g_sensitivity=chosen, partial=partial, earn_weights=earn_weights)
        return hand, extras, TermChoice(G_SENSITIVITY, chosen, how)
    plain = first or fit(g_sensitivity=False, partial=partial, earn_weights=earn_weights)
    # Each model with the weights its own residuals earn: a term the data need shrinks the noise
    # the other model must call a floor, and the likelihood says so (a test at the plain fit's
    # weights would let that floor hide the term).
    test = fit(g_sensitivity=True, partial=True, earn_weights=earn_weights, weights=plain.weights)
    ratio = max(2.0 * (test.log_likelihood - plain.log_likelihood), 0.0)
    p = float(chi2_distribution.sf(ratio, N_GS))
    choice = TermChoice(G_SENSITIVITY, p < CHOICE_ALPHA, "tested", ratio, (N_GS,), p)
    if not choice.chosen:
        return plain, extras, choice
    if not partial and not test.estimable.all():
        test = fit(g_sensitivity=True, partial=False, earn_weights=earn_weights, weights=plain.weights)
    return test, OptionalTerms((*extras.groups, G_SENSITIVITY)), choice


def _loosening(fit, g_sensitivity: bool) -> tuple[float, HandFit | None]:
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
            hand = fit(loosen, g_sensitivity=g_sensitivity, partial=True, earn_weights=True)
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
) -> tuple[HandFit, OptionalTerms, TermChoice, Run, list]:
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
    hand, used, choice = hand_fit_of(run, site, profile, extras, partial, req, without)
    sigma = np.sqrt(np.diag(hand.covariance))[P.GYRO_SCALE] * math.sqrt(max(hand.chi2_per_dof, 1.0))
    period = float(np.median(sample_intervals(run.time_s)))
    mistake = rate_mistake(hand.values[P.GYRO_SCALE], sigma, period)
    if mistake is not None:
        if not fix_units:
            raise CalibError(
                mistake.what,
                run.source,
                "give the IMU's own rate (--sample-rate-hz), or --fix-units to calibrate at the rate the "
                "data say (a gyro whose three scale factors are truly this alike cannot be told from it)",
            )
        run = fixed(run, [mistake])
        notes.append(f"fixed: {mistake.what}")
        hand, used, choice = hand_fit_of(run, site, profile, extras, partial, req, without)
    return hand, used, choice, run, notes


def as_fit(hand: HandFit, extras: OptionalTerms) -> Fit:
    """The estimator's :class:`calib.fit.solution.Fit` of a hand fit (what the result is built from)."""
    lay = hand.layout
    n_keep = lay.gs.stop
    cov = np.zeros((P.N_PARAMS + 3 + extras.n,) * 2)
    keep = np.r_[0 : P.N_PARAMS, lay.gs]
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
        extra_values=hand.g_sensitivity.reshape(9) if hand.g_sensitivity is not None else np.zeros(0),
        estimable=estimable,
        null_directions=hand.null_directions,
    )


def summary_of(hand: HandFit, run: Run, choice: TermChoice | None = None, notes: tuple = ()) -> HandSummary:
    """Rests and moves in seconds from the log's start, the weights earned and the model chosen."""
    t0 = float(run.time_s[0] - sample_intervals(run.time_s)[0])
    t = np.concatenate([[t0], run.time_s]) - t0  # sample i spans t[i] .. t[i + 1]
    rests = hand.data.rests
    rest_s = np.column_stack([t[rests.start], t[rests.end]])
    move_s = np.column_stack([t[rests.end[:-1]], t[rests.start[1:]]])
    return HandSummary(
        rest_s=rest_s,
        move_s=move_s,
        move_used=hand.data.move_used,
        rest_chi2=hand.rest_chi2,
        move_chi2=hand.move_chi2,
        clipped=tuple(describe_clipping(run)),
        chi2_per_dof=hand.chi2_per_dof,
        notes=(
            *notes,
            *(() if choice is None else (choice.line(),)),
            *hand.weights.lines(hand.weight_sizes),
            *hand.loose_rests,
        ),
        choices={"weights": hand.weights.to_json(hand.weight_sizes), "loose_rests": list(hand.loose_rests)}
        | ({} if choice is None else {"model": [choice.to_json()]}),
    )
