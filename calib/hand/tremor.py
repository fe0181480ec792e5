"""Hand tremor: the small wobble and shake of a pose held in the hand instead of set on a table.

During a held rest ``k`` (from ``t0`` to ``t1``) the attitude and the position are

    C_b_n(t) = C_k exp([theta(t) x]),    p_n(t) = d(t)

with ``theta`` (body axes, rad) and ``d`` (ENU, m) band-limited: on each axis a sum of
``J`` sinusoids ``A_j sin(2 pi f_j (t - t0) + phi_j)`` (frequencies uniform in the band of
physiological tremor, 3-12 Hz by default, random phases), faded in and out by the
window ``w(t)``: the minimum-jerk ramp over the first and last ``taper_s`` of the rest, 1
in between. ``w``, ``w'`` and ``w''`` vanish at the rest's ends, so the attitude, the
rate and its derivative join the moves' continuously (the table's rest is the special case
``theta = d = 0``). Exactly, with ``u`` the sum of sinusoids and ``q`` that of the shake:

    theta = w u,   theta' = w' u + w u'
    omega_nb_b = J_r(theta) theta'               (C^T dC/dt = [(J_r(theta) theta') x])
    v_n = w' q + w q',   a_n = w'' q + 2 w' q' + w q''

``J_r`` the right Jacobian of SO(3). The sizes are set as RMS per axis over the untapered
middle: ``J`` equal angle amplitudes ``A = theta_rms sqrt(2 / J)``, and displacement
amplitudes ``(shake_rms sqrt(2 / J)) / (2 pi f_j)^2`` so that each axis's acceleration has
RMS ``shake_rms``. ``docs/by-hand-sim.md`` gives the sizes of a real hand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .moves import right_jacobian
from .plan import HandPlan, min_jerk

TREMOR_BAND_HZ = (3.0, 12.0)  # physiological tremor (8-12 Hz) and the slower hand sway
TREMOR_SINES = 4  # sinusoids per axis
TAPER_S = 0.25  # the tremor fades in and out over this at each end of a held rest (at most a quarter)
SHAKE_MPS2 = 0.05  # default RMS acceleration per axis of a hand's shake (5 mg)


@dataclass(frozen=True)
class Tremor:
    """The tremor of the held rests of a plan, exactly (SI).

    Attributes
    ----------
    rest : ndarray of int, shape (R,)
        The rests held in the hand.
    start_s, end_s : ndarray, shape (R,)
        Each held rest's start and end (the plan's), s.
    taper_s : ndarray, shape (R,)
        Fade-in and fade-out time at each end, s.
    amplitude : ndarray, shape (R, 6, J)
        Per component: rotation vector x, y, z (body, rad), displacement E, N, U (m).
    frequency_hz : ndarray, shape (R, 6, J)
    phase_rad : ndarray, shape (R, 6, J)
    """

    rest: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    taper_s: np.ndarray
    amplitude: np.ndarray
    frequency_hz: np.ndarray
    phase_rad: np.ndarray

    def __post_init__(self):
        rest = np.asarray(self.rest, dtype=np.int64).reshape(-1)
        object.__setattr__(self, "rest", rest)
        for name in ("start_s", "end_s", "taper_s"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float).reshape(len(rest)))
        for name in ("amplitude", "frequency_hz", "phase_rad"):
            value = np.asarray(getattr(self, name), dtype=float)
            value = value.reshape(len(rest), 6, -1) if len(rest) else value.reshape(0, 6, 0)
            object.__setattr__(self, name, value)
        if np.any(self.end_s <= self.start_s) or np.any(self.taper_s <= 0):
            raise ValueError("a held rest needs a positive duration and taper")
        if np.any(2.0 * self.taper_s > self.end_s - self.start_s + 1e-12):
            raise ValueError("a held rest's tapers cannot overlap")

    @property
    def breakpoints_s(self) -> np.ndarray:
        """Where the window's third derivative jumps: the ends of the tapers."""
        return np.concatenate([self.start_s + self.taper_s, self.end_s - self.taper_s])

    def rms_angle_rad(self) -> np.ndarray:
        """RMS of each rotation-vector axis, (R, 3), over a long untapered window (there the cross terms
        of distinct frequencies average out; over a few seconds two close frequencies beat).
        """
        return np.sqrt(0.5 * np.sum(self.amplitude[:, :3] ** 2, axis=2))

    def rms_rate_rad_s(self, sample_period_s: float = 0.0) -> np.ndarray:
        """RMS body rate per axis, (R, 3), over a long untapered window, small angles (``J_r ~ I``).

        With ``sample_period_s`` > 0, that of the mean rates over samples of that length
        (what a rate-integrating gyro gives): each sinusoid is attenuated by
        ``sinc(f T) = sin(pi f T) / (pi f T)``.
        """
        w = 2.0 * np.pi * self.frequency_hz[:, :3]
        gain = np.sinc(self.frequency_hz[:, :3] * sample_period_s)
        return np.sqrt(0.5 * np.sum((self.amplitude[:, :3] * w * gain) ** 2, axis=2))

    def rms_accel_mps2(self) -> np.ndarray:
        """RMS shake acceleration per ENU axis, (R, 3), over a long untapered window."""
        w2 = (2.0 * np.pi * self.frequency_hz[:, 3:]) ** 2
        return np.sqrt(0.5 * np.sum((self.amplitude[:, 3:] * w2) ** 2, axis=2))


