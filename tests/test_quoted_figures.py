"""Figures quoted in shipped files are what the tool prints (issue 39).

A sequence's header comment, a pose list's and the guides quote durations, counts and
ratios; each is held here to the tool's own output (the CLI, in a process of its own), or
to the formula it comes from, so that a figure cannot drift from the code.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from realdata import XSENS

REPO = Path(__file__).resolve().parents[1]


def cli_json(*args) -> dict:
    res = subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *map(str, args), "--json"], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout)


def header(path: Path) -> str:
    """The comment lines before a file's first key, joined."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("# "))
    return " ".join(lines)


SEQUENCES = sorted((REPO / "sequences").glob("*.toml"))
POSE_LISTS = sorted((REPO / "sequences" / "hand").glob("*.toml"))


@pytest.mark.parametrize("path", SEQUENCES, ids=lambda p: p.stem)
def test_a_sequence_header_s_figures_are_what_show_prints(path):
    text = header(path)
    doc = cli_json("show", path)
    for minutes, seconds in re.findall(r"(\d+) min (\d+) s in all", text):
        assert int(minutes) * 60 + int(seconds) == pytest.approx(doc["duration_s"]), text
    for n in re.findall(r"(\d+) rest positions", text):
        assert int(n) == len(doc["positions"]), text
    for n in re.findall(r"(\d+) flips", text):
        assert int(n) == len(doc["positions"]) - 1, text


def test_every_duration_in_a_sequence_header_is_checked():
    # A header's duration in another wording would escape the test above: none may.
    for path in SEQUENCES:
        text = re.sub(r'"[^"]*"', "", header(path))  # what the paper says, quoted, is the paper's
        unchecked = re.findall(r"\d+(?:\.\d+)? (?:min|h)\b(?! \d+ s in all)", text)
        assert unchecked == [], (path.name, unchecked)


@pytest.mark.parametrize("path", POSE_LISTS, ids=lambda p: p.stem)
def test_a_pose_list_header_s_figures_are_what_analyze_prints(path):
    text = header(path)
    found = re.match(
        r"(\d+) poses, ([\d.]+) min, profile (\S+), requirements (\S+): worst 3 sigma/requirement "
        r"[\d.]+ as planned, ([\d.]+) \((\w+)\) with each pose placed within (\d+) deg; no plan of "
        r"this length does better than ([\d.]+) on the gyro biases",
        text,
    )
    assert found, text
    n, minutes, profile, requirements, worst, name, within, bound = found.groups()
    doc = cli_json("analyze", "--by-hand", path, "--profile", profile, "--requirements", requirements)
    assert doc["n_poses"] == int(n)
    assert doc["duration_s"] / 60 == pytest.approx(float(minutes), abs=0.05)
    assert doc["placement_tolerance_deg"] == float(within)
    assert doc["worst"]["name"] == name and round(doc["worst"]["ratio"], 2) == float(worst)
    # The gyro biases' bound: every second tells a bias through the ARW alone, sigma >= ARW / sqrt(T)
    # (docs/by-hand.md); the mems profile's ARW 2.6 deg/sqrt(h) against 30 deg/h at 3 sigma.
    assert (profile, requirements) == ("mems", "mems")
    sigma_dph = 2.6 / math.sqrt(doc["duration_s"] / 3600.0)
    assert round(3.0 * sigma_dph / 30.0, 2) == float(bound)


@pytest.mark.slow  # two hand fits of the real recording, ~10 s
@pytest.mark.parametrize(
    "terms, phrase",
    [
        (["--without", "g-sensitivity"], "Forced out (`--without g-sensitivity`) it leaves chi2/dof "),
        ([], "terms fitted (the default): chi2/dof "),
    ],
)
def test_the_by_hand_guide_s_chi2_figures_are_what_calibrate_prints(tmp_path, terms, phrase):
    guide = " ".join((REPO / "docs" / "by-hand.md").read_text().split())
    quoted = guide[guide.index(phrase) + len(phrase) :].split()[0].rstrip(",")
    doc = cli_json(
        "calibrate", XSENS / "xsens_acc.mat.gz", "--gyro-file", XSENS / "xsens_gyro.mat.gz",
        "--conversion", XSENS / "xsens-nominal-values.txt", "--by-hand", "--profile", "mems",
        "--latitude", "45.4", "--height", "0", *terms, "-o", tmp_path / "x.toml",
    )  # fmt: skip
    decimals = len(quoted.split(".")[1])
    assert round(doc["fit"]["chi2_per_dof"], decimals) == float(quoted)
