"""The fuel objective reached by continuation in its data (docs/mathematics.md §25): the start of a fuel problem whose
homotopy (:mod:`.homotopy`) cannot begin with its first level.

:meth:`~.homotopy.Homotopy.effort_problem` makes the homotopy's effort problem its first level, phi_1(s) = s^2 / (2 r),
when every part whose fuel counts is bounded and the parts' references r differ by more than the homotopy's
``effort_level_ratio``.  With an unbounded counted part it cannot: r is then the effort optimum's largest magnitude,
known only after the effort solve, and the fuel weights, chosen for the squared effort, price the parts' magnitudes in
another ratio than the effort's (configs/leo_body_engine.yaml with the fuel objective: the moment unbounded,
w_m = 1e10; its first level did not converge in 500 iterations).

:class:`ContinuationStart` reaches it through problems it can solve, each on the problem's own grid from the last
one's optimum (a :class:`~transcription.strategy.core.Continuation` along the path of :meth:`ContinuationStart.path`):

0. the start: every unbounded counted part bounded at its reference (``margin`` x its effort optimum's largest
   magnitude, rounded up to one significant digit, so that the effort optimum is feasible), and the fuel weights
   w_i' = w_i r_i / max_j r_j, so that the first level's weights w_i' / r_i are the file's effort weights (scaled):
   its effort problem is the file's, and the fuel strategy solves it (on leo_body_engine the start is
   configs/leo_engine_fuel.yaml's problem to the last bit);
1. the weights raised geometrically, by about ``weight_factor`` a step, to the file's;
2. the added bounds raised by ``bound_factor`` a step while any is active at the optimum (a bound the optimum does
   not touch leaves it a KKT point of the problem without it), at most ``bound_steps`` times;
3. the problem itself, from that optimum, by the structured finish and the fuel KKT guard.

Steps 1 and 2 are each a structured finish from the last converged optimum (``step``); a step need not pass the guard
(only the last solve is the answer), but it must converge: one that does not is halved (the geometric mean of the last
converged step's weights and bounds and its own), at most ``shorter`` times in a row.  Measurements:
docs/mathematics.md §25.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...geometry.state import U_FORCE, U_MOMENT
from ...ocp import AT_BOUND_RTOL, NormBound, Problem
from ...results.solution import Solution
from ...strategy.core import Context, Continuation, labelled, not_made, step_line
from .guard import counted_parts
from .homotopy import smoothing_reference


def counted_unbounded(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts (force, moment) whose fuel counts (:func:`~.guard.counted_parts`) and that have no
    bound."""
    c = problem.control
    return counted_parts(problem) & np.array([c.force_bound is None, c.moment_bound is None])


def significant(x: np.ndarray) -> np.ndarray:
    """x > 0 rounded up to one significant digit (9.96e-9 -> 1e-8, 1.01e-8 -> 2e-8)."""
    e = 10.0 ** np.floor(np.log10(x))
    return np.ceil(x / e * (1 - 1e-12)) * e


def diagonal_weights(problem: Problem) -> np.ndarray:
    """(2,) the fuel weights (w_f, w_m) of ``problem`` (its weights are w I)."""
    c = problem.control
    return np.array([c.W_f[0, 0], c.W_m[0, 0]])


def added_bounds(problem: Problem, free: np.ndarray) -> list[float]:
    """The radii of ``problem``'s bounds on the ``free`` parts (force, moment): those the continuation added."""
    c = problem.control
    return [b.b for f, b in zip(free, (c.force_bound, c.moment_bound)) if f]


def _weights(problem: Problem) -> str:
    w_f, w_m = diagonal_weights(problem)
    return f"w_f {w_f:.3g}, w_m {w_m:.3g}"


def _bounds(problem: Problem, free: np.ndarray) -> str:
    return ", ".join(f"|u_{n}| <= {b:.3g}" for n, b in zip(np.array(["f", "m"])[free], added_bounds(problem, free)))


