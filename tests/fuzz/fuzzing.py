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
choices with literals from the project's loaded modules, so a file run alone
and the whole suite try different, equally reproducible, cases.) Set
``SEQDESIGN_FUZZ_SCALE=10`` to try ten times as many cases locally and
``SEQDESIGN_FUZZ_RANDOM=1`` to draw fresh ones; ``--hypothesis-show-statistics``
shows the outcomes per test, and each test module prints the cases it tried per reader.

The layout: this module holds what every reader's tests share (the budget, the tally of
cases per reader, the contract, the byte-level mutations); ``fuzz_text.py`` the token rules
and random documents of the text formats; ``fuzz_fixtures.py`` the module-scoped fixtures
(``work``, ``bases`` with the valid base documents, the tally's report). The cases live one
file per reader: ``test_fuzz_sequence.py``, ``test_fuzz_profile.py``, ``test_fuzz_truth.py``
(errors/truth), ``test_fuzz_result.py``, ``test_fuzz_csv.py`` and ``test_fuzz_npz.py`` (run
logs), ``test_fuzz_flip_graph.py`` (attitudes typed by users) and ``test_fuzz_cli.py``.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, event as _hypothesis_event, settings, strategies as st
from hypothesis.control import currently_in_test_context

from calib.calibration.result import CalibrationResult
from calib.errors import CalibError
from calib.gimbal.encoders import rest_positions
from calib.model.error_model import ErrorModel
from calib.nav.transform import DIRECTIONS, attitude_from_directions
from calib.noise.profiles import NoiseProfile, load_profile
from calib.runlog import Run, read_run
from calib.sequence.definition import Sequence, load_sequence
from calib.sim.gimbal_run import Truth
from calib.sim.truth import read_errors, read_truth

REPO = Path(__file__).resolve().parents[2]
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


# Cases tried per reader and outcome, printed at the end of each test module
# (fuzz_fixtures.report_tally).
TALLY: dict[str, Counter] = {}
_current_kind = ["?"]


def event(label: str) -> None:
    """Count an outcome for the report, and for hypothesis' statistics when inside a test."""
    TALLY.setdefault(_current_kind[0], Counter())[label] += 1
    if currently_in_test_context():
        _hypothesis_event(label)


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
            # So is a notice of how the file was read (quotes, a cut last row, ...): it names the file.
            warnings.filterwarnings("ignore", re.escape(str(path)), UserWarning)
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
