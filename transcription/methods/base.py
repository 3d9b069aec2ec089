"""What every method shares: the Method protocol, the progress callback, and the Solution of a solve that could not
run.  A method is one solve and nothing else: a frozen object holding its options, with a ``name`` (its Solutions'
``method``), the ``kind`` of control it solves ('smooth' or 'impulsive'), and

    not_covered(problem) -> str               what of ``problem`` it does not cover ('' when it covers all of it)
    solve(problem, start, report) -> Solution one NLP or one Newton solve from ``start`` (a Start, or None)
    replace(**options) -> Method              the same method with some options changed (a strategy's budget)

Strategies (:mod:`transcription.strategy`) compose solves; the registry that picks a method for a problem is
:mod:`transcription.solve`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, fields, replace
from typing import Callable, Protocol

from ..dynamics.trajectory import trajectory
from ..ocp import Problem, terminal_error
from ..outcome import Iterate, Result
from ..results.solution import Solution
from ..results.start import Start
from ..results.trace import Attempt

Progress = Callable[[Iterate], None]


def phased(progress: Progress | None, phase: str) -> Progress | None:
    """``progress`` with each record's phase under ``phase`` ('phase / its own' for a nested solve's); None stays
    None."""
    if progress is None or not phase:
        return progress
    return lambda it: progress(replace(it, phase=f"{phase} / {it.phase}" if it.phase else phase))


def clocked(progress: Progress | None) -> Progress | None:
    """``progress`` with each record's ``elapsed_s`` the seconds since this call (the start of the top-level solve,
    :func:`transcription.solve.solve`), whatever solve inside it made the record; None stays None."""
    if progress is None:
        return None
    t0 = time.perf_counter()
    return lambda it: progress(replace(it, elapsed_s=time.perf_counter() - t0))


class Method(Protocol):
    """A method of the method layer (module docstring)."""

    name: str
    kind: str

    def not_covered(self, problem: Problem) -> str:
        """What of ``problem`` this method does not cover, in words ('' when it covers all of it)."""
        ...

    def solve(self, problem: Problem, start: Start | None = None, report: Progress | None = None,
              label: str = "") -> Solution:
        """One solve of ``problem`` from ``start``; failures are data (the Solution's ``result``); ``label`` names it
        in the Solution's trace."""
        ...

    def replace(self, **options) -> "Method":
        """This method with some of its options changed."""
        ...


@dataclass(frozen=True)
class OneFunction:
    """A method that is one function ``run(problem, options, report, start, label, **rest)`` and its fields
    (``options``, a dataclass, and the ``rest`` of the function's keyword arguments), named in its class line with
    ``covers(problem) -> str`` (what it does not cover): ``class Indirect(OneFunction, name="indirect",
    kind="smooth", run=solve_indirect, covers=not_covered)``.  ``replace`` changes some options (a strategy's IPOPT
    presets, ``ipopt``, do not apply to it)."""

    def __init_subclass__(cls, name: str, kind: str, run: Callable, covers: Callable[[Problem], str], **kwargs):
        super().__init_subclass__(**kwargs)
        cls.name, cls.kind, cls.run, cls.covers = name, kind, staticmethod(run), staticmethod(covers)

    def not_covered(self, problem: Problem) -> str:
        return self.covers(problem)

    def solve(self, problem: Problem, start: Start | None = None, report: Progress | None = None,
              label: str = "") -> Solution:
        rest = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "options"}
        return self.run(problem, self.options, report, start, label, **rest)

    def replace(self, ipopt=None, **options):
        return replace(self, options=self.options.replace(**options) if options else self.options)


def failed_solution(problem: Problem, method: str, solver: str, result: Result, message: str,
                    label: str = "") -> Solution:
    """The Solution of a solve that could not run (or does not apply): the free motion from X0 as its trajectory
    (never a solution), no controls, cost nan, no iterations (one attempt, named ``label``)."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.steps_of(problem.h), problem.N)
    return Solution(method=method, solver=solver, result=result, verdict=message, trajectory=trajectory(problem, X),
                    cost=float("nan"), terminal_error=terminal_error(X[-1], problem), problem=problem,
                    trace=(Attempt(label or solver, result),))
