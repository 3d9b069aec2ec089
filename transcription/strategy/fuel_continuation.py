"""The fuel objective reached by continuation in its data (docs/mathematics.md §25): the start of a fuel problem whose
homotopy (:mod:`.homotopy`) cannot begin with its first level.

:func:`~.homotopy.effort_problem` makes the homotopy's effort problem its first level, phi_1(s) = s^2 / (2 r), when
every part whose fuel counts is bounded and the parts' references r differ by more than EFFORT_LEVEL_RATIO
(configs/leo_engine_fuel.yaml).  With an unbounded counted part it cannot: r is then the effort optimum's largest
magnitude, known only after the effort solve, and the fuel weights, chosen for the squared effort, price the parts'
magnitudes in another ratio than the effort's.  configs/leo_body_engine.yaml with the fuel objective (the moment
unbounded, w_m = 1e10 against w_f = 1; references 1e-3 kN and 8.3e-9 kN km) did not converge by the homotopy in
8 min (docs §21), nor with its moment bounded at 1e-8 and w_m = 1e10 (the smoothed levels crawled).

:func:`continuation_guess` reaches it through problems it can solve, each on the problem's own grid from the last
one's optimum:

0. the start: every unbounded counted part bounded at its reference (BOUND_MARGIN x its effort optimum's largest
   magnitude, rounded up to one significant digit, so that the effort optimum is feasible), and the fuel weights
   w_i' = w_i r_i / max_j r_j, so that the first level's weights w_i' / r_i are the file's effort weights (scaled):
   its effort problem is the file's (with a bound its optimum satisfies), and the homotopy starts it with its first
   level.  The direct method's own plan solves it (subsolve: its effort problem, homotopy and structured finish).
   On leo_body_engine the start is configs/leo_engine_fuel.yaml's problem to the last bit (1.2 x 8.3e-9 -> 1e-8,
   w_m = 1e10 x 1e-8 / 1e-3 = 1e5).  That path is at the edge of converging: with w_m one unit in the last place
   higher (1e5 (1 + 2.2e-16)), or the bound 9.96e-9 unrounded, its level eps = 0.1 at its budget left a point from
   which the structured finish's rough solve reached its 500 iterations, and the epigraph fallback from it its 500
   too (docs §25).  Handing the file's effort optimum over instead of the plan's own effort solve took another path,
   which failed the same way;
1. the weights raised geometrically, by about WEIGHT_FACTOR a step, to the file's;
2. the added bounds raised by BOUND_FACTOR a step while any is active at the optimum (a bound the optimum does not
   touch leaves it a KKT point of the problem without it), at most BOUND_STEPS times;
3. the problem itself, from that optimum, by the plan's attempt: the structured finish and the fuel KKT guard
   (Guess.prepared_on PREPARED_ON, finished as a coarser grid's optimum is).

Steps 1 and 2 are each a structured finish from the last optimum (as from a coarser grid's); a step need not pass
the guard (only the last solve is the answer), but it must converge.  leo_body_engine, fuel, N = 400 (docs §25):
the start is configs/leo_engine_fuel.yaml; w_m 1e5 -> 1e10 in five steps of 34-79 s each,
the bound 1e-8 -> 1e-7 -> 1e-6 (inactive at 1.09e-7), the problem itself in 232 iterations to 30201.72849, guard
passed.  A step of 100 in the weights did not converge (its rough solve reached 500 iterations).
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from .starts import Guess, warm_guess
from ..geometry.state import U_FORCE, U_MOMENT
from ..options import DirectOptions
from ..ocp import AT_BOUND_RTOL, NormBound, Problem
from ..methods.base import phased, progress_of, under
from .fuel_structure import structured_finish
from .homotopy import (EFFORT_LEVEL_RATIO, counted_parts, effort_optimum, effort_problem, homotopy_guess, smoothing_reference)

#: an unbounded counted part's added bound: this times its largest magnitude in the effort optimum, rounded up to one
#: significant digit (:func:`significant`; the effort optimum then satisfies it and the first level's effort problem
#: is the file's)
BOUND_MARGIN = 1.2
#: the weights' steps: about this factor each (w_m 1e5 -> 1e7 in one step of leo_body_engine: the rough solve at
#: its 500 iterations; by 10: 42-79 s a step)
WEIGHT_FACTOR = 10.0
#: a step's structured finish takes at most this many rounds (its guard widening the structure and pruning it
#: again; the problem's own finish: fuel_structure.ROUNDS, 4).  leo_body_engine's bound 1e-7 passed the guard in 8; with
#: 4 it stopped at a worse point (30226.27 against 30218.56, the guard failed); on that path the problem itself did not
#: pass the guard in its own 4 rounds (its epigraph fallback then wandered)
STEP_ROUNDS = 12
#: the added bounds' steps: this factor each, at most BOUND_STEPS of them
BOUND_FACTOR = 10.0
BOUND_STEPS = 6
#: Guess.prepared_on of the continuation's optimum (the plan finishes the problem from it on its switching
#: structure, as from a coarser grid's)
PREPARED_ON = "the fuel continuation"


def counted_unbounded(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts (force, moment) whose fuel counts (:func:`~.homotopy.counted_parts`) and that have no
    bound."""
    c = problem.control
    return counted_parts(problem) & np.array([c.force_bound is None, c.moment_bound is None])


