"""The indirect method's solve: Newton-Armijo shooting on the initial costate (docs/mathematics.md §6, §10),
its initial costate (from a warm start or the options), and the Solution."""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ...dynamics.lgvi import two_point
from ...geometry.state import NU, NZ
from ..newton import NewtonResult, newton_armijo
from ...options import IndirectOptions
from ...ocp import (STATE_COMPONENTS, Problem, TargetOrbit, TargetRendezvous, TargetState,
                    objective_value, terminal_error)
from ...results.solution import Solution
from ...outcome import Iterate, Result
from ...dynamics.trajectory import trajectory
from ...results.start import Start, start_of
from ...results.trace import Attempt
from ..base import OneFunction, Progress, failed_solution
from .continuation import bound_continuation, free_final_time
from .control import bound_data, bounded, control_cost, weight_inverse
from .coordinates import body_coordinates
from .orbit import orbit_shooting
from .shooting import RolloutCache, shooting_functions, time_gradient_function


def not_covered(problem: Problem, replan: bool = False) -> str:
    """What of ``problem`` the indirect method does not cover, in words ('' if nothing): impulsive control, and what
    its objective's law (``Objective.indirect``, :mod:`.laws`) does not: the effort law covers a state or orbit target
    (:mod:`.orbit`) with box bounds on blocks with a diagonal weight and norm bounds on blocks with an isotropic one
    (where the saturation is the Hamiltonian's minimizer).  ``replan``: only the laws a re-plan's fixed-h Newton step
    covers (transcription.closedloop.mpc)."""
    if problem.kind != "smooth":
        return "the indirect method applies to smooth maneuvers; impulsive maneuvers are solved by the direct method"
    c = problem.control
    law = c.objective.indirect
    reasons = []
    if law is None or (replan and not law.replannable):
        reasons.append(f"the {c.objective} objective")
    else:
        reasons += law.not_covered(problem)   # on a non-uniform mesh too (docs/mathematics.md §19)
    if problem.constraints:
        moving = [f"{c.kind.replace('_', '-')} cone about the {c.direction}" for c in problem.constraints
                  if getattr(c, "moving", False)]
        # a min_radius is named with its radius: a central body's clearance (model.central_body_radius, a preset's
        # radius) is one, active or not -- the indirect method does not know that it is inactive
        radii = [f"min_radius {c.radius:.6g}" for c in problem.constraints if c.kind == "min_radius"]
        reasons.append("path constraints" + (f" (a {', a '.join(moving)})" if moving else
                                             f" ({', '.join(radii)})" if radii else ""))
    if isinstance(problem.terminal, TargetRendezvous):
        reasons.append("a rendezvous target (its point moves with the final time)")
    elif not isinstance(problem.terminal, (TargetState, TargetOrbit)):
        reasons.append("this kind of target")
    for name, W, bound in (("force", c.W_f, c.force_bound), ("moment", c.W_m, c.moment_bound)):
        if bound is None or bound.removed:
            continue
        if bound.channel_rows and (name != "force" or bound.engine_axis is None):
            reasons.append(f"{bound.noun} on the {name} (the saturation law takes one engine on the force)")
        if bound.variable_box() is not None and np.count_nonzero(W - np.diag(np.diag(W))):
            reasons.append(f"{bound.noun} on the {name} with a non-diagonal weight")
        if 0 < bound.radius < np.inf and not np.allclose(W, W[0, 0] * np.eye(3), rtol=1e-14, atol=0):
            reasons.append(f"{bound.noun} on the {name} with a weight that is not a multiple of the identity")
    return ", ".join(reasons)


def free_rows(target: TargetState) -> np.ndarray:
    """Boolean (12): the rows of z_N (tangent coordinates [dx; dgamma; zeta; dPi]) of the free terminal
    components, where the shooting residual is lambda_{N-1} instead (stationarity in z_N, docs/mathematics.md §10)."""
    return np.repeat([c in target.free for c in STATE_COMPONENTS], 3)


