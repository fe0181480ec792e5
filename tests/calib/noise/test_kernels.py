"""The compiled recursions (calib.noise.kernels) against the textbook recursions written plainly here.

The analyser's own fast-versus-exact tests (tests/calib/analysis/test_gm_fast.py) check the physics
end to end; these check each kernel alone, on random inputs that exercise every branch
(turned and unturned intervals, several mountings, zero and non-zero transition entries).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from calib.nav import earth
from calib.nav.jacobian import propagate, step_model
from calib.nav.site import Site
from calib.noise.gm_filter import MOUNTINGS_AT_ONCE, NavTable, gram_one, gram_pass

LAT = math.radians(40.0)


def _random_rotations(rng, n):
    q = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(n)]
    return np.array([r * np.sign(np.linalg.det(r)) for r in q])


def _reference_filter(F, Q, index, turns, turning, X, P, state):
    """Kalman filter of the columns, one mounting, in plain numpy (no closed forms, no skipping)."""
    s = F.shape[-1]
    gram = np.zeros((X.shape[-1],) * 2)
    for k in range(len(X)):
        Fk = F[index[k]].copy()
        if turning[k]:
            for j in range(3, s, 3):
                Fk[:, j : j + 3] = F[index[k]][:, j : j + 3] @ turns[k]
        J = Fk @ P @ Fk.T + Q[index[k]]
        S = J[s:, s:]
        gain = J[:s, s:] @ np.linalg.inv(S)
        predicted = Fk @ state
        e = X[k] - predicted[s:]
        gram += e.T @ np.linalg.solve(S, e)
        state = predicted[:s] + gain @ e
        P = J[:s, :s] - gain @ S @ gain.T
    return gram, P, state


def _random_filter_inputs(seed, K=40, M=3, c=5):
    rng = np.random.default_rng(seed)
    # the navigation-frame GM model's shape: phi rows couple to the gyro bias, the biases
    # decay on the diagonal, the velocity rows see all three blocks; zeros elsewhere
    F = np.zeros((2, 12, 9))
    for u in range(2):
        F[u, :3, :3] = np.eye(3) + 0.01 * rng.normal(size=(3, 3))
        F[u, :3, 3:6] = rng.normal(size=(3, 3))
        F[u, 3:9, 3:9] = np.eye(6) * 0.99
        F[u, 9:] = rng.normal(size=(3, 9))
    A = rng.normal(size=(2, 12, 12))
    Q = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(12)
    index = rng.integers(0, 2, K)
    turning = rng.random(K) < 0.5
    turns = _random_rotations(rng, K * M).reshape(K, M, 3, 3)
    X = rng.normal(size=(K, M, 3, c))
    B = rng.normal(size=(M, 9, 9))
    P = B @ B.transpose(0, 2, 1)
    state = rng.normal(size=(M, 9, c))
    return F, Q, index, turns, turning, X, P, state


# Both kernels: the mountings one by one (filter_columns) and their covariances at once (filter_mountings).
@pytest.mark.parametrize("M", [3, MOUNTINGS_AT_ONCE + 1])
@pytest.mark.parametrize("seed", [1, 2])
def test_compiled_filter_equals_the_textbook_filter(seed, M):
    # Same recursion, the arithmetic reordered (closed-form 3 x 3 inverse, zeros skipped,
    # one Gram product at the end): agreement to rounding over 40 intervals; 1e-9 relative
    # is far below any figure the analyser prints and far above double rounding here.
    F, Q, index, turns, turning, X, P, state = _random_filter_inputs(seed, M=M)
    gram, P_end, state_end = gram_pass(NavTable(F, Q, index), turns, turning, X, P, state)
    for m in range(X.shape[1]):
        ref = _reference_filter(F, Q, index, turns[:, m], turning, X[:, m], P[m], state[m])
        np.testing.assert_allclose(gram[m], ref[0], rtol=1e-9, atol=1e-9 * np.abs(ref[0]).max())
        np.testing.assert_allclose(P_end[m], ref[1], rtol=1e-9, atol=1e-9 * np.abs(ref[1]).max())
        np.testing.assert_allclose(state_end[m], ref[2], rtol=1e-9, atol=1e-9 * np.abs(ref[2]).max())


def test_the_two_kernels_give_the_same_bits():
    # filter_mountings is filter_columns with the covariance loops turned inside out: each
    # operation the same, in the same order, so each figure the same to the last bit.
    F, Q, index, turns, turning, X, P, state = _random_filter_inputs(4, M=MOUNTINGS_AT_ONCE)
    at_once = gram_pass(NavTable(F, Q, index), turns, turning, X, P, state)
    cut = MOUNTINGS_AT_ONCE // 2  # two batches below the threshold: the one-by-one kernel
    halves = [
        gram_pass(NavTable(F, Q, index), turns[:, h], turning, X[:, h], P[h], state[h])
        for h in (np.s_[:cut], np.s_[cut:])
    ]
    for whole, *parts in zip(at_once, *halves, strict=True):
        np.testing.assert_array_equal(whole, np.concatenate(parts))


def test_one_mounting_from_rest_is_the_batched_filter():
    F, Q, index, turns, turning, X, P, _ = _random_filter_inputs(3, M=1)
    gram, _, _ = gram_pass(NavTable(F, Q, index), turns, turning, X, P, np.zeros((1, 9, X.shape[-1])))
    one = gram_one(NavTable(F, Q, index), turns[:, 0], turning, X[:, 0], P[0])
    np.testing.assert_allclose(one, gram[0], rtol=1e-12)


def test_the_compiled_filter_refuses_an_innovation_covariance_that_is_not_positive():
    # A negative velocity noise makes S = F P F' + Q indefinite at the first interval: the
    # closed-form inverse must not return garbage (a negative "information") but raise.
    F = np.zeros((1, 12, 9))
    F[0, :9] = np.eye(9)
    Q = -np.eye(12)[None]
    X, turns = np.ones((2, 3, 4)), np.broadcast_to(np.eye(3), (2, 3, 3))
    with pytest.raises(np.linalg.LinAlgError):
        gram_one(NavTable(F, Q, np.zeros(2, int)), turns, np.zeros(2, bool), X, np.eye(9))
    M = MOUNTINGS_AT_ONCE  # and the kernel that filters many mountings at once
    with pytest.raises(np.linalg.LinAlgError):
        gram_pass(
            NavTable(F, Q, np.zeros(2, int)),
            np.broadcast_to(np.eye(3), (2, M, 3, 3)),
            np.zeros(2, bool),
            np.ones((2, M, 3, 4)),
            np.broadcast_to(np.eye(9), (M, 9, 9)),
            np.zeros((M, 9, 4)),
        )


def test_compiled_propagation_equals_the_loop():
    # The error-state recursion S_k = Phi(T_k) S_{k-1} + u_k with the tool's own transition
    # (Earth rate, gravity) over intervals of three lengths; the loop in numpy is the reference.
    rng = np.random.default_rng(4)
    g = earth.gravity(LAT)
    T = rng.choice([0.1, 1.0, 10.0], size=300)
    inputs = rng.normal(size=(300, 6, 7))
    S0 = rng.normal(size=(6, 7))
    out, S_end = propagate(inputs, T, S0, Site(LAT, g), return_final=True, compiled=True)
    model = step_model(Site(LAT, g))
    S, ref = S0.copy(), [S0[3:]]
    for t, u in zip(T, inputs, strict=True):
        S = np.asarray(model.transition(t)) @ S + u
        ref.append(S[3:])
    np.testing.assert_allclose(out, np.array(ref), rtol=1e-10, atol=1e-10 * np.abs(ref).max())
    np.testing.assert_allclose(S_end, S, rtol=1e-10, atol=1e-10 * np.abs(S).max())
    loop = propagate(inputs, T, S0, Site(LAT, g))
    np.testing.assert_allclose(out, loop, rtol=1e-12, atol=1e-12 * np.abs(loop).max())
