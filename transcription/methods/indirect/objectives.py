"""The indirect method for objectives linear in the control: the switching function, and the time objective's solve
-- a homotopy min T + eps (effort) with the saturated law, jointly with the free-final-time condition, eps -> 0
(docs/mathematics.md §18).

The switching function of control node j (per unit quadrature weight omega_j) is

    sigma_j = (s/h) B_c^T lambda_{j-1}        (6; s, B_c of :func:`~.control.control_law`),

the coefficient of u_j in the Lagrangian: the effort objective's stationarity reads W u_j + sigma_j = 0, and a cost
linear in u_j (time: none; fuel: w |u_j|) has u_j minimizing w |u_j| + sigma_j^T u_j over the bounds (bang-bang,
bang-off-bang): the limits of control.saturate (the eps-law below as e -> 0, switching.on_off as eps -> 0).  For the
time objective the shooting solves the eps-problem

    min  N h + eps * sum_j omega_j u_j^T W u_j / u_max^2        (u_max^2 = :func:`saturated_effort_rate`),

whose law is the saturated effort law with Winv / e, e = 2 eps / u_max^2, and whose free final time is
dL/dh = N + e J_effort / h + sum_k g_k = 0 (on a non-uniform mesh sum_k r_k g_k, h the mean step: §18).
"""
from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from ...geometry.state import NU, NX, NZ, U_FORCE, U_MOMENT, split_state
from ...dynamics.lgvi import Discretization, per_discretization, two_point
from ..newton import NewtonResult, newton_armijo
from ...outcome import Result
from ...ocp import Problem, quadrature_weights
from .control import NB, NO_NORM, control_matrix, control_scale
from .conditions import costate_functions, node_law, terminal_residual_function
from .shooting import MAPACCUM_OPTS, time_gradient_function

def switching_function(problem: Problem, lams: np.ndarray, h: float) -> np.ndarray:
    """sigma (6 x n_controls): sigma_j = (s/h_j) B_c(h_j)^T lambda_{j-1} for every control node j, from ``lams`` (12 x
    n_controls) the costates the controls are read from, in order (first_order: lambda_0..lambda_{N-1} for u_1..u_N;
    lgvi: the shooting unknown lambda_{-1}, then lambda_0..lambda_{N-1} for u_0..u_N), h the (mean) step size and h_j
    the size of the step whose law gives u_j (:func:`node_steps`: h on a uniform mesh).  Inertial force only (a
    body-fixed force reads R_j^T lambda_gamma, docs/mathematics.md §15)."""
    if problem.disc.force_frame != "inertial":
        raise ValueError("switching_function: a body-fixed force is not covered")
    lams, hn = np.asarray(lams, dtype=float), node_steps(problem, h)
    if np.ndim(hn) == 0:
        Bc = np.array(control_matrix(problem.disc)(h))
        return control_scale(problem.disc) / h * (Bc.T @ lams)
    return np.column_stack([node_matrix(problem.disc, hj).T @ lams[:, j] for j, hj in enumerate(hn)])


def node_steps(problem: Problem, h: float) -> float | np.ndarray:
    """The step size at which each control node's law is taken, for the (mean) step size h: h on a uniform mesh; on
    a non-uniform one (n_controls,) as the shooting takes them (docs/mathematics.md §17): first_order u_{k+1} at
    h_k; lgvi u_0 at h_0 and u_{k+1} at h_k."""
    hk = problem.steps_of(h)
    if np.ndim(hk) == 0:
        return hk
    return hk if problem.scheme == "first_order" else np.r_[hk[0], hk]


def node_matrix(disc: Discretization, h: float) -> np.ndarray:
    """(s/h) B_c(h) (12 x 6): sigma_j = this^T lambda (:func:`switching_function`) for a node whose step has size h."""
    return np.array(control_matrix(disc)(h)) * control_scale(disc) / h


def saturated_effort_rate(problem: Problem) -> float:
    """u_max^2 = the largest u^T W u the bounds allow (box with diagonal W: sum W_ii b_i^2; norm b: W_11 b^2;
    an engine: a^T W_f a T_max^2): the eps-term of the time homotopy is eps T at full saturation."""
    c = problem.control
    return sum(b.effort_rate(W) for W, b in ((c.W_f, c.force_bound), (c.W_m, c.moment_bound)) if b is not None)


