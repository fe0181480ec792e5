"""The NPZ run log: one reader and one writer, for whole runs and for runs read a chunk at a time.

A refusal names the file and the array element (``dv_mps[12, 1]``) or the
metadata key. Pickled content is never loaded.
"""

from __future__ import annotations

import functools
import json
import lzma
import os
import tempfile
import tokenize
import zipfile
import zlib
from dataclasses import replace

import numpy as np

from calib.errors import CalibError

from .checks import ArrayLocator, check_array_shape, check_meta, check_samples
from .format import NPZ_ARRAYS
from .paths import require_file
from .run import Run

# For the chunk reader, which reads members as streams.
NPZ_FIX = "write the file with numpy.savez (time_s, dtheta_rad, dv_mps, meta), or use CSV"

# Everything numpy/zipfile raise for a damaged or foreign file: RuntimeError covers
# an encrypted member and (NotImplementedError) an unknown compression method,
# LZMAError a damaged LZMA member, MemoryError a header that declares a huge shape;
# numpy parses the .npy header as a Python literal, which adds TokenError,
# SyntaxError, TypeError (e.g. an unhashable key) and RecursionError.
_ARCHIVE_ERRORS = (
    OSError,
    ValueError,
    EOFError,
    KeyError,
    zipfile.BadZipFile,
    zlib.error,
    RuntimeError,
    lzma.LZMAError,
    MemoryError,
    tokenize.TokenError,
    SyntaxError,
    TypeError,
    RecursionError,
)

# How a zip archive (empty or not) and a single .npy array start.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_MAGIC = b"\x93NUMPY"


def read_npz(path: str | os.PathLike, allow_gaps: bool) -> Run:
    """Read an NPZ run log; pickled content is never loaded."""
    name = str(path)
    require_file(path)
    arrays = _load_npz_arrays(path, name)
    meta = parse_npz_meta(arrays.pop("meta"), name)
    n = arrays["time_s"].shape[0] if arrays["time_s"].ndim >= 1 else 0
    for array_name, array in arrays.items():
        check_array_shape(array, array_name, n, f"{name}, array '{array_name}'")
    with np.errstate(over="ignore"):  # e.g. longdouble beyond float64: inf, refused below
        as_float = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()}
    run = Run(
        time_s=as_float["time_s"],
        dtheta_rad=as_float["dtheta_rad"],
        dv_mps=as_float["dv_mps"],
        meta=meta,
        gimbal_deg=as_float.get("gimbal_deg"),
        source=name,
    )
    locate = ArrayLocator(name)
    check_meta(meta, locate)
    return replace(run, clock=check_samples(run, locate, allow_gaps))


def _load_npz_arrays(path: str | os.PathLike, name: str) -> dict[str, np.ndarray]:
    """The run's arrays from an NPZ archive, refusing damaged, foreign or pickled content."""
    fix = "write the file again with numpy.savez, or use the CSV format"
    # Open the file ourselves: np.load leaks its handle when the zip is damaged.
    try:
        handle = open(path, "rb")
    except OSError as exc:
        raise CalibError(
            f"cannot read the file: {exc.strerror or exc}", name, "check the path and permissions"
        ) from None
    with handle:
        try:
            head = handle.read(len(_NPY_MAGIC))
            handle.seek(0)
        except OSError as exc:
            raise CalibError(
                f"cannot read the file: {exc.strerror or exc}", name, "check the path and permissions"
            ) from None
        if not head:
            raise CalibError("not a readable NPZ archive: the file is empty", name, fix)
        if not head.startswith(_ZIP_MAGIC) and not head.startswith(_NPY_MAGIC):
            raise CalibError(
                "not a readable NPZ archive: the file does not start with a zip signature", name, fix
            )
        try:
            archive = np.load(handle, allow_pickle=False)
        except _ARCHIVE_ERRORS as exc:
            raise CalibError(f"not a readable NPZ archive: {exc}", name, fix) from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise CalibError("the file is a single .npy array, not an NPZ archive", name, fix)
        with archive:
            present = set(archive.files)
            missing = [a for a in (*NPZ_ARRAYS, "meta") if a not in present]
            if missing:
                raise CalibError(
                    f"archive lacks array{'s' if len(missing) > 1 else ''} "
                    f"{', '.join(repr(m) for m in missing)}",
                    name,
                    "store time_s, dtheta_rad, dv_mps and meta (see docs/formats.md)",
                )
            arrays = {}
            for a in (*NPZ_ARRAYS, "gimbal_deg", "meta"):
                if a not in present:
                    continue
                try:
                    arrays[a] = archive[a]
                except _ARCHIVE_ERRORS as exc:
                    raise CalibError(
                        f"cannot read the archive member: {exc}", f"{name}, array '{a}'", fix
                    ) from None
    for a, array in arrays.items():
        # numpy hands back the raw bytes of a member that is not in .npy format.
        if not isinstance(array, np.ndarray):
            raise CalibError(
                f"archive member '{a}.npy' is not a numpy array (.npy format)", f"{name}, array '{a}'", fix
            )
    return arrays


