"""Fuzzing of every file reader: sequence, profile, errors/truth, run CSV/NPZ, result.

Each reader gets random and mutated input: truncated files, flipped, inserted and
deleted bytes, invalid UTF-8 and other encodings, numbers replaced by NaN/inf/huge
values/strings/booleans/arrays, deleted and renamed keys, unknown axes, flip
angles that are not multiples of 90 deg, random TOML documents built from
scratch, random NPZ archives (wrong shapes and dtypes, object arrays, missing
arrays, meta that is not JSON) and damaged zip bytes.

The contract checked on every case: the reader either returns a valid object
(finite numbers, right shapes) or raises the tool's own ``CalibError`` whose
message names the file. Anything else escaping is a bug. The CLI checks run a
handful of mutated files per reader through ``seqdesign`` and require exit code
0 or 2, no traceback, and no output file left behind after a refusal.

The budget is fixed (about 35 s in all) and the examples are derandomized, so a
given commit runs the same cases on every CI run. (Hypothesis also seeds its
choices with literals from the project's loaded modules, so the file run alone
and the whole suite try different, equally reproducible, cases.) Set
``SEQDESIGN_FUZZ_SCALE=10`` to try ten times as many cases locally and
``SEQDESIGN_FUZZ_RANDOM=1`` to draw fresh ones; ``--hypothesis-show-statistics``
shows the outcomes per test, and the module prints the cases tried per reader.
"""

from __future__ import annotations

import copy
import io
import itertools
import json
import math
import os
import re
import tomllib
import warnings
import zipfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from click.testing import CliRunner
from hypothesis import HealthCheck, event as _hypothesis_event, given, settings, strategies as st
from hypothesis.control import currently_in_test_context

from calib.calibration.result import CalibrationResult
from calib.errors import CalibError
from calib.gimbal.encoders import rest_positions
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.nav.transform import DIRECTIONS, attitude_from_directions, rotvec_to_dcm
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import Run, make_meta, read_run, write_run
from calib.sequence.definition import Sequence, load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import Truth, simulate
from calib.sim.truth import read_errors, read_truth, write_truth
from seqdesign.cli import main
from seqdesign.search.graph import attitude_of, flip_graph, parse_node

REPO = Path(__file__).resolve().parents[1]
SCALE = float(os.environ.get("SEQDESIGN_FUZZ_SCALE", "1"))
FRESH = os.environ.get("SEQDESIGN_FUZZ_RANDOM", "") not in ("", "0")


def budget(n: int, **extra) -> settings:
    """A fixed, reproducible budget of ``n`` examples (times SEQDESIGN_FUZZ_SCALE).

    CI runs the same derandomized cases every time; SEQDESIGN_FUZZ_RANDOM=1 draws
    fresh ones (for exploring locally; a failure prints the seed to reproduce it).
    """
    return settings(
        max_examples=max(1, int(n * SCALE)),
        deadline=None,
        derandomize=not FRESH,
        database=None,
        print_blob=False,
        suppress_health_check=[
            HealthCheck.too_slow,
            HealthCheck.data_too_large,
            HealthCheck.filter_too_much,
            HealthCheck.function_scoped_fixture,
        ],
        **extra,
    )


# Cases tried per reader and outcome, printed at the end of the module.
TALLY: dict[str, Counter] = {}
_current_kind = ["?"]


def event(label: str) -> None:
    """Count an outcome for the report, and for hypothesis' statistics when inside a test."""
    TALLY.setdefault(_current_kind[0], Counter())[label] += 1
    if currently_in_test_context():
        _hypothesis_event(label)


@pytest.fixture(scope="module", autouse=True)
def report_tally(request):
    yield
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    if reporter is None or capture is None:
        return
    with capture.global_and_fixture_disabled():
        _write_tally(reporter)


def _write_tally(reporter) -> None:
    reporter.write_line("")
    reporter.write_line(
        "fuzz cases per reader: valid result / refused with CalibError (CLI: exit 0 / exit 2)"
    )
    for kind, tally in sorted(TALLY.items()):
        if kind.startswith("CLI "):
            ok, refused = tally["CLI exit 0"], tally["CLI exit 2"]
        else:
            ok, refused = tally["valid result"], tally["refused"]
        reporter.write_line(f"  {kind:<14} {ok + refused:6d} cases: {ok:5d} / {refused:5d}")


# ---------------------------------------------------------------------------
# Valid documents to start from


SHORT_SEQUENCE = """\
name = "fuzz-short"
description = "two flips, short dwells"
start = ["east", "up", "south"]
initial_dwell_s = 12.0
latitude_deg = 40.0
height_m = 0.0

[[step]]
axis = "Z"
angle_deg = 90.0
rate_dps = 10.0
dwell_s = 5.0

[[step]]
axis = "Y"
angle_deg = -90.0
dwell_s = 5.0
"""


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture(scope="module")
def bases(work) -> dict[str, bytes]:
    """The bytes of one valid file per reader, written by the tool's own writers."""
    out = {
        "sequence": (REPO / "sequences" / "paper-9pos.toml").read_bytes(),
        "profile": (REPO / "calib" / "data" / "profiles" / "navigation.toml").read_bytes(),
    }
    (work / "short.toml").write_text(SHORT_SEQUENCE, encoding="utf-8")
    seq = load_sequence(work / "short.toml")
    run, truth = simulate(
        seq,
        SimConfig(latitude_rad=math.radians(40.0), sample_rate_hz=10.0),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        setup_rotvec=np.radians([1.0, -2.0, 3.0]),
        flip_error_deg=0.2,
        noise=True,
        seed=3,
    )
    write_truth(work / "base.truth.toml", truth, {"tool_version": "fuzz"})
    out["truth"] = (work / "base.truth.toml").read_bytes()
    # A small run keeps CSV/NPZ parsing cheap; the simulated one has gimbal angles.
    small = Run(
        time_s=run.time_s[:40].copy(),
        dtheta_rad=run.dtheta_rad[:40].copy(),
        dv_mps=run.dv_mps[:40].copy(),
        meta=run.meta,
        gimbal_deg=run.gimbal_deg[:40].copy(),
    )
    write_run(small, work / "base.csv")
    write_run(small, work / "base.npz")
    out["csv"] = (work / "base.csv").read_bytes()
    out["npz"] = (work / "base.npz").read_bytes()
    rng = np.random.default_rng(5)
    A = rng.normal(size=(21, 40))
    cov = A @ A.T
    d = np.sqrt(np.diag(cov))
    result = CalibrationResult(
        values=P.to_si(rng.normal(size=21)),
        sigma=P.to_si(np.abs(rng.normal(size=21)) + 0.01),
        C_b_n0=attitude_from_directions("east", "up", "south") @ rotvec_to_dcm([0.01, -0.02, 0.03]),
        converged=True,
        iterations=4,
        residual_rms_mps=9e-4,
        profile="navigation",
        chi2_per_dof=1.03,
        correlation=cov / np.outer(d, d),
        provenance={"tool_version": "fuzz", "command": "seqdesign calibrate run.npz", "run_sha256": "0" * 64},
    )
    result.save(work / "base.result.toml")
    out["result"] = (work / "base.result.toml").read_bytes()
    return out


