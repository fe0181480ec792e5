"""Which run-log file a path is: its kind by suffix, that it exists, its bytes."""

from __future__ import annotations

import gzip
import os
import warnings
import zlib
from pathlib import Path

from calib.errors import CalibError

TEXT = (".txt", ".log", ".dat", ".tsv")  # a logger's text log, read as CSV (docs/logs-columns.md)


def run_kind(path: str | os.PathLike) -> str:
    """Lower-case suffix, refused unless .csv, .npz or .imu; a text log (.txt, .log, .dat) reads as .csv."""
    suffix = Path(path).suffix.lower()
    if suffix == ".gz" and Path(path).name.lower().endswith(tuple(s + ".gz" for s in (".csv", *TEXT))):
        return ".csv"  # read through gzip (read_bytes)
    if suffix in TEXT:
        return ".csv"  # a logger's text: columns by the CSV reader's rules (headerless too)
    if suffix not in (".csv", ".npz", ".imu"):
        raise CalibError(
            f"unknown run log type {suffix or '(no suffix)'!r}",
            str(path),
            "name run logs *.csv (interchange), *.npz (fast native) or *.imu (PSINS text, read only); "
            "a logger's text log may be *.txt, *.log, *.dat or *.tsv",
        )
    return suffix


def require_file(path: str | os.PathLike) -> None:
    """Refuse a missing path or a directory before a parser sees it."""
    if not Path(path).exists():
        raise CalibError("file not found", str(path), "check the path")
    if not Path(path).is_file():
        raise CalibError("not a regular file", str(path), "give the path of a run log file")


def read_bytes(path: str | os.PathLike) -> bytes:
    """Read a whole file, turning OS errors into CalibError.

    A gzip file that ends early (a logger or a copy stopped mid-write) gives the whole
    lines its stream holds before the cut, said on stderr.
    """
    require_file(path)
    try:
        data = Path(path).read_bytes()
        if data[:2] != b"\x1f\x8b":
            return data
        try:
            return gzip.decompress(data)
        except EOFError:
            held = zlib.decompressobj(zlib.MAX_WBITS | 16).decompress(data)
            held = held[: held.rfind(b"\n") + 1]  # the line the cut went through is not whole
            if not held:
                raise
            lines = held.count(b"\n")
            warnings.warn(
                f"{path}: the gzip stream ends early (cut mid-write?); read the {lines} whole lines it holds",
                stacklevel=2,
            )
            return held
    except (OSError, EOFError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
        raise CalibError(
            f"cannot read the file: {getattr(exc, 'strerror', None) or exc}",
            str(path),
            "check the path and permissions",
        ) from None
