"""The one entry point of the numerical core: ``solve(problem, method)``, plus ``simulate`` and ``compare``.

Every front end calls :func:`solve`.  It picks the method's implementation for the problem's kind of control
(:data:`METHODS`; which methods solve which problems: :func:`not_covered`), composes its solves by a strategy (the
objective's default, ``Objective.strategy``, or the caller's) and returns a frozen Solution; checks add to it by
:func:`dataclasses.replace`.  ``method='both'`` runs both on the same discretization and compares them.
"""
from __future__ import annotations

import dataclasses
import itertools
import time
from dataclasses import dataclass, replace

import numpy as np

from .dynamics.lgvi import CAYLEY_TOL
from .dynamics.trajectory import trajectory
from .geometry.so3 import orthogonality_error
from .geometry.state import NU, unpack_states
from .methods.base import Progress, clocked, failed_solution
from .methods.direct import Direct, transcription
from .methods.impulsive import Impulsive
from .methods.indirect import Indirect
from .ocp import Problem, terminal_error
from .ocp.feasibility import necessary_conditions, step_failure
from .options import DirectOptions, IndirectOptions
from .outcome import Result
from .results.solution import SolveError, Solution, html_table
from .results.start import Start, as_start
from .results.trace import Attempt
from .objectives.effort import first_start
from .strategy.core import Context, default_strategy
from .strategy.hints import failure_hint
from .strategy.refine import AccuracyOptions, attach_checks, each, out_of_reach, refine

#: the registry: each method name and its implementations (one per kind of control)
METHODS = {"direct": {"smooth": Direct, "impulsive": Impulsive}, "indirect": {"smooth": Indirect}}
#: the implementations (method, kind of control) that take a non-uniform mesh (docs/mathematics.md §16)
ON_A_MESH = {("direct", "smooth"), ("indirect", "smooth")}
#: what ``solve`` accepts: a method name, or 'both'
METHOD_NAMES = ("direct", "indirect", "both")
#: relative cost difference above which compare reports different extremals
MISMATCH_COST_RTOL = 1e-6
#: IPOPT's tol of the direct re-solve before 'both' declares a mismatch (:func:`reconcile`): a solution at a looser
#: tol can sit inside an active bound by ~sqrt(tol) and cost more
RETIGHTEN_TOL = 1e-12


class NotCovered(ValueError):
    """:func:`solve`'s refusal of a method that cannot run on the problem at all (:func:`not_covered`'s sentence);
    a ValueError, and a class of its own for front ends that tell bad input from a defect."""


class OutOfReach(ValueError):
    """:func:`solve`'s refusal of an accuracy its scheme cannot reach within the cap on N, before solving:
    :func:`~transcription.strategy.refine.out_of_reach`'s sentence (a ValueError, as :class:`NotCovered`)."""


@dataclass(frozen=True)
class Comparison:
    """Both methods on one problem: their Solutions and how far they agree.

    cost_relative_difference = |J_d - J_i| / max(|J_d|, |J_i|); control_max_difference_relative = max |U_d - U_i| /
    max |U_d|; same_extremal: both converged and the costs agree to MISMATCH_COST_RTOL; verdict: a sentence."""

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
        verdict = f"not comparable: {na.verdict}"
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
    """The direct Solution ``d`` re-solved at tol RETIGHTEN_TOL from its own solution (primal and dual); when it
    converges, with ``d``'s attempts before its own, ``stats['retightened_from_tol']``, ``stats`` and ``why``."""
    tight = Direct(direct.replace(tol=RETIGHTEN_TOL)).solve(d.problem, d.warm, _tagged(progress, "direct", "retightened"),
                                                          f"its solution at tol {RETIGHTEN_TOL:.0e}")
    if not tight.converged:
        return tight
    return replace(tight, verdict=f"{d.verdict}; re-solved at tol {RETIGHTEN_TOL:.0e} from it {why}: {tight.verdict}",
                   trace=d.trace + tight.trace, notes=d.notes,
                   stats={**tight.stats, "retightened_from_tol": float(direct.tol), **stats})


