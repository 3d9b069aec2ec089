"""The fuel objective by homotopy (docs/mathematics.md, "The fuel homotopy"): the start of a fuel problem's solve.

The L1 objective sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|) has bang-off-bang minimizers that IPOPT reaches slowly
from the free motion or the screw interpolation (configs/orbit_raise_fuel.yaml, N = 100: 1020 iterations, 54 s;
N = 400: stopped at 'acceptable' after ~1300).  With ``initial_guess: auto`` the fuel problem is reached through
smooth problems and coarse grids instead (:func:`~transcription.strategy.plan.guess_plan`):

1. on the coarsest grid (N <= FUEL_COARSE_MIN steps), :func:`homotopy_guess`: the effort problem (the same
   maneuver with objective effort; :func:`effort_optimum`: with EFFORT_ROLLOUT, from the free motion first when
   its plan would start from the relaxed problem), then, with JUMP, the fuel NLP itself (eps = 0) from the effort
   optimum, cold, within JUMP_BUDGET iterations (the jump, on grids of at most JUMP_MAX_N steps); without JUMP
   or when the jump does not converge the fuel NLP with the smoothed magnitude
   phi_eps(s) = (1 - eps) s + eps s^2 / (2 s_ref) for eps = 1, 1/FACTOR, ... down to SMOOTHING_LAST
   (:func:`smoothing_levels`), each level started from the last one's primal and dual point (the NLPs have the
   same structure: eps is data of the control-node block), and the fuel NLP from the last level and its
   multipliers -- one of the multistart's starts, beside the free motion and the screw interpolation.  Why the
   jump first: on the fuel raise (25 steps) the levels took 62 + 76 + 61 + 117 + 5 iterations (eps = 1 ... 1e-4,
   then the fuel NLP) to 0.8129414920, the jump 55 to the same optimum; the effort problem 92 iterations by its
   plan (40 on the relaxed problem, which ends at another local minimum, 1.376 against 0.980, then 52 from it
   with the phase 1), 21 from the free motion to the same effort optimum.  The homotopy: 418 -> 77 iterations.
   Measured on ten fuel problems of <= 40 steps (the raise on 20, 25 (LGVI and first order), 30 steps and on the
   mesh of issue 26 on 25 and 40; the engine slew, the keep-out slew, the raise without a moment bound and
   leo_raise_slew, fuel, on 25 steps): the same final optimum to 12 digits in every case, and fewer iterations
   for the whole solve in every case (e.g. 1048 -> 649 on 20 steps; 754 -> 731 without a moment bound, where the
   jump took 283 and the levels 365).  On leo_raise_slew's 400 steps the jump did not converge (JUMP_MAX_N).
   Both on by default since the finish of step 2 is on the switching structure (see EFFORT_ROLLOUT);
2. on a finer grid of N steps: the fuel problem solved on max(FUEL_COARSE_MIN, N // FUEL_COARSE_FACTOR) steps
   (recursively), resampled to N steps on SE(3) and finished there on its switching structure
   (:mod:`.fuel_structure`, docs §23: the raise at N = 400 in 56 iterations on 400 steps to 0.8189057879); when
   that fails, the epigraph NLP from the same point with WARM_PRIMAL so that it stays near it (the raise at
   N = 400: 362 iterations on 400 steps to 0.8189058, where IPOPT's defaults took ~1260 to 0.8226885).  A
   smoothed level on the fine grid from the resampled point did not help: the fuel raise at N = 100 from its
   25-step optimum took 138 iterations to 0.81857033 directly, 62 + 83 + 44 through eps = 1e-2, 1e-3, and
   128 + 14 through 1e-4 (cold multipliers on the new grid either way).

Every solve ends with a KKT point of the L1 problem the fuel KKT guard has checked (:mod:`.fuel_guard`): the fuel
NLP itself on the coarsest grid, the structured NLP on finer ones (a KKT point of the fuel NLP too, docs §23).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from .starts import Guess, cayley_vectors
from ..geometry.state import U_FORCE, U_MOMENT
from ..nlp.solvers import ipopt_options, make_ipopt
from ..options import DirectOptions
from ..ocp import NormBound, Problem, ThrusterBound
from ..methods.base import Progress, progress_of, under
from ..nlp.transcription import SmoothTranscription

#: the smoothing levels: eps = SMOOTHING_FIRST, divided by SMOOTHING_FACTOR per level, down to SMOOTHING_LAST
SMOOTHING_FIRST = 1.0
SMOOTHING_FACTOR = 10.0
SMOOTHING_LAST = 1e-4
#: the fuel objective's coarse grid: max(FUEL_COARSE_MIN, N // FUEL_COARSE_FACTOR) steps (recursively)
FUEL_COARSE_MIN = 25
FUEL_COARSE_FACTOR = 4
#: IPOPT options of the finish on a finer grid from the coarser grid's optimum resampled (a primal point only: its
#: multipliers belong to the other grid): the barrier starts small and the point is pushed off its bounds (the
#: coast arcs' magnitudes s = 0) as little as possible, so IPOPT does not first wander away from a point that is
#: already near an optimum (IPOPT's default mu_init = 0.1 and bound_push = 1e-2 tripled the raise's cost in its
#: first 10 iterations)
WARM_PRIMAL = {"mu_init": 1e-6, "bound_push": 1e-9, "bound_frac": 1e-9, "slack_bound_push": 1e-9,
               "slack_bound_frac": 1e-9}
#: IPOPT options of a level started from the previous level's primal-dual point: the barrier starts small and
#: the given point and multipliers are pushed off the bounds as little as possible
WARM_LEVEL = {"warm_start_init_point": "yes", "mu_init": 1e-9, "warm_start_bound_push": 1e-9,
              "warm_start_slack_bound_push": 1e-9, "warm_start_mult_bound_push": 1e-9}
#: the NLP iterations a smoothed level may take before the homotopy ends (its start "not available"): the fuel
#: raise's levels take 5-117 (25 steps); on the LEO raises' 400 steps a level that had not converged in a few
#: hundred iterations crawled on (mu = 1e-9, steps cut to 1e-2 by the bounds) to 3000, minutes each, before the
#: plan's other starts were tried (docs/mathematics.md, "LEO fuel raises")
LEVEL_BUDGET = 500
#: the homotopy's first step from the effort optimum is the fuel NLP itself (eps = 0, cold, within JUMP_BUDGET
#: iterations), the smoothed levels only when that does not converge (module docstring) -- on grids of at most
#: JUMP_MAX_N steps, the largest measured (the jumps of the measured problems took 55-398 iterations).  On the
#: 400 steps of leo_raise_slew with the fuel objective (its coarse grids do not resolve it, :func:`~.plan.
#: coarse_resolves`) the jump reached JUMP_BUDGET without converging (114 s at load 2), and then the levels failed
#: as before (eps = 1: 54 iterations, eps = 0.1: 500, not converged): there the jump only cost time, so grids of
#: more steps keep the levels.  JUMP = False: the levels always.
JUMP = True
JUMP_BUDGET = LEVEL_BUDGET
JUMP_MAX_N = 40
#: the homotopy's effort problem, when its plan would start from the relaxed problem (control bounds or path
#: constraints) and the force is no body-fixed engine, is first solved from the free motion within
#: EFFORT_ROLLOUT_BUDGET iterations (:func:`effort_optimum`).  EFFORT_ROLLOUT = False: by the effort plan always.
#: Both on by default since the structured finish (docs/mathematics.md §23): they reach the same optima at the default
#: tol (the raise: 25 steps 0.8129414920420919 against 0.8129414920420421), but before §23 compare's re-tightening at
#: tol 1e-12 from the 100-step solution was hypersensitive to such 1e-12 differences in its epigraph finish (the raise
#: at N = 100 re-solved at tol 1e-12: 0.8186758353, the guard failed, against 0.8185703221; the mesh at N = 60:
#: 0.8172943137 against 0.8172622932).  With the finish on the switching structure the slow tests of both pass with
#: them on (the lead's run of `pytest -m slow -k fuel`, 11 passed).
EFFORT_ROLLOUT = True
EFFORT_ROLLOUT_BUDGET = 200
#: the homotopy's effort problem is weighted as its first level (:func:`effort_problem`) only where the references
#: differ by more than this factor (r_f / r_m or r_m / r_f), so that the file's weights
#: weigh the parts' squared magnitudes in a ratio more than this factor off the first level's: leo_engine_fuel 1e5.
#: The fuel raise (40) keeps the file's weights: with (1/40, 1) its 100-step direct point re-tightened at tol 1e-12
#: was one from which the indirect method did not converge (tests/test_indirect_fuel.py, |z_N| = 47 after 50
#: iterations), and on its 40-step mesh (tests/test_fuel_guard.py) the path stopped at another false minimum, 0.8151062,
#: than the one that test reproduces (0.8153924; both escaped to 0.8150812453)
EFFORT_LEVEL_RATIO = 1e3
#: Guess.prepared_on of the homotopy's point
PREPARED_ON = "the fuel homotopy"
#: a smoothed level after the first (eps < SMOOTHING_FIRST) that reaches LEVEL_BUDGET ends the homotopy with its
#: last point, which then starts the structured finish (:mod:`.fuel_structure`) as a coarser grid's optimum would
#: (Guess.prepared_on STRUCTURE_START), instead of no start.  Why: on a grid the coarse grids do not resolve
#: (:func:`~.plan.coarse_resolves`) the levels run on the problem's own steps, where a level may crawl (docs §21);
#: its point is still near the fuel optimum's switching structure.  configs/leo_engine_fuel.yaml (N = 400): the
#: level eps = 0.1 reached its 500 iterations with the thrust at 0 or its maximum on most nodes; the structured
#: finish from such a point converged and passed the guard (docs/mathematics.md §21, "A reaction-wheel bound").
#: STRUCTURE_FROM_BUDGET = False: a level at its budget ends the homotopy without a start, as before.
STRUCTURE_FROM_BUDGET = True
STRUCTURE_START = "the fuel homotopy's last level, at its budget"


def smoothing_levels() -> list[float]:
    """eps of the smoothed levels, decreasing geometrically: SMOOTHING_FIRST, ... >= SMOOTHING_LAST."""
    n = int(round(np.log(SMOOTHING_FIRST / SMOOTHING_LAST) / np.log(SMOOTHING_FACTOR)))
    return [SMOOTHING_FIRST / SMOOTHING_FACTOR**k for k in range(n + 1)]


def smoothing_reference(problem: Problem, U: np.ndarray) -> np.ndarray:
    """The references (r_f, r_m) of phi_eps(s) = (1 - eps) s + eps s^2 / (2 r), physical units: a bounded part's
    bound (its magnitude's scale, :meth:`SmoothTranscription.magnitude_scales`, as before); an unbounded part's
    largest magnitude in the effort optimum's controls U (6, n), or its scale where that vanishes (a removed part).
    (The structured finish's roundings are fractions of the same references, :mod:`.fuel_structure`.)  Why:
    an unbounded part's scale is a guess from the boundary data, and where the magnitudes are far from r the
    levels are no homotopy.  The LEO raises (docs/mathematics.md, "LEO fuel raises"): moments of up to 8e-9 kN km
    against a scale of 1.5e-11 made eps s^2 / (2 r) dominate the moment's cost down to eps ~ 1e-2, and the first
    level (eps = 1, 413 iterations on 400 steps) ended with multipliers that left the next one a dual
    infeasibility of 6.5e4 (restoration failures after > 700 iterations); with r = 8.3e-9 the first level took
    100 iterations and left 2.2e-3.  Forces of 6e-4 kN against a scale of 0.54 kN (no bound) left the force part
    of every level the fuel objective itself.  With these references phi_eps'(s) = 1 - eps + eps s / r is in
    [1 - eps, 1] on the effort optimum's magnitudes at every level."""
    c = problem.control
    mags = np.array([np.linalg.norm(U[sl], axis=0).max(initial=0.0) for sl in (U_FORCE, U_MOMENT)])
    unbounded = np.array([b is None or (isinstance(b, NormBound) and b.b <= 0) for b in (c.force_bound,
                                                                                        c.moment_bound)])
    return np.where(unbounded & np.isfinite(mags) & (mags > 0.0), mags, SmoothTranscription.magnitude_scales(problem))


def counted_parts(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts (force, moment) whose fuel counts: weight > 0 and not removed (a norm bound of 0) -- the
    parts the fuel guard checks (:func:`~.fuel_guard.checked_parts`)."""
    c = problem.control
    return np.array([not (isinstance(b, NormBound) and b.b == 0) and wt > 0
                     for b, wt in zip((c.force_bound, c.moment_bound), (c.W_f[0, 0], c.W_m[0, 0]))])


def effort_problem(problem: Problem) -> Problem:
    """The effort problem whose optimum starts the homotopy: ``problem`` with the objective effort,
    sum_j omega_j (1/2)(u_f^T W_f' u_f + u_m^T W_m' u_m), where W_i' = w_i / r_i I (w_i the fuel weights, r_i the
    references of :func:`smoothing_reference`, physical units) when every part whose fuel counts is bounded (then r_i is
    the bound, known before the solve) and the bounds differ by more than EFFORT_LEVEL_RATIO; otherwise W_i' = w_i I as
    before (an unbounded part's r is the effort optimum's own magnitude).  This effort problem is the first level's,
    phi_1(s) = s^2 / (2 r): its optimum is the level's.
    Why: the fuel weights price |u| and the effort weights |u|^2, so the same numbers weigh the parts in the ratio of
    their magnitudes differently.  configs/leo_engine_fuel.yaml (engine <= 1e-3 kN, wheels <= 1e-8 kN km) in a first
    draft with w_m = 1e4 /km: with those weights the moment's squared cost was ~1e-9 of the force's, the moment free in
    the effort problem, and its effort plan did not converge (3 + 200 + 200 + > 400 iterations, restoration).  With
    w_m = 1e5 and w_i / r_i the moment's weight is w_m r_f / (w_f r_m) = 1e10 times the force's, as in
    leo_body_engine.yaml: its effort optimum times 1e3 (235 iterations, 0.934848928)."""
    c = problem.control
    counted = [b for b, k in zip((c.force_bound, c.moment_bound), counted_parts(problem)) if k]
    r = SmoothTranscription.magnitude_scales(problem)
    if (not counted or any(b is None for b in counted)
            or max(r[0] / r[1], r[1] / r[0]) <= EFFORT_LEVEL_RATIO):
        return problem.replace(control=replace(c, objective="effort"))
    return problem.replace(control=replace(c, objective="effort", W_f=c.W_f / r[0], W_m=c.W_m / r[1]))


@dataclass
class Point:
    """A primal-dual point of the fuel NLP of one grid: x, lam_g, lam_x (scaled, of :class:`SmoothTranscription`)
    and the solve that made it: ``status`` (IPOPT's), ``iterations``."""

    x: np.ndarray
    lam_g: np.ndarray | None = None
    lam_x: np.ndarray | None = None
    status: str = ""
    iterations: int = 0

    @property
    def success(self) -> bool:
        return self.status == "Solve_Succeeded"


def level_phase(eps: float) -> str:
    """The progress phase of a level: 'eps 1e-01', or 'fuel jump' for eps = 0 (the fuel NLP from the effort
    optimum, JUMP)."""
    return f"eps {eps:.0e}" if eps > 0 else "fuel jump"


def solve_level(problem: Problem, options: DirectOptions, eps: float, start: Point,
                ref: np.ndarray | None = None, budget: int = LEVEL_BUDGET,
                progress: Progress | None = None) -> tuple[Point, SmoothTranscription]:
    """The fuel NLP smoothed by ``eps`` (references ``ref``, :func:`smoothing_reference`) on ``problem``'s grid,
    from ``start`` (warm when it has multipliers), within ``budget`` NLP iterations; its iterations reported to
    ``progress`` under :func:`level_phase`."""
    tr = SmoothTranscription(problem, options, smoothing=eps, smoothing_ref=ref)
    warm = start.lam_g is not None
    ipopt = ipopt_options(options, warm_duals=warm)
    ipopt["max_iter"] = min(int(ipopt["max_iter"]), budget)
    if warm:
        for k, v in WARM_LEVEL.items():
            ipopt.setdefault(k, v)
    solver = make_ipopt("fuel_homotopy", tr.nlp, ipopt, progress, tr.scales.objective, level_phase(eps))
    args = dict(x0=np.clip(start.x, tr.lbx, tr.ubx), lbx=tr.lbx, ubx=tr.ubx, lbg=tr.nlp.lbg, ubg=tr.nlp.ubg)
    if warm:
        args.update(lam_g0=start.lam_g, lam_x0=start.lam_x)
    out = solver(**args)
    stats = solver.stats()
    return Point(np.asarray(out["x"]).ravel(), np.asarray(out["lam_g"]).ravel(), np.asarray(out["lam_x"]).ravel(),
                 str(stats.get("return_status", "")), int(stats.get("iter_count", 0))), tr


def point_guess(tr: SmoothTranscription, point: Point) -> Guess:
    """The node states, controls and Cayley vectors of a point (physical units) and its multipliers."""
    w = point.x * tr.w_scale
    X = w[tr.layout.iX].T
    duals = None if point.lam_g is None else (tr.nlp.key, point.x, point.lam_g, point.lam_x)
    return Guess(X=X, U=w[tr.layout.iU], C=cayley_vectors(X), duals=duals)


def effort_optimum(effort: Problem, options: DirectOptions, subsolve, relaxation) -> tuple[object, str]:
    """The effort optimum that starts the homotopy (a Solution whose ``iterations`` count every solve made for it),
    and how it was reached (for ``homotopy_levels``): with control bounds or path constraints (where the effort plan
    starts from the relaxed problem, :func:`~.plan.relaxation`) and no body-fixed engine, first from the free motion
    within EFFORT_ROLLOUT_BUDGET iterations; otherwise, or when that does not converge, by the effort plan
    (``subsolve``; a :class:`~..base.Reporting` one reports under 'effort').  (None, '') if neither converged.
    ``relaxation``: :func:`~.plan.relaxation`, passed in (the plan imports this module)."""
    tried, said = 0, ""
    subsolve = under(subsolve, "effort")
    if EFFORT_ROLLOUT and relaxation(effort) is not None and not isinstance(effort.control.force_bound, ThrusterBound):
        sol = subsolve(effort, options.replace(initial_guess="rollout",
                                               max_iter=min(options.max_iter, EFFORT_ROLLOUT_BUDGET)))
        if sol.converged and sol.warm is not None:
            return sol, f"{sol.iterations} (from the free motion)"
        tried, said = sol.iterations, f"{sol.iterations} from the free motion ({sol.result}), then "
    sol = subsolve(effort, options)
    if not sol.converged or sol.warm is None:
        return None, ""
    plan_its = sol.iterations
    sol.iterations += tried
    return sol, f"{said}{plan_its} by the effort plan" if said else f"{plan_its}"


def homotopy_guess(problem: Problem, options: DirectOptions, subsolve, relaxation, effort=None) -> Guess | None:
    """Step 1 of the module docstring on ``problem``'s own grid: the effort optimum, then the fuel NLP from it (the
    jump, within JUMP_BUDGET iterations, on grids of at most JUMP_MAX_N steps) or, when that does not converge (or
    is not tried), the smoothed levels from it; the last
    point with its multipliers (``Guess.duals``), the start of the fuel solve (None if the effort problem or a level
    did not converge).  ``stats['homotopy_levels']`` says which path was taken and the iterations of each step.
    The levels report their iterations where ``subsolve`` reports its own (:func:`~..base.progress_of`).
    ``effort``: the effort optimum as :func:`effort_optimum` returns it, when the caller has solved it already
    (:func:`~.fuel_continuation.fuel_start`, which needs it to decide whether the continuation starts the solve)."""
    t0 = time.perf_counter()
    effort, said = effort or effort_optimum(effort_problem(problem), options, subsolve, relaxation)
    if effort is None:
        return None
    iterations, levels = effort.iterations, [f"effort: {said}"]
    tr = SmoothTranscription(problem, options, smoothing=SMOOTHING_FIRST)
    first = Point(tr.initial_point(Guess(X=effort.warm.X, U=effort.warm.U, C=cayley_vectors(effort.warm.X))))
    ref = smoothing_reference(problem, effort.warm.U)
    point, schedule, progress = first, smoothing_levels(), progress_of(subsolve)
    if JUMP and problem.N <= JUMP_MAX_N:
        jump, jtr = solve_level(problem, options, 0.0, first, ref, JUMP_BUDGET, progress=progress)
        iterations += jump.iterations
        if jump.success:
            levels.append(f"the fuel NLP from the effort optimum: {jump.iterations}")
            point, tr, schedule = jump, jtr, []
        else:
            levels.append(f"the fuel NLP from the effort optimum: {jump.iterations}, {jump.status or 'failed'}, "
                          f"so the levels")
    prepared = PREPARED_ON
    for eps in schedule:
        point, tr = solve_level(problem, options, eps, point, ref, progress=progress)
        iterations += point.iterations
        levels.append(f"eps = {eps:.0e}: {point.iterations}")
        if not point.success:
            if not (STRUCTURE_FROM_BUDGET and eps < SMOOTHING_FIRST and point.status == "Maximum_Iterations_Exceeded"):
                return None
            levels[-1] += f", {point.status}: its point starts the structured finish"
            point, prepared = Point(point.x), STRUCTURE_START      # its primal point alone: the finish is cold
            break
    return replace(point_guess(tr, point), iterations=iterations, seconds=time.perf_counter() - t0,
                   prepared_on=prepared, stats={"homotopy_levels": "; ".join(levels)})
