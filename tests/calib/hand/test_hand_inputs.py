"""Hand calibration recordings as their users have them: a sample counter, raw counts with a
nominal conversion, imu_tk's two files, clipped stretches; and the two real recordings.

Each format is written into tmp_path (plain and gzip-compressed) from known SI values and read
back; each refusal is checked through the CLI (one line, exit code 2, nothing written).
"""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import FERRARIS as FERRARIS_DIR, XSENS

from calib.errors import CalibError
from calib.fit import sanity
from calib.runlog import read_run
from calib.runlog.clipping import clipped_stretches, describe_clipping, flat_top
from calib.runlog.conversion import Conversion, read_conversion
from seqdesign.cli import main

FERRARIS = FERRARIS_DIR / "example_ferraris_session.csv"

SITE = {"latitude_deg": 45.4, "height_m": 12.0}
SITE_CLI = ["--latitude", "45.4", "--height", "12"]
FERRARIS_MAP = (
    "n_samples=counter,gyr_x=gyro_x_dps,gyr_y=gyro_y_dps,gyr_z=gyro_z_dps,"
    "acc_x=accel_x_mps2,acc_y=accel_y_mps2,acc_z=accel_z_mps2"
)
COUNTS_MAP = (
    "c=counter,gx=gyro_x_counts,gy=gyro_y_counts,gz=gyro_z_counts,"
    "ax=accel_x_counts,ay=accel_y_counts,az=accel_z_counts"
)

NOMINAL_TEXT = """# a comment; local gravity 9.81744 m/s^2; 100 Hz
offset_acc  (counts) = 33123 33276 32360
offset_gyro (counts) = 32768 32466 32485
DS_a_scale  (counts per m/s^2)  = diag(415, 413, 415)
DS_a_misal  = [1.00 0.00 -0.01; 0.01 1.00 0.01; 0.02 0.01 1.00]
DS_g_scale  (counts per rad/s)  = diag(4778, 4758, 4766)
DS_g_misal  = [1.00 -0.01 -0.02; 0.00 1.00 0.04; -0.01 0.01 1.00]
"""
CONVERSION_TOML = """gravity_mps2 = 9.81744
[gyro]
zero_counts = [32768, 32466, 32485]
counts_per_unit = [4778, 4758, 4766]
unit = "rad/s"
[accel]
zero_counts = [33123, 33276, 32360]
counts_per_unit = [415, 413, 415]
unit = "m/s^2"
"""
ZERO = {"gyro": np.array([32768.0, 32466, 32485]), "accel": np.array([33123.0, 33276, 32360])}
SCALE = {"gyro": np.array([4778.0, 4758, 4766]), "accel": np.array([415.0, 413, 415])}


def _invoke(*args) -> tuple[int, str]:
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


def _refusal(path: Path, *flags) -> str:
    """The one-line refusal of ``calibrate``: exit code 2, no result written."""
    out = path.parent / "out.result.toml"
    code, output = _invoke("calibrate", path, "-o", out, *flags)
    assert code == 2, output
    assert not out.exists()
    line = output.strip().splitlines()[-1]
    assert line.startswith("error: ") and "(" in line, line  # what, where: ... (fix)
    return line


def _write(path: Path, text: str) -> Path:
    if path.suffix == ".gz":
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path


