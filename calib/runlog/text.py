"""A log file's bytes as lines: UTF-8 (a BOM allowed), CRLF read as LF, a last row cut short left out."""

from __future__ import annotations

import re
import warnings

from calib.errors import CalibError

from .format import FORMAT

# Ours, C-style loggers' (Xsens MT Manager's "// Update Rate: ...") and MATLAB's "% " (ROS's
# `rostopic echo -p` header, "%time,field...", has no space after its "%": it is a header row).
COMMENT_MARKS = ("#", "//", "% ")


# Xsens MT Manager's export states its output rate among its preamble's comments.
_UPDATE_RATE = re.compile(r"^//\s*update rate\s*:\s*([0-9]+(?:\.[0-9]*)?)\s*hz\s*$", re.IGNORECASE)


def logger_rate(lines: list[str], header_index: int) -> tuple[float, int] | None:
    """The output rate a logger's preamble states, and its 1-based line; None if none does.

    Xsens MT Manager writes ``// Update Rate: 100.0Hz`` above its header row (its
    older exports; the 2022 ones state no rate).
    """
    for index, line in enumerate(lines[:header_index]):
        found = _UPDATE_RATE.match(line.strip())
        if found and float(found.group(1)) > 0.0:
            return float(found.group(1)), index + 1
    return None


def is_comment(line: str) -> bool:
    """Whether a line above (or among) the rows is a comment: ``#``, ``//``, or ``%`` and a space, first."""
    return line.lstrip().startswith(COMMENT_MARKS)


def decode_lines(data: bytes, name: str) -> list[str]:
    """UTF-8 (optional BOM) to lines split on LF; CRLF files read the same."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise CalibError(
            f"byte 0x{data[exc.start]:02x} is not valid UTF-8 (byte offset {exc.start})",
            f"{name}, line {line}",
            "save the file as UTF-8",
        ) from None
    if not text.strip():
        raise CalibError(
            "the file is empty",
            name,
            f"a run log starts with '# format: {FORMAT}', metadata, a header row and one row per sample",
        )
    if "\r" in text:
        text = text.replace("\r\n", "\n")
    return text.split("\n")


def without_cut_last_row(lines: list[str], name: str) -> list[str]:
    """The lines less a last row a logger left unfinished, said on stderr.

    A logger stopped mid-write (power cut, Ctrl-C) leaves a last row with fewer fields
    than the row before it and no line end. Only that row, and only then, is left out:
    a short row anywhere else, or one the file ends properly, is refused by the reader
    as it was written. Fields are counted at the separator the row before uses (a
    semicolon, a tab, a comma, else spaces), so a decimal comma is no separator.
    """
    if not lines or not lines[-1].strip() or is_comment(lines[-1]):  # ends with a line end
        return lines
    before = next((line for line in reversed(lines[:-1]) if line.strip()), None)
    if before is None or is_comment(before):
        return lines
    sep = next((c for c in (";", "\t", ",") if c in before), None)

    def count(line: str) -> int:
        return len([f for f in (line.split(sep) if sep else re.split(r"\s+", line.strip())) if f.strip()])

    have, want = count(lines[-1]), count(before)
    if have >= want:
        return lines
    warnings.warn(
        f"{name}, line {len(lines)}: the last row has {have} of {want} fields and no line end "
        "(the logger stopped mid-row); it is left out",
        stacklevel=3,
    )
    return lines[:-1]


def header_names(line: str) -> list[str]:
    """A header row's names: split at commas, each stripped of spaces and of one pair of double
    quotes around it (``"Time (s)"``, as phyphox and spreadsheets write names with spaces).
    """
    names = [field.strip() for field in line.strip().split(",")]
    return [n[1:-1].strip() if len(n) >= 2 and n[0] == n[-1] == '"' else n for n in names]
