"""A logger's fixed-width counter or tick clock rolling over is counted on, not refused."""

from __future__ import annotations

import numpy as np
import pytest

from calib.errors import CalibError
from calib.runlog import read_run
from calib.runlog.rollover import unwrapped

SITE = {"latitude_deg": 45.0, "height_m": 0.0}
COLUMNS = "gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"


def test_a_16_bit_packet_counter_counts_on_past_65535():
    count = (65000 + np.arange(2000)) % 65536  # Xsens' PacketCounter near its end
    out, bits = unwrapped(count.astype(np.int64))
    assert bits == 16
    assert np.array_equal(out, 65000 + np.arange(2000))


def test_a_32_bit_microsecond_clock_counts_on_with_its_jitter():
    rng = np.random.default_rng(3)
    true_us = 4_294_000_000 + np.cumsum(10_000 + rng.integers(-800, 800, 5000))  # micros() at 100 Hz
    out, bits = unwrapped((true_us % 2**32).astype(np.int64))
    assert bits == 32
    assert np.array_equal(out, true_us)


@pytest.mark.parametrize(
    "column",
    [
        np.r_[np.arange(40000, 45124), np.arange(0, 3000)],  # two logs spliced: restarts at 0 mid-count
        np.r_[np.arange(65000, 65536), np.arange(10, 500)],  # a rollover that skips 10 counts
        np.r_[np.arange(100, 200), np.arange(150, 300)],  # rows out of order
    ],
)
def test_a_step_back_that_does_not_go_on_counting_is_no_rollover(column):
    out, bits = unwrapped(column.astype(np.int64))
    assert bits == 0 and out is not None and np.array_equal(out, column)


def _log(path, first_column: str, stamps) -> None:
    rows = [f"{s},0.001,-0.002,0.003,0.05,0.02,9.81" for s in stamps]
    path.write_text(f"{first_column},gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")


def test_a_wrapping_counter_reads_as_the_same_log_counted_on(tmp_path):
    n = 3000
    _log(tmp_path / "wraps.csv", "n", (64000 + np.arange(n)) % 65536)
    _log(tmp_path / "straight.csv", "n", 64000 + np.arange(n))
    columns = "n=counter," + COLUMNS
    with pytest.warns(UserWarning, match=r"line 1538, column n .*rolls over at 2\^16 \(1 time\)"):
        wraps = read_run(tmp_path / "wraps.csv", columns=columns, sample_rate_hz=100.0, **SITE)
    straight = read_run(tmp_path / "straight.csv", columns=columns, sample_rate_hz=100.0, **SITE)
    assert np.array_equal(wraps.time_s, straight.time_s)
    assert np.array_equal(wraps.time_s, (np.arange(n) + 1) / 100.0)


def test_a_wrapping_microsecond_stamp_reads_as_the_same_log_counted_on(tmp_path):
    n = 3000
    us = 4_294_000_000 + 10_000 * np.arange(n, dtype=np.int64)
    _log(tmp_path / "wraps.csv", "t", us % 2**32)
    _log(tmp_path / "straight.csv", "t", us)
    columns = "t=time_us," + COLUMNS
    with pytest.warns(UserWarning, match=r"rolls over at 2\^32"):
        wraps = read_run(tmp_path / "wraps.csv", columns=columns, **SITE)
    straight = read_run(tmp_path / "straight.csv", columns=columns, **SITE)
    assert np.array_equal(wraps.time_s, straight.time_s)
    assert wraps.sample_rate_hz == pytest.approx(100.0)


def test_a_counter_that_restarts_is_still_refused(tmp_path):
    _log(tmp_path / "spliced.csv", "n", np.r_[np.arange(40000, 41000), np.arange(0, 1000)])
    with pytest.raises(CalibError, match="does not increase: 0 follows 40999"):
        read_run(tmp_path / "spliced.csv", columns="n=counter," + COLUMNS, sample_rate_hz=100.0, **SITE)