def lam0_from_costates(problem: Problem, lam: np.ndarray, u0: np.ndarray, h: float | None = None,
                       u1: np.ndarray | None = None) -> np.ndarray:
    """The shooting unknown from a solution's costate lambda_0 (12) (docs/mathematics.md §6, §15): first_order
    lambda_0; lgvi lambda_{-1} = A_0(X_0, [u_0; 0])^T lambda_0 (u_0 the first control) at step 0's size h_0 = r_0 h (h:
    the mean step, default the problem's; §17).  With a body-fixed force A_0 depends on the end kick R_1 u_{f,1}:
    lambda_{-1} = A_0(X_0, [u_0; u_1])^T lambda_0, u_1 the second control (required)."""
    lam = np.asarray(lam, dtype=float).reshape(NZ)
    if two_point(problem.scheme):
        body = body_coordinates(problem.disc)
        if body and u1 is None:
            raise ValueError("lam0_from_costates: a body-fixed force with the LGVI needs the second control u_1")
        h0 = np.ravel(problem.steps_of(problem.h if h is None else h))[0]
        A0 = np.array(problem.disc.variation(problem.X0, np.r_[u0, u1 if body else np.zeros(NU)], h0)[0])
        lam = A0.T @ lam
    return lam


def initial_costate(problem: Problem, options: IndirectOptions, warm: Start | None) -> tuple[np.ndarray, str, list]:
    """(lambda_0, its source, notes) from ``warm`` fitted to the problem's grid
    (:meth:`~transcription.results.start.Start.fit`): its lambda_0 ('warm_start'), else from its costates
    (:func:`lam0_from_costates`; 'from_direct' for a direct solution's, mapped from its multipliers); or from
    ``options.initial_costate``: 'zero', 12 numbers ('explicit'), 'from_direct' (needs the direct solution as
    ``warm``).  Raises ValueError when none is usable."""
    notes: list[str] = []
    if warm is not None:
        origin = warm.describe()
        fitted, resampled = warm.fit(problem.N, problem.scheme, problem.fractions)
        notes += [f"warm start from {origin}", *resampled]
        if fitted.lam0 is not None:
            return np.array(fitted.lam0, dtype=float), "warm_start", notes
        if fitted.costates is not None:
            if resampled:
                notes.append("lambda_0 from the resampled costates")
            U = fitted.U
            return (lam0_from_costates(problem, fitted.costates[0], U[:, 0], initial_step(problem, warm),
                                       u1=U[:, 1] if U.shape[1] > 1 else None),
                    "from_direct" if warm.source == "direct" else "warm_start", notes)
        notes.append("it carries no costates: lambda_0 from initial_costate")
    spec = options.initial_costate
    if spec == "zero":
        return np.zeros(NZ), "zero", notes
    if spec == "from_direct":
        raise ValueError("initial_costate from_direct: no direct solution with costates was given (solve(problem, "
                         "'indirect') runs the direct method first; its solution carries none)")
    return np.asarray(spec, dtype=float).reshape(NZ), "explicit", notes


