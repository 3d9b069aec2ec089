"""Accuracy on demand (docs/mathematics.md §11, §16): every smooth-control Solution of ``solve`` is flown in
continuous time (the continuous check, on by default), and with ``solver.accuracy`` the mesh is refined until that
flight lands within the tolerance.  :class:`AccuracyOptions` (transcription/options.py) are the ``solver`` block's
keys ``continuous_check``, ``accuracy`` (null: a fixed N) or ``maneuver_accuracy`` (the same as a fraction of the
maneuver), ``constraints_tolerance`` (the path constraints' violation between the nodes), ``max_N`` and
``max_levels``.  :func:`attach_checks`
stores a :class:`~transcription.results.check.ContinuousCheck` on every successful smooth-control Solution
(``sol.continuous``).
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..options import CHECK_ENV, AccuracyOptions
from ..results.check import ContinuousCheck, characteristic_length as _length, margin_scales, scaled_miss
from ..outcome import Result
from ..results.solution import Solution
from ..dynamics.trajectory import trajectory
from ..dynamics.lgvi import ORDER, discretization
from .mesh import Refinement, aimed_density, density_steps, error_estimate, path_density, subdivided_steps

if TYPE_CHECKING:  # pragma: no cover
    from ..solve import Comparison

__all__ = ["CHECK_ENV", "AccuracyOptions", "Refinement", "attach_checks", "level_miss", "out_of_reach", "refine",
           "scaled_miss"]

def _solutions(out: "Solution | Comparison") -> list[Solution]:
    return list(out.solutions.values()) if hasattr(out, "solutions") else [out]


def each(out: "Solution | Comparison", fn) -> "Solution | Comparison":
    """``fn`` applied to every Solution of ``out`` (a Comparison made again with them, its verdict unchanged)."""
    if hasattr(out, "solutions"):
        return dataclasses.replace(out, direct=fn(out.direct), indirect=fn(out.indirect))
    return fn(out)


def attach_checks(out: "Solution | Comparison", path_tol: float | None = None) -> "Solution | Comparison":
    """Every successful smooth-control Solution of ``out`` with its continuous check (``continuous``,
    :func:`~transcription.results.check.continuous_check`; a check already there is kept) and, in its message, the
    check's notes: a flown miss above 1 % of the maneuver, a path constraint left between the nodes by more than
    ``path_tol`` (``solver.constraints_tolerance``; None: the default PATH_MARGIN_TOL).  Failed solves, impulsive
    plans and simulations are left alone."""
    from ..results.check import continuous_check

    def checked(s: Solution) -> Solution:
        if s.continuous is None and s.converged and s.problem is not None and s.problem.kind == "smooth" \
                and s.controls is not None:
            check = continuous_check(s, path_tol=path_tol)
            s = dataclasses.replace(s, continuous=check)
            return s if check is None else s.with_notes(*(n for n in (check.miss_note(), check.path_note()) if n))
        return s

    return each(out, checked)


# ---------------------------------------------------------------------------- refinement to a tolerance
#: the most favourable order a level's miss may fall with: the best of the schemes' (the first-order scheme's miss can
#: fall at O(h^2) too, so its nominal ORDER would wrongly refuse a tolerance it reaches; §16)
BEST_ORDER = max(ORDER.values())


def path_violation(check, problem) -> float:
    """How far the flown path leaves the path constraints between the nodes, in the units of :func:`scaled_miss`:
    max(0, -smallest margin) over the constraints, a cone's margin (deg) in rad, a radius relative to L, a rate in
    rad per time unit; 0 without constraints."""
    from ..results.check import margin_keys

    worst = 0.0
    for key, s in zip(margin_keys(problem.constraints), margin_scales(problem)):
        worst = max(worst, -check.min_margins.get(key, 0.0) * s)
    return float(worst)


def next_N(N: int, ratio: float, order: float, max_N: int, rules: Refinement = Refinement()) -> int:
    """The N of the next level from this level's error ratio (miss / tol, > 1) and the scheme's observed order:
    safety N ratio^(1/order), at least 2 N (uniform doubling at least), at most growth N (the bound every level
    keeps, the adaptive ones too: :func:`capped_mesh`); not capped at max_N (the caller refuses a level beyond it)."""
    want = rules.safety * N * ratio ** (1.0 / order) if np.isfinite(ratio) else 2 * N
    return int(min(max(np.ceil(want), 2 * N), rules.growth * N))


def observed_order(levels: list[dict], scheme: str) -> float:
    """The order to extrapolate with: the scheme's (ORDER), or the slope of the last two levels' misses in N when
    it is lower (clamped to at least 0.5)."""
    p = float(ORDER[scheme])
    if len(levels) >= 2:
        a, b = levels[-2], levels[-1]
        if a["miss"] > 0 and b["miss"] > 0 and b["N"] > a["N"]:
            slope = np.log(a["miss"] / b["miss"]) / np.log(b["N"] / a["N"])
            if np.isfinite(slope):
                p = float(min(p, max(slope, 0.5)))
    return p


def refine(problem, run: Callable, opts: AccuracyOptions, warm=None, adaptive: bool = False,
           rules: Refinement = Refinement()) -> "Solution | Comparison":
    """Solve ``problem`` on refined meshes until the continuous check lands within ``opts.tolerance``
    (docs/mathematics.md §11, "Refinement to a tolerance"; §16, the adaptive mesh).

    run(problem, warm) -> Solution | Comparison is one solve on the problem's own grid.  Level 0 solves on the given
    N (from ``warm`` if any); each following level, warm-started from the previous one, on :func:`next_mesh`
    (``adaptive``: the estimated error equidistributed) or :func:`next_N` uniform steps.  The miss of a level is
    :func:`level_miss`: the scaled miss (``solver.accuracy``) or the flown miss as a fraction of the maneuver
    (``solver.maneuver_accuracy``); a level is accepted when it and the path violation are within the tolerance.

    **Bounded growth.** No level has more than ``rules.growth`` times the previous level's steps: the uniform N of
    :func:`next_N` is capped so, and an adaptive mesh with more steps is coarsened to that count in its own density
    (:func:`capped_mesh`), so a large miss is approached in several levels instead of one jump.

    **The best level is kept.** Every level that converged and was flown is kept.  When a later level fails (no
    method converged and was flown, or its miss cannot be measured) or is interrupted (a Solution with
    Result.interrupted, or KeyboardInterrupt out of ``run`` -- Ctrl-C), the best level so far (lowest
    max(miss, path_violation)) is returned, with the whole mesh history, ``accuracy_met`` False and a sentence
    naming the level that failed, how, and the level returned (N, miss); the same when the refinement stops short
    (``max_N``, ``max_levels``) and an earlier level was better than the last.  A failure or interrupt at level 0
    returns (or raises) as the solve did.

    Stops when the tolerance is met, when a level fails, or before a level beyond ``max_N`` or ``max_levels``.
    Returns the Solutions of the level met or kept, carrying the mesh history (``sol.mesh``: level, N, mesh, h_min,
    h_max, miss, predicted, path_violation, iterations, solve_s, check_s, status), ``stats['accuracy_met']``,
    ``stats['accuracy_level']`` (the level returned), ``stats['accuracy_interrupted']`` and a sentence in the
    message.  ``rules``: :class:`~.mesh.Refinement`."""
    levels, prob, kept = [], problem, []
    name = goal(opts)
    while True:
        t0 = time.perf_counter()
        try:
            out = attach_checks(run(prob, warm), opts.constraints_tolerance)
        except KeyboardInterrupt:
            if not kept:
                raise
            levels.append(_interrupted_record(prob, len(levels), time.perf_counter() - t0))
            return _best(kept, levels, f"refinement level {len(levels) - 1} (N = {prob.N}) was interrupted "
                                       f"(Ctrl-C) before it finished", name, interrupted=True)
        rec, best = _record(out, prob, len(levels), time.perf_counter() - t0, opts)
        levels.append(rec)
        stopped = any(s.result is Result.interrupted for s in _solutions(out))
        if stopped or best is None or not np.isfinite(rec["miss"]):
            why = (f"was interrupted ({_first_message(out, Result.interrupted)})" if stopped else
                   f"failed: {_failure(out, best, opts)}")
            if kept:
                return _best(kept, levels, f"refinement level {rec['level']} (N = {prob.N}) {why}", name,
                             interrupted=stopped)
            return _finish(out, levels, False, f"refinement stopped at level {rec['level']} (N = {prob.N}): "
                                                f"{rec['status']}" + ("" if best is None else f"; {why}"),
                           level=rec["level"], interrupted=stopped)
        worst = level_ratio(rec, opts)
        kept.append((worst, rec["level"], out))
        if not worst > 1.0:
            path = f", path violation {rec['path_violation']:.2e}" if opts.constraints_tolerance is not None else ""
            return _finish(out, levels, True, f"refined to {name}: {miss_name(opts)} {rec['miss']:.2e}{path} "
                                              f"at N = {prob.N} after {len(levels)} level(s)", level=rec["level"])
        least = least_N(prob.N, worst, adaptive, rules)
        if least > opts.max_N:    # even the most favourable order cannot land within max_N: no further level
            return _best(kept, levels, beyond_reach_sentence(rec, prob.N, least, adaptive, opts.max_N, rules, opts),
                         name)
        p = observed_order(levels, prob.scheme)
        mesh = next_mesh(prob, best, rec, opts.tolerance or math.inf, p, rules, miss_units(best, prob, opts),
                         opts.path_tolerance) if adaptive else None
        if mesh is not None:      # the miss this level's error estimate predicts (its calibration)
            rec["predicted"] = float(mesh[1])
            mesh = capped_mesh(mesh[0], rules.growth * prob.N)
        N = next_N(prob.N, worst, p, opts.max_N, rules) if mesh is None else len(mesh)
        if N > opts.max_N or len(levels) >= opts.max_levels:
            limit = f"solver.max_N = {opts.max_N}" if N > opts.max_N else f"solver.max_levels = {opts.max_levels}"
            return _best(kept, levels, needs_sentence(rec, prob.N, prob.scheme, p, limit, opts), name)
        T = min(max(best.T, prob.time_bounds[0]), prob.time_bounds[1]) if prob.free_time else prob.T
        prob, warm = dataclasses.replace(prob, N=N, T=T, mesh=mesh), best.warm


def capped_mesh(steps: np.ndarray, most: int) -> np.ndarray:
    """An adaptive level's mesh (relative steps, N') with at most ``most`` steps (growth times the previous N,
    docs/mathematics.md §16): unchanged when N' <= most, else coarsened to ``most`` steps keeping its density shape
    (:func:`~.mesh.subdivided_steps` by the factor most / N' < 1: each of its steps' share of the new nodes kept)."""
    n = len(steps)
    return steps if n <= most else subdivided_steps(steps, (most - 0.5) / n)


def goal(opts: AccuracyOptions) -> str:
    """What a refinement aims at, in its sentences: 'accuracy 1e-06', 'maneuver accuracy 0.01', 'constraints
    tolerance 1e-05' or 'accuracy 1e-06 and constraints tolerance 1e-05'."""
    parts = [] if opts.tolerance is None else [f"{tolerance_name(opts)} {opts.tolerance:.3g}"]
    if opts.constraints_tolerance is not None:
        parts.append(f"constraints tolerance {opts.constraints_tolerance:.3g}")
    return " and ".join(parts)


