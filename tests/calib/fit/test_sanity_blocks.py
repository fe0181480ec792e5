"""The whole-run sanity checks computed a block at a time give the whole-run answer.

``calib.fit.sanity`` walks long logs in blocks of ``MOTION_BLOCK`` samples so that
its memory does not grow with the log; the answers must not depend on where
the blocks end.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.errors import CalibError
from calib.fit import sanity
from calib.sequence import motion

RATE_HZ = 100.0
FLIP_RATE = math.radians(10.0)  # rad/s, the paper's turn rate


def _log(seed=3):
    """A rest, a 90 deg turn at 10 deg/s about z, a rest; white noise on every channel."""
    rng = np.random.default_rng(seed)
    n_rest, n_turn = 3000, int(round(9.0 * RATE_HZ))
    h = 1.0 / RATE_HZ
    rate = np.zeros((2 * n_rest + n_turn, 3))
    rate[n_rest : n_rest + n_turn, 2] = FLIP_RATE
    dtheta = rate * h + 1e-7 * rng.standard_normal(rate.shape)
    dv = np.tile([0.0, 0.0, 9.8 * h], (len(rate), 1)) + 1e-5 * rng.standard_normal(rate.shape)
    return dtheta, dv, np.full(len(rate), h)


@pytest.mark.parametrize("block", [7, 250, 4096])
def test_motion_diagnosis_does_not_depend_on_the_blocks(monkeypatch, block):
    dtheta, _, dt = _log()
    whole = motion.diagnose_motion(dtheta, dt, 0.01)
    monkeypatch.setattr(sanity, "MOTION_BLOCK", block)
    cut = motion.diagnose_motion(dtheta, dt, 0.01)
    # Sums carried across block ends in the whole-run order: the same floats; only the
    # sway RMS is summed in another order (rounding, 1e-12 of itself).
    for name in (
        "has_flip",
        "max_rate_rad_s",
        "max_mean_rate_rad_s",
        "window_s",
        "mean_rate_rad_s",
        "sway_arcsec",
    ):
        assert np.array_equal(getattr(whole, name), getattr(cut, name)), name
    assert np.allclose(whole.sway_rate_arcsec_s, cut.sway_rate_arcsec_s, rtol=1e-12, atol=0)
    # The 1-s mean rate of a 10 deg/s turn is 10 deg/s (noise 1e-7 rad a sample: 1e-6 of it).
    assert whole.has_flip and whole.max_mean_rate_rad_s == pytest.approx(FLIP_RATE, rel=1e-4)


@pytest.mark.parametrize("block", [5, 1000, 1 << 16])
def test_a_clipped_channel_is_found_across_block_ends(monkeypatch, block):
    dtheta, dv, _ = _log()
    # Clip dv_x at its noise's 2-sigma level from sample 995 to 1045: a stretch that crosses
    # the block end at 1000 whatever the block (except the whole-run one).
    limit = 2e-5
    dv[:, 0] = np.clip(dv[:, 0], -limit, limit)
    dv[990:1050, 0] = 0.0  # the samples either side inside the range: the stretch is exactly 50
    dv[995:1045, 0] = limit
    monkeypatch.setattr(sanity, "MOTION_BLOCK", block)
    with pytest.raises(CalibError, match="dv_x is stuck .* for 50 consecutive samples from sample 995"):
        sanity.check_saturation(dtheta, dv, "run")


def test_row_norm_is_numpys_norm_to_the_bit():
    a = np.random.default_rng(1).standard_normal((1000, 3)) * 10.0 ** np.arange(-3, 0)
    assert np.array_equal(motion.row_norm(a), np.linalg.norm(a, axis=1))
