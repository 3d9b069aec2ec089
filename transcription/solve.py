"""The one entry point of the method layer: ``solve(problem, method)``, plus ``simulate`` and ``compare``.

Every front end -- the Python API (``se3ocp.solve``), the CLI, sweeps, scripts -- calls :func:`solve`.  It
is a registry: each method name ('direct', 'indirect') stands for the implementations of
:class:`~transcription.methods.base.Method` listed in :data:`METHODS`, and the one whose ``kind`` is the
problem's runs it (the direct method: its NLP for smooth control, the impulsive solver for impulsive
control).  Which methods can solve which problems is decided in one place, :func:`not_covered`.  For
``method='both'`` it runs both on the same discretization and compares them; the direct solution starts
the indirect method when ``initial_costate: from_direct`` (as it does for 'indirect' alone).
"""
from __future__ import annotations

import dataclasses
import itertools
import time
from dataclasses import dataclass

import numpy as np

from .strategy.refine import AccuracyOptions, attach_checks, out_of_reach, refine
from .ocp.feasibility import necessary_conditions, step_failure
from .geometry.state import NU, unpack_states
from .dynamics.lgvi import CAYLEY_TOL
from .geometry.so3 import orthogonality_error
from .methods.base import Method, Progress, clocked, failed_solution, phased
from .methods.direct import DIRECT
from .methods.impulsive import IMPULSIVE
from .methods.indirect import INDIRECT
from .methods.indirect.solve import needs_fallback, with_fallback
from .options import DirectOptions, IndirectOptions
from .ocp import Problem, terminal_error
from .results.solution import Attempt, Result, SolveError, Solution, html_table, trajectory
from .results.start import WarmStart, as_warm_start

#: the registry: each method name and its implementations (one per kind of control)
METHODS: dict[str, tuple[Method, ...]] = {"direct": (DIRECT, IMPULSIVE), "indirect": (INDIRECT,)}
#: the implementations (method name, kind of control) that take a non-uniform mesh, step k with its own h_k
#: (issue 26, docs/mathematics.md §16); the others refuse one in :func:`not_covered`
ON_A_MESH = {("direct", "smooth"), ("indirect", "smooth")}
#: what ``solve`` accepts: a method name, or 'both'
METHOD_NAMES = ("direct", "indirect", "both")
#: relative cost difference above which compare reports different extremals
MISMATCH_COST_RTOL = 1e-6
#: IPOPT's tol of the direct method's re-solve (from its own solution, primal and dual) before 'both' declares
#: a mismatch: a solution at a looser tol can sit inside an active bound by ~sqrt(tol) and cost more
#: (:func:`reconcile`)
RETIGHTEN_TOL = 1e-12


class NotCovered(ValueError):
    """:func:`solve`'s refusal of a method that cannot run on the problem at all: :func:`not_covered`'s sentence.
    A ValueError, so that whoever catches ValueError still does; a front end that tells bad input from a defect
    catches this class (the CLI: one line naming the file's field, exit 2)."""


class OutOfReach(ValueError):
    """:func:`solve`'s refusal of an accuracy its scheme cannot reach within the cap on N, before solving:
    :func:`~transcription.strategy.refine.out_of_reach`'s sentence (a ValueError, as :class:`NotCovered`)."""


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

    def __repr__(self) -> str:
        return (f"Comparison({self.verdict}; cost relative difference {self.cost_relative_difference:.1e}\n"
                f"  {self.direct!r}\n  {self.indirect!r})")

    def _repr_html_(self) -> str:
        return html_table([self.direct, self.indirect], caption=self.verdict,
                          footer=f"cost relative difference {self.cost_relative_difference:.1e}")