def level_ratio(rec: dict, opts: AccuracyOptions) -> float:
    """How far a level is from its tolerances (<= 1: accepted): the path violation over ``opts.path_tolerance`` and,
    with accuracy or maneuver_accuracy, the level's miss over it -- the larger."""
    _, value, tol = dominant(rec, opts)
    return float(value / tol)


def dominant(rec: dict, opts: AccuracyOptions) -> tuple[str, float, float]:
    """(name, value, tolerance) of what keeps a level farthest from acceptance: the miss (:func:`miss_name`, against
    ``opts.tolerance``; not with ``constraints_tolerance`` alone) or the path violation (against
    ``opts.path_tolerance``)."""
    path = ("path violation", float(rec["path_violation"]), float(opts.path_tolerance))
    if opts.tolerance is None:
        return path
    miss = (miss_name(opts), float(rec["miss"]), float(opts.tolerance))
    return miss if miss[1] / miss[2] >= path[1] / path[2] else path


def tolerance_name(opts: AccuracyOptions) -> str:
    """'accuracy' or 'maneuver accuracy': the tolerance in the sentences of a refinement."""
    return "maneuver accuracy" if opts.of_maneuver else "accuracy"


def miss_name(opts: AccuracyOptions) -> str:
    """What a level's miss is, in the sentences of a refinement."""
    return "flown miss (fraction of the maneuver)" if opts.of_maneuver else "continuous miss"


