"""Fuzzing of the errors/truth file (``read_truth`` and ``read_errors``, which must agree):
mutated bytes, encodings, tokens, extreme numbers, hostile and random TOML documents.

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
    fuzz_case("truth", work, mutate_bytes(data, bases["truth"]))


def test_encodings_and_degenerate_files(bases, work):
    for _name, data in _encodings(bases["truth"]).items():
        fuzz_case("truth", work, data)


@budget(400)
@given(data=st.data())
def test_toml_token_mutations(data, bases, work):
    fuzz_case("truth", work, mutate_tokens(data, bases["truth"], TOML_RULES))


def test_extreme_numbers(bases, work):
    """Every number of a valid file, in turn, replaced by extreme and special values."""
    extreme_numbers("truth", bases, work)


def test_hostile_toml(bases, work):
    """Documents that break the TOML parser itself, alone and replacing each number."""
    hostile_toml("truth", bases, work)


@budget(400)
@given(data=st.data())
def test_toml_documents(data, bases, work):
    encoded = toml_bytes(mutate_doc(data, _doc(bases["truth"])))
    if encoded is not None:
        fuzz_case("truth", work, encoded)


@budget(200)
@given(doc=st.dictionaries(KEYS, VALUES, max_size=8))
def test_toml_from_scratch(doc, work):
    encoded = toml_bytes(doc)
    if encoded is not None:
        fuzz_case("truth", work, encoded)