def compare(a: Solution, b: Solution) -> Comparison:
    """Cost and control differences of two solutions of one problem; flags different extremals."""
    rel = abs(a.cost - b.cost) / max(abs(a.cost), abs(b.cost), 1e-300)
    du = None
    if a.controls is not None and b.controls is not None and a.controls.shape == b.controls.shape:
        du = float(np.abs(a.controls - b.controls).max() / max(np.abs(a.controls).max(), 1e-300))
    both = a.converged and b.converged
    same = bool(both and rel <= MISMATCH_COST_RTOL)
    na = next((s for s in (a, b) if s.result is Result.not_applicable), None)
    d, i = (a, b) if a.method == "direct" else (b, a)
    if na is not None:
        verdict = f"not comparable: {na.message.split(';')[0]}"
    elif not both:
        verdict = "not comparable: at least one method did not converge"
    elif same:
        verdict = "agree: same extremal" + (f" ({_tolerances(d, i)})" if "retightened_from_tol" in d.stats else "")
    else:
        lo, hi = sorted([a, b], key=lambda s: s.cost)
        tip = ("Try solver.indirect.initial_costate=from_direct." if i.stats.get("initial_costate") != "from_direct"
               else "Try another solver.direct.initial_guess (the indirect method started from the direct solution).")
        verdict = (f"MISMATCH: the methods reached different extremals ({lo.method} cost {lo.cost:.6g} vs "
                   f"{hi.method} cost {hi.cost:.6g}, ratio {hi.cost / lo.cost:.3g}, relative difference {rel:.1e} > "
                   f"{MISMATCH_COST_RTOL:.0e}; {_tolerances(d, i)}); the higher one is not the optimum. {tip}")
    return Comparison(d, i, float(rel), du, same, verdict)


def _tolerances(d: Solution, i: Solution) -> str:
    """The tolerances the two solutions were solved to, for a verdict: the direct method's KKT tol (and the
    looser one it was re-solved from, :func:`reconcile`), the indirect method's final |z_N|."""
    parts = []
    if "kkt_tol" in d.stats:
        parts.append(f"direct at tol {d.stats['kkt_tol']:.0e}")
        if "retightened_from_tol" in d.stats:
            why = (f"where the costs were {d.stats['cost_difference_before_retightening']:.1e} apart"
                   if "cost_difference_before_retightening" in d.stats else d.stats.get("retightened_for", ""))
            parts[-1] += f", re-solved from its solution at tol {d.stats['retightened_from_tol']:.0e}, {why}"
    if "residual_norm" in i.stats:
        parts.append(f"indirect at |z_N| = {i.stats['residual_norm']:.1e}")
    return "; ".join(parts) or "tolerances unknown"


def _retightened(d: Solution, direct: DirectOptions, progress: Progress | None, why: str, **stats) -> Solution:
    """The direct Solution ``d`` re-solved at tol RETIGHTEN_TOL from its own solution (primal and dual), for
    :func:`reconcile` and :func:`fuel_retighten`; when it converges, it carries ``d``'s iterations and times too,
    ``d``'s attempts and itself as the last, ``stats['retightened_from_tol']`` and ``stats``, and a message that
    says ``why``."""
    tight = _run(d.problem, "direct", direct.replace(tol=RETIGHTEN_TOL), phased(progress, "retightened"), d.warm)
    if not tight.converged:
        return tight
    tight.stats.update(retightened_from_tol=float(direct.tol), **stats)
    tight.message = (f"{d.message.split(';')[0]}; re-solved at tol {RETIGHTEN_TOL:.0e} from it {why}: "
                     f"{tight.message.split(';')[0]}")
    tight.attempts = (*d.attempts, Attempt(f"its solution at tol {RETIGHTEN_TOL:.0e}", tight.result, tight.iterations,
                                           tight.cost))
    tight.iterations += d.iterations
    tight.build_s += d.build_s
    tight.solve_s += d.solve_s
    return tight


def reconcile(cmp: Comparison, direct: DirectOptions, progress: Progress | None = None) -> Comparison:
    """``cmp`` again after the direct method was re-solved at tol RETIGHTEN_TOL from its own solution (primal and
    dual), when both converged but their costs differ by more than MISMATCH_COST_RTOL and the direct tol was
    looser: a difference that the direct method's tolerance explains is not a mismatch.  The re-solve's
    iterations and time are added to the direct Solution; its stats say what it was re-solved from
    (``retightened_from_tol``, ``cost_difference_before_retightening``) and the verdict names the tolerances.
    Unchanged when there is nothing to re-solve or the re-solve does not converge (then ``stats['retighten']``
    of the direct Solution says so)."""
    d = cmp.direct
    if cmp.same_extremal or not cmp.converged or d.solver != "ipopt" or direct.tol <= RETIGHTEN_TOL or d.warm is None:
        return cmp
    tight = _retightened(d, direct, progress, f"before comparing (the costs were {cmp.cost_relative_difference:.1e} "
                                              f"apart)", cost_difference_before_retightening=cmp.cost_relative_difference)
    if not tight.converged:
        d.stats["retighten"] = f"the re-solve at tol {RETIGHTEN_TOL:.0e} ended {tight.result}"
        d.message += f"; {d.stats['retighten']}"
        return compare(d, cmp.indirect)
    return compare(tight, cmp.indirect)