def lean_rollout(disc: Discretization, N: int, lam0, X0, h, Winv, bd) -> tuple:
    """(X (18 x N) nodes 1..N, lams (12 x N) lambda_0..lambda_{N-1}, U) of the shooting's rollout (h: the step sizes,
    1 x N) as MX expressions, by per-step Functions without the Cayley residual (a norm, infinite derivative at 0),
    so that reverse-mode AD through the rollout stays finite."""
    cm, fs = costate_functions(disc)
    X, lp, hs, Ws, bs = (ca.SX.sym(n, *sp) for n, sp in (("X", (NX, 1)), ("lam_prev", (NZ, 1)), ("h", (1, 1)),
                                                         ("Winv", (NU, NU)), ("bd", (NB, 1))))
    lean = ca.Function(f"{disc.scheme}_costate_map_lean", [X, lp, hs, Ws, bs], cm(X, lp, hs, Ws, bs)[:3])
    h0 = h[0, 0]                       # step 0's size (the first control's law)
    if disc.scheme == "first_order":
        X1, u1 = fs(X0, lam0, h0, Winv, bd)[:2]
        Xs, lams, Us, n, Xstart = [X1], [lam0], [u1], N - 1, X1
    else:
        Xs, lams, Us, n, Xstart = [], [], [node_law(disc, h0, Winv, bd)(lam0, split_state(X0)[2])[0]], N, X0
    if n > 0:
        steps = lean.mapaccum(f"{disc.scheme}_costate_lean_acc{n}", n, 2, MAPACCUM_OPTS)(
            Xstart, lam0, h[0, N - n:], ca.repmat(Winv, 1, n), ca.repmat(bd, 1, n))
        for acc, out in zip((Xs, lams, Us), steps):
            acc.append(out)
    return tuple(ca.horzcat(*a) for a in (Xs, lams, Us))


@per_discretization
def time_condition_function(disc: Discretization, N: int) -> ca.Function:
    """``{scheme}_time_condition{N}`` (lam0[12], X0, Xd, h, Winv[6x6], bd[NB], e, W[6x6], q[1 x n_controls],
    r[1 x N]) -> (g, dg_dlam0[1x12], dg_dh, dzN_dh[12], dlamN_dh[12]): the free-final-time condition of the
    eps-problem in the mean step h, step k of size h_k = r_k h (r = 1: a uniform mesh; docs/mathematics.md §17),

        g = dL/dh = N + e sum_j q_j (1/2) u_j^T W u_j + sum_k r_k lambda_k^T readback(d step_k / dh_k)

    (q the quadrature weights per unit h; Winv the scaled law's W^-1 / e) and the derivatives the joint Newton
    iteration on (lambda_0, h) needs beside Psi, by AD (one reverse sweep for dg/dlambda_0, one forward for
    d/dh) through the rollout (:func:`lean_rollout`; not compiled)."""
    lam0, X0, Xd = ca.MX.sym("lam0", NZ), ca.MX.sym("X0", NX), ca.MX.sym("Xd", NX)
    h, e, Winv = ca.MX.sym("h"), ca.MX.sym("e"), ca.MX.sym("Winv", NU, NU)
    bd, W, q = ca.MX.sym("bd", NB), ca.MX.sym("W", NU, NU), ca.MX.sym("q", 1, disc.n_controls(N))
    r = ca.MX.sym("r", 1, N)
    hk = h * r
    Xs, lams, U = lean_rollout(disc, N, lam0, X0, hk, Winv, bd)
    zN = terminal_residual_function()(Xs[:, -1], Xd)
    Xk = ca.horzcat(X0, Xs[:, :-1])
    steps = time_gradient_function(disc, N)(Xk, disc.stage_controls(U), lams, hk)
    g = N + e * 0.5 * ca.sum2(q * ca.sum1(U * ca.mtimes(W, U))) + ca.sum2(r * steps)
    lamN = lams[:, -1]
    return ca.Function(f"{disc.scheme}_time_condition{N}", [lam0, X0, Xd, h, Winv, bd, e, W, q, r],
                       [g, ca.gradient(g, lam0).T, ca.jacobian(g, h), ca.jacobian(zN, h), ca.jacobian(lamN, h)],
                       ["lam0", "X0", "Xd", "h", "Winv", "bd", "e", "W", "q", "r"],
                       ["g", "dg_dlam0", "dg_dh", "dzN_dh", "dlamN_dh"])


