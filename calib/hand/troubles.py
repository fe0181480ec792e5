"""What real hand recordings suffer from, for the simulator of runs placed by hand.

Each is off by default (a run without them is the table's exact run, bit for bit):

* tremor: the poses held in the hand wobble and shake (:mod:`calib.hand.tremor`);
* gyro g-sensitivity: ``omega_meas = A_g omega + b_g + G f`` with ``f`` the true specific
  force in body axes (the model :mod:`calib.hand.joint_fit` fits with ``--with g-sensitivity``);
  on increments exactly ``dtheta += G dv_true``;
* a sample-clock rate error ``epsilon``: the IMU samples at ``(1 + epsilon)`` times its
  nominal rate and outputs the mean rate and specific force over its own (shorter) sample;
  the log holds them as increments over the nominal period, so every increment is
  ``(1 + epsilon)`` times the true one (a turn reads ``1 + epsilon`` times its angle; the
  rates at rest are right) and the written stamps follow the nominal rate;
* a gyro scale that changes from turn to turn (:func:`scale_each_turn`, applied to a run);
* host stamps: each sample stamped at its reception, up to ``stamp_jitter_s`` late and in
  order (:mod:`calib.hand.host_clock`), in float seconds or integer epoch milliseconds. With a rate
  error the host's stamps follow the true time (the host's clock is right, the IMU's is not).

The truth file records them in its ``[hand]`` table (:func:`troubles_to_table`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from calib.model.optional_terms import G_SENSITIVITY_SI_PER_UNIT
from calib.nav.strapdown import sample_intervals

from .host_clock import EPOCH_MS, STAMP_MODES
from .plan import HandPlan
from .tremor import SHAKE_MPS2, Tremor, random_tremor, tremor_from_table, tremor_to_table

MAX_RATE_ERROR = 0.2  # beyond 20 % a rate is not a crystal's error but a wrong setting


@dataclass(frozen=True)
class HandTroubles:
    """The troubles of a simulated hand run (SI); the default is none.

    Attributes
    ----------
    tremor : Tremor or None
        The held rests' wobble and shake.
    g_sensitivity : ndarray, shape (3, 3), or None
        Gyro g-sensitivity ``G``, (rad/s) per (m/s^2): row ``i`` the ``i``-gyro's rate per
        unit specific force along each body axis.
    rate_error : float
        The IMU's true sample rate over its nominal one, less 1.
    stamp_jitter_s : float
        Largest host delay of a stamp, s (0: the stamps are the nominal sample times).
    stamps : str
        ``"seconds"`` (float s from the start) or ``"epoch-ms"`` (whole ms from ``epoch_ms``).
    epoch_ms : int
        The epoch-ms stamps' origin (the run's start), ms.
    """

    tremor: Tremor | None = None
    g_sensitivity: np.ndarray | None = None
    rate_error: float = 0.0
    stamp_jitter_s: float = 0.0
    stamps: str = "seconds"
    epoch_ms: int = EPOCH_MS

    def __post_init__(self):
        if self.g_sensitivity is not None:
            G = np.asarray(self.g_sensitivity, dtype=float).reshape(3, 3)
            if not np.all(np.isfinite(G)):
                raise ValueError("the g-sensitivity must be finite")
            object.__setattr__(self, "g_sensitivity", G)
        if not abs(self.rate_error) <= MAX_RATE_ERROR:
            raise ValueError(f"the rate error must be within +-{MAX_RATE_ERROR}")
        if not self.stamp_jitter_s >= 0.0:
            raise ValueError("the stamps' jitter must be >= 0")
        if self.stamps not in STAMP_MODES:
            raise ValueError(f"stamps must be one of {', '.join(STAMP_MODES)}")

    @property
    def any(self) -> bool:
        """Whether any trouble is on."""
        return bool(
            self.tremor is not None
            or self.g_sensitivity is not None
            or self.rate_error != 0.0
            or self.stamp_jitter_s > 0.0
            or self.stamps != "seconds"
        )

    @property
    def g_sensitivity_dphg(self) -> np.ndarray | None:
        """``G`` in deg/h per g (the report unit of ``gsxx``...)."""
        return None if self.g_sensitivity is None else self.g_sensitivity / G_SENSITIVITY_SI_PER_UNIT


def g_sensitivity_from_dphg(values) -> np.ndarray:
    """A 3x3 ``G`` (SI) from deg/h/g values: 9 row-major values (``gsxx gsxy ... gszz``)."""
    return np.asarray(values, dtype=float).reshape(3, 3) * G_SENSITIVITY_SI_PER_UNIT


def random_g_sensitivity(half_range_dphg: float, rng: np.random.Generator) -> np.ndarray:
    """A ``G`` (SI) each element uniform within ``+-half_range_dphg`` deg/h/g."""
    return g_sensitivity_from_dphg(rng.uniform(-half_range_dphg, half_range_dphg, 9))


def apply_g_sensitivity(dtheta: np.ndarray, dv_true: np.ndarray, G: np.ndarray | None) -> np.ndarray:
    """The gyro increments plus ``int G f dt = G dv_true`` (exact on increments: ``G`` is constant)."""
    return dtheta if G is None else dtheta + dv_true @ np.asarray(G).T


def troubles_to_table(troubles: HandTroubles) -> dict:
    """The keys a truth file's ``[hand]`` table gets for the troubles that are on (none when off)."""
    out: dict = {}
    if troubles.tremor is not None:
        out["tremor"] = tremor_to_table(troubles.tremor)
    if troubles.g_sensitivity is not None:
        dphg = troubles.g_sensitivity_dphg
        assert dphg is not None
        out["g_sensitivity_dphg"] = dphg.tolist()
    if troubles.rate_error != 0.0:
        out["rate_error"] = float(troubles.rate_error)
    if troubles.stamp_jitter_s > 0.0 or troubles.stamps != "seconds":
        stamps: dict = {"mode": troubles.stamps, "jitter_ms": 1000.0 * troubles.stamp_jitter_s}
        if troubles.stamps == "epoch-ms":
            stamps["epoch_ms"] = int(troubles.epoch_ms)
        out["stamps"] = stamps
    return out


