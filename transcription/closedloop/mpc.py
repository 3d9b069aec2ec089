"""Re-planning (MPC): shrinking-horizon re-plans of a plan from the flown state, each a fixed budget of the
indirect method's Newton steps warm-started from the previous plan (docs/mathematics.md §12, *Re-planning*).

At node k (every ``replan_every`` steps) the flown state X(t_k) starts the remaining problem (the plan's Problem over
the N - k remaining steps).  Its shooting unknown (lgvi lambda_{k-1}, first order lambda_k) is warm-started from the
current plan's costate there (:meth:`~transcription.results.start.Start.tail`), then ``iterations`` full Newton steps
with the exact Jacobian, no line search (a real-time iteration: a preparation at the plan's node,
:meth:`Replanner.prepare`, and a feedback phase from the flown state).  A step whose rollout is not finite, leaves a
Cayley residual above ``cayley_tol``, or misses the target by more than the warm start did is rejected and the current
plan kept.  Why the indirect method: §12, *Why this solver*; what it does not cover the re-planner refuses.

A minimum radius (a central body's clearance, which a preset adds to every maneuver) is carried as a condition of
acceptance, not in the Newton step's optimality conditions: where it is inactive its multiplier is zero, so the
conditions without it are the constrained problem's (§12, *Path constraints*); a re-plan whose predicted nodes come
inside the radius is rejected (the current plan, which kept it, is flown on), and the flight's margins check it
between the nodes too.  A plan that touches it (:func:`touching`: the constraint active, its multiplier not zero) is
not re-planned this way.

* :class:`Replanner` -- one Problem's re-plan: ``replan(X, tail) -> (new plan | None, Replan)``;
* :class:`Replanning` -- the flight engine's control law (transcription.flight.ControlLaw): re-plans at
  k = 0, e, 2e, ... and flies the current plan's interval commands in between, optionally with the LQR
  tracker's correction around the current plan (:func:`around`: the original plan's gains).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..dynamics.flight import interval_commands
from ..dynamics.trajectory import Trajectory
from ..geometry.state import NU, NX, NZ
from ..methods.indirect.control import bound_data, weight_inverse
from ..methods.indirect.shooting import shooting_functions
from ..methods.indirect.solve import free_rows, lam0_from_costates, not_covered
from ..options import IndirectOptions
from ..ocp import TargetOrbit
from .tracking import saturate
from ..results.start import Start

#: re-plan every this many node steps (the flight block's ``mpc.replan_every``)
DEFAULT_REPLAN_EVERY = 10
#: Newton steps per re-plan (the flight block's ``mpc.iterations``): one, as acados' real-time iteration
DEFAULT_ITERATIONS = 1
#: a re-plan is accepted when its prediction misses the terminal conditions by less than the warm start did, or by
#: less than this times the target state's largest magnitude (round-off, in the file's units: ~1 for a normalized
#: orbit, the momentum m |v| ~ 4e3 kg km/s in LEO): near the end of a plan on its bounds the remaining problem can
#: become infeasible
ACCEPT_BELOW = 1e-9


@dataclass(frozen=True)
class Replan:
    """What one re-plan did: at node ``k`` over ``horizon`` steps, |F| of the warm start (``residual_before``) and of
    the re-plan's own prediction (``residual_after``), the wall time from the flown state to the new plan
    (``solve_s``) and of the preparation (``prepare_s``), ``accepted`` (else the current plan was kept) and why not
    (``message``)."""

    k: int
    horizon: int
    residual_before: float
    residual_after: float
    solve_s: float
    accepted: bool
    message: str = ""
    prepare_s: float = 0.0


#: the path constraints a re-plan carries as a condition of acceptance (module docstring)
CHECKED_CONSTRAINTS = ("min_radius",)


def checked_constraints(problem) -> tuple:
    """The path constraints of ``problem`` the re-plans check on their predicted nodes (CHECKED_CONSTRAINTS)."""
    return tuple(c for c in problem.constraints if c.kind in CHECKED_CONSTRAINTS)


def least_margins(problem, X: np.ndarray) -> list[tuple[object, int, float]]:
    """(constraint, node, margin) of the smallest margin of each checked constraint (:func:`checked_constraints`)
    over the nodes X (n, 18), in the constraint's own unit (its ``margin``)."""
    traj = Trajectory(t=np.zeros(len(X)), X=np.asarray(X, float), mass=problem.model.mass,
                      inertia=problem.model.inertia)
    out = []
    for c in checked_constraints(problem):
        m = c.margin(traj)
        k = int(np.argmin(m))
        out.append((c, k, float(m[k])))
    return out


