"""Fuzzing of the calibration result (``CalibrationResult.load``): mutated bytes, encodings,
tokens, extreme numbers, hostile and random TOML documents.

The contract, the budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_text import (
    KEYS,
    TOML_RULES,
    VALUES,
    _doc,
    extreme_numbers,
    hostile_toml,
    mutate_doc,
    mutate_tokens,
    toml_bytes,
)
from fuzzing import _encodings, budget, fuzz_case, mutate_bytes
from hypothesis import given, strategies as st


@budget(300)
@given(data=st.data())
def test_mutated_bytes(data, bases, work):
    fuzz_case("result", work, mutate_bytes(data, bases["result"]))


def test_encodings_and_degenerate_files(bases, work):
    for _name, data in _encodings(bases["result"]).items():
        fuzz_case("result", work, data)


@budget(400)
@given(data=st.data())
def test_toml_token_mutations(data, bases, work):
    fuzz_case("result", work, mutate_tokens(data, bases["result"], TOML_RULES))


def test_extreme_numbers(bases, work):
    """Every number of a valid file, in turn, replaced by extreme and special values."""
    extreme_numbers("result", bases, work)


def test_hostile_toml(bases, work):
    """Documents that break the TOML parser itself, alone and replacing each number."""
    hostile_toml("result", bases, work)


@budget(400)
@given(data=st.data())
def test_toml_documents(data, bases, work):
    encoded = toml_bytes(mutate_doc(data, _doc(bases["result"])))
    if encoded is not None:
        fuzz_case("result", work, encoded)


@budget(200)
@given(doc=st.dictionaries(KEYS, VALUES, max_size=8))
def test_toml_from_scratch(doc, work):
    encoded = toml_bytes(doc)
    if encoded is not None:
        fuzz_case("result", work, encoded)
