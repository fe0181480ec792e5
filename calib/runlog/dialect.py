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
- Lines above the header row that hold no samples (Excel's ``sep=,`` declaration, a
  logger's ``DeviceTag:,Xsens DOT`` or ``Fs,100`` lines) when the column map's names are on
  a later line are that logger's preamble, said on stderr (`past_preamble`); a row of
  units right under the header (Shimmer's ``ms,m/(s^2),...``) is left out, said
  (`without_units_row`).
- Rows of ``label:value`` pairs (an Arduino's Serial Plotter lines, ``t:3456789,ax:-0.03,...``)
  the same labels on every row, are read with the labels as the header (`labelled_rows`).
- Rows of numbers among fixed text (an example sketch's ``Scaled. Acc (mg) [ -00003.69, ... ]``)
  are read as their numbers, by position, when the rows share that text (`templated_rows`).
- A row that repeats the header (a logger restarted and appended to its
  file) is not a sample: it is read as a blank line, said on stderr
  (`without_repeated_headers`). Rows after it go on as they are; a clock
  that restarts there is refused by the clock's checks.

Each is said on stderr, so a user sees how the file was read. Line numbers
are kept: a message about a row names the file's own line.
"""

from __future__ import annotations

import collections
import csv
import re
import warnings

from .text import is_comment
from .wallclock import CLOCK_FORM

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
        f"{name}: line(s) {at} repeat the header row (a logger that started again and appended, or one "
        "block per sensor as RealSense's rs-convert writes: split the file there?); left out, the rows "
        "around them read as samples",
        stacklevel=3,
    )
    return out


def _normal(line: str) -> str:
    return re.sub(r"\s+", " ", line.strip())


# Excel's declaration of the separator, a file's first line: sep=, or "sep=\t" (Shimmer, Movella DOT).
_SEP_LINE = re.compile(r'^"?sep=.?"?$')
PREAMBLE_LINES = 50  # lines searched below the first for the one the column map names


def _names(line: str) -> list[str]:
    """A line's fields as names, at commas, semicolons or tabs (else spaces), each without quotes."""
    text = line.strip()
    fields = re.split(r"[,;\t]", text) if re.search(r"[,;\t]", text) else text.split()
    return [f.strip().strip('"').strip() for f in fields]


def _holds_numbers(line: str) -> bool:
    """Whether a line is a row of numbers (a sample), not a preamble's text."""
    fields = [f for f in _names(line) if f]
    return bool(fields) and all(_is_number(f) for f in fields)


def _is_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def past_preamble(lines: list[str], header_index: int, mapping: dict[str, str], name: str) -> int:
    """The header row's index past a logger's own preamble lines, said on stderr.

    Excel's ``sep=`` line is always one. Other lines are when the column map names columns the
    first line lacks and a later line has, and no line between them is a row of numbers (a
    sample above a header is no preamble: the reader then says which line holds the names).
    """
    first = header_index
    if _SEP_LINE.match(lines[header_index].strip()):
        later = [
            k for k in range(header_index + 1, len(lines)) if lines[k].strip() and not is_comment(lines[k])
        ]
        if not later:
            return header_index
        header_index = later[0]
    named = [k for k in mapping if not k.isdigit()]
    if (
        named
        and not _holds_numbers(lines[header_index])
        and not all(k in _names(lines[header_index]) for k in named)
    ):
        for k in range(header_index + 1, min(len(lines), header_index + PREAMBLE_LINES)):
            if _holds_numbers(lines[k]):
                break
            if all(key in _names(lines[k]) for key in named):
                header_index = k
                break
    if header_index != first:
        said = f"line {first + 1}" if header_index == first + 1 else f"lines {first + 1}-{header_index}"
        warnings.warn(
            f"{name}: {said} above the header row (line {header_index + 1}) read as the logger's preamble",
            stacklevel=3,
        )
    return header_index


def without_units_row(lines: list[str], header_index: int, name: str) -> list[str]:
    """The lines with a row of units right under the header blanked (``ms,m/(s^2),deg/s``), said.

    Only that row, and only when none of its fields is a number and it has as many as the
    header: text anywhere else among the rows is refused by the reader, at its line.
    """
    k = next((k for k in range(header_index + 1, len(lines)) if lines[k].strip()), None)
    if k is None or is_comment(lines[k]) or _names(lines[k]) == _names(lines[header_index]):
        return lines  # a comment, or the header again (the repeated-header rule says it)
    fields, header = _names(lines[k]), _names(lines[header_index])
    if _holds_numbers(lines[header_index]) or len(fields) != len(header) or not any(fields):
        return lines  # rows without a header, or a row unlike the header's
    if any(_is_number(f) for f in fields if f):
        return lines
    warnings.warn(
        f"{name}, line {k + 1}: a row of no numbers under the header ({', '.join(f for f in fields[:4] if f)}"
        f"{', ...' if len(fields) > 4 else ''}: its units?); left out",
        stacklevel=3,
    )
    return lines[:k] + [""] + lines[k + 1 :]


_PAIR = re.compile(r"^\s*([A-Za-z_][\w.\[\]()/-]*)\s*:\s*([-+]?[\d.]+(?:[eE][-+]?\d+)?)\s*$")


def _pairs(line: str) -> list[tuple[str, str]] | None:
    """A row's ``(label, value)`` pairs, or None when it is not a row of them."""
    text = line.strip()
    fields = re.split(r"[,\t]", text) if re.search(r"[,\t]", text) else text.split()
    found = [_PAIR.match(f) for f in fields if f.strip()]
    if len(found) < 2 or not all(found):
        return None
    return [(m.group(1), m.group(2)) for m in found if m]


def labelled_rows(lines: list[str], header_index: int, name: str) -> tuple[list[str], int]:
    """Rows of ``label:value`` pairs as a header of their labels and rows of their values.

    The labels are those most rows carry in one order (an Arduino's Serial Plotter protocol); a
    first row holding only their last few (a capture cut mid-row) is left out, said, and any
    other row that does not carry them is left as it is, for the reader to refuse at its line.
    Returns the lines and the number put in above the rows (1 with the header, else 0).
    """
    first = _pairs(lines[header_index])
    if first is None:  # a capture cut mid-value ("6409,gx:0.41,..."): its pairs after the cut field
        first = _pairs(",".join(re.split(r"[,\t]", lines[header_index].strip())[1:]))
        if first is None or header_index + 1 >= len(lines) or _pairs(lines[header_index + 1]) is None:
            return lines, 0
    # The labels most rows carry: a serial capture's first line is often cut mid-row.
    seen = [_pairs(row) for row in lines[header_index : header_index + ROWS_LOOKED_AT] if row.strip()]
    runs = [tuple(label for label, _ in p) for p in seen if p is not None]
    labels = list(collections.Counter(runs).most_common(1)[0][0])
    head = [label for label, _ in first]
    cut = head != labels and labels[-len(head) :] == head
    out = lines[:header_index] + [",".join(labels)] + ([""] if cut else [])
    if cut:
        warnings.warn(
            f"{name}, line {header_index + 1}: the first row holds the last {len(head)} of the {len(labels)} "
            "labels (a capture cut mid-row); left out",
            stacklevel=3,
        )
    for row in lines[header_index + (1 if cut else 0) :]:
        pairs = _pairs(row) if row.strip() and not is_comment(row) else None
        if pairs is not None and [label for label, _ in pairs] == labels:
            out.append(",".join(value for _, value in pairs))
        else:
            out.append(row)
    warnings.warn(
        f"{name}: rows of label:value pairs ({', '.join(labels[:3])}{', ...' if len(labels) > 3 else ''}); "
        "read with the labels as the header",
        stacklevel=3,
    )
    return out, 1


# A number standing alone (not part of a name such as MPU6050 or accel_x), nan and inf included;
# a clock time (an Arduino IDE's "23:13:20.030 -> " before each line) is one field.
_NUMBER = re.compile(
    r"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])|(?<!\w)(?:nan|inf)(?!\w)", re.I
)
# A clock time with its date, in the forms wallclock reads (ISO, MATLAB's 14-Nov-2023): one field.
_CLOCK = re.compile(r"(?<![\w.:])" + CLOCK_FORM)
TEMPLATE_SHARE = 0.9  # of the rows looked at, that share one text around their numbers


def _template(row: str) -> str:
    """The row's text with each number as ``{}`` and no white space (numbers print padded to a sign)."""
    return re.sub(r"\s+", "", _NUMBER.sub("{}", _CLOCK.sub("{t}", row)))


def _texted(row: str) -> bool:
    """Whether a field of the row holds text and a number together (no table's cell does)."""
    fields = re.split(r"[,;\t]", _CLOCK.sub("", row))
    return any(re.search(r"[A-Za-z]", _NUMBER.sub("", f)) and _NUMBER.search(f) for f in fields)


def templated_rows(lines: list[str], header_index: int, name: str) -> tuple[list[str], int]:
    """Rows of numbers among the same text, as comma-separated numbers (and clock times).

    A sketch's serial prints (``Scaled. Acc (mg) [ -00003.69,  00013.09, ... ], Gyr (DPS) [ ...``)
    hold the same text in every row, the numbers between. When most of the rows looked at share
    one such text, those rows become their fields by position (``1`` ... ``N``, as a file without
    a header) and the lines above the first of them are left out, said. Returns the lines and the
    index of the first row.
    """
    rows = [k for k in range(header_index, len(lines)) if lines[k].strip() and not is_comment(lines[k])]
    looked = rows[:ROWS_LOOKED_AT]
    if len(looked) < 3 or not _texted(lines[looked[-1]]):
        return lines, header_index
    templates = collections.Counter(_template(lines[k]) for k in looked)
    text, count = templates.most_common(1)[0]
    first = next(k for k in rows if _template(lines[k]) == text)  # a status line may come before
    # Fields counted at the rows' own separator: a status line of words is no header of as many.
    sep = next((c for c in (",", ";", "\t") if c in lines[first]), None)
    fields_of = lambda line: len(line.split(sep)) if sep else len(line.split())  # noqa: E731
    width = fields_of(lines[first])
    before = (k for k in range(header_index, first) if lines[k].strip())
    if width > 1 and any(fields_of(lines[k]) == width for k in before):
        return lines, header_index  # a table whose header names as many columns: a cell of text
    bare = text.replace("{}", "").replace("{t}", "")
    shared = count >= TEMPLATE_SHARE * sum(k >= first for k in looked)
    if not shared or not re.search(r"[A-Za-z]", bare) or text.count("{}") + text.count("{t}") < 3:
        return lines, header_index
    out = list(lines)
    for k in range(header_index, first):
        out[k] = ""
    for k in rows:
        if k >= first and _template(lines[k]) == text:
            fields = [m.group(0) for m in re.finditer(f"{_CLOCK.pattern}|{_NUMBER.pattern}", lines[k], re.I)]
            out[k] = ",".join(fields)
    above = f"line {first}" if first == header_index + 1 else f"lines {header_index + 1}-{first}"
    preamble = f"; {above} above them left out" if first > header_index else ""
    warnings.warn(
        f"{name}: rows of numbers among the same text ({text[:60]}{'...' if len(text) > 60 else ''}); "
        f"read as {text.count('{}') + text.count('{t}')} columns by position{preamble}",
        stacklevel=3,
    )
    return out, first