def touching(problem, X: np.ndarray, tol: float) -> str:
    """'' unless the plan's nodes X (N+1, 18) come within ``tol`` (the constraint's unit) of a checked constraint's
    bound (:func:`checked_constraints`), where it may be active and the re-plans' conditions without it are not the
    problem's; else which, by how much and at which node."""
    for c, k, m in least_margins(problem, X):
        if m <= tol:
            return f"the plan touches its {c.kind} {c.limit:.6g} (margin {m:.3g} at node {k})"
    return ""


def replanned_problem(problem):
    """The problem a re-plan's Newton step solves: ``problem`` without the constraints it checks instead
    (:func:`checked_constraints`)."""
    if not checked_constraints(problem):
        return problem
    return problem.replace(constraints=tuple(c for c in problem.constraints if c.kind not in CHECKED_CONSTRAINTS))


def replan_not_covered(problem) -> str:
    """What of ``problem`` the re-planner does not cover ('' if nothing): what the indirect method does not cover with
    the effort law (:func:`~.methods.indirect.solve.not_covered`) on :func:`replanned_problem`, and an orbit target
    (the re-plan's shooting is the state target's)."""
    reasons = [r for r in (not_covered(replanned_problem(problem), replan=True),) if r]
    if isinstance(problem.terminal, TargetOrbit):
        reasons.append("an orbit target in a re-plan")
    return ", ".join(reasons)


def polished(plan) -> tuple[object, str]:
    """(the plan Solution with the warm start the re-plans take, a sentence saying which).  A direct plan's costates
    are IPOPT's multipliers, accurate to its tolerance, and a re-plan's shooting over a long horizon amplifies their
    error: the plan's warm start is polished by the indirect method's Newton shooting of :func:`replanned_problem`
    from the plan itself (one solve, a few iterations), and kept as it is when that does not converge."""
    from ..solve import solve

    if plan.method == "indirect":
        return plan, "the indirect plan's own costates"
    ind = solve(replanned_problem(plan.problem), "indirect", warm_start=plan)
    if not ind.converged or ind.warm is None:
        return plan, f"the {plan.method} plan's costates (the indirect method's polish did not converge: {ind.result})"
    return dataclasses.replace(plan, warm=ind.warm), (f"the {plan.method} plan's costates polished by the indirect "
                                                      f"method (|z_N| {ind.terminal_error:.1e})")


