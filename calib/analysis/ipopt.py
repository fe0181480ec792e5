"""IPOPT over python functions: one casadi Callback with its Jacobian, and a box maximiser.

The worst-mounting searches (:mod:`calib.analysis.worst_case`) and the design's dwell
refinement hand IPOPT a python function of a few variables together with
its Jacobian (exact, or finite differences the caller batches), so that
IPOPT takes no finite differences of its own.
"""

from __future__ import annotations

import casadi as ca
import numpy as np


class Function(ca.Callback):
    """A python function of a vector as a casadi function, and its Jacobian if given.

    Parameters
    ----------
    name : str
    value : callable
        ``value(x)`` of ``x`` (n,), returning the output's values (a float or an
        array, reshaped to ``shape_out``).
    sizes_in : list of int
        Lengths of the inputs; only the first, ``x``, is passed to ``value`` (a
        Jacobian's second input is the function's nominal output, unused).
    shape_out : tuple of int
    jacobian : callable, optional
        ``jacobian(x)``: the output's derivatives (m, n), or a gradient (n,) when
        the output is a scalar. Its casadi function is a ``Function`` too.
    opts : dict, optional
        casadi's options of the function (those it passes to a Jacobian).
    """

    def __init__(self, name: str, value, sizes_in: list, shape_out: tuple, jacobian=None, opts=None):
        ca.Callback.__init__(self)
        self._value, self._jacobian = value, jacobian
        self._sizes_in, self._shape_out = list(sizes_in), tuple(shape_out)
        self.construct(name, {} if opts is None else opts)

    def get_n_in(self):
        return len(self._sizes_in)

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self._sizes_in[i], 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(*self._shape_out)

    def eval(self, arg):
        x = np.asarray(arg[0], dtype=float).ravel()
        return [ca.DM(np.asarray(self._value(x), dtype=float).reshape(self._shape_out))]

    def has_jacobian(self):
        return self._jacobian is not None

    def get_jacobian(self, name, inames, onames, opts):
        n, m = self._sizes_in[0], self._shape_out[0]
        # casadi keeps no reference of its own to the Jacobian's callback
        self._jacobian_function = Function(name, self._jacobian, [n, m], (m, n), opts=opts)
        return self._jacobian_function


def function(name: str, n: int, m: int, value, jacobian) -> Function:
    """``value(x) -> m values`` of ``x`` (n,) with ``jacobian(x) -> (m, n)`` as a casadi function."""
    return Function(name, value, [n], (m, 1), jacobian)


def options(max_iter: int, tol: float) -> dict:
    """Quiet IPOPT with a limited-memory Hessian (only first derivatives are given)."""
    return {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.hessian_approximation": "limited-memory",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": tol,
    }


def maximize_in_box(
    f: Function, starts: list, bound: float, max_iter: int = 25, tol: float = 1e-6
) -> tuple[np.ndarray | None, float]:
    """Maximise a scalar function over the box ``|x_i| <= bound`` with IPOPT, from each start.

    Returns the best point found over the starts and its value; the point is None
    (and the value -inf) when no start ends above -inf (no starts, or only NaN values).
    """
    x = ca.MX.sym("x", f.size1_in(0))
    solver = ca.nlpsol("maximum", "ipopt", {"x": x, "f": -f(x)}, options(max_iter, tol))
    best_x: np.ndarray | None = None
    best = -np.inf
    for x0 in starts:
        sol = solver(x0=x0, lbx=-bound, ubx=bound)
        value = -float(sol["f"])
        if value > best:
            best, best_x = value, np.asarray(sol["x"]).ravel()
    return best_x, best
