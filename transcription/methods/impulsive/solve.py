"""The impulsive method's solve: the TPBVP for a state target, the relaxed problem for an orbit target, and the
Solution (impulses, their cost, the re-simulated coast); its Solutions are the direct method's
(``method='direct'``)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ...geometry.state import unpack_states
from ...nlp.solvers import ipopt_history
from ...options import DirectOptions
from ...ocp import Problem, TargetOrbit, TargetState, impulse_cost, orbit_conditions, terminal_error
from ...outcome import Iterate, Result, result_of_solver_status
from ...results.solution import Solution
from ...dynamics.trajectory import trajectory
from ...results.start import Start
from ...results.trace import Attempt
from ..base import OneFunction, Progress
from .reduced import relaxed_reduced
from .relaxed import relaxed_nlp, relaxed_start
from .sensitivity import with_momenta
from .tpbvp import ImpulsiveSettings, initial_momenta, simulate_momenta, solve_tpbvp, tpbvp_residual


@dataclass
class _Outcome:
    """What a transcription of the impulsive problem returns: the momenta p after the first impulse, the
    coast X from them, the post-impulse terminal momenta (gamma_N^+, Pi_N^+), result, message, solver name,
    history, iterations, times, method-specific stats."""

    p: np.ndarray
    X: np.ndarray
    gp: np.ndarray
    Pp: np.ndarray
    result: Result
    message: str
    solver: str
    history: list[Iterate]
    iterations: int
    build_s: float
    solve_s: float
    stats: dict = field(default_factory=dict)


def _impulses(problem: Problem, p: np.ndarray, XN: np.ndarray, gp: np.ndarray, Pp: np.ndarray):
    a0, aN = unpack_states(problem.X0), unpack_states(XN)
    return {"dgamma0": p[:3] - a0.gamma[0], "dPi0": p[3:] - a0.Pi[0], "dgammaN": gp - aN.gamma[0], "dPiN": Pp - aN.Pi[0]}


def _relaxed(problem: Problem, options: DirectOptions, progress: Progress | None, s: ImpulsiveSettings) -> _Outcome:
    """An orbit target: the feasible start (a TPBVP to a point of the orbit), then single or multiple shooting."""
    t1 = time.perf_counter()
    p0, history, start_status = relaxed_start(problem, s)
    start_s = time.perf_counter() - t1
    extra = {"transcription": options.transcription}
    if options.transcription == "multiple_shooting":
        p, stats, build_s, solve_s, min_norm, scale = relaxed_nlp(problem, p0, options, progress)
        status = str(stats.get("return_status", "unknown"))
        result = result_of_solver_status(status)
        history = history + ipopt_history(stats, scale, phase="nlp")
        iterations = int(stats.get("iter_count", 0))
        solver_name, label = "ipopt", "IPOPT"
        extra["solver_status"] = status
    else:
        red = relaxed_reduced(problem, p0, options, progress, s)
        p, result, iterations, build_s, solve_s = red.p, red.result, red.iterations, red.build_s, red.solve_s
        _, gp, Pp = orbit_conditions(red.XN, problem.terminal, problem.model.mass, problem.model.mu)
        min_norm = float(min(np.linalg.norm(v) for v in _impulses(problem, p, red.XN, gp, Pp).values()))
        status, history = result.value, history + red.history
        solver_name, label = "sqp", f"single-shooting SQP ({iterations} iterations, {red.rollouts} rollouts)"
        extra.update(multipliers=red.multipliers, rollouts=red.rollouts)
    X, _ = simulate_momenta(problem, p)
    C, gp, Pp = orbit_conditions(X[-1], problem.terminal, problem.model.mass, problem.model.mu)
    err = float(np.abs(C).max())
    message = f"{label}: {status}; max |C| = {err:.2e} on the re-simulation"
    if result is Result.converged and not err <= options.terminal_tol:
        result = Result.terminal_error
    if min_norm <= s.kink_tol:
        result = Result.kink
        message += (f"; an impulse norm is {min_norm:.1e}: the optimum is at a kink of the sum of norms, where the "
                    "smooth formulation does not apply")
    extra.update({"kkt_tol": float(options.tol), "terminal_conditions": C.tolist(), "start_status": start_status,
                  "min_impulse_norm": min_norm})
    return _Outcome(p, X, gp, Pp, result, message, solver_name, history, iterations, build_s, solve_s + start_s, extra)


def _state_target(problem: Problem, options: DirectOptions, progress: Progress | None,
                  s: ImpulsiveSettings) -> _Outcome:
    """A state target: the TPBVP by Newton-Armijo from one guess, then from the other if it fails."""
    Xd = problem.terminal.X
    t1 = time.perf_counter()
    first = "interpolate" if options.initial_guess == "interpolate" else "rollout"  # auto: rollout first
    history, attempts, iterations = [], [], 0
    for kind in (first, "rollout" if first == "interpolate" else "interpolate"):
        # Newton may stagnate at a local minimum of |r|: restart from the other guess
        nr, X = solve_tpbvp(problem, initial_momenta(problem, kind),
                            replace(s, newton_max_iter=min(options.max_iter, s.newton_max_iter)), progress=progress)
        history += [replace(r, phase=kind) for r in nr.history]
        attempts.append(f"{kind}: {nr.result.value} in {nr.iterations} iterations")
        iterations += nr.iterations
        if nr.result.successful:
            break
    solve_s = time.perf_counter() - t1
    d = unpack_states(Xd)
    r = tpbvp_residual(X[-1], Xd)
    message = f"Newton-Armijo ({'; '.join(attempts)}); |r|_inf = {np.abs(r).max():.2e} (six conditions on x_N, R_N)"
    if nr.rejected_aux and not nr.result.successful:
        message += (f"; {len(nr.rejected_aux)} trials were rejected because a Cayley equation was not solved "
                    f"(residual up to {max(nr.rejected_aux):.1e}): use a smaller step h = T/N (increase horizon.N)")
    extra = {"residual_inf": float(np.abs(r).max()), "newton_status": nr.result.value, "start": kind}
    return _Outcome(nr.x, X, d.gamma[0], d.Pi[0], nr.result, message, "newton-armijo", history, iterations, 0.0,
                    solve_s, extra)


def not_covered(problem: Problem) -> str:
    """What of ``problem`` the impulsive solver does not cover: smooth control (the direct method's NLP does)."""
    return "" if problem.kind == "impulsive" else "smooth control (the direct method's NLP covers it)"


def solve_impulsive(problem: Problem, options: DirectOptions | None = None, progress: Progress | None = None,
                    warm: Start | None = None, label: str = "",
                    settings: ImpulsiveSettings = ImpulsiveSettings()) -> Solution:
    """Solve an impulsive Problem (package docstring) by the direct method.

    The Solution has solver 'newton-armijo' (TPBVP), 'sqp' (relaxed, single shooting) or 'ipopt'
    (relaxed, multiple shooting); ``impulses`` =
    {dgamma0, dPi0 (at t = 0), dgammaN, dPiN (at t = T)}; cost = the sum of the four impulse norms;
    trajectory = the re-simulation from X_0^+ (X0 with the post-impulse momenta) with u = 0, its
    last node the state just *before* the terminal impulse (``stats['XN_plus']`` is the state
    after it).  terminal_error: TPBVP: the error of X_N^+ against the target (the momenta are
    matched by the impulse); relaxed: max |C|.  A ``warm`` start is not used (the impulsive method starts
    from its own guesses; the message says so); its Solutions carry none.  ``settings``: the numerical parameters.
    """
    options = options or DirectOptions()
    if problem.kind != "impulsive":
        raise ValueError("the impulsive method solves impulsive-control problems")
    t0 = time.perf_counter()
    problem.disc.rollout(problem.N)
    build_s = time.perf_counter() - t0
    run = _relaxed if isinstance(problem.terminal, TargetOrbit) else _state_target
    out = run(problem, options, progress, settings)
    imp = _impulses(problem, out.p, out.X[-1], out.gp, out.Pp)
    XNp = with_momenta(out.X[-1], np.r_[out.gp, out.Pp])
    if isinstance(problem.terminal, TargetState):
        err = terminal_error(out.X[-1], problem, XN_plus=XNp)
    else:
        err = float(np.abs(out.stats["terminal_conditions"]).max())
    out.stats["XN_plus"] = XNp
    message = out.message
    if warm is not None:
        message += f"; warm start from {warm.describe()} not used (the impulsive method starts from its own guesses)"
    cost = impulse_cost(imp)
    attempt = Attempt(label or str(out.stats.get("start", "")) or "impulsive", out.result, out.iterations,
                      cost if out.result.successful else float("nan"), build_s + out.build_s, out.solve_s)
    return Solution(method="direct", solver=out.solver, result=out.result, verdict=message,
                    trajectory=trajectory(problem, out.X), cost=cost, terminal_error=float(err), problem=problem,
                    impulses=imp, history=out.history, stats=out.stats, trace=(attempt,))


@dataclass(frozen=True)
class Impulsive(OneFunction, name="direct", kind="impulsive", run=solve_impulsive, covers=not_covered):
    """The direct method on impulsive control (package docstring): one solve of the impulsive problem (a TPBVP for a
    state target, the relaxed problem for an orbit target) with the direct method's ``options``."""

    options: DirectOptions = field(default_factory=DirectOptions)
    settings: ImpulsiveSettings = ImpulsiveSettings()     # the numerical parameters of its solves