class _Shooting:
    """The shooting of one problem: its Functions and data, the Newton iteration on lambda_0 at the mean step h
    (the Functions get ``problem.steps_of(h)``: h r_k on a non-uniform mesh, docs/mathematics.md §16), dL/dh for a
    free final time, and the Solution of the final lambda_0; ``stats``: what the Solution reports."""

    def __init__(self, problem: Problem, options: IndirectOptions, progress: Progress | None, source: str):
        self.problem, self.options, self.progress, self.source = problem, options, progress, source
        t0 = time.perf_counter()
        self.fns = shooting_functions(problem.disc, problem.N, bool(options.jit))
        self.build_s = time.perf_counter() - t0
        # an orbit target: its conditions and transversality (.orbit); Xd is then a placeholder nothing reads
        self.orbit = orbit_shooting(problem)
        self.X0, self.Xd = problem.X0, problem.X0 if self.orbit else problem.terminal.X
        self.Winv, self.bd = weight_inverse(problem), bound_data(problem)
        self.free = np.zeros(NZ, bool) if self.orbit else free_rows(problem.terminal)
        self.stats: dict = {"jit": bool(self.fns.compiled), "initial_costate": source}
        self.conditions = problem.control.objective.indirect   # the objective's law (.laws)
        self.law = (self.Winv, self.bd)   # the (Winv, bd) of the final rollout (the time objective: its eps-law's)
        self.primal = None                # (X, U) of the warm start on this grid (the time objective's first stage)
        self.structured, self.warm_U = None, None   # the fuel objective's (.fuel)
        self.start = None                 # (lam, h, rollout outputs) of the start's check (:meth:`cayley_residual`)

    def cayley_residual(self, lam: np.ndarray, h: float) -> float:
        """The largest relative Cayley residual of the rollout from lam at the step size h (the rollout kept: the
        Newton iteration from lam at h with the problem's bounds starts from it, :meth:`newton`)."""
        out = self.fns.rollout(lam, self.X0, self.Xd, self.problem.steps_of(h), self.Winv, self.bd)
        self.start = (np.array(lam, dtype=float), float(h), out)
        return float(out[2])

    def newton(self, lam, bd_stage, phase: str, h: float) -> NewtonResult:
        fns, X0, Xd, Winv, free, opts = self.fns, self.X0, self.Xd, self.Winv, self.free, self.options
        h_mean, h = float(h), self.problem.steps_of(h)

        start = self.start   # the rollout the start's check did, if this iteration starts there
        seed = (start[0], start[2]) if start is not None and start[1] == h_mean and np.array_equal(bd_stage, self.bd) \
            else None
        shared = RolloutCache(fns, (X0, Xd, h, Winv, bd_stage), seed)   # the Jacobian reuses the accepted rollout

        def residual(l):
            # the given terminal components, and lambda_{N-1} = 0 on the free ones (transversality)
            z, lamN, r = shared.residual(l)
            return np.where(free, np.array(lamN).ravel(), np.array(z).ravel()), float(r)

        def jacobian(l):
            # Psi only: z always comes from ``residual`` (one rounding for all comparisons)
            _, Psi, dlamN = shared.jacobian(l)
            return np.where(free[:, None], np.array(dlamN), np.array(Psi))

        # an orbit target: its conditions and transversality instead (.orbit)
        closures = self.orbit.closures(fns, (X0, Xd, h, Winv, bd_stage)) if self.orbit else (residual, jacobian)
        progress = self.progress
        tagged = (lambda it: progress(dataclasses.replace(it, phase=phase))) if progress and phase else progress
        nr = newton_armijo(lam, *closures, tol=opts.eps_S, alpha=opts.alpha, max_iter=opts.max_iter,
                           max_halvings=opts.max_halvings, aux_tol=opts.cayley_tol, floor_factor=opts.floor_factor,
                           floor_accept=opts.floor_accept, progress=tagged)
        if phase:
            nr.history = [dataclasses.replace(it, phase=phase) for it in nr.history]
        return nr

    def solve_at(self, lam, h: float, first: bool, phase: str = "") -> NewtonResult:
        """The fixed-step problem at h from lam by the objective's law (:mod:`.laws`): from lambda_0 = 0 with bounds,
        by the bound continuation; the fuel objective by the homotopy in eps (:func:`~.fuel.fuel_homotopy`; the final
        eps kept in bd)."""
        return self.conditions.solve_at(self, lam, h, first, phase)

    def cost(self, lam, h: float, bd: np.ndarray) -> float:
        """The cost of the controls of the rollout from lam at h with the bound data bd."""
        U = np.array(self.fns.shoot(lam, self.X0, self.Xd, self.problem.steps_of(h), self.Winv, bd)[3])
        return control_cost(self.problem, U, h)

    def fixed(self, lam, h: float, first: bool, phase: str, bd: np.ndarray) -> NewtonResult:
        """The fixed-step problem at h with the bound data bd from lam; from lambda_0 = 0 with bounds, by the bound
        continuation."""
        if first and self.source == "zero" and bounded(bd):
            nr, stages = bound_continuation(lambda l, b, ph: self.newton(l, b, f"{phase}{ph}", h), lam, bd, self.fns,
                                            (self.X0, self.Xd, self.problem.steps_of(h), self.Winv), self.conditions)
            self.stats["bound_continuation"] = stages
            return nr
        return self.newton(lam, bd, phase, h)

    def dL_dh(self, lam, h: float) -> float:
        """dJ*/dh = dL/dh at the solution (envelope theorem): J/h (the weights are proportional to h) plus the
        steps' terms (:func:`~.shooting.time_gradient_function`), each step's by its h_k = r_k h times dh_k/dh = r_k
        on a non-uniform mesh (docs/mathematics.md §17)."""
        problem, X0, hk = self.problem, self.X0, self.problem.steps_of(h)
        _, Xs, lams, U, _, _ = (np.array(a) for a in self.fns.shoot(lam, X0, self.Xd, hk, self.Winv, self.bd))
        Xk = np.column_stack([X0, Xs[:, :-1]])
        g = np.array(time_gradient_function(problem.disc, problem.N)(Xk, problem.disc.stage_controls(U), lams, hk))
        return control_cost(problem, U, h) / h + float(np.sum(g if problem.uniform else problem.mesh * g.ravel()))

    def run(self, lam, h: float) -> tuple[NewtonResult, float]:
        """The solve from lam at the step size h by the objective's law (:mod:`.laws`; the time objective: its
        homotopy in eps, with the free final time); the result and the final step size."""
        return self.conditions.run(self, lam, h)

    def default_run(self, lam, h: float) -> tuple[NewtonResult, float]:
        """The Newton iteration from lam at the step size h (with a free final time, inside the secant iteration
        on h, h the first guess); the result and the final step size."""
        problem = self.problem
        if not problem.free_time:
            return self.solve_at(lam, h, True), h
        N = problem.N
        lo, hi = (t / N for t in problem.time_bounds)
        nr, h, outer = free_final_time(self.solve_at, self.dL_dh, lam, h, lo, hi, N, self.conditions)
        self.stats["free_time"] = outer
        return nr, h

    def solution(self, nr: NewtonResult, h: float, solve_s: float, label: str) -> Solution:
        """The Solution of the final lambda_0: controls and costates from it, the re-simulated trajectory."""
        problem, stats, lam = self.problem, self.stats, nr.x
        _, _, lams, U, _, lres = self.fns.shoot(lam, self.X0, self.Xd, problem.steps_of(h), *self.law)
        U, lams = np.array(U), np.array(lams).T
        if self.structured is not None:   # the fuel objective's exact (eps = 0) solution (.fuel)
            U, lams = self.structured
        Xsim, res = problem.disc.simulate(self.X0, U, problem.steps_of(h), problem.N)
        finite = bool(np.all(np.isfinite(Xsim)))
        result, message = self._verdict(nr, finite)
        stats.update(
            residual_norm=float(np.linalg.norm(nr.F)),
            roundoff_floor=nr.floor,
            noise_level=nr.noise,
            max_cayley_residual=float(np.max(res)) if res.size else 0.0,
            max_costate_solve_residual=float(np.max(np.array(lres))),
            quadratic_C=quadratic_constant(nr.history, floor=10.0 * nr.noise if nr.noise else 0.0),
        )
        traj = trajectory(problem, Xsim, h)
        cost = objective_value(problem, U, h) if np.all(np.isfinite(U)) else float("inf")
        attempt = Attempt(label or f"initial_costate {self.source}", result, nr.iterations,
                          cost if result.successful else float("nan"), self.build_s, solve_s)
        return Solution(method="indirect", solver="newton-armijo", result=result, verdict=message, trajectory=traj,
                        cost=cost, terminal_error=terminal_error(Xsim[-1], problem) if finite else float("inf"),
                        problem=problem, controls=U, costates=lams, history=nr.history, stats=stats, trace=(attempt,),
                        warm=start_of(traj.t, Xsim, U, problem.scheme, "indirect", costates=lams, lam0=lam.copy()))

    def _verdict(self, nr: NewtonResult, finite: bool) -> tuple[Result, str]:
        stats = self.stats
        result, message = nr.result, nr.message.replace("|F|", "|z_N|").replace(" x ", " lambda_0 ")
        if "bound_continuation" in stats:
            message += f" (bound continuation from lambda_0 = 0: {'; '.join(stats['bound_continuation'])})"
        if "time_homotopy" in stats:
            message += f"; {stats['time_homotopy']['message']}"
        if "free_time" in stats:
            message += f"; {stats['free_time']['message']}"
            if result.successful and not stats["free_time"]["converged"]:
                result = Result.max_iterations
        if not result.successful and nr.rejected_aux:
            message += (f"; {len(nr.rejected_aux)} line-search trials were rejected because their controls turned the "
                        f"body too far per step for the Cayley solve (residual up to {max(nr.rejected_aux):.1e} > "
                        f"cayley_tol {self.options.cayley_tol:.0e}): a smaller step h = T/N (increase horizon.N) or a "
                        "better initial costate (initial_costate: from_direct) may help")
        if result.successful and not finite:
            result, message = Result.non_finite, "re-simulation produced non-finite states"
        return result, message


