"""Fuzzing of the noise profile (``load_profile``): mutated bytes, encodings, tokens, extreme
numbers, hostile and random TOML documents.

The contract, the budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_toml_reader import toml_reader_cases

TestProfile = toml_reader_cases("profile")