def test_an_mt_manager_export_reads_with_its_comment_lines_tabs_and_wrapping_counter(tmp_path):
    # Xsens MT Manager writes '//' comment lines (one of them 'key: value' shaped), then a
    # tab-separated header and rows each ending in a tab, counted by a 16-bit PacketCounter.
    n = 3000
    count = (64000 + np.arange(n)) % 65536
    preamble = "// General information:\n//  MT Manager version: 2019.0.0\n// Update Rate: 100.0Hz\n"
    rows = [f"{c:05d}\t0.05\t0.02\t9.81\t0.001\t-0.002\t0.003\t" for c in count]
    header = "PacketCounter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\t\n"
    (tmp_path / "mtm.txt").write_text(preamble + header + "\n".join(rows) + "\n")
    columns = (
        "PacketCounter=counter,Gyr_X=gyro_x_radps,Gyr_Y=gyro_y_radps,Gyr_Z=gyro_z_radps,"
        "Acc_X=accel_x_mps2,Acc_Y=accel_y_mps2,Acc_Z=accel_z_mps2"
    )
    with pytest.warns(UserWarning) as said:
        run = read_run(tmp_path / "mtm.txt", columns=columns, sample_rate_hz=100.0, **SITE)
    said = [str(w.message) for w in said]
    assert any("separated by tabs" in m for m in said) and any("rolls over at 2^16" in m for m in said)
    assert np.array_equal(run.time_s, (np.arange(n) + 1) / 100.0)
    assert np.allclose(run.dv_mps / 0.01, [0.05, 0.02, 9.81], rtol=0, atol=1e-12)
    assert np.allclose(run.dtheta_rad / 0.01, [0.001, -0.002, 0.003], rtol=0, atol=1e-15)


def test_a_counter_with_a_non_finite_value_is_refused_not_a_crash(tmp_path):
    count = np.arange(2000).astype(object)
    count[700] = "inf"
    _log(tmp_path / "inf.csv", "n", count)
    with pytest.raises(CalibError):
        read_run(tmp_path / "inf.csv", columns="n=counter," + COLUMNS, sample_rate_hz=100.0, **SITE)
    # Epoch-sized values stepping back are no counter's rollover: left for the reader.
    epoch = 1_700_000_000_000_000_000 + 5_000_000 * np.arange(500, dtype=np.int64)
    epoch[300:] -= 2_000_000
    assert unwrapped(epoch)[1] == 0


def _mt_export(path, preamble: str, n: int = 3000, rate_hz: float = 100.0) -> None:
    """An MT Manager export: '//' preamble, tabs, PacketCounter and SampleTimeFine (10 kHz ticks)."""
    fine = 35_412_700 + np.rint(np.arange(n) * 10_000 / rate_hz).astype(np.int64)
    rows = [f"{(23456 + i) % 65536}\t{f}\t0.05\t0.02\t9.81\t0.001\t-0.002\t0.003" for i, f in enumerate(fine)]
    header = "PacketCounter\tSampleTimeFine\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\n"
    path.write_text(preamble + header + "\n".join(rows) + "\n")


