"""The fuel of an engine with an unbounded torque reached through problems counted on channels (docs/mathematics.md
§25): the start of a fuel problem whose homotopy (:mod:`.homotopy`) cannot begin with its first level.

:meth:`~.homotopy.Homotopy.effort_problem` makes the homotopy's effort problem its first level, phi_1(s) = s^2 / (2 r),
when every part whose fuel counts is bounded and the parts' references r differ by more than the homotopy's
``effort_level_ratio``.  With an unbounded counted part it cannot: r is then the effort optimum's largest magnitude,
known only after the effort solve, and the fuel weights, chosen for the squared effort, price the parts' magnitudes in
another ratio than the effort's (configs/leo_body_engine.yaml with the fuel objective: the moment unbounded,
w_m = 1e10).  Where the other part's fuel counts on its channels (an engine), :class:`ContinuationStart` reaches the
problem through problems whose fuel counts on channels, linear (§27), each one warm solve from the last one's optimum
(a :class:`~transcription.strategy.core.Continuation` along :meth:`ContinuationStart.path`):

0. the start: every unbounded counted part given three channels on its frame's axes, each bounded at r = ``margin``
   x its largest magnitude in the effort optimum rounded up to one significant digit (the effort optimum satisfies
   it), and the fuel weights w_i' = p / r_i, p = min_j w_j r_j: each part at its bound priced like the
   cheaper part at its own (the weights a file without weights gets, each control in units of its size, up to one
   factor), so that the path's first step moves only the parts' price ratio to the file's: solved from the optimum
   of the homotopy's effort problem (:meth:`~.homotopy.Homotopy.effort_problem`: in the actuators' terms where the
   problem has sizes; on leo_body_engine b = 1e-8 and w_m' = 1 x 1e-3 / 1e-8 = 1e5 against the file's 1e10);
1. the file's weights (each step of 1-2 one warm solve from IPOPT's adaptive barrier: ``ContinuationStart.step``);
2. the added bounds raised by ``bound_factor`` a step while a channel touches one, at most ``bound_steps`` times: a
   bound the optimum does not touch leaves it a KKT point of the problem without it, whose part's fuel is the sum of
   its components' magnitudes (at most sqrt(3) times their 2-norm, the problem's);
3. the problem itself (the 2-norm of the part, the epigraph) from that optimum and its multipliers by the structured
   finish (``finish``) and the fuel KKT guard.

A step that does not converge ends the path.  Measurements: docs/mathematics.md §25.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from ...geometry.state import U_FORCE, U_MOMENT
from ...ocp import AT_BOUND_RTOL, BoxBound, Problem
from ...results.solution import Solution
from ...results.start import Start
from ...strategy.core import Context, Continuation, Solve, Warm, labelled, not_made, step_line
from .guard import counted_parts
from .homotopy import smoothing_reference


def counted_unbounded(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts (force, moment) whose fuel counts (:func:`~.guard.counted_parts`) and that have no
    bound."""
    c = problem.control
    return counted_parts(problem) & np.array([c.force_bound is None, c.moment_bound is None])


def through_channels(problem: Problem) -> bool:
    """Whether :class:`ContinuationStart` can start ``problem``: a counted part unbounded, and every other part's
    fuel counted on its actuator's channels (an engine, thrusters, wheels).  Its steps are cheap on the problem's own
    grid and scheme, where the fuel plan tries it first (no coarse grid, no LGVI route: docs §25)."""
    free, c = counted_unbounded(problem), problem.control
    return bool(free.any()) and all(f or (b is not None and b.fuel_channels is not None)
                                    for f, b in zip(free, (c.force_bound, c.moment_bound)))


def significant(x: np.ndarray) -> np.ndarray:
    """x > 0 rounded up to one significant digit (9.96e-9 -> 1e-8, 1.01e-8 -> 2e-8)."""
    e = 10.0 ** np.floor(np.log10(x))
    return np.ceil(x / e * (1 - 1e-12)) * e


def _weights(problem: Problem) -> str:
    return f"w_f {problem.control.W_f[0, 0]:.3g}, w_m {problem.control.W_m[0, 0]:.3g}"


def _bounds(problem: Problem, free: np.ndarray) -> str:
    c = problem.control
    return ", ".join(f"|u_{n},i| <= {b.b.max():.3g}" for n, f, b in zip("fm", free, (c.force_bound, c.moment_bound))
                     if f)