def troubles_from_table(table: dict) -> HandTroubles:
    """The troubles of a truth file's ``[hand]`` table (none where its keys are absent)."""
    stamps = table.get("stamps", {})
    G = table.get("g_sensitivity_dphg")
    return HandTroubles(
        tremor=tremor_from_table(table["tremor"]) if "tremor" in table else None,
        g_sensitivity=None if G is None else g_sensitivity_from_dphg(G),
        rate_error=float(table.get("rate_error", 0.0)),
        stamp_jitter_s=float(stamps.get("jitter_ms", 0.0)) / 1000.0,
        stamps=str(stamps.get("mode", "seconds")),
        epoch_ms=int(stamps.get("epoch_ms", EPOCH_MS)),
    )


@dataclass(frozen=True)
class TroubleSpec:
    """How big the troubles of simulated hand runs are; :meth:`draw` gives one run's (SI).

    Attributes
    ----------
    tremor_deg : float
        RMS tremor angle per body axis of a held pose, deg (0: no tremor).
    hand_held_s : float or None
        Only the rests that begin before this are held in the hand (None: all).
    shake_mps2 : float
        RMS shake acceleration per axis of a held pose, m/s^2.
    g_sensitivity_dphg : float, ndarray of 9, or None
        Gyro g-sensitivity in deg/h/g: 9 row-major values (``gsxx gsxy ... gszz``), or one
        half-range each run draws the 9 within (uniformly); None: none.
    rate_error : float
        The IMU's true sample rate over its nominal one, less 1.
    stamp_jitter_s : float
        Largest host delay of a stamp, s.
    stamps : str
        ``"seconds"`` or ``"epoch-ms"``.
    """

    tremor_deg: float = 0.0
    hand_held_s: float | None = None
    shake_mps2: float = SHAKE_MPS2
    g_sensitivity_dphg: float | tuple[float, ...] | None = None
    rate_error: float = 0.0
    stamp_jitter_s: float = 0.0
    stamps: str = "seconds"

    def draw(self, plan: HandPlan, rng: np.random.Generator) -> HandTroubles:
        """One run's troubles: its tremor, then its g-sensitivity, drawn from ``rng`` (only when on)."""
        tremor = None
        if self.tremor_deg > 0.0:
            tremor = random_tremor(plan, rng, self.tremor_deg, self.hand_held_s, self.shake_mps2)
        G = None
        if isinstance(self.g_sensitivity_dphg, float | int):
            G = random_g_sensitivity(float(self.g_sensitivity_dphg), rng)
        elif self.g_sensitivity_dphg is not None:
            G = g_sensitivity_from_dphg(self.g_sensitivity_dphg)
        return HandTroubles(tremor, G, self.rate_error, self.stamp_jitter_s, self.stamps)


TURNING_RAD_S = 0.05  # far above a MEMS gyro's noise at rest, far below a hand's turn


def scale_each_turn(run, sd: float, rng: np.random.Generator):
    """The run with each turn's gyro increments times its own ``1 + sd N(0, 1)``.

    A gyro whose scale factor changes from one turn to the next (a response the model
    lacks): the moves no longer fit one set of 21, the rests are untouched. A turn is a
    stretch of samples turning faster than `TURNING_RAD_S`.

    Parameters
    ----------
    run : calib.runlog.Run
    sd : float
        The scale's spread over the turns (0.005: 0.5 %).
    rng : numpy.random.Generator
        Draws one factor per turn, in order.
    """
    rate = np.linalg.norm(run.dtheta_rad, axis=1) / sample_intervals(run.time_s)
    turning = rate > TURNING_RAD_S
    factor = np.ones(len(rate))
    for a in np.flatnonzero(np.diff(turning.astype(int)) == 1) + 1:
        b = a + int(np.argmax(~turning[a:])) if not turning[a:].all() else len(rate)
        factor[a:b] = 1.0 + sd * rng.standard_normal()
    return replace(run, dtheta_rad=run.dtheta_rad * factor[:, None])
