"""The flip graph: the 24 grid attitudes reachable by 90-degree flips about body axes.

Nodes are attitudes named by where body X, Y, Z point; an edge is a +-90 deg
flip about a body axis (``C_new = C_old R_axis(+-90)``). A sequence is a walk;
consecutive flips about the same axis in the same direction with no dwell
between them are one continuous turn, so a *move* here is ``q`` quarter
turns about one axis (``q = 1`` is a flip, ``q = 5`` a turn and a quarter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import networkx as nx
import numpy as np

from calib.errors import CalibError
from calib.nav.transform import AXES, attitude_from_directions, directions_of, rot_axis

Node = tuple[str, str, str]


@dataclass(frozen=True)
class Move:
    """``quarters`` quarter turns about body ``axis`` in direction ``sign`` (+1/-1)."""

    axis: str
    sign: int
    quarters: int

    @property
    def angle_deg(self) -> float:
        return 90.0 * self.sign * self.quarters

    def label(self) -> str:
        return f"{'+' if self.sign > 0 else '-'}{self.quarters * 90}{self.axis}"


def node_of(C: np.ndarray) -> Node:
    """The grid node (where X, Y, Z point) of a grid attitude."""
    return directions_of(np.round(C))


def as_node(start: Node) -> Node:
    """``start`` as a tuple (the hashable key the graph uses), also when a caller gives a list."""
    x, y, z = start
    return x, y, z


def attitude_of(node: Node) -> np.ndarray:
    """``C_b_n`` of a grid node."""
    return attitude_from_directions(*node)


def flip_graph(start: Node, axes: str = AXES) -> nx.MultiDiGraph:
    """All attitudes reachable from ``start`` by 90-degree flips about ``axes``.

    Each edge carries ``axis`` and ``sign``; from every node there is exactly
    one edge per (axis, sign).
    """
    g = nx.MultiDiGraph()
    todo = [as_node(start)]
    g.add_node(todo[0])
    while todo:
        node = todo.pop()
        C = attitude_of(node)
        for axis in axes:
            for sign in (1, -1):
                nxt = node_of(C @ rot_axis(AXES.index(axis), sign * math.pi / 2))
                if nxt not in g:
                    g.add_node(nxt)
                    todo.append(nxt)
                g.add_edge(node, nxt, axis=axis, sign=sign)
    return g


def apply_move(graph: nx.MultiDiGraph, node: Node, move: Move) -> Node:
    """Follow ``move.quarters`` edges labelled (axis, sign) from ``node``.

    Memoised in the graph's attribute dict: the search asks this once per candidate.
    """
    memo = graph.graph.setdefault("apply_move", {})
    key = (node, move)
    if key not in memo:
        end = node
        for _ in range(move.quarters):
            end = next(
                v
                for _, v, d in graph.out_edges(end, data=True)
                if d["axis"] == move.axis and d["sign"] == move.sign
            )
        memo[key] = end
    return memo[key]


def parse_node(text: str, where: str = "--start") -> Node:
    """A node from ``"east,up,south"``, refused with ``where`` if it is not a frame."""
    parts = [p.strip().lower() for p in str(text).replace(" ", ",").split(",") if p.strip()]
    if len(parts) != 3:
        raise CalibError(
            f"{text!r} is not three directions", where, 'write where X, Y, Z point, e.g. "east,up,south"'
        )
    x, y, z = parts
    attitude_from_directions(x, y, z, where=where)
    return x, y, z


def moves(axes: str = AXES, max_quarters: int = 1) -> list[Move]:
    """Every move about ``axes`` of up to ``max_quarters`` quarter turns, both signs."""
    return [Move(a, s, q) for a in axes for s in (1, -1) for q in range(1, max_quarters + 1)]
