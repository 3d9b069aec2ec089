"""fatrop on the stage-ordered NLP of the direct method (fixed-time effort problems to a state target without
bounds or path constraints); IPOPT is its fallback (transcription.methods.direct.solve)."""
from __future__ import annotations

import time
from typing import Any, Callable

import casadi as ca
import numpy as np

from ...guess import Guess
from ...layout import NX
from ...options import DirectOptions, raw_solver_value
from ...problem import Problem, TargetState
from ...results import Solution
from .solution import nlp_solution
from .transcription import SmoothTranscription

#: why fatrop is not used for a problem it does not cover (IPOPT solves it)
NOT_COVERED = "fatrop is used for fixed-time effort problems to a state target without bounds or path constraints"


def covers(problem: Problem) -> bool:
    """Whether fatrop's stage-ordered NLP covers ``problem`` (:data:`NOT_COVERED`)."""
    c = problem.control
    return not (problem.free_time or problem.constraints or c.objective != "effort" or c.bounded
                or not isinstance(problem.terminal, TargetState))


def try_fatrop(problem: Problem, options: DirectOptions, guess: Callable[[], Guess]) -> tuple[Solution | None, dict]:
    """fatrop from the first guess of the plan: (its Solution, {}) if it converged, else (None, what the IPOPT
    fallback reports: fatrop_fallback, fatrop_status, fatrop_message, fatrop_build_s, fatrop_solve_s)."""
    if not covers(problem):
        return None, {"fatrop_fallback": True, "fatrop_status": "not_applicable", "fatrop_build_s": 0.0,
                      "fatrop_solve_s": 0.0, "fatrop_message": NOT_COVERED}
    return _solve_fatrop(problem, options, guess())


def _fatrop_solver(tr: SmoothTranscription, options: DirectOptions) -> tuple[ca.Function, np.ndarray, np.ndarray]:
    """fatrop on the stage-ordered transcription: rows in stage order [gap_0, path_0, ..., path_N]
    with gap_k = s_{k+1} - Phi(s_k, q_k) (the dynamics rows negated, then the LGVI lifting rows),
    path_k = the Cayley rows (stage 0: and X_0 - X0), path_N the terminal rows; every row an
    equality.  CasADi's fatrop interface derives the Jacobian and Hessian from the graph.
    Returns (solver, row permutation, row signs) so that g_fatrop = sign * g[perm]."""
    nlp, lay, N = tr.nlp, tr.layout, tr.problem.N
    dyn, term, init = nlp.rows("dynamics"), nlp.rows("terminal")[:, 0], nlp.rows("initial")[:, 0]
    lift = nlp.rows("lift") if "lift" in [b.name for b in nlp.blocks] else np.zeros((0, N), dtype=int)
    perm, sign = [], []
    for k in range(N):
        gap = [dyn[:NX, k], lift[:, k]]
        path = [dyn[NX:, k]] + ([init] if k == 0 else [])
        for part, s in ((gap[0], -1.0), (gap[1], 1.0), *((p, 1.0) for p in path)):
            perm += list(part)
            sign += [s] * len(part)
    perm += list(term)
    sign += [1.0] * len(term)
    perm, sign = np.array(perm), np.array(sign)
    g = ca.DM(sign) * nlp.g[perm.tolist()]
    fat = {"tol": float(options.tol), "constr_viol_tol": 1e-2 * float(options.tol), "max_iter": int(options.max_iter),
           "print_level": 0, **{k: raw_solver_value(v) for k, v in options.fatrop_options.items()}}
    npath = dyn.shape[0] - NX
    nlp_opts = {"equality": [True] * len(perm), "expand": bool(options.fatrop_expand), "print_time": False, "fatrop": fat,
                "structure_detection": "manual", "N": N, "nx": [lay.ns] * (N + 1), "nu": [lay.nq] * N + [0],
                "ng": [npath + NX] + [npath] * (N - 1) + [len(term)]}
    return ca.nlpsol("direct_fatrop", "fatrop", {"x": nlp.w, "f": nlp.f, "g": g}, nlp_opts), perm, sign


def _solve_fatrop(problem: Problem, options: DirectOptions, guess: Guess) -> tuple[Solution | None, dict[str, Any]]:
    """fatrop on the stage-ordered NLP; (Solution, {}) if it converged, else (None, fallback info)."""
    t0 = time.perf_counter()
    try:
        tr = SmoothTranscription(problem, options, stage_order=True)
        solver, perm, sign = _fatrop_solver(tr, options)
    except RuntimeError as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        return None, {"fatrop_fallback": True, "fatrop_status": "build_failed", "fatrop_message":
                      f"fatrop could not be set up ({msg[:300]})", "fatrop_build_s": time.perf_counter() - t0,
                      "fatrop_solve_s": 0.0}
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        out = solver(x0=tr.initial_point(guess), lbx=tr.lbx, ubx=tr.ubx, lbg=0.0, ubg=0.0)
        stats = solver.stats()
        status = "Solve_Succeeded" if stats.get("success") else f"fatrop_{stats.get('return_status', 'failed')}"
    except RuntimeError as exc:
        out, stats, status = None, {}, f"fatrop_error: {str(exc).strip().splitlines()[-1][:200] if str(exc).strip() else ''}"
    solve_s = time.perf_counter() - t0
    sol = None
    if out is not None and all(np.all(np.isfinite(np.array(out[k]))) for k in ("x", "lam_g")):
        lam = np.zeros(tr.nlp.ng)
        lam[perm] = sign * np.array(out["lam_g"]).ravel()
        gval = np.zeros(tr.nlp.ng)
        gval[perm] = sign * np.array(out["g"]).ravel()
        out = {"x": out["x"], "lam_g": lam, "g": gval}
        sol = nlp_solution(problem, options, tr, out, stats, status, "fatrop", build_s, solve_s)
        if sol.converged:
            sol.stats["fatrop_fallback"] = False
            return sol, {}
    why = sol.message if sol is not None else status
    return None, {"fatrop_fallback": True, "fatrop_status": status, "fatrop_message": f"fatrop did not converge ({why})",
                  "fatrop_build_s": build_s, "fatrop_solve_s": solve_s}
