"""Escape from a saddle (docs/mathematics.md §10, "Saddles"): a strategy that checks the second-order condition of a
converged solve and, at a saddle of the NLP, leads lower along its direction of negative curvature.

IPOPT converges to KKT points, saddles included.  A start that shares a symmetry of the problem (a raise in the orbit
plane whose body turns about its largest principal axis, when a roll about the engine would let it turn about a
smaller one) keeps the solver on the symmetric set, where the gradient in the symmetry-breaking directions vanishes;
the Lagrangian's curvature there is negative (:mod:`transcription.nlp.curvature`), and IPOPT's Hessian
regularization at every iteration is the sign of it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..ocp import Problem
from ..outcome import Result
from ..results.solution import Solution
from ..results.start import Point, Start
from .core import Context, Strategy


def regularized(sol: Solution) -> bool:
    """Whether IPOPT added a multiple of the identity to the Hessian at the last iteration of ``sol``'s solve
    (Iterate.regularization > 0): the converged point may not be a minimum, the curvature check decides."""
    return bool(sol.history) and sol.history[-1].regularization > 0


def nudged(sol: Solution, direction: np.ndarray, step: float) -> Start:
    """``sol``'s warm start moved to its NLP point + ``step`` * ``direction`` / max |direction| (scaled variables:
    no variable moves by more than ``step`` of its scale); its constraint multipliers, kept on the Start, start the
    solve's duals (the same NLP)."""
    p = sol.warm.point
    d = np.asarray(direction, float) / max(np.abs(direction).max(), 1e-300)
    return replace(sol.warm, point=Point(p.key, p.x + step * d))


@dataclass(frozen=True)
class Escape:
    """``inner``, then while its Solution is a saddle of the NLP -- converged (or IPOPT's 'acceptable': the linear
    convergence of regularized steps at a saddle can stall there), IPOPT's Hessian regularized at its
    end (:func:`regularized`) and the Lagrangian's least curvature on the tangent space below -``rtol`` times its
    largest (``ctx.method.curvature``) -- a solve from the point moved by ``step`` along the direction of negative
    curvature (:func:`nudged`; then the opposite way), kept when it converges lower; at most ``rounds`` times.  A
    saddle it cannot leave is reported as one (a note and ``stats['saddle']``), never as a minimum.  Without a
    curvature (another method, fatrop) it is ``inner``."""

    inner: Strategy
    step: float = 0.1
    rtol: float = 1e-6
    rounds: int = 3

    @property
    def label(self) -> str:
        return getattr(self.inner, "label", "")

    @property
    def budget(self) -> int | None:
        return getattr(self.inner, "budget", None)

    def ends(self, sol: Solution) -> bool:
        return getattr(self.inner, "ends", lambda _: False)(sol)

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        sol = self.inner.run(problem, start, ctx)
        trace, lines = list(sol.trace), []
        measure = getattr(ctx.method, "curvature", None)
        for _ in range(self.rounds):
            if measure is None or not ((sol.converged or sol.result is Result.acceptable) and regularized(sol)):
                break
            c = measure(problem, sol)
            if c is None or not c.saddle(self.rtol):
                break
            said = (f"a saddle of the NLP at cost {sol.cost:.10g} (curvature {c.least:.3g} on the active constraints' "
                    f"tangent space, largest {c.largest:.3g})")
            lower = None
            for sign in (1.0, -1.0):
                s = ctx.solve(problem, nudged(sol, sign * c.direction, self.step), "from the saddle, along its "
                              "negative curvature")
                trace += s.trace
                if s.converged and s.cost < sol.cost - self.rtol * abs(sol.cost):
                    lower = s
                    break
            if lower is None:
                lines.append(f"{said}: the solves along its negative curvature did not end lower")
                sol = sol.with_notes(f"ended at {lines[-1]}; not a minimum", saddle=True)
                break
            lines.append(f"left {said} along its negative curvature for cost {lower.cost:.10g}")
            sol = lower.with_notes(lines[-1])
        if lines:
            sol = sol.with_notes(saddle_escapes=lines)
        return replace(sol, trace=tuple(trace))


__all__ = ["Escape", "nudged", "regularized"]
