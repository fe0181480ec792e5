"""What kind of file a user gave, so that a wrong one is named as what it is.

A result given to ``show``, a run given to ``analyze`` or a truth file given
to ``calibrate`` would otherwise be refused for a missing key. The readers
call :func:`expect` first: it looks at the suffix and, for TOML, at the
tables and keys that only one kind of file has.
"""

from __future__ import annotations

import os
from pathlib import Path

from calib.errors import CalibError

# For each TOML kind, a key or table that marks it (checked in this order). A result is
# marked first by its [parameters]; its [initial_attitude] alone marks it only after every
# other kind, so that a sequence which borrowed that table is still read as a sequence.
_TOML_MARKS = (
    ("result", ("parameters",)),
    ("truth", ("errors",)),
    ("poses", ("pose",)),  # before sequence: its keys (hold_s) are no sequence's
    ("sequence", ("step", "start")),
    ("requirements", ("requirements",)),
    ("profile", ("gyro_arw_dph", "accel_vrw_ug")),
    ("gimbal", ("outer", "middle", "inner")),
    ("result", ("initial_attitude",)),
)
_WHAT = {
    "result": "a calibration result (what calibrate writes)",
    "truth": "a truth file (what simulate writes beside a run)",
    "sequence": "a sequence file",
    "poses": "a pose list, for a run placed by hand (read with --by-hand)",
    "requirements": "a requirements file",
    "profile": "a noise profile",
    "gimbal": "a gimbal description",
    "run": "a run log",
    "psins": "a PSINS .imu log",
    "unknown": "an unknown file",
}
_FIX = {
    "sequence": "give a sequence file (.toml with start and [[step]]) or a shipped name",
    "run": "give the run log (.csv, .csv.gz, .npz or .imu) that simulate or a logger wrote",
    "result": "give the result TOML that calibrate wrote",
    "profile": "give a profile TOML or a built-in name",
}


def kind_of(path: str | os.PathLike) -> str:
    """``run``, ``psins``, ``result``, ``truth``, ``poses``, ``sequence``, ``requirements``,
    ``profile``, ``gimbal`` or ``unknown``, from the suffix and, for TOML, the top-level keys.
    """
    name = str(path).lower()
    if name.endswith((".csv", ".csv.gz", ".npz")):
        return "run"
    if name.endswith(".imu"):
        return "psins"
    if not name.endswith(".toml"):
        return "unknown"
    try:
        import tomllib

        doc = tomllib.loads(Path(path).read_text("utf-8"))
    except (OSError, ValueError, UnicodeDecodeError, RecursionError):
        return "unknown"  # the reader itself says what is wrong with it
    for kind, marks in _TOML_MARKS:
        if any(m in doc for m in marks):
            return kind
    return "unknown"


def expect(path: str | os.PathLike, wanted: str) -> None:
    """Refuse a file that is recognisably of another kind than ``wanted``, naming it."""
    if not Path(path).is_file():
        return
    kind = kind_of(path)
    same = kind == wanted or (wanted == "run" and kind == "psins") or kind == "unknown"
    if not same:
        raise CalibError(
            f"this is {_WHAT[kind]}, not {_WHAT[wanted]}",
            str(path),
            _FIX.get(wanted, f"give {_WHAT[wanted]}"),
        )