def differentiable_bounds(problem: Problem, bd: np.ndarray) -> np.ndarray:
    """The bound data ``bd`` with each block's absent norm bound (NO_NORM) replaced by a finite one no control
    within its other bound reaches ((10 max(|b|, 1))^2): the same controls bit for bit (the norm factor is exactly 1),
    but derivatives of the rollout by AD stay finite (with NO_NORM they are 0 x inf = nan)."""
    out = np.array(bd, dtype=float)
    for i, bound in enumerate((problem.control.force_bound, problem.control.moment_bound)):
        if out[NU + i] >= NO_NORM:
            out[NU + i] = (10.0 * max(bound.largest_norm() if bound is not None else 1.0, 1.0)) ** 2
    return out


def residual_rows(problem: Problem, free: np.ndarray) -> np.ndarray:
    """Boolean (12): the rows of z_N replaced by lambda_{N-1} -- the free terminal components and, with the force
    removed, position and linear momentum: no control moves them, so they hold or fail whatever lambda_0 is
    (:func:`solve_time` checks) and their multipliers are arbitrary (taken 0)."""
    rows = np.array(free, dtype=bool)
    if problem.control.removed[0]:
        rows[:6] = True
    return rows


class TimeShooting:
    """The time objective's shooting at a given eps: Newton-Armijo on x = [lambda_0; h / h0] (13), residual
    F = [z_N (lambda_{N-1} on :func:`residual_rows`); g / N], g = dL/dh of the eps-problem
    (:func:`time_condition_function`), Jacobian [[Psi, dz_N/dh h0], [dg/dlambda_0 / N, dg/dh h0 / N]] (Psi from
    the compiled shooting, the rest by AD).  ``shooting``: the method's :class:`~.solve._Shooting`."""

    def __init__(self, shooting, h0: float):
        p = shooting.problem
        self.sh, self.p, self.h0 = shooting, p, float(h0)
        self.rows = residual_rows(p, shooting.free)
        self.W, self.umax2 = p.control.W, saturated_effort_rate(p)
        self.q = quadrature_weights(p.scheme, p.N, p.steps_of(1.0))      # per unit (mean) h
        self.r = np.ones(p.N) if p.mesh is None else p.mesh              # h_k = r_k h (docs/mathematics.md §17)
        self.cond = time_condition_function(p.disc, p.N)
        self.tg = time_gradient_function(p.disc, p.N)
        self.bd = differentiable_bounds(p, shooting.bd)
        self.last = None

    def law(self, eps: float) -> tuple[float, np.ndarray]:
        """(e, Winv / e): the eps-problem's effort weight and the inverse weight of its saturated law."""
        e = 2.0 * eps / self.umax2
        return e, self.sh.Winv / e

    def rollout(self, x: np.ndarray, eps: float) -> tuple:
        """(X (18 x N) nodes 1..N, lams (12 x N) lambda_0..lambda_{N-1}, U, h) of x at eps."""
        sh, h = self.sh, float(x[NZ] * self.h0)
        _, Xs, lams, U, _, _ = (np.array(a) for a in sh.fns.shoot(x[:NZ], sh.X0, sh.Xd, self.p.steps_of(h),
                                                                   self.law(eps)[1], self.bd))
        return Xs, lams, U, h

    def g(self, x: np.ndarray, eps: float) -> float:
        """dL/dh of the eps-problem at x (module docstring; on a mesh the steps' terms weighted by r_k, §17)."""
        Xs, lams, U, h = self.rollout(x, eps)
        Xk = np.column_stack([self.sh.X0, Xs[:, :-1]])
        steps = np.array(self.tg(Xk, self.p.disc.stage_controls(U), lams, self.p.steps_of(h)))
        e = self.law(eps)[0]
        steps = steps if self.p.mesh is None else self.r * steps.ravel()
        return self.p.N + e * 0.5 * float(np.einsum("k,ik,ij,jk->", self.q, U, self.W, U)) + float(np.sum(steps))

    def residual(self, x: np.ndarray, eps: float) -> tuple[np.ndarray, float]:
        """(F (13), the largest Cayley residual of the rollout)."""
        sh, h = self.sh, float(x[NZ] * self.h0)
        if not h > 0:
            return np.full(NZ + 1, np.nan), np.inf
        z, lamN, r = sh.fns.residual(x[:NZ], sh.X0, sh.Xd, self.p.steps_of(h), self.law(eps)[1], self.bd)
        F = np.where(self.rows, np.array(lamN).ravel(), np.array(z).ravel())
        return np.r_[F, self.g(x, eps) / self.p.N], float(r)

    def jacobian(self, x: np.ndarray, eps: float) -> np.ndarray:
        """dF/dx (13 x 13); the last one is kept (the predictor needs the Jacobian Newton ended with)."""
        if self.last is not None and self.last[1] == eps and np.array_equal(self.last[0], x):
            return self.last[2]
        sh, rows, N, h0 = self.sh, self.rows, self.p.N, self.h0
        lam, h, (e, Winv) = x[:NZ], float(x[NZ] * h0), self.law(eps)
        _, Psi, dlamN = sh.fns.shoot_jac(lam, sh.X0, sh.Xd, self.p.steps_of(h), Winv, self.bd)
        _, dg_dlam, dg_dh, dz_dh, dlamN_dh = (np.array(a) for a in self.cond(lam, sh.X0, sh.Xd, h, Winv, self.bd,
                                                                               e, self.W, self.q, self.r))
        top = np.column_stack([np.where(rows[:, None], np.array(dlamN), np.array(Psi)),
                               h0 * np.where(rows, dlamN_dh.ravel(), dz_dh.ravel())])
        J = np.vstack([top, np.r_[dg_dlam.ravel(), h0 * dg_dh.item()][None, :] / N])
        self.last = (x.copy(), eps, J)
        return J

    def predictor(self, x: np.ndarray, eps: float, eps1: float) -> np.ndarray:
        """x + dx/deps (eps1 - eps) at a solution x of eps: the tangent of the path, dx/deps = -J^-1 dF/deps
        (dF/deps by a difference quotient; the switching nodes' sigma = O(e), so the tangent carries them)."""
        d = 1e-6 * eps
        dF = (self.residual(x, eps + d)[0] - self.residual(x, eps)[0]) / d
        try:
            dx = -np.linalg.solve(self.jacobian(x, eps), dF)
        except np.linalg.LinAlgError:
            return x
        return x + dx * (eps1 - eps) if np.all(np.isfinite(dx)) else x

    def newton(self, x0: np.ndarray, eps: float, phase: str, max_iter: int) -> NewtonResult:
        opts, progress = self.sh.options, self.sh.progress
        tagged = (lambda it: progress(dataclasses.replace(it, phase=phase))) if progress else None
        nr = newton_armijo(x0, lambda x: self.residual(x, eps), lambda x: self.jacobian(x, eps), tol=opts.eps_S,
                           alpha=opts.alpha, max_iter=max_iter, max_halvings=opts.max_halvings,
                           aux_tol=opts.cayley_tol, floor_factor=opts.floor_factor, floor_accept=opts.floor_accept,
                           progress=tagged)
        nr.history = [dataclasses.replace(it, phase=phase) for it in nr.history]
        return nr


