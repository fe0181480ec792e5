"""Logger files as a new user brings them, through the CLI: time units, column maps, units, static logs.

Each case first builds the file the issue describes (a simulated run written as
a logger writes it, or a static MEMS log), then checks what the tool says.
"""

from __future__ import annotations

import json
import math
import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from realdata import REPO

from calib.errors import CalibError
from calib.fit.sanity import GyroUnitError, explain_gyro_unit
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.earth import RATE as W_EARTH
from calib.noise.profiles import load_profile
from calib.runlog import Run, make_meta, read_run, write_run
from calib.runlog.csv import time_in_seconds
from calib.sequence.definition import sequence_from_dict
from calib.sequence.kinematics import SimConfig
from calib.sequence.motion import check_sequence_matches
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.cli import main

RATE_HZ = 100.0
LAT_DEG = 51.08
SITE = ["--latitude", str(LAT_DEG), "--height", "0"]
STEPS = [("Z", 90), ("Y", 90), ("X", -90), ("Y", -90), ("Y", -90), ("X", -90), ("Y", -90), ("Z", 90)]
OUR_NAMES = "time_s,gyro_x_radps,gyro_y_radps,gyro_z_radps,accel_x_mps2,accel_y_mps2,accel_z_mps2"
TICKS = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9}


def _sequence(rate_dps: float = 10.0):
    doc = {
        "name": "short",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 20.0,
        "step": [{"axis": a, "angle_deg": g, "dwell_s": 20.0, "rate_dps": rate_dps} for a, g in STEPS],
    }
    return sequence_from_dict(doc, "short")


def _simulate(rate_dps: float = 10.0) -> Run:
    run, _ = simulate(
        _sequence(rate_dps),
        SimConfig(latitude_rad=math.radians(LAT_DEG), sample_rate_hz=RATE_HZ),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians([1.0, -2.0, 3.0]), noise=True, seed=3),
    )
    return run


@pytest.fixture(scope="module")
def run() -> Run:
    """A noisy navigation-grade run of nine positions at 100 Hz (252 s)."""
    return _simulate()


