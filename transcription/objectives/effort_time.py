"""A weighted sum of effort and time: min sum_j omega_j (1/2) u_j^T W u_j + rho T, the final time free in its bounds
(the effort objective's blocks and the time objective's block weighted by ``rho``; the effort objective's strategy).
How much a unit of time is worth in effort: rho -> 0 is the effort optimum over T in the bounds, a large rho drives
T to its lower bound.  At an interior optimum dJ_effort*/dT = -rho (tests/test_effort_time.py checks it against
fixed-T solves).  The indirect method does not cover it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..nlp import blocks
from ..nlp.structured import Block
from ..ocp import Problem, ProblemError
from .effort import Effort


@dataclass(frozen=True)
class EffortTime(Effort):
    """min effort + rho T (module docstring); ``balance`` as the effort objective's."""

    rho: float = 1.0
    indirect: ClassVar = None
    fatrop: ClassVar[str] = "fatrop is used for fixed-time effort problems"
    name: ClassVar[str] = "effort_time"
    free_time: ClassVar[bool] = True

    def __post_init__(self):
        if not (np.isfinite(self.rho) and self.rho >= 0):
            raise ProblemError("control.objective.rho", f"expected a non-negative number, got {self.rho!r}")

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return super().value(problem, U, h) + self.rho * problem.N * h

    def unit_weights(self, force: float, moment: float) -> None:
        """None: rho prices time against the given weights."""
        return None

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        sU, effort = super().scales(problem, sU)
        return sU, effort + self.rho * problem.T

    def blocks(self, tr) -> list:
        time = Block("time", blocks.time_cost(tr.problem.disc), np.array([tr.layout.ih]),
                     np.array([tr.h_scale, self.rho * tr.problem.N / tr.scales.objective]))
        return super().blocks(tr) + [(time, np.zeros(0))]