def costate_transfer(problem: Problem, X: np.ndarray, U: np.ndarray, h: float) -> list[np.ndarray]:
    """[M_0, ..., M_{N-1}] (12 x 12 each): lambda_k = M_k y along a solution's fixed trajectory (X (N+1, 18), U), y
    the shooting unknown (first_order lambda_0; lgvi lambda_{-1}), by lambda_k = A_k^-T lambda_{k-1} with A_k as the
    shooting takes it (first_order at (X_k, 0), lgvi at (X_k, [u_k; 0]), step size h_k, docs/mathematics.md §17)."""
    disc, N, Ms = problem.disc, problem.N, []
    hk = np.broadcast_to(problem.steps_of(h), (N,))
    M = np.eye(NZ)
    for k in range(N):
        if disc.scheme == "first_order" and k == 0:
            Ms.append(M)
            continue
        wA = np.zeros(NU) if disc.scheme == "first_order" else np.r_[U[:, k], np.zeros(NU)]
        A = np.array(disc.variation(X[k], wA, hk[k])[0])
        M = np.linalg.solve(A.T, M)
        Ms.append(M)
    return Ms


def structure_start(ts: TimeShooting, X: np.ndarray, U: np.ndarray, h: float) -> tuple[np.ndarray, float] | None:
    """(x = [y; 1], eps): a start on the eps-problem's path from a solution's primal (the direct solution: X (N+1,
    18), U, h = T/N) for an eps small enough that its bang nodes stay saturated, or None.  With the primal fixed
    the conditions are linear in y (:func:`costate_transfer`, sigma_j = S_j y): at each node where the control is
    inside its bound sigma_j = -e W u_j (the eps-law's interior; e = 2 eps / u_max^2), the free-final-time
    condition g = N + e J_effort / h + sum_k t_k^T lambda_k = 0 (t_k = readback(d step_k / dh); on a mesh
    r_k readback(d step_k / dh_k), docs/mathematics.md §17), lambda_{N-1} = 0
    on :func:`residual_rows`; solved (least squares) as y = y0 + e y1.  e = a quarter of the largest e at which
    every bang node keeps |sigma_i| >= e W_ii b_i (box) or |sigma| >= e w b (norm)."""
    p, disc, N, c = ts.p, ts.p.disc, ts.p.N, ts.p.control
    Ms = costate_transfer(p, X, U, h)
    Ls = ([np.eye(NZ)] if two_point(disc.scheme) else []) + Ms           # the costate each control is read from
    hn = np.broadcast_to(node_steps(p, h), (len(Ls),))                  # each node's step size (h: uniform)
    S = [node_matrix(disc, hj).T @ L for hj, L in zip(hn, Ls)]          # sigma_j = S_j y
    rows, rhs0, rhs1, bang, bang_u = [], [], [], [], []
    for sl, bound in ((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound)):
        W = c.W[sl, sl]
        for j, Sj in enumerate(S):
            u = U[sl, j]
            box = None if bound is None else bound.variable_box()
            if bound is not None and bound.removed:
                continue
            if box is not None:             # a symmetric box on the axes
                b = box[1]
                inside = np.abs(u) < b * (1.0 - 1e-6)
                for i in np.flatnonzero(inside & (b > 0)):
                    rows.append(Sj[sl][i]); rhs0.append(0.0); rhs1.append(-W[i, i] * u[i])
                bang += [(Sj[sl][i], W[i, i] * b[i]) for i in np.flatnonzero(~inside)]
                bang_u += [u[i] for i in np.flatnonzero(~inside)]
            elif bound is not None and np.isfinite(bound.radius):
                if np.linalg.norm(u) < bound.radius * (1.0 - 1e-6):
                    rows += list(Sj[sl]); rhs0 += [0.0] * 3; rhs1 += list(-W @ u)
                else:
                    bang.append((Sj[sl], W[0, 0] * bound.radius))
                    bang_u.append(u)
            else:
                return None
    Xk, Wst = X[:-1].T, disc.stage_controls(U)
    t = np.vstack([np.array(ts.tg(Xk, Wst, np.repeat(np.eye(NZ)[:, [i]], N, axis=1), p.steps_of(h)))
                   for i in range(NZ)])
    if p.mesh is not None:                                              # dL/dh = ... + sum_k r_k g_k (§17)
        t = t * p.mesh[None, :]
    effort = 0.5 * float(np.einsum("k,ik,ij,jk->", ts.q, U, ts.W, U))
    rows.append(sum(t[:, k] @ Ms[k] for k in range(N))); rhs0.append(-float(N)); rhs1.append(-effort)
    for r in np.flatnonzero(ts.rows):
        rows.append(Ms[-1][r]); rhs0.append(0.0); rhs1.append(0.0)
    A = np.array(rows)
    y0, y1 = (np.linalg.lstsq(A, np.array(b), rcond=None)[0] for b in (rhs0, rhs1))
    limits = [np.linalg.norm(Sb @ y0) / (wb + np.linalg.norm(Sb @ y1)) for Sb, wb in bang]
    signs = all(np.all(np.sign(Sb @ y0) == -np.sign(U_b)) for (Sb, _), U_b in zip(bang, bang_u))
    if not limits or not signs or not np.all(np.isfinite(y0)) or min(limits) <= 0:
        return None
    e = 0.25 * min(limits)
    return np.r_[y0 + e * y1, 1.0], e * ts.umax2 / 2.0


