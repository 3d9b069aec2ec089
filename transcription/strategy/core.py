"""Strategies: small typed combinators over one method solve (diffrax's step-size controllers apart from its solvers).

A strategy is a frozen dataclass whose fields are its parameters, with one method ``run(problem, start, ctx) ->
Solution`` that solves through its :class:`Context` (``ctx.solve``: one solve of ``ctx.method``) and returns a Solution
whose trace holds every attempt it made (:mod:`transcription.results.trace`).  The generic combinators here:
:class:`Solve`, :class:`FirstOf`, :class:`BestOf`, :class:`CoarseToFine` and :class:`Continuation`; each objective
composes its default strategy from them (:mod:`transcription.objectives`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Protocol

import numpy as np

from ..dynamics.lgvi import discretization
from ..geometry.state import X_POS
from ..methods.base import Method, Progress, failed_solution, phased
from ..ocp import Problem
from ..ocp.estimate import target_estimate
from ..outcome import Result
from ..results.solution import Solution
from ..results.start import Start
from ..results.trace import Attempt
from . import starts


@dataclass(frozen=True)
class Context:
    """What a strategy solves with: ``method`` (a Method and its options) and ``report`` (the progress callback,
    already under the phase of the strategy running)."""

    method: Method
    report: Progress | None = None

    def solve(self, problem: Problem, start: Start | None, label: str, ipopt=None, **options) -> Solution:
        """One solve of ``problem`` from ``start`` by the method with ``options`` changed (and, for the direct method,
        the IPOPT options ``ipopt`` added), its progress under ``label``, its trace's attempt named ``label``."""
        method = self.method
        if options or ipopt:
            method = method.replace(**options) if ipopt is None else method.replace(ipopt=ipopt, **options)
        return method.solve(problem, start, phased(self.report, label), label)

    def under(self, phase: str) -> "Context":
        """This context with its solves' progress under ``phase`` (nested: 'coarse N=25 / effort / rollout')."""
        return replace(self, report=phased(self.report, phase))

    def using(self, **options) -> "Context":
        """This context with the method's options changed."""
        return replace(self, method=self.method.replace(**options))

    @property
    def options(self):
        return self.method.options


class Strategy(Protocol):
    """A strategy (module docstring)."""

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        ...


class Composed:
    """A strategy composed of others for each problem: :meth:`compose` gives the combinator it runs (data: a caller or
    a test reads which starts it tries, in which order, with which budgets), :meth:`run` runs it."""

    def compose(self, problem: Problem, options, start: Start | None = None) -> Strategy:
        raise NotImplementedError

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        return self.compose(problem, ctx.options, start).run(problem, start, ctx)


def chosen(problem: Problem, options) -> "Solve | None":
    """The one start a user chose (``initial_guess`` other than 'auto': :data:`~.starts.KINDS`) as a strategy, its
    whole budget; None with 'auto'."""
    kind = options.initial_guess
    return None if kind == "auto" else Solve(lambda p: starts.make(kind, p), kind)


def not_made(problem: Problem, ctx: Context, label: str, why: str, parts: tuple[Attempt, ...] = (),
             on: str = "", result: Result = Result.solver_failed) -> Solution:
    """The Solution of a start that could not be made (its ``parts``: the solves that tried to make it): no solve
    from it, ``result`` (``infeasible`` where making it proved the problem has no solution); the trace's attempt
    says why."""
    sol = failed_solution(problem, ctx.method.name, getattr(ctx.options, "solver", ""), result, why)
    return replace(sol, trace=(Attempt(label, None, note=why, parts=parts, prepared_on=on),))


def labelled(sol: Solution, label: str, parts: tuple[Attempt, ...] = (), on: str = "", was: str = "") -> Solution:
    """``sol`` with its first attempt named ``label`` -- or, with ``was``, every attempt whose name begins with
    ``was`` renamed so (a finish's attempts: 'from coarse, on its switching structure', 'from coarse') -- and
    ``parts`` (the solves that made its start, on ``on``) before the first."""
    trace = sol.trace or (Attempt(label, sol.result),)
    named = [replace(a, label=label + a.label[len(was):]) if was and a.label.startswith(was) else a for a in trace]
    if not was:
        named[0] = replace(named[0], label=label)
    return replace(sol, trace=(named[0].prepared(parts, on), *named[1:]))