_serial = itertools.count()


def case_file(directory: Path, suffix: str, data: bytes) -> Path:
    """Write one case to a fresh, uniquely named file."""
    path = directory / f"case{next(_serial):06d}{suffix}"
    path.write_bytes(data)
    return path


# ---------------------------------------------------------------------------
# The contract


def check_reader(read, path: Path, validate) -> CalibError | None:
    """``read(path)`` is valid or a CalibError naming the file; anything else propagates.

    Returns the refusal, or None for a valid result.
    """
    try:
        with warnings.catch_warnings():
            # A random key is the tool's notice of a key it does not read, meant: not a leak.
            warnings.filterwarnings("ignore", r"(?s).*: key .* is not a \w+ key; it is ignored", UserWarning)
            obj = read(path)
    except CalibError as exc:
        message = str(exc)
        assert path.name in message, f"refusal does not name the file: {message!r}"
        assert message.strip() != path.name
        event("refused")
        event("refusal: " + _category(exc))
        return exc
    finally:
        path.unlink(missing_ok=True)
    validate(obj)
    event("valid result")
    return None


def _category(exc: CalibError) -> str:
    """A coarse label of a refusal for the statistics (first words of what is wrong)."""
    words = re.sub(r"[^a-z ]+", " ", exc.what.lower()).split()
    return " ".join(words[:3])


def finite(x) -> bool:
    return bool(np.all(np.isfinite(np.asarray(x, dtype=float))))


def valid_sequence(seq: Sequence) -> None:
    assert isinstance(seq, Sequence)
    assert isinstance(seq.name, str) and seq.name
    assert isinstance(seq.description, str)
    assert all(d in DIRECTIONS for d in seq.start)
    attitude_from_directions(*seq.start)
    assert math.isfinite(seq.initial_dwell_s) and seq.initial_dwell_s > 0
    assert seq.latitude_deg is None or -90 < seq.latitude_deg < 90
    assert seq.height_m is None or math.isfinite(seq.height_m)
    assert len(seq.steps) >= 1
    for s in seq.steps:
        assert s.axis in ("X", "Y", "Z")
        assert math.isfinite(s.angle_deg) and s.angle_deg != 0
        assert math.isfinite(s.rate_dps) and s.rate_dps > 0
        assert math.isfinite(s.dwell_s) and s.dwell_s >= 0
    assert math.isfinite(seq.duration_s) and seq.duration_s <= 6 * 3600
    # What `show` does with it: any angle must still expand (not only multiples of 90).
    positions = rest_positions(seq)
    assert positions and all(finite(p.gimbal_deg) for p in positions)


def valid_profile(prof: NoiseProfile) -> None:
    assert isinstance(prof, NoiseProfile)
    assert isinstance(prof.name, str) and prof.name
    for v in (prof.gyro_arw_dph, prof.accel_vrw_ug, prof.arw, prof.vrw):
        assert isinstance(v, float) and math.isfinite(v) and v > 0


def valid_errors(model: ErrorModel) -> None:
    assert isinstance(model, ErrorModel)
    assert np.shape(model.values) == (21,) and finite(model.values)
    assert finite(model.gyro_matrix) and finite(model.accel_matrix)


def valid_truth(truth: Truth) -> None:
    assert isinstance(truth, Truth)
    valid_errors(truth.errors)
    assert np.shape(truth.setup_rotvec) == (3,) and finite(truth.setup_rotvec)
    assert np.ndim(truth.flip_errors_deg) == 1 and finite(truth.flip_errors_deg)
    assert isinstance(truth.profile, str)
    assert truth.seed is None or (isinstance(truth.seed, int) and not isinstance(truth.seed, bool))
    assert isinstance(truth.noise, bool)
    assert finite(truth.R_setup)


def valid_run(run: Run) -> None:
    assert isinstance(run, Run)
    n = run.n_samples
    assert n >= 2
    assert run.time_s.shape == (n,) and run.time_s.dtype == np.float64
    assert np.all(np.diff(run.time_s) > 0)
    for array in (run.time_s, run.dtheta_rad, run.dv_mps):
        assert finite(array)
    assert run.dtheta_rad.shape == run.dv_mps.shape == (n, 3)
    if run.gimbal_deg is not None:
        assert run.gimbal_deg.shape == (n, 3) and finite(run.gimbal_deg)
    assert all(isinstance(k, str) and isinstance(v, str) for k, v in run.meta.items())
    assert -90 <= run.latitude_deg <= 90
    assert math.isfinite(run.height_m)
    assert run.sample_rate_hz > 0 and math.isfinite(run.dt_nominal)
    assert run.gravity_mps2 is None or (math.isfinite(run.gravity_mps2) and run.gravity_mps2 > 0)


def valid_result(res: CalibrationResult) -> None:
    assert isinstance(res, CalibrationResult)
    assert res.values.shape == res.sigma.shape == (21,)
    assert finite(res.values) and finite(res.sigma) and np.all(res.sigma >= 0)
    assert res.C_b_n0.shape == (3, 3) and finite(res.C_b_n0)
    np.testing.assert_allclose(res.C_b_n0 @ res.C_b_n0.T, np.eye(3), atol=1e-6)
    assert isinstance(res.converged, bool)
    assert isinstance(res.iterations, int) and res.iterations >= 0
    assert isinstance(res.residual_rms_mps, float)
    assert isinstance(res.chi2_per_dof, float)
    assert isinstance(res.profile, str)
    assert res.correlation is None or (res.correlation.shape == (21, 21) and finite(res.correlation))
    assert isinstance(res.provenance, dict)


def read_truth_and_errors(path: Path) -> Truth:
    """Both readers of a truth/errors file must agree on acceptance."""
    try:
        errors = read_errors(path)
    except CalibError as exc:
        assert path.name in str(exc)
        errors = None
    truth = read_truth(path)  # checks more than read_errors: setup, flips, meta
    assert errors is not None, "read_truth accepted a file that read_errors refused"
    np.testing.assert_array_equal(errors.values, truth.errors.values)
    return truth


