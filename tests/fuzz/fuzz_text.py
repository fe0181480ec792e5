"""Token rules and random documents for fuzzing the text formats (TOML and CSV).

The token-level mutations (numbers, strings, keys, tables, lines replaced, dropped or
repeated), the TOML and CSV token tables and rules, the documents that break the parsers
themselves, and the random TOML documents (schema-aware edits of valid ones, and from
scratch). The shared checks of extreme numbers and hostile TOML run one reader's cases.
"""

from __future__ import annotations

import copy
import math
import re
import tomllib
from pathlib import Path

import tomli_w
from fuzzing import fuzz_case
from hypothesis import strategies as st

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


def extreme_numbers(kind: str, bases: dict[str, bytes], work: Path) -> None:
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


def hostile_toml(kind: str, bases: dict[str, bytes], work: Path) -> None:
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