class Replanner:
    """Re-plans of one Problem (smooth-control effort, state target) at the (mean) step size h (on a mesh the
    remaining steps h r_k, :meth:`steps`): ``iterations`` Newton steps on the remaining problem's shooting unknown
    from a warm start; ``jit``: the per-step maps compiled to C.  ValueError for a problem not covered."""

    def __init__(self, problem, h: float, iterations: int = DEFAULT_ITERATIONS, jit: bool = True,
                 cayley_tol: float = IndirectOptions.cayley_tol):
        reason = replan_not_covered(problem)
        if reason:
            raise ValueError(f"MPC re-plans by the indirect method's Newton step, which does not cover {reason}")
        if int(iterations) < 1:
            raise ValueError(f"iterations: expected a positive integer, got {iterations}")
        self.problem, self.h, self.iterations, self.jit = problem, float(h), int(iterations), bool(jit)
        self.Xd, self.Winv, self.bd = problem.terminal.X, weight_inverse(problem), bound_data(problem)
        self.free, self.cayley_tol = free_rows(problem.terminal), float(cayley_tol)

    def steps(self, n: int) -> float | np.ndarray:
        """The step sizes of the last n steps (a shrinking horizon's remainder): h on a uniform mesh, else h_k =
        h r_k of steps N-n..N-1 of the problem's mesh (docs/mathematics.md §17)."""
        s = self.problem.steps_of(self.h)
        return s if np.ndim(s) == 0 else s[len(s) - int(n):]

    def functions(self, n: int):
        """The indirect method's shooting Functions of n steps (built once per n and Discretization)."""
        return shooting_functions(self.problem.disc, int(n), self.jit)

    def start(self, plan: Start) -> Start:
        """``plan`` with its shooting unknown: its own lam0, else from its costates (methods.indirect.solve.
        lam0_from_costates at the plan's X_0 and h: the LGVIs' lambda_{-1} = A_0^T lambda_0, lgvi_kepler's too).
        ValueError without costates."""
        if plan.lam0 is not None:
            return plan
        if plan.costates is None:
            raise ValueError("MPC: the plan carries no costates to warm-start the re-plans from")
        lam0 = lam0_from_costates(self.problem.replace(X0=np.asarray(plan.X[0], float)), plan.costates[0],
                                  plan.U[:, 0], self.h, plan.U[:, 1] if plan.U.shape[1] > 1 else None)
        return Start(t=plan.t, X=plan.X, U=plan.U, scheme=plan.scheme, source=plan.source,
                         costates=plan.costates, lam0=np.asarray(lam0, float))

    def prepare(self, tail: Start) -> tuple[np.ndarray, float]:
        """The preparation phase of a re-plan: the Jacobian dF/dlam at the predicted state ``tail.X[0]`` and the warm
        start, before the flown state is known; and its wall time (s)."""
        t0 = time.perf_counter()
        _, J = self._newton_system(self.functions(tail.N), np.asarray(tail.lam0, float).reshape(NZ),
                                   (tail.X[0], self.Xd, self.steps(tail.N), self.Winv, self.bd))
        return J, time.perf_counter() - t0

    def replan(self, X, tail: Start, k: int = 0, J0: np.ndarray | None = None) -> tuple[Start | None, Replan]:
        """The remaining problem from the state X (18,) over ``tail.N`` steps, warm-started from ``tail``: the new plan
        (node times from 0, predicted states X_0 = X .. X_n, controls, costates, lam0), or None when rejected; and the
        :class:`Replan` record (k: the node).  ``J0``: the prepared Jacobian (:meth:`prepare`) for the first step;
        without it every step takes the exact Jacobian at X."""
        X, n = np.asarray(X, float).reshape(NX), tail.N
        fns, args = self.functions(n), (X, self.Xd, self.steps(n), self.Winv, self.bd)
        lam, before, msg = np.asarray(tail.lam0, float).reshape(NZ), np.nan, ""
        t0 = time.perf_counter()
        try:
            for i in range(self.iterations):
                F, J = (self._residual(fns, lam, args), J0) if i == 0 and J0 is not None else \
                    self._newton_system(fns, lam, args)
                before = np.linalg.norm(F) if i == 0 else before
                lam = lam - np.linalg.solve(J, F)
            zN, Xs, lams, U, res, _ = (np.array(a) for a in fns.shoot(lam, *args))
        except np.linalg.LinAlgError as e:
            zN, res, msg = np.full(NZ, np.nan), np.array([np.inf]), f"singular Newton system ({e})"
        solve_s = time.perf_counter() - t0
        after = float(np.linalg.norm(np.where(self.free, 0.0, zN.ravel())))
        ok = not msg and np.isfinite(after) and bool(np.all(np.isfinite(U))) and float(np.max(res)) <= self.cayley_tol
        if not ok and not msg:
            msg = f"the re-planned rollout is not finite or leaves a Cayley residual {float(np.max(res)):.1e}"
        elif ok and not (after <= before or after <= ACCEPT_BELOW * max(1.0, float(np.abs(self.Xd).max()))):
            ok, msg = False, f"the re-plan misses its own target by more than the warm start ({after:.1e} > {before:.1e})"
        elif ok:
            msg = self.violated(Xs.T)
            ok = not msg
        rec = Replan(k=int(k), horizon=int(n), residual_before=float(before), residual_after=after, solve_s=solve_s,
                     accepted=bool(ok), message=msg)
        if not ok:
            return None, rec
        hs = self.steps(n)
        t = np.arange(n + 1) * self.h if np.ndim(hs) == 0 else np.r_[0.0, np.cumsum(hs)]
        new = Start(t=t, X=np.vstack([X[None, :], Xs.T]), U=U, scheme=tail.scheme,
                        source="mpc", costates=lams.T, lam0=lam)
        return new, rec

    def violated(self, Xs: np.ndarray) -> str:
        """'' when the predicted nodes Xs (n, 18) keep every checked constraint (:func:`checked_constraints`), else
        which one they violate and by how much (its margin's unit)."""
        for c, _, worst in least_margins(self.problem, Xs):
            if worst < 0:
                return f"the re-plan's prediction violates its {c.kind} {c.limit:.6g} by {-worst:.3g} at a node"
        return ""

    def _residual(self, fns, lam, args) -> np.ndarray:
        """F: the shooting residual (z_N, lambda_{n-1} on free terminal rows) of one rollout."""
        zN, lamN, _ = fns.residual(lam, *args)
        return np.where(self.free, np.array(lamN).ravel(), np.array(zN).ravel())

    def _newton_system(self, fns, lam, args) -> tuple[np.ndarray, np.ndarray]:
        """(F, dF/dlam): the shooting residual (z_N, lambda_{n-1} on free terminal rows) and its Jacobian."""
        zN, Psi, dlamN = fns.shoot_jac(lam, *args)
        F, J = np.array(zN).ravel(), np.array(Psi)
        if self.free.any():
            lamN = np.array(fns.residual(lam, *args)[1]).ravel()
            F, J = np.where(self.free, lamN, F), np.where(self.free[:, None], np.array(dlamN), J)
        return F, J