def level_miss(check: ContinuousCheck, problem, opts: AccuracyOptions) -> float:
    """The miss a refinement level is judged by: the check's flown miss as a fraction of what the maneuver changes
    (``ContinuousCheck.maneuver_fraction``) with ``solver.maneuver_accuracy``, else :func:`scaled_miss`."""
    return float(check.maneuver_fraction) if opts.of_maneuver else scaled_miss(check, problem)


def miss_units(best: Solution, problem, opts: AccuracyOptions) -> tuple[float, float, float, float]:
    """The divisors (position, velocity, angle, rate) that put a terminal error into the units of
    :func:`level_miss`, for the error estimate of an adaptive level (transcription.strategy.mesh.tangent_norms):
    (L, V, 1, 1) of :func:`scaled_miss`; with ``maneuver_accuracy`` what the maneuver changes (inf for what it does
    not: the rate never counts), or (L, V, 1, 1) when it changes no component (an orbit target: the fraction is of
    the target-error measure, and the estimate's calibration by the flown miss takes care of the units)."""
    L = _length(problem)
    V = float(np.sqrt(problem.model.mu / L)) if problem.model.mu else 1.0
    chk = best.continuous
    if opts.of_maneuver and chk is not None and chk.maneuver_parts():
        def of(c):
            return float(c) if np.isfinite(c) and c > 0 else math.inf
        return of(chk.change_position), of(chk.change_velocity), of(chk.change_attitude), math.inf
    return L, V, 1.0, 1.0