def solve_indirect(problem: Problem, options: IndirectOptions | None = None, progress: Progress | None = None,
                   warm: Start | None = None, label: str = "") -> Solution:
    """Newton-Armijo shooting on lambda_0 (docs/mathematics.md §6, §10) for a smooth-control problem ('first_order' or
    'lgvi', whose unknown is lambda_{-1}: LGVI_CONDITIONS); problems it does not cover (:func:`not_covered`) return
    Result.not_applicable.  Beyond the paper: control bounds (semismooth Newton through :func:`~.control.saturate`,
    from lambda_0 = 0 by :func:`~.continuation.bound_continuation`), free terminal components (:func:`free_rows`), a
    free final time (:func:`~.continuation.free_final_time`), and the time (§18) and fuel (§19) objectives' laws.

    The initial costate comes from ``warm`` (:func:`initial_costate`) or ``options.initial_costate``; the iteration is
    :func:`~transcription.methods.newton.newton_armijo` on z_N(lambda_0) with the exact Jacobian Psi, round-off floor
    detection (``floor_factor``, ``floor_accept``) and trials whose rollout misses ``cayley_tol`` rejected.

    The Solution (method 'indirect', solver 'newton-armijo'): the controls (first_order 6 x N, u_1..u_N; lgvi
    6 x N+1, u_0..u_N) from the lambda_k, the costates (N, 12) lambda_0..lambda_{N-1}, the trajectory re-simulated
    from those controls with its terminal error, the cost, and the history (the initial rollout and every trial).
    """
    options = options or IndirectOptions()
    if problem.kind != "smooth":
        raise ValueError("the indirect method solves smooth-control problems")
    missing = not_covered(problem)
    if missing:
        return failed_solution(problem, "indirect", "newton-armijo", Result.not_applicable,
                               f"the indirect method does not cover {missing}; solve it by the direct method (whose "
                               "Solution carries costate estimates mapped from its multipliers)")
    try:
        lam, source, notes = initial_costate(problem, options, warm)
    except ValueError as exc:
        return failed_solution(problem, "indirect", "newton-armijo", Result.invalid_option, str(exc))
    law = problem.control.objective.indirect
    why = law.start_error(warm, source)     # the time objective starts from a solution's structure (.laws)
    if why:
        return failed_solution(problem, "indirect", "newton-armijo", Result.invalid_option, why)
    shooting = _Shooting(problem, options, progress, source)
    law.prepare(shooting, warm)
    h = initial_step(problem, warm)
    if warm is not None and np.isclose(warm.T, h * problem.N, rtol=1e-14):
        fitted = warm.fit(problem.N, problem.scheme, problem.fractions)[0]   # on a mesh: its node times
        shooting.primal = (fitted.X, fitted.U)
    r0 = shooting.cayley_residual(lam, h)
    if not r0 <= options.cayley_tol:
        return failed_solution(problem, "indirect", "newton-armijo", Result.invalid_option,
                               f"the rollout from the initial lambda_0 does not solve the Cayley equation (residual "
                               f"{r0:.1e} > cayley_tol {options.cayley_tol:.0e}): the rotation per step is too large; "
                               f"use a smaller step h = T/N (increase horizon.N) or another initial costate")
    t1 = time.perf_counter()
    nr, h = shooting.run(lam, h)
    sol = shooting.solution(nr, h, time.perf_counter() - t1, label)
    if notes:
        sol = sol.with_notes(*notes, warm_start=notes[0].removeprefix("warm start from "),
                             warm_start_resampled=any(n.startswith("resampled") for n in notes),
                             warm_start_notes="; ".join(notes[1:]))
    return sol


