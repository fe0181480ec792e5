"""Arrays of numbers read from TOML files (calib.io.fields.Fields.numbers) and their readers."""

import inspect
import math

import numpy as np
import pytest
import tomli_w

from calib.errors import CalibError
from calib.gimbal.description import load_gimbal
from calib.io.fields import Fields
from calib.model.error_model import ErrorModel
from calib.sim.gimbal_run import Truth
from calib.sim.truth import read_truth, truth_to_dict

BAD_ARRAYS = [  # (value, what the refusal must say, the offending item's key)
    (0.5, "must be an array", "x"),
    ([1.0], "array of 2 numbers", "x"),
    ([1.0, 2.0, 3.0], "array of 2 numbers", "x"),
    ([1.0, "two"], "must be a number", "x[1]"),
    ([True, 1.0], "must be a number", "x[0]"),
    ([1.0, [2.0]], "must be a number", "x[1]"),
    ([math.nan, 1.0], "must be finite", "x[0]"),
    ([1.0, math.inf], "must be finite", "x[1]"),
    ([-11.0, 1.0], "outside [-10, 10] deg", "x[0]"),
]


@pytest.mark.parametrize("value, what, key", BAD_ARRAYS)
def test_numbers_refuses_bad_arrays_naming_the_item(value, what, key):
    fields = Fields({"x": value}, "f.toml: [t]")
    with pytest.raises(CalibError) as err:
        fields.numbers("x", length=2, low=-10.0, high=10.0, unit=" deg", fix="give two angles")
    assert what in err.value.what
    assert err.value.where == f"f.toml: [t]: key '{key}'"
    assert err.value.fix == "give two angles"


def test_numbers_reads_what_number_reads():
    fields = Fields({"x": [1, -2.5, 10]}, "f.toml")
    assert fields.numbers("x", low=-10.0, high=10.0) == [1.0, -2.5, 10.0]  # bounds inclusive
    assert fields.numbers("y", []) == []
    assert [Fields({"v": v}, "f").number("v") for v in (1, -2.5, 10)] == fields.numbers("x")
    with pytest.raises(CalibError, match="missing key 'y'"):
        fields.numbers("y")


def test_numbers_refuses_a_check_that_number_does_not_take():
    # A misspelt check ("hihg") would otherwise pass silently whenever the key is absent and a
    # default given: the programmer's mistake is a TypeError at once, the key present or not.
    fields = Fields({"x": [1.0]}, "f.toml")
    for key in ("x", "absent"):
        with pytest.raises(TypeError, match="hihg"):
            fields.numbers(key, [], hihg=10.0)
    # Every keyword number() takes is one numbers() passes on.
    keywords = [n for n, p in inspect.signature(Fields.number).parameters.items() if p.kind is p.KEYWORD_ONLY]
    assert fields.numbers("x", **dict.fromkeys(keywords, None) | {"positive": True, "finite": True}) == [1.0]


def _truth_file(tmp_path, flips):
    doc = truth_to_dict(
        Truth(
            errors=ErrorModel.from_units(np.zeros(21)),
            setup_rotvec=np.zeros(3),
            flip_errors_deg=np.zeros(2),
            profile="navigation",
            seed=1,
            noise=True,
        )
    )
    doc["flips"]["angle_error_deg"] = flips
    path = tmp_path / "run.truth.toml"
    path.write_text(tomli_w.dumps(doc))
    return path


@pytest.mark.parametrize(
    "flips, what",
    [
        ("0.1", "must be an array"),
        ([0.1, "x"], "must be a number"),
        ([0.1, math.nan], "must be finite"),
        ([0.1, 12.0], "outside [-10, 10] deg"),
        ([-10.5], "outside [-10, 10] deg"),
    ],
)
def test_truth_refuses_bad_flip_errors_naming_file_and_key(tmp_path, flips, what):
    path = _truth_file(tmp_path, flips)
    with pytest.raises(CalibError) as err:
        read_truth(path)
    assert what in err.value.what
    assert str(path) in err.value.where and "[flips]" in err.value.where
    assert "angle_error_deg" in err.value.where
    assert "one small angle per flip, in degrees" in err.value.fix


def test_truth_reads_good_flip_errors(tmp_path):
    assert list(read_truth(_truth_file(tmp_path, [0.25, -10.0])).flip_errors_deg) == [0.25, -10.0]
    path = _truth_file(tmp_path, [])
    assert read_truth(path).flip_errors_deg.shape == (0,)


@pytest.mark.parametrize(
    "range_deg, what",
    [
        ("[-360]", "array of 2 numbers"),
        ("[-360, 0, 360]", "array of 2 numbers"),
        ('[-360, "a"]', "must be a number"),
        ("[nan, 360]", "must be finite"),
        ("-360", "must be an array"),
    ],
)
def test_gimbal_refuses_a_bad_range_naming_file_and_key(tmp_path, range_deg, what):
    path = tmp_path / "g.toml"
    path.write_text(f"[outer]\n[middle]\nrange_deg = {range_deg}\n[inner]\n")
    with pytest.raises(CalibError) as err:
        load_gimbal(path)
    assert what in err.value.what
    assert str(path) in err.value.where and "[middle]" in err.value.where
    assert "range_deg" in err.value.where
    assert "range_deg = [-360, 360]" in err.value.fix