READERS = {
    "sequence": (".toml", load_sequence, valid_sequence),
    "profile": (".toml", load_profile, valid_profile),
    "truth": (".truth.toml", read_truth_and_errors, valid_truth),
    "csv": (".csv", lambda p: read_run(p, allow_gaps=False), valid_run),
    "npz": (".npz", lambda p: read_run(p, allow_gaps=False), valid_run),
    "result": (".result.toml", CalibrationResult.load, valid_result),
}


def fuzz_case(kind: str, work: Path, data: bytes) -> CalibError | None:
    suffix, read, validate = READERS[kind]
    _current_kind[0] = kind
    return check_reader(read, case_file(work, suffix, data), validate)


# ---------------------------------------------------------------------------
# Byte-level mutations (every reader)

INVALID_UTF8 = [
    b"\xff",
    b"\xfe",
    b"\xc3",
    b"\xc3\x28",
    b"\xe2\x82",
    b"\xed\xa0\x80",
    b"\xf0\x9f\x98",
    b"\xf8\x88\x80\x80\x80",
    b"\x80",
]
SPECIAL_BYTES = [
    b"\x00",
    b"\r",
    b"\n",
    b"\r\n",
    b"\t",
    b'"',
    b"'",
    b"[",
    b"]",
    b"[[",
    b"=",
    b",",
    b"#",
    b"{",
    b"}",
    b".",
    b"-",
    b"e",
    b"\\",
    b"\xef\xbb\xbf",
    b'"""',
    b"'''",
    b"PK\x03\x04",
    b"\x93NUMPY",
]


def mutate_bytes(data: st.DataObject, base: bytes) -> bytes:
    out = bytearray(base)
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        op = data.draw(
            st.sampled_from(["truncate", "flip", "insert", "special", "utf8", "delete", "duplicate"]),
            label="op",
        )
        i = data.draw(st.integers(0, len(out)), label="at")
        if op == "truncate":
            del out[i:]
        elif op == "flip" and i < len(out):
            out[i] ^= data.draw(st.integers(1, 255), label="xor")
        elif op == "insert":
            out[i:i] = data.draw(st.binary(min_size=1, max_size=8), label="bytes")
        elif op == "special":
            out[i:i] = data.draw(st.sampled_from(SPECIAL_BYTES), label="special")
        elif op == "utf8":
            out[i:i] = data.draw(st.sampled_from(INVALID_UTF8), label="invalid")
        elif op == "delete":
            del out[i : i + data.draw(st.integers(1, 64), label="length")]
        elif op == "duplicate":
            j = min(len(out), i + data.draw(st.integers(1, 80), label="length"))
            out[j:j] = out[i:j]
    return bytes(out)


@pytest.mark.parametrize("kind", list(READERS))
@budget(300)
@given(data=st.data())
def test_mutated_bytes(kind, data, bases, work):
    fuzz_case(kind, work, mutate_bytes(data, bases[kind]))


# ---------------------------------------------------------------------------
# Encodings and degenerate files (every reader, fixed cases)


