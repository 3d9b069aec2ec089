"""The fuel objective by homotopy (docs/mathematics.md §20-§21): the start of a fuel problem's solve on its coarsest
grid.  The L1 objective sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|) is reached from the effort optimum either directly
(the jump: the fuel NLP, eps = 0, cold) or through the smoothed magnitude phi_eps(s) = (1 - eps) s + eps s^2 / (2 s_ref)
at decreasing eps, then the fuel NLP from the last level, warm (:class:`Homotopy`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from ...geometry.state import U_FORCE, U_MOMENT
from ...nlp.transcription import SmoothTranscription
from ...ocp import Problem
from ...ocp.estimate import control_sizes
from ...results.solution import Solution
from ...results.start import Start
from ...strategy.core import Context, not_made
from ..effort import Effort, EffortStrategy, relaxation
from .guard import counted_parts


def smoothing_reference(problem: Problem, U: np.ndarray) -> np.ndarray:
    """The references (r_f, r_m) of phi_eps(s) = (1 - eps) s + eps s^2 / (2 r), physical units: a bounded part's
    bound (its magnitude's scale, :meth:`SmoothTranscription.magnitude_scales`); an unbounded part's largest
    magnitude in the effort optimum's controls U (6, n), or its scale where that vanishes (a removed part); so
    phi_eps'(s) is in [1 - eps, 1] on the effort optimum's magnitudes (docs/mathematics.md §21).  The structured
    finish's roundings are fractions of the same references (:mod:`.structure`)."""
    c = problem.control
    mags = np.array([np.linalg.norm(U[sl], axis=0).max(initial=0.0) for sl in (U_FORCE, U_MOMENT)])
    unbounded = np.array([b is None or b.removed for b in (c.force_bound, c.moment_bound)])
    return np.where(unbounded & np.isfinite(mags) & (mags > 0.0), mags, SmoothTranscription.magnitude_scales(problem))


@dataclass(frozen=True)
class Homotopy:
    """The homotopy on the problem's own grid: the effort optimum, the jump or the smoothed levels, then the fuel NLP
    from the last point (docs/mathematics.md §20); its attempt (named ``label``) carries the effort solves and the
    levels as its parts, ``stats['homotopy_levels']`` says which path was taken.

    ``jump``, ``jump_budget``, ``jump_max_n``: the first step from the effort optimum is the fuel NLP itself (eps = 0,
    cold, within jump_budget iterations) on grids of at most jump_max_n steps, the levels only when that does not
    converge.  ``first``, ``factor``, ``last``: the levels eps = first, first / factor, ... >= last, each within
    ``level_budget`` iterations, from the last level's primal point with IPOPT's own barrier start; the fuel NLP after
    the last level starts warm (``warm``, the guard's IPOPT options, :class:`.guard.Guarded`).
    ``structure_from_budget``: a level after the first that reaches its budget ends the homotopy with its last point,
    which then starts the structured finish (``finish``) as a coarser grid's optimum would (it is near the switching
    structure already).  ``effort_rollout``, ``effort_rollout_budget``: the effort problem, when its plan would start
    from the relaxed problem and the force is no body-fixed engine, is first solved from the free motion within that
    budget.  ``effort_level_ratio``: :meth:`effort_problem`."""

    finish: object
    warm: Mapping | None = None
    jump: bool = True
    jump_budget: int = 500
    jump_max_n: int = 40
    first: float = 1.0
    factor: float = 10.0
    last: float = 1e-4
    level_budget: int = 500
    structure_from_budget: bool = True
    effort_rollout: bool = True
    effort_rollout_budget: int = 200
    effort_level_ratio: float = 1e3
    label: str = "the fuel homotopy from the effort optimum"

    def levels(self) -> list[float]:
        """eps of the smoothed levels, decreasing geometrically: first, first / factor, ... >= last."""
        n = int(round(np.log(self.first / self.last) / np.log(self.factor)))
        return [self.first / self.factor**k for k in range(n + 1)]

    def effort_problem(self, problem: Problem) -> Problem:
        """The effort problem whose optimum starts the homotopy: ``problem`` with the objective effort,
        sum_j omega_j (1/2)(u_f^T W_f' u_f + u_m^T W_m' u_m), where W_i' = w_i / r_i I (w_i the fuel weights, r_i the
        parts' magnitude scales: their bounds) when every part whose fuel counts is bounded and the bounds differ by
        more than ``effort_level_ratio``: the first level's problem, phi_1(s) = s^2 / (2 r) (docs/mathematics.md §21).
        With an unbounded counted part (its reference is the effort optimum's own magnitude, not known before it) the
        effort in the actuators' terms, W_i' = I / s_i^2 (s_i the controls' sizes,
        :func:`~transcription.ocp.estimate.control_sizes`: each control in units of its size, docs §7), where the
        problem has sizes: the fuel weights squared price the parts in a ratio that depends on the units (docs §25);
        otherwise, as where the references are within ``effort_level_ratio``, W_i' = w_i I."""
        c = problem.control
        counted = [b for b, k in zip((c.force_bound, c.moment_bound), counted_parts(problem)) if k]
        unbounded = any(b is None for b in counted)
        sizes = control_sizes(problem) if unbounded else None
        if sizes is not None:
            W_f, W_m = Effort().unit_weights(*sizes)
            return problem.replace(control=replace(c, objective=Effort(), W_f=W_f, W_m=W_m))
        r = SmoothTranscription.magnitude_scales(problem)
        if not counted or unbounded or max(r[0] / r[1], r[1] / r[0]) <= self.effort_level_ratio:
            return problem.replace(control=replace(c, objective=Effort()))
        return problem.replace(control=replace(c, objective=Effort(), W_f=c.W_f / r[0], W_m=c.W_m / r[1]))

    def effort(self, problem: Problem, ctx: Context) -> tuple[Solution, str]:
        """The effort optimum of the effort problem ``problem`` -- with control bounds or path
        constraints and no body-fixed engine, first from the free motion within ``effort_rollout_budget``; otherwise,
        or when that does not converge, by the effort strategy; its trace holds every solve -- and how it was reached,
        in words."""
        ctx = ctx.under("effort")
        tried, said = (), ""
        if self.effort_rollout and relaxation(problem) is not None and \
                getattr(problem.control.force_bound, "engine_axis", None) is None:
            sol = ctx.solve(problem, None, "rollout", max_iter=min(int(ctx.options.max_iter),
                                                                    self.effort_rollout_budget))
            if sol.converged and sol.warm is not None:
                return sol, f"{sol.iterations} (from the free motion)"
            tried, said = sol.trace, f"{sol.iterations} from the free motion ({sol.result}), then "
        sol = EffortStrategy().run(problem, None, ctx)
        return replace(sol, trace=tried + sol.trace), (f"{said}{sol.iterations} by the effort plan" if said
                                                        else f"{sol.iterations}")

    def run(self, problem: Problem, start: Start | None, ctx: Context,
            effort: tuple[Solution, str] | None = None) -> Solution:
        effort, said = effort or self.effort(self.effort_problem(problem), ctx)
        if not effort.converged or effort.warm is None:
            return not_made(problem, ctx, self.label, "not available (the effort problem or a smoothed problem did "
                                                      "not converge)", effort.trace, "the effort problem")
        parts, levels = list(effort.trace), [f"effort: {said}"]
        ref = smoothing_reference(problem, effort.warm.U)
        fuel = problem.control.objective
        last, schedule = None, self.levels()
        if self.jump and problem.N <= self.jump_max_n:
            jump = ctx.solve(self._level(problem, fuel, 0.0, ref), effort.warm.primal(), "fuel jump",
                             max_iter=min(int(ctx.options.max_iter), self.jump_budget))
            parts += jump.trace
            status = jump.stats.get("solver_status", str(jump.result))
            if jump.converged:
                levels.append(f"the fuel NLP from the effort optimum: {jump.trace[-1].iterations}")
                last, schedule = jump, []
            else:
                levels.append(f"the fuel NLP from the effort optimum: {jump.trace[-1].iterations}, {status}, so the "
                              "levels")
        for eps in schedule:
            sol = ctx.solve(self._level(problem, fuel, eps, ref), effort.warm.primal() if last is None else last.warm,
                            f"eps {eps:.0e}",
                            max_iter=min(int(ctx.options.max_iter), self.level_budget))
            parts += sol.trace
            levels.append(f"eps = {eps:.0e}: {sol.trace[-1].iterations}")
            if not sol.converged:
                status = sol.stats.get("solver_status", str(sol.result))
                if not (self.structure_from_budget and eps < self.first and status == "Maximum_Iterations_Exceeded") \
                        or sol.warm is None:
                    return not_made(problem, ctx, self.label, "not available (the effort problem or a smoothed "
                                    "problem did not converge)", tuple(parts), "the fuel homotopy")
                levels[-1] += f", {status}: its point starts the structured finish"
                done = self.finish.run(problem, sol.warm.primal(), ctx.under("from last level"))
                return self._said(done, parts, levels, "the fuel homotopy's last level, at its budget")
            last = sol
        done = ctx.solve(problem, last.warm, "from homotopy", ipopt=self.warm)
        return self._said(done, parts, levels, "the fuel homotopy")

    @staticmethod
    def _level(problem: Problem, fuel, eps: float, ref: np.ndarray) -> Problem:
        """``problem`` with its fuel objective smoothed by eps (references ``ref``)."""
        return problem.replace(control=replace(problem.control, objective=fuel.smoothed(eps, ref)))

    def _said(self, sol: Solution, parts: list, levels: list[str], on: str) -> Solution:
        first = replace(sol.trace[0], label=self.label).prepared(tuple(parts), on)
        return replace(sol, trace=(first,) + sol.trace[1:]).with_notes(homotopy_levels="; ".join(levels))


__all__ = ["Homotopy", "smoothing_reference"]
