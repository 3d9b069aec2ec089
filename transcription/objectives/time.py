"""The time objective (docs/mathematics.md §10, §18): min T, the final time free in its bounds and every control
bounded -- its cost block of the direct method's NLP (N h), its scales, and its default strategy
(:class:`TimeStrategy`: symmetry-breaking starts, a multistart on a coarser grid).  In the indirect method its
conditions are the bang-bang law and the time condition (:mod:`transcription.methods.indirect.objectives`)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import ClassVar

import numpy as np

from ..geometry.state import U_FORCE, U_MOMENT
from ..nlp import blocks
from ..nlp.structured import Block
from ..methods.indirect.laws import TimeLaw
from ..ocp import Objective, Problem, ProblemError
from ..strategy.core import BestOf, CoarseToFine, Composed, FirstOf, Solve, chosen
from ..strategy.starts import perturbed


@dataclass(frozen=True)
class Time(Objective):
    """min T = N h (module docstring): a free final time (the problem's time_bounds) and a bound on every control
    (a norm bound of 0 removes one)."""

    indirect: ClassVar = TimeLaw()
    name: ClassVar[str] = "time"
    free_time: ClassVar[bool] = True

    def check(self, control) -> None:
        if control.force_bound is None or control.moment_bound is None:
            raise ProblemError("control.bounds", "the time objective needs a bound on every control (force and moment; "
                                                 "a norm bound of 0 removes one)")

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return float(problem.N * h)

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        return sU, problem.T

    def blocks(self, tr) -> list:
        fn = blocks.time_cost(tr.problem.disc)
        return [(Block("time", fn, np.array([tr.layout.ih]), np.array([tr.h_scale, tr.problem.N / tr.scales.objective])),
                 np.zeros(0))]

    def strategy(self, problem: Problem, options) -> "TimeStrategy":
        return TimeStrategy()


def bracketing_times(problem: Problem) -> list[float]:
    """The final times of the starts that bracket the guess T on the coarsest grid: the geometric means of T and
    each of the time bounds (those not equal to T).  Why: a time-optimal maneuver's local minima differ in
    their time, and the starts at the guess alone may all fall into the one nearest to it."""
    lo, hi = problem.time_bounds
    T = problem.T
    return [float(np.sqrt(T * b)) for b in (lo, hi) if not np.isclose(b, T, rtol=1e-9, atol=0.0)]


def start_sizes(problem: Problem) -> np.ndarray:
    """(6,) the size of each control component's random start (:func:`~transcription.strategy.starts.perturbed`):
    its box bound, an engine's max (its random force is projected onto its axis), or a norm bound / sqrt(3)."""
    size = np.zeros(6)
    for sl, bound in ((U_FORCE, problem.control.force_bound), (U_MOMENT, problem.control.moment_bound)):
        size[sl] = bound.sizes() / (np.sqrt(3.0) if np.isfinite(bound.radius) else 1.0)
    return size


@dataclass(frozen=True)
class TimeStrategy(Composed):
    """The time objective's default: ``starts`` symmetry-breaking starts (the screw interpolation with seeded random
    controls, :func:`~transcription.strategy.starts.perturbed`), the fastest converged maneuver kept (time-optimal
    slews have several local minima: the asymmetric slew of configs/slew_time_optimal.yaml 28.63 s and 29.41 s, the
    first-order scheme at N = 100 reaching the latter from seed 0); on a grid finer than
    max(coarse_min, N // coarse_factor) steps they are solved there first (recursively: that solve does the same),
    the best resampled and finished here, the starts on this grid being the fallback -- each start costs a quarter (or
    less) of a fine one and the finish takes few iterations; on the coarsest grid, also starts over the times that
    bracket the guess (:func:`bracketing_times`)."""

    starts: int = 3
    coarse_factor: int = 4
    coarse_min: int = 25

    def compose(self, problem: Problem, options, start=None):
        if start is not None:
            return Solve(label="warm start")
        if (one := chosen(problem, options)) is not None:
            return one
        size = start_sizes(problem)
        fine = tuple(Solve(partial(perturbed, size=size, seed=k), f"interpolate with symmetry-breaking controls (seed {k})")
                     for k in range(self.starts))
        coarse = CoarseToFine(self, Solve(label="from coarse"), self.coarse_factor, self.coarse_min)
        if coarse.grid(problem) < problem.N:
            return FirstOf((coarse, BestOf(fine)))
        bracket = tuple(Solve(partial(perturbed, size=size, seed=0, T=Ts),
                              f"interpolate over T = {Ts:.6g} with symmetry-breaking controls (seed 0)")
                        for Ts in bracketing_times(problem))
        return BestOf(fine + bracket)


__all__ = ["Time", "TimeStrategy", "bracketing_times", "start_sizes"]
