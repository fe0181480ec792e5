"""Setup mistakes made in writing a run log, as transformations of a correct :class:`~calib.runlog.Run`.

What a user's logger does wrong, turned into what a correct run would then look like
once read (for tests of a diagnosis of the setup before a fit). Each function returns a
new run and leaves its argument alone; the run's metadata keeps claiming the correct
units. A logger that writes rates (deg/s, g) and one that writes increments make the same
mistakes here: a unit's factor multiplies increments and rates alike.

* :func:`accel_in_g`: the accelerometer wrote g, the column says m/s^2 (``|f|`` at rest reads 1);
* :func:`gyro_in_deg`: the gyro wrote deg/s (deg), the column says rad/s (x 57.3);
* :func:`gyro_accel_swapped`: the two triads' columns exchanged;
* :func:`axes_swapped`: two axes of one sensor exchanged (a left-handed triad);
* :func:`axis_flipped`: one axis's sign flipped (a left-handed triad);
* :func:`rate_mislabelled`: a rate-writing logger's samples read at the wrong sample rate.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from calib.model.params import STANDARD_GRAVITY
from calib.runlog import Run

SENSORS = ("gyro", "accel")
AXES = "xyz"


def _with(run: Run, **changes) -> Run:
    """A copy of ``run`` (metadata copied too) with ``changes``; its clock is no longer known."""
    arrays = {k: np.array(getattr(run, k)) for k in ("time_s", "dtheta_rad", "dv_mps")}
    return dataclasses.replace(run, **(arrays | {"meta": dict(run.meta), "clock": None} | changes))


def _field(sensor: str) -> str:
    if sensor not in SENSORS:
        raise ValueError(f"sensor must be one of {', '.join(SENSORS)}, not {sensor!r}")
    return "dtheta_rad" if sensor == "gyro" else "dv_mps"


def _axis(axis: str | int) -> int:
    index = AXES.index(axis) if isinstance(axis, str) and axis in AXES else axis
    if not isinstance(index, int) or not 0 <= index <= 2:
        raise ValueError(f"axis must be x, y, z or 0, 1, 2, not {axis!r}")
    return index


def accel_in_g(run: Run) -> Run:
    """The accelerometer logged in g (standard gravity, 9.80665 m/s^2) where m/s^2 is declared."""
    return _with(run, dv_mps=run.dv_mps / STANDARD_GRAVITY)


def accel_in_mg(run: Run) -> Run:
    """The accelerometer logged in milli-g where m/s^2 is declared."""
    return _with(run, dv_mps=run.dv_mps * 1000.0 / STANDARD_GRAVITY)


def gravity_removed(run: Run, gravity_mps2: float) -> Run:
    """A phone's 'linear acceleration': each sample less ``gravity_mps2`` along its own direction.

    At rest, where the specific force is gravity, what is left is its few-per-cent errors and
    noise, as a phone's fused output leaves; in a move it is the unit's own acceleration, roughly.
    """
    f = run.dv_mps
    norm = np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-12)
    period = np.diff(run.time_s, prepend=run.time_s[0] - (run.time_s[1] - run.time_s[0]))[:, None]
    return _with(run, dv_mps=f - gravity_mps2 * period * f / norm)


def gyro_in_deg(run: Run) -> Run:
    """The gyro logged in deg/s (increments in deg) where rad/s (rad) is declared."""
    return _with(run, dtheta_rad=np.degrees(run.dtheta_rad))


def gyro_in_mdeg(run: Run) -> Run:
    """The gyro logged in milli-degrees per second where rad/s is declared (ST's drivers' unit)."""
    return _with(run, dtheta_rad=np.degrees(run.dtheta_rad) * 1000.0)


def gyro_accel_swapped(run: Run) -> Run:
    """The gyro's and the accelerometer's columns exchanged."""
    return _with(run, dtheta_rad=np.array(run.dv_mps), dv_mps=np.array(run.dtheta_rad))


def axes_swapped(run: Run, sensor: str = "gyro", axes: tuple[str | int, str | int] = ("x", "y")) -> Run:
    """Two axes of ``sensor`` (``gyro`` or ``accel``) exchanged (gyro x and y by default)."""
    name = _field(sensor)
    i, j = _axis(axes[0]), _axis(axes[1])
    if i == j:
        raise ValueError("swap two different axes")
    data = np.array(getattr(run, name))
    data[:, [i, j]] = data[:, [j, i]]
    return _with(run, **{name: data})


def axis_flipped(run: Run, sensor: str = "gyro", axis: str | int = "z") -> Run:
    """One axis of ``sensor`` with its sign flipped."""
    name = _field(sensor)
    data = np.array(getattr(run, name))
    data[:, _axis(axis)] *= -1.0
    return _with(run, **{name: data})


def rate_mislabelled(run: Run, sample_rate_hz: float) -> Run:
    """A rate-writing logger's run read at ``sample_rate_hz`` instead of its true rate.

    Its samples are mean rates; read at the wrong rate each becomes an increment over the
    wrong period (x ``true / given``) and the samples are placed at the given rate.
    """
    if not sample_rate_hz > 0:
        raise ValueError("the sample rate must be > 0")
    factor = run.sample_rate_hz / sample_rate_hz
    meta = dict(run.meta) | {"sample_rate_hz": repr(float(sample_rate_hz))}
    return _with(
        run,
        time_s=np.arange(1, run.n_samples + 1) / sample_rate_hz,
        dtheta_rad=run.dtheta_rad * factor,
        dv_mps=run.dv_mps * factor,
        meta=meta,
    )


# Each mistake of a logger's setup by name, with its default arguments (for parametrised tests).
MISTAKES = {
    "accel-in-g": accel_in_g,
    "gyro-in-deg": gyro_in_deg,
    "gyro-accel-swapped": gyro_accel_swapped,
    "gyro-xy-swapped": axes_swapped,
    "gyro-z-flipped": axis_flipped,
}