def reconcile(cmp: Comparison, direct: DirectOptions, progress: Progress | None = None) -> Comparison:
    """``cmp`` again after the direct method was re-solved at tol RETIGHTEN_TOL from its own solution, when both
    converged but their costs differ by more than MISMATCH_COST_RTOL at a looser direct tol: a difference the
    tolerance explains is not a mismatch.  The direct Solution carries the re-solve (``retightened_from_tol``,
    ``cost_difference_before_retightening``).  Unchanged when there is nothing to re-solve, or the re-solve fails
    (``stats['retighten']`` says so)."""
    d = cmp.direct
    if cmp.same_extremal or not cmp.converged or d.solver != "ipopt" or direct.tol <= RETIGHTEN_TOL or d.warm is None:
        return cmp
    tight = _retightened(d, direct, progress, f"before comparing (the costs were {cmp.cost_relative_difference:.1e} "
                                              f"apart)", cost_difference_before_retightening=cmp.cost_relative_difference)
    if not tight.converged:
        said = f"the re-solve at tol {RETIGHTEN_TOL:.0e} ended {tight.result}"
        return compare(d.with_notes(said, retighten=said), cmp.indirect)
    return compare(tight, cmp.indirect)


# ---------------------------------------------------------------------------- the registry
def implementation(problem: Problem, name: str, direct: DirectOptions | None = None,
                   indirect: IndirectOptions | None = None):
    """The method ``name`` ('direct' or 'indirect') for the kind of ``problem``'s control with its options (None if
    the method has none)."""
    cls = METHODS[name].get(problem.kind)
    if cls is None:
        return None
    return cls(indirect or IndirectOptions()) if name == "indirect" else cls(direct or DirectOptions())


def not_covered(problem: Problem, method: str) -> str:
    """Why ``method`` ('direct', 'indirect' or 'both') cannot run on ``problem`` at all, in one sentence ('' when it
    can): the one place that says which methods solve which problems; ``solve`` raises NotCovered with it.  What a
    method does not cover *within* a problem is its Solution's Result.not_applicable."""
    if method not in METHOD_NAMES:
        return f"method must be one of {', '.join(METHOD_NAMES)}, got {method!r}"
    if problem.kind is None:
        return "the problem has no terminal target and no control: there is nothing to solve (simulate it)"
    for name in (("direct", "indirect") if method == "both" else (method,)):
        if not problem.uniform and (name, problem.kind) not in ON_A_MESH:   # issue 26
            return f"a non-uniform mesh (Problem.mesh) is not supported yet by the {name} method: use uniform steps"
        if implementation(problem, name) is None:
            return Indirect().not_covered(problem) if name == "indirect" else Direct().not_covered(problem)
    return ""


def _tagged(progress: Progress | None, name: str, phase: str = "") -> Progress | None:
    """progress with each Iterate naming its method (and under ``phase``)."""
    if progress is None:
        return None
    return lambda it: progress(dataclasses.replace(
        it, method=name, phase=f"{phase} / {it.phase}" if phase and it.phase else phase or it.phase))


# ---------------------------------------------------------------------------- one method
def solve_direct(problem: Problem, options: DirectOptions | None = None, progress: Progress | None = None,
                 warm: Start | None = None, strategy=None) -> Solution:
    """The direct method on ``problem``: impulsive control by its one solve; smooth control by ``strategy`` (default
    the objective's) from ``warm`` when given, fatrop first when ``options.solver`` is 'fatrop' (IPOPT the fallback),
    with what to try next when it fails from its own starts (:func:`~transcription.strategy.hints.failure_hint`)."""
    options = options or DirectOptions()
    ctx = Context(implementation(problem, "direct", options), progress)
    if problem.kind == "impulsive":
        sol = ctx.method.solve(problem, None, progress)
        return sol.with_notes(f"warm start from {warm.describe()} not used (the impulsive method starts from its own "
                              "guesses)") if warm is not None else sol
    if strategy is None:
        strategy = problem.control.objective.strategy(problem, options) if warm is not None else \
            default_strategy(problem, options)
    if options.solver == "fatrop":
        sol = _fatrop_first(problem, strategy, ctx, warm)
    else:
        sol = strategy.run(problem, warm, ctx)
    if warm is not None:
        return _warm_notes(problem, sol, warm, options)
    hint = failure_hint(sol, options)
    return sol.with_notes(hint, hint=hint) if hint else sol