def _encodings(base: bytes) -> dict[str, bytes]:
    text = base.decode("utf-8")
    nonascii = text.replace("\n", " # Größe µg °\n", 1)
    return {
        "empty": b"",
        "blank": b" \n\n\t\n",
        "nul": b"\x00" * 64,
        "utf-8 BOM": b"\xef\xbb\xbf" + base,
        "utf-16": text.encode("utf-16"),
        "utf-16-le": text.encode("utf-16-le"),
        "utf-32": text.encode("utf-32"),
        "latin-1 non-ascii": nonascii.encode("latin-1"),
        "cp1252 non-ascii": nonascii.encode("cp1252"),
        "utf-8 non-ascii": nonascii.encode("utf-8"),
        "CRLF": text.replace("\n", "\r\n").encode("utf-8"),
        "CR only": text.replace("\n", "\r").encode("utf-8"),
        "first half": base[: len(base) // 2],
        "one byte": base[:1],
        "binary noise": bytes(range(256)) * 4,
        "no final newline": base.rstrip(b"\n"),
        "doubled": base + base,
        "gzip": b"\x1f\x8b\x08\x00" + base,
        "zip": b"PK\x05\x06" + b"\x00" * 18,
    }


@pytest.mark.parametrize("kind", [k for k in READERS if k != "npz"])
def test_encodings_and_degenerate_files(kind, bases, work):
    for _name, data in _encodings(bases[kind]).items():
        fuzz_case(kind, work, data)


# ---------------------------------------------------------------------------
# Token-level mutations of the text formats

NUMBER = re.compile(rb"(?<![\w.\"])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.])")
STRING = re.compile(rb'"[^"\n]*"')
KEY = re.compile(rb"^([A-Za-z_][\w-]*)[ \t]*=", re.M)
TABLE = re.compile(rb"^\[\[?[^\]\n]*\]\]?[ \t]*$", re.M)
LINE = re.compile(rb"^.*$", re.M)

TOML_VALUES = [
    b"nan",
    b"+nan",
    b"-nan",
    b"inf",
    b"+inf",
    b"-inf",
    b"1e400",
    b"-1e400",
    b"1e-400",
    b"5e-324",
    b"1.7976931348623157e308",
    b"0",
    b"-0.0",
    b"-1",
    b"-90",
    b"1" + b"0" * 30,
    b"1" + b"0" * 400,
    b"9" * 4400,
    b"9223372036854775807",
    b"-9223372036854775808",
    b"0x7fffffffffffffff",
    b"0b1",
    b"0o7",
    b"1_000",
    b"true",
    b"false",
    b'"12.5"',
    b'"nan"',
    b'""',
    b'"east"',
    b'"Z"',
    b"[]",
    b"[1, 2]",
    b"[[1, 2], [3]]",
    b'["a", 1]',
    b"{}",
    b"{ a = 1 }",
    b"1979-05-27",
    b"1979-05-27T07:32:00Z",
    b"07:32:00",
    b"45",
    b"30.5",
    b"89.999",
    b"3600",
    b"3601",
    b"1000.5",
    b"-180",
    b"270",
    b"0.001",
    b"[" * 2000,
    b"{a=" * 2000,
]
TOML_STRINGS = [
    b'"X"',
    b'"Y"',
    b'"Z"',
    b'"x"',
    b'"W"',
    b'"XY"',
    b'""',
    b'" Z "',
    b'"east"',
    b'"EAST"',
    b'"north"',
    b'"down"',
    b'"up"',
    b'"west"',
    b'"south"',
    b'"sky"',
    b'"\\u0000"',
    b'"\\u00e9"',
    b'"\\ud800"',
    b'"nan"',
    b'"1e400"',
    b"1",
    b"90.0",
    b"nan",
    b"true",
    b"[]",
    b"{}",
    b'["east"]',
    b'"' + b"a" * 5000 + b'"',
]
TOML_KEYS = [
    b"name",
    b"start",
    b"step",
    b"axis",
    b"angle_deg",
    b"rate_dps",
    b"dwell_s",
    b"initial_dwell_s",
    b"latitude_deg",
    b"height_m",
    b"gyro_arw_dph",
    b"accel_vrw_ug",
    b"value",
    b"sigma",
    b"C_b_n",
    b"bgx",
    b"sgy",
    b"mazy",
    b"east_deg",
    b"seed",
    b"noise",
    b"iterations",
    b"converged",
    b"unknown",
    b"Axis",
    b"x",
]
TOML_TABLES = [
    b"[step]",
    b"[[step]]",
    b"[errors]",
    b"[[errors]]",
    b"[setup]",
    b"[meta]",
    b"[flips]",
    b"[parameters]",
    b"[parameters.bgx]",
    b"[[parameters.bgx]]",
    b"[initial_attitude]",
    b"[fit]",
    b"[correlation]",
    b"[provenance]",
    b"[x.y.z]",
    b"[]",
    b"[step",
    b"",
]


def mutate_tokens(data: st.DataObject, base: bytes, rules) -> bytes:
    """Replace, drop or duplicate tokens found by the ``rules`` (pattern, replacements)."""
    out = base
    for _ in range(data.draw(st.integers(1, 4), label="edits")):
        pattern, replacements = data.draw(st.sampled_from(rules), label="rule")
        matches = list(pattern.finditer(out))
        if not matches:
            continue
        m = matches[data.draw(st.integers(0, len(matches) - 1), label="which")]
        action = data.draw(
            st.sampled_from(["replace", "replace", "replace", "drop", "repeat"]), label="action"
        )
        if action == "replace":
            new = data.draw(st.sampled_from(replacements), label="with")
            if pattern is KEY:
                new = new + b" ="
        elif action == "drop":
            new = b""
        else:
            new = m.group(0) + (b"\n" if pattern in (LINE, TABLE) else b"") + m.group(0)
        out = out[: m.start()] + new + out[m.end() :]
    return out


TOML_RULES = [
    (NUMBER, TOML_VALUES),
    (STRING, TOML_STRINGS),
    (KEY, TOML_KEYS),
    (TABLE, TOML_TABLES),
    (LINE, [b"", b"x", b"= 1", b"[[step]]"]),
]


@pytest.mark.parametrize("kind", ["sequence", "profile", "truth", "result"])
@budget(400)
@given(data=st.data())
def test_toml_token_mutations(kind, data, bases, work):
    fuzz_case(kind, work, mutate_tokens(data, bases[kind], TOML_RULES))


CSV_VALUES = [
    b"nan",
    b"NaN",
    b"inf",
    b"-inf",
    b"Infinity",
    b"1e400",
    b"-1e400",
    b"1e-400",
    b"",
    b" ",
    b"abc",
    b"1,2",
    b"0x1p3",
    b"1_0",
    b"\xff",
    b"-",
    b"+",
    b"1e",
    b".",
    b"0",
    b"-0",
    b"1e308",
    b"-1e308",
    b"5e-324",
    b"9" * 400,
    b"1.0.0",
    b'"1.0"',
    b"1;2",
    b"\t1",
    b"# 1",
    b"\x00",
    b"-90.5",
    b"90",
    b"-1",
    b"1e-9",
    b"1000000",
]
CSV_HEADER_NAMES = [
    b"time_s",
    b"dtheta_x_rad",
    b"dv_z_mps",
    b"outer_deg",
    b"inner_deg",
    b"Time_s",
    b"TIME_S",
    b" time_s ",
    b"",
    b"x",
    b"dv_x_mps,dv_x_mps",
]
CSV_NAME = re.compile(rb"(?<=[,\n])[a-z]+_[a-z_]+(?=[,\n])")
CSV_META_VALUE = re.compile(rb"(?<=: )[^\n]*")
CSV_META_KEY = re.compile(rb"(?<=^# )[\w ]+(?=:)", re.M)
CSV_META_VALUES = [
    b"imu-run/2",
    b"imu-run/1 ",
    b"",
    b"nan",
    b"inf",
    b"-91",
    b"91",
    b"0",
    b"-10",
    b"1e-300",
    b"5e-324",
    b"1e400",
    b"abc",
    b"200",
    b"0.001",
    b"1e9",
]
CSV_META_KEYS = [
    b"format",
    b"latitude_deg",
    b"height_m",
    b"sample_rate_hz",
    b"gravity_mps2",
    b"sequence",
    b"",
    b" ",
    b"x",
    b"Format",
]
CSV_RULES = [
    (NUMBER, CSV_VALUES),
    (CSV_NAME, CSV_HEADER_NAMES),
    (CSV_META_VALUE, CSV_META_VALUES),
    (CSV_META_KEY, CSV_META_KEYS),
    (LINE, [b"", b"#", b"# :", b"# x", b",,,,,,,,,", b"1,2,3"]),
]


@budget(600)
@given(data=st.data())
def test_csv_token_mutations(data, bases, work):
    fuzz_case("csv", work, mutate_tokens(data, bases["csv"], CSV_RULES))


# ---------------------------------------------------------------------------
# Extreme values in every place, and documents that break the parsers themselves

HOSTILE_TOML = {
    "integer of 5000 digits": b"x = 1" + b"0" * 5000 + b"\n",
    "integer of 400 digits": b"x = 1" + b"0" * 400 + b"\n",
    "arrays nested 5000 deep": b"x = " + b"[" * 5000 + b"]" * 5000 + b"\n",
    "inline tables nested 5000 deep": b"x = " + b"{a = " * 5000 + b"1" + b"}" * 5000 + b"\n",
    "dotted key 5000 long": b"a" + b".a" * 5000 + b" = 1\n",
    "table header nested deep": b"[" + b"a." * 3000 + b"a]\nx = 1\n",
}


EXTREME_TOML = [
    b"1e308",
    b"-1e308",
    b"1e20",
    b"-1e20",
    b"5e-324",
    b"1e-300",
    b"0",
    b"-0.0",
    b"nan",
    b"inf",
    b"-inf",
    b"9223372036854775807",
    b"3601",
    b"-3601",
    b"10.5",
]


@pytest.mark.parametrize("kind", ["sequence", "profile", "truth", "result"])
def test_extreme_numbers(kind, bases, work):
    """Every number of a valid file, in turn, replaced by extreme and special values."""
    base = bases[kind]
    numbers = list(NUMBER.finditer(base))
    for m in numbers[:: max(1, len(numbers) // 60)]:  # the result file has 500 numbers
        line = base[base.rfind(b"\n", 0, m.start()) + 1 : m.start()]
        key = re.match(rb"\s*([\w-]+)\s*=", line)
        for value in EXTREME_TOML:
            refusal = fuzz_case(kind, work, base[: m.start()] + value + base[m.end() :])
            if refusal is not None:
                # The place: the key (or its table, for matrices), or the line for syntax.
                places = [key.group(1).decode()] if key else ["["]
                places += ["line", "sequence lasts"]
                assert any(p in str(refusal) for p in places), (places, str(refusal))


CSV_EXTREMES = [
    b"1e308",
    b"-1e308",
    b"5e-324",
    b"1e-300",
    b"1e20",
    b"-1e20",
    b"0",
    b"-0",
    b"nan",
    b"inf",
    b"-inf",
    b"90",
    b"-90",
    b"90.000001",
    b"1e6",
    b"9" * 400,
]


def test_csv_extreme_metadata(bases, work):
    """Every metadata value of a valid run log replaced by extreme and special values."""
    base = bases["csv"]
    for m in CSV_META_VALUE.finditer(base.split(b"\ntime_s")[0]):
        for value in CSV_EXTREMES:
            refusal = fuzz_case("csv", work, base[: m.start()] + value + base[m.end() :])
            if refusal is not None:
                assert ", line " in str(refusal), str(refusal)  # the metadata line


@pytest.mark.parametrize("kind", ["sequence", "profile", "truth", "result"])
def test_hostile_toml(kind, bases, work):
    """Documents that break the TOML parser itself, alone and replacing each number."""
    for data in HOSTILE_TOML.values():
        fuzz_case(kind, work, data)
    huge = b"1" + b"0" * 400
    for m in NUMBER.finditer(bases[kind][:4000]):
        for value in (huge, b"-" + huge, b"9" * 4400, b"[" * 3000):
            fuzz_case(kind, work, bases[kind][: m.start()] + value + bases[kind][m.end() :])


# ---------------------------------------------------------------------------
# Random TOML documents (schema-aware edits of valid ones, and from scratch)

FLOATS = st.floats(allow_nan=True, allow_infinity=True)
HOSTILE = st.sampled_from(
    [
        math.nan,
        math.inf,
        -math.inf,
        1e308,
        -1e308,
        5e-324,
        0,
        -0.0,
        -1,
        10**30,
        2**63 - 1,
        -(2**63),
        10**400,
        True,
        False,
        "",
        "nan",
        "1e400",
        "x",
        "Z",
        "east",
        [],
        {},
        [1, 2, 3],
        [[1.0]],
        {"a": 1},
        [math.nan] * 3,
    ]
)
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12)
KEYS = st.one_of(TEXT, st.sampled_from([k.decode() for k in TOML_KEYS]))
SCALARS = st.one_of(
    st.booleans(),
    st.integers(-(10**400), 10**400),
    FLOATS,
    TEXT,
    HOSTILE,
    st.dates(),
    st.sampled_from(["X", "Y", "Z", "W", "east", "up", "south"]),
)
VALUES = st.recursive(
    SCALARS,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(KEYS, children, max_size=4),
    max_leaves=12,
)


def _paths(doc, prefix=()):
    if prefix:
        yield prefix
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for key, value in items:
        yield from _paths(value, prefix + (key,))


def mutate_doc(data: st.DataObject, base: dict, extra: st.SearchStrategy | None = None) -> dict:
    """Delete, replace or add entries anywhere in a parsed document."""
    doc = copy.deepcopy(base)
    for _ in range(data.draw(st.integers(1, 4), label="edits")):
        paths = list(_paths(doc))
        if not paths:
            break
        path = data.draw(st.sampled_from(paths), label="path")
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        key = path[-1]
        action = data.draw(st.sampled_from(["delete", "replace", "replace", "add"]), label="action")
        # Copies: sampled_from hands out the same list/dict objects every time.
        values = (VALUES if extra is None else st.one_of(VALUES, extra)).map(copy.deepcopy)
        if action == "delete":
            del parent[key]
        elif action == "replace":
            parent[key] = data.draw(values, label="value")
        elif isinstance(parent, dict):
            parent[data.draw(KEYS, label="key")] = data.draw(values, label="value")
        else:
            parent.insert(key, data.draw(values, label="value"))
    return doc


def toml_bytes(doc: dict) -> bytes | None:
    try:
        return tomli_w.dumps(doc).encode("utf-8")
    except (TypeError, ValueError):
        return None  # not representable in TOML (e.g. an array of mixed tables)


def _doc(base: bytes) -> dict:
    return tomllib.loads(base.decode("utf-8"))


ANGLES = st.one_of(
    st.floats(-4000, 4000),
    st.integers(-4000, 4000),
    st.sampled_from(
        [
            90,
            -90,
            180,
            270,
            360,
            45,
            30.5,
            89.999,
            90.0001,
            1e-300,
            0,
            -0.0,
            3600,
            -3600,
            3600.0001,
            1e300,
            math.nan,
            math.inf,
        ]
    ),
)
STEPS = st.fixed_dictionaries(
    {
        "axis": st.one_of(
            st.sampled_from(["X", "Y", "Z", "x", "y", "z"]),
            st.sampled_from(["W", "", "XY", " X", "Q", "1"]),
            st.integers(0, 3),
        )
    },
    optional={
        "angle_deg": ANGLES,
        "rate_dps": st.one_of(st.floats(-10, 2000), st.sampled_from([0, 1e-300, 1000, 1001])),
        "dwell_s": st.one_of(st.floats(-10, 30000), st.sampled_from([0, 1e-300, 21600])),
        "note": TEXT,
    },
)


@budget(600)
@given(data=st.data())
def test_sequence_documents(data, bases, work):
    """Random steps (unknown axes, any angle, any rate/dwell) and random edits."""
    doc = _doc(bases["sequence"])
    if data.draw(st.booleans(), label="random steps"):
        doc["step"] = data.draw(st.lists(STEPS, max_size=6), label="steps")
        doc["start"] = data.draw(
            st.one_of(
                st.just(["east", "up", "south"]),
                st.lists(st.sampled_from(list(DIRECTIONS) + ["EAST", "sky", " up"]), min_size=0, max_size=4),
            ),
            label="start",
        )
    if data.draw(st.booleans(), label="edit"):
        doc = mutate_doc(data, doc, STEPS)
    encoded = toml_bytes(doc)
    if encoded is not None:
        fuzz_case("sequence", work, encoded)


@pytest.mark.parametrize("kind", ["profile", "truth", "result"])
@budget(400)
@given(data=st.data())
def test_toml_documents(kind, data, bases, work):
    encoded = toml_bytes(mutate_doc(data, _doc(bases[kind])))
    if encoded is not None:
        fuzz_case(kind, work, encoded)


@pytest.mark.parametrize("kind", ["sequence", "profile", "truth", "result"])
@budget(200)
@given(doc=st.dictionaries(KEYS, VALUES, max_size=8))
def test_toml_from_scratch(kind, doc, work):
    encoded = toml_bytes(doc)
    if encoded is not None:
        fuzz_case(kind, work, encoded)


# ---------------------------------------------------------------------------
# Random NPZ archives


def _npz(arrays: dict) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


GOOD_META = json.dumps(make_meta(40.0, 0.0, 10.0))


def _meta_arrays():
    texts = st.one_of(
        st.just(GOOD_META),
        TEXT,
        st.sampled_from(
            [
                "",
                "{}",
                "[]",
                "null",
                "1",
                '"x"',
                "{",
                "[" * 100000,
                '{"a": ' * 100000,
                "1" + "0" * 5000,
                '{"format": "imu-run/1"}',
                GOOD_META.replace("10.0", "NaN"),
                GOOD_META.replace("10.0", "1" + "0" * 5000),
                GOOD_META.replace("10.0", "1e400"),
                GOOD_META.replace('"10.0"', "[10]"),
                GOOD_META.replace('"10.0"', "true"),
                GOOD_META.replace('"10.0"', "null"),
                GOOD_META.replace("40.0", "91"),
                GOOD_META.replace("10.0", "0"),
                GOOD_META.replace("10.0", "1e-320"),
                GOOD_META.replace("imu-run/1", "imu-run/2"),
                GOOD_META + "x",
            ]
        ),
        st.dictionaries(
            KEYS, st.one_of(TEXT, FLOATS, st.integers(), st.booleans(), st.none()), max_size=5
        ).map(lambda d: json.dumps({**make_meta(40.0, 0.0, 10.0), **d})),
    )
    return st.one_of(
        texts.map(np.array),
        texts.map(lambda t: np.array(t.encode("utf-8", "surrogatepass"))),
        st.just(np.array(b"\xff\xfe{")),
        texts.map(lambda t: np.array([t, t])),
        st.just(np.array(1.0)),
        st.just(np.zeros((0,), dtype="U1")),
        st.just(np.array({"format": "imu-run/1"}, dtype=object)),
    )


def _bad_array(n: int, cols: int | None):
    """Arrays a run log must refuse (or, for odd but real dtypes, convert)."""
    shape = (n,) if cols is None else (n, cols)
    good = np.arange(1, n + 1) / 10.0 if cols is None else np.full(shape, 1e-4)
    wrong_shapes = st.sampled_from(
        [(), (0,), (n + 1,), (n - 1,), (n, 2), (n, 4), (3, n), (n, 3, 1), (1, n), (n, 1)]
    ).map(np.ones)
    dtypes = st.sampled_from(
        [
            "f2",
            "f4",
            "i1",
            "i8",
            "u8",
            "?",
            "c16",
            "U3",
            "S3",
            "M8[s]",
            "m8[s]",
            "V8",
            np.longdouble,
            [("a", "f8")],
        ]
    )
    special = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, -1.0])

    def poisoned(args):
        value, index = args
        out = good.copy()
        out.flat[index % out.size] = value
        return out

    def typed(dtype):
        try:
            return good.astype(dtype) if np.dtype(dtype).kind in "iuf" else np.ones(shape, dtype)
        except (TypeError, ValueError):
            return np.ones(shape)

    return st.one_of(
        wrong_shapes,
        dtypes.map(typed),
        st.tuples(special, st.integers(0, 10**6)).map(poisoned),
        st.just(np.array([None] * n, dtype=object)),
        st.just(np.full(shape, 1e300, dtype=np.longdouble) * 1e300),
        st.just(good[::-1].copy()),
        st.just(np.zeros(shape)),
        st.just(good * 100.0),
        st.just(good / 100.0),
    )


