"""The translational relaxation of a fuel maneuver by successive convexification (SCvx), issue 41's speed anchor.

    .venv/bin/python scripts/scvx_relaxation.py configs/leo_body_engine.yaml --set control.objective=fuel

needs the optional extra ``scvx`` (cvxpy and Clarabel: ``pip install -e '.[scvx]'``).

The problem, read from a maneuver's :class:`~se3ocp.Problem` (``se3ocp.load(path).problem``; no number of a config is
copied here): the translation alone, the force free to point anywhere in the inertial frame,

    min  sum_j omega_j w_f |u_j|         (j = 0..N, omega the trapezoid of the LGVIs' node controls: the fuel
                                          objective's own quadrature, transcription.ocp.quadrature_weights)
    s.t. |u_j| <= F                       (F the force bound's largest norm: an engine's max thrust)
         (x_{k+1}, v_{k+1}) = step_k(x_k, v_k, u_k, u_{k+1})     (the scheme's translation, below)
         (x_0, v_0) from X0,  the terminal target's translational rows = 0.

The step is lgvi_kepler's translation (docs/mathematics.md §2a, eq. 7a): kick by the non-Kepler force and the
control, the exact two-body drift, kick --

    v+ = v_k + h/(2m) (f_P(x_k) + u_k),   (x_{k+1}, v-) = kepler_drift(mu)(x_k, v+, h),
    v_{k+1} = v- + h/(2m) (f_P(x_{k+1}) + u_{k+1}),

with the drift the project's own CasADi Function (``transcription.dynamics.kepler.kepler_drift``, Lagrange's f and g
in universal variables) and f_P = (the model's force at the initial attitude) - (the point-mass force
``kepler_force``): for a rigid body around a point mass the coupling to the attitude, ~1e-14 of gravity.  The
scheme 'lgvi' (a file that names it) drifts freely instead (eq. 7-8).  The step and its Jacobians are evaluated by
CasADi's algorithmic differentiation on that graph (no finite differences).  The terminal conditions are the
project's own (``transcription.ocp.terminal_rows``) at a terminal state whose attitude and angular momentum are
free: a state target's position and momentum rows (a target given by elements, as leo_body_engine's, is such a
state target), linearized by CasADi; an orbit target's |x| - r, e_n.x and momentum rows.

SCvx (Mao, Szmuk and Acikmese 2016, 2018, in the form of Malyuta et al., "Convex optimization for trajectory
generation", IEEE Control Systems 42(5), 2022): in canonical units (length the initial radius, time its
sqrt(r^3 / mu), force the bound F), from the free motion (u = 0, the step's rollout from X0 -- not an interpolation:
the raise is 1.5e-3 of the radius, so the free orbit is near every feasible path), each iteration linearizes the step
and the terminal rows about the last iterate (ref) and solves the second-order-cone subproblem in the changes d

    min  sum_j omega_j/T |u_j| + lam (sum_k |nu_k|_1 + |nu_N|_1) + (prox/2) |d|^2
    s.t. dz_{k+1} = step_k(ref) - z_{k+1} + A_k dz_k + B_k du_k + C_k du_{k+1} + nu_k    (virtual controls nu_k)
         r(ref_N) + J_r dz_N + nu_N = 0,   dz_0 = z_0 - ref_0,   |u_j| <= 1 (u = ref + du),
         |dz|_inf <= eta, |du|_inf <= eta                                                  (the trust region)

by Clarabel through cvxpy (tolerances 1e-10).  The ratio rho = (Jt(ref) - Jt(new)) / (Jt(ref) - L(new)) of the
actual to the predicted decrease of the penalized cost Jt = cost + lam (|defects|_1 + |r(z_N)|_1) (L the subproblem's
cost without its proximal term) accepts or rejects the step and scales eta (Malyuta's rule): rho < rho0 = 0 rejected,
eta / 2; rho < rho1 = 0.1 accepted, eta / 2; rho >= rho2 = 0.7 accepted, 2 eta; else accepted, eta kept.  Converged
when a subproblem's virtual controls are at most ``tol_nu`` = 1e-9 and its step at most ``tol_step`` = 1e-5 (canonical
units, max-norm) and it was accepted.  lam = 1e4 exceeds the dynamics' multipliers (a velocity change of one canonical
unit, 7.7 km/s, costs ~700 in the scaled cost of a LEO raise, whose engine gives T F / m = 11 m/s), so the penalty is
exact: the virtual controls end at ~1e-15, and ``defect`` reports the dynamics' largest defect of the returned iterate.

The proximal term (the penalized trust region of PTR, here beside the hard one) is there because the optimum is
degenerate: for a small raise any spread of along-track burns that keeps the orbit circular and the phase costs the
same to first order, so the linearized subproblem has a flat face of optima, and without the term SCvx hops along it
(steps of 0.3 F at a cost constant to 1e-9, never converging by its step).  With prox = 1e-3 the step contracts by
~0.3 per iteration down to Clarabel's noise floor (its tolerance / prox = 1e-7); prox does not move the fixed point (its gradient vanishes at
d = 0).  Measured on leo_body_engine with the fuel objective (N = 400): 9 iterations, ~1.2 s wall of which Clarabel
0.7 s, cost 2.8252906891 kN s (5.650581 m/s, 8.3e-8 above Hohmann's), its controls flown by the step from X0 miss the
target by 3e-9 km.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import math
import time
import warnings
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

import se3ocp
from se3ocp import NormBound, TargetOrbit, TargetRendezvous, TargetState
from se3ocp.transcription.dynamics.kepler import kepler_drift, kepler_force
from se3ocp.transcription.dynamics.lgvi import discretization
from se3ocp.transcription.geometry.state import X_ANG, X_MOM, X_POS, X_ROT
from se3ocp.transcription.ocp import quadrature_weights, terminal_rows


# ----------------------------------------------------------------------------------------------- the problem
@dataclass(frozen=True)
class Translation:
    """The translational relaxation of ``problem`` (module docstring), in canonical units: length LU = |x_0|, time
    TU = sqrt(LU^3 / mu), velocity VU = LU / TU, force F (the bound's largest norm).  z = (x / LU, v / VU) (6,),
    controls u / F (3,) at the N + 1 nodes."""

    problem: se3ocp.Problem
    F: float
    LU: float
    TU: float
    VU: float
    step: ca.Function = field(repr=False)          # (z[6], u0[3], u1[3], h) -> (z1[6], A[6x6], B[6x3], C[6x3])
    rows: ca.Function = field(repr=False)          # (zN[6]) -> (r[nr], J[nr x 6]), r scaled per row
    omega: np.ndarray = field(repr=False)          # quadrature weights / T (N+1,)

    @property
    def N(self) -> int:
        return self.problem.N

    @property
    def z0(self) -> np.ndarray:
        X0, m = self.problem.X0, self.problem.model.mass
        return np.concatenate([X0[X_POS] / self.LU, X0[X_MOM] / (m * self.VU)])

    def cost(self, U: np.ndarray) -> float:
        """The fuel cost sum_j omega_j w_f |u_j| in the problem's units (U (3, N+1) in units of F)."""
        w_f = float(self.problem.control.W_f[0, 0])
        return float(w_f * self.F * self.problem.T * np.sum(self.omega * np.linalg.norm(U, axis=0)))

    def rollout(self, U: np.ndarray) -> np.ndarray:
        """The states (6, N+1) the step flies from z0 under the controls U (3, N+1) (canonical units)."""
        Z = np.empty((6, self.N + 1))
        Z[:, 0] = self.z0
        hs = self.problem.steps / self.TU
        for k in range(self.N):
            Z[:, k + 1] = np.asarray(self.step(Z[:, k], U[:, k], U[:, k + 1], hs[k])[0]).ravel()
        return Z


def translation(problem: se3ocp.Problem) -> Translation:
    """The translational relaxation of a smooth-control ``problem`` around a central body (module docstring)."""
    model, m = problem.model, float(problem.model.mass)
    mu = float(model.mu or 0.0)
    if not mu:
        raise ValueError("the translational relaxation is written for a central body (the model's mu)")
    if problem.scheme not in ("lgvi", "lgvi_kepler"):
        raise ValueError(f"the translation of {problem.scheme!r} is not written here (lgvi, lgvi_kepler)")
    if problem.free_time:
        raise ValueError("a free final time is not written here")
    bound = problem.control.force_bound
    F = bound.largest_norm() if bound is not None and not bound.removed else math.inf
    if not math.isfinite(F):
        raise ValueError("the fuel relaxation needs a bounded force")
    X0 = problem.X0
    LU = float(np.linalg.norm(X0[X_POS]))
    TU = math.sqrt(LU**3 / mu)
    VU = LU / TU
    R0 = ca.DM(X0[X_ROT].reshape(3, 3, order="F"))

    def f_P(x):            # the model's force at the initial attitude less its point-mass part
        return model.forces(x, R0)[0] - kepler_force(mu, m, x)

    z, u0, u1, hs = ca.SX.sym("z", 6), ca.SX.sym("u0", 3), ca.SX.sym("u1", 3), ca.SX.sym("h")
    x, v, h = LU * z[:3], VU * z[3:], TU * hs
    if problem.scheme == "lgvi_kepler":
        vp = v + h / (2 * m) * (f_P(x) + F * u0)
        x1, vm, _ = kepler_drift(mu)(x, vp, h)
        v1 = vm + h / (2 * m) * (f_P(x1) + F * u1)
    else:                  # eq. (7)-(8): kick by the whole force, free drift, kick
        f = lambda y: model.forces(y, R0)[0]
        vp = v + h / (2 * m) * (f(x) + F * u0)
        x1 = x + h * vp
        v1 = vp + h / (2 * m) * (f(x1) + F * u1)
    z1 = ca.vertcat(x1 / LU, v1 / VU)
    step = ca.Function("translation_step", [z, u0, u1, hs],
                       [z1, ca.jacobian(z1, z), ca.jacobian(z1, u0), ca.jacobian(z1, u1)])

    # the terminal rows: the project's own residual at a terminal state of free attitude and angular momentum
    target = problem.terminal
    XN = ca.vertcat(LU * z[:3], m * VU * z[3:], ca.DM(X0[X_ROT]), ca.DM(X0[X_ANG]))
    if isinstance(target, TargetState):
        free = frozenset(target.free) | {"attitude", "angular_velocity"}
        r = terminal_rows(XN, problem.replace(terminal=TargetState(target.X, free)))
    elif isinstance(target, TargetRendezvous):
        r = terminal_rows(XN, problem.replace(terminal=dataclasses.replace(target, R=None, Pi=None)))
    elif isinstance(target, TargetOrbit):
        r = terminal_rows(XN, problem)[[0, 1, 4, 5, 6]]       # |x| - r, e_n.x, momentum; not the body axis nor Pi
    else:
        raise ValueError(f"a terminal target {type(target).__name__} is not written here")
    Jr = ca.jacobian(r, z)
    scale = np.linalg.norm(np.asarray(ca.Function("J0", [z], [Jr])(np.concatenate(
        [X0[X_POS] / LU, X0[X_MOM] / (m * VU)]))), axis=1)       # each row in canonical units
    scale = np.where(scale > 0, scale, 1.0)
    rows = ca.Function("terminal_rows", [z], [r / ca.DM(scale), Jr / ca.repmat(ca.DM(scale), 1, 6)])
    omega = quadrature_weights(problem.scheme, problem.N, problem.steps_of(problem.h)) / problem.T
    return Translation(problem, F, LU, TU, VU, step, rows, omega)


def relaxed_problem(problem: se3ocp.Problem) -> se3ocp.Problem:
    """The same relaxation as a Problem for our direct method: the force in the inertial frame (as
    ``transcription.objectives.effort.relaxation`` makes it) under the norm bound F, the moment removed (a norm
    bound of 0), the terminal attitude and angular momentum free, no path constraints.  The attitude states stay in
    the NLP but nothing acts on them except the body's own gravity-gradient torque, and nothing asks anything of
    them: its optimum is the translational one."""
    c, d, target = problem.control, problem.disc, problem.terminal
    F = c.force_bound.largest_norm()
    if isinstance(target, TargetState):
        target = TargetState(target.X, frozenset(target.free) | {"attitude", "angular_velocity"})
    elif isinstance(target, TargetRendezvous):
        target = dataclasses.replace(target, R=None, Pi=None)
    else:
        raise ValueError(f"a terminal target {type(target).__name__} is not relaxed here")
    return problem.replace(disc=discretization(d.model, d.scheme, d.newton_iters, force_frame="inertial"),
                           control=dataclasses.replace(c, force_bound=NormBound(F), moment_bound=NormBound(0.0)),
                           terminal=target, constraints=())


#: IPOPT's KKT tolerance for the relaxed fuel problem: the default 1e-10 is not met on it (its optimum is degenerate,
#: module docstring); measured on leo_body_engine's relaxation at N = 25 (the fuel strategy's coarsest grid): tol 1e-10
#: ended infeasible after 955 iterations (its homotopy 'acceptable'), tol 1e-8 converged in 738
IPOPT_TOL = 1e-8


def solve_relaxed(problem: se3ocp.Problem, tol: float = IPOPT_TOL, **options):
    """Our direct method (IPOPT) on :func:`relaxed_problem` of ``problem``: the objective's own strategy (for fuel
    :class:`FuelStrategy`) on the problem's scheme, KKT tolerance ``tol``, no continuous check (the SCvx relaxation has
    none).  Why not ``se3ocp.solve``'s defaults: for lgvi_kepler they first solve the problem on the lgvi scheme
    (``transcription.solve.solve_direct``, ``from_scheme``), whose orbit is 3.5 km (N = 400) to 56 km (N = 100) off
    the exact one, and their tol is 1e-10.  Measured on leo_body_engine's relaxation: N = 400, defaults: solver_failed
    after 1626 iterations, 115 s; N = 400, tol 1e-8 with the detour: 'terminal_error' after 74 iterations; N = 100 with
    the detour: the lgvi effort problem 'infeasible'.  This function: N = 400 converged in 809 iterations, ~8 s."""
    rel = relaxed_problem(problem)
    strategy = rel.control.objective.strategy(rel, None)
    return se3ocp.solve(rel, continuous_check=False, strategy=strategy, direct={"tol": tol}, **options)


# ------------------------------------------------------------------------------------------------------ SCvx
@dataclass(frozen=True)
class Options:
    """SCvx's parameters (module docstring); tolerances in canonical units, max-norm."""

    lam: float = 1e4              # the virtual controls' L1 penalty weight
    eta0: float = 1.0             # the first trust region
    eta_min: float = 1e-8
    eta_max: float = 10.0
    rho0: float = 0.0
    rho1: float = 0.1
    rho2: float = 0.7
    beta: float = 2.0             # shrink and growth factor of the trust region
    prox: float = 1e-3            # the subproblem's proximal weight (prox/2) |d|^2 (module docstring)
    tol_nu: float = 1e-9          # converged: the subproblem's virtual controls at most this ...
    tol_step: float = 1e-5        # ... and its step at most this
    max_iter: int = 50
    clarabel: dict = field(default_factory=lambda: {"tol_gap_abs": 1e-10, "tol_gap_rel": 1e-10, "tol_feas": 1e-10})


@dataclass
class Result:
    """What :func:`solve` returns: the cost (the problem's units), the controls U (3, N+1, the problem's force units,
    inertial), the states (x (3, N+1), v (3, N+1)), the iterations (subproblems solved) and the accepted ones, the
    wall time of the whole solve (linearizations, cvxpy's compilation, Clarabel), Clarabel's own time summed, the
    setup time (building the CasADi step), whether it converged, the final trust region, the largest dynamics
    ``defect`` of the returned iterate (km, km/s) and the terminal miss of the controls flown by the step from X0
    (position km, velocity km/s), how many subproblems Clarabel solved only to its reduced accuracy ('optimal_inaccurate',
    accepted as cvxpy does), one record per iteration."""

    cost: float
    U: np.ndarray
    x: np.ndarray
    v: np.ndarray
    iterations: int
    accepted: int
    wall_s: float
    solver_s: float
    setup_s: float
    converged: bool
    eta: float
    defect: tuple[float, float]
    miss: tuple[float, float]
    inaccurate: int = 0
    history: list = field(default_factory=list)


def _linearize(tr: Translation, Z: np.ndarray, U: np.ndarray):
    """The step's value and Jacobians at every step of the reference (Z, U), and the terminal rows at Z_N."""
    N = tr.N
    stepN = tr.step.map(N)
    hs = tr.problem.steps / tr.TU
    z1, A, B, C = stepN(Z[:, :-1], U[:, :-1], U[:, 1:], hs.reshape(1, -1))
    A = np.asarray(A).reshape(6, N, 6).transpose(1, 0, 2)      # (N, 6, 6): horzcat of the maps' 6x6 blocks
    B = np.asarray(B).reshape(6, N, 3).transpose(1, 0, 2)
    C = np.asarray(C).reshape(6, N, 3).transpose(1, 0, 2)
    r, J = tr.rows(Z[:, -1])
    return np.asarray(z1), A, B, C, np.asarray(r).ravel(), np.asarray(J)


def _penalized(tr: Translation, lam: float, Z, U, lin=None) -> tuple[float, float, float]:
    """(Jt, cost part, largest defect) of the penalized nonlinear cost at (Z, U) (canonical units)."""
    z1, *_, r, _ = lin if lin is not None else _linearize(tr, Z, U)
    defects = z1 - Z[:, 1:]
    cost = float(np.sum(tr.omega * np.linalg.norm(U, axis=0)))
    return cost + lam * (np.abs(defects).sum() + np.abs(r).sum()), cost, float(np.abs(defects).max(initial=0.0))


def _subproblem(tr: Translation, Z, U, lin, eta: float, opts: Options):
    """The convex subproblem about (Z, U) (module docstring), solved by Clarabel through cvxpy: (dZ, dU, nu, L, the
    solver's time)."""
    import cvxpy as cp
    import scipy.sparse as sp

    N = tr.N
    z1, A, B, C, r, J = lin
    dZ, dU = cp.Variable((6, N + 1)), cp.Variable((3, N + 1))
    nu, nuN = cp.Variable((6, N)), cp.Variable(r.size)
    # dz_{k+1} - A_k dz_k - B_k du_k - C_k du_{k+1} - nu_k = step_k(ref) - z_{k+1}, stacked column-major
    eye6 = sp.identity(6 * N, format="csr")
    S = sp.hstack([sp.csr_matrix((6 * N, 6)), eye6]) - sp.hstack([sp.block_diag(list(A), format="csr"),
                                                                  sp.csr_matrix((6 * N, 6))])
    Bu = sp.hstack([sp.block_diag(list(B), format="csr"), sp.csr_matrix((6 * N, 3))]) + \
        sp.hstack([sp.csr_matrix((6 * N, 3)), sp.block_diag(list(C), format="csr")])
    dz, du = cp.vec(dZ, order="F"), cp.vec(dU, order="F")
    rhs = (z1 - Z[:, 1:]).ravel(order="F")
    Unew = U + dU
    cons = [S @ dz - Bu @ du - cp.vec(nu, order="F") == rhs,
            dZ[:, 0] == tr.z0 - Z[:, 0],
            r + J @ dZ[:, -1] + nuN == 0,
            cp.norm(Unew, 2, axis=0) <= 1.0,
            cp.abs(dZ) <= eta, cp.abs(dU) <= eta]
    L = tr.omega @ cp.norm(Unew, 2, axis=0) + opts.lam * (cp.sum(cp.abs(nu)) + cp.sum(cp.abs(nuN)))
    prob = cp.Problem(cp.Minimize(L + 0.5 * opts.prox * (cp.sum_squares(dZ) + cp.sum_squares(dU))), cons)
    with warnings.catch_warnings():      # 'Solution may be inaccurate': kept as the status, counted by solve()
        warnings.simplefilter("ignore", UserWarning)
        prob.solve(solver=cp.CLARABEL, **opts.clarabel)
    if prob.status not in ("optimal", "optimal_inaccurate"):
        raise RuntimeError(f"the SCvx subproblem ended {prob.status}")
    solve_s = float(prob.solver_stats.solve_time or 0.0)
    return (dZ.value, dU.value, np.concatenate([nu.value.ravel(), nuN.value]), float(L.value), solve_s,
            prob.status == "optimal_inaccurate")


def solve(problem: se3ocp.Problem, options: Options | None = None, progress: bool = False) -> Result:
    """SCvx on the translational relaxation of ``problem`` from the free motion (module docstring)."""
    importlib.import_module("cvxpy")     # before the clock starts: a solve's time, not the import's

    opts = options or Options()
    t0 = time.perf_counter()
    tr = translation(problem)
    setup_s = time.perf_counter() - t0
    U = np.zeros((3, tr.N + 1))
    Z = tr.rollout(U)                                     # the free motion
    lin = _linearize(tr, Z, U)
    Jt, _, _ = _penalized(tr, opts.lam, Z, U, lin)
    eta, solver_s, history, accepted, converged, inaccurate = opts.eta0, 0.0, [], 0, False, 0
    for it in range(1, opts.max_iter + 1):
        dZ, dU, nu, L, s, inexact = _subproblem(tr, Z, U, lin, eta, opts)
        inaccurate += inexact
        solver_s += s
        step = float(max(np.abs(dZ).max(), np.abs(dU).max()))
        nu_max = float(np.abs(nu).max(initial=0.0))
        Zn, Un = Z + dZ, U + dU
        lin_n = _linearize(tr, Zn, Un)
        Jn, cost_n, defect_n = _penalized(tr, opts.lam, Zn, Un, lin_n)
        predicted = Jt - L
        rho = (Jt - Jn) / predicted if predicted > 0 else 1.0
        rec = {"iteration": it, "eta": eta, "rho": rho, "step": step, "nu": nu_max, "cost": cost_n,
               "defect": defect_n, "solver_s": s, "inaccurate": bool(inexact)}
        if rho >= opts.rho0:
            Z, U, lin, Jt = Zn, Un, lin_n, Jn
            accepted += 1
            rec["accepted"] = True
        else:
            rec["accepted"] = False
        if progress:
            print(" ".join(f"{k} {v:.12g}" if k == "cost" else f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in rec.items()), flush=True)
        history.append(rec)
        if rec["accepted"] and nu_max <= opts.tol_nu and step <= opts.tol_step:
            converged = True
            break
        if rho < opts.rho1:
            eta = max(opts.eta_min, eta / opts.beta)
        elif rho >= opts.rho2:
            eta = min(opts.eta_max, eta * opts.beta)
    wall_s = time.perf_counter() - t0
    z1 = lin[0]
    defect = float(np.abs(z1 - Z[:, 1:])[:3].max()) * tr.LU, float(np.abs(z1 - Z[:, 1:])[3:].max()) * tr.VU
    flown = tr.rollout(U)[:, -1]
    r, _ = tr.rows(flown)
    m = problem.model.mass
    Xd = problem.terminal.X if isinstance(problem.terminal, TargetState) else None
    if Xd is not None:
        miss = (float(np.linalg.norm(flown[:3] * tr.LU - Xd[X_POS])),
                float(np.linalg.norm(flown[3:] * tr.VU - Xd[X_MOM] / m)))
    else:
        miss = (float(np.abs(np.asarray(r)).max()) * tr.LU, math.nan)
    return Result(cost=tr.cost(U), U=U * tr.F, x=Z[:3] * tr.LU, v=Z[3:] * tr.VU, iterations=len(history),
                  accepted=accepted, wall_s=wall_s, solver_s=solver_s, setup_s=setup_s, converged=converged,
                  eta=eta, defect=defect, miss=miss, inaccurate=inaccurate, history=history)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--set", action="append", default=[], help="a config override KEY=VALUE (repeatable)")
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    problem = se3ocp.load(a.config, a.set).problem
    res = solve(problem, progress=not a.quiet)
    print(f"SCvx: {'converged' if res.converged else 'NOT converged'} in {res.iterations} iterations "
          f"({res.accepted} accepted), wall {res.wall_s:.2f} s (Clarabel {res.solver_s:.2f} s, setup {res.setup_s:.2f} s); "
          f"cost {res.cost:.10g} (delta-v {res.cost / problem.model.mass:.6g}); largest defect {res.defect[0]:.2e} / "
          f"{res.defect[1]:.2e}; the controls flown from X0 miss by {res.miss[0]:.2e} / {res.miss[1]:.2e}")


if __name__ == "__main__":
    main()
