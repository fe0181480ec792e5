"""A correction that carries a fitted bias drift: ``b(t) = b + d (t - bias_time_s)``.

Each figure is derived from the line itself: a raw signal that is a known specific force
plus a bias moving linearly is brought back to that force exactly when the drift is
carried, and left off by ``d (t - bias_time_s)`` when one bias is taken out. ``correct
--carry-drift`` does it on the log's own time axis (its ``time_origin_s`` plus ``time_s``),
only inside the span the drift was fitted over.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from calib.calibration.correction import Correction, SensorCorrection, sample_middles
from calib.errors import CalibError
from calib.runlog import Run, read_run, write_run
from calib.runlog.run import make_meta
from seqdesign.cli import main

RATE_HZ = 100.0
ORIGIN_S = 1.7e9  # a UNIX time: the drift's times are absolute, the log's time_s counts from it
N = 2000  # 20 s
ACCEL_BIAS = np.array([0.05, -0.03, 0.08])  # m/s^2 at the biases' time
ACCEL_DRIFT = np.array([-1e-4, 4e-5, 0.0])  # m/s^2 per s (about -600 ug/min on x)
GYRO_BIAS = np.array([1e-4, -2e-4, 5e-5])  # rad/s
GYRO_DRIFT = np.array([2e-6, -3e-6, 0.0])  # rad/s per s (about 25 deg/h/min)
BIAS_TIME = ORIGIN_S + 15.0


def _sensor(b, drift, unit: str) -> SensorCorrection:
    nan = np.full(3, np.nan)
    sigma_drift = None if drift is None else np.full(3, 1e-7)
    return SensorCorrection(np.eye(3), np.asarray(b), np.full((3, 3), np.nan), nan, unit, drift, sigma_drift)


def _correction(
    span=(ORIGIN_S, ORIGIN_S + N / RATE_HZ), drift: bool = True, samples: int | None = N
) -> Correction:
    return Correction(
        _sensor(GYRO_BIAS, GYRO_DRIFT if drift else None, "rad/s"),
        _sensor(ACCEL_BIAS, ACCEL_DRIFT if drift else None, "m/s^2"),
        source="test",
        bias_time_s=BIAS_TIME if drift else None,
        drift_span_s=span if drift else None,
        drift_samples=samples if drift else None,
    )


# A still unit, z up: the true specific force and rate every sample (any constant would do).
TRUE_FORCE = np.array([0.0, 0.0, 9.80665])
TRUE_RATE = np.array([0.0, 3.0e-5, -5.0e-5])


def _raw_run(origin_s: float = ORIGIN_S) -> Run:
    """The raw log: the truth plus each bias at each sample's middle, stamped from ``origin_s``."""
    time_s = np.arange(1, N + 1) / RATE_HZ
    dt = 1.0 / RATE_HZ
    tau = origin_s + time_s - 0.5 * dt - BIAS_TIME
    force = TRUE_FORCE + ACCEL_BIAS + tau[:, None] * ACCEL_DRIFT
    rate = TRUE_RATE + GYRO_BIAS + tau[:, None] * GYRO_DRIFT
    meta = make_meta(45.0, 0.0, RATE_HZ, time_origin_s=repr(origin_s))
    return Run(time_s, rate * dt, force * dt, meta)


def test_a_carried_drift_takes_a_linear_bias_out_exactly_and_one_bias_leaves_the_line():
    run = _raw_run()
    c = _correction()
    dt = 1.0 / RATE_HZ
    times = sample_middles(run)
    rate, force = c.apply(run.dtheta_rad / dt, run.dv_mps / dt, times)
    # M = I: the truth comes back to float64 rounding of quantities near 10 m/s^2.
    assert np.allclose(force, TRUE_FORCE, rtol=0, atol=1e-12)
    assert np.allclose(rate, TRUE_RATE, rtol=0, atol=1e-12)
    rate1, force1 = c.apply(run.dtheta_rad / dt, run.dv_mps / dt)
    # One bias: what is left is the drift from the biases' time, d (t - bias_time_s).
    tau = times - BIAS_TIME
    assert np.allclose(force1 - TRUE_FORCE, tau[:, None] * ACCEL_DRIFT, rtol=0, atol=1e-12)
    assert np.allclose(rate1 - TRUE_RATE, tau[:, None] * GYRO_DRIFT, rtol=0, atol=1e-12)


