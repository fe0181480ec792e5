"""Fuzzing of the sequence reader (``load_sequence``): mutated bytes, encodings, tokens,
extreme numbers, hostile TOML, random steps and documents, and flips of any angle.

The contract, the budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

import math

import tomli_w
from fuzz_fixtures import bases_fixture, report_tally, work_fixture  # noqa: F401 (fixtures)
from fuzz_text import TEXT, _doc, mutate_doc, toml_bytes
from fuzz_toml_reader import toml_reader_cases
from fuzzing import budget, case_file, fuzz_case, valid_sequence
from hypothesis import given, strategies as st

from calib.nav.transform import DIRECTIONS
from calib.sequence.definition import load_sequence

# ---------------------------------------------------------------------------
# Random sequence documents (random steps, and schema-aware edits)

ANGLES = st.one_of(
    st.floats(-4000, 4000),
    st.integers(-4000, 4000),
    st.sampled_from(
        [
            90,
            -90,
            180,
            270,
            360,
            45,
            30.5,
            89.999,
            90.0001,
            1e-300,
            0,
            -0.0,
            3600,
            -3600,
            3600.0001,
            1e300,
            math.nan,
            math.inf,
        ]
    ),
)
STEPS = st.fixed_dictionaries(
    {
        "axis": st.one_of(
            st.sampled_from(["X", "Y", "Z", "x", "y", "z"]),
            st.sampled_from(["W", "", "XY", " X", "Q", "1"]),
            st.integers(0, 3),
        )
    },
    optional={
        "angle_deg": ANGLES,
        "rate_dps": st.one_of(st.floats(-10, 2000), st.sampled_from([0, 1e-300, 1000, 1001])),
        "dwell_s": st.one_of(st.floats(-10, 30000), st.sampled_from([0, 1e-300, 21600])),
        "note": TEXT,
    },
)


class TestSequence(toml_reader_cases("sequence")):
    @budget(600)
    @given(data=st.data())
    def test_toml_documents(self, data, bases, work):
        """Random steps (unknown axes, any angle, any rate/dwell) and random edits."""
        doc = _doc(bases["sequence"])
        if data.draw(st.booleans(), label="random steps"):
            doc["step"] = data.draw(st.lists(STEPS, max_size=6), label="steps")
            doc["start"] = data.draw(
                st.one_of(
                    st.just(["east", "up", "south"]),
                    st.lists(
                        st.sampled_from(list(DIRECTIONS) + ["EAST", "sky", " up"]), min_size=0, max_size=4
                    ),
                ),
                label="start",
            )
        if data.draw(st.booleans(), label="edit"):
            doc = mutate_doc(data, doc, STEPS)
        encoded = toml_bytes(doc)
        if encoded is not None:
            fuzz_case("sequence", work, encoded)


# ---------------------------------------------------------------------------
# Flips that are not multiples of 90 deg


@budget(100)
@given(
    angles=st.lists(
        ANGLES.filter(lambda a: isinstance(a, (int, float)) and math.isfinite(a) and 0 < abs(a) <= 3600),
        min_size=1,
        max_size=4,
    ),
    axes=st.lists(st.sampled_from("XYZ"), min_size=4, max_size=4),
)
def test_any_angle_loads_and_expands(angles, axes, work):
    """Angles that are not multiples of 90 deg leave the grid but still load and show."""
    doc = {
        "name": "odd",
        "start": ["east", "up", "south"],
        "initial_dwell_s": 10.0,
        "step": [
            {"axis": ax, "angle_deg": float(a), "rate_dps": 100.0, "dwell_s": 1.0}
            for a, ax in zip(angles, axes, strict=False)  # axes: always 4, angles: 1 to 4
        ],
    }
    path = case_file(work, ".toml", tomli_w.dumps(doc).encode())
    seq = load_sequence(path)
    valid_sequence(seq)
    assert [s.angle_deg for s in seq.steps] == [float(a) for a in angles]