# ---------------------------------------------------------------------------- the registry
def implementation(problem: Problem, name: str) -> Method | None:
    """The implementation of method ``name`` ('direct' or 'indirect') for the kind of ``problem``'s control
    (None if the method has none)."""
    return next((m for m in METHODS[name] if m.kind == problem.kind), None)


def not_covered(problem: Problem, method: str) -> str:
    """Why ``method`` ('direct', 'indirect' or 'both') cannot be run on ``problem`` at all, in one sentence
    ('' when it can): the one place that says which methods solve which problems (impulsive maneuvers: the
    direct method only; a motion without control: none).  ``solve`` raises NotCovered with it; the CLI and
    the sweeps report it as bad input (and the CLI narrows 'both' to the method that applies).  What a method does not cover *within* a problem it solves (the indirect method
    and path constraints) is not decided here: that method's Solution says so (Result.not_applicable)."""
    if method not in METHOD_NAMES:
        return f"method must be one of {', '.join(METHOD_NAMES)}, got {method!r}"
    if problem.kind is None:
        return "the problem has no terminal target and no control: there is nothing to solve (simulate it)"
    for name in (("direct", "indirect") if method == "both" else (method,)):
        if not problem.uniform and (name, problem.kind) not in ON_A_MESH:   # issue 26
            return f"a non-uniform mesh (Problem.mesh) is not supported yet by the {name} method: use uniform steps"
        if implementation(problem, name) is None:
            return METHODS[name][0].not_covered(problem)
    return ""


def _tagged(progress: Progress | None, name: str) -> Progress | None:
    """progress with each Iterate naming its method."""
    return None if progress is None else (lambda it: progress(dataclasses.replace(it, method=name)))


def _run(problem: Problem, name: str, options, progress: Progress | None, warm: WarmStart | None) -> Solution:
    return implementation(problem, name).solve(problem, options, warm=warm, progress=_tagged(progress, name))


def _indirect_after_direct(problem: Problem, indirect: IndirectOptions, progress: Progress | None,
                           dsol: Solution, direct_s: float | None) -> Solution:
    """The indirect method started from the direct solution (initial_costate: from_direct); with ``direct_s``
    (the direct solve was run for it) its stats say what the direct solve did."""
    isol = _run(problem, "indirect", indirect, progress, dsol.warm)
    if direct_s is not None:
        isol.stats.update(direct_solve_s=direct_s, direct_status=dsol.result.value, direct_cost=float(dsol.cost))
    return isol


def _fallback(problem: Problem, isol: Solution, direct: DirectOptions, indirect: IndirectOptions,
              progress: Progress | None, warm: WarmStart | None, dsol: Solution | None) -> Solution:
    """``isol`` if it succeeded or needs no fallback (:func:`~.methods.indirect.solve.needs_fallback`), else the
    indirect method started again from the direct solution ``dsol`` (solved here when None) -- the cold start's
    failure and the fallback in its attempts and message (:func:`~.methods.indirect.solve.with_fallback`).  A warm
    start is retried too when ``dsol`` is given ('both': the warm start came from elsewhere, e.g. refinement's previous
    level resampled onto this mesh, where the fuel raise's indirect start failed and this grid's direct solution
    converges in 2 iterations, docs/mathematics.md §19)."""
    if not needs_fallback(isol, indirect, warm, retry_warm=dsol is not None):
        return isol
    direct_s = None
    if dsol is None:
        t0 = time.perf_counter()
        dsol = _run(problem, "direct", direct, progress, None)
        direct_s = time.perf_counter() - t0
    retry = _run(problem, "indirect", indirect, progress, dsol.warm) if dsol.converged and dsol.warm else None
    return with_fallback(isol, retry, dsol, direct_s)


