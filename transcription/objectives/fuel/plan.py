"""The fuel objective's default strategy (:class:`FuelStrategy`): on a grid of more than ``coarse_min`` steps the best
start on max(coarse_min, N // coarse_factor) steps (recursively), resampled on SE(3) and finished here on its switching
structure (:mod:`.structure`; the free motion and the screw interpolation on this grid are the fallback); on the
coarsest grid -- or on the problem's own where the continuation through problems counted on channels applies
(:func:`.continuation.through_channels`) -- the multistart: the homotopy from the effort optimum (:mod:`.homotopy`; or
that continuation, :mod:`.continuation`), the free motion and the screw interpolation, the lowest converged cost
kept; every epigraph solution checked by the fuel KKT guard and escaped from a false minimum (:mod:`.guard`)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

from ...ocp import Problem
from ...results.solution import Solution
from ...results.start import Start
from ...strategy import starts
from ...strategy.core import BestOf, CoarseToFine, Composed, Context, FirstOf, Solve, Warm, chosen, not_made, resolves
from .continuation import ContinuationStart, counted_unbounded, through_channels
from .guard import Guarded
from .homotopy import Homotopy
from .structure import StructuredFinish

def coarse_resolves(problem: Problem, Nc: int, fraction: float) -> bool:
    """Whether the maneuver on Nc uniform steps is near enough the one on ``problem``'s grid for its optimum to
    start the fuel solve (:func:`~transcription.strategy.core.resolves`).  Why: around the Earth a one-revolution LEO
    raise with a 1 N engine on 500 kg can move the body by 31 km, while the discrete orbit of 100 steps ends 53 km from
    that of 400 steps: its coarse problems are infeasible (docs/mathematics.md, "LEO fuel raises"); the fuel raise's
    gap is 0.0044 against a reach of 9.8."""
    return resolves(problem, problem.replace(N=Nc, mesh=None), fraction)


@dataclass(frozen=True)
class FuelStart:
    """The homotopy's start on the coarsest grid, or, where the homotopy cannot begin with its first level
    (:meth:`.continuation.ContinuationStart.start_problem`), the continuation's; the effort optimum is solved once
    for either.  ``continued``: the continuation's alone (not made where it does not apply: the plan goes on)."""

    homotopy: Homotopy
    continuation: ContinuationStart
    continued: bool = False

    @property
    def label(self) -> str:
        return self.homotopy.label

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        effort, said = self.homotopy.effort(self.homotopy.effort_problem(problem), ctx)
        if not effort.converged or effort.warm is None:
            return not_made(problem, ctx, self.label, "not available (the effort problem or a smoothed problem did "
                                                      "not converge)", effort.trace, "the effort problem")
        bounded = self.continuation.start_problem(problem, effort.warm.U, self.homotopy.effort_level_ratio)
        if bounded is None and self.continued:
            return not_made(problem, ctx, self.label, "not needed (the homotopy starts the problem itself)",
                            effort.trace, "the effort problem")
        if bounded is None:
            return self.homotopy.run(problem, None, ctx, effort=(effort, said))
        sol = self.continuation.run(problem, bounded, effort.warm, ctx)
        first = sol.trace[0].prepared(effort.trace, sol.trace[0].prepared_on or "the effort problem")
        return replace(sol, trace=(first,) + sol.trace[1:])


@dataclass(frozen=True)
class FuelStrategy(Composed):
    """The fuel objective's default (module docstring).  ``first_budget``: the free-motion and interpolation starts
    get at most this many iterations (IPOPT is slow to their bang-off-bang optima).  ``coarse_factor``,
    ``coarse_min``: the coarse grid; ``coarse_reach``: it starts the solve only when its free motion ends near this
    grid's (:func:`coarse_resolves`).  ``resolved_fraction``: a warm start on a non-uniform mesh (an adaptive level of
    refinement, docs/mathematics.md §16) with more than this fraction of the problem's steps resolves the switching
    times: its finish is one exact solve on its own burn nodes.  ``guard``, ``structure``, ``homotopy``,
    ``continuation``: the parts (their own parameters; their sub-strategies are wired here)."""

    first_budget: int = 600
    coarse_factor: int = 4
    coarse_min: int = 25
    coarse_reach: float = 0.5
    resolved_fraction: float = 0.5
    guard: Guarded = field(default_factory=lambda: Guarded(None))
    structure: StructuredFinish | None = None
    homotopy: Homotopy | None = None
    continuation: ContinuationStart | None = None

    def _structure(self, **changes) -> StructuredFinish:
        base = self.structure or StructuredFinish(self.guard)
        return replace(base, guard=self.guard, **changes)

    def homotopy_start(self) -> Homotopy:
        """The homotopy wired to this strategy's guard and structured finish."""
        base = self.homotopy or Homotopy(None)
        return replace(base, warm=self.guard.warm,
                       finish=self._structure(label="from last level", fallback_budget=base.level_budget))

    def _continuation(self) -> ContinuationStart:
        base = self.continuation or ContinuationStart(None)
        return replace(base, finish=self._structure(label="from continuation", cold=base.rough, shared_duals=True,
                                                    warm=base.resolve))

    def compose(self, problem: Problem, options, start: Start | None = None) -> Guarded:
        inner = self._from(problem, start) if start is not None else chosen(problem, options) or self._plan(problem)
        return replace(self.guard, inner=inner)

    def _from(self, problem: Problem, start: Start):
        """A given start: a solution on another grid finished on its switching structure (as a coarser grid's, or,
        from an adaptive level resolving the switching times, on its own burn nodes); one on this grid solved from."""
        fitted, notes = start.fit(problem.N, problem.scheme, problem.fractions)
        if not notes:
            return Warm()
        resolved = start.N > self.resolved_fraction * problem.N and not start.uniform
        return _Fitted(self._structure(label="warm start", resolved=resolved))

    def _plan(self, problem: Problem):
        fine = (Solve(starts.rollout, "rollout", self.first_budget), Solve(starts.interpolation, "interpolate"))
        coarse = CoarseToFine(self, self._structure(label="from coarse"), self.coarse_factor, self.coarse_min)
        Nc = coarse.grid(problem)
        first = FuelStart(self.homotopy_start(), self._continuation())
        if counted_unbounded(problem).any():
            first = replace(first, homotopy=replace(first.homotopy, label=first.continuation.label))
        if Nc < problem.N and coarse_resolves(problem, Nc, self.coarse_reach):
            grids = FirstOf((coarse, BestOf(fine)))
            # the continuation through channels, where it applies, on this grid before the coarse ones (docs §25)
            return FirstOf((replace(first, continued=True), grids)) if through_channels(problem) else grids
        entries = (first, fine[0], replace(fine[1], budget=self.first_budget))
        return FirstOf(entries) if Nc < problem.N else BestOf(entries, judge=self.guard.failed)


@dataclass(frozen=True)
class _Fitted:
    """``finish`` from a given start fitted onto the problem's grid."""

    finish: StructuredFinish

    def run(self, problem: Problem, start: Start, ctx: Context) -> Solution:
        return self.finish.run(problem, start.fit(problem.N, problem.scheme, problem.fractions)[0], ctx)


__all__ = ["FuelStart", "FuelStrategy", "coarse_resolves"]