def held_rests(plan: HandPlan, hand_held_s: float | None = None) -> np.ndarray:
    """The rests held in the hand: all (None), or those that begin before ``hand_held_s``."""
    if hand_held_s is None:
        return np.arange(plan.n_poses)
    return np.flatnonzero(plan.rest_start_s < hand_held_s)


def random_tremor(
    plan: HandPlan,
    rng: np.random.Generator,
    tremor_deg: float,
    hand_held_s: float | None = None,
    shake_mps2: float = SHAKE_MPS2,
    band_hz: tuple[float, float] = TREMOR_BAND_HZ,
    sines: int = TREMOR_SINES,
    taper_s: float = TAPER_S,
) -> Tremor:
    """Draw the tremor of a plan's held rests.

    Parameters
    ----------
    plan : HandPlan
    rng : numpy.random.Generator
    tremor_deg : float
        RMS angle of each body axis's wobble, deg (a hand: 0.05-0.5).
    hand_held_s : float, optional
        Only the rests that begin before this are held (None: all).
    shake_mps2 : float
        RMS acceleration of each ENU axis's shake, m/s^2.
    band_hz : (float, float)
        The sinusoids' frequencies are uniform in this band.
    sines : int
        Sinusoids per axis ``J``.
    taper_s : float
        Fade in and out over this (at most a quarter of the rest).

    Returns
    -------
    Tremor
    """
    if tremor_deg < 0 or shake_mps2 < 0 or sines < 1 or not 0 < band_hz[0] <= band_hz[1]:
        raise ValueError("tremor sizes must be >= 0, with at least one sinusoid in a positive band")
    rest = held_rests(plan, hand_held_s)
    shape = (len(rest), 6, sines)
    freq = rng.uniform(band_hz[0], band_hz[1], shape)
    phase = rng.uniform(0.0, 2.0 * np.pi, shape)
    per_sine = np.sqrt(2.0 / sines)
    amp = np.empty(shape)
    amp[:, :3] = np.radians(tremor_deg) * per_sine
    amp[:, 3:] = shake_mps2 * per_sine / (2.0 * np.pi * freq[:, 3:]) ** 2
    start, end = plan.rest_start_s[rest], plan.rest_end_s[rest]
    return Tremor(rest, start, end, np.minimum(taper_s, 0.25 * (end - start)), amp, freq, phase)