def _warm_notes(problem: Problem, sol: Solution, warm: Start, options: DirectOptions) -> Solution:
    """``sol`` with what became of the warm start in its message and stats (``warm_start``, ``warm_start_resampled``,
    ``warm_start_notes``)."""
    fitted, notes = warm.fit(problem.N, problem.scheme, problem.fractions)
    said = list(notes)
    key = transcription(problem, options)[0].nlp.key
    if not (fitted.multipliers is not None and fitted.nlp_key == key) and not any("multipliers" in n for n in said):
        why = "the warm start carries none" if warm.multipliers is None else "they belong to an NLP of another structure"
        said.append(f"IPOPT's multipliers started cold ({why})")
    return sol.with_notes(f"warm start from {warm.describe()}", *said, warm_start=warm.describe(),
                          warm_start_resampled=bool(notes), warm_start_notes="; ".join(said))


def _fatrop_first(problem: Problem, strategy, ctx: Context, warm: Start | None) -> Solution:
    """fatrop from ``warm`` (else the effort objective's first start: fatrop covers effort problems only), IPOPT by
    ``strategy`` when it does not converge (or does not cover the problem): the Solution says what fatrop did
    (``stats['fatrop_*']``, its verdict before IPOPT's)."""
    label, start = ("warm start", warm) if warm is not None else first_start(problem)
    fat = ctx.solve(problem, start, label)
    if fat.converged:
        return fat.with_notes(fatrop_fallback=False)
    why = fat.verdict if fat.result is Result.not_applicable or fat.verdict.startswith("fatrop") else \
        f"fatrop did not converge ({fat.verdict})"
    sol = strategy.run(problem, warm, replace(ctx, method=ctx.method.replace(solver="ipopt")))
    return replace(sol, verdict=f"{why}; IPOPT fallback: {sol.verdict}", trace=fat.trace + sol.trace).with_notes(
        fatrop_fallback=True, fatrop_status=str(fat.stats.get("solver_status", fat.result.value)),
        fatrop_message=why)


def _indirect_after_direct(problem: Problem, indirect: IndirectOptions, progress: Progress | None,
                           dsol: Solution, direct_s: float | None) -> Solution:
    """The indirect method started from the direct solution (initial_costate: from_direct); with ``direct_s``
    (the direct solve was run for it) its stats say what the direct solve did."""
    isol = Indirect(indirect).solve(problem, dsol.warm, _tagged(progress, "indirect"))
    if direct_s is None:
        return isol
    return isol.with_notes(direct_solve_s=direct_s, direct_status=dsol.result.value, direct_cost=float(dsol.cost))


#: results after which a failed start of the indirect method is final (nothing to retry: the method does not apply,
#: or the user stopped it)
NO_FALLBACK = (Result.not_applicable, Result.interrupted)


def needs_fallback(sol: Solution, options: IndirectOptions, warm: Start | None, *, retry_warm: bool = False) -> bool:
    """Whether the indirect solve ``sol`` failed and is to be started again from the direct solution
    (``options.fallback``, :func:`with_fallback`); a failed warm start only with ``retry_warm`` (the direct solution
    of this very grid is at hand)."""
    return (bool(options.fallback) and (warm is None or retry_warm) and options.initial_costate != "from_direct"
            and not sol.result.successful and sol.result not in NO_FALLBACK)