def _first_message(out, result: Result) -> str:
    s = next((s for s in _solutions(out) if s.result is result), None)
    return f"{s.method}: {s.message}" if s is not None else str(result)


def _failure(out, best, opts: AccuracyOptions) -> str:
    """How a level failed, in words: the methods' results and messages, or why its miss cannot be measured."""
    if best is None:
        flown = [s for s in _solutions(out) if s.converged and s.continuous is not None and not s.continuous.ok]
        if flown:
            return "; ".join(f"{s.method} converged but cannot be flown ({s.continuous.message})" for s in flown)
        return "; ".join(f"{s.method} {s.result.value} ({s.message})" for s in _solutions(out)
                         if s.result is not Result.not_applicable)
    return (f"its {miss_name(opts)} is not defined (what the maneuver changes was not measured)" if opts.of_maneuver
            else "its continuous miss is not finite")


def _interrupted_record(problem, level: int, wall: float) -> dict:
    """The mesh-history record of a level stopped by KeyboardInterrupt (nothing solved to record)."""
    steps = problem.steps
    return {"level": level, "N": int(problem.N), "mesh": "uniform" if problem.uniform else "adaptive",
            "h_min": float(steps.min()), "h_max": float(steps.max()), "miss": math.nan, "path_violation": math.nan,
            "iterations": 0, "solve_s": float(wall), "check_s": 0.0, "status": "interrupted (Ctrl-C)"}


def _best(kept: list, levels: list[dict], what: str, name: str, interrupted: bool = False):
    """The refinement's answer when it ends without meeting the tolerance: the kept level (converged and flown) with
    the lowest :func:`level_ratio` -- the later of equal ones -- with the whole history and the sentence
    ``what``, naming the level returned when it is not the last one solved."""
    _, j, out = min(kept, key=lambda k: (k[0], -k[1]))
    rec = levels[j]
    if j != levels[-1]["level"] or interrupted:
        what += (f"; returned level {j} (N = {rec['N']}, miss {rec['miss']:.2e}, path violation "
                 f"{rec['path_violation']:.1e}), the best level solved: {name} not reached")
    return _finish(out, levels, False, what, level=j, interrupted=interrupted)


def least_N(N: int, ratio: float, adaptive: bool, rules: Refinement = Refinement()) -> float:
    """The fewest steps that could bring a level's error (``ratio`` = miss / tol, > 1, at N steps) within the
    tolerance: N ratio^(1/BEST_ORDER), divided by adaptive_gain on an adaptive mesh -- an optimistic estimate, so
    that a tolerance it puts above max_N is out of reach whichever order the scheme shows (docs/mathematics.md §16,
    "Out of reach after the first level")."""
    return N * ratio ** (1.0 / BEST_ORDER) / (rules.adaptive_gain if adaptive else 1.0)


