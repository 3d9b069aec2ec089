"""The direct method's solve: the initial guesses of the plan tried in turn on the one NLP, fatrop first when
asked for, the Solution that says what was tried."""
from __future__ import annotations

import time
from dataclasses import replace

import casadi as ca
import numpy as np

from ...strategy.starts import Guess, warm_guess
from ...nlp.solvers import ipopt_options, make_ipopt
from ...options import DirectOptions
from ...ocp import Problem
from ...results.solution import Attempt, Solution
from ...outcome import Result
from ...results.start import WarmStart
from ..base import Progress, Reporting, failed_solution
from .fatrop import try_fatrop
from ...strategy.fuel_continuation import PREPARED_ON as CONTINUED
from ...strategy.fuel_guard import ESCAPE, false_minima, guarded, switching, verdict
from ...strategy.fuel_structure import applies as structure_applies, resolves, structured_finish
from ...strategy.homotopy import LEVEL_BUDGET, PREPARED_ON, STRUCTURE_START, WARM_LEVEL, WARM_PRIMAL, Point
from ...strategy.plan import (COARSE, NOT_TRIED, RELAXED, RESOLVED, PlanEntry, failure_hint, guess_plan, multistart, plan_ipopt_options)
from .solution import nlp_solution
from ...nlp.transcription import SmoothTranscription


#: the label (and progress phase) of a warm start's solve
WARM = "warm start"
#: the progress phase of a plan's solve from a guess made on another problem (Guess.prepared_on); a solve from
#: any other guess (or a warm start, whichever grid it came from) is under its plan label ('rollout',
#: 'interpolate (seed 1)', 'warm start', a fuel guard escape)
FROM = {RELAXED: "from relaxed", COARSE: "from coarse", RESOLVED: "from resolved grid",
        PREPARED_ON: "from homotopy", STRUCTURE_START: "from last level", CONTINUED: "from continuation"}


def attempt_phase(label: str, prepared_on: str) -> str:
    """The progress phase of the plan's solve from the guess labelled ``label`` (:data:`FROM`)."""
    if label == WARM:
        return label
    return FROM.get(prepared_on) or label.replace(" with symmetry-breaking controls", "")