def solve_time(shooting, lam, h: float, law, primal: tuple | None = None) -> tuple[NewtonResult, float, dict, tuple]:
    """The time objective from (lambda_0, h) (:func:`~.solve.initial_costate`) and, when given, the direct solution's
    ``primal`` (X (N+1, 18), U), by ``law`` (a :class:`~.laws.TimeLaw`): the first stage from :func:`structure_start`,
    else (or when it fails) from (lambda_0, h) at law.eps_start, raised by law.start_raise on failure; then stages at
    eps times law.eps_factor (its square root after a failure), each from the previous solution moved along the
    path's tangent (:meth:`TimeShooting.predictor`), until two stages give the same T to law.t_rtol (T and the
    controls are then eps = 0's, docs/mathematics.md §18) or eps reaches law.eps_end.  Returns (the last good stage's
    NewtonResult, x its lambda_0, with every stage's history and iterations; h; a summary for the stats; the final
    eps-law's (Winv, bd)).  Terminal conditions no control moves (:func:`residual_rows`) that fail make it
    ``infeasible``."""
    ts, N = TimeShooting(shooting, h), shooting.problem.N
    x0 = np.r_[np.asarray(lam, dtype=float), 1.0]
    starts = [structure_start(ts, *primal, h)] if primal is not None else []
    starts = [s for s in starts if s is not None] + [(x0, law.eps_start * law.start_raise ** i)
                                                     for i in range(law.start_tries + 1)]
    history, iters, stages, good, settled, factor = [], 0, [], None, False, law.eps_factor

    def stage(x, eps, max_iter):
        nonlocal iters
        nr = ts.newton(x, eps, f"eps = {eps:.1e}: ", max_iter)
        history.extend(nr.history)
        iters += nr.iterations
        T = float(nr.x[NZ] * ts.h0 * N)
        stages.append({"eps": float(eps), "result": nr.result.value, "iterations": nr.iterations, "T": T})
        return nr, T

    for j, (x, eps) in enumerate(starts):
        nr, T = stage(x, eps, shooting.options.max_iter if j == 0 else law.stage_iterations)
        if nr.result.successful:
            good = (nr, eps, T)
            break
    while good is not None and good[1] > law.eps_end * (1 + 1e-9) and len(stages) < law.max_stages:
        eps1 = max(good[1] * factor, law.eps_end)
        nr, T = stage(ts.predictor(good[0].x, good[1], eps1), eps1, law.stage_iterations)
        if nr.result.successful:
            settled = abs(T - good[2]) <= law.t_rtol * T
            good = (nr, eps1, T)
            if settled:
                break
        elif factor >= law.eps_factor_max:
            break
        else:
            factor = np.sqrt(factor)
    out = nr if good is None else good[0]
    if good is not None and not settled:       # T is eps = 0's only once it has settled
        why = f"the next stage failed: {nr.message}" if not nr.result.successful else f"{len(stages)} stages"
        out.result = nr.result if not nr.result.successful else Result.max_iterations
        out.message = f"the homotopy in eps stopped at eps = {good[1]:.1e}, T = {good[2]:.12g} before T settled ({why})"
    out.history, out.iterations = history, iters
    final = good[1] if good is not None else stages[-1]["eps"]
    summary = {"eps": float(final), "e": ts.law(final)[0], "stages": stages, "settled": settled,
               "structure_start": primal is not None and len(starts) > law.start_tries + 1,
               "message": _homotopy_message(stages, settled)}
    if out.result.successful:
        _check_uncontrolled(ts, out, final)
    h = float(out.x[NZ] * ts.h0)
    out.x = out.x[:NZ]
    return out, h, summary, (ts.law(final)[1], ts.bd)


