"""The direct method's initial guesses: which to try, in which order, with which iteration budget, and what to
try next after a failure (``initial_guess``, :class:`~transcription.options.DirectOptions`).

A plan is a list of (label, maker, budget): the maker makes the :class:`~transcription.strategy.starts.Guess` when its
turn comes (None when it cannot), the budget bounds the NLP iterations from it.  Guesses that are solutions of
another problem -- the problem without its bounds and path constraints, the time objective's starts on a
coarser grid -- are solved by ``subsolve`` (the direct method itself, passed in: this module does not
import the solve); a :class:`~..base.Reporting` subsolve reports their iterations under 'relaxed' and
'coarse N=25' (:func:`~..base.under`).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from .starts import (Guess, aimed_guess, cayley_vectors, implied_effort, make_guess, perturbed_interpolation_guess, target_estimate, warm_guess)
from ..geometry.state import U_FORCE, U_MOMENT, X_ANG, X_POS, X_ROT
from ..options import DirectOptions
from ..ocp import BoxBound, NormBound, Problem, ThrusterBound
from ..outcome import Result
from ..results.solution import Solution
from ..methods.base import under
from .fuel_continuation import counted_unbounded, fuel_start
from .homotopy import FUEL_COARSE_FACTOR, FUEL_COARSE_MIN
from ..nlp.scaling import scaled_terminal_miss

#: one entry of a plan: (label, maker of the guess (None: not available), NLP iteration budget)
PlanEntry = tuple[str, Callable[[], "Guess | None"], int]
#: the direct solve of another problem (a coarser grid, the relaxed problem) with the same options
SubSolve = Callable[[Problem, DirectOptions], Solution]

#: with initial_guess 'auto', the first guess of an effort problem (see ROLLOUT_FIRST_MISS; the relaxed
#: problem's solution when there are bounds or path constraints) gets at most this many NLP iterations
#: before the next one is tried: a solve that needs more is usually wandering.
AUTO_FIRST_BUDGET = 200
#: ... and which of the free motion (rollout) and the screw interpolation goes first: the rollout when it
#: ends within this many characteristic scales of the target (:func:`scaled_terminal_miss`, the terminal
#: rows as the solver sees them), else the interpolation.  A free motion that misses by far is a poor
#: start: doubling the orbit radius in one period (configs/everyday/orbit_double.yaml, miss 3.1) takes
#: > 1100 iterations from the rollout, 5 from the interpolation; the capture from a fast tumble
#: (capture_fast_tumble.yaml, 1.9) 185 to a local minimum of cost 97.0 against 10 to 32.7.  A near one is a
#: good start, and the interpolation's defects, spread over every step, cost iterations that grow with N:
#: E3 (0.52) 6 iterations from the rollout at N = 250, 1000 and 4000 against 7, 8 and 11 from the
#: interpolation; the 45 deg plane change (0.79) 9 against 12, the detumble (0.93) 6 against 8; E4 (0.78)
#: is the exception, 7-8 against 6.  Misses of the everyday cases: 0.30 ... 3.1 (docs/everyday.md).
ROLLOUT_FIRST_MISS = 1.0
#: ... and for the fuel objective's free-motion and interpolation starts (beside the homotopy of :mod:`.homotopy`),
#: whose bang-off-bang solutions take IPOPT long from those starts (configs/orbit_raise_fuel.yaml, N = 100: the
#: rollout reached max_iterations in 600 iterations, the interpolation converged in 420 more to 0.8195953)
AUTO_FIRST_BUDGET_FUEL = 600
#: with initial_guess 'auto' and the time objective, this many symmetry-breaking starts are solved and
#: the fastest converged maneuver kept: time-optimal slews have several local minima (the asymmetric
#: slew of configs/slew_time_optimal.yaml: 28.63 s and 29.41 s, the first-order scheme at N = 100
#: reaching the latter from seed 0)
TIME_STARTS = 3
#: with initial_guess 'auto' and the time objective, the starts are solved on a coarser grid of
#: max(TIME_COARSE_MIN, N // 4) steps (recursively: that solve does the same), the best converged
#: maneuver is resampled to N steps and finished there; the fine-grid starts remain the fallback.
#: Each start costs a quarter (or less) of a fine one and the finish takes few iterations.
TIME_COARSE_MIN = 25


#: IPOPT options of an effort problem with bounds or path constraints (those with a :func:`relaxation`), unless
#: the raw options set them: IPOPT's heuristics for a problem expected to be infeasible (the restoration phase
#: called sooner, more reduction of the violation before leaving it; off once the violation is below 1e-3) ...
INFEASIBILITY_DETECTION = {"expect_infeasible_problem": "yes"}
#: ... and for the start from the relaxation's solution a phase 1: IPOPT starts in its restoration phase, which
#: minimizes the violation of the bounds and constraints the relaxed optimum breaks.  If that ends at a least
#: violation > 0 (Infeasible_Problem_Detected) the problem is reported infeasible and the other starts are not
#: tried (NOT_TRIED).  E3 with the thrust norm bounded by 10 instead of 12 (configs/e3_bounded.yaml, no solution),
#: N = 500: infeasible in 54 iterations from the relaxed optimum, where without the phase 1 IPOPT spent its 200
#: there, then 69 (rollout) and 79 (interpolation) more to Infeasible_Problem_Detected, and without either
#: option 200 + 3000 + 3000 iterations (> 900 s on the loaded machine).  The price on feasible problems: the
#: bounded E3 (N = 500) 57 iterations instead of 43 to the same solution.  Only with a control bound: with path
#: constraints alone it cost the keep-out slew 42 iterations instead of 14 and E3 with a minimum radius 34
#: instead of 26.  Not for the time and fuel objectives (no relaxation):
#: expect_infeasible_problem took the fuel raise (N = 100) to another local minimum (0.819710 against 0.819595).
PHASE1 = {"start_with_resto": "yes"}
#: Guess.prepared_on of the relaxation's solution
RELAXED = "the relaxed problem"
#: Guess.prepared_on of a start solved on a coarser grid (:func:`coarse_guess`)
COARSE = "the coarse grid"
#: Guess.prepared_on of a fuel warm start from a grid that resolves the problem's switching times (a previous level
#: of refinement to an accuracy: .fuel_structure.resolves), finished on its own burn nodes
RESOLVED = "a grid resolving the switching times"
#: the note of the starts not tried after the phase 1 found the problem infeasible
NOT_TRIED = ("not tried (the phase 1 from the relaxed optimum ended at a least violation > 0: locally infeasible; "
             "solver.direct.initial_guess=rollout or interpolate tries this start)")


def plan_ipopt_options(problem: Problem, phase1: bool = False) -> dict:
    """IPOPT options the plan adds for ``problem`` (:data:`INFEASIBILITY_DETECTION`; ``phase1``, the start from
    the relaxation's solution: :data:`PHASE1` too)."""
    c = problem.control
    if relaxation(problem) is None or isinstance(c.force_bound, ThrusterBound):
        return {}     # a body-fixed engine (issue 24) starts from the aimed relaxed solution: not measured with these
    bounded = any(b is not None and not r for b, r in zip((c.force_bound, c.moment_bound), c.removed))
    return {**INFEASIBILITY_DETECTION, **(PHASE1 if phase1 and bounded else {})}


def guess_plan(problem: Problem, options: DirectOptions, subsolve: SubSolve) -> tuple[list[PlanEntry], str]:
    """The initial guesses to try, as (label, maker, iteration budget), and how to pick the result:
    'first' (the first that converges), 'best' (the lowest cost of those that converge) or 'coarse'
    (the time objective: the first entry, the starts solved on a coarser grid and finished on this one,
    is kept if it converges, else the best of the fine-grid starts that follow); the
    ``initial_guess`` option (see :class:`~transcription.options.DirectOptions`)."""
    disc, X0, N, T = problem.disc, problem.X0, problem.N, problem.T

    def made(kind):
        return lambda: make_guess(kind, disc, X0, target_estimate(problem), N, T, problem.fractions)

    if options.initial_guess != "auto":
        return [(options.initial_guess, made(options.initial_guess), options.max_iter)], "first"
    if problem.control.objective == "time":
        return _time_plan(problem, options, subsolve)
    if problem.control.objective == "fuel":
        return _fuel_plan(problem, options, subsolve, made)
    rollout = made("rollout")()           # its final state decides the order (ROLLOUT_FIRST_MISS)
    label, interpolated = judged_interpolation(problem)
    order = [(label, lambda: interpolated), ("rollout", lambda: rollout)]
    if scaled_terminal_miss(problem, rollout.X[-1]) <= ROLLOUT_FIRST_MISS:
        order.reverse()
    plan = [(*order[0], min(options.max_iter, AUTO_FIRST_BUDGET)), (*order[1], options.max_iter)]
    relaxed = relaxation(problem)
    if relaxed is not None:
        plan.insert(0, ("the solution without bounds and path constraints",
                        lambda: relaxed_guess(problem, relaxed, options, subsolve),
                        min(options.max_iter, AUTO_FIRST_BUDGET)))
    return plan, "first"


def judged_interpolation(problem: Problem) -> tuple[str, Guess]:
    """The interpolated start of an effort problem: the path of the screw interpolation ('interpolate') or, around
    a central body, of the screw interpolation in the frame turning with the orbit ('orbit',
    :func:`~transcription.strategy.starts.orbit_interpolation_guess`), judged before any solve by the effort its motion
    needs (:func:`~transcription.strategy.starts.implied_effort`), the translation and the rotation each on its own: the
    positions and momenta of the one whose force effort is lower, the attitudes and angular momenta of the one
    whose moment effort is lower (both meet both ends, so the parts fit).  Its label names what was taken
    ('orbit', 'interpolate', or 'orbit, attitude of interpolate'), ``stats['interpolation_efforts']`` the efforts.

    Why: over several revolutions the screw interpolation turns once at most, and the solver ends at a local
    minimum of its shape -- the five-orbit phasing (configs/everyday/phasing_5_orbits.yaml, N = 1000) solved to
    cost 17.38 on a path out to r = 4.7 (120 iterations) from it, to 0.02868 near r = 1 (9) from the orbit's; the
    three-orbit raise 47.5 out to r = 3.5 against 0.295 (22 each).  The attitude is judged apart because a body
    held inertially (the LEO raise and slew, rest to rest) would turn a whole revolution with the orbit's frame:
    from that start the LEO raise ended at twice the cost (0.00225 against 0.001125).  Where the screw path is
    the cheaper (E3, E4, the plane changes, the captures) nothing changes."""
    disc, X0, N, T = problem.disc, problem.X0, problem.N, problem.T
    Xd = target_estimate(problem)
    judged = {}
    for kind in ("interpolate", "orbit"):
        guess = make_guess(kind, disc, X0, Xd, N, T, problem.fractions)
        if guess is not None and all(np.all(np.isfinite(a)) for a in (guess.X, guess.U, guess.C)):
            efforts = implied_effort(disc, guess.X, problem.steps, problem.control.W)
            judged[kind] = (guess, tuple(e if np.isfinite(e) else np.inf for e in efforts))
    if not judged:       # not finite (a singular potential along the path): the plan's run says so
        return "interpolate", make_guess("interpolate", disc, X0, Xd, N, T, problem.fractions)
    path = min(judged, key=lambda k: judged[k][1][0])         # dict order: the screw interpolation on a tie
    turn = min(judged, key=lambda k: judged[k][1][1])
    X = judged[path][0].X.copy()
    X[:, X_ROT], X[:, X_ANG] = judged[turn][0].X[:, X_ROT], judged[turn][0].X[:, X_ANG]
    said = "; ".join(f"{k}: force {e[0]:.3g}, moment {e[1]:.3g}" for k, (_, e) in judged.items())
    label = path if path == turn else f"{path}, attitude of {turn}"
    return label, Guess(X=X, U=judged[path][0].U, C=cayley_vectors(X), stats={"interpolation_efforts": said})


def _time_plan(problem: Problem, options: DirectOptions, subsolve: SubSolve) -> tuple[list[PlanEntry], str]:
    """The time objective: TIME_STARTS symmetry-breaking starts, solved on a coarser grid first when there is
    one (TIME_COARSE_MIN)."""
    disc, X0, N, T = problem.disc, problem.X0, problem.N, problem.T
    size = np.zeros(6)
    for sl, bound in ((U_FORCE, problem.control.force_bound), (U_MOMENT, problem.control.moment_bound)):
        size[sl] = bound.b if isinstance(bound, BoxBound) else bound.max if isinstance(bound, ThrusterBound) else \
            bound.b / np.sqrt(3.0)      # an engine's random force is projected onto its axis (initial_point)

    def start(Ts: float, k: int):
        return lambda: replace(perturbed_interpolation_guess(disc, X0, target_estimate(problem), N, Ts, size, seed=k,
                                                             s=problem.fractions), h=Ts / N)

    starts = [(f"interpolate with symmetry-breaking controls (seed {k})", start(T, k), options.max_iter)
              for k in range(TIME_STARTS)]
    Nc = max(TIME_COARSE_MIN, N // 4)
    if Nc < N:
        return [(f"the best start on {Nc} steps, resampled",
                 lambda: coarse_guess(problem, options, Nc, subsolve), options.max_iter)] + starts, "coarse"
    return starts + [(f"interpolate over T = {Ts:.6g} with symmetry-breaking controls (seed 0)", start(Ts, 0),
                      options.max_iter) for Ts in bracketing_times(problem)], "best"


def _fuel_plan(problem: Problem, options: DirectOptions, subsolve: SubSolve, made) -> tuple[list[PlanEntry], str]:
    """The fuel objective (:mod:`.homotopy`): on a grid of more than FUEL_COARSE_MIN steps the best start on
    max(FUEL_COARSE_MIN, N // 4) steps, resampled and finished here ('coarse': the free motion and the
    screw interpolation on this grid are the fallback); on the coarsest grid the multistart: the homotopy from the
    effort optimum, the free motion and the screw interpolation, the lowest converged cost kept ('best')."""
    N, budget = problem.N, min(options.max_iter, AUTO_FIRST_BUDGET_FUEL)
    Nc = max(FUEL_COARSE_MIN, N // FUEL_COARSE_FACTOR)
    if Nc < N and coarse_resolves(problem, Nc):
        return [(f"the best start on {Nc} steps, resampled", lambda: coarse_guess(problem, options, Nc, subsolve),
                 options.max_iter), ("rollout", made("rollout"), budget),
                ("interpolate", made("interpolate"), options.max_iter)], "coarse"
    # the coarsest grid, or a coarser grid that is another maneuver (coarse_resolves): the same starts, the lowest
    # converged cost kept on the coarsest grid, the first that converges otherwise
    # (with an unbounded counted part, the homotopy of a bounded problem continued to this one where the references
    # differ by more than EFFORT_LEVEL_RATIO: .fuel_continuation)
    label = "the fuel homotopy from the effort optimum" + (
        " (or its continuation from a bounded problem)" if counted_unbounded(problem).any() else "")
    return [(label, lambda: fuel_start(problem, options, subsolve, relaxation), options.max_iter),
            ("rollout", made("rollout"), budget), ("interpolate", made("interpolate"), budget)], \
        "first" if Nc < N else "best"


#: a coarser grid starts the fuel plan only when its free motion ends within this fraction of the force's reach
#: (:func:`coarse_resolves`) of the free motion on the problem's own grid
COARSE_REACH_FRACTION = 0.5


def coarse_resolves(problem: Problem, Nc: int) -> bool:
    """Whether the maneuver on Nc uniform steps is near enough the one on ``problem``'s grid for its optimum to
    start the fuel solve: the two grids' free motions (:func:`~transcription.strategy.starts.make_guess` 'rollout') end at
    positions at most COARSE_REACH_FRACTION * F T^2 / (2 m) apart, F the largest force the bound allows (without
    a bound: the displacement the maneuver needs, below).  Why: around the Earth a one-revolution LEO raise with a
    1 N engine on 500 kg
    (configs/leo_body_engine.yaml, N = 400) can move the body by F T^2 / (2 m) = 31 km in T, while the discrete
    orbit of 100 steps ends 53 km from that of 400 steps: the coarse problems are infeasible
    (their effort version at N = 100 ended cayley_failed after 3467 iterations) and each cost minutes before the
    fine grid was tried.  For the fuel raise the gap is 0.0044 against a reach of 9.8.  Without a force bound the
    reach is the displacement the maneuver needs, the fine free motion's miss |x_d - x_N^(N)| (x_d of
    :func:`~transcription.strategy.starts.target_estimate`): leo_raise_slew.yaml (the same orbit, no bound) has a gap of
    53 km against a miss of 47 km on 100 steps, and its 25-step problem needed 20 kN of thrust where the 400-step
    one needs 0.6 N (docs/mathematics.md, "LEO fuel raises"); gaps at round-off (1e-9 of the position) always
    resolve, so a maneuver the free motion already completes keeps its coarse grids."""
    bound = problem.control.force_bound
    F = bound.max if isinstance(bound, ThrusterBound) else bound.largest_norm() if bound is not None else np.inf
    Xd, T = target_estimate(problem), problem.T
    fine = make_guess("rollout", problem.disc, problem.X0, Xd, problem.N, T, problem.fractions).X[-1]
    coarse = make_guess("rollout", problem.disc, problem.X0, Xd, Nc, T).X[-1]
    gap = float(np.linalg.norm(fine[X_POS] - coarse[X_POS]))
    reach = F * T**2 / (2.0 * problem.model.mass) if np.isfinite(F) else float(np.linalg.norm(Xd[X_POS] - fine[X_POS]))
    return gap <= COARSE_REACH_FRACTION * reach or gap <= 1e-9 * max(float(np.linalg.norm(fine[X_POS])), 1.0)


def bracketing_times(problem: Problem) -> list[float]:
    """The final times of the starts that bracket the guess T on the coarsest grid: the geometric means of T and
    each of the time bounds (those not equal to T).  Why: a time-optimal maneuver's local minima differ in
    their time, and the starts at the guess alone may all fall into the one nearest to it."""
    lo, hi = problem.time_bounds
    T = problem.T
    return [float(np.sqrt(T * b)) for b in (lo, hi) if not np.isclose(b, T, rtol=1e-9, atol=0.0)]


def coarse_guess(problem: Problem, options: DirectOptions, Nc: int, subsolve: SubSolve) -> Guess | None:
    """The time (or fuel) objective's starts solved on Nc = max(TIME_COARSE_MIN (FUEL_COARSE_MIN), N // 4) steps
    (recursively), the best resampled to N steps (:meth:`~transcription.results.start.WarmStart.fit`) with its step size T / N (None if
    the coarse solve did not converge)."""
    sol = under(subsolve, f"coarse N={Nc}")(problem.replace(N=Nc, mesh=None), options)  # a mesh's: on uniform steps
    if not sol.converged or sol.warm is None:
        return None
    fitted, _ = sol.warm.fit(problem.N, problem.scheme, problem.fractions)
    said = {k: v for k, v in sol.stats.items() if k.startswith(("multistart", "homotopy"))}
    return replace(warm_guess(fitted), iterations=sol.iterations, seconds=sol.build_s + sol.solve_s, prepared_on=COARSE,
                   stats=said)


def relaxation(problem: Problem) -> Problem | None:
    """The effort problem without its control bounds (a removed control stays removed) and path
    constraints, whose solution starts the solve of the full one (None if there is nothing to relax or
    the objective needs its bounds).  The bounded E3 (configs/e3_bounded.yaml): 6 + 37 iterations, 2.4 s,
    against 200 from the rollout then 37 from the interpolation, 12 s; the keep-out slew 5 + 11
    against 200 + 12."""
    c = problem.control
    removed = c.removed
    bounds = [b for b, r in zip((c.force_bound, c.moment_bound), removed) if b is not None and not r]
    if c.objective != "effort" or not (bounds or problem.constraints):
        return None
    keep = [b if r else None for b, r in zip((c.force_bound, c.moment_bound), removed)]
    return problem.replace(control=replace(c, force_bound=keep[0], moment_bound=keep[1]), constraints=())


def relaxed_guess(problem: Problem, relaxed: Problem, options: DirectOptions, subsolve: SubSolve) -> Guess | None:
    """The Guess of :func:`relaxation`'s solution (None if it did not converge), with its iterations and time;
    for a body-fixed engine the body turned to aim the relaxed solution's force (:func:`aimed_guess`)."""
    sol = under(subsolve, "relaxed")(relaxed, options)
    if not sol.converged or sol.warm is None:
        return None
    guess = replace(warm_guess(sol.warm), iterations=sol.iterations, seconds=sol.build_s + sol.solve_s,
                    prepared_on=RELAXED, h=None)
    engine = problem.control.force_bound
    if isinstance(engine, ThrusterBound):
        guess = aimed_guess(problem.disc, guess, engine.axis, (engine.min, engine.max), problem.steps_of(problem.h))
    return guess


def failure_hint(sol: Solution, options: DirectOptions) -> str:
    """What to try next after a direct solve of a smooth problem that did not converge ('' if it did, was
    interrupted, or its message already says what to change): the settings a user can change with
    ``--set``, in the order most likely to help.  Why: a failure that only names IPOPT's status leaves the
    user to guess that another initial guess, more iterations or an easier neighbouring maneuver (reached
    by continuation) would do."""
    r = sol.result
    if sol.converged or r in (Result.interrupted, Result.cayley_failed, Result.invalid_option, Result.non_finite):
        return ""
    tips = []
    binding = binding_bound(sol)
    if binding and r in (Result.infeasible, Result.max_iterations, Result.acceptable, Result.time_limit,
                                          Result.solver_failed):
        tips.append(binding)
    if r is Result.acceptable:
        tips.append("a looser solver.direct.tol (IPOPT stalled at its 'acceptable' level above it) or "
                    "solver.direct.options.acceptable_iter=0 (keep iterating)")
    if options.initial_guess != "auto":
        tips.append("solver.direct.initial_guess=auto (the screw interpolation and the free motion in turn)")
    elif r is Result.max_iterations:
        tips.append(budget_tip(sol, options))
    tips.append("an easier neighbouring maneuver (longer horizon.T, smaller change) reached by continuation: a sweep "
                "along the changed key with continuation (configs/sweeps/)")
    return "try " + "; or ".join(tips)


def budget_tip(sol: Solution, options: DirectOptions) -> str:
    """The iteration tip of a solve that ended at its iteration limit, with the budgets its attempts actually ran on
    (an attempt that reached max_iterations spent its budget: its iterations less those spent making its guess).
    Why: the plan caps its first starts (AUTO_FIRST_BUDGET, AUTO_FIRST_BUDGET_FUEL) below max_iter, and "a larger
    max_iter (now 3000)" after attempts that stopped at 600 promises what raising max_iter does not give them."""
    spent = [a.iterations - a.guess_iterations for a in sol.attempts if a.result is Result.max_iterations]
    capped = sorted({b for b in spent if b < options.max_iter})
    now = f"a larger solver.direct.max_iter (now {options.max_iter})"
    if not capped:
        return now
    return (f"{now} for the starts it bounds: the starts that reached their limit ran on "
            f"{' and '.join(map(str, spent))} iterations ({' and '.join(map(str, capped))}: the plan's cap on its first "
            "starts, which max_iter does not raise; solver.direct.initial_guess=rollout or interpolate gives one start "
            "the whole max_iter)")


#: a bound binds a failed solve when at least this fraction of the control nodes of its last iterate is at it
BINDING_FRACTION = 0.1


def binding_bound(sol: Solution) -> str:
    """The control bound that binds the last iterate of a failed solve, in words ('' if none does): the one with
    the largest fraction of control nodes at it (within AT_BOUND_RTOL, :meth:`NormBound.active`), at least
    BINDING_FRACTION, with its value and the key to change.  Why: a solve that ends infeasible or at its
    iteration limit with the controls pinned to a bound is usually asking more than that bound gives in the
    horizon, and naming the bound says what to change."""
    if sol.controls is None or sol.problem is None or sol.problem.kind != "smooth":
        return ""
    c, U = sol.problem.control, np.asarray(sol.controls, float)
    best = None
    for name, sl, bound in (("force", U_FORCE, c.force_bound), ("moment", U_MOMENT, c.moment_bound)):
        if not hasattr(bound, "active") or (isinstance(bound, NormBound) and bound.b == 0):
            continue
        at = float(np.mean(bound.active(U[sl].T)))
        if at >= BINDING_FRACTION and (best is None or at > best[0]):
            best = (at, name, bound)
    if best is None:
        return ""
    at, name, bound = best
    sym = "u_f" if name == "force" else "u_m"
    what = (f"|{sym}| <= {bound.b:.6g}" if isinstance(bound, NormBound) else
            f"|{sym},i| <= [{', '.join(f'{b:.6g}' for b in bound.b)}]" if isinstance(bound, BoxBound) else
            f"(engine thrust <= {bound.max:.6g})" if isinstance(bound, ThrusterBound) else "")
    return (f"the {name} bound {what} binds ({at:.0%} of the control nodes of the last iterate are at it): a larger "
            f"control.bounds.{name} or a longer horizon.T")


#: converged starts whose costs differ by at most this (relative) count as one optimum
SAME_OPTIMUM_RTOL = 1e-6


def multistart(attempts, N: int) -> dict:
    """The spread of the starts of a multistart ('best' pick: every start solved on this grid of N steps), as
    Solution stats: ``multistart_starts`` (converged starts), ``multistart_optima`` (distinct optima, costs
    within SAME_OPTIMUM_RTOL of one another counted once), ``multistart_spread`` = (max - min) / min of their
    costs, ``multistart_grid`` = N, and ``multistart`` (the sentence of the message); {} with fewer than two."""
    costs = sorted(a.cost for a in attempts if a.result is not None and a.result.successful and np.isfinite(a.cost))
    if len(costs) < 2:
        return {}
    optima = [costs[0]]
    for c in costs[1:]:
        if c - optima[-1] > SAME_OPTIMUM_RTOL * abs(optima[-1]):
            optima.append(c)
    spread = (costs[-1] - costs[0]) / max(abs(costs[0]), 1e-300)
    said = (f"the {len(costs)} starts on {N} steps ended at the same optimum (spread {spread:.1e})" if len(optima) == 1
            else f"the {len(costs)} starts on {N} steps ended at {len(optima)} different optima (costs "
                 f"{', '.join(f'{c:.6g}' for c in optima)}; spread {spread:.1%}): the lowest is kept, and a lower one "
                 f"may exist (more starts: a sweep over horizon.T.guess or the seeds)")
    return {"multistart_starts": len(costs), "multistart_optima": len(optima), "multistart_spread": float(spread),
            "multistart_grid": N, "multistart": said}