def parse_npz_meta(array: np.ndarray, name: str) -> dict[str, str]:
    """Decode the ``meta`` array: one JSON object of string (or number) values."""
    where = f"{name}, array 'meta'"
    fix = "store meta as a JSON object string, e.g. json.dumps(run.meta)"
    if array.size != 1 or array.dtype.kind not in "US":
        raise CalibError(
            f"meta is a {array.dtype} array of shape {array.shape}, not one JSON string", where, fix
        )
    text = array.reshape(()).item()
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError:
            raise CalibError("meta is not valid UTF-8", where, fix) from None
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibError(
            f"meta is not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})", where, fix
        ) from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise CalibError(f"meta is not valid JSON ({str(exc).split(';')[0]})", where, fix) from None
    except RecursionError:
        raise CalibError("meta is not valid JSON (nested too deeply)", where, fix) from None
    if not isinstance(raw, dict):
        raise CalibError(f"meta is a JSON {type(raw).__name__}, not an object", where, fix)
    meta: dict[str, str] = {}
    for key, value in raw.items():
        if isinstance(value, str):
            meta[key] = value
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            # Other programs may store numbers as numbers; keep them exactly.
            meta[key] = repr(value)
        else:
            raise CalibError(
                f"meta value {value!r} is neither a string nor a number", f"{name}, meta key '{key}'", fix
            )
    return meta


def npz_meta(path) -> dict[str, str]:
    """The metadata of an NPZ run log, without reading its samples."""
    where = str(path)
    try:
        with zipfile.ZipFile(path) as archive, archive.open("meta.npy") as member:
            array = np.lib.format.read_array(member, allow_pickle=False)
    except (OSError, zipfile.BadZipFile, KeyError, ValueError) as exc:
        raise CalibError(f"not a readable NPZ run log ({exc})", where, NPZ_FIX) from None
    return parse_npz_meta(array, where)


def _npy_stream(archive: zipfile.ZipFile, name: str, where: str):
    """An open member positioned at its data, with its shape and dtype."""
    try:
        member = archive.open(f"{name}.npy")
    except KeyError:
        raise CalibError(f"archive lacks array '{name}'", where, NPZ_FIX) from None
    version = np.lib.format.read_magic(member)
    read_header = (
        np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    )
    shape, fortran, dtype = read_header(member)
    if fortran or dtype.kind not in "fiu" or len(shape) not in (1, 2):
        raise CalibError(
            f"array '{name}' is {dtype} of shape {shape}{' in Fortran order' if fortran else ''}",
            where,
            NPZ_FIX,
        )
    return member, shape, dtype