@dataclass(frozen=True)
class ContinuationStart:
    """Steps 0-3 of the module docstring: ``first`` solves the start problem (the fuel strategy), ``step`` each step
    of the path (a structured finish without fallback, more rounds than the problem's own), ``finish`` the problem
    itself.  ``margin``, ``weight_factor``, ``bound_factor``, ``bound_steps``: module docstring; ``shorter``: how many
    times in a row a step that did not converge is halved (:meth:`path`)."""

    first: object
    step: object
    finish: object
    margin: float = 1.2
    weight_factor: float = 10.0
    bound_factor: float = 10.0
    bound_steps: int = 6
    shorter: int = 3
    label: str = "the fuel homotopy from the effort optimum (or its continuation from a bounded problem)"

    def start_problem(self, problem: Problem, U: np.ndarray, ratio: float) -> Problem | None:
        """Step 0 from the effort optimum's controls U (6, n): ``problem`` with every unbounded counted part bounded
        at r = margin x its largest magnitude in U rounded up to one significant digit (:func:`significant`) and the
        fuel weights w_i r_i / max_j r_j; None when the homotopy starts ``problem`` itself: no unbounded counted part,
        or references within ``ratio`` of each other (there the file's weights are the first level's)."""
        free = counted_unbounded(problem)
        if not free.any():
            return None
        r = smoothing_reference(problem, U).astype(float)
        r[free] = significant(self.margin * r[free])
        if max(r[0] / r[1], r[1] / r[0]) <= ratio:
            return None
        c = problem.control
        bounds = [NormBound(r[i]) if free[i] else b for i, b in enumerate((c.force_bound, c.moment_bound))]
        # (w_i r_i) / max r, not w_i (r_i / max r): leo_body_engine's 1e10 x 1e-8 / 1e-3 is 1e5 to the bit so, and its
        # start problem the bundled leo_engine_fuel's (module docstring: one unit in the last place changed the path)
        W_f, W_m = c.W_f * r[0] / r.max(), c.W_m * r[1] / r.max()
        return problem.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1], W_f=W_f, W_m=W_m))

    def weight_steps(self, start: Problem, problem: Problem) -> list[Problem]:
        """Step 1: ``start`` with its weights raised geometrically to ``problem``'s in n steps of about
        ``weight_factor`` (n = the largest ratio's rounded number of factors, at least 1 where a weight differs), its
        bounds kept."""
        c0 = start.control
        w0, w1 = diagonal_weights(start), diagonal_weights(problem)
        ratio = np.where(w0 > 0, w1 / np.where(w0 > 0, w0, 1.0), 1.0)
        n = int(max(np.round(np.log(ratio.max()) / np.log(self.weight_factor)), 1)) if ratio.max() > 1.0 else 0
        return [start.replace(control=replace(c0, W_f=np.eye(3) * w[0], W_m=np.eye(3) * w[1]))
                for w in (w0 * ratio ** (k / n) if k < n else w1 for k in range(1, n + 1))]

    def raised(self, step: Problem, problem: Problem, U: np.ndarray) -> Problem | None:
        """Step 2: ``step`` with its added bounds (the parts ``problem`` leaves unbounded) that the controls U (6, n)
        touch (within AT_BOUND_RTOL) raised by ``bound_factor``; None when none is touched."""
        free = counted_unbounded(problem)
        c = step.control
        bounds = [c.force_bound, c.moment_bound]
        raised = False
        for i, sl in enumerate((U_FORCE, U_MOMENT)):
            if free[i] and np.linalg.norm(U[sl], axis=0).max() >= bounds[i].b * (1.0 - AT_BOUND_RTOL):
                bounds[i], raised = NormBound(bounds[i].b * self.bound_factor), True
        return step.replace(control=replace(c, force_bound=bounds[0], moment_bound=bounds[1])) if raised else None

    def between(self, a: Problem, b: Problem, free: np.ndarray) -> Problem:
        """The shorter step from ``a`` (converged) towards ``b`` (not): weights and added bounds (the ``free`` parts'),
        each the geometric mean of a's and b's."""
        ca_, cb = a.control, b.control
        w = np.sqrt(diagonal_weights(a) * diagonal_weights(b))
        bounds = [NormBound(np.sqrt(x.b * y.b)) if f else x for f, x, y in
                  zip(free, (ca_.force_bound, ca_.moment_bound), (cb.force_bound, cb.moment_bound))]
        return a.replace(control=replace(ca_, W_f=w[0] * np.eye(3), W_m=w[1] * np.eye(3), force_bound=bounds[0],
                                         moment_bound=bounds[1]))

    def path(self, start: Problem, problem: Problem):
        """The path of steps 1-2 as the Continuation asks for it: (phase, problem) after the ``history`` tried.  After a
        step that did not converge, the step from the last converged problem is halved (in the logarithm of the
        weights and bounds, :meth:`between`) at most ``shorter`` times in a row, then the path ends."""
        weights, free = self.weight_steps(start, problem), counted_unbounded(problem)
        b0 = added_bounds(start, free)

        def nxt(_, history):
            ok = [i for i, (_p, sol) in enumerate(history) if sol.converged and sol.warm is not None]
            last, sol = history[ok[-1]] if ok else (start, None)
            failed = len(history) - (ok[-1] + 1 if ok else 0)
            if failed:
                if failed > self.shorter:
                    return None
                step = self.between(last, history[-1][0], free)
                return f"continuation {_weights(step)}, {_bounds(step, free)} (shorter)", step
            w = diagonal_weights(last)
            ahead = [p for p in weights if np.max(diagonal_weights(p) / w) > 1 + 1e-9]
            if ahead:
                return f"continuation {_weights(ahead[0])}", ahead[0]
            raises = np.log(max(b / b_0 for b, b_0 in zip(added_bounds(last, free), b0))) / np.log(self.bound_factor)
            step = None if sol is None or raises >= self.bound_steps - 1e-9 else self.raised(last, problem,
                                                                                              sol.warm.U)
            return None if step is None else (f"continuation {_bounds(step, free)}", step)

        return nxt

    def run(self, problem: Problem, start_problem: Problem, ctx: Context) -> Solution:
        free = counted_unbounded(problem)
        first = self.first.run(start_problem, None, ctx.under("continuation start"))
        lines = [step_line(f"start: {_weights(start_problem)}, {_bounds(start_problem, free)}", first)]
        last = first if first.converged and first.warm is not None else None
        stepped = None
        if last is not None:
            stepped = Continuation(self.path(start_problem, problem), self.step, "continuation").run(
                problem, first.warm, ctx)
            if stepped is not None:
                lines += stepped.stats["continuation_steps"]
                last = stepped if stepped.converged and stepped.warm is not None else None
        parts = first.trace + (() if stepped is None else stepped.trace)
        if last is None:
            return not_made(problem, ctx, self.label, "not available (the effort problem, a smoothed problem or a "
                            "step of the continuation did not converge)", parts, "the fuel continuation")
        done = self.finish.run(problem, last.warm.primal(), ctx.under("from continuation"))
        return labelled(done, self.label, parts, "the fuel continuation").with_notes(fuel_continuation=lines)


__all__ = ["ContinuationStart", "counted_unbounded", "significant"]
