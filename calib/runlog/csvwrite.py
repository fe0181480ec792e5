"""Writing the CSV run log: metadata lines, the header row, one shortest-repr row per sample."""

from __future__ import annotations

import numpy as np

from calib.errors import CalibError

from .format import FORMAT, GIMBAL_COLUMNS, REQUIRED_COLUMNS


def write_csv(handle, meta: dict[str, str], windows, gimbal: bool = False) -> int:
    """Write a CSV run log to an open text handle: metadata (format first), header, rows.

    Parameters
    ----------
    handle : file object
        Open for writing text (UTF-8, LF newlines).
    meta : dict of str to str
        Metadata; ``format`` is written first whatever its place.
    windows : iterable of tuple of numpy.ndarray
        Consecutive blocks ``(time_s, dtheta_rad, dv_mps)``, with ``gimbal_deg``
        appended when ``gimbal``: the whole run in one block, or a long run a
        block at a time.
    gimbal : bool
        Write the gimbal encoder columns.

    Returns
    -------
    int
        Number of samples written.
    """
    header = REQUIRED_COLUMNS + (GIMBAL_COLUMNS if gimbal else ())
    meta_lines = [f"# format: {FORMAT}"]
    meta_lines += [f"# {key}: {value}" for key, value in meta.items() if key != "format"]
    handle.write("\n".join(meta_lines) + "\n" + ",".join(header) + "\n")
    n = 0
    for window in windows:
        handle.write(_csv_rows(window))
        n += len(window[0])
    return n


def _csv_rows(columns) -> str:
    """Shortest-repr rows of a block of columns, one line per sample."""
    table = np.hstack([np.asarray(c, dtype=np.float64).reshape(len(c), -1) for c in columns])
    if not len(table):
        return ""
    # repr() is the shortest text that reads back to the same float, and
    # mapping it column by column is as fast as np.savetxt('%.17g').
    text_columns = [list(map(repr, column)) for column in table.T.tolist()]
    return "\n".join(map(",".join, zip(*text_columns, strict=True))) + "\n"


def check_meta_writable_as_csv(meta: dict[str, str], name: str) -> None:
    """Refuse metadata that would not read back the same from '# key: value' lines."""
    for key, value in meta.items():
        if not key or key != key.strip() or ":" in key or "\n" in key or "\r" in key:
            raise CalibError(
                f"metadata key {key!r} cannot be written as '# key: value'",
                name,
                "use keys without ':', line breaks or surrounding spaces",
            )
        if "\n" in value or "\r" in value:
            raise CalibError(
                f"metadata '{key}' contains a line break", name, "keep metadata values on one line"
            )
