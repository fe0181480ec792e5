"""A MEMS fit's mean error over the noise, measured without a Monte Carlo: antithetic noise.

White noise is symmetric: a run with noise ``n`` and the same run with ``-n`` are equally likely.
The estimate is exact without noise, so its error is ``L n + Q(n, n) + ...``: the first-order
part, the one the sigmas describe, cancels in the half-sum of the two runs' errors, and what is
left is the part even in the noise, whose expectation is the fit's bias. Its spread from run to
run is small (0.002-0.01 sigma measured over 12 MEMS units), so one pair of runs measures a bias
that a Monte Carlo of 200 runs (standard error 0.07 sigma) can only just see.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from calib.calibration.entry import CalibrateOptions, calibrate
from calib.model import params as P
from calib.model.error_model import ErrorModel
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence
from calib.sequence.kinematics import SimConfig
from calib.sim.gimbal_run import SimOptions, simulate
from seqdesign.verify import error_half_range

SEED = 1400  # the first unit of benchmarks/mems_mc.py
# Half the 2-standard-error threshold of a 200-run Monte Carlo (2 / sqrt(200) = 0.14 sigma): a bias
# below it is invisible there, and one pair's spread (0.01 sigma at most, measured) is far below.
BIAS_LIMIT_SIGMA = 0.07
GYRO_SCALES = [P.NAMES.index(n) for n in ("sgx", "sgy", "sgz")]


@pytest.fixture(scope="module")
def even_part():
    """(z(+n) + z(-n)) / 2 of one MEMS unit on paper-9pos, as benchmarks/mems_mc.py draws it."""
    rng = np.random.default_rng(SEED)
    errors = ErrorModel.from_units(rng.uniform(-1.0, 1.0, P.N_PARAMS) * error_half_range("mems"))
    prof = load_profile("mems")
    cfg = SimConfig(latitude_rad=math.radians(40.0), sample_rate_hz=100.0)
    draw = SimOptions(seed=SEED, flip_error_deg=0.5, random_setup_deg=3.0)
    clean, truth = simulate(
        load_sequence("paper-9pos"), cfg, errors, prof, dataclasses.replace(draw, noise=False)
    )
    noisy, _ = simulate(load_sequence("paper-9pos"), cfg, errors, prof, draw)
    z = []
    for sign in (1.0, -1.0):
        run = dataclasses.replace(
            clean,
            dtheta_rad=clean.dtheta_rad + sign * (noisy.dtheta_rad - clean.dtheta_rad),
            dv_mps=clean.dv_mps + sign * (noisy.dv_mps - clean.dv_mps),
        )
        res = calibrate(run, prof, requirements="mems", options=CalibrateOptions(require_convergence=False))
        assert res.converged
        z.append((res.values - truth.errors.values) / res.sigma)
    return (z[0] + z[1]) / 2.0


@pytest.mark.slow  # 4 simulations and 2 MEMS calibrations of paper-9pos at 100 Hz: ~30 s
def test_mems_fit_has_no_bias_but_the_gyro_scale_factors(even_part):
    # baz's 200-run mean of -0.23 sigma (2.9 standard errors) is not a bias: its even part is
    # 0.000 +- 0.002 sigma over 12 units. Every parameter but the gyro scale factors likewise.
    others = np.delete(np.arange(P.N_PARAMS), GYRO_SCALES)
    worst = others[np.argmax(np.abs(even_part[others]))]
    assert abs(even_part[worst]) < BIAS_LIMIT_SIGMA, (P.NAMES[worst], even_part[worst])
    assert abs(even_part[P.NAMES.index("baz")]) < 0.01  # measured 0.000-0.003 over 12 units


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="second-order gyro scale-factor bias of the MEMS attitude feedback: +0.14, +0.08, "
    "+0.16 sigma (quadratic in the gyro noise; BENCHMARKS.md, 'Honest means of a MEMS fit')",
)
def test_mems_gyro_scale_factors_unbiased(even_part):
    assert np.all(np.abs(even_part[GYRO_SCALES]) < BIAS_LIMIT_SIGMA), even_part[GYRO_SCALES]