def solve(problem: Problem, method: str = "direct", *, direct: DirectOptions | None = None,
          indirect: IndirectOptions | None = None, progress: Progress | None = None,
          warm_start: Solution | WarmStart | None = None, throw: bool = False,
          accuracy: AccuracyOptions | None = None) -> Solution | Comparison:
    """Solve ``problem`` by ``method`` ('direct', 'indirect' or 'both').

    direct, indirect: the options of each method (defaults if None).  progress: called as progress(Iterate)
    during the solve, the Iterate naming its method (``Iterate.method``), its solve (``phase``: e.g. the direct
    method's starts, coarse grids and homotopy levels, a refinement level 'level 1 N=200', 'retightened') and the
    seconds since this call (``elapsed_s``).  warm_start: a previous Solution
    (its ``warm``) or a :class:`~transcription.results.start.WarmStart`, of either method and of any N and scheme (it
    is resampled; the Solution's message and ``stats['warm_start*']`` say what was reused): continuation,
    refinement, a hand-over between methods.  Returns a Solution, or for 'both' a :class:`Comparison`.
    Failures are data (``solution.result``); with ``throw=True`` a Solution that is not successful raises
    :class:`~transcription.results.solution.SolveError`.  A method that cannot solve the problem at all
    (:func:`not_covered`), or an accuracy out of reach (:func:`~transcription.strategy.refine.out_of_reach`), raises
    :class:`NotCovered` or :class:`OutOfReach` (ValueErrors) with the one-line answer.  accuracy: the continuous
    check and refinement to a tolerance (:class:`~transcription.strategy.refine.AccuracyOptions`; default: the
    check on, N fixed): every successful smooth-control Solution carries its continuous check (``sol.continuous``).
    """
    reason = not_covered(problem, method)
    if reason:
        raise NotCovered(reason)
    reason = necessary_conditions(problem)
    if reason is not None:  # provably no solution: said at once, with the reason (feasibility.py)
        out = _infeasible(problem, method, reason)
        return raise_unconverged(out) if throw else out
    direct = direct or DirectOptions()
    indirect = indirect or IndirectOptions()
    accuracy = accuracy or AccuracyOptions.default()
    reason = out_of_reach(problem, accuracy)      # a tolerance the scheme cannot reach: said before solving
    if reason:
        raise OutOfReach(reason)
    warm, note = as_warm_start(warm_start)
    progress = clocked(progress)
    if accuracy.accuracy is not None and problem.kind == "smooth":   # refinement to a tolerance (accuracy.py)
        names = ("direct", "indirect") if method == "both" else (method,)
        adaptive = accuracy.refinement == "adaptive" and all((n, problem.kind) in ON_A_MESH for n in names)
        levels = itertools.count()      # one call a level: numbered as refine's mesh history numbers them

        def level(p, w):
            return _dispatch(p, method, direct, indirect, phased(progress, f"level {next(levels)} N={p.N}"), w)

        out = refine(problem, level, accuracy, warm, adaptive=adaptive)
    else:
        out = _dispatch(problem, method, direct, indirect, progress, warm)
    if accuracy.continuous_check:
        attach_checks(out)
    if note:
        for s in (out.solutions.values() if isinstance(out, Comparison) else [out]):
            s.message += f"; {note}"
    return raise_unconverged(out) if throw else out


def _dispatch(problem: Problem, method: str, direct: DirectOptions, indirect: IndirectOptions,
              progress: Progress | None, warm: WarmStart | None) -> Solution | Comparison:
    """One solve of ``problem`` by ``method`` on its own grid (``solve`` without its checks and notes)."""
    out: Solution | Comparison
    if method == "direct":
        out = _run(problem, "direct", direct, progress, warm)
    elif method == "indirect" and (warm is not None or indirect.initial_costate != "from_direct"):
        out = _fallback(problem, _run(problem, "indirect", indirect, progress, warm), direct, indirect, progress,
                        warm, None)
    elif method == "indirect":                       # from_direct: the direct solution first
        t0 = time.perf_counter()
        dsol = _run(problem, "direct", direct, progress, None)
        out = _indirect_after_direct(problem, indirect, progress, dsol, time.perf_counter() - t0)
    else:
        dsol = _run(problem, "direct", direct, progress, warm)
        if indirect.initial_costate == "from_direct":
            isol = _indirect_after_direct(problem, indirect, progress, dsol, None)
        else:
            isol = _fallback(problem, _run(problem, "indirect", indirect, progress, warm), direct, indirect, progress,
                             warm, dsol)
        out = reconcile(fuel_retighten(compare(dsol, isol), direct, indirect, progress), direct, progress)
    return out


