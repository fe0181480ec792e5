"""Shared helpers for the tests: independent physics, the copied paper tables, one simulation.

Everything here is written from ``conventions.md`` directly (direction names,
Rodrigues' formula, the WGS-84 formula, the parameter names), so that tests
compare the code with an independent construction rather than with itself.
"""

from __future__ import annotations

# One BLAS thread per test process, set before numpy loads, as the CLI runs: the suite runs
# on two workers of a 2-core machine.
from seqdesign import blas  # noqa: F401

# isort: split
import csv
import math
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "calib" / "data"  # copies of the paper's tables shipped in the repo
SHARED_PAPER = REPO.parent / "shared" / "paper"  # only on a developer's machine / CI

# Conventions.md constants, typed in from the spec (not imported from the code).
W_EARTH = 7.292115e-5  # rad/s
LAT_DEG = 40.0  # default site of the conventions
DEG = math.pi / 180.0
ARCSEC = DEG / 3600.0
DEG_PER_H = DEG / 3600.0
UG = 9.80665e-6  # m/s^2
PPM = 1e-6
ARW_NAV = 0.001 * DEG / 60.0  # navigation profile, rad/sqrt(s)
VRW_NAV = 10.0 * UG  # navigation profile, m/s/sqrt(s)

ENU = {
    "east": (1.0, 0.0, 0.0),
    "west": (-1.0, 0.0, 0.0),
    "north": (0.0, 1.0, 0.0),
    "south": (0.0, -1.0, 0.0),
    "up": (0.0, 0.0, 1.0),
    "down": (0.0, 0.0, -1.0),
}

SPEC_NAMES = (
    "bgx bgy bgz sgx sgy sgz mgxy mgxz mgyx mgyz mgzx mgzy bax bay baz sax say saz mayx mazx mazy"
).split()

# Paper sequence timing (Table 1 with the sequence's 180 s dwells and 10 deg/s flips).
DWELL_S = 180.0
FLIP_S = 9.0  # 90 deg at 10 deg/s
N_POS = 9


def rest_window(k: int) -> tuple[float, float]:
    """Start and end (s) of rest position ``k`` (1-based) of paper-9pos."""
    start = (k - 1) * (DWELL_S + FLIP_S)
    return start, start + DWELL_S


def attitude(x: str, y: str, z: str) -> np.ndarray:
    """C_b^n whose columns are the ENU vectors of where body X, Y, Z point."""
    return np.column_stack([ENU[x], ENU[y], ENU[z]])


def skew(v) -> np.ndarray:
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rodrigues(rotvec) -> np.ndarray:
    """exp([rotvec x]) by Rodrigues' formula."""
    v = np.asarray(rotvec, dtype=float)
    a = np.linalg.norm(v)
    if a == 0.0:
        return np.eye(3)
    K = skew(v / a)
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * K @ K


def rot_about(axis: str, angle_rad: float) -> np.ndarray:
    """Right-hand rotation about body axis 'X', 'Y' or 'Z'."""
    e = np.zeros(3)
    e["XYZ".index(axis)] = 1.0
    return rodrigues(e * angle_rad)


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (angle well below pi)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    a = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    if a < 1e-12:
        return w
    return w * a / math.sin(a)


def normal_gravity(lat_rad: float, h: float) -> float:
    """The conventions' WGS-84 formula, typed in from conventions.md."""
    s2 = math.sin(lat_rad) ** 2
    g0 = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
    a, f, m = 6378137.0, 1 / 298.257223563, 0.00344978650684
    return g0 * (1 - 2 * h / a * (1 + f + m - 2 * f * s2) + 3 * h * h / (a * a))


def earth_rate_enu(lat_rad: float) -> np.ndarray:
    return np.array([0.0, W_EARTH * math.cos(lat_rad), W_EARTH * math.sin(lat_rad)])


def read_table(path: Path) -> list[dict]:
    """Rows of a paper CSV (lines starting with '#' are comments)."""
    lines = [ln for ln in path.read_text("utf-8").splitlines() if ln and not ln.startswith("#")]
    return list(csv.DictReader(lines))


def table1_positions() -> list[dict]:
    return read_table(DATA / "table1_positions.csv")


def table1_gimbal() -> list[dict]:
    return read_table(DATA / "table1_gimbal_angles.csv")


def table_column_units(name: str, column: str) -> dict[str, float]:
    """One column of a 21-parameter paper table, by spec name, in spec units."""
    return {r["name"]: float(r[column]) for r in read_table(DATA / f"{name}.csv")}


SI_PER_UNIT = {"deg/h": DEG_PER_H, "ppm": PPM, "arcsec": ARCSEC, "ug": UG}


def table_column_si(name: str, column: str) -> dict[str, float]:
    rows = read_table(DATA / f"{name}.csv")
    return {r["name"]: float(r[column]) * SI_PER_UNIT[r["unit"]] for r in rows}


def sensor_model(values_si: dict[str, float], sensor: str):
    """(I + S + M, b) built from spec names: 'sgy' -> (y, y), 'mgxy' -> row x, col y."""
    s = "g" if sensor == "gyro" else "a"
    E = np.eye(3)
    b = np.zeros(3)
    for name, v in values_si.items():
        if name[1] != s:
            continue
        i = "xyz".index(name[2])
        if name[0] == "b":
            b[i] = v
        elif name[0] == "s":
            E[i, i] += v
        elif name[0] == "m":
            E[i, "xyz".index(name[3])] += v
    return E, b


def pre_attitudes() -> list[np.ndarray]:
    """Nominal C_b^n of positions 1..9 from Table 1's direction names."""
    return [attitude(r["pre_x"], r["pre_y"], r["pre_z"]) for r in table1_positions()]


SETUP_DEG = (1.0, -2.0, 3.0)


@pytest.fixture(scope="session")
def paper_seq():
    from calib.sequence.definition import load_sequence

    return load_sequence("paper-9pos")


@pytest.fixture(scope="session")
def clean_sim(paper_seq):
    """Error-free, noise-free paper-9pos at 40 deg, 200 Hz, setup (1, -2, 3) deg."""
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    cfg = SimConfig(latitude_rad=math.radians(LAT_DEG))
    run, truth = simulate(
        paper_seq,
        cfg,
        ErrorModel.zero(),
        load_profile("navigation"),
        options=SimOptions(setup_rotvec=np.radians(SETUP_DEG), noise=False, seed=1),
    )
    return run, truth, cfg
