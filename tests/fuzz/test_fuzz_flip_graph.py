"""Fuzzing of the flip graph's reader of attitudes typed by users (``parse_node``, "east,up,south").

The budget and the tally: ``fuzzing.py``.
"""

from __future__ import annotations

import numpy as np
from fuzz_fixtures import report_tally  # noqa: F401 (the tally's report)
from fuzzing import _current_kind, budget, event
from hypothesis import given, strategies as st

from calib.errors import CalibError
from calib.nav.transform import DIRECTIONS
from seqdesign.search.graph import attitude_of, flip_graph, parse_node

NODE_TEXT = st.one_of(
    st.text(max_size=30),
    st.lists(
        st.sampled_from(
            list(DIRECTIONS)
            + ["EAST", " Up", "sky", "", "north-east", "0", "90", "45", "east,", "ÉAST", "eaſt"]
        ),
        max_size=5,
    ).map(lambda parts: data_join(parts)),
    st.lists(st.sampled_from(list(DIRECTIONS)), min_size=3, max_size=3).map(",".join),
)


def data_join(parts: list[str]) -> str:
    return ",".join(parts) if len(parts) % 2 else " ".join(parts)


GRID = set(flip_graph(("east", "up", "south")).nodes)


@budget(500)
@given(text=NODE_TEXT)
def test_parse_node(text):
    _current_kind[0] = "graph node"
    try:
        node = parse_node(text, "--start")
    except CalibError as exc:
        assert "--start" in str(exc)
        event("refused")
        return
    event("valid result")
    assert node in GRID  # one of the 24 grid attitudes, reachable by 90-degree flips
    C = attitude_of(node)
    np.testing.assert_allclose(C @ C.T, np.eye(3))
    assert len(flip_graph(node).nodes) == 24
