"""The design search: flip walks on the 24-attitude graph, scored, re-scored exactly, refined.

Modules, lowest first: :mod:`.graph` (the flip graph), :mod:`.gm` (exact noise
whitening per candidate), :mod:`.gimbal` (what a real gimbal allows),
:mod:`.constraints`, :mod:`.segments` (segment matrices), :mod:`.objective`,
:mod:`.beam` (the beam search), :mod:`.refine` (IPOPT dwells), :mod:`.parallel`
(the one parallel map), :mod:`.pipeline` (exact re-scoring of the candidates),
:mod:`.design` (one budget) and :mod:`.report` (several budgets, Pareto front).
"""

from .beam import SearchModel, beam_search, brute_force
from .constraints import Constraints, DesignOptions, check_constraints, to_sequence
from .design import DesignResult, design
from .gimbal import gimbal_constraints
from .graph import Move, flip_graph, parse_node
from .parallel import map_jobs
from .pipeline import Progress
from .report import DesignReport, design_budgets, design_rate_dps

__all__ = [
    "Constraints",
    "DesignOptions",
    "DesignReport",
    "DesignResult",
    "Move",
    "Progress",
    "SearchModel",
    "beam_search",
    "brute_force",
    "check_constraints",
    "design",
    "design_budgets",
    "design_rate_dps",
    "flip_graph",
    "map_jobs",
    "parse_node",
    "gimbal_constraints",
    "to_sequence",
]
