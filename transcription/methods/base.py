"""What every method shares: the Method protocol and the Solution of a solve that could not run.

A method is an object with a ``name`` (what its Solutions report as ``method``), the ``kind`` of control it
solves ('smooth' or 'impulsive'), the type of its options, and

    not_covered(problem) -> str        what of ``problem`` it does not cover ('' when it covers all of it)
    solve(problem, options, *, warm, progress) -> Solution

(the shape of diffrax's solver classes and rockit's ``ocp.method(...)``).  The registry that picks one for a
problem is :mod:`transcription.solve`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable, Protocol

from ..ocp import Problem, terminal_error
from ..outcome import Iterate, Result
from ..results.solution import Solution
from ..dynamics.trajectory import trajectory
from ..results.start import WarmStart

Progress = Callable[[Iterate], None]


def phased(progress: Progress | None, phase: str) -> Progress | None:
    """``progress`` with each record's phase under ``phase``: ``phase`` for a record without one, 'phase / its own'
    for a nested solve's (e.g. 'coarse N=25 / effort / rollout').  None stays None: a solve nobody listens to
    pays nothing."""
    if progress is None:
        return None
    return lambda it: progress(replace(it, phase=f"{phase} / {it.phase}" if it.phase else phase))


def clocked(progress: Progress | None) -> Progress | None:
    """``progress`` with each record's ``elapsed_s`` the seconds since this call (the start of the top-level solve,
    :func:`transcription.solve.solve`), whatever solve inside it made the record; None stays None."""
    if progress is None:
        return None
    t0 = time.perf_counter()
    return lambda it: progress(replace(it, elapsed_s=time.perf_counter() - t0))


@dataclass(frozen=True)
class Reporting:
    """A solve of another problem inside a method's solve (e.g. the direct method's coarse grid, its relaxed or
    effort problem) that reports its iterations to ``progress``: called as ``(problem, options)``, the shape of
    :data:`~transcription.strategy.plan.SubSolve`, it calls ``solve(problem, options, progress)``;
    :func:`under` names its records' phase."""

    solve: Callable[..., Solution]
    progress: Progress

    def __call__(self, problem: Problem, options) -> Solution:
        return self.solve(problem, options, self.progress)


def under(subsolve: Callable, phase: str) -> Callable:
    """``subsolve`` with its solves' progress records under ``phase`` (:func:`phased`) if it reports them
    (:class:`Reporting`); any other callable as it is."""
    return replace(subsolve, progress=phased(subsolve.progress, phase)) if isinstance(subsolve, Reporting) else subsolve


def progress_of(subsolve: Callable) -> Progress | None:
    """The progress callback ``subsolve`` reports to (:class:`Reporting`), else None: for the NLPs a caller solves
    itself beside its subsolves (the fuel homotopy's levels)."""
    return subsolve.progress if isinstance(subsolve, Reporting) else None


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
