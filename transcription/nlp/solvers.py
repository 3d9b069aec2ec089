"""The NLP solvers' set-up shared by every NLP of the project: IPOPT's options and solver on a
:class:`~transcription.nlp.structured.StructuredNLP`, the progress callback, the iteration history and the
split of a solve's time."""
from __future__ import annotations

from typing import Any, Callable

import casadi as ca
import numpy as np

from ..options import DirectOptions, raw_solver_value
from ..outcome import Iterate
from .structured import StructuredNLP

#: MUMPS settings for this already scaled, banded KKT system: AMD ordering, no permuting scaling, no row/column
#: scaling (E3 N = 1000: IPOPT call 1.9 s -> 0.7 s; docs/performance.md, docs/bench_notes.md).  Raw ``options``
#: override them.
MUMPS_DEFAULTS: dict[str, Any] = {"mumps_permuting_scaling": 0, "mumps_pivot_order": 0, "mumps_scaling": 0}


#: relative objective change per iteration below which an 'acceptable' iterate may end the solve (IPOPT's default,
#: 1e20, ends it however fast the objective still moves; docs/everyday.md, phasing_5_orbits)
ACCEPTABLE_OBJ_CHANGE_TOL = 1e-12


def ipopt_options(options: DirectOptions, warm_duals: bool = False) -> dict[str, Any]:
    """IPOPT options of a direct solve: tolerances, the exact Hessian, MUMPS_DEFAULTS, then the raw
    ``options`` (true/false become yes/no).  constr_viol_tol: the defects accumulate over N steps of the
    re-simulation, so they are driven well below tol.  acceptable_obj_change_tol: IPOPT stops at its 'acceptable'
    level only at a round-off floor, not while it still converges slowly."""
    ipopt = {"tol": float(options.tol), "constr_viol_tol": 1e-2 * float(options.tol), "max_iter": int(options.max_iter),
             "acceptable_obj_change_tol": ACCEPTABLE_OBJ_CHANGE_TOL, "print_level": 0, "sb": "yes",
             "hessian_approximation": "exact", **MUMPS_DEFAULTS}
    ipopt.update({k: raw_solver_value(v) for k, v in options.options.items()})
    if warm_duals:
        ipopt.setdefault("warm_start_init_point", "yes")
    return ipopt


def make_ipopt(name: str, nlp: StructuredNLP, ipopt: dict[str, Any], progress: Callable[[Iterate], None] | None,
               obj_scale: float, phase: str = "") -> ca.Function:
    """An IPOPT nlpsol on a StructuredNLP with its block-assembled derivatives; with ``progress``, one
    :class:`ProgressCallback` record per iteration, under ``phase``.  (The bundled OpenBLAS keeps its own thread
    count: docs/mathematics.md §24.)"""
    nlp_opts: dict[str, Any] = {"print_time": False, "ipopt": ipopt, "show_eval_warnings": False,
                                **nlp.derivative_functions()}
    if progress is not None:
        # the callback must outlive every solver made with it: each is kept on the NLP object (a solver kept and
        # reused after another was made on the same NLP lost its callback when one attribute held them, and IPOPT
        # stopped at its first iteration: "Callback object has been deleted")
        callback = ProgressCallback(nlp.n, nlp.ng, progress, obj_scale, nlp.lbg, nlp.ubg, phase,
                                    int(ipopt.get("max_iter", 0)))
        nlp.__dict__.setdefault("callbacks", []).append(callback)
        nlp_opts["iteration_callback"] = callback
    return ca.nlpsol(name, "ipopt", {"x": nlp.w, "f": nlp.f, "g": nlp.g}, nlp_opts)


class ProgressCallback(ca.Callback):
    """NLP iteration callback: one :class:`~transcription.results.solution.Iterate` per iteration to ``fn``
    (cost = objective x ``obj_scale``, residual = max |g - bounds violation| of the scaled rows; ``phase``;
    ``budget``: the solver's max_iter, the most iterations after iteration 0)."""

    def __init__(self, nx: int, ng: int, fn: Callable[[Iterate], None], obj_scale: float, lbg, ubg, phase: str = "",
                 budget: int = 0):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.fn, self.obj_scale, self.k = nx, ng, fn, obj_scale, 0
        self.lbg, self.ubg, self.phase, self.budget = np.asarray(lbg, float), np.asarray(ubg, float), phase, budget
        self.construct("nlp_progress", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        # Ctrl-C (KeyboardInterrupt here or from ``fn``) returns 1 (IPOPT: User_Requested_Stop): an exception
        # escaping a callback would make CasADi warn on stderr; the caller keeps its own record of the signal
        try:
            g = np.array(arg[ca.nlpsol_out().index("g")]).ravel()
            viol = np.maximum(np.maximum(self.lbg - g, g - self.ubg), 0.0) if g.size else np.zeros(0)
            f = float(arg[ca.nlpsol_out().index("f")])
            self.fn(Iterate(iteration=self.k, cost=f * self.obj_scale, residual=float(viol.max()) if viol.size else 0.0,
                            phase=self.phase, budget=self.budget))
            self.k += 1
            return [0]
        except KeyboardInterrupt:
            return [1]


def ipopt_history(stats: dict, obj_scale: float, phase: str = "") -> list[Iterate]:
    """The IPOPT (or fatrop) iterations recorded in a solver's stats as Iterates."""
    it = stats.get("iterations", {}) or {}
    keys = ("obj", "inf_pr", "inf_du", "alpha_pr", "regularization_size")
    cols = [it.get(k, []) for k in keys]
    n = max((len(c) for c in cols), default=0)
    cols = [list(c) + [float("nan")] * (n - len(c)) for c in cols]
    return [Iterate(iteration=i, cost=float(o) * obj_scale, residual=float(p), dual=float(d), step=float(a),
                    regularization=float(r), phase=phase) for i, (o, p, d, a, r) in enumerate(zip(*cols))]


def solve_time_split(stats: dict, solve_s: float) -> dict:
    """Where a solve's wall time went, from CasADi's solver stats (IPOPT and fatrop alike).

    ``evaluations_s``: wall time in the NLP Functions (the ``t_wall_nlp_*`` stats), split in
    ``evaluations_by_function``; ``solver_internal_s``: the rest of ``solve_s``; for fatrop ``fatrop_own_s``: its
    ``time_total`` less its evaluation callbacks.
    """
    by = {k[len("t_wall_"):]: float(v) for k, v in stats.items() if k.startswith("t_wall_nlp_")}
    ev = float(sum(by.values()))
    out = {"evaluations_s": ev, "solver_internal_s": max(float(solve_s) - ev, 0.0), "evaluations_by_function": by}
    fat = stats.get("fatrop")
    if isinstance(fat, dict) and "time_total" in fat:
        cb = sum(float(fat.get(k, 0.0)) for k in ("eval_hess_time", "eval_jac_time", "eval_cv_time", "eval_grad_time",
                                                   "eval_obj_time"))
        out["fatrop_own_s"] = max(float(fat["time_total"]) - cb, 0.0)
    return out
