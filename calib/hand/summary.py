"""What a fit of a run placed by hand used: its rests and moves, and the worst of them.

A small record the result carries (``calibrate --json`` under ``by_hand``, and
the lines ``calibrate`` prints), so that a user sees which stretches of the
log made the numbers and, when the residuals exceed the profile's noise,
where.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

WORST_SHOWN = 3
CHI2_NAMED = 2.0  # chi2/dof above this: the worst rests and moves are named


@dataclass(frozen=True)
class HandSummary:
    """Rests and moves of a hand-placed run, times in s from the log's start stamp.

    Attributes
    ----------
    rest_s : ndarray, shape (K, 2)
        Start and end of each rest used.
    move_s : ndarray, shape (K - 1, 2)
        Start and end of each move between them.
    move_used : ndarray of bool, shape (K - 1,)
        False for a move left out (clipped samples).
    rest_chi2, move_chi2 : ndarray
        Whitened residual power of each rest (6 scalars) and move (3; nan when unused).
    clipped : tuple of str
        The clipped stretches, described.
    lost : dict
        Samples lost amid each move left out for them, by move index (read with gaps
        allowed: put in as a guess, never fitted).
    chi2_per_dof : float
    notes : tuple of str
        The model chosen and the weights earned (:mod:`calib.hand.weights`), as printed.
    choices : dict
        The same for ``--json``: ``model`` and ``weights``.
    """

    rest_s: np.ndarray
    move_s: np.ndarray
    move_used: np.ndarray
    rest_chi2: np.ndarray
    move_chi2: np.ndarray
    clipped: tuple = ()
    lost: dict = field(default_factory=dict)
    chi2_per_dof: float = float("nan")
    notes: tuple = ()  # the model chosen and the weights earned, one line each
    choices: dict = field(default_factory=dict)  # the same for --json

    def worst(self) -> tuple[list[int], list[int]]:
        """Indices of the rests and used moves with the largest residual power, largest first."""
        rests = list(np.argsort(-self.rest_chi2)[:WORST_SHOWN])
        used = np.flatnonzero(self.move_used)
        moves = list(used[np.argsort(-self.move_chi2[used])][:WORST_SHOWN])
        return [int(r) for r in rests], [int(m) for m in moves]

    def lines(self) -> list[str]:
        """What ``calibrate --by-hand`` prints under the table."""
        lengths = self.rest_s[:, 1] - self.rest_s[:, 0]
        out = [
            f"rests used: {len(lengths)} (each {lengths.min():.1f}-{lengths.max():.1f} s long, "
            f"{lengths.sum():.0f} s in all); moves used: {int(self.move_used.sum())} of {len(self.move_used)}"
        ]
        for k in np.flatnonzero(~self.move_used):
            why = (
                f"{self.lost[int(k)]} sample(s) lost amid its turn (put in as a guess by --allow-gaps)"
                if int(k) in self.lost
                else "clipped"
            )
            out.append(f"move {k + 1} ({self.move_s[k, 0]:.2f}-{self.move_s[k, 1]:.2f} s) left out: {why}")
        out += list(self.notes)
        out += list(self.clipped)
        if self.chi2_per_dof > CHI2_NAMED:
            rests, moves = self.worst()
            out.append(
                "largest residuals: "
                + "; ".join(
                    f"rest {r + 1} ({self.rest_s[r, 0]:.2f}-{self.rest_s[r, 1]:.2f} s, chi2 "
                    f"{self.rest_chi2[r]:.1f} over 6)"
                    for r in rests
                )
                + "; "
                + "; ".join(
                    f"move {m + 1} ({self.move_s[m, 0]:.2f}-{self.move_s[m, 1]:.2f} s, chi2 "
                    f"{self.move_chi2[m]:.1f} over 3)"
                    for m in moves
                )
            )
        return out

    def to_json(self) -> dict:
        rests, moves = self.worst()
        return {
            "rests": [
                {"start_s": float(a), "end_s": float(b), "chi2": float(c)}
                for (a, b), c in zip(self.rest_s, self.rest_chi2, strict=True)
            ],
            "moves": [
                {"start_s": float(a), "end_s": float(b), "used": bool(u), "chi2": float(c) if u else None}
                | ({"lost_samples": self.lost[k]} if k in self.lost else {})
                for k, ((a, b), u, c) in enumerate(
                    zip(self.move_s, self.move_used, self.move_chi2, strict=True)
                )
            ],
            "clipped": list(self.clipped),
            **self.choices,
            "worst_rests": [r + 1 for r in rests],
            "worst_moves": [m + 1 for m in moves],
        }