def with_fallback(cold: Solution, retry: Solution | None, dsol: Solution, direct_s: float | None) -> Solution:
    """The Solution of an indirect solve whose start from ``initial_costate`` (``cold``) failed and that was started
    again from the direct solution ``dsol`` (``retry``; None when the direct method did not converge): the successful
    one (else ``cold``), its trace the two starts (``direct_s``: the direct solve's time, as the second's part), its
    message saying which succeeded; ``stats['fallback']``."""
    spec = cold.stats.get("initial_costate", "zero")
    first = (replace(cold.trace[0], label=f"initial_costate {spec}"),) if cold.trace else ()
    what = "from_direct (the direct solution's costates" + (f", its T = {dsol.warm.T:.10g})" if
                                                             cold.problem.free_time and dsol.warm else ")")
    ran = (Attempt("the direct solution", dsol.result, 0, float(dsol.cost), 0.0, direct_s,
                   note="the direct method's solve for this start"),) if direct_s is not None else ()
    if retry is None:
        second = Attempt(what, None, note=f"not available (the direct method ended {dsol.result}: {dsol.message})")
        out, said = cold, f"the fallback {second.line()}"
    else:
        second = replace(retry.trace[0], label=what) if retry.trace else Attempt(what, retry.result)
        out = retry if retry.converged else cold
        said = (f"started from the direct solution (initial_costate from_direct) after the start from initial_costate "
                f"{spec} failed ({cold.result}: {cold.verdict})" if retry.converged else
                f"the fallback from the direct solution failed too ({retry.result}: {retry.verdict})")
    stats = {"fallback": "from_direct" if retry is not None and retry.converged else "failed"}
    if direct_s is not None:
        stats.update(direct_solve_s=direct_s, direct_status=dsol.result.value, direct_cost=float(dsol.cost))
    return replace(out, trace=first + (second.prepared(ran, "the direct solution"),)).with_notes(said, **stats)


def _fallback(problem: Problem, isol: Solution, direct: DirectOptions, indirect: IndirectOptions,
              progress: Progress | None, warm: Start | None, dsol: Solution | None) -> Solution:
    """``isol`` if it succeeded or needs no fallback (:func:`needs_fallback`), else the indirect method started again
    from the direct solution ``dsol`` (solved here when None; :func:`with_fallback`).  A failed warm start is retried
    too when ``dsol`` is given (docs/mathematics.md §19)."""
    if not needs_fallback(isol, indirect, warm, retry_warm=dsol is not None):
        return isol
    direct_s = None
    if dsol is None:
        t0 = time.perf_counter()
        dsol = solve_direct(problem, direct, _tagged(progress, "direct"))
        direct_s = time.perf_counter() - t0
    retry = Indirect(indirect).solve(problem, dsol.warm, _tagged(progress, "indirect")) \
        if dsol.converged and dsol.warm else None
    return with_fallback(isol, retry, dsol, direct_s)


def fuel_retighten(cmp: Comparison, direct: DirectOptions, indirect: IndirectOptions,
                   progress: Progress | None) -> Comparison:
    """When the direct method converged and the indirect one did not on a problem whose indirect law starts from the
    direct solution's switching structure (the fuel objective): the direct method re-solved at tol RETIGHTEN_TOL and
    the indirect one restarted from that (docs/mathematics.md §19: at a looser tol the switching structure is
    scattered).  ``cmp`` unchanged otherwise, or when the re-solve does not converge."""
    d, i = cmp.direct, cmp.indirect
    law = getattr(d.problem.control, "objective", None)
    if (d.problem.kind != "smooth" or not getattr(law.indirect, "from_structure", False) or not d.converged
            or i.converged or i.result is Result.not_applicable or d.solver != "ipopt" or direct.tol <= RETIGHTEN_TOL
            or d.warm is None):
        return cmp
    tight = _retightened(d, direct, progress, "for the indirect method's switching structure",
                         retightened_for="where the indirect method failed from its switching structure")
    if not tight.converged:
        return cmp
    retry = Indirect(indirect).solve(d.problem, tight.warm, _tagged(progress, "indirect"))
    retry = replace(retry, trace=i.trace + retry.trace).with_notes(
        f"started from the direct solution re-solved at tol {RETIGHTEN_TOL:.0e} after the indirect method failed "
        f"({i.result}: {i.verdict})")
    return compare(tight, retry if retry.converged else i)