def collapsed(sol: Solution, label: str, on: str) -> Solution:
    """``sol`` with its attempts made one, named ``label``: its last solve's, the earlier ones its parts (``on``
    describing them) -- a strategy whose several solves make one start (a structured finish's rounds)."""
    if not sol.trace:
        return sol
    *earlier, last = sol.trace
    return replace(sol, trace=(replace(last, label=label).prepared(tuple(earlier), on),))


@dataclass(frozen=True)
class Solve:
    """One solve from the start ``make(problem)`` gives (None: the start given to the strategy), within ``budget``
    iterations (None: the method's own), named ``label``, with IPOPT options ``ipopt`` added (the direct method) and
    ``stats`` (what the start's making says) added to its Solution."""

    make: Callable[[Problem], Start | None] | None = None
    label: str = ""
    budget: int | None = None
    ipopt: dict | None = None
    stats: dict | None = None

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        start = self.make(problem) if self.make is not None else start
        label = self.label or (str(start.origin) if start is not None else "rollout")
        budget = {} if self.budget is None else {"max_iter": min(int(ctx.options.max_iter), int(self.budget))}
        sol = ctx.solve(problem, start, label, ipopt=self.ipopt, **budget)
        return sol.with_notes(**self.stats) if self.stats else sol


@dataclass(frozen=True)
class Warm:
    """One solve from the start given to the strategy: an optimum of a related problem (the previous refinement
    level's, another scheme's or grid's, the user's ``warm_start``), near this one's.  IPOPT's barrier parameter
    starts at ``mu_init`` instead of its default 0.1, which pushes such a point off its active bounds and can carry the
    solve into another basin: a LEO phasing's refinement level went from cost 198.28 to 205.93 in 175 iterations
    from its previous level's optimum, and stays at 198.28 in 14 this way (docs/mathematics.md §16, *Warm levels*).
    Without inequality constraints the barrier plays no part and nothing changes."""

    label: str = "warm start"
    mu_init: float = 1e-4

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        return Solve(label=self.label, ipopt={"mu_init": self.mu_init}).run(problem, start, ctx)


@dataclass(frozen=True)
class FirstOf:
    """The strategies in turn until one converges (or the user interrupts): its Solution, the trace of all of them.
    A strategy whose Solution it ``ends`` (its own method ``ends(solution)``, e.g. a phase 1 that proved the problem
    locally infeasible) ends the list; the rest are recorded as not tried, ``not_tried`` saying why."""

    strategies: tuple
    not_tried: str = "not tried"

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        trace, sol = [], None
        for i, s in enumerate(self.strategies):
            sol = s.run(problem, start, ctx)
            trace += sol.trace
            if sol.converged or sol.result is Result.interrupted:
                break
            if getattr(s, "ends", lambda _: False)(sol):
                trace += [Attempt(getattr(r, "label", type(r).__name__), None, note=self.not_tried)
                          for r in self.strategies[i + 1:]]
                break
        return replace(sol, trace=tuple(trace))


@dataclass(frozen=True)
class BestOf:
    """Every strategy (a multistart); the lowest-cost converged Solution, the trace of all of them, and the spread of
    the converged costs (:func:`spread`).  ``judge(solution, ctx) -> bool``: whether a converged start is a false
    minimum of the NLP rather than an optimum of the problem (named in the sentence; None: none judged).  ``names``
    (one per strategy, e.g. the homotopy classes of a path round its cones) and ``stat``: what each ended at and the
    iterations it spent, said in the message and in ``stats[stat]`` (:func:`tried`)."""

    strategies: tuple
    same_optimum_rtol: float = 1e-6
    judge: Callable[[Solution, "Context"], bool] | None = None
    names: tuple[str, ...] = ()
    stat: str = ""

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        sols = []
        for s in self.strategies:
            sols.append(s.run(problem, start, ctx))
            if sols[-1].result is Result.interrupted:
                return replace(sols[-1], trace=tuple(a for x in sols for a in x.trace))
        done = [s for s in sols if s.converged]
        best = min(done, key=lambda s: s.cost) if done else sols[-1]
        said = spread([s.cost for s in done], problem.N, self.same_optimum_rtol,
                      [s.cost for s in done if self.judge is not None and self.judge(s, ctx)])
        best = replace(best, trace=tuple(a for x in sols for a in x.trace))
        best = best.with_notes(said["multistart"] if best.converged and said else "", **said)
        if not self.names:
            return best
        line, stats = tried(self.stat, self.names, sols)
        return best.with_notes(line, **stats)