def significant(x: np.ndarray) -> np.ndarray:
    """x > 0 rounded up to one significant digit (9.96e-9 -> 1e-8, 1.01e-8 -> 2e-8)."""
    e = 10.0 ** np.floor(np.log10(x))
    return np.ceil(x / e * (1 - 1e-12)) * e


def start_problem(problem: Problem, U: np.ndarray) -> Problem | None:
    """Step 0 of the module docstring from the effort optimum's controls U (6, n): ``problem`` with every unbounded
    counted part bounded at r = BOUND_MARGIN x its largest magnitude in U rounded up to one significant digit
    (:func:`significant`) and the fuel weights w_i r_i / max_j r_j (r
    the references of :func:`~.homotopy.smoothing_reference` then: the bounds); None when the homotopy starts
    ``problem`` itself: no unbounded counted part, or references within EFFORT_LEVEL_RATIO of each other (there
    the file's weights are the first level's, as for the bounded fuel raise)."""
    free = counted_unbounded(problem)
    if not free.any():
        return None
    r = smoothing_reference(problem, U).astype(float)
    r[free] = significant(BOUND_MARGIN * r[free])
    if max(r[0] / r[1], r[1] / r[0]) <= EFFORT_LEVEL_RATIO:
        return None
    c = problem.control
    bounds = [NormBound(r[i]) if free[i] else b for i, b in enumerate((c.force_bound, c.moment_bound))]
    # (w_i r_i) / max r, not w_i (r_i / max r): leo_body_engine's 1e10 x 1e-8 / 1e-3 is 1e5 to the bit so, and its start
    # problem the bundled leo_engine_fuel's (module docstring: one unit in the last place changed the path)
    W_f, W_m = c.W_f * r[0] / r.max(), c.W_m * r[1] / r.max()
    return problem.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1], W_f=W_f, W_m=W_m))


def weight_steps(start: Problem, problem: Problem) -> list[Problem]:
    """Step 1: ``start`` with its weights raised geometrically to ``problem``'s in n steps of about WEIGHT_FACTOR
    (n = the largest ratio's rounded number of factors, at least 1 where a weight differs), its bounds kept."""
    c0, c1 = start.control, problem.control
    w0 = np.array([c0.W_f[0, 0], c0.W_m[0, 0]])
    w1 = np.array([c1.W_f[0, 0], c1.W_m[0, 0]])
    ratio = np.where(w0 > 0, w1 / np.where(w0 > 0, w0, 1.0), 1.0)
    n = int(max(np.round(np.log(ratio.max()) / np.log(WEIGHT_FACTOR)), 1)) if ratio.max() > 1.0 else 0
    out = []
    for k in range(1, n + 1):
        w = w0 * ratio ** (k / n) if k < n else w1
        out.append(start.replace(control=replace(c0, W_f=np.eye(3) * w[0], W_m=np.eye(3) * w[1])))
    return out


def raised_bounds(step: Problem, problem: Problem, U: np.ndarray) -> Problem | None:
    """Step 2: ``step`` with its added bounds (the parts ``problem`` leaves unbounded) that the controls U (6, n)
    touch (within AT_BOUND_RTOL) raised by BOUND_FACTOR; None when none is touched."""
    free = counted_unbounded(problem)
    c = step.control
    bounds = [c.force_bound, c.moment_bound]
    raised = False
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        if free[i] and np.linalg.norm(U[sl], axis=0).max() >= bounds[i].b * (1.0 - AT_BOUND_RTOL):
            bounds[i], raised = NormBound(bounds[i].b * BOUND_FACTOR), True
    return step.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1])) if raised else None


