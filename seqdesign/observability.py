"""Observability of a sequence: Fisher information, predicted sigma, separability.

The information is the one the estimator would gather: the same linear
model (:func:`calib.jacobian.observation_jacobian`) evaluated along the
nominal trajectory of the sequence, the same observation intervals and the
same noise whitening. Its inverse is the covariance the calibration will
reach with that noise profile; the Monte Carlo tests check that it does.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from calib import earth
from calib import params as P
from calib.extras import Extras
from calib.information import ScaledInverse, eliminate, marginal, projected_covariance, scaled_inverse
from calib.jacobian import (
    N_UNKNOWN,
    ObservationGrid,
    observation_matrix,
    propagate,
    sample_layout,
    step_model,
)
from calib.jacobian import PHI0 as PHI0_IDX
from calib.noise import Whitener, whiten
from calib.nominal import (  # noqa: F401
    ANALYSIS_REST_STEP_S,
    FLIP_SUBSAMPLE_DEG,
    REST_SUBSAMPLES,
    NominalRun,
    information_along,
    information_along_many,
    noise_along,
    nominal_run,
    nominal_samples,
)
from calib.profiles import NoiseProfile
from calib.requirements import PAPER, Requirements
from calib.sequence import Sequence, nominal_attitude, timeline
from calib.sim import body_integrals
from calib.transform import rotvec_to_dcm, skew

CORRELATION_LIMIT = 0.9


@dataclass(frozen=True)
class Observability:
    """Predicted accuracy and separability of the 21 parameters at one mounting.

    Attributes
    ----------
    information : ndarray (24, 24)
        Fisher information of [21 parameters, phi0] in SI.
    covariance : ndarray (21, 21)
        Marginal covariance of the 21 (SI) with the unobserved directions left
        unfitted; rows of parameters that are not estimable mean nothing.
    rank : int
        Number of observed directions of the 21 (:mod:`calib.information`'s rule).
    unobservable : list of str
        Unobserved directions as combinations of parameter names.
    estimable : ndarray (21,) of bool
        Whether each parameter can be estimated on its own.
    null_basis : ndarray (21, k)
        The unobserved directions (requirement-scaled, orthonormal).
    """

    information: np.ndarray
    covariance: np.ndarray
    rank: int
    unobservable: list[str]
    duration_s: float
    profile: str
    setup_rotvec: np.ndarray
    estimable: np.ndarray
    null_basis: np.ndarray
    requirements: Requirements = PAPER

    @property
    def sigma(self) -> np.ndarray:
        """1-sigma (SI) of each parameter; inf where it is not estimable."""
        s = np.sqrt(np.abs(np.diag(self.covariance)))
        return np.where(self.estimable, s, np.inf)

    @property
    def ratio(self) -> np.ndarray:
        return self.requirements.ratio(self.sigma)

    @property
    def worst(self) -> tuple[str, float]:
        """The estimable parameter with the largest ratio (inf if none is estimable)."""
        r = np.where(self.estimable, self.ratio, -np.inf)
        i = int(np.argmax(r))
        return P.NAMES[i], float(r[i]) if self.estimable.any() else math.inf

    @property
    def correlation(self) -> np.ndarray:
        s = np.sqrt(np.abs(np.diag(self.covariance)))
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = self.covariance / np.outer(s, s)
        rho[~self.estimable, :] = np.nan
        rho[:, ~self.estimable] = np.nan
        return rho

    def correlated_pairs(self, limit: float = CORRELATION_LIMIT) -> list[tuple[str, str, float]]:
        """Pairs of estimable parameters with |rho| above ``limit``, strongest first."""
        rho = self.correlation
        out = [
            (P.NAMES[i], P.NAMES[j], float(rho[i, j]))
            for i, j in itertools.combinations(range(P.N_PARAMS), 2)
            if self.estimable[i] and self.estimable[j] and abs(rho[i, j]) > limit
        ]
        return sorted(out, key=lambda t: -abs(t[2]))

    def scaled_information(self) -> np.ndarray:
        """Marginal information of the 21, in units of the requirements (dimensionless)."""
        D = self.requirements.si
        return marginal(self.information) * np.outer(D, D)

    def criteria(self) -> dict[str, float]:
        """D-, A-, E-criteria and condition number of the requirement-scaled information.

        D: log det of the scaled information (larger is better); A: trace of
        the scaled covariance, i.e. sum of (sigma/requirement)^2 (smaller is
        better); E: smallest eigenvalue of the scaled information (larger is
        better).
        """
        ev = np.linalg.eigvalsh(self.scaled_information())
        if self.rank < P.N_PARAMS or ev[0] <= 0:
            return {"D": -math.inf, "A": math.inf, "E": 0.0, "condition": math.inf}
        return {
            "D": float(np.sum(np.log(ev))),
            "A": float(np.sum(1.0 / ev)),
            "E": float(ev[0]),
            "condition": float(ev[-1] / ev[0]),
        }


def from_information(
    info: np.ndarray,
    duration_s: float,
    profile: str,
    setup_rotvec,
    nominal: "Observability | None" = None,
    requirements: Requirements = PAPER,
) -> Observability:
    """Observability from the information of [21, phi0].

    With ``nominal`` (the same sequence at the nominal mounting), what is
    observed is judged there: its unobserved directions stay unfitted here
    too, so a tilt cannot make a parameter count as observed.
    """
    D = requirements.si
    Ms = marginal(info) * np.outer(D, D)
    inv = scaled_inverse(Ms, P.NAMES)
    if nominal is not None and not nominal.estimable.all():
        cov = projected_covariance(Ms, nominal.null_basis)
        inv = ScaledInverse(cov, nominal.rank, nominal.null_basis, nominal.estimable, inv.names)
    return Observability(
        information=info,
        covariance=inv.covariance * np.outer(D, D),
        rank=inv.rank,
        unobservable=inv.null_directions(),
        duration_s=duration_s,
        profile=profile,
        setup_rotvec=np.asarray(setup_rotvec, dtype=float),
        estimable=inv.estimable,
        null_basis=inv.null_basis,
        requirements=requirements,
    )


N_BASIS = 9 + 27 + 27


def basis_weights(R: np.ndarray, omega_ie_n: np.ndarray, f_n: np.ndarray) -> np.ndarray:
    """Weights of the mounting basis: ``R[a,b]``, ``R[a,b] (R^T w)_c``, ``R[a,b] (R^T f)_c``."""
    w, f = R.T @ omega_ie_n, R.T @ f_n
    return np.concatenate(
        [R.reshape(9), np.einsum("ab,c->abc", R, w).reshape(27), np.einsum("ab,c->abc", R, f).reshape(27)]
    )


def rotvec_derivatives(rotvec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R = exp([rotvec x])`` and ``dR/drotvec_k`` (3, 3, 3; k first), in closed form.

    ``dR = [(J_l drotvec) x] R`` with the left Jacobian of SO(3),
    ``J_l = I + (1 - cos n)/n^2 K + (n - sin n)/n^3 K^2`` (``K = [rotvec x]``); the
    two coefficients use their Taylor series below n = 1e-4 rad, where the
    closed forms lose digits to cancellation.
    """
    rotvec = np.asarray(rotvec, dtype=float)
    n = float(np.linalg.norm(rotvec))
    K = skew(rotvec)
    if n < 1e-4:
        a, b = 0.5 - n**2 / 24.0, 1.0 / 6.0 - n**2 / 120.0
    else:
        a, b = (1.0 - math.cos(n)) / n**2, (n - math.sin(n)) / n**3
    J = np.eye(3) + a * K + b * K @ K
    R = rotvec_to_dcm(rotvec)
    return R, np.array([skew(J[:, k]) @ R for k in range(3)])


def basis_weights_jacobian(rotvec: np.ndarray, omega_ie_n: np.ndarray, f_n: np.ndarray) -> np.ndarray:
    """``d basis_weights / d rotvec``, shape (N_BASIS, 3): :func:`basis_weights` differentiated."""
    R, dR = rotvec_derivatives(rotvec)
    w, f = R.T @ omega_ie_n, R.T @ f_n
    cols = []
    for d in dR:
        dw, df = d.T @ omega_ie_n, d.T @ f_n
        cols.append(
            np.concatenate(
                [
                    d.reshape(9),
                    (np.einsum("ab,c->abc", d, w) + np.einsum("ab,c->abc", R, dw)).reshape(27),
                    (np.einsum("ab,c->abc", d, f) + np.einsum("ab,c->abc", R, df)).reshape(27),
                ]
            )
        )
    return np.array(cols).T


@dataclass(frozen=True)
class SequenceModel:
    """Whitened observation model of a sequence for every base mounting at once.

    The mounting ``R`` enters the moments only as ``R C_nom`` and through the
    Earth rate and gravity seen in the body, ``E R^T w`` and ``E R^T f`` (see
    :func:`calib.sim.body_integrals`). So the moments, and with them the
    linear, whitened ``H``, are a fixed combination of 63 basis terms weighted
    by :func:`basis_weights`; the initial-attitude columns do not depend on
    ``R`` at all. Of the 63 x 21 (basis term, parameter) columns only those the
    step's input map feeds are not identically zero; column ``j`` kept is basis
    term ``column_basis[j]`` of parameter ``column_param[j]``. With ``X`` the
    kept whitened columns and the three of phi0, ``H = X A(R)`` and the
    information of any mounting is ``A' (X' X) A``: building keeps only the
    Gram matrix ``X' X`` (a few hundred square, whatever the sequence's length),
    and each mounting costs a product of that size.
    """

    gram: np.ndarray  # (n + 3, n + 3): X' X, phi0 columns last
    column_basis: np.ndarray  # (n,) int
    column_param: np.ndarray  # (n,) int
    omega_ie_n: np.ndarray
    f_n: np.ndarray
    duration_s: float
    profile: str
    source: tuple = ()  # (sequence, profile, latitude_rad, height_m) to rebuild X from

    @property
    def _X(self) -> np.ndarray:
        """The kept whitened columns and phi0's, (3K, n + 3), rebuilt (not kept in memory)."""
        return np.concatenate([Hw for Hw, _ in _whitened_chunks(*self.source)], axis=0)

    @property
    def Hw_basis(self) -> np.ndarray:
        """The whitened basis as (3K, N_BASIS, 21), zero columns included (rebuilt)."""
        X = self._X
        out = np.zeros((X.shape[0], N_BASIS, P.N_PARAMS))
        out[:, self.column_basis, self.column_param] = X[:, :-3]
        return out

    @property
    def Hw_phi0(self) -> np.ndarray:
        """The whitened initial-attitude columns (3K, 3) (rebuilt)."""
        return self._X[:, -3:]

    def _combination(self, setup_rotvec) -> np.ndarray:
        """(n + 3, 24) map from the kept columns and phi0 to the 24 columns of ``H``."""
        R = rotvec_to_dcm(np.asarray(setup_rotvec, dtype=float))
        w = basis_weights(R, self.omega_ie_n, self.f_n)
        n = len(self.column_basis)
        A = np.zeros((n + 3, N_UNKNOWN))
        A[np.arange(n), self.column_param] = w[self.column_basis]
        A[n:, P.N_PARAMS :] = np.eye(3)
        return A

    def whitened(self, setup_rotvec) -> np.ndarray:
        """Whitened ``H`` (3K x 24) for one mounting (rebuilds ``X``: slow, for checks)."""
        return self._X @ self._combination(setup_rotvec)

    def information(self, setup_rotvec=(0.0, 0.0, 0.0)) -> np.ndarray:
        A = self._combination(setup_rotvec)
        N = A.T @ (self.gram @ A)
        return 0.5 * (N + N.T)

    def sigma_gradient(self, setup_rotvec, index: int) -> tuple[float, np.ndarray]:
        """One parameter's sigma (SI) and its exact gradient in the mounting (per rad).

        With full rank, ``sigma_i^2 = e_i' N^-1 e_i`` (the marginal covariance of the
        21 is the block of the full inverse), so with ``v = N^-1 e_i`` and ``H = X A``
        (``X`` the kept columns and phi0): ``d sigma_i^2 = -2 (H v)' dH v``, where
        ``(H v)' X = (gram A v)'`` and ``dH`` is the mounting basis times
        :func:`basis_weights_jacobian`.
        """
        rotvec = np.asarray(setup_rotvec, dtype=float)
        A = self._combination(rotvec)
        gram_A = self.gram @ A
        N = A.T @ gram_A
        e = np.zeros(len(N))
        e[index] = 1.0
        v = np.linalg.solve(0.5 * (N + N.T), e)
        sigma = math.sqrt(max(v[index], 0.0))
        n = len(self.column_basis)
        y = (gram_A @ v)[:n]
        dvar_dw = -2.0 * np.bincount(self.column_basis, weights=y * v[self.column_param], minlength=N_BASIS)
        J = basis_weights_jacobian(rotvec, self.omega_ie_n, self.f_n)
        return sigma, (dvar_dw @ J) / (2.0 * sigma)

    def analyze(
        self,
        setup_rotvec=(0.0, 0.0, 0.0),
        nominal: "Observability | None" = None,
        requirements: Requirements = PAPER,
    ) -> "Observability":
        return from_information(
            self.information(setup_rotvec), self.duration_s, self.profile, setup_rotvec, nominal, requirements
        )


def _contract_into(
    out: np.ndarray, first_column: int, prim: np.ndarray, G: np.ndarray, params: np.ndarray
) -> int:
    """Write ``sum_{w,i,m} prim[k,w,b,i,m,c] G[w,a,i,m,p,s]`` into ``out[k, s, columns]``.

    ``prim`` (K, w, b, i, m, c) and ``G`` (w, a, i, m, p, s); only the parameters
    ``params`` (those ``G`` feeds at all) are formed. The columns, from
    ``first_column`` on, run over ``(b, c, a, p)``, so that each state's matrix
    product lands in ``out`` in one strided copy. Returns the next free column.
    """
    K, nw, nb, ni, nm, nc = prim.shape
    X = prim.transpose(0, 2, 5, 1, 3, 4).reshape(K * nb * nc, nw * ni * nm)
    Y = G[:nw][..., params, :].transpose(5, 0, 2, 3, 1, 4).reshape(6, nw * ni * nm, -1)
    n = nb * nc * 3 * len(params)
    for s in range(6):
        out[:, s, first_column : first_column + n] = (X @ Y[s]).reshape(K, n)
    return first_column + n


def _block_columns(first_term: int, nb: int, nc: int, params: np.ndarray) -> np.ndarray:
    """``basis_term * 21 + parameter`` of the columns :func:`_contract_into` writes."""
    b, c, a, p = np.meshgrid(np.arange(nb), np.arange(nc), np.arange(3), params, indexing="ij")
    return ((first_term + (a * nb + b) * nc + c) * P.N_PARAMS + p).ravel()


def _fed(G: np.ndarray) -> np.ndarray:
    """The parameters a block of the input map feeds (non-zero anywhere)."""
    return np.flatnonzero(np.any(G != 0.0, axis=tuple(i for i in range(G.ndim) if i != G.ndim - 2)))


def _basis_blocks(
    C_mid: np.ndarray,
    flip: np.ndarray,
    E: np.ndarray,
    h: np.ndarray,
    tau: np.ndarray,
    starts: np.ndarray,
    latitude_rad: float,
    gravity_mps2: float,
) -> tuple[list, np.ndarray]:
    """How the 63 mounting basis terms feed ``d x_next / d params`` of every interval.

    The moments of basis term ``(a, b)`` are those of the nominal attitude's row ``b``
    placed on navigation axis ``a`` (and likewise ``(a, b, c)`` with component ``c``
    of the body-frame Earth rate or gravity), so instead of writing 63 sparse moment
    vectors per interval and multiplying them by the step's input map, each
    interval's nominal moments are contracted with the map's rows of axis ``a``,
    and only for the parameters the map feeds from them.

    Returns
    -------
    blocks : list of (moments (K, w, b, i, m, c), map (w, a, i, m, p, s), params, term)
        For :func:`_chunk_inputs`: the per-interval nominal moments of a family of
        basis terms (from ``term`` on), the input map's rows for them, and the
        parameters it feeds.
    keep : ndarray (n,) of int
        The columns formed, as ``basis_term * 21 + parameter``.
    """
    G = step_model(float(latitude_rad), float(gravity_mps2)).input_map
    G = G.reshape(5, 36, N_UNKNOWN, 6)[:, :, : P.N_PARAMS]  # moment block, row, unknown, state
    GK = G[:, :27].reshape(5, 3, 3, 3, P.N_PARAMS, 6)  # block, a, i, m, p, s
    # A bias moment (sum tau^w C h) feeds the gyro bias channel of block w and, for w < 2,
    # the accelerometer's of block 3 + w: a "body axis" m of 2 for the contraction.
    GB = np.zeros((3, 3, 3, 2, P.N_PARAMS, 6))  # w, a, i, m, p, s
    GB[:, :, :, 0] = G[:3, 27:].reshape(3, 3, 3, P.N_PARAMS, 6)
    GB[:2, :, :, 1] = G[3:, 27:].reshape(2, 3, 3, P.N_PARAMS, 6)
    weights = np.stack([np.ones_like(tau), tau, tau**2], axis=1)  # (n, w)
    lengths = np.diff(np.append(starts, len(tau)))

    def interval_sum(x):  # per sample (n, ...) -> per interval and weight (K, w, ...)
        # An interval holds a few samples: add the o-th sample of every interval that has
        # one, o = 0, 1, ... (the order np.add.reduceat adds in, at a fraction of its cost).
        out = np.zeros((len(starts), 3) + x.shape[1:])
        for o in range(int(lengths.max())):
            k = np.flatnonzero(lengths > o)
            j = starts[k] + o
            out[k] += weights[j].reshape((len(j), 3) + (1,) * (x.ndim - 1)) * x[j, None]
        return out

    kflip = interval_sum(np.einsum("nbi,nm->nbim", C_mid, flip))  # (K, w, b, i, m)
    bias = interval_sum(C_mid * h[:, None, None])[..., None]  # (K, w, b, i, 1)
    # The rotation terms: flip moments (m = body axis) and bias moments side by side.
    rot = np.concatenate([kflip, bias, bias], axis=4)[..., None]  # (K, w, b, i, 5, 1)
    G_rot = np.concatenate([GK[:3], GB], axis=3)
    t4 = interval_sum(np.einsum("nbi,nmc->nbimc", C_mid, E))  # (K, w, b, i, m, c)
    blocks = [(rot, G_rot, 0), (t4, GK[:3], 9), (t4[:, :2], GK[3:], 36)]
    blocks = [(prim, Gb, _fed(Gb), term) for prim, Gb, term in blocks]
    keep = np.concatenate(
        [_block_columns(term, prim.shape[2], prim.shape[5], params) for prim, _, params, term in blocks]
    )
    return blocks, keep


def _chunk_inputs(blocks: list, intervals: slice, extra_columns: int) -> np.ndarray:
    """The kept columns' inputs ``d x_next / d params`` of some intervals, (k, 6, n + extra)."""
    k = len(range(*intervals.indices(len(blocks[0][0]))))
    n = sum(prim.shape[2] * prim.shape[5] * 3 * len(params) for prim, _, params, _ in blocks)
    inputs = np.zeros((k, 6, n + extra_columns))
    column = 0
    for prim, Gb, params, _ in blocks:
        column = _contract_into(inputs, column, prim[intervals], Gb, params)
    return inputs


CHUNK_INTERVALS = 512  # ~13 MB of inputs: buffers reused, not paged in afresh


def _whitened_chunks(seq: Sequence, profile: NoiseProfile, latitude_rad: float, height_m: float):
    """The kept whitened columns and phi0's, ``CHUNK_INTERVALS`` intervals at a time.

    Yields ``(X_chunk (3k, n + 3), keep)``. Propagation and whitening are recursions
    over the intervals: their states are carried from chunk to chunk, so the chunks
    stacked are the whole-run ``X`` exactly, without holding it.
    """
    g = earth.gravity(latitude_rad, height_m)
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    flip, E = body_integrals(tl, t_nav[1:])
    C = nominal_attitude(tl, t_nav)
    L = sample_layout(C, t_nav, ObservationGrid(bounds))  # bounds cover every sample
    T = np.diff(t_nav[bounds])
    blocks, keep = _basis_blocks(L.C_mid, flip, E, L.h, L.tau, L.starts, latitude_rad, g)
    noise = noise_along(t_nav, C, bounds, latitude_rad, g, profile)
    w = noise.whitener
    S = np.zeros((6, len(keep) + 3))
    S[:3, -3:] = np.eye(3)
    state = None
    for k0 in range(0, len(T), CHUNK_INTERVALS):
        part = slice(k0, k0 + CHUNK_INTERVALS)
        S_v, S = propagate(_chunk_inputs(blocks, part, 3), T[part], S, latitude_rad, g, return_final=True)
        H = observation_matrix(S_v, noise.Phi_vv[part])
        w_part = Whitener(w.F_ss[part], w.F_vs[part], w.gain[part], w.L_inv[part], 0.0, w.P_end)
        Hw, state = whiten(w_part, H, state, return_final=True)
        yield Hw.reshape(-1, H.shape[-1]), keep


@functools.lru_cache(maxsize=32)
def sequence_model(
    seq: Sequence, profile: NoiseProfile, latitude_rad: float, height_m: float = 0.0
) -> SequenceModel:
    """Build (and cache) the mounting-independent model of a sequence."""
    gram = 0.0
    for Hw, keep in _whitened_chunks(seq, profile, latitude_rad, height_m):
        gram = gram + Hw.T @ Hw
    g = earth.gravity(latitude_rad, height_m)
    return SequenceModel(
        gram=0.5 * (gram + gram.T),
        column_basis=keep // P.N_PARAMS,
        column_param=keep % P.N_PARAMS,
        omega_ie_n=earth.omega_ie_n(latitude_rad),
        f_n=earth.specific_force_n(g),
        duration_s=seq.duration_s,
        profile=profile.name,
        source=(seq, profile, latitude_rad, height_m),
    )


def information(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float = 0.0,
    setup_rotvec=(0.0, 0.0, 0.0),
) -> np.ndarray:
    """Fisher information (24 x 24, SI) of [21 parameters, phi0] for one base mounting."""
    return sequence_model(seq, profile, latitude_rad, height_m).information(setup_rotvec)


def analyze(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float = 0.0,
    setup_rotvec=(0.0, 0.0, 0.0),
) -> Observability:
    """Observability of a sequence at one base mounting."""
    return sequence_model(seq, profile, latitude_rad, height_m).analyze(setup_rotvec)


@dataclass(frozen=True)
class Robustness:
    """Observability over the +-tolerance box of base mountings."""

    nominal: Observability
    worst: Observability  # the mounting with the largest worst ratio
    per_parameter_worst_sigma: np.ndarray  # (21,) SI, max over the box of each sigma
    points: int
    tolerance_deg: float
    searched: bool = False  # whether IPOPT refined the worst parameter beyond the 27 points

    @property
    def per_parameter_worst_ratio(self) -> np.ndarray:
        return self.nominal.requirements.ratio(self.per_parameter_worst_sigma)


def _point(arg) -> np.ndarray:
    return np.asarray(arg[0], dtype=float).ravel()


def _scalar_callback(name: str, value, gradient):
    """A casadi Callback of ``value(theta_deg) -> float`` with Jacobian ``gradient(theta_deg)``.

    IPOPT then needs no finite differences of its own.
    """
    import casadi as ca

    class _Grad(ca.Callback):
        def __init__(self, name, opts):
            ca.Callback.__init__(self)
            self.construct(name, opts)

        def get_n_in(self):
            return 2  # the point and the nominal output

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(3, 1) if i == 0 else ca.Sparsity.dense(1, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(1, 3)

        def eval(self, arg):
            return [ca.DM(np.asarray(gradient(_point(arg)), dtype=float)[None, :])]

    class _CB(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct(name, {})

        def has_jacobian(self):
            return True

        def get_jacobian(self, name, inames, onames, opts):
            self._jac = _Grad(name, opts)  # casadi keeps no reference of its own
            return self._jac

        def get_n_in(self):
            return 1

        def get_n_out(self):
            return 1

        def get_sparsity_in(self, i):
            return ca.Sparsity.dense(3, 1)

        def get_sparsity_out(self, i):
            return ca.Sparsity.dense(1, 1)

        def eval(self, arg):
            return [float(value(_point(arg)))]

    return _CB()


def _ipopt_max(
    cb, starts_deg: list, tolerance_deg: float, max_iter: int = 25, tol: float = 1e-6
) -> tuple[np.ndarray, float]:
    """Maximise a scalar callback of the mounting (deg) over the box from each start."""
    import casadi as ca

    x = ca.MX.sym("theta_deg", 3)
    solver = ca.nlpsol(
        "worst",
        "ipopt",
        {"x": x, "f": -cb(x)},
        {
            "print_time": False,
            "ipopt.print_level": 0,
            "ipopt.sb": "yes",
            "ipopt.hessian_approximation": "limited-memory",
            "ipopt.max_iter": max_iter,
            "ipopt.tol": tol,
        },
    )
    best_x, best = None, -np.inf
    for x0 in starts_deg:
        sol = solver(x0=x0, lbx=-tolerance_deg, ubx=tolerance_deg)
        value = -float(sol["f"])
        if value > best:
            best, best_x = value, np.asarray(sol["x"]).ravel()
    return best_x, best


def search_worst_mounting(
    model: SequenceModel,
    index: int,
    starts_deg: list,
    tolerance_deg: float,
    requirements: Requirements = PAPER,
) -> tuple[np.ndarray, float]:
    """Maximise one parameter's sigma over the mounting box with IPOPT, from several starts.

    The gradient is exact (:meth:`SequenceModel.sigma_gradient`: the mounting basis
    differentiated). Returns the mounting (rotation vector, rad) and that
    parameter's sigma (SI).
    """
    req = requirements.si[index]

    def value(theta_deg):
        return model.analyze(np.radians(theta_deg)).sigma[index] / req

    def gradient(theta_deg):
        _, grad = model.sigma_gradient(np.radians(theta_deg), index)
        return grad * (math.pi / 180.0) / req

    cb = _scalar_callback(f"sigma_{P.NAMES[index]}", value, gradient)
    best_x, best = _ipopt_max(cb, starts_deg, tolerance_deg)
    return np.radians(best_x), best * req


FD_STEP_DEG = 1e-3  # forward step of the direct search's gradient (see search_worst_direct)
DIRECT_MAX_ITER = 8


def search_worst_direct(
    sigma_of, start_deg, tolerance_deg: float, max_iter: int = DIRECT_MAX_ITER, sigmas_of=None
) -> tuple[np.ndarray, float]:
    """Maximise ``sigma_of(rotvec)`` over the box with IPOPT where no closed form exists.

    For Gauss-Markov bias instability the noise filter's gains depend on the
    attitude of every interval (a Riccati recursion), and the optional terms'
    sensitivities are polynomials of up to third degree in the mounting: neither
    enters the 63-term basis. Each value is then an exact evaluation along the
    mounting's own trajectory (as the 27 box points), and the gradient IPOPT is
    steered by is a forward difference of those values, ``FD_STEP_DEG`` apart
    (truncation ~ step / 2 x curvature: ~1e-4 of the gradient over a 3 deg box;
    rounding ~1e-12 / 2e-5 rad). What is returned is the best exact evaluation
    seen, so the search can only raise the worst case, never invent one.

    ``sigmas_of(rotvecs) -> sigmas``, if given, evaluates a gradient's points (the
    value and its three steps, those not yet seen) in one call: a batch shares one
    pass of the noise filter (:func:`calib.nominal.information_along_many`).

    Returns the mounting (rotation vector, rad) and its ``sigma_of``.
    """
    seen: dict[tuple, float] = {}

    def key_of(theta_deg):
        return tuple(np.round(theta_deg, 12))

    def value(theta_deg):
        key = key_of(theta_deg)
        if key not in seen:
            seen[key] = float(sigma_of(np.radians(theta_deg)))
        return seen[key]

    def gradient(theta_deg):
        points = [np.asarray(theta_deg, dtype=float)] + [theta_deg + FD_STEP_DEG * e for e in np.eye(3)]
        new = [t for t in points if key_of(t) not in seen]
        if sigmas_of is not None and len(new) > 1:
            for t, sigma in zip(new, sigmas_of([np.radians(t) for t in new])):
                seen[key_of(t)] = float(sigma)
        f0 = value(points[0])
        return np.array([(value(t) - f0) / FD_STEP_DEG for t in points[1:]])

    scale = value(np.asarray(start_deg, dtype=float))
    cb = _scalar_callback("sigma", lambda t: value(t) / scale, lambda t: gradient(t) / scale)
    _ipopt_max(cb, [start_deg], tolerance_deg, max_iter=max_iter, tol=1e-5)
    # Only the box's evaluations count, not the forward-difference points outside it.
    inside = {k: v for k, v in seen.items() if max(abs(x) for x in k) <= tolerance_deg}
    key = max(inside, key=inside.get)
    return np.radians(np.array(key)), inside[key]


BATCH_MOUNTINGS = 9  # mountings per pass of the GM noise filter: the 27 box points in 3 passes


def _batches(items: list, size: int) -> list[list]:
    return [items[i : i + size] for i in range(0, len(items), size)]


def _gm_information(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float,
    rotvecs: list,
    extras: Extras | None = None,
    batch: int = BATCH_MOUNTINGS,
) -> list[np.ndarray]:
    """Fisher information of each mounting, evaluated along its own nominal trajectory.

    ``batch`` mountings share a pass of the noise filter
    (:func:`calib.nominal.information_along_many`); ``batch=1`` evaluates each on its
    own (:func:`calib.nominal.information_along`), the reference the tests hold the
    batches to.
    """
    g = earth.gravity(latitude_rad, height_m)
    kw = {} if extras is None else {"extras": extras}
    out = []
    for part in _batches(list(rotvecs), max(1, batch)):
        noms = [nominal_run(seq, latitude_rad, height_m, rv) for rv in part]
        if batch > 1:
            out.extend(information_along_many(noms, profile, latitude_rad, g, **kw))
        else:
            out.extend(information_along(n, profile, latitude_rad, g, **kw) for n in noms)
    return out


def _evaluator(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float,
    requirements: Requirements,
    batch: int = BATCH_MOUNTINGS,
):
    """``evaluate(rotvecs, nominal=None) -> [Observability]`` and the basis model (None with GM)."""
    if profile.has_gauss_markov:
        # Bias-instability weights depend on the mounting (measured: up to 4.7 % on a sigma
        # for designed-30min-9moves if the nominal weights are reused), so evaluate each directly.
        def evaluate(rotvecs, nominal=None):
            infos = _gm_information(seq, profile, latitude_rad, height_m, rotvecs, batch=batch)
            return [
                from_information(info, seq.duration_s, profile.name, rv, nominal, requirements)
                for info, rv in zip(infos, rotvecs)
            ]

        return evaluate, None
    model = sequence_model(seq, profile, latitude_rad, height_m)

    def evaluate(rotvecs, nominal=None):
        return [model.analyze(rv, nominal, requirements) for rv in rotvecs]

    return evaluate, model


def analyze_tolerance(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    height_m: float = 0.0,
    tolerance_deg: float = 3.0,
    search: bool = True,
    starts: int = 2,
    requirements: Requirements = PAPER,
    batch: int = BATCH_MOUNTINGS,
) -> Robustness:
    """Worst case over the +-tolerance box of base mountings.

    The 27 corner/edge/face/centre points are evaluated; then, if ``search``,
    IPOPT maximises the sigma of the worst parameter, since the worst mounting
    need not be a grid point: under white noise from its ``starts`` worst grid
    points with the exact gradient of the mounting basis
    (:func:`search_worst_mounting`); under Gauss-Markov bias instability, whose
    whitening the basis does not hold, from its worst grid point over direct
    evaluations (:func:`search_worst_direct`), ``batch`` mountings at a time
    (``batch=1``: one at a time, the unbatched reference).
    """
    evaluate, model = _evaluator(seq, profile, latitude_rad, height_m, requirements, batch)
    nominal = evaluate([np.zeros(3)])[0]
    if tolerance_deg == 0:
        return Robustness(nominal, nominal, nominal.sigma, 1, 0.0)
    levels = (-tolerance_deg, 0.0, tolerance_deg)
    grid = [np.array(p) for p in itertools.product(levels, levels, levels)]
    results = evaluate([np.radians(p) for p in grid], nominal)
    sigmas = np.array([r.sigma for r in results])
    per_param = sigmas.max(axis=0)
    worst = max(results, key=lambda r: r.worst[1])
    if not search or nominal.rank < P.N_PARAMS:
        return Robustness(nominal, worst, per_param, len(grid), tolerance_deg)
    index = int(np.argmax(requirements.ratio(per_param)))
    order = np.argsort(-sigmas[:, index])
    if model is not None:
        rotvec, sigma = search_worst_mounting(
            model, index, [grid[i] for i in order[:starts]], tolerance_deg, requirements
        )
    else:
        rotvec, sigma = search_worst_direct(
            lambda rv: evaluate([rv], nominal)[0].sigma[index],
            grid[order[0]],
            tolerance_deg,
            sigmas_of=lambda rvs: [o.sigma[index] for o in evaluate(rvs, nominal)],
        )
    if sigma > per_param[index]:
        found = evaluate([rotvec], nominal)[0]
        per_param = np.maximum(per_param, found.sigma)
        if found.worst[1] > worst.worst[1]:
            worst = found
    return Robustness(nominal, worst, per_param, len(grid), tolerance_deg, searched=True)


@dataclass(frozen=True)
class ExtrasCost:
    """What fitting a real unit's optional terms costs the 21, worst over the mounting box.

    Attributes
    ----------
    extras : Extras
    sigma_without, sigma_with : ndarray (21,)
        Each parameter's worst sigma over the box (SI) without and with the terms.
    extra_sigma : ndarray (e,)
        Each optional parameter's worst sigma (SI); inf where unobservable.
    unobservable : list of str
        Null directions of [21, extras] (scaled by requirements and typical sizes).
    points : int
    """

    extras: Extras
    sigma_without: np.ndarray
    sigma_with: np.ndarray
    extra_sigma: np.ndarray
    unobservable: list[str]
    points: int
    tolerance_deg: float
    searched: bool = False  # whether IPOPT searched beyond the points (analyze_extras)

    def verdicts(self) -> list[str]:
        """Per optional parameter: ``observable`` (3 sigma within its typical size),
        ``weak`` (beyond it) or ``unobservable``.
        """
        out = []
        for p, s in zip(self.extras.parameters, self.extra_sigma):
            out.append(
                "unobservable" if not np.isfinite(s) else "observable" if 3.0 * s <= p.scale_si else "weak"
            )
        return out


def _extras_evaluator(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    extras: Extras,
    height_m: float,
    requirements: Requirements,
    batch: int = BATCH_MOUNTINGS,
):
    """``evaluate(rotvecs) -> [(sigma of the 21 without, with, sigma of the extras)]`` (SI).

    Each mounting is evaluated directly along its own nominal trajectory, ``batch``
    at a time (:func:`_gm_information`); what is observed is judged at the nominal
    mounting (the first evaluation), returned as the second value.
    """
    scale = np.concatenate([requirements.si, extras.scale_si])
    names = P.NAMES + extras.names
    nom_info = _gm_information(seq, profile, latitude_rad, height_m, [np.zeros(3)], extras, batch)[0]
    nominal = scaled_inverse(eliminate(nom_info, PHI0_IDX) * np.outer(scale, scale), names)
    nominal_without = from_information(
        nom_info[:N_UNKNOWN, :N_UNKNOWN], seq.duration_s, profile.name, np.zeros(3), None, requirements
    )

    def sigmas(rotvec, info):
        obs = from_information(
            info[:N_UNKNOWN, :N_UNKNOWN], seq.duration_s, profile.name, rotvec, nominal_without, requirements
        )
        M = eliminate(info, PHI0_IDX) * np.outer(scale, scale)
        variance = np.diag(projected_covariance(M, nominal.null_basis))
        s = np.where(nominal.estimable, np.sqrt(np.abs(variance)), np.inf) * scale
        return obs.sigma, s[: P.N_PARAMS], s[P.N_PARAMS :]

    def evaluate(rotvecs):
        infos = _gm_information(seq, profile, latitude_rad, height_m, rotvecs, extras, batch)
        return [sigmas(rv, info) for rv, info in zip(rotvecs, infos)]

    return evaluate, nominal


def analyze_extras(
    seq: Sequence,
    profile: NoiseProfile,
    latitude_rad: float,
    extras: Extras,
    height_m: float = 0.0,
    tolerance_deg: float = 3.0,
    requirements: Requirements = PAPER,
    search: bool = False,
    batch: int = BATCH_MOUNTINGS,
) -> ExtrasCost:
    """Sigma of the 21 with and without the optional terms, and theirs, worst over the box.

    Both figures come from the same 27 mountings (corners, edges, faces and
    centre of the box) evaluated directly along each nominal trajectory, so
    their ratio is the cost of the terms alone. (The optional terms' moments
    are not in the 63-term mounting basis, hence direct evaluation.) With
    ``search``, IPOPT then maximises the sigma (with the terms) of the worst of
    the 21 from its worst grid point (:func:`search_worst_direct`), and that
    mounting counts as a 28th. ``batch`` mountings are evaluated at a time
    (``batch=1``: one at a time, the unbatched reference).
    """
    levels = (-tolerance_deg, 0.0, tolerance_deg) if tolerance_deg > 0 else (0.0,)
    points = [np.radians(p) for p in itertools.product(levels, levels, levels)]
    evaluate, nominal = _extras_evaluator(seq, profile, latitude_rad, extras, height_m, requirements, batch)
    results = evaluate(points)
    searched = search and tolerance_deg > 0 and bool(nominal.estimable[: P.N_PARAMS].all())
    if searched:
        with_ = np.array([r[1] for r in results])
        index = int(np.argmax(requirements.ratio(with_.max(axis=0))))
        start = np.degrees(points[int(np.argmax(with_[:, index]))])
        rotvec, _ = search_worst_direct(
            lambda rv: evaluate([rv])[0][1][index],
            start,
            tolerance_deg,
            sigmas_of=lambda rvs: [r[1][index] for r in evaluate(rvs)],
        )
        results.extend(evaluate([rotvec]))
    without, with_, extra = (np.max([r[i] for r in results], axis=0) for i in range(3))
    return ExtrasCost(
        extras, without, with_, extra, nominal.null_directions(), len(points), tolerance_deg, searched
    )


def accel_scale_bound(
    duration_s: float,
    profile: NoiseProfile,
    gravity_mps2: float,
    requirements: Requirements = PAPER,
    rate_dps: float | None = None,
) -> float:
    """Best possible worst ratio of the accelerometer scale factors (conventions.md).

    Gravity is their only excitation and ``sum f_i^2 = g^2``: the three share
    at most ``g^2 T / VRW^2`` of information, so at best each gets a third,
    ``sigma >= VRW sqrt(3 / T) / g``.

    With a Gauss-Markov accelerometer bias and a gimbal turning at most ``rate_dps``
    (docs/design.md, "What bounds the Gauss-Markov front"): the information of a long
    run in stationary noise of two-sided density ``S(f)`` is ``int |F(f)|^2 / S(f) df`` (Whittle). The noise
    density ``VRW^2 + S_gm(f)`` falls with frequency, and the rate limit
    ``|du/dt| <= omega`` on the direction of gravity bounds the regressor's power
    above ``f`` by ``(omega / 2 pi f)^2`` of its total; since ``1 / S`` is concave in
    ``(2 pi f)^2`` the best a sequence can do is put all of it at
    ``f = omega / 2 pi`` (one turn of gravity per ``360 / rate`` s), which
    replaces ``VRW^2`` by :func:`accel_density_at_rate`.
    """
    density = profile.vrw**2 if rate_dps is None else accel_density_at_rate(profile, rate_dps)
    sigma = math.sqrt(density * 3.0 / duration_s) / gravity_mps2
    return 3.0 * sigma / min(requirements.si[P.ACCEL_SCALE])


def accel_density_at_rate(profile: NoiseProfile, rate_dps: float) -> float:
    """Accelerometer noise density, ``(m/s^2)^2/Hz`` two-sided, at the frequency one
    turn takes at ``rate_dps``: white ``VRW^2`` plus the GM bias's
    ``2 sigma^2 tau / (1 + (2 pi f tau)^2)`` (whose integral over all f is ``sigma^2``).
    """
    density = profile.vrw**2
    tau = profile.accel_bias_correlation_s
    if profile.accel_gm_sigma > 0 and tau > 0:
        omega = math.radians(rate_dps)  # 2 pi f
        density += 2.0 * profile.accel_gm_sigma**2 * tau / (1.0 + (omega * tau) ** 2)
    return density