@dataclass(frozen=True)
class Guessed:
    """``inner`` run on the problem with its final-time guess T replaced (a free final time: the same NLP from other
    starts -- theirs made over T, a rendezvous target placed where it is at T), its Solution's problem the one
    given.  A :class:`BestOf` over several is a multistart across the time bounds."""

    inner: Strategy
    T: float

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        sol = self.inner.run(problem.replace(T=self.T), start, ctx.under(f"T guess {self.T:.6g}"))
        return replace(sol, problem=problem)


def tried(what: str, names: tuple[str, ...], sols: list[Solution]) -> tuple[str, dict]:
    """The sentence and stats of a :class:`BestOf` whose strategies are named (``names``, one each): what each
    ended at (its cost to 6 digits, or its result) and the iterations it spent, one line each in ``stats[what]``
    (words: summary.json keeps them) and joined in the sentence."""
    rows = [f"{n}: " + (f"{s.cost:.6g}" if s.converged else s.result.value) + f" ({s.iterations} iterations)"
            for n, s in zip(names, sols)]
    return f"{what.replace('_', ' ')} tried: {'; '.join(rows)}; the lowest kept", {what: rows}


def spread(costs: list[float], N: int, rtol: float, false: list[float] = ()) -> dict:
    """The spread of a multistart's converged costs on N steps, as Solution stats: ``multistart_starts``,
    ``multistart_optima`` (costs within ``rtol`` counted once), ``multistart_spread`` = (max - min) / min,
    ``multistart_grid`` = N, ``multistart`` (the sentence), and with ``false`` (the costs of false minima of the NLP)
    ``multistart_false_minima``; {} with fewer than two."""
    costs = sorted(c for c in costs if np.isfinite(c))
    if len(costs) < 2:
        return {}
    optima = [costs[0]]
    for c in costs[1:]:
        if c - optima[-1] > rtol * abs(optima[-1]):
            optima.append(c)
    rel = (costs[-1] - costs[0]) / max(abs(costs[0]), 1e-300)
    said = (f"the {len(costs)} starts on {N} steps ended at the same optimum (spread {rel:.1e})" if len(optima) == 1
            else f"the {len(costs)} starts on {N} steps ended at {len(optima)} different optima (costs "
                 f"{', '.join(f'{c:.6g}' for c in optima)}; spread {rel:.1%}): the lowest is kept, and a lower one "
                 f"may exist (more starts: a sweep over horizon.T.guess or the seeds)")
    out = {"multistart_starts": len(costs), "multistart_optima": len(optima), "multistart_spread": float(rel),
           "multistart_grid": N}
    if false:
        bad = ", ".join(f"{c:.6g}" for c in sorted(false))
        said += (f"; of these, {len(false)} ({bad}) fail the fuel KKT guard: false minima of the NLP, where thrust "
                 f"would pay on coast nodes, not optima of the fuel problem")
        out["multistart_false_minima"] = len(false)
    return {**out, "multistart": said}


