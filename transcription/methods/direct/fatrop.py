"""fatrop on the stage-ordered NLP of the direct method (fixed-time effort problems to a state or orbit target
without bounds or path constraints: :func:`covers`; an objective says why it is not covered, ``Objective.fatrop``);
IPOPT is its fallback (transcription.solve)."""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from ...geometry.state import NX
from ...options import DirectOptions, raw_solver_value
from ...ocp import Problem, TargetOrbit, TargetState
from ...outcome import Result
from ...results.solution import Solution
from ...results.start import Start
from ..base import failed_solution
from .solution import nlp_solution
from ...nlp.transcription import SmoothTranscription

#: why fatrop is not used for a problem it does not cover (IPOPT solves it; an objective says its own reason)
NOT_COVERED = ("fatrop is used for fixed-time effort problems to a state or orbit target without bounds or path "
               "constraints")


def not_covered(problem: Problem) -> str:
    """Why fatrop's stage-ordered NLP is not used for ``problem`` ("" if it is): its objective's reason
    (``Objective.fatrop``, docs/mathematics.md §20), else :data:`NOT_COVERED`.  The stage form takes bounds' rows
    too, but fatrop stalls on an active bound (docs/mathematics.md §10, *The direct method*)."""
    c = problem.control
    if c.objective.fatrop:
        return c.objective.fatrop
    if problem.free_time or problem.constraints or c.bounded or not isinstance(problem.terminal, (TargetState,
                                                                                                 TargetOrbit)):
        return NOT_COVERED
    return ""


def covers(problem: Problem) -> bool:
    """Whether fatrop's stage-ordered NLP covers ``problem`` (:func:`not_covered`)."""
    return not not_covered(problem)


def stage_rows(tr: SmoothTranscription) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The rows of the stage-ordered transcription in fatrop's order, [gap_0, path_0, ..., gap_{N-1},
    path_{N-1}, path_N]: gap_k = s_{k+1} - Phi(s_k, q_k) (the dynamics rows negated, then the LGVI lifting
    rows), path_k every other row whose variables are all in stage k (``layout.stage_of``): the Cayley rows of
    step k, X_0 - X0 (k = 0), the control-node rows (norm bounds, fuel epigraph) of the nodes whose copy of
    u_j and slacks sit in q_k, the terminal rows (k = N).  Returns (perm, sign, ng): g_fatrop = sign * g[perm],
    ng (N + 1,) the path rows per stage.  A row that spans two stages (other than a gap) raises ValueError."""
    nlp, lay, N = tr.nlp, tr.layout, tr.problem.N
    dyn = nlp.rows("dynamics")
    names = [b.name for b in nlp.blocks]
    lift = nlp.rows("lift") if "lift" in names else np.zeros((0, N), dtype=int)
    path: list[list[int]] = [list(dyn[NX:, k]) for k in range(N)] + [[]]
    for blk in nlp.blocks:
        if blk.name in ("dynamics", "lift") or blk.nr == 0:
            continue
        st = lay.stage_of[blk.idx]
        if np.any(st.min(axis=0) != st.max(axis=0)):
            raise ValueError(f"block {blk.name} spans two stages: fatrop takes path rows of one stage")
        rows = nlp.rows(blk.name)
        for m, k in enumerate(st[0]):
            path[k] += list(rows[:, m])
    perm, sign = [], []
    for k in range(N + 1):
        if k < N:
            perm += list(dyn[:NX, k]) + list(lift[:, k])
            sign += [-1.0] * NX + [1.0] * lift.shape[0]
        perm += path[k]
        sign += [1.0] * len(path[k])
    return np.array(perm), np.array(sign), [len(p) for p in path]


def _fatrop_solver(tr: SmoothTranscription, options: DirectOptions) -> tuple[ca.Function, np.ndarray, np.ndarray]:
    """fatrop on the stage-ordered transcription, rows in :func:`stage_rows`' order (gaps and equality rows
    with lbg = ubg, the norm bounds and |d|^2 <= 1 inequality rows with their bounds; the variable bounds --
    the fuel magnitudes s >= 0, box bounds -- stay lbx/ubx, which CasADi's interface hands to fatrop per
    stage).  CasADi's fatrop interface derives the Jacobian and Hessian from the graph.  Returns (solver, row
    permutation, row signs) so that g_fatrop = sign * g[perm]."""
    nlp, lay, N = tr.nlp, tr.layout, tr.problem.N
    perm, sign, ng = stage_rows(tr)
    g = ca.DM(sign) * nlp.g[perm.tolist()]
    fat = {"tol": float(options.tol), "constr_viol_tol": 1e-2 * float(options.tol), "max_iter": int(options.max_iter),
           "print_level": 0, **{k: raw_solver_value(v) for k, v in options.fatrop_options.items()}}
    lbg, ubg = stage_bounds(tr, perm, sign)
    nlp_opts = {"equality": (lbg == ubg).tolist(), "expand": bool(options.fatrop_expand), "print_time": False,
                "fatrop": fat, "structure_detection": "manual", "N": N, "nx": [lay.ns] * (N + 1), "nu": lay.nu,
                "ng": ng}
    return ca.nlpsol("direct_fatrop", "fatrop", {"x": nlp.w, "f": nlp.f, "g": g}, nlp_opts), perm, sign


def stage_bounds(tr: SmoothTranscription, perm: np.ndarray, sign: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """lbg, ubg of the rows sign * g[perm] (a negated row's bounds swap and change sign)."""
    lo, hi = tr.nlp.lbg[perm], tr.nlp.ubg[perm]
    return np.where(sign > 0, lo, -hi), np.where(sign > 0, hi, -lo)


def solve_fatrop(problem: Problem, options: DirectOptions, start: Start, label: str) -> Solution:
    """fatrop on the stage-ordered NLP from ``start`` (on the problem's grid): its Solution, converged or not; a
    problem it does not cover (:func:`not_covered`) or an NLP it cannot set up is Result.not_applicable or
    Result.solver_failed, saying why (a strategy then falls back to IPOPT)."""
    why = not_covered(problem)
    if why:
        return failed_solution(problem, "direct", "fatrop", Result.not_applicable, why)
    t0 = time.perf_counter()
    try:
        tr = SmoothTranscription(problem, options, stage_order=True)
        solver, perm, sign = _fatrop_solver(tr, options)
    except RuntimeError as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        return failed_solution(problem, "direct", "fatrop", Result.solver_failed,
                               f"fatrop could not be set up ({msg[:300]})")
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        lbg, ubg = stage_bounds(tr, perm, sign)
        out = solver(x0=tr.initial_point(start), lbx=tr.lbx, ubx=tr.ubx, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        status = "Solve_Succeeded" if stats.get("success") else f"fatrop_{stats.get('return_status', 'failed')}"
    except RuntimeError as exc:
        out, stats, status = None, {}, f"fatrop_error: {str(exc).strip().splitlines()[-1][:200] if str(exc).strip() else ''}"
    solve_s = time.perf_counter() - t0
    if out is None or not all(np.all(np.isfinite(np.array(out[k]))) for k in ("x", "lam_g")):
        return failed_solution(problem, "direct", "fatrop", Result.solver_failed, f"fatrop did not converge ({status})")
    lam = np.zeros(tr.nlp.ng)
    lam[perm] = sign * np.array(out["lam_g"]).ravel()
    gval = np.zeros(tr.nlp.ng)
    gval[perm] = sign * np.array(out["g"]).ravel()
    return nlp_solution(problem, options, tr, {"x": out["x"], "lam_g": lam, "g": gval}, stats, status, "fatrop",
                        build_s, solve_s, label)