class _PlanRun:
    """The guesses of a plan solved in turn on one NLP (built once), with IPOPT solvers by iteration budget;
    the attempts made and the totals of build time, solve time and iterations of all of them.  ``progress``: the
    iterations of each attempt, numbered from 0 and under :func:`attempt_phase` (the solvers are reused across
    attempts), and those of the structured finish (its own phases)."""

    def __init__(self, problem: Problem, options: DirectOptions, progress: Progress | None, warm: WarmStart | None):
        self.problem, self.options, self.progress = problem, options, progress
        self.phase, self.k = "", 0
        self.listen = None if progress is None else self.report
        t0 = time.perf_counter()
        self.tr = SmoothTranscription(problem, options)
        self.build_s = time.perf_counter() - t0
        # a warm start's multipliers start IPOPT's duals only on an NLP of the same structure
        self.nu0 = warm.multipliers if warm is not None and warm.nlp_key == self.tr.nlp.key else None
        self.solvers: dict[tuple[int, bool], ca.Function] = {}
        self.attempts: list[Attempt] = []
        self.points: dict[int, Point] = {}   # id(Solution) -> its scaled primal-dual point (the fuel guard's)
        self.switchings: dict[int, dict] = {}   # id(Solution) -> .fuel_guard.switching of its converged fuel point
        self.verdicts: dict[int, str] = {}   # id(Attempt) -> the fuel guard's verdict on its converged point
        self.structure: list[str] = []       # what the structured fuel finish did (.fuel_structure)
        self.extra_build_s, self.solve_s, self.iterations = 0.0, 0.0, 0

    def solver(self, budget: int, phase1: bool = False, level: bool = False, fine: bool = False) -> ca.Function:
        """IPOPT within ``budget`` iterations (``phase1``: from a relaxation's solution, :func:`plan_ipopt_options`;
        ``level``: from the fuel homotopy's last level and its multipliers, :data:`~.homotopy.WARM_LEVEL`;
        ``fine``: a fuel problem from its coarser grid's optimum, :data:`~.homotopy.WARM_PRIMAL`)."""
        key = (budget, phase1, level, fine)
        if key not in self.solvers:
            t0 = time.perf_counter()
            ipopt = ipopt_options(self.options.replace(max_iter=budget), warm_duals=self.nu0 is not None or level)
            for k, value in {**plan_ipopt_options(self.problem, phase1), **(WARM_LEVEL if level else {}),
                             **(WARM_PRIMAL if fine else {})}.items():
                ipopt.setdefault(k, value)
            self.solvers[key] = make_ipopt("direct_ms", self.tr.nlp, ipopt, self.listen, self.tr.scales.objective)
            self.extra_build_s += time.perf_counter() - t0
        return self.solvers[key]

    def report(self, it) -> None:
        """An attempt's iterate to ``progress``, numbered within the attempt and under its phase."""
        self.progress(replace(it, iteration=self.k, phase=self.phase))
        self.k += 1

    def attempt(self, label: str, guess: Guess, budget: int) -> Solution:
        """IPOPT from ``guess`` within ``budget`` iterations; its Solution counts the iterations and time spent
        making the guess too."""
        tr = self.tr
        # near the fuel optimum's structure
        structure = guess.prepared_on in (COARSE, RESOLVED, STRUCTURE_START, CONTINUED)
        if tr.fuel and structure and structure_applies(self.problem, self.options):
            sol = self.structured(label, guess)
            if sol is not None:
                return sol
            if guess.prepared_on == STRUCTURE_START:    # a level's point at its budget: the fallback gets a level's
                budget = min(budget, LEVEL_BUDGET)      # budget, not max_iter (the plan's other starts follow)
        level = guess.duals is not None and guess.duals[0] == tr.nlp.key
        solver = self.solver(budget, guess.prepared_on == RELAXED, level, tr.fuel and structure)
        args = dict(x0=tr.initial_point(guess, guess.h), lbx=tr.lbx, ubx=tr.ubx, lbg=tr.nlp.lbg, ubg=tr.nlp.ubg)
        if level:   # the very point of the homotopy's last level (its slacks too), with its multipliers
            args.update(x0=guess.duals[1], lam_g0=guess.duals[2], lam_x0=guess.duals[3])
        elif self.nu0 is not None:
            args["lam_g0"] = tr.scaled_multipliers(self.nu0)
        self.phase, self.k = attempt_phase(label, guess.prepared_on), 0
        t0 = time.perf_counter()
        out = solver(**args)
        solve_s = time.perf_counter() - t0
        self.solve_s += solve_s
        point = Point(*(np.array(out[k]).ravel() for k in ("x", "lam_g", "lam_x")))
        stats = solver.stats()
        sol = nlp_solution(self.problem, self.options, tr, out, stats, str(stats.get("return_status", "unknown")),
                           "ipopt", self.build_s, solve_s)
        self.counted(label, sol, guess)
        self.points[id(sol)] = point
        if tr.fuel and sol.converged:   # the fuel guard's values: its escape, the multistart's false minima
            self.switchings[id(sol)] = switching(tr, point.x, point.lam_g)
            self.verdicts[id(self.attempts[-1])] = verdict(self.switchings[id(sol)])["fuel_guard"]
        return sol

    def counted(self, label: str, sol: Solution, guess: Guess) -> None:
        """``sol`` (from ``guess``) counted as an attempt: the guess's making (the relaxed problem's or the coarse
        grid's solve: its iterations and time) added to it, its iterations to the run's, its Attempt, and
        ``stats['initial_guess']`` with what the guess's making reported."""
        if guess.iterations:
            sol.iterations += guess.iterations
            sol.solve_s += guess.seconds
            self.solve_s += guess.seconds
        self.iterations += sol.iterations
        self.attempts.append(Attempt(label, sol.result, sol.iterations, sol.cost if sol.converged else float("nan"),
                                     guess.iterations, guess.prepared_on))
        sol.stats["initial_guess"] = label
        sol.stats.update(guess.stats)

    def structured(self, label: str, guess: Guess) -> Solution | None:
        """The fuel problem finished from a coarser grid's optimum on its switching structure
        (:func:`.fuel_structure.structured_finish`; ``resolved`` from a grid that resolves the switching times,
        :data:`~.plan.RESOLVED`): its Solution if it converged and passed the fuel KKT guard, else
        None (the epigraph NLP then finishes from the same guess; ``structure`` says what was tried)."""
        sol, stats = structured_finish(self.problem, self.options, guess, self.progress,
                                       resolved=guess.prepared_on == RESOLVED)
        self.extra_build_s += sol.build_s
        self.solve_s += sol.solve_s
        self.structure = stats["fuel_structure"]
        if not (sol.converged and stats["fuel_guard"] == "passed"):
            self.structure = self.structure + ["not kept: the fuel NLP finished from the same start"]
            self.iterations += sol.iterations    # the guess's making counts once, with the fallback's attempt
            self.attempts.append(Attempt(f"{label}, on its switching structure", sol.result, sol.iterations,
                                         float("nan"), 0, guess.prepared_on))
            return None
        sol.stats.update(stats)
        self.counted(label, sol, guess)
        return sol

    def run(self, plan: list[PlanEntry], pick: str) -> Solution | None:
        """The plan's guesses in turn (:func:`~transcription.strategy.plan.guess_plan` says how ``pick``
        chooses); the Solution chosen, or None if no guess could be solved."""
        sol, best = None, None
        for i, (label, maker, budget) in enumerate(plan):
            guess = maker()
            if guess is None:
                what = "coarse-grid problem" if pick == "coarse" and i == 0 else \
                    "effort problem, a smoothed problem or a step of the continuation" if "continuation" in label else \
                    "effort problem or a smoothed problem" if "homotopy" in label else "relaxed problem"
                self.attempts.append(Attempt(label, None, note=f"not available (the {what} did not converge)"))
                continue
            if not all(np.all(np.isfinite(a)) for a in (guess.X, guess.U, guess.C)):
                self.attempts.append(Attempt(label, None, note="not finite"))
                continue
            sol = self.attempt(label, guess, budget)
            if sol.converged and (best is None or sol.cost < best.cost):
                best = sol
            if sol.result is Result.interrupted or (sol.converged and pick == "first"):
                break
            if pick == "coarse" and guess.prepared_on == COARSE and sol.converged:
                break   # finished on the fine grid: the fine-grid starts are only the fallback
            if guess.prepared_on == RELAXED and sol.result is Result.infeasible:
                self.attempts += [Attempt(rest, None, note=NOT_TRIED) for rest, _, _ in plan[i + 1:]]
                break   # the phase 1 from the relaxed optimum ended at a least violation > 0 (plan_ipopt_options)
        if sol is None:
            return None
        return best if best is not None and sol.result is not Result.interrupted else sol