_MT_SENSORS = (
    "Gyr_X=gyro_x_radps,Gyr_Y=gyro_y_radps,Gyr_Z=gyro_z_radps,"
    "Acc_X=accel_x_mps2,Acc_Y=accel_y_mps2,Acc_Z=accel_z_mps2"
)


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*fields separated by tabs:UserWarning")
def test_an_mt_manager_update_rate_line_times_its_counter(tmp_path):
    # The older export states its output rate, '// Update Rate: 200.0Hz': the counter needs no option.
    _mt_export(tmp_path / "old.txt", "// Start Time: Unknown\n// Update Rate: 200.0Hz\n", rate_hz=200.0)
    with pytest.warns(UserWarning, match=r"line 2: the sample counter is timed at the 200 Hz this line"):
        run = read_run(tmp_path / "old.txt", columns="PacketCounter=counter," + _MT_SENSORS, **SITE)
    assert np.array_equal(run.time_s, (np.arange(3000) + 1) / 200.0)
    assert run.sample_rate_hz == 200.0
    # A rate given by the user wins over the line.
    run = read_run(
        tmp_path / "old.txt", columns="PacketCounter=counter," + _MT_SENSORS, sample_rate_hz=100.0, **SITE
    )
    assert run.sample_rate_hz == 100.0


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*fields separated by tabs:UserWarning")
def test_sample_time_fine_in_10_khz_ticks_reads_as_seconds(tmp_path):
    # SampleTimeFine counts a 10 kHz clock: 100 ticks a sample at 100 Hz, 0.01 s.
    _mt_export(tmp_path / "new.txt", "// General information:\n//  MT Manager version: 2022.2.0\n")
    run = read_run(tmp_path / "new.txt", columns="SampleTimeFine=time_100us," + _MT_SENSORS, **SITE)
    assert run.sample_rate_hz == pytest.approx(100.0, rel=1e-12)
    assert np.allclose(np.diff(run.time_s), 0.01, rtol=0, atol=1e-12)
    assert run.time_s[0] == pytest.approx(3541.27, abs=1e-9)  # 35,412,700 ticks of 0.1 ms


# The notice is asserted where it is the point (or is not its point), and kept out of the summary.
@pytest.mark.filterwarnings("ignore:.*fields separated by tabs:UserWarning")
def test_an_mt_manager_export_without_a_rate_names_its_own_clock(tmp_path):
    _mt_export(tmp_path / "new.txt", "// General information:\n//  MT Manager version: 2022.2.0\n")
    with pytest.raises(CalibError, match=r"line 3: .*map SampleTimeFine=time_100us") as err:
        read_run(tmp_path / "new.txt", columns="PacketCounter=counter," + _MT_SENSORS, **SITE)
    assert "--sample-rate-hz" in err.value.fix


def test_a_stamp_garbled_on_the_way_is_no_rollover_and_is_mended_only_when_gaps_are_allowed(tmp_path):
    # An ESP32's micros() at 77 Hz over a serial link that lost one stamp's leading digit:
    # 988842245, 88855245, 988868245. Its neighbours, two steps apart, go on from each other, so
    # the step back is no 2^30 rollover (which read the log as two holes of 13,365 and 69,231
    # samples): refused naming the row, and with gaps allowed put midway between them.
    rng = np.random.default_rng(4)
    true_us = 988_000_000 + np.cumsum(13_000 + rng.integers(-300, 300, 2000))
    garbled = true_us.copy()
    garbled[1000] = int(str(true_us[1000])[1:])  # the leading '9' lost
    assert unwrapped(garbled)[1] == 0
    _log(tmp_path / "garbled.csv", "t", garbled)
    _log(tmp_path / "whole.csv", "t", true_us)
    columns = "t=time_us," + COLUMNS
    with pytest.raises(CalibError) as err:
        read_run(tmp_path / "garbled.csv", columns=columns, **SITE)
    assert err.value.where.startswith(f"{tmp_path / 'garbled.csv'}, line 1002")  # header, then row 1001
    assert "out of line with its neighbours" in err.value.what and "the CLI's --allow-gaps" in err.value.fix
    with pytest.warns(UserWarning, match="1 stamp.s. of column 't' out of line"):
        mended = read_run(tmp_path / "garbled.csv", columns=columns, allow_gaps=True, **SITE)
    whole = read_run(tmp_path / "whole.csv", columns=columns, **SITE)
    # The mended stamp is its neighbours' midpoint, within the jitter of the true one (300 us), which
    # the clock then puts on its uniform base like every other: the two reads agree but for the
    # rate fitted through the stamps, which that one stamp moves by parts in 1e11.
    assert mended.n_samples == whole.n_samples and mended.clock.dropped == []
    np.testing.assert_allclose(mended.dv_mps, whole.dv_mps, rtol=1e-9)
    assert np.max(np.abs(mended.time_s - whole.time_s)) < 1e-6