def fuel_retighten(cmp: Comparison, direct: DirectOptions, indirect: IndirectOptions,
                   progress: Progress | None) -> Comparison:
    """For the fuel objective, when the direct method converged and the indirect one did not (from its own start
    and from the direct solution): the direct method re-solved at tol RETIGHTEN_TOL from its solution and the
    indirect one started again from that (docs/mathematics.md §19: the indirect method takes the switching structure
    of the direct solution, and at IPOPT's default tol the fuel raise's is scattered, its costates contradicting it).
    ``cmp`` unchanged otherwise, or when the re-solve does not converge; the re-solve's iterations and time are the
    direct Solution's (``stats['retightened_from_tol']``), the indirect Solution's message says it was restarted."""
    d, i = cmp.direct, cmp.indirect
    if (d.problem.kind != "smooth" or d.problem.control.objective != "fuel" or not d.converged or i.converged
            or i.result is Result.not_applicable or d.solver != "ipopt" or direct.tol <= RETIGHTEN_TOL
            or d.warm is None):
        return cmp
    tight = _retightened(d, direct, progress, "for the indirect method's switching structure",
                         retightened_for="where the indirect method failed from its switching structure")
    if not tight.converged:
        return cmp
    retry = _run(d.problem, "indirect", indirect, progress, tight.warm)
    retry.message += (f"; started from the direct solution re-solved at tol {RETIGHTEN_TOL:.0e} after the indirect "
                      f"method failed ({i.result}: {i.message.split(';')[0]})")
    retry.iterations += i.iterations
    retry.solve_s += i.solve_s
    return compare(tight, retry if retry.converged else i)


def _infeasible(problem: Problem, method: str, reason: str) -> Solution | Comparison:
    """The Solution(s) of a problem a necessary condition rules out (feasibility.py): Result.infeasible, the
    reason, no iteration; the trajectory is the free motion from the initial state (what the record can show)."""
    def one(name: str) -> Solution:
        return failed_solution(problem, name, "necessary conditions", Result.infeasible,
                               f"provably infeasible (checked before solving; no solver was run): {reason}")

    return compare(one("direct"), one("indirect")) if method == "both" else one(method)


def raise_unconverged(out: Solution | Comparison) -> Solution | Comparison:
    """``out`` unchanged if every Solution in it converged, else SolveError of the first that did not
    (``solve(..., throw=True)``)."""
    for s in (out.solutions.values() if isinstance(out, Comparison) else [out]):
        if not s.converged:
            raise SolveError(s)
    return out


# ---------------------------------------------------------------------------- simulation
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
    X, res = disc.simulate(problem.X0, U, problem.steps_of(h), N)
    run_s = time.perf_counter() - t0
    E = np.array(problem.model.energy().map(X.shape[0])(X.T)).ravel()
    rel = np.abs(E - E[0]) / max(abs(E[0]), 1e-300)
    orth, det = orthogonality_error(unpack_states(X).R)
    worst = float(res.max()) if res.size else 0.0
    result, message = _simulation_verdict(problem, X, res, worst)
    finite = np.all(np.isfinite(X))
    miss = terminal_error(X[-1], problem) if problem.terminal is not None and finite else float("nan")
    stats = {"max_orthogonality_error": float(orth.max()), "max_determinant_error": float(det.max()),
             "energy_initial": float(E[0]), "max_relative_energy_error": float(np.nanmax(rel)),
             "final_relative_energy_error": float(rel[-1]), "max_cayley_residual": worst}
    return Solution(method="simulate", solver=disc.scheme, result=result, message=message,
                    trajectory=trajectory(problem, X), cost=float("nan"), terminal_error=miss, iterations=0,
                    build_s=0.0, solve_s=run_s, problem=problem, controls=U, stats=stats)


def _simulation_verdict(problem: Problem, X: np.ndarray, res: np.ndarray, worst: float) -> tuple[Result, str]:
    finite = np.all(np.isfinite(X), axis=1)
    if finite.all() and worst <= CAYLEY_TOL:
        return Result.converged, "simulated: every step solves the discrete equations"
    if not finite.all() and (not np.isfinite(res).all() or res[np.isfinite(res)].max(initial=0) <= CAYLEY_TOL):
        k = int(np.argmin(finite))
        return Result.non_finite, (f"the state became non-finite at node {k} (overflow or a singular potential: check "
                                   "the model parameters and that the body stays away from the central mass)")
    # a step's Cayley equation not solved: the fold of the scheme, or data no step size can fix
    return step_failure(problem, X, res, problem.h)
