"""The effort objective (the paper's, docs/mathematics.md §6): min sum_j omega_j (1/2) u_j^T W u_j,
W = blkdiag(W_f, W_m) symmetric positive definite -- its cost block of the direct method's NLP, its scales, and its
default strategy (:class:`EffortStrategy`).  The indirect method's conditions are the effort objective's own
(:mod:`transcription.methods.indirect`: the saturated control law of the costate)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial
from typing import ClassVar, Mapping

import casadi as ca
import numpy as np

from ..dynamics.lgvi import discretization, per_discretization
from ..geometry.state import NU, U_FORCE, X_ANG, X_ROT
from ..nlp.scaling import control_magnitudes, scaled_terminal_miss
from ..nlp.structured import Block, BlockFunction
from ..methods.indirect.laws import EffortLaw
from ..ocp import Objective, Problem, effort_cost, quadrature_weights
from ..ocp.actuators import NormBound
from ..ocp.estimate import moment_size
from ..outcome import Result
from ..results.solution import Solution
from ..results.start import Start
from ..strategy import starts
from ..strategy.saddle import Escape
from ..strategy.core import BestOf, Composed, Context, FirstOf, Guessed, Solve, Warm, chosen, labelled, not_made
from ..strategy.starts import aimed, class_name, cone_classes, implied_effort
from .peak import PeakForce, least_peak_force
from .time import bracketing_times


@per_discretization
def effort_node(disc, free_h: bool) -> BlockFunction:
    """The effort at one control node j: v = [u_j (6); h / h_scale (free_h)], p = [sU (6); omega_j / h; h (or
    h_scale); s_obj; vec W_f (9); vec W_m (9)]; cost omega_j (1/2)(u_f^T W_f u_f + u_m^T W_m u_m) / s_obj, no rows.
    (The LGVI's trapezoid: each node control at half the weight of the steps it joins.)"""
    v = ca.SX.sym("v", NU + (1 if free_h else 0))
    p = ca.SX.sym("p", NU + 3 + 18)
    u = v[:NU] * p[:NU]
    h = p[NU + 1] * v[NU] if free_h else p[NU + 1]
    W = ca.SX.zeros(NU, NU)
    W[0:3, 0:3] = ca.reshape(p[NU + 3:NU + 12], 3, 3)
    W[3:6, 3:6] = ca.reshape(p[NU + 12:NU + 21], 3, 3)
    cost = p[NU] * h * 0.5 * ca.bilin(W, u, u) / p[NU + 2]
    return BlockFunction(ca.Function(f"effort_node{'_freeh' if free_h else ''}", [v, p], [cost, ca.SX(0, 1)],
                                     ["v", "p"], ["cost", "rows"]))


@dataclass(frozen=True)
class Effort(Objective):
    """min sum_j omega_j (1/2)(u_f^T W_f u_f + u_m^T W_m u_m) (module docstring).

    ``balance``: the smallest ratio of the scaled control cost curvatures W_i s_i^2 the NLP's scales allow (the
    control scales are raised until every W_i s_i^2 >= balance max_j W_j s_j^2): with W_m = I the moment directions
    would otherwise carry a scaled Hessian of ~1e-8, IPOPT's inertia correction swamps them and the solve stalls at
    "Solved_To_Acceptable_Level" (measured, E3 N = 100); balanced it reaches Solve_Succeeded."""

    balance: float = 1e-2
    indirect: ClassVar = EffortLaw()
    fatrop: ClassVar[str] = ""
    name: ClassVar[str] = "effort"

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return effort_cost(U, problem.control, quadrature_weights(problem.scheme, problem.N, problem.steps_of(h)))

    def unit_weights(self, force: float, moment: float) -> tuple[np.ndarray, np.ndarray] | None:
        """I / force^2, I / moment^2: the effort of controls in units of their sizes."""
        return np.eye(3) / force**2, np.eye(3) / moment**2

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        Wdiag = np.diag(problem.control.W)
        cw = Wdiag * sU**2
        sU = sU * np.sqrt(np.maximum(1.0, self.balance * cw.max() / cw))
        return sU, 0.5 * problem.T * float(np.sum(Wdiag * sU**2))

    def blocks(self, tr) -> list:
        problem, sc, c = tr.problem, tr.scales, tr.problem.control
        data = tr.node_parameters(sc.U, np.r_[problem.h, sc.objective, c.W_f.ravel(order="F"), c.W_m.ravel(order="F")])
        fn = effort_node(problem.disc, tr.free_h)
        return [(Block("effort", fn, tr.node_variables(own=False), data), np.zeros(0))]

    def strategy(self, problem: Problem, options) -> "EffortStrategy":
        return EffortStrategy()


# ---------------------------------------------------------------------------- the default strategy
def relaxation(problem: Problem) -> Problem | None:
    """The problem without its control bounds (a removed control stays removed) and path constraints, whose solution
    starts the solve of the full one (None if there is nothing to relax).  The bounds stay as caps on the relaxed
    problem's control scales (``Problem.control_scales``): the boundary data's m L / T^2 can exceed them by far (a
    LEO orbit's: 600 times a 1 N engine), and the full problem's controls stay within them.  A body-fixed force (an
    engine) is relaxed to a force free to point anywhere in the inertial frame: the translation no longer depends on
    the attitude.  (Relaxed in the body frame and scaled by the orbit, the body's attitude and the force's direction
    trade at equal force effort -- a direction the effort does not see -- and IPOPT crept along it:
    leo_body_engine's relaxed solve took 55 iterations at 0.35 s each, against 10 now; docs/mathematics.md §7.)"""
    c = problem.control
    removed = c.removed
    bounds = [b for b, r in zip((c.force_bound, c.moment_bound), removed) if b is not None and not r]
    if not (bounds or problem.constraints):
        return None
    keep = [b if r else None for b, r in zip((c.force_bound, c.moment_bound), removed)]
    relaxed = problem.replace(control=replace(c, force_bound=keep[0], moment_bound=keep[1]), constraints=(),
                              control_scales=tuple(control_magnitudes(problem)))
    d = problem.disc
    if d.force_frame != "inertial" and not removed[0]:
        relaxed = relaxed.replace(disc=discretization(d.model, d.scheme, d.newton_iters, force_frame="inertial"))
    return relaxed


def judged_interpolation(problem: Problem) -> tuple[str, Start, str]:
    """The interpolated start of an effort problem: the path of the screw interpolation ('interpolate') or, around
    a central body, of the screw interpolation in the frame turning with the orbit ('orbit',
    :func:`~transcription.strategy.starts.orbit_interpolation`), judged before any solve by the effort its motion
    needs (:func:`~transcription.strategy.starts.implied_effort`), the translation and the rotation each on its own:
    the positions and momenta of the one whose force effort is lower, the attitudes and angular momenta of the one
    whose moment effort is lower (both meet both ends, so the parts fit).  Its label names what was taken
    ('orbit', 'interpolate', or 'orbit, attitude of interpolate'); the third part says the efforts.

    Why: over several revolutions the screw interpolation turns once at most, and the solver ends at a local minimum
    of its shape (the five-orbit phasing: cost 17.38 on a path out to r = 4.7 from it, 0.02868 from the orbit's); the
    attitude is judged apart because a body held inertially would turn a whole revolution with the orbit's frame
    (docs/everyday.md)."""
    judged = {}
    for kind in ("interpolate", "orbit"):
        start = starts.make(kind, problem)
        if start.finite:
            efforts = implied_effort(problem.disc, start.X, problem.steps, problem.control.W)
            judged[kind] = (start, tuple(e if np.isfinite(e) else np.inf for e in efforts))
    if not judged:       # not finite (a singular potential along the path): the strategy's solve says so
        return "interpolate", starts.interpolation(problem), ""
    path = min(judged, key=lambda k: judged[k][1][0])         # dict order: the screw interpolation on a tie
    turn = min(judged, key=lambda k: judged[k][1][1])
    X = judged[path][0].X.copy()
    X[:, X_ROT], X[:, X_ANG] = judged[turn][0].X[:, X_ROT], judged[turn][0].X[:, X_ANG]
    label = path if path == turn else f"{path}, attitude of {turn}"
    said = "; ".join(f"{k}: force {e[0]:.3g}, moment {e[1]:.3g}" for k, (_, e) in judged.items())
    return label, replace(judged[path][0], X=X), said


def ordered_starts(problem: Problem, rollout_first_miss: float) -> list[tuple[str, Start, dict | None]]:
    """The free motion and the judged interpolation (:func:`judged_interpolation`) as (label, Start, stats to report),
    the rollout first when it ends within ``rollout_first_miss`` characteristic scales of the target
    (:class:`EffortStrategy`)."""
    rollout = starts.rollout(problem)          # its final state decides the order
    label, interpolated, said = judged_interpolation(problem)
    order = [(label, interpolated, {"interpolation_efforts": said} if said else None), ("rollout", rollout, None)]
    if scaled_terminal_miss(problem, rollout.X[-1]) <= rollout_first_miss:
        order.reverse()
    return order


def first_start(problem: Problem) -> tuple[str, Start]:
    """The first start of the default effort strategy (:func:`ordered_starts`): (label, Start)."""
    label, start, _ = ordered_starts(problem, EffortStrategy().rollout_first_miss)[0]
    return label, start


@dataclass(frozen=True)
class RelaxedStart:
    """The solve from the solution of ``relaxed`` (the problem without its bounds and path constraints, solved by
    ``inner``): with a body-fixed engine the body turned to aim its force (:func:`~.starts.aimed`, ``aim_fraction``);
    within ``budget`` iterations (None: the solver's max_iter), IPOPT options ``ipopt``.  ``phase1``: its solve
    starts in IPOPT's restoration phase; one that ends locally infeasible ends the strategy (:meth:`ends`)."""

    inner: object
    relaxed: Problem
    budget: int | None
    ipopt: Mapping
    phase1: bool
    aim_fraction: float
    hull_budget: int = 200
    peak_rtol: float = 1e-6
    label: str = "the solution without bounds and path constraints"

    def run(self, problem: Problem, start: Start | None, ctx: Context):
        sub = self.inner.run(self.relaxed, None, ctx.under("relaxed"))
        if not sub.converged or sub.warm is None:
            return not_made(problem, ctx, self.label, "not available (the relaxed problem did not converge)",
                            sub.trace, "the relaxed problem")
        first, parts = sub.warm.primal(), sub.trace
        engine = problem.control.force_bound
        if engine is not None and engine.engine_axis is not None:
            hull, first = self.within_hull(engine, first, ctx)
            parts += hull.trace if hull is not None else ()
            if hull is not None and hull.result is Result.interrupted:
                return labelled(hull, self.label, sub.trace, "the relaxed problem")
            if hull is not None and hull.result is Result.infeasible:     # stats: the force it needs, for the CLI
                return not_made(problem, ctx, self.label, hull.verdict, parts, "the relaxed problem",
                                Result.infeasible).with_notes(least_peak_force=hull.stats["least_peak_force"])
            M = moment_size(problem)            # the body turns in at the angular acceleration M / lambda_max(J)
            alpha = None if M is None else M / np.linalg.eigvalsh(problem.disc.J)[-1]
            first = aimed(problem, first, engine.engine_axis, engine.engine_range, fraction=self.aim_fraction,
                          frame=self.relaxed.disc, alpha=alpha)
        budget = int(ctx.options.max_iter) if self.budget is None else min(int(ctx.options.max_iter), self.budget)
        sol = ctx.solve(problem, first, "from relaxed", ipopt=self.ipopt, max_iter=budget)
        return labelled(sol, self.label, parts, "the relaxed problem")

    def within_hull(self, engine, first: Start, ctx: Context) -> tuple[Solution | None, Start]:
        """Where the relaxed solution ``first`` asks more force than the engine's largest thrust F: first the least
        peak force of the relaxed problem (:class:`~transcription.objectives.peak.PeakForce`) from ``first``; where it
        exceeds F (by more than ``peak_rtol``) no attitude of the engine can give the force the maneuver needs, and
        the problem is reported infeasible (a Solution whose result says so, ``stats['least_peak_force']`` the force;
        :meth:`ends`).  Else the relaxed problem
        with |f| <= F (a gimballed engine: the convex hull of the forces the engine gives, pointing anywhere) from the
        least peak force's optimum (within the bound: a feasible start) -- or, where that solve did not converge, from
        ``first`` with its force clipped to the ball -- (:class:`~transcription.strategy.core.Warm`), each within
        ``hull_budget`` iterations: (the hull's Solution, its optimum -- or ``first`` as it was if it did not converge:
        the aimed start then clips it).  (None, ``first``) where nothing exceeds F, or with a ``hull_budget`` of 0.
        A free final time asks no least peak force (it falls as T grows): the hull is solved from the clipped start.
        Why: the aimed start clips the thrust to the engine's range; where the relaxed optimum asks more (a raise
        with a phase to meet, its peak 1.4 F) the clipped start misses its target by far and the engine's solve
        from it stalled; where no thrust within F can do it, nothing said so in 8 minutes of solving
        (docs/mathematics.md §14, *Within the engine's thrust*)."""
        F = engine.engine_range[1]
        f = first.U[U_FORCE]
        size = np.linalg.norm(f, axis=0)
        if not size.max(initial=0.0) > F or self.hull_budget <= 0:
            return None, first
        budget = ctx.using(max_iter=min(int(ctx.options.max_iter), self.hull_budget))
        c = self.relaxed.control
        least = None if self.relaxed.free_time else \
            Warm("the least peak force").run(self.relaxed.replace(control=replace(c, objective=PeakForce())), first,
                                             budget)
        if least is not None and least.result is Result.interrupted:
            return least, first
        if least is not None and least.converged and least.warm is not None:
            need = least_peak_force(least.controls)
            if need > F * (1.0 + self.peak_rtol):
                why = (f"the maneuver needs a force of at least {need:.6g} at its peak even pointing anywhere (the "
                       f"least peak force of the problem without the engine's attitude), more than the engine's "
                       f"largest thrust {F:.6g}: no attitude of the engine can give it (a thrust above {need:.4g} or a "
                       f"longer horizon is needed)")
                return replace(least, result=Result.infeasible, verdict=why).with_notes(least_peak_force=need), first
            start = least.warm.primal()
        else:
            U = first.U.copy()
            U[U_FORCE] = f * np.minimum(1.0, F / np.where(size > 0, size, 1.0))
            start = replace(first, U=U)
        within = self.relaxed.replace(control=replace(c, force_bound=NormBound(F)))
        sol = Warm("within the engine's thrust").run(within, start, budget)
        sol = labelled(sol, "within the engine's thrust", least.trace if least is not None else (),
                       "the least peak force")
        return sol, (sol.warm.primal() if sol.converged and sol.warm is not None else first)

    def ends(self, sol) -> bool:
        """The problem was found infeasible: by the phase 1 (``phase1``), or before any solve of it (its attempt not
        run: the least peak force exceeds the engine's thrust, :meth:`within_hull`)."""
        return sol.result is Result.infeasible and (self.phase1 or (bool(sol.trace) and sol.trace[0].result is None))


@dataclass(frozen=True)
class EffortStrategy(Composed):
    """The effort objective's default (``initial_guess: auto``): with bounds or path constraints, first the start
    from the relaxed problem's solution (:class:`RelaxedStart`); then the free motion (rollout) and the judged
    interpolation (:func:`judged_interpolation`) in the order ``rollout_first_miss`` decides, the first of them
    within ``first_budget`` iterations; the first that converges is kept.

    ``first_budget``: the first starts get at most this many NLP iterations before the next one is tried (a solve
    that needs more is usually wandering).  ``rollout_first_miss``: the rollout goes first when it ends within this
    many characteristic scales of the target (:func:`~transcription.nlp.scaling.scaled_terminal_miss`), else the
    interpolation: a free motion that misses by far is a poor start, and a near one a good one (the interpolation's
    defects, spread over every step, cost iterations that grow with N; docs/everyday.md).

    ``infeasibility_detection``: IPOPT options of a problem with bounds or path constraints (the restoration phase
    called sooner) ...  ``phase1``: ... and, with a control bound, the start from the relaxation's solution in IPOPT's
    restoration phase, which minimizes the violation the relaxed optimum leaves; if that ends at a least violation > 0
    (Infeasible_Problem_Detected) the problem is reported infeasible and the other starts are not tried (E3 with the
    thrust bounded by 10, N = 500: infeasible in 54 iterations, against 200 + 3000 + 3000 without either option).
    Neither for a body-fixed engine, whose start is the aimed relaxed solution, within the solver's whole max_iter:
    the free motion and the interpolation know nothing of the engine (a raise with a 3 N engine: converged from the
    aimed start in 240 iterations, failed from it at 200 and then from the others after 3404).  ``aim_fraction``:
    the engine's aimed start (:func:`~.starts.aimed`) turns the body fully where |f_j| >= this fraction of max_j
    |f_j|.  ``hull_budget``: where the relaxed solution asks more force than the engine's largest thrust, the
    iterations of its solve within that thrust (:meth:`RelaxedStart.within_hull`; 0: not solved, the relaxed solution
    aimed and clipped as it is).  ``escape``: the fields of the :class:`~transcription.strategy.saddle.Escape` that
    checks each start's solve for a saddle of the NLP (docs/mathematics.md §10) before the next start is tried.

    With keep-out or keep-in cones in the way of the straight path (within ``cone_reach_deg``), one such strategy
    per homotopy class of the path round them (:func:`~transcription.strategy.starts.cone_classes`, at most
    ``max_classes``): each first tries the interpolation routed through a waypoint ``cone_clearance_deg`` outside each
    cone on the side the class says (``sides``; :func:`~transcription.strategy.starts.detour`), within
    ``first_budget``, then the starts above; the lowest cost is kept, the classes named in the message and in
    ``stats['homotopy_classes']``.  Why: every start above crosses the cones, and the solver pushes the path out on
    whichever side it meets first -- not always the cheaper (configs/slew_keep_out_effort.yaml: the near side
    0.0012423, the far side 0.0012091).

    With a free final time and ``bracket_times``, all this from the guess T and from the times that bracket it
    (:func:`~transcription.objectives.time.bracketing_times`, the geometric means of T and each bound), the lowest
    cost kept, each named in the message and in ``stats['time_guesses']``.  Why: the effort has a local minimum in T
    for each way of phasing (configs/rendezvous_free_time.yaml: 0.182268 at T = 0.697 from the guess 0.8, 0.163349
    at T = 1.302 from 1.1)."""

    first_budget: int = 200
    rollout_first_miss: float = 1.0
    infeasibility_detection: Mapping = field(default_factory=lambda: {"expect_infeasible_problem": "yes"})
    phase1: Mapping = field(default_factory=lambda: {"start_with_resto": "yes"})
    aim_fraction: float = 0.1
    hull_budget: int = 200
    escape: Mapping = field(default_factory=dict)
    not_tried: str = ("not tried (the start from the relaxed optimum found the problem infeasible: its phase 1 ended "
                      "at a least violation > 0, or the least peak force exceeds the engine's thrust; "
                      "solver.direct.initial_guess=rollout or interpolate tries this start)")
    cone_reach_deg: float = 10.0
    cone_clearance_deg: float = 5.0
    max_classes: int = 4
    sides: tuple = ()
    bracket_times: bool = True

    def compose(self, problem: Problem, options, start: Start | None = None):
        if start is not None:
            return Escape(Warm(), **self.escape)
        if (one := chosen(problem, options)) is not None:
            return Escape(one, **self.escape)
        if problem.free_time and self.bracket_times:
            times = (problem.T, *bracketing_times(problem))
            return BestOf(tuple(Guessed(replace(self, bracket_times=False), T) for T in times),
                          names=tuple(f"T guess {T:.6g}" for T in times), stat="time_guesses")
        if not self.sides and (classes := cone_classes(problem, self.cone_reach_deg, self.max_classes)):
            return BestOf(tuple(replace(self, sides=c) for c in classes),
                          names=tuple(class_name(problem, c) for c in classes), stat="homotopy_classes")
        relaxed = relaxation(problem)
        c = problem.control
        engine = c.force_bound is not None and c.force_bound.engine_axis is not None
        extra = {} if relaxed is None or engine else dict(self.infeasibility_detection)
        bounded = any(b is not None and not r for b, r in zip((c.force_bound, c.moment_bound), c.removed))
        entries = []
        if relaxed is not None:
            phase1 = bounded and not engine
            entries.append(RelaxedStart(replace(self, sides=()), relaxed, None if engine else self.first_budget,
                                        {**extra, **(self.phase1 if phase1 else {})}, phase1, self.aim_fraction,
                                        self.hull_budget))
        (l0, s0, st0), (l1, s1, st1) = ordered_starts(problem, self.rollout_first_miss)
        entries += [Solve(partial(_given, s0), l0, self.first_budget, extra or None, st0),
                    Solve(partial(_given, s1), l1, None, extra or None, st1)]
        if self.sides:
            routed = partial(starts.detour, sides=dict(self.sides), clearance=np.radians(self.cone_clearance_deg))
            entries.insert(0, Solve(routed, f"interpolate round {class_name(problem, self.sides)}", self.first_budget,
                                    extra or None))
        return FirstOf(tuple(Escape(e, **self.escape) for e in entries), self.not_tried)


def _given(start: Start, problem: Problem) -> Start:
    """``start`` (made before the strategy ran), whatever the problem."""
    return start


__all__ = ["Effort", "EffortStrategy", "RelaxedStart", "effort_node", "first_start", "judged_interpolation",
           "ordered_starts", "relaxation"]