@st.composite
def npz_archives(draw) -> bytes:
    """A valid archive with zero to three faults, sometimes with damaged bytes too."""
    n = draw(st.integers(2, 30), label="n")
    arrays = {
        "time_s": np.arange(1, n + 1) / 10.0,
        "dtheta_rad": np.full((n, 3), 1e-5),
        "dv_mps": np.tile([0.0, 0.0, 0.98], (n, 1)),
        "meta": np.array(GOOD_META),
    }
    if draw(st.booleans(), label="gimbal"):
        arrays["gimbal_deg"] = np.zeros((n, 3))
    for _ in range(draw(st.integers(0, 3), label="faults")):
        name = draw(
            st.sampled_from(["time_s", "dtheta_rad", "dv_mps", "gimbal_deg", "meta", "extra"]), label="array"
        )
        action = draw(st.sampled_from(["replace", "replace", "replace", "drop"]), label="action")
        if action == "drop":
            arrays.pop(name, None)
        elif name == "meta":
            arrays["meta"] = draw(_meta_arrays(), label="meta")
        elif name == "extra":
            arrays[draw(st.text("abcxyz_", min_size=1, max_size=6), label="name")] = np.ones(3)
        else:
            arrays[name] = draw(_bad_array(n, None if name == "time_s" else 3), label=name)
    data = _npz(arrays)
    if draw(st.integers(0, 5), label="damage") == 0:
        data = mutate_bytes(draw(st.data()), data)
    return data