def _finished(problem: Problem, options: DirectOptions, guess: Guess, progress, phase: str):
    """``problem`` solved from ``guess`` on its switching structure (a coarser grid's optimum would be: dilated,
    rough, pruned); (its WarmStart, iterations, a line) or (None, iterations, a line) if it did not converge."""
    sol, _ = structured_finish(problem, options, guess, phased(progress, phase), rounds=STEP_ROUNDS)
    return (sol.warm if sol.converged and sol.warm is not None else None), sol.iterations, _line(phase, sol)


def _line(what: str, sol) -> str:
    """A step's line of ``stats['fuel_continuation']``: what was solved, how it ended, its iterations and cost."""
    return f"{what}: {sol.result.value} in {sol.iterations} iterations" + (
        f", cost {sol.cost:.10g}" if sol.converged else "")


def _weights(problem: Problem) -> str:
    c = problem.control
    return f"w_f {c.W_f[0, 0]:.3g}, w_m {c.W_m[0, 0]:.3g}"


def _bounds(problem: Problem, free: np.ndarray) -> str:
    c = problem.control
    parts = (("f", c.force_bound, free[0]), ("m", c.moment_bound, free[1]))
    return ", ".join(f"|u_{n}| <= {b.b:.3g}" for n, b, f in parts if f)


def fuel_start(problem: Problem, options: DirectOptions, subsolve, relaxation) -> Guess | None:
    """The start of a fuel problem's solve on its own grid: the homotopy's point (:func:`~.homotopy.homotopy_guess`)
    or, where the homotopy cannot begin with its first level (:func:`start_problem`), the continuation's optimum
    (:func:`continuation_guess`); the effort optimum is solved once for either.  None if a step did not converge."""
    t0 = time.perf_counter()
    effort = effort_optimum(effort_problem(problem), options, subsolve, relaxation)
    if effort[0] is None:
        return None
    start = start_problem(problem, effort[0].warm.U)
    guess = homotopy_guess(problem, options, subsolve, relaxation, effort) if start is None else \
        continuation_guess(problem, start, options, subsolve, effort[0].iterations)
    return None if guess is None else replace(guess, seconds=time.perf_counter() - t0)


def continuation_guess(problem: Problem, start: Problem, options: DirectOptions, subsolve,
                       iterations: int = 0) -> Guess | None:
    """Steps 0-2 of the module docstring from ``start`` (:func:`start_problem`; solved by ``subsolve``, the direct
    method with its own plan): the last optimum as the Guess the plan finishes ``problem`` from (prepared_on
    PREPARED_ON), its iterations ``iterations`` (those spent before, the file's effort problem) and those of every
    solve made, ``stats['fuel_continuation']`` one line per step; None if a step did not converge."""
    progress, free = progress_of(subsolve), counted_unbounded(problem)
    first = under(subsolve, "continuation start")(start, options)
    iterations += first.iterations
    lines = [_line(f"start: {_weights(start)}, {_bounds(start, free)}", first)]
    warm = first.warm if first.converged else None
    step = start
    for step in weight_steps(start, problem):
        if warm is None:
            break
        warm, its, line = _finished(step, options, warm_guess(warm), progress, f"continuation {_weights(step)}")
        iterations, lines = iterations + its, lines + [line]
    for _ in range(BOUND_STEPS):
        if warm is None:
            break
        raised = raised_bounds(step, problem, warm.U)
        if raised is None:
            break
        step = raised
        warm, its, line = _finished(step, options, warm_guess(warm), progress, f"continuation {_bounds(step, free)}")
        iterations, lines = iterations + its, lines + [line]
    if warm is None:
        return None
    return replace(warm_guess(warm), iterations=iterations, prepared_on=PREPARED_ON, stats={"fuel_continuation": lines})


__all__ = ["BOUND_FACTOR", "BOUND_MARGIN", "BOUND_STEPS", "STEP_ROUNDS", "WEIGHT_FACTOR", "continuation_guess",
           "fuel_start", "start_problem"]
