"""Fuzzing of the run log's CSV reader (``read_run``): mutated bytes, encodings, tokens
(numbers, header names, metadata keys and values) and extreme metadata.

The contract, the budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_text import CSV_META_VALUE, CSV_RULES, mutate_tokens
from fuzzing import _encodings, budget, fuzz_case, mutate_bytes
from hypothesis import given, strategies as st


@budget(300)
@given(data=st.data())
def test_mutated_bytes(data, bases, work):
    fuzz_case("csv", work, mutate_bytes(data, bases["csv"]))


def test_encodings_and_degenerate_files(bases, work):
    for _name, data in _encodings(bases["csv"]).items():
        fuzz_case("csv", work, data)


@budget(600)
@given(data=st.data())
def test_csv_token_mutations(data, bases, work):
    fuzz_case("csv", work, mutate_tokens(data, bases["csv"], CSV_RULES))


CSV_EXTREMES = [
    b"1e308",
    b"-1e308",
    b"5e-324",
    b"1e-300",
    b"1e20",
    b"-1e20",
    b"0",
    b"-0",
    b"nan",
    b"inf",
    b"-inf",
    b"90",
    b"-90",
    b"90.000001",
    b"1e6",
    b"9" * 400,
]


def test_csv_extreme_metadata(bases, work):
    """Every metadata value of a valid run log replaced by extreme and special values."""
    base = bases["csv"]
    for m in CSV_META_VALUE.finditer(base.split(b"\ntime_s")[0]):
        for value in CSV_EXTREMES:
            refusal = fuzz_case("csv", work, base[: m.start()] + value + base[m.end() :])
            if refusal is not None:
                assert ", line " in str(refusal), str(refusal)  # the metadata line