def beyond_reach_sentence(rec: dict, N: int, least: float, adaptive: bool, max_N: int, rules: Refinement,
                          opts: AccuracyOptions) -> str:
    """'accuracy 1e-09 not reached: the continuous miss 6.01e-04 at N = 200 would need N ≈ 7.8e+04 even if it
    fell at O(h^2), ...' -- the one line of :func:`refine` when :func:`least_N` is above ``max_N`` after a level."""
    what, value, _ = dominant(rec, opts)
    gain = f", with an adaptive mesh credited with {rules.adaptive_gain:g} times fewer steps" if adaptive else ""
    return (f"{goal(opts)} not reached: the {what} {value:.2e} at N = {N} would need N ≈ {least:.2g} even if it "
            f"fell at O(h^{BEST_ORDER}), the best order of either scheme{gain}, above solver.max_N = {max_N}, so no "
            f"further level was solved: raise solver.max_N to at least {least:.2g} or loosen "
            f"solver.{opts.tolerance_key}")


def next_mesh(problem, best: Solution, rec: dict, tol: float, order: float, rules: Refinement,
              units: tuple[float, float, float, float] | None = None,
              path_tol: float | None = None) -> tuple[np.ndarray, float]:
    """The adaptive level's next mesh (relative step sizes) and this level's predicted miss (docs/mathematics.md
    §16): each step's local error (step doubling) propagated to the final node (transcription.strategy.mesh),
    equidistributed so that the predicted miss of the refined mesh (:func:`~.mesh.aimed_density`) is tol / safety,
    calibrated by this level's flown miss over its own prediction.  A path violation over ``path_tol`` (default tol)
    is refined by :func:`path_mesh` (the steps whose local errors drift the path off, and those about a contact); if
    that finds nothing, the mesh is subdivided by the uniform factor of :func:`next_N`.  tol = inf
    (``solver.constraints_tolerance`` alone): the miss is not refined.  ``units``: the divisors of :func:`miss_units`
    (default those of :func:`scaled_miss`).  The mesh may have more than growth N steps: the caller caps it
    (:func:`capped_mesh`)."""
    p = ORDER[problem.scheme]
    L = _length(problem)
    V = float(np.sqrt(problem.model.mu / L)) if problem.model.mu else 1.0
    units = units or (L, V)
    _, predicted, c = error_estimate(problem, best.trajectory.X, best.controls, best.steps, p, *units)
    path_tol = tol if path_tol is None else path_tol
    if rec["path_violation"] > path_tol:
        mesh = path_mesh(problem, best, c, units, predicted, rec, path_tol, rules, tol)
        if mesh is not None:
            return mesh, predicted
    ratio = max(rec["miss"] / tol, rec["path_violation"] / path_tol)
    if rec["path_violation"] / path_tol > rec["miss"] / tol or not (predicted > 0 and rec["miss"] > 0):
        return subdivided_steps(best.steps, next_N(problem.N, ratio, order, 0, rules) / problem.N), predicted
    return density_steps(best.steps, miss_density(problem, best.steps, c, units, predicted, rec, tol, rules)), predicted


def miss_density(problem, steps: np.ndarray, c: np.ndarray, units: tuple, predicted: float, rec: dict, tol: float,
                 rules: Refinement) -> np.ndarray:
    """The node density whose predicted miss is tol / safety (:func:`~.mesh.aimed_density`, the safety its margin),
    calibrated by this level's flown miss over its own ``predicted`` one: the terminal miss's rule of
    :func:`next_mesh` and :func:`path_mesh`."""
    return aimed_density(problem, steps, c, ORDER[problem.scheme], tol / rules.safety * predicted / rec["miss"], units,
                         rules, rules.safety)


def path_mesh(problem, best: Solution, c: np.ndarray, units: tuple, predicted: float, rec: dict, tol: float,
              rules: Refinement, miss_tol: float | None = None) -> np.ndarray | None:
    """The next mesh when the flown path leaves a path constraint between the nodes by more than tol
    (docs/mathematics.md §16): on every step the larger of the terminal miss's node density (:func:`next_mesh`, aimed
    at ``miss_tol``, default tol, from the steps' contributions ``c`` in ``units`` and their ``predicted`` miss;
    1 / h_k when there is no miss or miss_tol is inf) and transcription.strategy.mesh.path_density's (aimed at
    tol / safety).  None when the path rule finds nothing over the tolerance (the caller subdivides)."""
    from ..dynamics.flight import DEFAULT_SAMPLES, FlightError

    p, h = ORDER[problem.scheme], best.steps
    try:
        dens = path_density(problem, best.trajectory.X, best.controls, h, p, tol / rules.safety,
                            margin_scales(problem), DEFAULT_SAMPLES, rules)
    except FlightError:       # an interval flown from its own node failed: subdivide as before
        dens = None
    if dens is None:
        return None
    miss_tol = tol if miss_tol is None else miss_tol
    if predicted > 0 and rec["miss"] > 0 and np.isfinite(miss_tol):
        dens = np.maximum(dens, miss_density(problem, h, c, units, predicted, rec, miss_tol, rules))
    else:
        dens = np.maximum(dens, 1.0 / h)
    return density_steps(h, dens)


