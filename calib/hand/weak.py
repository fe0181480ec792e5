"""The directions a hand fit leaves weak, in a user's words: parameters, or rests turning together.

The hand fit's unknowns are the 21 (and the g-sensitivity), the horizontal Earth
rate and every rest's attitude. A weak direction of its information matrix
(:func:`calib.model.information.scaled_inverse`) is one of two kinds:

* one the **parameters** take part in: the poses do not separate them. It is
  written over the parameters' names alone, as the gimbal fit writes its own
  (``+1.00*sgy -0.02*baz``), and a parameter on it is not estimable;
* one that only the **rests' attitudes** span: a block of rests that no move
  which fits ties to the others (a move weighted out by its own residuals, a
  splice of two recordings) turns freely as a whole about the vertical, where
  gravity cannot see it. It costs the parameters nothing; the user is told which
  rests, in the rests' own numbers, never the fit's state names.
"""

from __future__ import annotations

import numpy as np

from calib.model.information import ESTIMABLE_TOL, ScaledInverse, describe_null, row_echelon

AXIS_WORDS = ("east", "north", "the vertical")
ONE_AXIS = 0.9  # of a block's turn on one axis: named as that axis, else "together"
IN_BLOCK = 0.01  # of the largest rest's share: below it a rest is not part of the block


def split_weak(inv: ScaledInverse, n_parameters: int, rest_columns: list[np.ndarray]) -> tuple[list, list]:
    """The weak directions as parameter combinations and as loose blocks of rests.

    Parameters
    ----------
    inv : ScaledInverse
        The fit's information, inverted, with its weak subspace (``null_basis``) and names.
    n_parameters : int
        How many leading unknowns are the calibration's parameters (the 21 and the g-sensitivity).
    rest_columns : list of ndarray of int
        Rest ``r``'s attitude columns (2 for the first rest, its tilts; 3 for the others).

    Returns
    -------
    parameters : list of str
        Combinations of the parameters that the run does not observe.
    rests : list of str
        One sentence per block of rests that turns freely as a whole.
    """
    null = inv.null_basis
    if null.shape[1] == 0:
        return [], []
    u, size, vt = np.linalg.svd(null[:n_parameters], full_matrices=True)
    size = np.concatenate([size, np.zeros(null.shape[1] - len(size))])
    involved = size > ESTIMABLE_TOL
    parameters = describe_null(u[:, : int(involved.sum())], inv.names[:n_parameters])
    loose = null @ vt[~involved].T  # the weak directions with no part in the parameters
    blocks = [_block(row, rest_columns) for row in row_echelon(loose.T)] if loose.shape[1] else []
    return parameters, [sentence for _, sentence in sorted(blocks)]


def _block(direction: np.ndarray, rest_columns: list[np.ndarray]) -> tuple[int, str]:
    """Which rests turn together along ``direction``, about which axis: (the first's number, a sentence)."""
    turn = np.zeros((len(rest_columns), 3))
    for r, cols in enumerate(rest_columns):
        turn[r, : len(cols)] = direction[cols]
    share = np.linalg.norm(turn, axis=1)
    members = np.flatnonzero(share > IN_BLOCK * share.max())
    axis = np.sum(turn[members] ** 2, axis=0)
    one_axis = axis.max() >= ONE_AXIS * axis.sum()
    about = AXIS_WORDS[int(np.argmax(axis))] if one_axis else "an axis of their own"
    if len(members) == 1:  # a pose whose moves on both sides were left out
        about = about.replace("their own", "its own")
        return int(members[0]) + 1, (
            f"rest {members[0] + 1} turns alone about {about}: no move that fits ties it to the "
            "others, so its heading is free (the 21 parameters do not depend on it)"
        )
    return int(members[0]) + 1, (
        f"rests {_ranges(members + 1)} turn together about {about}: no move that fits ties them to the "
        "others, so their common heading is free (the 21 parameters do not depend on it)"
    )


def _ranges(numbers: np.ndarray) -> str:
    """``1, 3-7, 9``: sorted integers written as runs."""
    out, start = [], None
    for i, n in enumerate(numbers):
        if start is None:
            start = n
        if i + 1 == len(numbers) or numbers[i + 1] != n + 1:
            out.append(f"{start}" if start == n else f"{start}-{n}")
            start = None
    return ", ".join(out)
