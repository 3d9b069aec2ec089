"""What every method shares: the Method protocol and the Solution of a solve that could not run.

A method is an object with a ``name`` (what its Solutions report as ``method``), the ``kind`` of control it
solves ('smooth' or 'impulsive'), the type of its options, and

    not_covered(problem) -> str        what of ``problem`` it does not cover ('' when it covers all of it)
    solve(problem, options, *, warm, progress) -> Solution

(the shape of diffrax's solver classes and rockit's ``ocp.method(...)``).  The registry that picks one for a
problem is :mod:`transcription.solve`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

from ..problem import Problem, terminal_error
from ..results import Iterate, Result, Solution, trajectory
from ..warm import WarmStart

Progress = Callable[[Iterate], None]


class Method(Protocol):
    """A method of the method layer (module docstring)."""

    name: str
    kind: str
    options_type: type

    def not_covered(self, problem: Problem) -> str:
        """What of ``problem`` this method does not cover, in words ('' when it covers all of it)."""
        ...

    def solve(self, problem: Problem, options, *, warm: WarmStart | None = None,
              progress: Progress | None = None) -> Solution:
        """Solve ``problem``; failures are data (the Solution's ``result``)."""
        ...


@dataclass(frozen=True)
class Implementation:
    """A :class:`Method` made of two functions: ``solve_fn(problem, options, progress, warm) -> Solution`` and
    ``not_covered_fn(problem) -> str`` (how each method package defines its own)."""

    name: str
    kind: str
    options_type: type
    solve_fn: Callable[..., Solution]
    not_covered_fn: Callable[[Problem], str]

    def not_covered(self, problem: Problem) -> str:
        return self.not_covered_fn(problem)

    def solve(self, problem: Problem, options, *, warm: WarmStart | None = None,
              progress: Progress | None = None) -> Solution:
        return self.solve_fn(problem, options, progress, warm)


def failed_solution(problem: Problem, method: str, solver: str, result: Result, message: str,
                    build_s: float = 0.0) -> Solution:
    """The Solution of a solve that could not run (or does not apply): the free motion from X0 as its
    trajectory (something to show; never a solution), no controls, cost nan, the free motion's terminal
    error, no iterations."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.steps_of(problem.h), problem.N)
    return Solution(method=method, solver=solver, result=result, message=message, trajectory=trajectory(problem, X),
                    cost=float("nan"), terminal_error=terminal_error(X[-1], problem), iterations=0, build_s=build_s,
                    solve_s=0.0, problem=problem)