def _si_signals(n: int, rate_hz: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Rates (rad/s) and specific force (m/s^2) of a unit at rest that turns once about z."""
    rng = np.random.default_rng(seed)
    w = rng.normal(0.0, 0.01, (n, 3))
    f = np.array([0.3, -0.2, 9.8]) + rng.normal(0.0, 0.01, (n, 3))
    t = np.arange(n) / rate_hz
    w[:, 2] += np.where((t > 2.0) & (t < 3.0), 1.5, 0.0)
    return w, f


# --------------------------------------------------------------------------
# A sample counter


def _counter_csv(path: Path, counter, w, f, preamble: str = "") -> Path:
    rows = [
        f"{c},{','.join(repr(math.degrees(x)) for x in wi)},{','.join(repr(float(x)) for x in fi)}"
        for c, wi, fi in zip(counter, w, f, strict=True)
    ]
    return _write(path, preamble + "n_samples,gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z\n" + "\n".join(rows) + "\n")


@pytest.mark.parametrize("name", ["log.csv", "log.csv.gz"])
def test_a_counter_at_a_stated_rate_is_the_time_base(tmp_path, name):
    rate = 102.4
    w, f = _si_signals(600, rate)
    path = _counter_csv(tmp_path / name, range(7, 607), w, f)
    run = read_run(path, columns=FERRARIS_MAP, sample_rate_hz=rate, **SITE)
    assert run.n_samples == 600 and run.sample_rate_hz == rate
    np.testing.assert_allclose(
        run.time_s, np.arange(1, 601) / rate, rtol=0, atol=1e-12
    )  # end of each interval
    np.testing.assert_allclose(run.dtheta_rad, w / rate, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(run.dv_mps, f / rate, rtol=1e-12)
    assert run.clipped is None and run.conversion is None
    # The rate may be a metadata line instead.
    lined = _counter_csv(tmp_path / "lined.csv", range(600), w, f, "# sample_rate_hz: 102.4\n")
    np.testing.assert_array_equal(read_run(lined, columns=FERRARIS_MAP, **SITE).time_s, run.time_s)


def test_a_counter_without_a_rate_is_refused(tmp_path):
    w, f = _si_signals(50, 100.0)
    path = _counter_csv(tmp_path / "log.csv", range(50), w, f)
    line = _refusal(path, *SITE_CLI, "--columns", FERRARIS_MAP)
    assert (
        "sample counter" in line
        and "--sample-rate-hz" in line
        and "log.csv, line 2, column n_samples" in line
    )
    with pytest.raises(CalibError, match="sample_rate_hz"):
        read_run(path, columns=FERRARIS_MAP, **SITE)


@pytest.mark.parametrize(
    ("counter", "line", "said"),
    [
        ([0, 1, 2.5, 3, 4, 5], 4, "not a whole number"),
        ([0, 1, 2, 2, 3, 4], 5, "does not increase: 2 follows 2"),
        ([0, 1, 2, 5, 6, 7], 5, "jumps from 2 to 5: 2 sample(s) dropped"),
    ],
)
def test_a_bad_counter_is_refused_naming_the_row(tmp_path, counter, line, said):
    w, f = _si_signals(len(counter), 100.0)
    path = _counter_csv(tmp_path / "log.csv", counter, w, f)
    text = _refusal(path, *SITE_CLI, "--columns", FERRARIS_MAP, "--sample-rate-hz", "100")
    assert said in text and f"log.csv, line {line}, column n_samples" in text, text


def test_a_counter_that_jumps_at_rest_is_filled_with_allow_gaps(tmp_path):
    w, f = _si_signals(400, 100.0)
    w[:, 2] = 0.0  # at rest throughout
    w *= 0.01
    counter = np.r_[np.arange(300), np.arange(301, 401)]
    path = _counter_csv(tmp_path / "log.csv", counter, w, f)
    run = read_run(path, columns=FERRARIS_MAP, sample_rate_hz=100.0, allow_gaps=True, **SITE)
    assert run.n_samples == 401 and run.clock.dropped == [(pytest.approx(3.01), 1)]


def test_a_time_column_that_counts_samples_is_refused(tmp_path):
    w, f = _si_signals(1200, 100.0)
    path = _counter_csv(tmp_path / "log.csv", range(1200), w, f)
    mapped = FERRARIS_MAP.replace("=counter", "=time_s")
    for flags in (["--sample-rate-hz", "100"], []):  # a stated rate, or a log too long for 1 Hz
        line = _refusal(path, *SITE_CLI, "--columns", mapped, *flags)
        assert "steps by exactly 1 s" in line and "looks like a sample counter" in line, line
        assert "n_samples=counter" in line and "--sample-rate-hz" in line
    # A stated 1 Hz is believed.
    run = read_run(path, columns=mapped, sample_rate_hz=1.0, **SITE)
    assert run.sample_rate_hz == 1.0


# --------------------------------------------------------------------------
# Raw counts and their conversion


@pytest.mark.parametrize("kind", ["nominal.txt", "nominal.txt.gz", "conversion.toml"])
def test_both_conversion_formats_read_the_same(tmp_path, kind):
    text = CONVERSION_TOML if kind.endswith(".toml") else NOMINAL_TEXT
    conversion = read_conversion(_write(tmp_path / kind, text))
    for sensor in ("gyro", "accel"):
        np.testing.assert_array_equal(conversion.zero_counts[sensor], ZERO[sensor])
        np.testing.assert_array_equal(conversion.counts_per_unit[sensor], SCALE[sensor])
    assert conversion.gravity_mps2 == 9.81744 and conversion.range_counts == (0.0, 65535.0)
    if kind.startswith("nominal"):
        assert (
            conversion.misalignment["gyro"][1, 2] == 0.04 and conversion.misalignment["accel"][2, 0] == 0.02
        )


def test_a_toml_may_state_its_scale_in_deg_per_s(tmp_path):
    text = CONVERSION_TOML.replace('unit = "rad/s"', 'unit = "deg/s"')
    conversion = read_conversion(_write(tmp_path / "c.toml", text))
    np.testing.assert_allclose(conversion.counts_per_unit["gyro"], SCALE["gyro"] * 180 / math.pi)


@pytest.mark.parametrize(
    ("kind", "text", "said"),
    [
        ("c.txt", NOMINAL_TEXT.replace("DS_g_scale", "# DS_g_scale"), "lacks DS_g_scale"),
        ("c.txt", NOMINAL_TEXT.replace("diag(415, 413, 415)", "diag(415, 413)"), "line 4"),
        (
            "c.txt",
            NOMINAL_TEXT.replace("(counts per rad/s)", "(counts per deg/s)"),
            "not in (counts per rad/s)",
        ),
        ("c.txt", NOMINAL_TEXT + "what is this\n", "line 8"),
        ("c.toml", CONVERSION_TOML.replace("[accel]", "[acel]"), "did you mean 'accel'"),
        ("c.toml", CONVERSION_TOML.replace("[accel]", "[other]"), "missing table [accel]"),
        ("c.toml", CONVERSION_TOML.replace("[4778, 4758, 4766]", "[4778, 4758]"), "counts_per_unit"),
        ("c.toml", CONVERSION_TOML.replace("zero_counts = [33123", "zero_count = [33123"), "did you mean"),
        ("c.toml", CONVERSION_TOML.replace("[4778, 4758, 4766]", "[4778, 0, 4766]"), "zero"),
        # A file-wide key inside a sensor's table would be ignored (its default taken), and the
        # reverse: each refused, saying where it belongs.
        (
            "c.toml",
            CONVERSION_TOML.replace('unit = "rad/s"', 'unit = "rad/s"\nrange_counts = [-32768, 32767]'),
            "range_counts is written inside [gyro]",
        ),
        ("c.toml", 'unit = "rad/s"\n' + CONVERSION_TOML, "unit is written above the tables"),
    ],
)
def test_a_bad_conversion_file_is_refused_naming_the_place(tmp_path, kind, text, said):
    path = _write(tmp_path / kind, text)
    with pytest.raises(CalibError) as info:
        read_conversion(path)
    assert said in info.value.message and str(path) in info.value.message
    assert info.value.fix


def _counts_csv(path: Path, rate_hz: float, w, f, clip_at: int | None = None) -> Path:
    counts = {
        "gyro": np.rint(w * SCALE["gyro"] + ZERO["gyro"]),
        "accel": np.rint(f * SCALE["accel"] + ZERO["accel"]),
    }
    if clip_at is not None:
        counts["gyro"][clip_at : clip_at + 4, 0] = 65535.0
    rows = [
        f"{k},{','.join(f'{x:.0f}' for x in g)},{','.join(f'{x:.0f}' for x in a)}"
        for k, (g, a) in enumerate(zip(counts["gyro"], counts["accel"], strict=True))
    ]
    return _write(path, "c,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")


def test_counts_read_back_to_the_si_values_they_were_made_of(tmp_path):
    rate = 100.0
    w, f = _si_signals(500, rate)
    path = _counts_csv(tmp_path / "log.csv", rate, w, f)
    conversion = read_conversion(_write(tmp_path / "c.toml", CONVERSION_TOML))
    run = read_run(path, columns=COUNTS_MAP, sample_rate_hz=rate, conversion=conversion, **SITE)
    # Within half a count of the values the counts were made of.
    assert np.all(np.abs(run.dtheta_rad * rate - w) <= 0.5 / SCALE["gyro"] + 1e-12)
    assert np.all(np.abs(run.dv_mps * rate - f) <= 0.5 / SCALE["accel"] + 1e-12)
    assert run.conversion is conversion and run.clipped is None
    assert run.meta["conversion_gyro_counts_per_unit"] == "4778.0 4758.0 4766.0 per rad/s"
    assert run.meta["conversion_accel_zero_counts"] == "33123.0 33276.0 32360.0"
    # ... and a result can be told back in counts.
    np.testing.assert_allclose(
        conversion.to_counts(run.dv_mps * rate, "accel"), np.rint(f * SCALE["accel"] + ZERO["accel"])
    )


def test_counts_beyond_the_converters_range_are_refused_as_a_signed_converter_not_clipped(tmp_path):
    # A signed converter's counts (zero at 0) read under the unsigned default range [0, 65535]:
    # every negative count would pass for clipped. A count beyond the range cannot be the
    # converter's: refused, naming the first and the signed range to give.
    rate = 100.0
    w, f = _si_signals(500, rate)
    text = CONVERSION_TOML.replace("[32768, 32466, 32485]", "[0, 0, 0]").replace(
        "[33123, 33276, 32360]", "[0, 0, 0]"
    )
    conversion = read_conversion(_write(tmp_path / "c.toml", text))
    assert not conversion.zero_counts["gyro"].any() and not conversion.zero_counts["accel"].any()
    counts = {"gyro": np.rint(w * SCALE["gyro"]), "accel": np.rint(f * SCALE["accel"])}
    rows = [
        f"{k},{','.join(f'{x:.0f}' for x in g)},{','.join(f'{x:.0f}' for x in a)}"
        for k, (g, a) in enumerate(zip(counts["gyro"], counts["accel"], strict=True))
    ]
    path = _write(tmp_path / "log.csv", "c,gx,gy,gz,ax,ay,az\n" + "\n".join(rows) + "\n")
    assert min(counts["gyro"].min(), counts["accel"].min()) < 0  # the premise: negative counts
    with pytest.raises(CalibError) as info:
        read_run(path, columns=COUNTS_MAP, sample_rate_hz=rate, conversion=conversion, **SITE)
    assert "beyond the conversion's range_counts [0, 65535]" in info.value.message
    assert "signed" in info.value.message and "range_counts = [-32768, 32767]" in info.value.fix
    # Given the signed range at the file's top, the same log reads.
    wide = read_conversion(_write(tmp_path / "s.toml", "range_counts = [-32768, 32767]\n" + text))
    run = read_run(path, columns=COUNTS_MAP, sample_rate_hz=rate, conversion=wide, **SITE)
    assert run.clipped is None or not run.clipped[:, 3:].any()


def test_counts_without_a_conversion_and_a_conversion_without_counts_are_refused(tmp_path):
    w, f = _si_signals(200, 100.0)
    path = _counts_csv(tmp_path / "log.csv", 100.0, w, f)
    line = _refusal(path, *SITE_CLI, "--columns", COUNTS_MAP, "--sample-rate-hz", "100")
    assert "raw counts" in line and "--conversion FILE" in line, line
    conversion = _write(tmp_path / "c.toml", CONVERSION_TOML)
    si = _counter_csv(tmp_path / "si.csv", range(200), w, f)
    line = _refusal(
        si, *SITE_CLI, "--columns", FERRARIS_MAP, "--sample-rate-hz", "100", "--conversion", conversion
    )
    assert "no column is in raw counts" in line, line
    mixed = COUNTS_MAP.replace("gz=gyro_z_counts", "gz=gyro_z_dps")
    line = _refusal(
        path, *SITE_CLI, "--columns", mixed, "--sample-rate-hz", "100", "--conversion", conversion
    )
    assert "mixes raw counts and SI units" in line, line


# --------------------------------------------------------------------------
# imu_tk's two files


def _imutk_files(tmp_path: Path, n: int = 800, suffix: str = "", seed: int = 1):
    rate = 100.0
    w, f = _si_signals(n, rate, seed)
    rng = np.random.default_rng(seed)
    t = 0.03 + np.arange(n) / rate + rng.uniform(-0.4e-3, 0.4e-3, n)  # a host clock's jitter
    gyro = np.rint(w * SCALE["gyro"] + ZERO["gyro"])
    acc = np.rint(f * SCALE["accel"] + ZERO["accel"])
    table = lambda x: (
        "\n".join(f"   {ti:.7e}" + "".join(f"   {v:.7e}" for v in row) for ti, row in zip(t, x, strict=True))
        + "\n"
    )  # noqa: E731
    acc_path = _write(tmp_path / f"acc.mat{suffix}", table(acc))
    gyro_path = _write(tmp_path / f"gyro.mat{suffix}", table(gyro))
    return acc_path, gyro_path, w, f, t


@pytest.mark.parametrize("suffix", ["", ".gz"])
def test_imu_tk_two_files_read_into_one_run(tmp_path, suffix):
    acc, gyro, w, f, t = _imutk_files(tmp_path, suffix=suffix)
    conversion = _write(tmp_path / "nominal.txt", NOMINAL_TEXT)
    run = read_run(acc, gyro_path=gyro, conversion=conversion, **SITE)
    assert run.n_samples == len(t) and run.meta["source_format"] == "imu_tk"
    period = run.dt_nominal
    assert run.sample_rate_hz == pytest.approx(100.0, rel=1e-4)
    # The stamps' jitter is measured and does not enter the increments.
    assert 0.1e-3 < run.clock.jitter_rms_s < 0.3e-3
    np.testing.assert_allclose(np.diff(run.time_s), period, rtol=1e-9)
    assert np.all(np.abs(run.dtheta_rad / period - w) <= 0.5 / SCALE["gyro"] + 1e-12)
    assert np.all(np.abs(run.dv_mps / period - f) <= 0.5 / SCALE["accel"] + 1e-12)
    assert run.conversion is not None and run.conversion.gravity_mps2 == 9.81744


def test_imu_tk_refusals_name_the_files_and_rows(tmp_path):
    acc, gyro, _, _, t = _imutk_files(tmp_path)
    conversion = _write(tmp_path / "nominal.txt", NOMINAL_TEXT)
    flags = [*SITE_CLI, "--gyro-file", gyro]
    line = _refusal(acc, *flags)
    assert "raw counts" in line and "--conversion FILE" in line, line
    line = _refusal(acc, "--gyro-file", gyro, "--conversion", conversion)
    assert "do not say the site" in line and "--latitude" in line, line
    # Files of two recordings (no common time) are refused naming both.
    rows = gyro.read_text().splitlines()
    later = [f"{float(r.split()[0]) + 100.0:.7e} " + " ".join(r.split()[1:]) for r in rows]
    apart = _write(tmp_path / "gyro_later.mat", "\n".join(later) + "\n")
    line = _refusal(acc, *SITE_CLI, "--gyro-file", apart, "--conversion", conversion)
    assert "do not overlap" in line and "acc.mat" in line and "gyro_later.mat" in line, line
    rows[7] = "  1.0   2.0   x"
    broken = _write(tmp_path / "gyro_broken.mat", "\n".join(rows) + "\n")
    line = _refusal(acc, *SITE_CLI, "--gyro-file", broken, "--conversion", conversion)
    assert "gyro_broken.mat, line 8" in line and "not four numbers" in line, line


def test_the_cli_takes_the_conversion_files_gravity_and_names_clipping(tmp_path):
    acc, gyro, _, _, _ = _imutk_files(tmp_path, n=300)
    rows = gyro.read_text().splitlines()
    for k in range(100, 104):  # the x gyro at the converter's top
        fields = rows[k].split()
        fields[1] = "6.5535000e+04"
        rows[k] = "   ".join(fields)
    _write(gyro, "\n".join(rows) + "\n")
    conversion = _write(tmp_path / "nominal.txt", NOMINAL_TEXT)
    code, output = _invoke(
        "calibrate",
        acc,
        "-o",
        tmp_path / "r.toml",
        *SITE_CLI,
        "--gyro-file",
        gyro,
        "--conversion",
        conversion,
    )
    assert "gravity: 9.81744 m/s^2, the local gravity the conversion file" in output, output
    assert "warning: gyro x clipped from" in output and "(4 samples)" in output, output
    code2, output2 = _invoke(
        "calibrate",
        acc,
        "-o",
        tmp_path / "r.toml",
        *SITE_CLI,
        "--gyro-file",
        gyro,
        "--conversion",
        conversion,
        "--gravity",
        "9.81",
    )
    assert "gravity: 9.81744" not in output2


def test_the_stream_reader_refuses_the_hand_options(tmp_path):
    acc, gyro, _, _, _ = _imutk_files(tmp_path, n=50)
    line = _refusal(acc, *SITE_CLI, "--gyro-file", gyro, "--stream")
    assert "read whole" in line


# --------------------------------------------------------------------------
# Clipping and the gimbal's rate check


def test_clipping_counts_at_the_converter_limit_and_flat_tops():
    n = 200
    rate = np.zeros((n, 3))
    rate[50:60, 1] = np.linspace(0, 6, 10)
    rate[60:63, 1] = 7.0  # a flat top above 5 rad/s
    mask = flat_top(rate)
    assert mask[60:63, 1].all() and mask.sum() == 3
    rate[60:63, 1] = [6.99, 7.0, 6.98]  # a peak, not a top
    assert not flat_top(rate).any()
    slow = rate * 0.5  # below 5 rad/s a flat top counts when ramps border it (a gyro of small range)
    slow[60:63, 1] = 3.5
    assert flat_top(slow)[60:63, 1].all() and flat_top(slow).sum() == 3
    gimbal = rate * 0.2  # below 1.5 rad/s (86 deg/s) no top is judged: a gimbal's flips stay there
    gimbal[60:63, 1] = 1.4
    assert not flat_top(gimbal).any()
    clipped = np.zeros((n, 6), dtype=bool)
    clipped[10:15, 0] = True
    clipped[100:101, 4] = True
    time = 0.01 * np.arange(1, n + 1)
    stretches = clipped_stretches(clipped, time)
    assert [s.describe() for s in stretches] == [
        "gyro x clipped from 0.11 s to 0.15 s (5 samples)",
        "accel y clipped from 1.01 s to 1.01 s (1 sample)",
    ]


def test_a_smooth_peak_printed_in_whole_deg_per_s_is_no_flat_top_and_a_saturated_one_is():
    # A hand's 361 deg/s turn (a half sine over T = 0.5 s, 200 Hz) printed in whole deg/s stays
    # within a step of its top for 2 sqrt(q / k) = 24 ms (k = P pi^2 / (2 T^2), its curvature
    # there), so its rounding repeats the peak over 3-5 samples, as a real gesture-calibration
    # log does (360, 361, 361, 361, 361, 359): not the converter, whose neighbours would climb.
    # The same turn saturating at 300 deg/s repeats 300 while the ramps beside it climb by
    # 4-5 deg/s a sample: clipped (with the ramp's samples within 1 % of the top, the plateau's).
    t = np.arange(0.0, 1.5, 1.0 / 200.0)
    turn = np.where((t > 0.5) & (t < 1.0), np.sin(np.pi * (t - 0.5) / 0.5), 0.0)
    dps = np.zeros((t.size, 3))
    dps[:, 0] = np.round(361.4 * turn)
    assert (dps[:, 0] == 361).sum() >= 3  # the rounding repeats the top
    assert not flat_top(np.radians(dps)).any()
    dps[:, 0] = np.round(np.minimum(361.4 * turn, 300.0))
    mask = flat_top(np.radians(dps))
    assert np.all(mask[dps[:, 0] == 300, 0]) and np.all(dps[mask[:, 0], 0] >= 297) and not mask[:, 1:].any()


@pytest.mark.parametrize("rate_hz", [100.0, 400.0, 1000.0])
def test_a_smooth_fast_turn_is_no_plateau_and_the_same_turn_saturated_is_one(rate_hz):
    # A hand's 600 deg/s turn lasting 0.6 s (rate a half sine) on a unit with 0.2 deg/s of
    # rate noise a sample. Its top stays within 1 % of its peak for 9 % of the turn: 5-54
    # samples at these rates, which a count of samples called clipped (the old rule set off
    # a move's worth of "clipping" on simulated runs that had none).
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 2.0, 1.0 / rate_hz)
    turn = np.where((t > 0.7) & (t < 1.3), np.sin(np.pi * (t - 0.7) / 0.6), 0.0)
    peak = math.radians(600.0)
    rate = np.zeros((t.size, 3))
    rate[:, 2] = peak * turn + math.radians(0.2) * rng.standard_normal(t.size)
    assert not flat_top(rate).any()
    # The same turn through a sensor that saturates at 500 deg/s, its noise on top: a
    # plateau entered and left on the turn's flanks, flagged over the saturated stretch.
    saturated = rate.copy()
    limit = math.radians(500.0)
    over = peak * turn > limit
    saturated[over, 2] = limit + math.radians(0.2) * rng.standard_normal(over.sum())
    mask = flat_top(saturated)[:, 2]
    # Every saturated sample (its noise, 0.2 deg/s, is far inside the 5 deg/s band), and
    # beside them only the flanks' samples already within the band of the limit.
    assert mask[over].all()
    assert not mask[peak * turn < 0.98 * limit].any()


def _quantized(rate_dps: np.ndarray, lsb_per_dps: float) -> np.ndarray:
    """A 16-bit gyro's reading in rad/s: rounded to its count, held at the range's ends."""
    counts = np.clip(np.round(rate_dps * lsb_per_dps), -32768, 32767)
    return np.radians(counts / lsb_per_dps)


@pytest.mark.parametrize("rate_hz", [100.0, 400.0, 1000.0])
def test_a_low_range_gyro_clipping_a_hand_turn_is_found_and_its_smooth_or_steady_tops_are_not(rate_hz):
    # A hand's 200 deg/s turn (half sine, 0.6 s) read by a 16-bit gyro of range 125 deg/s
    # (262 counts per deg/s, as BMI160-class parts at their smallest range), 0.1 deg/s of
    # noise a sample: the converter repeats its last count over the cut top, 125 deg/s
    # (2.18 rad/s), below the 286 deg/s from which any flat top was taken as clipping.
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 2.0, 1.0 / rate_hz)
    turn = np.where((t > 0.7) & (t < 1.3), np.sin(np.pi * (t - 0.7) / 0.6), 0.0)
    true_dps = np.zeros((t.size, 3))
    true_dps[:, 0] = 200.0 * turn + 0.1 * rng.standard_normal(t.size)
    cut = _quantized(true_dps, 262.0)
    over = true_dps[:, 0] * 262.0 >= 32767  # the samples the converter held at its end
    assert over.sum() >= 2
    assert np.array_equal(flat_top(cut)[:, 0], over)
    # The same turn on the 250 deg/s range (131 counts per deg/s): its smooth top in noise
    # repeats no count at its peak with a ramp on both sides.
    assert not flat_top(_quantized(true_dps, 131.0)).any()
    # A steady 120 deg/s turn (a rate table, entered in one sample) read coarsely (16.4
    # counts per deg/s, its rate half-way between two counts, noise a tenth of a count): its
    # top repeats its highest count over and over, but inside a plateau that no ramp
    # borders on both sides. It is no clipping.
    steady = np.zeros((t.size, 3))
    level = (1968.5 / 16.4) * ((t > 0.5) & (t < 1.5))
    steady[:, 1] = level + (0.1 / 16.4) * rng.standard_normal(t.size)
    coarse = _quantized(steady, 16.4)
    at_top = coarse[:, 1] == coarse[:, 1].max()
    assert np.any(at_top[1:] & at_top[:-1])  # the case a bare flat top would flag
    assert not flat_top(coarse).any()


def test_the_gimbal_rate_check_is_the_callers():
    dt = np.full(10, 0.01)
    dtheta = np.zeros((10, 3))
    dtheta[5, 0] = 0.11  # 11 rad/s
    with pytest.raises(sanity.GyroUnitError, match="beyond any gimbal"):
        sanity.check_rates(dtheta, dt, "run")
    sanity.check_rates(dtheta, dt, "run", max_rate_rad_s=None)
    sanity.check_rates(dtheta, dt, "run", max_rate_rad_s=12.0)
    conversion = Conversion(ZERO, SCALE)
    assert conversion.max_rate_rad_s == pytest.approx(11.84, abs=0.01)


# --------------------------------------------------------------------------
# The real recordings


@pytest.fixture(scope="module")
def xsens():
    return read_run(
        XSENS / "xsens_acc.mat.gz",
        gyro_path=XSENS / "xsens_gyro.mat.gz",
        conversion=XSENS / "xsens-nominal-values.txt",
        **SITE,
    )


def test_the_xsens_recording_reads_as_it_is(xsens):
    assert xsens.n_samples == 51175
    assert xsens.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    period = xsens.dt_nominal
    still = xsens.time_s < 50.0  # the first ~52 s are static
    f = xsens.dv_mps[still].mean(axis=0) / period
    w = xsens.dtheta_rad[still].mean(axis=0) / period
    assert np.linalg.norm(f) == pytest.approx(9.81, abs=0.05)
    assert np.all(np.abs(w) < 0.01)  # rad/s: bias and Earth rate only
    assert xsens.conversion.gravity_mps2 == 9.81744
    lines = describe_clipping(xsens)
    assert lines and all(line.startswith(("gyro x", "gyro y")) for line in lines), lines
    stretches = clipped_stretches(xsens.clipped, xsens.time_s)
    assert min(s.start_s for s in stretches) > 505.0  # the fast motion at the very end
    assert any(s.channel == "gyro x" and s.end_s > 511.0 for s in stretches)
    # The gimbal's check refuses it; the range the conversion gives lets it through.
    rate_dt = np.full(xsens.n_samples, period)
    with pytest.raises(sanity.GyroUnitError):
        sanity.check_rates(xsens.dtheta_rad, rate_dt, "xsens")
    sanity.check_rates(xsens.dtheta_rad, rate_dt, "xsens", xsens.conversion.max_rate_rad_s)


def test_the_ferraris_recording_reads_at_its_counters_rate():
    run = read_run(FERRARIS, columns=FERRARIS_MAP, sample_rate_hz=102.4, **SITE)
    assert run.n_samples == 10376 and run.sample_rate_hz == 102.4
    assert run.time_s[-1] == pytest.approx(10376 / 102.4)
    assert run.clipped is None  # 15.8 rad/s, within a BMI160's range, is no flat top
    faces = json.loads((FERRARIS.parent / "example_ferraris_session_list.json").read_text())
    f = run.dv_mps / run.dt_nominal

    def mean(name):
        return f[faces[name]["start"] : faces[name]["end"]].mean(axis=0)

    assert np.linalg.norm(mean("x_p")) == pytest.approx(9.81, rel=0.06)  # the first static face, raw
    for axis, name in enumerate("xyz"):  # up and down: the biases cancel, g is left
        assert (mean(f"{name}_p") - mean(f"{name}_a"))[axis] / 2 == pytest.approx(
            9.81, rel=0.03
        )  # z: 10.04, its scale error