def write_logger(
    path: Path,
    run: Run,
    time_unit: str = "s",
    rate_scale: float = 1.0,
    header: str = OUR_NAMES,
    preamble: str = "",
    integer_time: bool = False,
) -> Path:
    """``run`` as a logger writes it: rates and specific force, time in ``time_unit``.

    The numbers are rad/s and m/s^2 scaled by ``rate_scale`` on the gyro (180/pi
    writes deg/s), whatever the ``header`` says they are.
    """
    dt = 1.0 / RATE_HZ
    if integer_time:  # the run's stamps are whole periods: exact integer ticks
        stamps = [str(int(round(t * RATE_HZ)) * (TICKS[time_unit] // int(RATE_HZ))) for t in run.time_s]
    else:
        stamps = [repr(float(t)) for t in run.time_s * TICKS[time_unit]]
    table = np.hstack([run.dtheta_rad / dt * rate_scale, run.dv_mps / dt])
    rows = (",".join([s, *map(repr, values)]) for s, values in zip(stamps, table.tolist(), strict=True))
    path.write_text(preamble + header + "\n" + "\n".join(rows) + "\n")
    return path


def _invoke(*args: str):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    return result


def _calibrate(path: Path, *flags: str) -> dict:
    result = _invoke("calibrate", path, "-o", path.with_suffix(".result.toml"), "--json", *SITE, *flags)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def _refusal(path: Path, *flags: str) -> str:
    out = path.with_suffix(".result.toml")
    result = _invoke("calibrate", path, "-o", out, *flags)
    assert result.exit_code == 2, result.output
    assert not out.exists()
    return result.output.strip().splitlines()[-1]


def _values(doc: dict) -> np.ndarray:
    return np.array([doc["parameters"][name]["value"] for name in P.NAMES])


# --------------------------------------------------------------------------
# Time units


@pytest.fixture(scope="module")
def in_seconds(run, tmp_path_factory) -> dict:
    return _calibrate(write_logger(tmp_path_factory.mktemp("s") / "log.csv", run))


@pytest.mark.parametrize("unit", ["ms", "us", "ns"])
def test_time_in_ms_us_ns_is_converted_not_refused(run, in_seconds, tmp_path, unit):
    # The issue: `time_ms` was refused ("the time unit must be s"). The same run with its
    # time in ms, us or ns is the same run: the same samples, rate and estimates.
    header = OUR_NAMES.replace("time_s", f"time_{unit}")
    path = write_logger(tmp_path / "log.csv", run, unit, header=header, integer_time=unit != "ms")
    read = read_run(path, latitude_deg=LAT_DEG, height_m=0.0)
    assert read.sample_rate_hz == RATE_HZ
    np.testing.assert_allclose(read.time_s, run.time_s, rtol=0, atol=1e-12)
    doc = _calibrate(path)
    sigma = np.array([in_seconds["parameters"][n]["sigma"] for n in P.NAMES])
    assert np.all(np.abs(_values(doc) - _values(in_seconds)) < 1e-6 * sigma)


def test_integer_ns_stamps_are_rounded_once():
    # Epoch-sized ns stamps: a float of ns already rounds (to 256 ns) before the division
    # rounds again; whole seconds and the rest in integers keep every stamp within one
    # float spacing of its exact value in s.
    stamps = 1_700_000_000_123_456_789 + 10_000_001 * np.arange(2000, dtype=np.int64)
    rows = [f"{s},0" for s in stamps.tolist()]
    time_s = time_in_seconds(stamps.astype(float), rows, 0, 10**9, "t", str)
    exact = np.array([float(Fraction(int(s), 10**9)) for s in stamps])
    assert np.all(np.abs(time_s - exact) <= np.spacing(exact))
    through_float = stamps.astype(float) / 1e9
    assert np.abs(through_float - exact).max() > np.abs(time_s - exact).max()


def test_ms_in_a_column_named_time_s_is_named_without_a_rate(run, tmp_path):
    # The issue: milliseconds in `time_s` were diagnosed as a short first rest.
    line = _refusal(write_logger(tmp_path / "log.csv", run, "ms"), *SITE)
    assert "time steps of 10 'seconds'" in line and "looks like milliseconds" in line, line
    assert "name it time_ms" in line
    assert "first rest" not in line and "not at rest" not in line


def test_ms_in_a_column_named_time_s_is_named_against_the_stated_rate(run, tmp_path):
    path = write_logger(tmp_path / "log.csv", run, "ms", preamble="# sample_rate_hz: 100\n")
    line = _refusal(path, *SITE)
    assert "time steps of 10 'seconds' at 100 Hz" in line and "looks like milliseconds" in line, line
    assert "name it time_ms" in line


def test_seconds_in_a_column_named_time_ms_are_named(run, tmp_path):
    header = OUR_NAMES.replace("time_s", "time_ms")
    line = _refusal(write_logger(tmp_path / "log.csv", run, "s", header=header), *SITE)
    assert "looks like seconds" in line and "name it time_s" in line, line


def test_an_unknown_time_unit_lists_the_known_ones(run, tmp_path):
    header = OUR_NAMES.replace("time_s", "time_min")
    line = _refusal(write_logger(tmp_path / "log.csv", run, header=header), *SITE)
    assert "'time_min'" in line and all(n in line for n in ("time_s", "time_ms", "time_us", "time_ns"))


# --------------------------------------------------------------------------
# Degrees per second in a column named rad/s


def test_deg_per_s_in_radps_columns_is_named_as_such(run, tmp_path):
    # The issue: the hint spoke of `dtheta` columns the file does not have. Flips at
    # 10 deg/s read as 10 rad/s.
    line = _refusal(write_logger(tmp_path / "log.csv", run, rate_scale=180 / math.pi), *SITE)
    assert "look like deg/s" in line and "gyro_x_dps, gyro_y_dps, gyro_z_dps" in line, line
    assert "dtheta" not in line


def test_deg_per_s_in_radps_columns_seen_at_the_first_rest(tmp_path):
    # Flips at 3 deg/s stay below any gimbal's rate when read as rad/s; the first rest then
    # turns at the Earth rate times 57 (plus the bias): beyond a navigation unit.
    slow = _simulate(rate_dps=3.0)
    line = _refusal(write_logger(tmp_path / "log.csv", slow, rate_scale=180 / math.pi), *SITE)
    assert "at the first rest" in line and "look like deg/s" in line, line
    assert "name them gyro_x_dps" in line and "dtheta" not in line


def test_deg_per_s_hint_follows_a_column_map():
    error = GyroUnitError("the gyros read 0.004 rad/s", "log.csv", "dtheta must be in rad", 4e-3, 1e-3)
    mapped = (("gx", "gyro_x_radps"), ("gy", "gyro_y_radps"), ("gz", "gyro_z_radps"))
    assert "map gx=gyro_x_dps,gy=gyro_y_dps,gz=gyro_z_dps" in explain_gyro_unit(error, mapped).message
    # Increments keep the increments' hint; so does a reading no unit makes plausible.
    increments = tuple((n, n) for n in ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad"))
    assert explain_gyro_unit(error, increments) is error
    wild = GyroUnitError("the gyros read 1 rad/s", "log.csv", "dtheta must be in rad", 1.0, 1e-3)
    fix = explain_gyro_unit(wild, mapped).fix
    assert "look like deg/s" not in fix and "dtheta" not in fix and "gx, gy, gz" in fix


# --------------------------------------------------------------------------
# The column map


MAP = (
    "t=time_s,gx=gyro_x_radps,gy=gyro_y_radps,gz=gyro_z_radps,ax=accel_x_mps2,ay=accel_y_mps2,az=accel_z_mps2"
)


def test_a_header_of_its_own_is_refused_then_read_with_columns(run, in_seconds, tmp_path):
    path = write_logger(tmp_path / "log.csv", run, header="t,gx,gy,gz,ax,ay,az")
    line = _refusal(path, *SITE)  # the issue: only "lacks column 'time_s'"
    assert "lacks column 'time_s'" in line and "column map" in line and "--columns" in line
    doc = _calibrate(path, "--columns", MAP)
    np.testing.assert_array_equal(_values(doc), _values(in_seconds))


def test_columns_give_the_unit_deg_per_s_and_ms(run, in_seconds, tmp_path):
    path = write_logger(
        tmp_path / "log.csv", run, "ms", rate_scale=180 / math.pi, header="t,gx,gy,gz,ax,ay,az"
    )
    columns = MAP.replace("time_s", "time_ms").replace("radps", "dps")
    doc = _calibrate(path, "--columns", columns)
    sigma = np.array([in_seconds["parameters"][n]["sigma"] for n in P.NAMES])
    assert np.all(np.abs(_values(doc) - _values(in_seconds)) < 1e-6 * sigma)


def test_library_reads_the_same_map_as_a_dict(run, tmp_path):
    path = write_logger(tmp_path / "log.csv", run, header="t,gx,gy,gz,ax,ay,az")
    as_dict = dict(item.split("=") for item in MAP.split(","))
    a = read_run(path, latitude_deg=LAT_DEG, height_m=0.0, columns=MAP)
    b = read_run(path, latitude_deg=LAT_DEG, height_m=0.0, columns=as_dict)
    np.testing.assert_array_equal(a.dtheta_rad, b.dtheta_rad)
    # rate * (t_k - t_{k-1}): the step of printed times is exact to ~1e-14 s of 0.01 s.
    np.testing.assert_allclose(a.dtheta_rad, run.dtheta_rad, rtol=1e-10, atol=1e-18)


@pytest.mark.parametrize(
    "columns, parts",
    [
        (MAP.replace("gx=", "gq="), ["'gq'", "header row does not have", "t, gx, gy"]),
        (
            MAP.replace("gyro_x_radps", "gyro_x_degps"),
            ["unknown name 'gyro_x_degps'", "gyro_{x,y,z}_{radps,dps,mdps}"],
        ),
        (
            MAP.replace("gyro_x_radps", "speed"),
            ["unknown name 'speed'", "time_ms", "accel_{x,y,z}_{mps2,g,mg}"],
        ),
        ("t:time_s", ["'t:time_s' is not FILE_NAME=OUR_NAME"]),
        (MAP + ",t=time_ms", ["'t' twice"]),
    ],
)
def test_bad_column_maps_are_refused_naming_the_item(run, tmp_path, columns, parts):
    path = write_logger(tmp_path / "log.csv", run, header="t,gx,gy,gz,ax,ay,az")
    line = _refusal(path, *SITE, "--columns", columns)
    for part in parts:
        assert part in line, line


def test_columns_refuse_what_has_no_header(run, tmp_path):
    write_run(run, tmp_path / "run.npz")
    assert "no header to rename" in _refusal(tmp_path / "run.npz", "--columns", MAP)
    path = write_logger(tmp_path / "log.csv", run, header="t,gx,gy,gz,ax,ay,az")
    assert "read whole" in _refusal(path, *SITE, "--columns", MAP, "--stream")


@pytest.mark.parametrize("command", [["calibrate"], ["view"], ["profile", "fit"]])
def test_columns_are_documented_on_each_command(command):
    result = _invoke(*command, "--help")
    assert result.exit_code == 0 and "--columns MAP" in result.output and "t=time_ms" in result.output


def test_view_takes_columns(run, tmp_path):
    pytest.importorskip("rerun")
    preamble = f"# latitude_deg: {LAT_DEG}\n# height_m: 0\n"
    path = write_logger(tmp_path / "log.csv", run, header="t,gx,gy,gz,ax,ay,az", preamble=preamble)
    assert "lacks column 'time_s'" in _invoke("view", path, "-o", tmp_path / "log.rrd").output
    result = _invoke("view", path, "-o", tmp_path / "log.rrd", "--columns", MAP)
    assert result.exit_code == 0, result.output
    assert (tmp_path / "log.rrd").stat().st_size > 0


# --------------------------------------------------------------------------
# A static log


def static_mems_run(bias_dps=(0.4, -0.4, -0.3), taps_s=(6.3,), seconds=120.0) -> Run:
    """A MEMS unit on a bench: Earth rate, a large bias, white noise; a bench tap or two.

    The bias (0.66 deg/s, an ADIS16405's) is above the flip threshold of 0.57 deg/s, as
    is its 1-s mean rate; a tap turns the unit by a fraction of a degree and back.
    """
    profile = load_profile("mems")
    rng = np.random.default_rng(7)
    n, dt = int(seconds * RATE_HZ), 1.0 / RATE_HZ
    lat = math.radians(LAT_DEG)
    # Body = ENU: the Earth rate and gravity as a level unit sees them.
    earth = W_EARTH * np.array([0.0, math.cos(lat), math.sin(lat)])
    rate = earth + np.radians(bias_dps) + profile.arw / math.sqrt(dt) * rng.standard_normal((n, 3))
    for t in taps_s:  # 0.2 s at 2 deg/s about x and back
        k = int(t * RATE_HZ)
        rate[k : k + 20, 0] += math.radians(2.0)
        rate[k + 20 : k + 40, 0] -= math.radians(2.0)
    force = np.array([0.0, 0.0, 9.81]) + profile.vrw / math.sqrt(dt) * rng.standard_normal((n, 3))
    time_s = (np.arange(n) + 1) * dt
    return Run(time_s=time_s, dtheta_rad=rate * dt, dv_mps=force * dt, meta=make_meta(LAT_DEG, 0.0, RATE_HZ))


def static_mems_log(path: Path, taps_s=(6.3,)) -> Path:
    """The static MEMS run through the run-log writer (imu-run/1 CSV)."""
    write_run(static_mems_run(taps_s=taps_s), path)
    return path


@pytest.mark.parametrize("taps_s", [(6.3,), ()])
def test_a_static_mems_log_is_named_static(tmp_path, taps_s):
    # The issue: "the first rest lasts 6.3 s, too short to align" (0.0 s without a tap).
    path = static_mems_log(tmp_path / "static.csv", taps_s=taps_s)
    for flags in (["--profile", "mems", "--requirements", "mems"], []):
        line = _refusal(path, *flags)
        assert "never rotates" in line and "static log" in line and "seqdesign profile fit" in line, line
        largest = float(re.search(r"largest rotation between rests ([0-9.e+-]+) deg", line).group(1))
        assert largest < 1.0  # a tap turns by 0.4 deg; noise by less
        assert "too short to align" not in line


def test_a_static_log_serves_profile_fit_with_its_own_header(tmp_path):
    # What the refusal above sends the user to, with a logger's header and a column map.
    path = write_logger(tmp_path / "static.csv", static_mems_run(taps_s=()), header="t,gx,gy,gz,ax,ay,az")
    fit = ["profile", "fit", path, "-o", tmp_path / "mine.toml", "--no-plot", "--json", *SITE]
    result = _invoke(*fit, "--columns", MAP)
    assert result.exit_code == 0, result.output
    # The white noise simulated is the mems profile's: the fit finds its ARW.
    arw = json.loads(result.stdout)["profile"]["gyro_arw_dph"]
    assert arw == pytest.approx(load_profile("mems").gyro_arw_dph, rel=0.2)


# --------------------------------------------------------------------------
# Library messages speak library terms


OWN = [
    "calib/sequence/motion.py",
    "calib/fit/sanity.py",
    "calib/fit/start.py",
    *map(str, Path("calib/runlog").glob("*.py")),
]


@pytest.mark.parametrize("name", OWN)
def test_reader_and_motion_messages_name_flags_only_as_the_clis(name):
    # A notebook user calls read_run(..., height_m=...): "give --height M" means nothing there.
    text = (REPO / name).read_text()
    strings = re.findall(r'"[^"\n]*"', text)
    bare = [s for s in strings if re.search(r"(?<!the CLI's )--[a-z]", s)]
    assert not bare, bare


def test_a_sequence_that_does_not_match_says_so_in_library_terms():
    seq = _sequence()
    dt = np.full(100, 0.01)
    detected = np.zeros(100, dtype=bool)
    detected[10:20] = True
    with pytest.raises(CalibError) as info:
        check_sequence_matches(seq, detected, np.zeros(100, dtype=bool), dt, "run")
    assert "--" not in info.value.message