@dataclass(frozen=True)
class CoarseToFine:
    """``coarse`` on a coarser uniform grid of max(min_N, N // factor) steps, its solution resampled onto this grid
    on SE(3) and finished by ``finish`` (named ``label``, the coarse solves its attempt's parts); when the coarse
    solve fails, a Solution saying so (a FirstOf then tries the next start).

    ``fallback``: the starts on this grid (a strategy) tried too when the finish converged more than ``jump_rtol`` (relative)
    above the coarse optimum -- it left the coarse optimum's basin for another local minimum rather than refining it
    -- the lower of the two kept, the jump said in the message and ``stats['finish_jumps']``.  Why: a 50 deg
    minimum-time plane change at thrust 15 (configs/plane_change_time_50.yaml): 0.5209 on 25 steps, its finish on 50
    steps 0.7525, on 100 steps 0.7391, where every start on 100 steps reaches 0.5212."""

    coarse: Strategy
    finish: Strategy
    factor: int = 4
    min_N: int = 25
    fallback: Strategy | None = None
    jump_rtol: float = 0.02

    def grid(self, problem: Problem) -> int:
        return max(self.min_N, problem.N // self.factor)

    @property
    def label(self) -> str:
        return "the best start on a coarser grid, resampled"

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        Nc = self.grid(problem)
        label = f"the best start on {Nc} steps, resampled"
        c = self.coarse.run(problem.replace(N=Nc, mesh=None), None, ctx.under(f"coarse N={Nc}"))
        if not c.converged or c.warm is None:
            return not_made(problem, ctx, label, "not available (the coarse-grid problem did not converge)", c.trace,
                            "the coarse grid")
        fine = c.warm.fit(problem.N, problem.scheme, problem.fractions)[0]
        sol = labelled(self.finish.run(problem, fine, ctx), label, c.trace, "the coarse grid",
                       getattr(self.finish, "label", ""))
        stats = {k: v for k, v in c.stats.items() if k.startswith(("multistart", "homotopy", "fuel_continuation"))}
        said = stats.get("multistart", "") if sol.converged else ""
        sol = sol.with_notes(said, **stats)
        if self.fallback is None or not sol.converged or sol.cost - c.cost <= self.jump_rtol * abs(c.cost):
            return sol
        alt = self.fallback.run(problem, None, ctx)
        jump = (f"the finish from {Nc} steps ended at {sol.cost:.6g}, {sol.cost / c.cost - 1:.1%} above the coarse "
                f"optimum {c.cost:.6g} (another local minimum): the starts on {problem.N} steps tried too, "
                + (f"best {alt.cost:.6g}" if alt.converged else f"{alt.result.value}"))
        best = alt if alt.converged and alt.cost < sol.cost else sol
        jumps = [*c.stats.get("finish_jumps", []), jump]
        return replace(best, trace=sol.trace + alt.trace).with_notes(jump, finish_jumps=jumps)


@dataclass(frozen=True)
class FromRelated:
    """The problem first solved as a related one -- ``related(problem)``, by its default strategy
    (:func:`default_strategy`), its progress under ``name`` -- that optimum fitted onto this problem's grid and scheme
    and finished by ``finish`` (within ``finish_budget`` iterations per solve when given), the attempt named ``label``
    (the first solves its parts, on ``on``); when the first solve fails, a Solution saying so (its trace: what the
    related problem tried)."""

    finish: Strategy
    related: Callable[[Problem], Problem]
    name: str
    label: str
    on: str
    finish_budget: int | None = None

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution:
        other = self.related(problem)
        c = default_strategy(other, ctx.options).run(other, start, ctx.under(self.name))
        if not c.converged or c.warm is None:
            return not_made(problem, ctx, self.label, f"not available ({self.on} did not converge)", c.trace, self.on)
        fitted = c.warm.fit(problem.N, problem.scheme, problem.fractions)[0]
        if self.finish_budget is not None:
            ctx = ctx.using(max_iter=min(self.finish_budget, ctx.options.max_iter))
        return labelled(self.finish.run(problem, fitted, ctx), self.label, c.trace, self.on,
                        getattr(self.finish, "label", ""))


def from_scheme(finish: Strategy, scheme: str = "lgvi", finish_budget: int | None = 200) -> FromRelated:
    """The problem first solved on another ``scheme`` of the same grid and control layout (:class:`FromRelated`),
    named 'from the <scheme> optimum', its finish within ``finish_budget`` iterations.

    How the Kepler-split LGVI is reached (docs/mathematics.md §2a): its exact two-body drift is strongly nonlinear
    in the state far from an orbit, where a solver's first iterates are, while the LGVI's drift is polynomial; their
    optima differ by the LGVI's orbit error (3.5 km in a LEO orbit at N = 400), a few iterations apart: 7 to 27 on the
    six bundled lgvi_kepler files.  A finish that has not converged in ``finish_budget`` (about seven times the most
    measured) is not near: on leo_engine_fuel.yaml's effort problem (the wheels' torque bounded) it wandered for
    3000 iterations at a residual of 0.18, where the objective's own strategy on that scheme converges in 69."""
    def other(p: Problem) -> Problem:
        d = p.disc
        return replace(p, disc=discretization(d.model, scheme, d.newton_iters, force_frame=d.force_frame))
    return FromRelated(finish, other, scheme, f"from the {scheme} optimum", f"the {scheme} problem",
                       finish_budget=finish_budget)


def resolves(problem: Problem, other: Problem, fraction: float) -> bool:
    """Whether ``other`` -- the same maneuver on another grid or scheme -- is near enough ``problem`` for its optimum to
    start it: their free motions end at positions at most ``fraction`` * F T^2 / (2 m) apart, F the largest force the
    bound allows (what the controls can move the body by in T; without a bound: the displacement the maneuver needs,
    |x_d - x_N|, x_d of :func:`~transcription.ocp.estimate.target_estimate`); gaps at round-off (1e-9 of the position)
    always resolve.  Otherwise ``other``'s discrete motion differs from ``problem``'s by a good part of what the
    maneuver can change: it is another maneuver, whose optimum is no start (and which may have none)."""
    bound = problem.control.force_bound
    F = bound.largest_norm() if bound is not None else np.inf
    fine, coarse = starts.rollout(problem).X[-1], starts.rollout(other).X[-1]
    gap = float(np.linalg.norm(fine[X_POS] - coarse[X_POS]))
    reach = F * problem.T**2 / (2.0 * problem.model.mass) if np.isfinite(F) else \
        float(np.linalg.norm(target_estimate(problem)[X_POS] - fine[X_POS]))
    return gap <= fraction * reach or gap <= 1e-9 * max(float(np.linalg.norm(fine[X_POS])), 1.0)


def default_strategy(problem: Problem, options, reach: float = 0.5) -> Strategy:
    """The strategy of ``problem`` when none is given: its objective's; on the Kepler-split LGVI first from its
    optimum on the LGVI (:func:`from_scheme`) when the LGVI's discrete orbit :func:`resolves` this one (within
    ``reach`` of what the controls can change: the coarse grids' rule of the fuel strategy), then -- or only, when it
    does not -- the objective's own strategy on that scheme, unless the objective's own strategy reaches it otherwise
    (:meth:`~transcription.ocp.objective.Objective.via_lgvi`).  Measured (leo_body_engine, 1 N on 500 kg, reach 31 km):
    at N = 400 the LGVI's orbit ends 3.5 km off and its route reaches the better optimum; at N = 100 (56 km) and 40 its
    problem failed after 94 and 49 s where the own starts converge in 1.2 and 1.0 s."""
    strategy = problem.control.objective.strategy(problem, options)
    if problem.scheme != "lgvi_kepler" or not problem.control.objective.via_lgvi(problem):
        return strategy
    route = from_scheme(strategy)
    return FirstOf((route, strategy)) if resolves(problem, route.related(problem), reach) else strategy


def step_line(what: str, sol: Solution) -> str:
    """A continuation step's line: what was solved, how it ended, its iterations and (converged) its cost."""
    return f"{what}: {sol.result.value} in {sol.iterations} iterations" + (
        f", cost {sol.cost:.10g}" if sol.converged else "")


@dataclass(frozen=True)
class Continuation:
    """A path of problems solved in turn, each from the last converged one's solution: ``path(problem, history)``
    gives the next (phase, problem) from the history of ((problem, solution), ...) tried so far, failures included
    (None: the path is done), each solved by ``step``.  The path moves the parameter (a smoothing eps, the weights, the
    bounds, a sweep's axis) and is its own step-size controller: after a step that did not converge it may try a
    shorter one, or end.  The Solution is the last one tried, its attempt named ``label`` with every step's solves as
    its parts and ``stats['continuation_steps']`` one line per step; None when the path is empty."""

    path: Callable[[Problem, tuple], tuple[str, Problem] | None]
    step: Strategy
    label: str = "continuation"

    def run(self, problem: Problem, start: Start | None, ctx: Context) -> Solution | None:
        history, parts, lines, sol, warm = (), [], [], None, start
        while (nxt := self.path(problem, history)) is not None:
            phase, p = nxt
            sol = self.step.run(p, warm, ctx.under(phase))
            parts += sol.trace
            lines.append(step_line(phase, sol))
            history += ((p, sol),)
            if sol.converged and sol.warm is not None:
                warm = sol.warm
        if sol is None:
            return None
        last = replace(parts[-1], label=self.label).prepared(tuple(parts[:-1]), "the continuation")
        return replace(sol, trace=(last,)).with_notes(continuation_steps=lines)


__all__ = ["BestOf", "CoarseToFine", "Composed", "Context", "Continuation", "FirstOf", "FromRelated", "Guessed",
           "Solve", "Strategy", "Warm", "chosen", "collapsed", "default_strategy", "from_scheme", "labelled",
           "not_made", "resolves", "spread", "step_line", "tried"]
