"""How a logger writes its rows, read into plain comma-separated fields.

Loggers write the same numbers in many ways. Before the columns are read, the
rows under the header are brought to one form: fields between commas, no
quotes, decimal points.

- Fields between ``;`` or tabs (a spreadsheet in a locale that writes decimal
  commas: ``0,25;1,5``), or between spaces under a header written the same
  way (``t ax ay az gx gy gz``), are put between commas (`to_commas`).
- Fields in double quotes (``"0.010","-8.42"``, as spreadsheets export) lose
  their quotes; a quoted decimal comma (``"0,25"``) is read as a point
  (`unquoted`).
- A row that repeats the header (a logger restarted and appended to its
  file) is not a sample: it is read as a blank line, said on stderr
  (`without_repeated_headers`). Rows after it go on as they are; a clock
  that restarts there is refused by the clock's checks.

Each is said on stderr, so a user sees how the file was read. Line numbers
are kept: a message about a row names the file's own line.
"""

from __future__ import annotations

import csv
import re
import warnings

from .text import is_comment

ROWS_LOOKED_AT = 100  # rows read to judge how a file writes its fields


def _body(lines: list[str], header_index: int) -> list[str]:
    return [row for row in lines[header_index + 1 : header_index + 1 + ROWS_LOOKED_AT] if row.strip()]


def to_commas(lines: list[str], header_index: int, name: str) -> list[str]:
    """Lines of a CSV written with ``;``, tabs or spaces between fields, rewritten with commas.

    A semicolon- or tab-separated file from a locale that writes decimal commas
    (``0,25;1,5``) has its decimal commas read as points. A header whose names
    are separated by spaces is read so when the rows below it split into as many
    fields at white space (and have no commas).
    """
    header = lines[header_index]
    if "," in header:
        return lines
    sep = next((c for c in (";", "\t") if c in header), None)
    body = lines[header_index + 1 :]
    if sep is None:
        return _spaces_to_commas(lines, header_index, name)
    decimal_commas = any("," in row for row in body[:ROWS_LOOKED_AT])  # no field separator: a decimal comma
    if decimal_commas:
        body = [row.replace(",", ".") for row in body]
    warnings.warn(
        f"{name}: fields separated by {'tabs' if sep == chr(9) else repr(sep)}"
        f"{' with decimal commas' if decimal_commas else ''}; read as such",
        stacklevel=3,
    )
    return lines[:header_index] + [row.replace(sep, ",") for row in [header] + body]


def _spaces_to_commas(lines: list[str], header_index: int, name: str) -> list[str]:
    names = lines[header_index].split()
    rows = _body(lines, header_index)
    if len(names) < 2 or not rows or any("," in row or len(row.split()) != len(names) for row in rows):
        return lines
    warnings.warn(f"{name}: fields separated by spaces; read as such", stacklevel=4)
    return lines[:header_index] + [",".join(names)] + [_spaced(row) for row in lines[header_index + 1 :]]


def _spaced(row: str) -> str:
    return row if not row.strip() or is_comment(row) else ",".join(row.split())


def unquoted(lines: list[str], header_index: int, name: str) -> list[str]:
    """The rows below the header with double quotes around fields taken off (comma-separated rows).

    A field in quotes may hold a decimal comma (``"0,25"``): it is read as a point,
    since within quotes a comma separates nothing.
    """
    if not any('"' in row for row in _body(lines, header_index)):
        return lines
    sep = next((c for c in (",", ";", "\t") if c in lines[header_index]), ",")
    out = lines[: header_index + 1]
    for row in lines[header_index + 1 :]:
        if '"' not in row or is_comment(row):
            out.append(row)
            continue
        fields = next(csv.reader([row], delimiter=sep))
        out.append(sep.join(f.strip().replace(",", ".") for f in fields))  # a comma inside quotes: decimal
    warnings.warn(f"{name}: fields in double quotes; read without them", stacklevel=3)
    return out


def without_repeated_headers(lines: list[str], header_index: int, name: str) -> list[str]:
    """The lines with rows that repeat the header row blanked (read as no sample), said on stderr."""
    header = _normal(lines[header_index])
    again = [k for k in range(header_index + 1, len(lines)) if _normal(lines[k]) == header]
    if not again:
        return lines
    out = list(lines)
    for k in again:
        out[k] = ""
    at = ", ".join(str(k + 1) for k in again[:5]) + (f" and {len(again) - 5} more" if len(again) > 5 else "")
    warnings.warn(
        f"{name}: line(s) {at} repeat the header row (a logger that started again and appended?); "
        "left out, the rows around them read as samples",
        stacklevel=3,
    )
    return out


def _normal(line: str) -> str:
    return re.sub(r"\s+", " ", line.strip())
