"""The hand fit's inputs as values: the samples it reads and the options it is fitted with.

:class:`HandFitOptions` travels from :func:`calib.hand.calibrate.hand_fit_of` (and
:mod:`seqdesign.hand.prediction`) down to :func:`calib.hand.joint_fit.fit_by_hand`; its
defaults are written here once. :class:`HandSamples` is a run's increments as the fit
reads them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.model.requirements import PAPER, Requirements
from calib.nav.strapdown import sample_intervals


@dataclass(frozen=True)
class HandFitOptions:
    """How :func:`calib.hand.joint_fit.fit_by_hand` fits a run placed by hand.

    Parameters
    ----------
    g_sensitivity : bool
        Also fit the gyros' rate per specific force (9 terms, ``w_meas = A_g w + b_g + G f``).
    requirements : Requirements
        Scales the observability rule.
    partial : bool
        Fit the estimable parameters of a run that leaves some unobserved instead of refusing it.
    heading_prior : bool
        Weight the horizontal Earth rate by the prior of an unknown heading (off: only the
        gyros tell it, as for a noise-free run whose exact recovery a test checks).
    earn_weights : bool
        Give each group of observations the noise its residuals show, and an outlying block
        its own (:mod:`calib.hand.weights`); off: the profile's weights (or the ones the fit
        is given) as they are.
    loosen : float
        Multiplies the rest finder's thresholds (poses held in the hand).
    use_moves : bool
        Chain the rests through the moves (off: the rests alone, each its own attitude; the
        view that judges a rest's specific force by the other rests', :mod:`calib.hand.weights`).
    bias_drift : bool
        Also fit the accelerometers' bias drift (3 terms, linear in time over the run).
    gyro_drift : bool
        Also fit the gyros' bias drift (3 terms, linear in time over the run).
    """

    g_sensitivity: bool = False
    requirements: Requirements = PAPER
    partial: bool = False
    heading_prior: bool = True
    earn_weights: bool = True
    loosen: float = 1.0
    use_moves: bool = True
    bias_drift: bool = False
    gyro_drift: bool = False


HAND_FIT = HandFitOptions()  # the defaults
# The requirements a unit placed by hand is judged by unless told (calibrate, analyze, verify,
# design --by-hand): a hand-turned unit is a MEMS one, and judged by the paper's navigation-grade
# requirements every sigma would be "weak" and nothing estimable.
HAND_REQUIREMENTS = "mems"


@dataclass(frozen=True)
class HandSamples:
    """A run's increments as the hand fit reads them (SI).

    Parameters
    ----------
    dtheta, dv : ndarray, shape (n, 3)
        The gyros' (rad) and the accelerometers' (m/s) increment over each sample.
    dt : ndarray, shape (n,)
        Each sample's interval, s.
    clipped : ndarray of bool, shape (n,), optional
        Samples at the sensor's range, or lost and guessed: a move holding one is not used.
    """

    dtheta: np.ndarray
    dv: np.ndarray
    dt: np.ndarray
    clipped: np.ndarray | None = None

    @classmethod
    def of_run(cls, run) -> HandSamples:
        """The samples of a :class:`calib.runlog.Run` (a sample clipped on any axis is clipped, as
        is one lost amid a turn and put in as a guess: its move is no measurement).
        """
        clipped = None if run.clipped is None else run.clipped.any(axis=1)
        if run.guessed is not None:
            clipped = run.guessed if clipped is None else clipped | run.guessed
        return cls(run.dtheta_rad, run.dv_mps, sample_intervals(run.time_s), clipped)
