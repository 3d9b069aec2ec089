"""The Solution of a finished NLP solve of the direct method (IPOPT or fatrop): the controls re-simulated,
the checks a converged solve must pass, the costates from the multipliers, the warm start it hands on."""
from __future__ import annotations

import numpy as np

from ...ocp.feasibility import step_failure
from ...dynamics.lgvi import CAYLEY_TOL
from ...nlp.solvers import ipopt_history, solve_time_split
from ...options import DirectOptions
from ...ocp import Problem, control_activity, objective_value, quadrature_weights, terminal_error
from ...outcome import Result, result_of_solver_status
from ...results.solution import Solution
from ...dynamics.trajectory import Trajectory, trajectory
from ...results.start import Point, start_of
from ...results.trace import Attempt
from ...nlp.transcription import SmoothTranscription


def _verdict(problem: Problem, status: str, solver: str, Xsim: np.ndarray, res: np.ndarray, h: float, err: float,
             options: DirectOptions) -> tuple[Result, str]:
    """The result and message of a solve from the solver's status and the re-simulation (states Xsim, Cayley
    residuals res at step size h): its terminal error err and largest Cayley residual."""
    worst_cayley = float(np.max(res)) if res.size else 0.0
    result = result_of_solver_status(status)
    label = "IPOPT" if solver == "ipopt" else solver
    if result is Result.converged and not err <= options.terminal_tol:
        result = Result.terminal_error
        message = (f"{label}: {status}, but the re-simulated terminal error {err:.2e} exceeds terminal_tol "
                   f"{options.terminal_tol:.1e} (max Cayley residual {worst_cayley:.1e})")
    elif result is Result.converged:
        message = f"{label}: {status}; re-simulated terminal error {err:.2e}"
    else:
        message = f"{label} did not converge: {status}; re-simulated terminal error {err:.2e}"
    if not result.successful and not worst_cayley <= CAYLEY_TOL:  # non-finite, or the Cayley fold: say which
        result, why = step_failure(problem, Xsim, res, h)
        message += f"; in the re-simulation, {why}"
    return result, message


def nlp_solution(problem: Problem, options: DirectOptions, tr: SmoothTranscription, out, stats, status: str,
                 solver: str, build_s: float, solve_s: float, label: str = "") -> Solution:
    """The Solution of a finished NLP solve (IPOPT or fatrop): re-simulation, checks, costates, warm start.

    The result is converged iff the solver converged, the re-simulated terminal error is <= terminal_tol and
    no path constraint is violated by more than terminal_tol."""
    w = np.array(out["x"]).ravel() * tr.w_scale
    Xn, U, _ = tr.layout.unpack(w)
    h = float(w[tr.layout.ih]) if tr.layout.ih is not None else problem.h
    lam_g = np.array(out["lam_g"]).ravel()
    g_phys = np.array(out["g"]).ravel() * tr.g_scale
    Xsim, res = problem.disc.simulate(problem.X0, U, problem.steps_of(h), problem.N)
    err = terminal_error(Xsim[-1], problem, T=problem.N * h)
    traj = trajectory(problem, Xsim, h)
    worst_cayley = float(np.max(res)) if res.size else 0.0
    result, message = _verdict(problem, status, solver, Xsim, res, h, err, options)
    stats_out = {
        "solver_status": status,
        "kkt_tol": float(options.tol),
        "initial_guess": label or options.initial_guess,
        "cayley_variables": tr.layout.with_c,
        "n_variables": int(tr.layout.n),
        "n_constraints": int(tr.nlp.ng),
        "max_defect": float(np.abs(g_phys[tr.defect_rows.ravel()]).max()),
        "nlp_terminal_error": terminal_error(Xn[:, -1], problem, T=problem.N * h),
        "max_cayley_residual": worst_cayley,
        "jit": bool(tr.nlp.compiled),
        **solve_time_split(stats, solve_s),
    }
    if problem.free_time:
        stats_out["T"] = problem.N * h
    times = traj.t[1:] if U.shape[1] == problem.N else traj.t
    activity = control_activity(problem.control, U, quadrature_weights(problem.scheme, problem.N, problem.steps_of(h)),
                                times)
    if activity:
        stats_out["bounds"] = activity
    if problem.constraints:
        stats_out["constraints"] = _constraint_report(problem, traj, tr, lam_g)
        worst = min(c["min_margin"] for c in stats_out["constraints"])
        stats_out["min_constraint_margin"] = worst
        if result is Result.converged and worst < -options.terminal_tol:
            result = Result.terminal_error
            message += f"; a path constraint is violated on the re-simulation by {-worst:.2e}"
    costates = tr.costates(Xn, lam_g)
    cost = objective_value(problem, U, h)
    point = Point(tr.point_key, np.array(out["x"]).ravel(), lam_g, np.array(out["lam_x"]).ravel()) \
        if "lam_x" in out else None
    attempt = Attempt(label, result, int(stats.get("iter_count", 0)), cost if result.successful else float("nan"),
                      build_s, solve_s)
    return Solution(method="direct", solver=solver, result=result, verdict=message, trajectory=traj, cost=cost,
                    terminal_error=err, problem=problem, controls=U, costates=costates,
                    history=ipopt_history(stats, tr.scales.objective), stats=stats_out, trace=(attempt,),
                    warm=start_of(traj.t, Xsim, U, problem.scheme, "direct", multipliers=tr.multipliers(lam_g),
                                  nlp_key=tr.nlp.key, point=point, costates=costates))


def _constraint_report(problem: Problem, traj: Trajectory, tr: SmoothTranscription, lam_g: np.ndarray) -> list[dict]:
    """Per path constraint: kind, the minimum margin on the re-simulated trajectory (its units), the
    nodes where it is active (margin within 1e-6 of the constraint's scale) and the largest
    multiplier (physical units of the cost per unit of the smooth form g >= 0)."""
    out = []
    for con, rows in zip(problem.constraints, tr.constraint_rows):
        margin = con.margin(traj)
        mult = np.abs(tr.scales.objective * lam_g[rows] / tr.g_scale[rows])
        active = np.flatnonzero(margin[1:] <= 1e-6 * max(1.0, np.abs(margin).max())) + 1
        out.append({"kind": con.kind, "dimension": con.dimension, "min_margin": float(margin.min()),
                    "active_nodes": int(active.size),
                    "active_times": [float(traj.t[active[0]]), float(traj.t[active[-1]])] if active.size else [],
                    "max_multiplier": float(mult.max()) if mult.size else 0.0})
    return out