# ---------------------------------------------------------------------------- the entry point
def solve(problem: Problem, method: str = "direct", *, direct: DirectOptions | None = None,
          indirect: IndirectOptions | None = None, progress: Progress | None = None,
          warm_start: Solution | Start | None = None, throw: bool = False,
          accuracy: AccuracyOptions | None = None, strategy=None) -> Solution | Comparison:
    """Solve ``problem`` by ``method`` ('direct', 'indirect' or 'both').

    direct, indirect: each method's options (defaults if None).  strategy: how the direct method composes its solves
    (:mod:`transcription.strategy`; default the objective's).  progress: called as progress(Iterate), the Iterate
    naming its method, its solve (``phase``) and the seconds since this call (``elapsed_s``).  warm_start: a
    previous Solution or a :class:`~transcription.results.start.Start`, of either method, any N and scheme
    (resampled).  accuracy: the continuous check and refinement to a tolerance
    (:class:`~transcription.strategy.refine.AccuracyOptions`; default: the check on, N fixed).  Returns a Solution,
    or for 'both' a :class:`Comparison`.  Failures are data (``solution.result``); ``throw=True`` raises
    :class:`~transcription.results.solution.SolveError` for an unsuccessful one.  Raises :class:`NotCovered`
    (:func:`not_covered`) or :class:`OutOfReach` (:func:`~transcription.strategy.refine.out_of_reach`) before
    solving.
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
    warm, note = as_start(warm_start)
    progress = clocked(progress)

    def one(p, w, phase=""):
        return _dispatch(p, method, direct, indirect, progress, w, strategy, phase)

    if accuracy.refines and problem.kind == "smooth":   # refinement to a tolerance (refine.py)
        names = ("direct", "indirect") if method == "both" else (method,)
        adaptive = accuracy.refinement == "adaptive" and all((n, problem.kind) in ON_A_MESH for n in names)
        levels = itertools.count()      # one call a level: numbered as refine's mesh history numbers them
        out = refine(problem, lambda p, w: one(p, w, f"level {next(levels)} N={p.N}"), accuracy, warm,
                     adaptive=adaptive)
    else:
        out = one(problem, warm)
    if accuracy.continuous_check:
        out = attach_checks(out, accuracy.constraints_tolerance)
    if note:
        out = each(out, lambda s: s.with_notes(note))
    return raise_unconverged(out) if throw else out


def _dispatch(problem: Problem, method: str, direct: DirectOptions, indirect: IndirectOptions,
              progress: Progress | None, warm: Start | None, strategy, phase: str = "") -> Solution | Comparison:
    """One solve of ``problem`` by ``method`` on its own grid (``solve`` without its checks and notes); its
    progress under ``phase``."""
    def d(w):
        return solve_direct(problem, direct, _tagged(progress, "direct", phase), w, strategy)

    def i(w):
        return Indirect(indirect).solve(problem, w, _tagged(progress, "indirect", phase))

    if method == "direct":
        return d(warm)
    if method == "indirect" and (warm is not None or indirect.initial_costate != "from_direct"):
        return _fallback(problem, i(warm), direct, indirect, progress, warm, None)
    if method == "indirect":                       # from_direct: the direct solution first
        t0 = time.perf_counter()
        dsol = d(None)
        return _indirect_after_direct(problem, indirect, progress, dsol, time.perf_counter() - t0)
    dsol = d(warm)
    if indirect.initial_costate == "from_direct":
        isol = _indirect_after_direct(problem, indirect, progress, dsol, None)
    else:
        isol = _fallback(problem, i(warm), direct, indirect, progress, warm, dsol)
    return reconcile(fuel_retighten(compare(dsol, isol), direct, indirect, progress), direct, progress)


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

    Returns a Solution with method 'simulate': result converged, cayley_failed (a step's Cayley equation not solved
    to CAYLEY_TOL: h too large) or non_finite; terminal_error: the miss of the terminal target (nan without one);
    stats: orthogonality, determinant, relative energy errors, the largest Cayley residual.
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
    return Solution(method="simulate", solver=disc.scheme, result=result, verdict=message,
                    trajectory=trajectory(problem, X), cost=float("nan"), terminal_error=miss, problem=problem,
                    controls=U, stats=stats, trace=(Attempt("simulate", result, 0, solve_s=run_s),))


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


__all__ = ["Comparison", "NotCovered", "OutOfReach", "compare", "not_covered", "reconcile", "simulate",
           "solve", "solve_direct"]
