"""The one entry point of the method layer: ``solve(problem, method)``, plus ``simulate`` and ``compare``.

Every front end -- the Python API (``se3ocp.solve``), the CLI, sweeps, scripts -- calls
:func:`solve`; it dispatches on the method, runs both methods for ``method='both'`` (the direct
solution then starts the indirect method when ``initial_costate: from_direct``) and compares them.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .direct import solve_direct
from .feasibility import necessary_conditions, step_failure
from .indirect import solve_indirect
from .layout import NU, unpack_states
from .lgvi import CAYLEY_TOL
from .lie import orthogonality_error
from .options import DirectOptions, IndirectOptions
from .problem import Problem, terminal_error
from .results import Iterate, Result, SolveError, Solution, Trajectory

METHODS = ("direct", "indirect", "both")
#: relative cost difference above which compare reports different extremals
MISMATCH_COST_RTOL = 1e-6

Progress = Callable[[str, Iterate], None]


@dataclass
class Comparison:
    """Both methods on one problem: their Solutions and how far they agree.

    cost_relative_difference = |J_d - J_i| / max(|J_d|, |J_i|); control_max_difference_relative =
    max |U_d - U_i| / max |U_d|; same_extremal: both converged and the costs agree to
    MISMATCH_COST_RTOL; verdict: a sentence (which one is lower if they differ)."""

    direct: Solution
    indirect: Solution
    cost_relative_difference: float
    control_max_difference_relative: float | None
    same_extremal: bool
    verdict: str

    @property
    def solutions(self) -> dict[str, Solution]:
        return {"direct": self.direct, "indirect": self.indirect}

    @property
    def converged(self) -> bool:
        return self.direct.converged and self.indirect.converged

    def summary(self) -> dict:
        return {"cost_relative_difference": self.cost_relative_difference,
                "control_max_difference_relative": self.control_max_difference_relative,
                "same_extremal": self.same_extremal, "verdict": self.verdict}


def compare(a: Solution, b: Solution) -> Comparison:
    """Cost and control differences of two solutions of one problem; flags different extremals."""
    rel = abs(a.cost - b.cost) / max(abs(a.cost), abs(b.cost), 1e-300)
    du = None
    if a.controls is not None and b.controls is not None and a.controls.shape == b.controls.shape:
        du = float(np.abs(a.controls - b.controls).max() / max(np.abs(a.controls).max(), 1e-300))
    both = a.converged and b.converged
    same = bool(both and rel <= MISMATCH_COST_RTOL)
    na = next((s for s in (a, b) if s.result is Result.not_applicable), None)
    if na is not None:
        verdict = f"not comparable: {na.message.split(';')[0]}"
    elif not both:
        verdict = "not comparable: at least one method did not converge"
    elif same:
        verdict = "agree: same extremal"
    else:
        lo, hi = sorted([a, b], key=lambda s: s.cost)
        verdict = (f"MISMATCH: the methods reached different extremals ({lo.method} cost {lo.cost:.6g} vs "
                   f"{hi.method} cost {hi.cost:.6g}, ratio {hi.cost / lo.cost:.3g}); the higher one is not the "
                   f"optimum. Try solver.indirect.initial_costate=from_direct.")
    d, i = (a, b) if a.method == "direct" else (b, a)
    return Comparison(d, i, float(rel), du, same, verdict)


def _check_method(problem: Problem, method: str):
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if problem.kind is None:
        raise ValueError("the problem has no terminal target and no control: there is nothing to solve (simulate it)")
    if method != "direct" and problem.kind == "impulsive":
        raise ValueError(f"method {method!r}: the indirect method applies to smooth control; impulsive maneuvers are "
                         "solved by method='direct'")


def solve(problem: Problem, method: str = "direct", *, direct: DirectOptions | None = None,
          indirect: IndirectOptions | None = None, progress: Progress | None = None, warm_start=None,
          throw: bool = False) -> Solution | Comparison:
    """Solve ``problem`` by ``method`` ('direct', 'indirect' or 'both').

    direct, indirect: the options of each method (defaults if None).  progress: called as
    progress(method, Iterate) during the solve.  warm_start: a previous Solution of the same method
    and size (continuation), or for the indirect method 12 numbers (lambda_0).  Returns a Solution,
    or for 'both' a :class:`Comparison`.  Failures are data (``solution.result``); with
    ``throw=True`` a Solution that is not successful raises :class:`~transcription.results.SolveError`.
    """
    _check_method(problem, method)
    reason = necessary_conditions(problem)
    if reason is not None:  # provably no solution: said at once, with the reason (feasibility.py)
        out = _infeasible(problem, method, reason)
        return raise_unconverged(out) if throw else out
    direct = direct or DirectOptions()
    indirect = indirect or IndirectOptions()

    def tagged(name):
        return (lambda rec: progress(name, rec)) if progress is not None else None

    out: Solution | Comparison
    if method == "direct":
        out = solve_direct(problem, direct, tagged("direct"), warm_start=warm_start)
    elif method == "indirect":
        out = solve_indirect(problem, indirect, tagged("indirect"), warm_start=warm_start, direct_options=direct)
    else:
        dsol = solve_direct(problem, direct, tagged("direct"))
        hand_off = dsol if indirect.initial_costate == "from_direct" and dsol.costates is not None else None
        isol = solve_indirect(problem, indirect, tagged("indirect"), warm_start=hand_off, direct_options=direct)
        out = compare(dsol, isol)
    return raise_unconverged(out) if throw else out


def _infeasible(problem: Problem, method: str, reason: str) -> Solution | Comparison:
    """The Solution(s) of a problem a necessary condition rules out: Result.infeasible, the reason, no
    iteration; the trajectory is the free motion from the initial state (what the record can show)."""
    free = simulate(problem)

    def one(name: str) -> Solution:
        return Solution(method=name, solver="necessary conditions", result=Result.infeasible,
                        message=f"provably infeasible (checked before solving; no solver was run): {reason}",
                        trajectory=free.trajectory, cost=float("nan"), terminal_error=free.terminal_error,
                        iterations=0, build_s=0.0, solve_s=free.solve_s, problem=problem)

    return compare(one("direct"), one("indirect")) if method == "both" else one(method)


def raise_unconverged(out: Solution | Comparison) -> Solution | Comparison:
    """``out`` unchanged if every Solution in it converged, else SolveError of the first that did not
    (``solve(..., throw=True)``)."""
    for s in (out.solutions.values() if isinstance(out, Comparison) else [out]):
        if not s.converged:
            raise SolveError(s)
    return out


def simulate(problem: Problem, controls: np.ndarray | None = None) -> Solution:
    """The motion of ``problem``'s discretization from X0 under ``controls`` (6 x n_controls; None:
    free motion) over its horizon.

    Returns a Solution with method 'simulate': result converged (the motion is a solution of the
    discrete equations), cayley_failed (a step's Cayley equation was not solved to CAYLEY_TOL: h
    too large) or non_finite; terminal_error = how far the motion misses the problem's terminal
    target (nan without one); stats: orthogonality, determinant, relative energy errors, the
    largest Cayley residual.
    """
    disc, N, h = problem.disc, problem.N, problem.h
    t0 = time.perf_counter()
    U = None if controls is None else np.asarray(controls, dtype=float).reshape(NU, -1)
    X, res = disc.simulate(problem.X0, U, h, N)
    run_s = time.perf_counter() - t0
    model = problem.model
    E = np.array(model.energy().map(X.shape[0])(X.T)).ravel()
    rel = np.abs(E - E[0]) / max(abs(E[0]), 1e-300)
    orth, det = orthogonality_error(unpack_states(X).R)
    worst = float(res.max()) if res.size else 0.0
    finite = np.all(np.isfinite(X), axis=1)
    if finite.all() and worst <= CAYLEY_TOL:
        result, message = Result.converged, "simulated: every step solves the discrete equations"
    elif not finite.all() and (not np.isfinite(res).all() or res[np.isfinite(res)].max(initial=0) <= CAYLEY_TOL):
        k = int(np.argmin(finite))
        result = Result.non_finite
        message = (f"the state became non-finite at node {k} (overflow or a singular potential: check the model "
                   "parameters and that the body stays away from the central mass)")
    else:  # a step's Cayley equation not solved: the fold of the scheme, or data no step size can fix
        result, message = step_failure(problem, X, res, h)
    miss = terminal_error(X[-1], problem) if problem.terminal is not None and finite.all() else float("nan")
    stats = {"max_orthogonality_error": float(orth.max()), "max_determinant_error": float(det.max()),
             "energy_initial": float(E[0]), "max_relative_energy_error": float(np.nanmax(rel)),
             "final_relative_energy_error": float(rel[-1]), "max_cayley_residual": worst}
    return Solution(method="simulate", solver=disc.scheme, result=result, message=message,
                    trajectory=Trajectory(t=h * np.arange(N + 1), X=X, mass=model.mass, inertia=model.inertia),
                    cost=float("nan"), terminal_error=miss, iterations=0, build_s=0.0, solve_s=run_s, problem=problem,
                    controls=U, stats=stats)
