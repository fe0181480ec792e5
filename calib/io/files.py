"""Small file helpers: atomic writes and content hashes.

A file the tool writes is either complete or absent: a crash, a full disk or
Ctrl-C half way through never leaves a truncated run log or result behind
that a later command would trust.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from pathlib import Path
from typing import IO

from calib.errors import CalibError


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` so that the file is either complete or untouched.

    The bytes go to a temporary file in the same directory (so that the final
    rename stays on one file system), are flushed to disk, and the temporary
    file then replaces ``path`` in one step. On any exception, including
    ``KeyboardInterrupt``, the temporary file is removed and an existing
    ``path`` keeps its old content.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its directory must exist.
    data : bytes
        Complete new content.

    Raises
    ------
    CalibError
        If the file cannot be written (missing directory, no permission,
        disk full, ...).
    """
    atomic_write_file(path, lambda handle: handle.write(data))


def atomic_write_file(path: str | os.PathLike, write, text: bool = False):
    """Let ``write(handle)`` fill an open file, flushed to disk and put at ``path`` in one step.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its directory must exist.
    write : callable
        Called with the open temporary file; may write it a block at a time.
    text : bool
        Open the file for text (UTF-8, LF newlines on every platform)
        rather than bytes.

    Returns
    -------
    object
        What ``write`` returned.
    """

    def produce(tmp_name: str):
        handle: IO
        handle = open(tmp_name, "w", encoding="utf-8", newline="\n") if text else open(tmp_name, "wb")
        with handle:
            out = write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        return out

    return atomic_write_with(path, produce)


def atomic_write_with(path: str | os.PathLike, write):
    """Let ``write(tmp_path)`` produce the file, then put it at ``path`` in one step.

    The temporary file lies in the same directory (the rename stays on one
    file system); on any exception, including ``KeyboardInterrupt``, it is
    removed and an existing ``path`` keeps its old content. For writers that
    stream (a long simulated run) as well as for :func:`atomic_write_bytes`.

    Returns
    -------
    object
        What ``write`` returned.
    """
    target = Path(path)
    directory = target.parent
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
        os.close(fd)
    except OSError as exc:
        raise CalibError(
            f"cannot write the file: {exc.strerror or exc}",
            str(target),
            "check that the directory exists and is writable",
        ) from exc
    try:
        out = write(tmp_name)
        # mkstemp creates the file private (0600); give it the permissions an
        # ordinary open() would, so results can be shared like any other file.
        os.chmod(tmp_name, default_mode(target))
        os.replace(tmp_name, target)
    except BaseException as exc:
        remove_quietly(tmp_name)
        if isinstance(exc, OSError):
            raise CalibError(
                f"cannot write the file: {exc.strerror or exc}",
                str(target),
                "check free disk space and permissions",
            ) from exc
        raise
    _fsync_directory(directory)
    return out


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    r"""Write ``text`` as UTF-8 to ``path`` atomically (see `atomic_write_bytes`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file. Its directory must exist.
    text : str
        Complete new content; newlines are written as ``"\\n"`` on every
        platform so files compare equal across machines.
    """
    atomic_write_bytes(path, text.encode("utf-8"))


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's content, to tie a result to the exact run it came from.

    Parameters
    ----------
    path : str or os.PathLike
        File to hash.

    Returns
    -------
    str
        64 lowercase hex digits.

    Raises
    ------
    CalibError
        If the file cannot be read.
    """
    try:
        with open(path, "rb") as handle:
            return hashlib.file_digest(handle, "sha256").hexdigest()
    except OSError as exc:
        raise CalibError(
            f"cannot read the file: {exc.strerror or exc}", str(path), "check the path and permissions"
        ) from exc


def default_mode(target: Path) -> int:
    """Permission bits for ``target``: keep an existing file's, else 0666 minus umask."""
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        pass
    # The umask can only be read by setting it; restore it at once.
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def remove_quietly(name: str) -> None:
    """Remove a temporary file; it may already be gone."""
    try:
        os.unlink(name)
    except OSError:
        pass


def _fsync_directory(directory: Path) -> None:
    """Make the rename itself durable where the OS allows it (POSIX)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return  # e.g. Windows cannot open directories; the rename is still atomic
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def load_toml(path: str | os.PathLike) -> dict:
    """Parse a TOML file; every way it can fail becomes a :class:`CalibError` naming the file."""
    import tomllib

    where = str(path)
    try:
        return tomllib.loads(Path(path).read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        line = exc.object.count(b"\n", 0, exc.start) + 1
        raise CalibError(
            f"not UTF-8 text (line {line}, byte {exc.start})", where, "save the file as UTF-8"
        ) from None
    except tomllib.TOMLDecodeError as exc:
        raise CalibError(f"not valid TOML: {exc}", where) from None
    except ValueError as exc:  # tomllib: an integer of more than 4300 digits
        raise CalibError(
            f"not valid TOML: {str(exc).split(';')[0]}", where, "write numbers with fewer digits"
        ) from None
    except RecursionError:
        raise CalibError("not valid TOML: arrays or tables nested too deeply", where) from None
    except OSError as exc:
        raise CalibError(f"cannot read: {exc.strerror}", where) from None


def toml_number(value) -> float | None:
    """A TOML value as a float, or None if it is not a number (booleans are not).

    An integer beyond the float range becomes +-inf, so callers that demand a
    finite number refuse it with their own message.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def check_writable_dir(path: str | os.PathLike, where: str) -> None:
    """Refuse, before any long computation, an output whose folder is missing or read-only."""
    directory = Path(path).parent if str(Path(path).parent) else Path(".")
    if not directory.is_dir():
        raise CalibError(
            f"folder {str(directory)!r} does not exist", where, "create it first or choose another path"
        )
    if not os.access(directory, os.W_OK | os.X_OK):
        raise CalibError(
            f"folder {str(directory)!r} is not writable", where, "choose a folder you can write to"
        )