def needs_sentence(rec: dict, N: int, scheme: str, order: float, limit: str, opts: AccuracyOptions) -> str:
    """'accuracy 1e-06 not reached: ... would need N ~ 1.6e+07 (first_order, error O(h^1)), above ...; the lgvi
    scheme (O(h^2)) would need N ~ ...' -- the one line of a tolerance out of reach (the miss or the path
    violation, whichever is farther from its tolerance: :func:`dominant`)."""
    what, miss, tol = dominant(rec, opts)
    need = N * (miss / tol) ** (1.0 / order)
    out = (f"{goal(opts)} not reached: the {what} {miss:.2e} at N = {N} would need "
           f"N ≈ {need:.2g} ({scheme}, error O(h^{order:g})), above {limit}")
    if scheme != "lgvi":
        # the second-order scheme's error constant is about the first-order one's (E3, E4: within a factor 10)
        lg = N * (miss / tol) ** 0.5
        out += f"; the lgvi scheme (O(h²)) would need N ≈ {lg:.2g}: use discretization: lgvi"
    return out


def _record(out, problem, level: int, wall: float,
            opts: AccuracyOptions | None = None) -> tuple[dict, Solution | None]:
    """The mesh-history record of one level and the Solution to continue from (the direct one if flown; None
    when no method converged and was flown).  Its miss is :func:`level_miss` (the worst method's)."""
    opts = opts or AccuracyOptions(accuracy=1.0)
    sols = [s for s in _solutions(out) if s.continuous is not None and s.continuous.ok]
    check_s = sum(s.continuous.elapsed_s for s in sols)
    miss = max((level_miss(s.continuous, problem, opts) for s in sols), default=math.nan)
    viol = max((path_violation(s.continuous, problem) for s in sols), default=math.nan)
    steps = problem.steps
    rec = {"level": level, "N": int(problem.N), "mesh": "uniform" if problem.uniform else "adaptive",
           "h_min": float(steps.min()), "h_max": float(steps.max()), "miss": float(miss), "path_violation": float(viol),
           "iterations": int(sum(s.iterations for s in _solutions(out))), "solve_s": float(wall - check_s),
           "check_s": float(check_s), "status": ", ".join(f"{s.method} {s.result.value}" for s in _solutions(out))}
    best = next((s for s in sols if s.method == "direct"), sols[0] if sols else None)
    return rec, best


def _finish(out, levels: list[dict], met: bool, sentence: str, level: int | None = None, interrupted: bool = False):
    """The mesh history, the verdict and its sentence on every Solution of the level returned (``level``: its
    number, default the last)."""
    level = levels[-1]["level"] if level is None else level
    return each(out, lambda s: dataclasses.replace(s, mesh=tuple(dict(r) for r in levels)).with_notes(
        sentence, accuracy_met=bool(met), accuracy_levels=len(levels), accuracy_level=int(level),
        accuracy_interrupted=bool(interrupted)))


# ---------------------------------------------------------------------------- the answer before solving
def free_motion_check(problem, scheme: str | None = None) -> ContinuousCheck | None:
    """The continuous check of a scheme's free motion on ``problem``'s grid (``simulate``, no control) -- what the
    a-priori estimate of :func:`out_of_reach` flies; None if there is nothing to fly."""
    from ..results.check import continuous_check

    scheme = scheme or problem.scheme
    d = problem.disc
    if scheme != problem.scheme:
        problem = dataclasses.replace(problem, disc=discretization(d.model, scheme, d.newton_iters,
                                                                   force_frame=d.force_frame))
    X, _ = problem.disc.simulate(problem.X0, None, problem.h, problem.N)
    free = Solution(method="simulate", solver=scheme, result=Result.converged, verdict="free motion",
                    trajectory=trajectory(problem, X), cost=math.nan, terminal_error=math.nan, problem=problem)
    return continuous_check(free)