def _window(tremor: Tremor, j: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fade window of held rest ``j`` at ``t`` and its first two time derivatives."""
    tau = tremor.taper_s[j]
    rise = min_jerk((t - tremor.start_s[j]) / tau)
    fall = min_jerk((tremor.end_s[j] - t) / tau)
    in_rise = t - tremor.start_s[j] < tau
    in_fall = tremor.end_s[j] - t < tau
    w = np.where(in_rise, rise[0], np.where(in_fall, fall[0], 1.0))
    dw = np.where(in_rise, rise[1] / tau, np.where(in_fall, -fall[1] / tau, 0.0))
    ddw = np.where(in_rise, rise[2] / tau**2, np.where(in_fall, fall[2] / tau**2, 0.0))
    return w, dw, ddw


def held_at(tremor: Tremor, t: np.ndarray) -> np.ndarray:
    """For each time, the held rest (index into ``tremor.rest``) it lies in, or -1."""
    t = np.asarray(t, dtype=float)
    j = np.searchsorted(tremor.start_s, t, side="right") - 1
    jc = np.clip(j, 0, max(len(tremor.rest) - 1, 0))
    inside = (j >= 0) & (t <= tremor.end_s[jc]) if len(tremor.rest) else np.zeros(t.shape, bool)
    return np.where(inside, jc, -1)


@dataclass(frozen=True)
class TremorState:
    """The tremor's share of the motion at ``m`` instants inside held rests (SI)."""

    theta: np.ndarray  # (m, 3) rotation vector, body
    omega_nb_b: np.ndarray  # (m, 3) J_r(theta) theta'
    p_n: np.ndarray  # (m, 3)
    v_n: np.ndarray
    a_n: np.ndarray


def tremor_state(tremor: Tremor, j: np.ndarray, t: np.ndarray) -> TremorState:
    """The tremor at times ``t`` inside held rests ``j`` (from :func:`held_at`, all >= 0)."""
    s = (t - tremor.start_s[j])[:, None, None]
    w2pi = 2.0 * np.pi * tremor.frequency_hz[j]
    arg = w2pi * s + tremor.phase_rad[j]
    amp = tremor.amplitude[j]
    u = np.sum(amp * np.sin(arg), axis=2)
    du = np.sum(amp * w2pi * np.cos(arg), axis=2)
    ddu = -np.sum(amp * w2pi**2 * np.sin(arg), axis=2)
    w, dw, ddw = (x[:, None] for x in _window(tremor, j, t))
    theta, d_theta = w * u[:, :3], dw * u[:, :3] + w * du[:, :3]
    q, dq, ddq = u[:, 3:], du[:, 3:], ddu[:, 3:]
    omega = np.einsum("nij,nj->ni", right_jacobian(theta), d_theta)
    return TremorState(theta, omega, w * q, dw * q + w * dq, ddw * q + 2.0 * dw * dq + w * ddq)


def tremor_to_table(tremor: Tremor) -> dict:
    """The ``[hand.tremor]`` table of a truth file: the tremor exactly (angles in rad, lengths in m)."""
    return {
        "rest": tremor.rest.tolist(),
        "start_s": tremor.start_s.tolist(),
        "end_s": tremor.end_s.tolist(),
        "taper_s": tremor.taper_s.tolist(),
        "amplitude": tremor.amplitude.tolist(),
        "frequency_hz": tremor.frequency_hz.tolist(),
        "phase_rad": tremor.phase_rad.tolist(),
        "rms_angle_deg": np.degrees(tremor.rms_angle_rad()).tolist(),
        "rms_accel_mps2": tremor.rms_accel_mps2().tolist(),
    }


def tremor_from_table(table: dict) -> Tremor:
    """The tremor of a ``[hand.tremor]`` table written by :func:`tremor_to_table`."""
    keys = ("rest", "start_s", "end_s", "taper_s", "amplitude", "frequency_hz", "phase_rad")
    return Tremor(*(np.asarray(table[k]) for k in keys))