def initial_step(problem: Problem, warm: Start | None) -> float:
    """The first step size of the shooting: the problem's h = T/N, except for a free final time started from a
    solution (``warm``: the direct solution of initial_costate from_direct, or any warm start), whose T
    (clipped to the time bounds) goes with its costates."""
    if not problem.free_time or warm is None:
        return problem.h
    lo, hi = problem.time_bounds
    return min(max(warm.T, lo), hi) / problem.N


@dataclass(frozen=True)
class Indirect(OneFunction, name="indirect", kind="smooth", run=solve_indirect, covers=not_covered):
    """The indirect method (package docstring): one solve of the discrete necessary conditions by Newton-Armijo
    shooting on the initial costate (with the objective's law: its continuations and homotopies inside) from a
    start's costates or ``options.initial_costate``."""

    options: IndirectOptions = field(default_factory=IndirectOptions)


def outer_errors(history: list[Iterate]) -> np.ndarray:
    """|z_N|_2 after each outer iteration (index 0: the initial guess) from a history."""
    return np.array([r.residual for r in history if r.accepted])


def quadratic_constant(history: list[Iterate], floor: float = 0.0, tail_from: float = 0.1) -> float | None:
    """max e_{i+1}/e_i^2 over the full-step (c = 1) outer iterations of the local phase
    (e_i <= tail_from) that end above ``floor`` (iterations that land at the round-off
    floor measure the noise, not the convergence rate).  None if there is none."""
    acc = [r for r in history if r.accepted]
    ratios = [b.residual / a.residual ** 2 for a, b in zip(acc[:-1], acc[1:])
              if b.step == 1.0 and 0 < a.residual <= tail_from and b.residual > floor]
    return float(max(ratios)) if ratios else None