def free_motion_miss(problem, scheme: str | None = None, opts: AccuracyOptions | None = None) -> float:
    """The a-priori error estimate of a scheme on ``problem``'s grid (docs/mathematics.md §11): :func:`level_miss`
    (default :func:`scaled_miss`) of its free motion (``simulate``) against the same motion flown in continuous
    time; nan if it cannot be flown."""
    check = free_motion_check(problem, scheme)
    if check is None or not check.ok:
        return math.nan
    return level_miss(check, problem, opts) if opts is not None else scaled_miss(check, problem)


def undefined_maneuver(problem) -> str:
    """'' or why ``solver.maneuver_accuracy`` cannot apply to ``problem``: the flown miss as a fraction of the
    maneuver (ContinuousCheck.maneuver_fraction) needs a change to measure it against -- a terminal target and a
    component the maneuver changes (or a target the free motion misses), measured on the free motion."""
    if problem.terminal is None:
        return "the problem has no terminal target to measure the maneuver by"
    check = free_motion_check(problem)
    if check is None or not check.ok or not np.isfinite(check.change_target):
        why = check.message if check is not None and check.message else "its free motion cannot be flown"
        return f"what the maneuver changes cannot be measured ({why})"
    if check.maneuver_parts() or check.change_target > 0:
        return ""
    return ("the maneuver changes nothing measurable: no component of its target differs from the initial state or "
            "the free motion's end by a millionth of its scale, and the free motion already meets the target "
            f"(terminal error {check.change_target:.2e})")


def out_of_reach(problem, opts: AccuracyOptions) -> str:
    """The one-line answer before solving ('' when there is none): ``opts.tolerance`` needs more than ``opts.max_N``
    steps of the problem's scheme by the a-priori estimate (:func:`free_motion_miss` extrapolated with the scheme's
    order, N_need = N (miss / tol)^(1/p)); the sentence names that N and what the other scheme would need (around a
    central body the Kepler-split LGVI, whose free motion is the two-body orbit; else the LGVI).  With
    ``maneuver_accuracy``, also a maneuver whose change cannot be measured (:func:`undefined_maneuver`)."""
    if not opts.refines or problem.kind is None:
        return ""
    key = f"solver.{opts.tolerance_key}"
    if problem.kind != "smooth":
        return ("refinement to an accuracy applies to smooth control (an impulsive plan coasts between its impulses "
                f"on the scheme's free motion): remove {key}")
    if opts.tolerance is None:      # constraints_tolerance alone: no a-priori estimate of a violation
        return ""
    if opts.of_maneuver:
        why = undefined_maneuver(problem)
        if why:
            return (f"maneuver accuracy {opts.tolerance:.3g} (a fraction of the maneuver) cannot apply: {why}; give "
                    f"solver.accuracy (the miss in the problem's scaled units) instead; nothing was solved")
    tol, scheme, N, name = float(opts.tolerance), problem.scheme, problem.N, tolerance_name(opts)
    miss = free_motion_miss(problem, opts=opts)
    need = N * (miss / tol) ** (1.0 / ORDER[scheme]) if miss > tol else 0.0
    if not need > opts.max_N:
        return ""
    out = (f"{name} {tol:.3g} is out of reach of the {scheme} scheme within solver.max_N = {opts.max_N}: it would "
           f"need N ≈ {need:.2g} steps (error O(h^{ORDER[scheme]}); its free motion at N = {N} misses the continuous "
           f"flight by {miss:.2e}{' of the maneuver' if opts.of_maneuver else ''}); nothing was solved")
    alt = "lgvi_kepler" if problem.model.mu and scheme != "lgvi_kepler" else "lgvi"
    if scheme != alt:
        lg = free_motion_miss(problem, alt, opts)
        need_lg = N * (lg / tol) ** (1.0 / ORDER[alt]) if lg > tol else N
        out += (f"; the {alt} scheme (O(h^{ORDER[alt]})) would need N ≈ {need_lg:.2g}" +
                (f": use discretization: {alt}" if need_lg <= opts.max_N else ", also above the cap"))
    if "also above" in out or scheme == alt:
        out += f": loosen {key} or raise solver.max_N"
    return out