def test_a_correction_with_a_drift_reads_back_as_written_and_refuses_a_time_outside_its_span(tmp_path):
    c = _correction()
    path = tmp_path / "c.toml"
    c.save(path)
    back = Correction.load(path)
    assert back.bias_time_s == BIAS_TIME and back.drift_span_s == c.drift_span_s and back.drift_samples == N
    assert np.array_equal(back.accel.drift, ACCEL_DRIFT) and np.array_equal(back.gyro.drift, GYRO_DRIFT)
    text = path.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(f"bias_time_s = {BIAS_TIME!r}", f"bias_time_s = {ORIGIN_S - 5.0!r}"))
    with pytest.raises(CalibError, match="outside drift_span_s"):
        Correction.load(bad)
    bad.write_text(text.replace(f"bias_time_s = {BIAS_TIME!r}\n", ""))
    with pytest.raises(CalibError, match="bias_time_s"):
        Correction.load(bad)


def _correct(tmp_path, run: Run, correction: Correction, *extra: str):
    log, corr, out = tmp_path / "raw.csv", tmp_path / "c.toml", tmp_path / "calibrated.csv"
    write_run(run, log)
    correction.save(corr)
    res = CliRunner().invoke(
        main, ["correct", str(log), "--correction", str(corr), "-o", str(out), "--json", *extra]
    )
    return res, out


def test_cli_carries_the_drift_on_the_logs_own_time_axis_only_when_asked(tmp_path):
    res, out = _correct(tmp_path, _raw_run(), _correction(), "--carry-drift")
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["drift_carried"] is True
    back = read_run(out)
    dt = 1.0 / RATE_HZ
    # Through a CSV of exact reprs: the truth again, the stamps read from time_origin_s = 1.7e9.
    assert np.allclose(back.dv_mps / dt, TRUE_FORCE, rtol=0, atol=1e-9)
    assert np.allclose(back.dtheta_rad / dt, TRUE_RATE, rtol=0, atol=1e-9)
    out.unlink()
    res, out = _correct(tmp_path, _raw_run(), _correction())
    assert res.exit_code == 0, res.output
    assert "--carry-drift" in res.stderr  # the drift left in is said
    back = read_run(out)
    # One bias: the x force runs along the drift, -1e-4 m/s^2 per s over 20 s.
    slope = np.polyfit(back.time_s, back.dv_mps[:, 0] / dt, 1)[0]
    assert slope == pytest.approx(ACCEL_DRIFT[0], rel=1e-6)


@pytest.mark.parametrize(
    ("origin_s", "drift", "samples", "message"),
    [
        (ORIGIN_S + 60.0, True, N, "not the log the drift was fitted on"),  # a later log
        (ORIGIN_S, True, N + 100, "not the log the drift was fitted on"),  # another log, the same span
        (ORIGIN_S, False, N, "carries no bias drift"),
    ],
)
def test_cli_refuses_to_carry_a_drift_it_has_not_or_beyond_its_log(
    tmp_path, origin_s, drift, samples, message
):
    res, out = _correct(
        tmp_path, _raw_run(origin_s), _correction(drift=drift, samples=samples), "--carry-drift"
    )
    assert res.exit_code != 0
    assert message in res.output and "Traceback" not in res.output
    assert not out.exists()


def test_cli_correct_fills_a_sample_lost_at_rest_only_when_told(tmp_path):
    # A still log that lost one sample: refused as the readers refuse it, naming --allow-gaps, and
    # with it filled (at rest, from its neighbours) and said before the correction is applied.
    run = _raw_run()
    keep = np.r_[0:500, 501:N]
    lost = Run(run.time_s[keep], run.dtheta_rad[keep], run.dv_mps[keep], run.meta)
    res, out = _correct(tmp_path, lost, _correction(drift=False))
    assert res.exit_code != 0 and "--allow-gaps" in res.output and not out.exists()
    res, out = _correct(tmp_path, lost, _correction(drift=False), "--allow-gaps")
    assert res.exit_code == 0, res.output
    assert "1 sample(s) the log lost at rest filled" in res.stderr
    back = read_run(out)
    assert back.n_samples == N
    # The still unit's force comes back at every sample, the filled one too (its neighbours'): the
    # one bias leaves the raw log's drift, d (t - bias_time_s), at most 1.5e-3 m/s^2 over its 20 s.
    assert np.allclose(back.dv_mps * RATE_HZ, TRUE_FORCE, rtol=0, atol=1.6e-3)
