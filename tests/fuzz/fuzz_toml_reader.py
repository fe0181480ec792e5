"""The fuzz cases every TOML reader faces, written once: a test module takes the class of its
reader's cases (``test_fuzz_profile.py``: ``TestProfile = toml_reader_cases("profile")``) and
subclasses it where its reader needs more.

Mutated bytes, encodings and degenerate files, token mutations, every number made extreme,
TOML that breaks the parser, mutated and random documents. The contract, the budget and the
tally: ``fuzzing.py``.
"""

from __future__ import annotations

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


def toml_reader_cases(kind: str) -> type:
    """The test class of one TOML reader (``kind``: its name in the tally and the base documents).

    Made anew for each reader, not inherited: Hypothesis refuses one ``@given`` method run from
    the instances of several classes (its health check: draws replayed across executors).
    """

    class Cases:
        @budget(300)
        @given(data=st.data())
        def test_mutated_bytes(self, data, bases, work):
            fuzz_case(kind, work, mutate_bytes(data, bases[kind]))

        def test_encodings_and_degenerate_files(self, bases, work):
            for _name, data in _encodings(bases[kind]).items():
                fuzz_case(kind, work, data)

        @budget(400)
        @given(data=st.data())
        def test_toml_token_mutations(self, data, bases, work):
            fuzz_case(kind, work, mutate_tokens(data, bases[kind], TOML_RULES))

        def test_extreme_numbers(self, bases, work):
            """Every number of a valid file, in turn, replaced by extreme and special values."""
            extreme_numbers(kind, bases, work)

        def test_hostile_toml(self, bases, work):
            """Documents that break the TOML parser itself, alone and replacing each number."""
            hostile_toml(kind, bases, work)

        @budget(400)
        @given(data=st.data())
        def test_toml_documents(self, data, bases, work):
            encoded = toml_bytes(mutate_doc(data, _doc(bases[kind])))
            if encoded is not None:
                fuzz_case(kind, work, encoded)

        @budget(200)
        @given(doc=st.dictionaries(KEYS, VALUES, max_size=8))
        def test_toml_from_scratch(self, doc, work):
            encoded = toml_bytes(doc)
            if encoded is not None:
                fuzz_case(kind, work, encoded)

    Cases.__name__ = Cases.__qualname__ = f"Test{kind.capitalize()}"
    return Cases
