"""Where the tests find real recordings, and what they do when one is not here.

The three hand recordings (imu_tk's Xsens, imucal's Ferraris session, mikoff's MPU-9150 logs) are
copied into ``tests/data/realdata`` with their licences and sources (its README), so every clone
runs their tests. The static logs (the ADIS16405, whose licence forbids copying it here, and
PSINS's laser-gyro log) are read from ``../shared/realdata`` beside the repository, or from the
folder ``SEQDESIGN_REALDATA`` names: absent on a user's clone, their tests are skipped; absent
where ``CI`` is set, they fail, so that CI cannot pass without them.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
HAND = REPO / "tests" / "data" / "realdata"
XSENS = HAND / "imu_tk-xsens"
FERRARIS = HAND / "imucal-ferraris"
MIKOFF = HAND / "mikoff-mpu9150"
SHARED = Path(os.environ.get("SEQDESIGN_REALDATA", REPO.parent / "shared" / "realdata"))
ADIS = SHARED / "adis16405-static-100hz.csv.gz"
PSINS = SHARED / "psins-lasergyro-static.imu"


def needs(path: Path):
    """Run the test where ``path`` exists; skip it on a user's clone; fail it under CI."""
    if path.exists():
        return lambda test: test
    if not os.environ.get("CI"):
        return pytest.mark.skip(reason=f"{path} is absent (a user's clone)")

    def failing(test):
        @functools.wraps(test)
        def absent(*args, **kwargs):
            pytest.fail(f"{path} is absent where CI is set: give CI ../shared/realdata or SEQDESIGN_REALDATA")

        return absent

    return failing