def not_covered(problem: Problem) -> str:
    """What of ``problem`` the direct method's NLP does not cover: impulsive control (its impulsive solver does)."""
    return "" if problem.kind == "smooth" else "impulsive control (the direct method's impulsive solver covers it)"


def solve_direct(problem: Problem, options: DirectOptions | None = None, progress: Progress | None = None,
                 warm: WarmStart | None = None) -> Solution:
    """Solve a smooth-control ``problem`` by the direct method (transcription.methods.direct); failures are data.

    The initial guesses of :func:`~transcription.strategy.plan.guess_plan` are tried in order until one
    converges (``Solution.attempts`` and the message say which were tried; ``iterations``, ``build_s`` and
    ``solve_s`` are those of all of them).  ``warm``: a :class:`~transcription.results.start.WarmStart` (of any method,
    N and scheme: fitted to this grid, :meth:`~transcription.results.start.WarmStart.fit`) is the only initial guess,
    and its NLP multipliers, if it carries those of an NLP of the same structure, start IPOPT's duals; the
    message and ``stats['warm_start']`` say what was resampled and what was not reused.

    ``progress``: every NLP iteration of the solve, those of the guesses' own solves too (the relaxed problem,
    the coarse grids, the fuel homotopy's effort problem and levels, the structured finish), each record under
    the phase of its solve (nested: 'coarse N=25 / effort / rollout'; :func:`attempt_phase`) and with its
    ``budget``.

    Smooth control: controls (6, n_controls) [u_f inertial; u_m body]; trajectory = the re-simulation from X0
    with those controls; terminal_error on it; costates (N, 12) from the multipliers.  The result is
    converged iff the solver converged, the re-simulated terminal error is <= terminal_tol and no path
    constraint is violated by more than terminal_tol.  A converged fuel solve is checked against the L1 problem's
    switching condition on its coast nodes and escapes a false minimum of the NLP (:func:`.fuel_guard.guarded`:
    ``stats['fuel_guard']``, ``fuel_switching_max``, ``fuel_escape``).
    """
    options = options or DirectOptions()
    if problem.kind != "smooth":
        raise ValueError("the direct method's NLP solves smooth-control problems (impulsive ones: "
                         "transcription.methods.impulsive)")
    notes: tuple[str, ...] = ()
    origin = warm.describe() if warm is not None else ""
    if warm is not None:
        kind = RESOLVED if resolves(warm, problem.N) else COARSE
        warm, notes = warm.fit(problem.N, problem.scheme, problem.fractions)
        # a fuel plan on another grid is finished like a coarser grid's optimum: on its switching structure (§23);
        # from an adaptive level's mesh that resolves the switching times, on its own burn nodes
        resampled = problem.control.objective == "fuel" and bool(notes)
        guess = replace(warm_guess(warm), prepared_on=kind) if resampled else warm_guess(warm)
        plan, pick = [(WARM, lambda: guess, options.max_iter)], "first"
    else:
        plan, pick = guess_plan(problem, options,
                                solve_direct if progress is None else Reporting(solve_direct, progress))
    fallback: dict = {}
    if options.solver == "fatrop":
        fsol, fallback = try_fatrop(problem, options, plan[0][1])
        if fsol is not None:
            return _with_warm_notes(fsol, warm, origin, notes, used_duals=False)
    run = _PlanRun(problem, options, progress, warm)
    sol = run.run(plan, pick)
    if sol is None:
        return failed_solution(problem, "direct", options.solver, Result.non_finite,
                               "the initial guess is not finite (overflow or a singular potential along the free "
                               "motion): check the model and the states")
    if run.tr.fuel and sol.converged and id(sol) in run.switchings:   # the fuel KKT guard and the escape
        sol = guarded(run, sol)                                       # (.fuel_guard; a structured finish: its own)
    if run.structure and "fuel_structure" not in sol.stats:
        sol.stats["fuel_structure"] = run.structure
    # every guess tried counts: iterations and times are those of the whole solve
    sol.build_s, sol.solve_s, sol.iterations = run.build_s + run.extra_build_s, run.solve_s, run.iterations
    sol.attempts = tuple(run.attempts)
    if len(run.attempts) > 1:
        sol.message += "; initial guesses tried: " + "; ".join(a.line() for a in run.attempts)
    if pick == "best":
        starts = [a for a in run.attempts if not a.label.startswith(ESCAPE)]
        sol.stats.update(multistart(starts, problem.N))
        sol.stats.update(false_minima(run.verdicts, starts, sol.stats))
    if sol.converged and "multistart" in sol.stats:
        sol.message += f"; {sol.stats['multistart']}"
    hint = failure_hint(sol, options) if warm is None else ""
    if hint:
        sol.stats["hint"] = hint
        sol.message += f"; {hint}"
    if fallback:
        sol.stats.update(fallback)
        sol.message = f"{fallback['fatrop_message']}; IPOPT fallback: {sol.message}"
        sol.build_s += fallback["fatrop_build_s"]
        sol.solve_s += fallback["fatrop_solve_s"]
    return _with_warm_notes(sol, warm, origin, notes, used_duals=run.nu0 is not None)


def _with_warm_notes(sol: Solution, warm: WarmStart | None, origin: str, notes: tuple[str, ...],
                     used_duals: bool) -> Solution:
    """The Solution with what became of the warm start in its message and stats: ``warm_start`` (where it came
    from), ``warm_start_resampled``, ``warm_start_notes`` (what was resampled, what was not reused)."""
    if warm is None:
        return sol
    said = list(notes)
    if not used_duals and not any("multipliers" in n for n in said):
        why = "the warm start carries none" if warm.multipliers is None else "they belong to an NLP of another structure"
        said.append(f"IPOPT's multipliers started cold ({why})")
    sol.stats.update(warm_start=origin, warm_start_resampled=bool(notes), warm_start_notes="; ".join(said))
    sol.message += f"; warm start from {origin}" + "".join(f"; {n}" for n in said)
    return sol
