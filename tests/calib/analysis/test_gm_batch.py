"""The GM analyser batched over mountings against the one-at-a-time computation.

Under a Gauss-Markov profile every mounting has its own noise filter; the
analyser runs the filters of several mountings in one pass over the shared
interval grid (:func:`calib.analysis.nominal.information_along_many`). The reference
is the unbatched path, :func:`calib.analysis.nominal.information_along` (one
:func:`calib.noise.whitening.whitener` and :func:`calib.noise.whitening.whiten` per mounting),
reached in the analyser with ``batch=1``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.analysis import nominal as nominal_module
from calib.analysis.nominal import information_along, information_along_many, nominal_run, same_grid
from calib.analysis.worst_case import Evaluation, analyze_extras, analyze_tolerance
from calib.model.optional_terms import load_optional_terms
from calib.nav import earth
from calib.nav.jacobian import state_matrix
from calib.nav.site import Site
from calib.noise.profiles import load_profile
from calib.noise.whitening import (
    filter_blocks,
    gm_interval_arrays,
    interval_models,
    whiten,
    whiten_batch,
    whitener,
)
from calib.sequence.definition import load_sequence

LAT = math.radians(40.0)
SITE = Site.at(LAT)
G = earth.gravity(LAT)
GM = load_profile("navigation-gm")
MOUNTINGS = [
    np.radians(d) for d in ([0.0, 0.0, 0.0], [3.0, -3.0, 3.0], [-1.0, 2.5, -0.5], [-3.0, -3.0, -3.0])
]


def _scaled_difference(N, N_ref):
    """Largest ``|N - N_ref|_ij / sqrt(N_ii N_jj)``: the difference in correlation units,
    so that the small entries of a matrix spanning many decades are judged fairly."""
    d = np.sqrt(np.einsum("...ii->...i", N_ref))
    return np.max(np.abs(N - N_ref) / (d[..., :, None] * d[..., None, :]))


def test_the_interval_grid_does_not_depend_on_the_mounting():
    seq = load_sequence("designed-15min-gm")
    noms = [nominal_run(seq, SITE, rv) for rv in MOUNTINGS]
    assert same_grid(noms)
    other = nominal_run(load_sequence("paper-9pos"), SITE, MOUNTINGS[1])
    assert not same_grid([noms[0], other])


def test_whiten_batch_is_whitener_then_whiten():
    # Random attitudes and interval lengths: each mounting's slice of the batch against its
    # own Riccati recursion and whitening. The operations are the same ones in the same
    # order; 1e-13 leaves room for a BLAS that orders a stacked product differently.
    rng = np.random.default_rng(3)
    A, K, M, c = state_matrix(SITE), 40, 3, 5
    T = rng.choice([0.5, 1.0, 5.0], size=K)
    C = [np.linalg.qr(rng.normal(size=(K, 3, 3)))[0] for _ in range(M)]
    C = [q * np.sign(np.linalg.det(q))[:, None, None] for q in C]
    X = rng.normal(size=(K, M, 3, c))
    arrays = [gm_interval_arrays(A, T, GM, Cm) for Cm in C]
    blocks = filter_blocks(np.stack([a[0] for a in arrays], axis=1), np.stack([a[1] for a in arrays], axis=1))
    P0 = np.zeros((M, 9, 9))
    P0[:, 3:, 3:] = arrays[0][2]
    Xw, P_end, _ = whiten_batch(blocks, X, P0, np.zeros((M, 9, c)))
    for m in range(M):
        w = whitener(interval_models(A, T, GM, C[m]))
        np.testing.assert_allclose(Xw[:, m], whiten(w, X[:, m]), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(P_end[m], w.P_end, rtol=1e-13, atol=1e-13 * np.abs(w.P_end).max())


@pytest.mark.parametrize("extras", [None, "all"])
def test_information_along_many_equals_one_at_a_time(extras, monkeypatch):
    # A short GM sequence at four mountings, with the noise model carried across blocks of
    # 7 intervals (the analyser's blocks are 1024: this exercises the carrying). Same
    # operations in the same order (measured: identical bits here); 1e-12 leaves room for
    # a BLAS that orders a stacked 9 x 9 product differently.
    monkeypatch.setattr(nominal_module, "BATCH_INTERVALS", 7)
    seq, ex = load_sequence("paper-9pos"), load_optional_terms(extras)
    noms = [nominal_run(seq, SITE, rv) for rv in MOUNTINGS]
    reference = np.array([information_along(n, GM, SITE, ex) for n in noms])
    batched = information_along_many(noms, GM, SITE, ex)
    assert batched.shape == reference.shape
    assert _scaled_difference(batched, reference) < 1e-12


def test_information_along_many_falls_back_when_grids_differ():
    noms = [
        nominal_run(load_sequence(name), SITE, MOUNTINGS[1]) for name in ("paper-9pos", "paper-9pos-turns")
    ]
    many = information_along_many(noms, GM, SITE)
    for N, nom in zip(many, noms, strict=True):
        assert np.array_equal(N, information_along(nom, GM, SITE))


@pytest.mark.slow
def test_analyze_tolerance_and_extras_batched_equal_unbatched():
    # The whole analysis (27 box points and the forward-difference-steered search) in
    # batches of mountings against one mounting at a time. The informations are the same
    # arithmetic (measured: identical bits). Why 1e-10 and not 1e-15: near the box centre
    # a sigma moves ~1e-9 relative over the search's 1e-3 deg step, so a 1e-15 rounding
    # difference in the information (a ~1e-12 one in a sigma, as a BLAS ordering its
    # products differently would give) is a 1e-3 one in the forward-difference gradient;
    # measured with the Gram matrix summed in blocks: box points 1.7e-12 apart, the
    # searched worst sigma 9e-10.
    seq = load_sequence("paper-9pos")
    one = analyze_tolerance(seq, GM, SITE, how=Evaluation(batch=1, direct=True))
    many = analyze_tolerance(seq, GM, SITE, how=Evaluation(direct=True))
    assert one.searched and many.searched
    np.testing.assert_allclose(many.nominal.sigma, one.nominal.sigma, rtol=1e-10)
    np.testing.assert_allclose(many.per_parameter_worst_sigma, one.per_parameter_worst_sigma, rtol=1e-10)
    np.testing.assert_allclose(many.worst.sigma, one.worst.sigma, rtol=1e-10)
    extras = load_optional_terms("all")
    one = analyze_extras(seq, GM, SITE, extras, search=True, how=Evaluation(batch=1))
    many = analyze_extras(seq, GM, SITE, extras, search=True)
    assert one.searched and many.searched
    for a, b in (
        (many.sigma_without, one.sigma_without),
        (many.sigma_with, one.sigma_with),
        (many.extra_sigma, one.extra_sigma),
    ):
        np.testing.assert_allclose(a, b, rtol=1e-10)
    assert many.unobservable == one.unobservable