class Replanning:
    """The control law of a re-planned flight (transcription.flight.ControlLaw): at nodes k = 0, e, 2e, ...
    (e = ``every``; none in the last ``min_horizon - 1`` steps) the :class:`Replanner` re-plans the remainder from
    the flown state X(t_k); over every interval the current plan's command (transcription.flight.interval_commands),
    plus, with ``gains`` (the original plan's tracking Gains), the tracker's correction around the current plan
    (:func:`around`).  ``prepared``: the first Newton step takes the prepared Jacobian (:meth:`Replanner.prepare`).
    ``replans``: the :class:`Replan` records, in order."""

    def __init__(self, replanner: Replanner, plan: Start, every: int = DEFAULT_REPLAN_EVERY,
                 min_horizon: int = 1, gains=None, prepared: bool = True):
        if int(every) < 1 or int(min_horizon) < 1:
            raise ValueError("every and min_horizon: expected positive integers")
        self.replanner, self.every, self.min_horizon = replanner, int(every), int(min_horizon)
        self.current, self.k0, self.N, self.prepared = replanner.start(plan), 0, plan.N, bool(prepared)
        self.gains, self.tracker = gains, None if gains is None else gains.tracker()
        self.replans: list[Replan] = []
        self._saturated, self._steps = 0, 0

    def commands(self, k: int, t: float, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if k % self.every == 0 and self.N - k >= self.min_horizon:
            tail, k0 = self.current.tail(k - self.k0), self.k0
            J0, prep = self.replanner.prepare(tail) if self.prepared else (None, 0.0)
            new, rec = self.replanner.replan(X, tail, k, J0)
            self.replans.append(dataclasses.replace(rec, prepare_s=prep))
            if new is not None:
                self.current, self.k0 = new, k
                if self.gains is not None:       # the disturbance estimate carries over to the new plan's tracker
                    r = self.tracker.unexplained(k - k0, X)
                    self._saturated += self.tracker.saturated_steps
                    self.tracker = around(self.gains, k, new).tracker(r0=r)
        j, self._steps = k - self.k0, k + 1
        start, end = interval_commands(self.current.scheme, self.current.U[:, j:j + 2])
        a, b = start[:NU, 0], end[:NU, 0]
        if self.tracker is None:
            return a, b
        du = self.tracker.correction(j, X)
        a, b = a + du, b + du
        if self.tracker.bounded:       # the plan's round-off only (the correction keeps within the headroom)
            g = self.gains
            a, b = (saturate(u, g.force_bound, g.moment_bound)[0] for u in (a, b))
        return a, b

    @property
    def solve_times(self) -> np.ndarray:
        """The wall time (s) of every re-plan so far, from the flown state to the new plan."""
        return np.array([r.solve_s for r in self.replans], float)

    @property
    def prepare_times(self) -> np.ndarray:
        """The wall time (s) of every re-plan's preparation phase so far (0 without)."""
        return np.array([r.prepare_s for r in self.replans], float)

    @property
    def rejected(self) -> int:
        return sum(not r.accepted for r in self.replans)

    @property
    def saturated_fraction(self) -> float:
        """The fraction of the steps so far whose tracker correction the actuators' bounds limited."""
        steps = self._saturated + (self.tracker.saturated_steps if self.tracker is not None else 0)
        return steps / self._steps if self._steps else 0.0


def around(gains, k: int, plan: Start):
    """The original plan's tracker ``gains`` from node k on, around the re-planned ``plan`` (its X and U over the
    remaining N - k steps): the original gains and linearization, which a nearby re-plan changes only to first
    order; on a non-uniform mesh the steps k..N-1."""
    return dataclasses.replace(gains, K=gains.K[k:], L=gains.L[k:], P=gains.P[k:], S=gains.S[k:], A=gains.A[k:],
                               B=gains.B[k:], t=gains.t[k:], X=plan.X, U=plan.U,
                               steps=None if gains.steps is None else gains.steps[k:],
                               eps=None if gains.eps is None else gains.eps[k:],
                               f=None if gains.f is None else gains.f[k:])
