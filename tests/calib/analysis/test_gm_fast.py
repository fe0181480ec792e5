"""The analyser's fast path under any noise profile against the exact evaluation along each mounting.

Under a Gauss-Markov profile the worst-mounting search evaluates every mounting
through the sequence's unwhitened mounting basis and a navigation-frame GM
filter run for many mountings at once (:mod:`calib.analysis.gm_mounting`,
:mod:`calib.noise.gm_filter`); under white noise through the whitened basis
(:mod:`calib.analysis.mounting`). The reference is :func:`calib.analysis.nominal.information_along`:
the Jacobian along the mounting's own nominal trajectory and the body-frame
filter of :func:`calib.noise.whitening.whitener`, one mounting at a time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from realdata import REPO

from calib.analysis.gm_mounting import extra_basis, extra_columns, gm_basis, informations
from calib.analysis.mounting import sequence_model
from calib.analysis.nominal import information_along, information_one, nominal_run
from calib.analysis.worst_case import Evaluation, analyze_extras, analyze_tolerance, box_interpolant_maximum
from calib.model.optional_terms import GROUP_NAMES, OptionalTerms
from calib.nav import earth
from calib.nav.jacobian import observation_jacobian
from calib.nav.site import Site
from calib.noise.gm_filter import MOUNTINGS_AT_ONCE
from calib.noise.profiles import load_profile
from calib.sequence.definition import load_sequence

LAT = math.radians(40.0)
SITE = Site.at(LAT)
G = earth.gravity(LAT)
ADIS = REPO / "benchmarks" / "profiles" / "adis16405.toml"
PROFILES = ["navigation-gm", "mems", str(ADIS)]
# Six mountings: the filter takes them all at once (calib.noise.gm_filter.MOUNTINGS_AT_ONCE), as in the
# box pass; test_one_mounting_filter_equals_the_exact_evaluation covers the one-by-one kernel.
MOUNTINGS = [
    np.radians(d)
    for d in (
        [0.0, 0.0, 0.0],
        [3.0, -3.0, 3.0],
        [-1.0, 2.5, -0.5],
        [-3.0, 0.0, 3.0],
        [2.0, 3.0, -3.0],
        [0.5, -2.0, 1.5],
    )
]
assert len(MOUNTINGS) >= MOUNTINGS_AT_ONCE
ALL = OptionalTerms(GROUP_NAMES)


def _sigmas(info):
    return np.sqrt(np.diag(np.linalg.inv(info))[:21])


@pytest.mark.parametrize("name", PROFILES)
def test_fast_sigma_equals_the_exact_evaluation(name):
    # Same model, the arithmetic reordered (basis combined after propagation, biases in
    # navigation-frame coordinates, S^-1 in closed form): agreement to rounding. Measured
    # 2e-13 relative on a sigma; 1e-9 leaves room for another machine's BLAS.
    profile = load_profile(name)
    seq = load_sequence("paper-9pos")
    if profile.has_gauss_markov:
        fast = informations(gm_basis(seq, profile, SITE), MOUNTINGS)
    else:
        model = sequence_model(seq, profile, SITE)
        fast = np.array([model.information(rv) for rv in MOUNTINGS])
    for rv, info in zip(MOUNTINGS, fast, strict=True):
        exact = information_along(nominal_run(seq, SITE, rv), profile, SITE)
        np.testing.assert_allclose(_sigmas(info), _sigmas(exact), rtol=1e-9)


def test_terms_columns_from_the_basis_equal_each_trajectory():
    # The optional terms' columns of H as polynomials in the mounting (lever arm, k2, time
    # offset), weighted per mounting, against the Jacobian along each mounting's own
    # trajectory. Measured: 4e-14 of each column's largest element.
    seq = load_sequence("paper-9pos")
    basis = gm_basis(seq, load_profile("navigation-gm"), SITE)
    fast = extra_columns(basis, extra_basis(seq, SITE, ALL), MOUNTINGS)
    for m, rv in enumerate(MOUNTINGS):
        nom = nominal_run(seq, SITE, rv)
        H = observation_jacobian(nom, SITE, basis.Phi_vv, ALL)
        exact = H[:, :, 24:]
        scale = np.abs(exact).max(axis=(0, 1))
        assert np.all(np.abs(fast[:, m] - exact).max(axis=(0, 1)) <= 1e-11 * scale)


@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_fast_sigma_with_the_terms_equals_the_exact_evaluation(name):
    # --with all under a GM profile: the 21, phi0 and the terms' columns in one pass of the
    # filter, against each mounting's own evaluation with the terms. Measured 8e-13 on a sigma.
    profile = load_profile(name)
    seq = load_sequence("paper-9pos")
    fast = informations(gm_basis(seq, profile, SITE), MOUNTINGS, extra_basis(seq, SITE, ALL))
    for rv, info in zip(MOUNTINGS, fast, strict=True):
        exact = information_along(nominal_run(seq, SITE, rv), profile, SITE, ALL)
        sigma = [np.sqrt(np.diag(np.linalg.inv(i))) for i in (info, exact)]
        np.testing.assert_allclose(sigma[0], sigma[1], rtol=1e-9)


def test_the_box_pass_with_the_terms_leaves_the_21_as_they_are():
    # analyze_tolerance told the terms analyze_extras will be asked about shares its pass:
    # the same figures as without them (the filter whitens column by column).
    profile = load_profile("navigation-gm")
    seq = load_sequence("paper-9pos")
    alone = analyze_tolerance(seq, profile, SITE, search=False)
    shared = analyze_tolerance(seq, profile, SITE, search=False, extras=ALL)
    np.testing.assert_allclose(shared.per_parameter_worst_sigma, alone.per_parameter_worst_sigma, rtol=1e-12)
    np.testing.assert_allclose(shared.nominal.sigma, alone.nominal.sigma, rtol=1e-12)


@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_one_mounting_filter_equals_the_exact_evaluation(name):
    # One mounting's trajectory through the navigation-frame filter in one loop of 2-D
    # products (what a design's screen runs per candidate), with and without the terms,
    # against the body-frame filter along the same trajectory. Measured 1e-14 on a sigma.
    profile = load_profile(name)
    seq = load_sequence("paper-9pos")
    for extras in (OptionalTerms(), ALL):
        for rv in MOUNTINGS[:2]:
            nom = nominal_run(seq, SITE, rv)
            fast = information_one(nom, profile, SITE, extras)
            exact = information_along(nom, profile, SITE, extras)
            sigma = [np.sqrt(np.diag(np.linalg.inv(i))) for i in (fast, exact)]
            np.testing.assert_allclose(sigma[0], sigma[1], rtol=1e-9)


def test_the_screen_at_the_nominal_mounting_equals_the_direct_evaluation():
    # Zero tolerance (a design's screen): analyze_tolerance and analyze_extras through the
    # one-mounting filter, against the direct evaluation they kept before.
    profile = load_profile(str(ADIS))
    seq = load_sequence("paper-9pos")
    fast = analyze_tolerance(seq, profile, SITE, tolerance_deg=0.0)
    ref = analyze_tolerance(seq, profile, SITE, tolerance_deg=0.0, how=Evaluation(direct=True))
    np.testing.assert_allclose(fast.nominal.sigma, ref.nominal.sigma, rtol=1e-9)
    fast_x = analyze_extras(seq, profile, SITE, ALL, tolerance_deg=0.0)
    ref_x = analyze_extras(seq, profile, SITE, ALL, tolerance_deg=0.0, how=Evaluation(direct=True))
    np.testing.assert_allclose(fast_x.sigma_with, ref_x.sigma_with, rtol=1e-9)
    np.testing.assert_allclose(fast_x.extra_sigma, ref_x.extra_sigma, rtol=1e-9)


@pytest.mark.slow
def test_fast_extras_cost_equals_the_direct_evaluation():
    # analyze --with all under a GM profile (the 27 points and the search's peak) against
    # every mounting evaluated along its own trajectory: the same box figures to rounding.
    profile = load_profile("navigation-gm")
    seq = load_sequence("paper-9pos")
    fast = analyze_extras(seq, profile, SITE, ALL)
    ref = analyze_extras(seq, profile, SITE, ALL, how=Evaluation(direct=True))
    for a, b in ((fast.sigma_with, ref.sigma_with), (fast.sigma_without, ref.sigma_without)):
        np.testing.assert_allclose(a, b, rtol=1e-9)
    np.testing.assert_allclose(fast.extra_sigma, ref.extra_sigma, rtol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_fast_worst_case_equals_the_direct_search(name):
    # The whole worst case (27 box points and the search beyond them) against the
    # reference that evaluates every mounting along its own trajectory and steers its
    # search by forward differences: the same box figures to rounding, the same worst
    # ratio within 0.5 % (the two searches may stop at different points of a flat top).
    profile = load_profile(name)
    seq = load_sequence("paper-9pos")
    fast = analyze_tolerance(seq, profile, SITE)
    ref = analyze_tolerance(seq, profile, SITE, how=Evaluation(direct=True))
    box_fast = analyze_tolerance(seq, profile, SITE, search=False)
    box_ref = analyze_tolerance(seq, profile, SITE, search=False, how=Evaluation(direct=True))
    np.testing.assert_allclose(
        box_fast.per_parameter_worst_sigma, box_ref.per_parameter_worst_sigma, rtol=1e-9
    )
    np.testing.assert_allclose(fast.nominal.sigma, ref.nominal.sigma, rtol=1e-9)
    assert fast.worst.worst[1] == pytest.approx(ref.worst.worst[1], rel=5e-3)
    assert np.all(fast.per_parameter_worst_sigma >= box_fast.per_parameter_worst_sigma)


def test_box_interpolant_maximum_finds_an_interior_peak_and_keeps_a_corner():
    # A quadratic is its own triquadratic interpolant: the lattice's best point is the
    # peak to within half a lattice step (0.05 deg over a 3 deg box).
    levels = (-3.0, 0.0, 3.0)
    grid = np.array([(a, b, c) for a in levels for b in levels for c in levels])
    peak = np.array([1.2, -0.7, 2.1])
    values = 2.0 - 0.01 * np.sum((grid - peak) ** 2, axis=1)
    found, value = box_interpolant_maximum(values, 3.0)
    assert np.allclose(found, peak, atol=0.051)
    assert value == pytest.approx(2.0, abs=1e-4)
    found, _ = box_interpolant_maximum(np.sum(grid, axis=1), 3.0)  # monotone: the corner
    assert np.allclose(found, [3.0, 3.0, 3.0])


def _random_attitudes(seed: int, n: int = 3) -> list[np.ndarray]:
    """``n`` random proper rotations (QR of Gaussian matrices, the sign fixed to det +1)."""
    rng = np.random.default_rng(seed)
    qs = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(n)]
    return [q * np.sign(np.linalg.det(q)) for q in qs]


@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_closed_form_segment_equals_the_interval_fold(name):
    # The beam's GM segment step (Woodbury on the segment's stacked observations) against
    # the Kalman fold over its intervals, for candidates with different filter covariances
    # and states (after 0, 1 and 2 earlier segments), segments stacked over start attitudes.
    from calib.noise.gm_filter import gm_start_covariance
    from seqdesign.search.gm import fold, fold_block, segment_blocks, stack, start_state
    from seqdesign.search.segments import Segment, segment_columns

    profile = load_profile(name)
    attitudes = _random_attitudes(5)
    turn = stack(
        [segment_columns(Segment(C, 45.0, math.radians(10.0), 1), SITE, profile, 45) for C in attitudes]
    )
    rest = stack([segment_columns(Segment(C, 30.0, 0.0, -1), SITE, profile, 12) for C in attitudes])
    X, N, P = (np.repeat(a[None], 3, axis=0) for a in start_state(gm_start_covariance(profile), 24))
    nodes = np.array([0, 1, 2])
    X, N, P = fold(rest, X, N, P, nodes)
    X2, N2, P2 = fold(turn, X, N, P, nodes[::-1])
    X, N, P = np.concatenate([X, X2]), np.concatenate([N, N2]), np.concatenate([P, P2])
    nodes = np.array([0, 1, 2, 2, 0, 1])
    for cols in (turn, rest):
        ref = fold(cols, X, N, P, nodes)
        fast = fold_block(segment_blocks(cols), X, N, P, nodes)
        d = np.sqrt(np.einsum("bii->bi", ref[1]))
        assert np.max(np.abs(fast[1] - ref[1]) / (d[:, :, None] * d[:, None, :])) < 1e-10
        np.testing.assert_allclose(fast[0], ref[0], rtol=1e-9, atol=1e-12 * np.abs(ref[0]).max())
        np.testing.assert_allclose(fast[2], ref[2], rtol=1e-9, atol=1e-12 * np.abs(ref[2]).max())


@pytest.mark.parametrize("name", ["navigation-gm", str(ADIS)])
def test_a_turn_then_its_rest_in_one_block_equals_the_two_folds(name):
    # The beam folds a move's turn and the rest after it through one block (gm.then): the
    # same information, state and covariance as the Kalman loop over both, stacked nodes.
    from calib.noise.gm_filter import gm_start_covariance
    from seqdesign.search.gm import fold, fold_block, segment_blocks, stack, start_state, then
    from seqdesign.search.segments import Segment, segment_columns

    profile = load_profile(name)
    attitudes = _random_attitudes(7)
    turn = stack(
        [segment_columns(Segment(C, 27.0, math.radians(10.0), 2), SITE, profile, 27) for C in attitudes]
    )
    rest = stack([segment_columns(Segment(C, 40.0, 0.0, -1), SITE, profile, 12) for C in attitudes[::-1]])
    X, N, P = (np.repeat(a[None], 4, axis=0) for a in start_state(gm_start_covariance(profile), 24))
    nodes = np.array([0, 1, 2, 1])
    X, N, P = fold(rest, X, N, P, nodes)  # candidates with a history (different covariances)
    ref = fold(rest, *fold(turn, X, N, P, nodes), nodes)
    fast = fold_block(segment_blocks(then(turn, rest)), X, N, P, nodes)
    d = np.sqrt(np.einsum("bii->bi", ref[1]))
    assert np.max(np.abs(fast[1] - ref[1]) / (d[:, :, None] * d[:, None, :])) < 1e-10
    np.testing.assert_allclose(fast[0], ref[0], rtol=1e-9, atol=1e-12 * np.abs(ref[0]).max())
    np.testing.assert_allclose(fast[2], ref[2], rtol=1e-9, atol=1e-12 * np.abs(ref[2]).max())