def npz_chunks(path, rows: int):
    """Yield ``(time_s, dtheta_rad, dv_mps)`` blocks of ``rows`` samples, members read as streams."""
    where = str(path)
    try:
        archive = zipfile.ZipFile(path)
    except (OSError, zipfile.BadZipFile) as exc:
        raise CalibError(f"not a readable NPZ run log ({exc})", where, NPZ_FIX) from None
    with archive:
        streams = [_npy_stream(archive, name, where) for name in NPZ_ARRAYS]
        n = streams[0][1][0]
        if any(s[1] != (n,) + ((3,) if i else ()) for i, s in enumerate(streams)):
            raise CalibError(
                "time_s, dtheta_rad and dv_mps do not have shapes (n,), (n, 3), (n, 3)", where, NPZ_FIX
            )
        for a in range(0, n, rows):
            m = min(rows, n - a)
            out = []
            for member, shape, dtype in streams:
                width = 1 if len(shape) == 1 else 3
                data = member.read(m * width * dtype.itemsize)
                out.append(
                    np.frombuffer(data, dtype).astype(np.float64).reshape((m,) if width == 1 else (m, 3))
                )
            yield tuple(out)
        for member, _, _ in streams:
            member.close()


# --------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------


def write_npz(handle, meta: dict[str, str], windows, gimbal: bool = False) -> int:
    """Write an uncompressed NPZ run log to an open binary handle, one member at a time.

    Parameters
    ----------
    handle : file object
        Open for writing bytes (and seeking).
    meta : dict of str to str
        Metadata, stored as one JSON string (member ``meta``).
    windows : list or iterable of tuple of numpy.ndarray
        Consecutive blocks ``(time_s, dtheta_rad, dv_mps)``, with ``gimbal_deg``
        appended when ``gimbal``. A list of one block (a run in memory) goes
        straight into the archive; other blocks are first spooled to scratch
        files beside the output, since a member's header states its length.
    gimbal : bool
        Store the gimbal encoder angles (member ``gimbal_deg``).

    Returns
    -------
    int
        Number of samples written.
    """
    names = (*NPZ_ARRAYS, "gimbal_deg") if gimbal else NPZ_ARRAYS
    if isinstance(windows, (list, tuple)) and len(windows) == 1:
        columns = [np.ascontiguousarray(c, dtype="<f8") for c in windows[0]]
        n = len(columns[0])
        _write_members(handle, meta, n, names, [[c.data.cast("B")] for c in columns])
        return n
    folder = os.path.dirname(os.path.abspath(handle.name)) if hasattr(handle, "name") else None
    scratch = [tempfile.TemporaryFile(dir=folder) for _ in names]
    n = 0
    try:
        for window in windows:
            for spool, column in zip(scratch, window, strict=True):
                spool.write(np.ascontiguousarray(column, dtype="<f8").tobytes())
            n += len(window[0])
        for spool in scratch:
            spool.seek(0)
        _write_members(
            handle, meta, n, names, [iter(functools.partial(s.read, 1 << 24), b"") for s in scratch]
        )
    finally:
        for spool in scratch:
            spool.close()
    return n


def _write_members(handle, meta: dict[str, str], n: int, names, blocks) -> None:
    """The archive: each named ``(n,)`` or ``(n, 3)`` float64 column from its byte blocks, then ``meta``.

    As ``numpy.savez`` writes it: stored (not deflated), ZIP64 members, ``.npy``
    version 1.0 headers.
    """
    with zipfile.ZipFile(handle, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
        for name, column in zip(names, blocks, strict=True):
            shape = (n,) if name == "time_s" else (n, 3)
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array_header_1_0(
                    member, {"descr": "<f8", "fortran_order": False, "shape": shape}
                )
                for block in column:
                    member.write(block)
        with archive.open("meta.npy", "w", force_zip64=True) as member:
            np.lib.format.write_array(member, np.array(json.dumps(meta, ensure_ascii=False)))
