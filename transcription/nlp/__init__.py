"""The structured NLPs of the project: the one builder (:mod:`.structured`: blocks mapped over the horizon, exact
derivatives assembled block by block), the block Functions (:mod:`.blocks`), the orders of the decision vector
(:mod:`.layouts`) and the solvers' set-up (:mod:`.solvers`: IPOPT, the progress callback, histories)."""
from __future__ import annotations

from .layouts import NLPLayout, StageLayout, control_nodes
from .solvers import ipopt_history, ipopt_options, make_ipopt, solve_time_split
from .structured import Block, StructuredNLP, assemble

__all__ = ["Block", "NLPLayout", "StageLayout", "StructuredNLP", "assemble", "control_nodes", "ipopt_history",
           "ipopt_options", "make_ipopt", "solve_time_split"]