@budget(800)
@given(data=npz_archives())
def test_npz_archives(data, work):
    fuzz_case("npz", work, data)


def _zip_with(members: dict[str, bytes], compression=zipfile.ZIP_STORED) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=compression) as z:
        for name, content in members.items():
            z.writestr(name, content)
    return buffer.getvalue()


def _npy(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _patch_all(data: bytes, old: bytes, new: bytes) -> bytes:
    assert old in data
    return data.replace(old, new)


def _fixed_npz_cases(base: bytes) -> dict[str, bytes]:
    """Damaged archives that random flips rarely produce."""
    z = zipfile.ZipFile(io.BytesIO(base))
    members = {info.filename: z.read(info) for info in z.infolist()}
    time = members["time_s.npy"]
    # time_s.npy claiming 1e12 samples (8 TB) in an archive of a few kB.
    header_len = int.from_bytes(time[8:10], "little")
    header = time[10 : 10 + header_len].decode("latin-1")
    big = header.replace("(40,)", "(1000000000000,)")
    big_npy = (
        time[:8]
        + len(big.ljust(header_len)).to_bytes(2, "little")
        + big.ljust(header_len).encode("latin-1")
        + time[10 + header_len :]
    )
    stored = _zip_with(members)

    def with_header(text: bytes) -> bytes:
        """time_s.npy with another header (padded to the original length)."""
        padded = text.ljust(header_len - 1) + b"\n"
        return _zip_with(
            {
                **members,
                "time_s.npy": time[:8] + len(padded).to_bytes(2, "little") + padded + time[10 + header_len :],
            }
        )

    deflated = _zip_with(members, zipfile.ZIP_DEFLATED)

    # Local and central headers carry the method (offset 8 / 10) and flags (6 / 8).
    def patch_method(data: bytes, method: int) -> bytes:
        out = bytearray(data)
        for sig, off in ((b"PK\x03\x04", 8), (b"PK\x01\x02", 10)):
            for m in re.finditer(re.escape(sig), data):
                out[m.start() + off : m.start() + off + 2] = method.to_bytes(2, "little")
        return bytes(out)

    def patch_flags(data: bytes, flags: int) -> bytes:
        out = bytearray(data)
        for sig, off in ((b"PK\x03\x04", 6), (b"PK\x01\x02", 8)):
            for m in re.finditer(re.escape(sig), data):
                out[m.start() + off : m.start() + off + 2] = flags.to_bytes(2, "little")
        return bytes(out)

    cases = {
        "empty": b"",
        "npy not npz": _npy(np.ones(3)),
        "pickle": b"\x80\x04\x95" + b"\x00" * 20,
        "text": b"# format: imu-run/1\n",
        "truncated central directory": stored[:-10],
        "truncated half": stored[: len(stored) // 2],
        "deflated truncated": deflated[: len(deflated) - 200],
        "unknown compression": patch_method(stored, 99),
        "lzma garbage": patch_method(stored, 14),
        "lzma corrupt stream": patch_method(
            _zip_with({**members, "time_s.npy": b"\x09\x04\x05\x00\x5d\x00\x00\x80\x00" + b"\xff" * 40}), 14
        ),
        "bzip2 garbage": patch_method(stored, 12),
        "deflate garbage": patch_method(stored, 8),
        "encrypted flag": patch_flags(stored, 1),
        "utf-8 names flag": patch_flags(stored, 0x800),
        "huge declared shape": _zip_with({**members, "time_s.npy": big_npy}),
        "object array": _zip_with({**members, "meta.npy": _npy(np.array([{"a": 1}], dtype=object))}),
        "member not npy": _zip_with({**members, "dv_mps.npy": b"hello"}),
        "member empty": _zip_with({**members, "dv_mps.npy": b""}),
        "member bad header": _zip_with({**members, "dv_mps.npy": time[:10] + b"{'descr': <f8" + time[23:]}),
        "member truncated": _zip_with({**members, "dv_mps.npy": members["dv_mps.npy"][:-7]}),
        "member fortran": _zip_with({**members, "dv_mps.npy": _npy(np.asfortranarray(np.ones((40, 3))))}),
        "nested zip": _zip_with({"time_s.npy": stored}),
        "header unbalanced": with_header(header.encode().replace(b"{", b"z", 1)),
        "header unhashable key": with_header(
            b"{[]: 1, 'descr': '<f8', 'fortran_order': False, 'shape': (40,)}"
        ),
        "header not a dict": with_header(b"(" * 100 + b")" * 100),
        "header negative shape": with_header(b"{'descr': '<f8', 'fortran_order': False, 'shape': (-40,)}"),
        "header huge dtype": with_header(
            b"{'descr': '<V99999999999', 'fortran_order': False, 'shape': (40,)}"
        ),
        "header object dtype": with_header(b"{'descr': '|O', 'fortran_order': False, 'shape': (40,)}"),
        "no members": _zip_with({}),
        "duplicate member": _zip_with({**members, "time_s.npy ": members["time_s.npy"]}).replace(
            b"time_s.npy ", b"time_s.npy\x00"
        ),
    }
    return cases


@budget(400)
@given(data=st.data())
def test_npz_member_headers(data, bases, work):
    """Damaged .npy headers inside an intact zip (valid CRCs), so numpy parses them."""
    with zipfile.ZipFile(io.BytesIO(bases["npz"])) as z:
        members = {info.filename: z.read(info) for info in z.infolist()}
    name = data.draw(st.sampled_from(sorted(members)), label="member")
    npy = members[name]
    end = 10 + int.from_bytes(npy[8:10], "little")
    cut = data.draw(st.sampled_from([end, end, 10, 8, 6]), label="header part")
    members[name] = mutate_bytes(data, npy[:cut]) + npy[cut:]
    fuzz_case("npz", work, _zip_with(members))


def test_npz_damaged_archives(bases, work):
    for _name, data in _fixed_npz_cases(bases["npz"]).items():
        fuzz_case("npz", work, data)


# ---------------------------------------------------------------------------
# The flip graph: attitudes typed by users ("east,up,south")

NODE_TEXT = st.one_of(
    st.text(max_size=30),
    st.lists(
        st.sampled_from(
            list(DIRECTIONS)
            + ["EAST", " Up", "sky", "", "north-east", "0", "90", "45", "east,", "ÉAST", "eaſt"]
        ),
        max_size=5,
    ).map(lambda parts: data_join(parts)),
    st.lists(st.sampled_from(list(DIRECTIONS)), min_size=3, max_size=3).map(",".join),
)


def data_join(parts: list[str]) -> str:
    return ",".join(parts) if len(parts) % 2 else " ".join(parts)


GRID = set(flip_graph(("east", "up", "south")).nodes)


@budget(500)
@given(text=NODE_TEXT)
def test_parse_node(text):
    _current_kind[0] = "graph node"
    try:
        node = parse_node(text, "--start")
    except CalibError as exc:
        assert "--start" in str(exc)
        event("refused")
        return
    event("valid result")
    assert node in GRID  # one of the 24 grid attitudes, reachable by 90-degree flips
    C = attitude_of(node)
    np.testing.assert_allclose(C @ C.T, np.eye(3))
    assert len(flip_graph(node).nodes) == 24


@budget(100)
@given(
    angles=st.lists(
        ANGLES.filter(lambda a: isinstance(a, (int, float)) and math.isfinite(a) and 0 < abs(a) <= 3600),
        min_size=1,
        max_size=4,
    ),
    axes=st.lists(st.sampled_from("XYZ"), min_size=4, max_size=4),
)
def test_any_angle_loads_and_expands(angles, axes, work):
    """Angles that are not multiples of 90 deg leave the grid but still load and show."""
    doc = {
        "name": "odd",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 10.0,
        "step": [
            {"axis": ax, "angle_deg": float(a), "rate_dps": 100.0, "dwell_s": 1.0}
            for a, ax in zip(angles, axes, strict=False)  # axes: always 4, angles: 1 to 4
        ],
    }
    path = case_file(work, ".toml", tomli_w.dumps(doc).encode())
    seq = load_sequence(path)
    valid_sequence(seq)
    assert [s.angle_deg for s in seq.steps] == [float(a) for a in angles]


# ---------------------------------------------------------------------------
# The CLI: exit 0 or 2, never a traceback, nothing half-written


def _invoke(kind: str, args: list[str]):
    _current_kind[0] = f"CLI {kind}"
    result = CliRunner().invoke(main, args)
    output = result.output
    assert "Traceback" not in output, output
    assert result.exit_code in (0, 2), (result.exit_code, output, result.exception)
    if result.exception is not None:
        assert isinstance(result.exception, SystemExit), repr(result.exception)
    if result.exit_code == 2:
        assert "error: " in output and "Traceback" not in output
        event("CLI exit 2")
    else:
        event("CLI exit 0")
    return result


def _cli_mutation(data, base: bytes, text_rules) -> bytes:
    how = data.draw(st.sampled_from(["bytes", "tokens", "tokens", "none"]), label="mutation")
    if how == "bytes":
        return mutate_bytes(data, base)
    if how == "tokens":
        return mutate_tokens(data, base, text_rules)
    return base  # the valid file: the command must then succeed and write its output


@budget(20)
@given(data=st.data())
def test_cli_show(data, bases, work):
    path = case_file(work, ".toml", _cli_mutation(data, bases["sequence"], TOML_RULES))
    _invoke("sequence", ["show", str(path)])
    _invoke("sequence", ["show", str(path), "--json"])


@budget(20)
@given(data=st.data())
def test_cli_analyze_profile(data, bases, work):
    path = case_file(work, ".toml", _cli_mutation(data, bases["profile"], TOML_RULES))
    _invoke("profile", ["analyze", "paper-9pos", "--profile", str(path), "--tolerance-deg", "0"])


@pytest.mark.parametrize(
    "arw, vrw",
    [
        ("1e-300", "1e-300"),
        ("1e300", "1e300"),
        ("1e200", "10"),
        ("5e-324", "10"),
        ("0.001", "1e-320"),
        ("1" + "0" * 400, "10"),
        ("1e-6", "1e-3"),
        ("100", "1e5"),
        ("1e-6", "1e5"),
        ("100", "1e-3"),
    ],
)
def test_cli_analyze_extreme_profiles(arw, vrw, work):
    """Profiles the reader accepts must analyse; the rest are refused, not crashed on."""
    path = case_file(work, ".toml", f'name = "p"\ngyro_arw_dph = {arw}\naccel_vrw_ug = {vrw}\n'.encode())
    _invoke("profile", ["analyze", "paper-9pos", "--profile", str(path), "--tolerance-deg", "0"])


@budget(20)
@given(data=st.data())
def test_cli_simulate_errors(data, bases, work):
    errors = case_file(work, ".toml", _cli_mutation(data, bases["truth"], TOML_RULES))
    out = work / f"sim{next(_serial):06d}.npz"
    result = _invoke(
        "errors",
        [
            "simulate",
            "paper-9pos",
            "--errors",
            str(errors),
            "-o",
            str(out),
            "--noise-free",
            "--sample-rate-hz",
            "10",
        ],
    )
    truth = out.with_name(out.stem + ".truth.toml")
    if result.exit_code == 2:
        assert not out.exists() and not truth.exists(), "a refused simulate left output behind"
    else:
        valid_run(read_run(out))
        valid_truth(read_truth(truth))
    assert not list(work.glob(f".{out.name}.*")), "temporary file left behind"


@pytest.fixture(scope="module")
def paper_run(work) -> dict[str, bytes]:
    """The paper's sequence simulated at 10 Hz (calibrates in well under a second)."""
    out = work / "paper.npz"
    result = CliRunner().invoke(
        main, ["simulate", "paper-9pos", "--table2", "--seed", "4", "--sample-rate-hz", "10", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    write_run(read_run(out), work / "paper.csv")
    # The provenance records pytest's command line: fix it, so the cases do not depend on it.
    truth = tomllib.loads((work / "paper.truth.toml").read_text("utf-8"))
    truth["provenance"] = {"tool_version": "fuzz", "command": "seqdesign simulate paper-9pos"}
    return {
        "npz": out.read_bytes(),
        "csv": (work / "paper.csv").read_bytes(),
        "truth": tomli_w.dumps(truth).encode("utf-8"),
    }


@pytest.mark.parametrize("kind", ["csv", "npz", "truth"])
@budget(20)
@given(data=st.data())
def test_cli_calibrate(kind, data, paper_run, work):
    """A mutated run log (or the truth file beside it) through ``calibrate``."""
    if kind == "truth":
        run = case_file(work, ".npz", paper_run["npz"])
        run.with_name(run.stem + ".truth.toml").write_bytes(
            _cli_mutation(data, paper_run["truth"], TOML_RULES)
        )
    elif kind == "csv":
        run = case_file(work, ".csv", _cli_mutation(data, paper_run["csv"], CSV_RULES))
    else:
        how = data.draw(st.sampled_from(["bytes", "bytes", "none"]), label="mutation")
        run = case_file(
            work, ".npz", mutate_bytes(data, paper_run["npz"]) if how == "bytes" else paper_run["npz"]
        )
    out = run.with_name(run.stem + ".result.toml")
    result = _invoke(f"run {kind}", ["calibrate", str(run), "-o", str(out)])
    if result.exit_code == 2:
        assert not out.exists(), "a refused calibrate left a result behind"
    else:
        valid_result(CalibrationResult.load(out))  # what calibrate writes, the reader reads
    assert not list(work.glob(f".{out.name}.*")), "temporary file left behind"


def test_cli_simulate_any_angle(work):
    """Flips that are not multiples of 90 deg load, show and simulate."""
    doc = {
        "name": "odd-angles",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 20.0,
        "step": [
            {"axis": "Z", "angle_deg": 45.0, "dwell_s": 10.0},
            {"axis": "X", "angle_deg": -137.5, "rate_dps": 20.0, "dwell_s": 10.0},
            {"axis": "Y", "angle_deg": 721.0, "rate_dps": 90.0, "dwell_s": 10.0},
        ],
    }
    seq = case_file(work, ".toml", tomli_w.dumps(doc).encode())
    assert _invoke("sequence", ["show", str(seq)]).exit_code == 0
    out = work / "odd.csv"
    assert (
        _invoke(
            "sequence", ["simulate", str(seq), "-o", str(out), "--sample-rate-hz", "10", "--table2"]
        ).exit_code
        == 0
    )
    valid_run(read_run(out))
    valid_truth(read_truth(work / "odd.truth.toml"))