def _homotopy_message(stages: list[dict], settled: bool) -> str:
    """One line on the homotopy: its eps path, the final T and how it ended."""
    ok = [s for s in stages if s["result"] in ("converged", "round_off_floor")]
    if not ok:
        return f"time objective: the first stage of the homotopy (eps = {stages[0]['eps']:.1e}) failed"
    last = ok[-1]
    how = (f"T settled: the last two stages agree to {abs(last['T'] - ok[-2]['T']) / last['T']:.1e}" if settled
           else "T had not settled")
    return (f"time objective: homotopy min T + eps (effort) from eps = {stages[0]['eps']:.1e} to {last['eps']:.1e} in "
            f"{len(stages)} stages ({len(stages) - len(ok)} retried), T = {last['T']:.12g}; {how}")


def _check_uncontrolled(ts: TimeShooting, nr: NewtonResult, eps: float) -> None:
    """The terminal conditions no control moves (rows of :func:`residual_rows` that are not free components) must
    hold by themselves: else ``nr`` becomes ``infeasible`` (no lambda_0 can meet them)."""
    rows = ts.rows & ~np.asarray(ts.sh.free, dtype=bool)
    if not rows.any():
        return
    sh, h = ts.sh, float(nr.x[NZ] * ts.h0)
    z = np.array(sh.fns.residual(nr.x[:NZ], sh.X0, sh.Xd, ts.p.steps_of(h), ts.law(eps)[1], ts.bd)[0]).ravel()[rows]
    scale = max(1.0, float(np.abs(sh.Xd).max()))
    if np.abs(z).max() > 1e-9 * scale:
        nr.result = Result.infeasible
        nr.message = (f"the terminal position and linear momentum miss by {np.abs(z).max():.1e} and no control moves "
                      "them (the force is removed)")
