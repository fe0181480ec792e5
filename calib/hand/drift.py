"""Biases that drift over a run placed by hand: the times they are fitted about, and the biases at its end.

A unit still warming up moves its biases over minutes: the accelerometers' (a RealSense T265's x
bias, 700 ug/min) and the gyros' (a wireless IMU's x gyro, from -75 deg/h to -230 deg/h over four
minutes). Fitted as ``b + d tau``, each bias's drift ``d`` is taken about the middle of the rests
(``tau`` from halfway between the first and last rests' middles: the bias and its drift are
least correlated there); a correction applied after the run needs the bias of its end, the last
rest's (:func:`at_last_rest`). A move's increments read the gyro's bias at the move's own middle.
"""

from __future__ import annotations

import numpy as np

from calib.model import params as P


def drift_times(data, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rest's middle and each move's middle, s, from halfway between the first rest's and the
    last rest's middles: the time the drifts are fitted about.
    """
    ends = np.concatenate([[0.0], np.cumsum(dt)])
    rest_mid = 0.5 * (ends[data.rests.start] + ends[data.rests.end])
    move_mid = np.array([0.5 * (ends[sl.start] + ends[sl.stop]) for sl in data.move_slices])
    origin = 0.5 * (rest_mid[0] + rest_mid[-1])
    return rest_mid - origin, move_mid - origin


def at_last_rest(state, covariance: np.ndarray, layout, data, dt: np.ndarray):
    """The 21 and their covariance with the drifting biases at the last rest, ``b + d tau_last``.

    ``state`` carries the accelerometers' drift ``D`` and the gyros' ``Dg``; ``layout`` says which
    were fitted and where (:class:`calib.hand.joint_fit.Layout`).
    """
    if not (layout.bias_drift or layout.gyro_drift):
        return state.values, covariance
    tau_last = float(drift_times(data, dt)[0][-1])
    values = state.values.copy()
    T = np.eye(layout.n)
    for fitted, bias, drift, rate in (
        (layout.bias_drift, P.ACCEL_BIAS, layout.drift, state.D),
        (layout.gyro_drift, P.GYRO_BIAS, layout.gdrift, state.Dg),
    ):
        if fitted:
            values[bias] += rate * tau_last
            T[bias, drift] = np.eye(3) * tau_last
    return values, T @ covariance @ T.T
