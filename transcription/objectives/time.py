"""The time objective (docs/mathematics.md §10, §18): min T, the final time free in its bounds and every control
bounded -- its cost block of the direct method's NLP (N h), its scales, and its default strategy
(:class:`TimeStrategy`: symmetry-breaking starts, a multistart on a coarser grid).  In the indirect method its
conditions are the bang-bang law and the time condition (:mod:`transcription.methods.indirect.objectives`)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import partial
from typing import ClassVar

import numpy as np

from ..geometry.state import U_FORCE, U_MOMENT
from ..nlp import blocks
from ..nlp.structured import Block
from ..methods.indirect.laws import TimeLaw
from ..ocp import Objective, Problem, ProblemError
from ..ocp.estimate import time_estimate
from ..results.start import Start
from ..strategy.core import BestOf, CoarseToFine, Composed, FirstOf, Solve, Warm, chosen
from ..strategy.starts import class_name, cone_classes, detour, perturbed


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


def estimate_times(problem: Problem, factors: tuple[float, ...]) -> list[float]:
    """The final times of the starts across the problem's own estimate of its minimum time T_e
    (:func:`~transcription.ocp.estimate.time_estimate`: the Hohmann delta-v at full thrust, the eigenaxis bang-bang
    slew): T_e times each of ``factors``, clipped to the time bounds, those within 5 % of the guess or of each other
    counted once; [] without an estimate.  Why: the guess alone may lie nearer a worse local minimum (a raise from
    T = 0.4 at N = 100 wandered 10 min; docs/mathematics.md §10)."""
    est = time_estimate(problem)
    if est is None:
        return []
    lo, hi = problem.time_bounds
    out: list[float] = []
    for f in factors:
        T = float(np.clip(est * f, lo, hi))
        if all(abs(T - o) > 0.05 * o for o in out + [problem.T]):
            out.append(T)
    return out


def routed(problem: Problem, size: np.ndarray, seed: int, T: float | None, sides: tuple, clearance_deg: float) -> Start:
    """The symmetry-breaking start (:func:`~transcription.strategy.starts.perturbed`) over T, its attitude routed
    round the cones on ``sides`` (:func:`~transcription.strategy.starts.detour`; () the straight path)."""
    base = detour(problem, dict(sides), np.radians(clearance_deg), T) if sides else None
    return perturbed(problem, size, seed, T, base)


@dataclass(frozen=True)
class TimeStrategy(Composed):
    """The time objective's default: ``starts`` symmetry-breaking starts (the screw interpolation with seeded random
    controls, :func:`~transcription.strategy.starts.perturbed`), the fastest converged maneuver kept (time-optimal
    slews have several local minima: the asymmetric slew of configs/slew_time_optimal.yaml 28.63 s and 29.41 s, the
    first-order scheme at N = 100 reaching the latter from seed 0); on a grid finer than
    max(coarse_min, N // coarse_factor) steps they are solved there first (recursively: that solve does the same),
    the best resampled and finished here, the starts on this grid being the fallback -- each start costs a quarter (or
    less) of a fine one and the finish takes few iterations; on the coarsest grid, also starts over the times that
    bracket the guess (:func:`bracketing_times`) and across the problem's own estimate of its minimum time
    (:func:`estimate_times`, ``estimate_factors``), each within ``start_budget`` iterations (a start over
    T = 0.364 of configs/orbit_raise_time.yaml on 50 steps wandered 1528 iterations, 133 s, and failed).  The grids
    halve (``coarse_factor`` 2): that raise at N = 100 finished from 25 steps wandered off (T ~ 1.1, not ended in 10
    min); by halves it takes 2.4 s.  A finish that ends more than ``finish_jump_rtol`` above its coarse optimum jumped to
    another local minimum: the (budgeted) starts on its grid are tried in turn until one converges, the lower kept
    (:class:`CoarseToFine`'s ``fallback``; a 50 deg plane change: 0.5209 on 25 steps, finished at 0.7391 on 100, where
    0.5212 exists).  In turn, not all of them: a fallback, not a multistart on the fine grid (there, seed 1 of that plane
    change took 144 iterations and 80 s, IPOPT's inertia correction at regularizations up to 1e7).

    With keep-out or keep-in cones in the way of the straight path (within ``cone_reach_deg``), one such strategy
    per homotopy class of the path round them (:func:`cone_classes`, at most ``max_classes``): its starts routed
    through a waypoint ``cone_clearance_deg`` outside each cone on the side the class says (``sides``), each class
    finished on this grid, the fastest kept, the classes named in the message and in ``stats['homotopy_classes']``.
    Why finished apart: a coarse path may cut a cone between its nodes and its finish jump to another class (the
    120 deg slew past a 40 deg cone: 28.7 on 25 steps, 39.23 on 200, where 28.89 exists)."""

    starts: int = 3
    coarse_factor: int = 2
    coarse_min: int = 25
    estimate_factors: tuple[float, ...] = (1.0, 2.0, 4.0)
    start_budget: int | None = 400
    cone_reach_deg: float = 10.0
    cone_clearance_deg: float = 5.0
    max_classes: int = 4
    finish_jump_rtol: float = 0.02
    sides: tuple = ()

    def compose(self, problem: Problem, options, start=None):
        if start is not None:
            return Warm()
        if (one := chosen(problem, options)) is not None:
            return one
        if not self.sides and (classes := cone_classes(problem, self.cone_reach_deg, self.max_classes)):
            return BestOf(tuple(replace(self, sides=c) for c in classes), names=tuple(class_name(problem, c)
                                                                                      for c in classes),
                          stat="homotopy_classes")
        size = start_sizes(problem)
        route = partial(routed, size=size, sides=self.sides, clearance_deg=self.cone_clearance_deg)
        where = f" round {class_name(problem, self.sides)}" if self.sides else ""
        fine = tuple(Solve(partial(route, seed=k, T=None), f"interpolate{where} with symmetry-breaking controls "
                                                           f"(seed {k})") for k in range(self.starts))
        budgeted = tuple(replace(f, budget=self.start_budget) for f in fine)
        coarse = CoarseToFine(self, Solve(label="from coarse"), self.coarse_factor, self.coarse_min,
                              None if self.sides else FirstOf(budgeted), self.finish_jump_rtol)
        if coarse.grid(problem) < problem.N and self.sides:     # a coarse path may cut the cone: one start here too
            return FirstOf((BestOf((coarse, replace(fine[0], budget=self.start_budget))), BestOf(fine[1:])))
        if coarse.grid(problem) < problem.N:
            return FirstOf((coarse, BestOf(fine)))
        times = bracketing_times(problem) + estimate_times(problem, self.estimate_factors)
        bracket = tuple(Solve(partial(route, seed=0, T=Ts), f"interpolate{where} over T = {Ts:.6g} with "
                              "symmetry-breaking controls (seed 0)", self.start_budget) for Ts in times)
        return BestOf(budgeted + bracket)


__all__ = ["Time", "TimeStrategy", "bracketing_times", "class_name", "cone_classes", "estimate_times", "routed",
           "start_sizes"]