@dataclass(frozen=True)
class ContinuationStart:
    """Steps 0-3 of the module docstring: ``finish`` solves the problem itself from the path's last optimum, its
    multipliers included (a structured finish, whose rough solve starts with the IPOPT options ``rough``: a small
    barrier, as the last step's optimum is a neighbouring problem's on the same grid -- IPOPT's adaptive barrier from
    its default 0.1 threw leo/raise_engine's point away, residual 1e3 within 50 iterations, where 1e-6 converged in
    140 -- and with that optimum's multipliers on the rows the two NLPs share; docs §25).  ``step``: the IPOPT options
    of steps 1-2, each from the last step's optimum: IPOPT's adaptive barrier from 1e-4.  The monotone barrier of a
    warm start (:class:`~transcription.strategy.core.Warm`) fell to 1e-9 within 30 iterations of leo_body_engine's
    weights step, far from its optimum, and crawled along the bounds with steps of a few hundredths: 229 iterations,
    64 this way; its bound step 111, 24 this way.  ``resolve``: the IPOPT options of the finish's warm solves (on the
    pruned structure, on a widened one), with the last solve's multipliers from a barrier of 1e-6 and IPOPT's default
    pushes off the bounds (the guard's barrier of 1e-9 sent leo_body_engine's pruned solve, infeasible by 7e-2 where
    the pruned controls were zeroed, into IPOPT's restoration phase: 103 iterations, 18 this way).  ``margin``,
    ``bound_factor``, ``bound_steps``: module docstring."""

    finish: object
    margin: float = 1.2
    bound_factor: float = 10.0
    bound_steps: int = 6
    rough: Mapping = field(default_factory=lambda: {"mu_init": 1e-6})
    step: Mapping = field(default_factory=lambda: {"mu_init": 1e-4, "mu_strategy": "adaptive"})
    resolve: Mapping = field(default_factory=lambda: {"warm_start_init_point": "yes", "mu_init": 1e-6})
    label: str = "the fuel homotopy from the effort optimum (or its continuation from channels)"

    def start_problem(self, problem: Problem, U: np.ndarray, ratio: float) -> Problem | None:
        """Step 0 from the effort optimum's controls U (6, n): ``problem`` with every unbounded counted part on three
        channels bounded at r = margin x its largest magnitude in U rounded up to one significant digit
        (:func:`significant`) and the fuel weights w_i' = p / r_i, p = min_j w_j r_j (module docstring);
        None when the homotopy starts ``problem`` itself (references within ``ratio`` of each other: there the file's
        weights are the first level's) or the continuation cannot start it (:func:`through_channels`: no unbounded
        counted part, or a gimballed one)."""
        if not through_channels(problem):
            return None
        free = counted_unbounded(problem)
        r = smoothing_reference(problem, U).astype(float)
        r[free] = significant(self.margin * r[free])
        if max(r[0] / r[1], r[1] / r[0]) <= ratio:
            return None
        c = problem.control
        bounds = [BoxBound(np.full(3, r[i])) if free[i] else b for i, b in enumerate((c.force_bound, c.moment_bound))]
        # the prices at the bounds (fuel per second at a full channel) made equal: dimensionless, where the former
        # w_i r_i / max r depended on the units (r_m / r_f is a length); measured in docs §25
        price = np.array([c.W_f[0, 0], c.W_m[0, 0]]) * r
        W_f, W_m = c.W_f * (price.min() / price[0]), c.W_m * (price.min() / price[1])
        return problem.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1], W_f=W_f, W_m=W_m))

    def raised(self, step: Problem, problem: Problem, U: np.ndarray) -> Problem | None:
        """Step 2: ``step`` with its added bounds (on the parts ``problem`` leaves unbounded) that a channel of the
        controls U (6, n) touches (within AT_BOUND_RTOL) raised by ``bound_factor``; None when none is touched."""
        free = counted_unbounded(problem)
        c = step.control
        bounds = [c.force_bound, c.moment_bound]
        touched = [f and bool(np.any(np.abs(U[sl]).max(axis=1) >= b.b * (1.0 - AT_BOUND_RTOL)))
                   for f, b, sl in zip(free, bounds, (U_FORCE, U_MOMENT))]
        bounds = [b.scaled(self.bound_factor) if t else b for b, t in zip(bounds, touched)]
        return step.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1])) if any(touched) else None

    def path(self, start: Problem, problem: Problem):
        """Steps 1-2 as the Continuation asks for them: the next (phase, problem) after the ``history`` tried, None
        when the last step did not converge, touches no added bound, or the bounds were raised ``bound_steps``
        times."""
        free = counted_unbounded(problem)
        weighted = start.replace(control=replace(start.control, W_f=problem.control.W_f, W_m=problem.control.W_m))

        def nxt(_, history):
            if not history:
                return f"continuation {_weights(weighted)}", weighted
            last, sol = history[-1]
            if not sol.converged or sol.warm is None or len(history) > self.bound_steps:
                return None
            step = self.raised(last, problem, sol.warm.U)
            return None if step is None else (f"continuation {_bounds(step, free)}", step)

        return nxt

    def run(self, problem: Problem, start_problem: Problem, effort: Start, ctx: Context) -> Solution:
        """Steps 0-3 from the effort optimum ``effort`` (of :meth:`~.homotopy.Homotopy.effort_problem`)."""
        free = counted_unbounded(problem)
        first = Warm("continuation start").run(start_problem, effort, ctx)
        lines = [step_line(f"start: {_weights(start_problem)}, {_bounds(start_problem, free)}", first)]
        stepped = None
        if first.converged and first.warm is not None:
            steps = Solve(label="warm start", ipopt=dict(self.step))
            stepped = Continuation(self.path(start_problem, problem), steps).run(problem, first.warm, ctx)
            lines += stepped.stats["continuation_steps"]
        parts = first.trace + (() if stepped is None else stepped.trace)
        if stepped is None or not stepped.converged or stepped.warm is None:
            return not_made(problem, ctx, self.label, "not available (the effort problem or a step of the "
                            "continuation did not converge)", parts, "the fuel continuation")
        done = self.finish.run(problem, stepped.warm, ctx.under("from continuation"))
        return labelled(done, self.label, parts, "the fuel continuation").with_notes(fuel_continuation=lines)


__all__ = ["ContinuationStart", "counted_unbounded", "significant", "through_channels"]
