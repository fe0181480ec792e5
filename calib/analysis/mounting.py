"""The mounting basis: the whitened observation model of a sequence for every base mounting.

The mounting enters the model only through 63 basis weights
(:func:`basis_weights`), so the Gram matrix of the whitened basis columns,
built once per sequence (:func:`sequence_model`), gives the information
and the exact sigma gradient of any mounting at the cost of a small product
(:class:`SequenceModel`). :func:`analyze` is the observability of a
sequence at one mounting.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from calib.model import params as P
from calib.model.requirements import PAPER, Requirements
from calib.nav import earth
from calib.nav.jacobian import (
    N_UNKNOWN,
    ObservationGrid,
    observation_matrix,
    propagate,
    sample_layout,
    step_model,
)
from calib.nav.site import Site
from calib.nav.transform import rotvec_to_dcm, skew
from calib.noise.profiles import NoiseProfile
from calib.noise.whitening import Whitener, whiten
from calib.sequence.definition import Sequence, nominal_attitude, timeline
from calib.sequence.kinematics import body_integrals

from .nominal import noise_along, nominal_samples
from .observability import Observability, from_information

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


def combination(
    setup_rotvec, column_basis: np.ndarray, column_param: np.ndarray, omega_ie_n: np.ndarray, f_n: np.ndarray
) -> np.ndarray:
    """(n + 3, 24) map from the kept basis columns and phi0's to the 24 columns of ``H``.

    Kept column ``j`` is basis term ``column_basis[j]`` of parameter ``column_param[j]``
    (see :class:`SequenceModel`): it enters that parameter's column with the term's
    :func:`basis_weights` at the mounting; phi0's three columns pass unchanged.
    """
    R = rotvec_to_dcm(np.asarray(setup_rotvec, dtype=float))
    w = basis_weights(R, omega_ie_n, f_n)
    n = len(column_basis)
    A = np.zeros((n + 3, N_UNKNOWN))
    A[np.arange(n), column_param] = w[column_basis]
    A[n:, P.N_PARAMS :] = np.eye(3)
    return A


@dataclass(frozen=True)
class SequenceModel:
    """Whitened observation model of a sequence for every base mounting at once.

    The mounting ``R`` enters the moments only as ``R C_nom`` and through the
    Earth rate and gravity seen in the body, ``E R^T w`` and ``E R^T f`` (see
    :func:`calib.sequence.kinematics.body_integrals`). So the moments, and with them the
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
    source: tuple = ()  # (sequence, profile, site) to rebuild X from

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
        return combination(setup_rotvec, self.column_basis, self.column_param, self.omega_ie_n, self.f_n)

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
        nominal: Observability | None = None,
        requirements: Requirements = PAPER,
    ) -> Observability:
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
    site: Site,
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
    G = step_model(site).input_map
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
    parts = [(rot, G_rot, 0), (t4, GK[:3], 9), (t4[:, :2], GK[3:], 36)]
    blocks = [(prim, Gb, _fed(Gb), term) for prim, Gb, term in parts]
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


def basis_chunks(seq: Sequence, site: Site, Phi_vv: np.ndarray, compiled: bool = False):
    """The kept basis columns and phi0's of ``H``, unwhitened, ``CHUNK_INTERVALS`` intervals at a time.

    Yields ``(intervals (slice), H_chunk (k, 3, n + 3), keep)``; propagation is a
    recursion over the intervals, its state carried from chunk to chunk. ``Phi_vv``
    (K, 3, 3) is every interval's velocity transition (the profile's
    :func:`calib.noise.whitening.velocity_transitions`, the same for every mounting); ``compiled``
    as in :func:`calib.nav.jacobian.propagate`.
    """
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    flip, E = body_integrals(tl, t_nav[1:])
    C = nominal_attitude(tl, t_nav)
    L = sample_layout(C, t_nav, ObservationGrid(bounds))  # bounds cover every sample
    T = np.diff(t_nav[bounds])
    blocks, keep = _basis_blocks(L.C_mid, flip, E, L.h, L.tau, L.starts, site)
    S = np.zeros((6, len(keep) + 3))
    S[:3, -3:] = np.eye(3)
    for k0 in range(0, len(T), CHUNK_INTERVALS):
        part = slice(k0, k0 + CHUNK_INTERVALS)
        inputs = _chunk_inputs(blocks, part, 3)
        S_v, S = propagate(inputs, T[part], S, site, return_final=True, compiled=compiled)
        yield part, observation_matrix(S_v, Phi_vv[part]), keep


def _whitened_chunks(seq: Sequence, profile: NoiseProfile, site: Site):
    """The kept whitened columns and phi0's, ``CHUNK_INTERVALS`` intervals at a time.

    Yields ``(X_chunk (3k, n + 3), keep)``. Propagation and whitening are recursions
    over the intervals: their states are carried from chunk to chunk, so the chunks
    stacked are the whole-run ``X`` exactly, without holding it.
    """
    tl = timeline(seq)
    t_nav, bounds = nominal_samples(tl)
    noise = noise_along(t_nav, nominal_attitude(tl, t_nav), bounds, site, profile)
    w = noise.whitener
    state = None
    for part, H, keep in basis_chunks(seq, site, noise.Phi_vv):
        w_part = Whitener(w.F_ss[part], w.F_vs[part], w.gain[part], w.L_inv[part], 0.0, w.P_end)
        Hw, state = whiten(w_part, H, state, return_final=True)
        yield Hw.reshape(-1, H.shape[-1]), keep


@functools.lru_cache(maxsize=32)
def sequence_model(seq: Sequence, profile: NoiseProfile, site: Site) -> SequenceModel:
    """Build (and cache) the mounting-independent model of a sequence."""
    gram: np.ndarray | float = 0.0
    # every chunk keeps the same columns: the last chunk's `keep` is used below
    for Hw, keep in _whitened_chunks(seq, profile, site):  # noqa: B007
        gram = gram + Hw.T @ Hw
    return SequenceModel(
        gram=0.5 * (gram + np.transpose(gram)),
        column_basis=keep // P.N_PARAMS,
        column_param=keep % P.N_PARAMS,
        omega_ie_n=site.omega_ie_n,
        f_n=earth.specific_force_n(site.gravity_mps2),
        duration_s=seq.duration_s,
        profile=profile.name,
        source=(seq, profile, site),
    )


def information(seq: Sequence, profile: NoiseProfile, site: Site, setup_rotvec=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Fisher information (24 x 24, SI) of [21 parameters, phi0] for one base mounting."""
    return sequence_model(seq, profile, site).information(setup_rotvec)


def analyze(seq: Sequence, profile: NoiseProfile, site: Site, setup_rotvec=(0.0, 0.0, 0.0)) -> Observability:
    """Observability of a sequence at one base mounting."""
    return sequence_model(seq, profile, site).analyze(setup_rotvec)
