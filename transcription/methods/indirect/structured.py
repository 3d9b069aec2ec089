"""The fuel objective's conditions at eps = 0 with the switching structure fixed (docs/mathematics.md §19): every
control node of each block is on (u = b v / |v|), off (u = 0) or partial (u = m_j v / |v|, m_j an unknown with the
equation S_j = |v_j| - 1 = 0), taken from a solution (the direct one, or the last eps-stage); Newton-Armijo on
[lambda_0; m] with the residual [the terminal conditions (orbit: with transversality); S_j on the partial nodes], the
Jacobian by forward AD through the rollout (not compiled).  Afterwards the structure is checked: S > 0 where on,
S < 0 where off, 0 < m_j < b.  Inertial force, norm bounds (a bound of 0: the block off throughout)."""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...dynamics.lgvi import SCHEMES, two_point
from ...geometry.state import NU, NX, NZ, U_FORCE, U_MOMENT
from ..newton import NewtonResult, newton_armijo
from ...ocp import STATE_COMPONENTS, Problem, TargetOrbit
from .conditions import orthonormalized, terminal_residual_function
from .control import control_matrix, control_scale
from .elimination import solve_unpivoted
from .orbit import orbit_shooting_function

def node_modes(problem: Problem, U: np.ndarray, partial_rtol: float) -> np.ndarray:
    """(2, n_controls) modes of the control nodes of U per block (force, moment): 1 on (|u| = b), 0 off, -1 partial
    (within partial_rtol b of neither 0 nor b: the fuel law's); a removed block (b = 0) off."""
    c = problem.control
    modes = []
    for sl, bound in ((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound)):
        m, b = np.linalg.norm(U[sl], axis=0), bound.b
        modes.append(np.zeros(m.size) if b == 0 else np.where(m >= (1 - partial_rtol) * b, 1.0,
                                                                np.where(m <= partial_rtol * b, 0.0, -1.0)))
    return np.array(modes)


def _law(v, mode, b, m):
    """u of one block: b v/|v| (mode 1), 0 (mode 0), m v/|v| (mode -1); SX."""
    n = ca.sqrt(ca.fmax(ca.dot(v, v), 1e-300))
    return v * (ca.if_else(mode == 1, b, ca.if_else(mode == -1, m, 0.0)) / n)


def _step_function(problem: Problem) -> ca.Function:
    """(X, lam_prev, uk[6], mode[2], mag[2], h) -> (X1, lam, u1[6], v1[6]): one step of the forward map of
    :func:`~.conditions._forward_step` (inertial force) with the structured law for the control lambda_k determines."""
    disc, c = problem.disc, problem.control
    X, lp, uk = ca.SX.sym("X", NX), ca.SX.sym("lam_prev", NZ), ca.SX.sym("uk", NU)
    mode, mag, h = ca.SX.sym("mode", 2), ca.SX.sym("mag", 2), ca.SX.sym("h")
    Bc = control_matrix(disc)(h)
    Winv = np.linalg.inv(c.W)
    zero = ca.DM.zeros(NU)
    wA = zero if disc.scheme == "first_order" else ca.vertcat(uk, zero)
    cr, _ = disc.cayley_solve(disc.cayley_rhs(X, wA, h))
    A = disc.variation(orthonormalized(X), wA, h)[0]
    mu = solve_unpivoted(A.T, lp)
    v = -control_scale(disc) * ca.mtimes(Winv, ca.mtimes(Bc.T, mu)) / h
    u1 = ca.vertcat(*[_law(v[sl], mode[i], bound.b, mag[i]) for i, (sl, bound) in
                      enumerate(((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound)))])
    X1 = disc.step_given_c(X, cr, u1 if disc.scheme == "first_order" else ca.vertcat(uk, u1), h)[0]
    return ca.Function("structured_step", [X, lp, uk, mode, mag, h], [X1, mu, u1, v], ["X", "lam_prev", "uk", "mode",
                                                                                     "mag", "h"],
                       ["X1", "lam", "u1", "v1"])


class StructuredShooting:
    """The structured conditions of one problem for the node modes ``modes`` (2 x n_controls, :func:`node_modes`):
    ``fun`` (x) -> (F, J = dF/dx, U (controls), V (the unconstrained effort controls v), lam (12 x N: lambda_0 ..
    lambda_{N-1})) of x = [lambda_0 (the method's shooting unknown); m (the partial nodes' magnitudes)]."""

    def __init__(self, problem: Problem, modes: np.ndarray, h: float | None = None):
        if problem.scheme not in SCHEMES:
            raise ValueError(problem.scheme)
        self.problem, self.modes = problem, np.asarray(modes, float)
        # the step sizes h_k (docs/mathematics.md §19, on a non-uniform mesh): h_k = r_k h, h the mean step
        self.hk = np.broadcast_to(problem.steps_of(problem.h if h is None else h), (problem.N,))
        self.partial = np.argwhere(self.modes == -1)          # (block, node) pairs
        p, N, npart = problem, problem.N, len(self.partial)
        x = ca.MX.sym("x", NZ + npart)
        lam0 = x[:NZ]
        mags = [[ca.MX(0.0), ca.MX(0.0)] for _ in range(self.modes.shape[1])]
        for i, (blk, j) in enumerate(self.partial):
            mags[j][blk] = x[NZ + i]
        step = _step_function(p)
        X, lam, hk = ca.MX(p.X0), lam0, self.hk
        # the first control from the unknown itself (lgvi: u_0 from lambda_{-1}; first_order: u_1 from lambda_0),
        # at the size h_0 of step 0
        u, v = self._first(lam0, mags[0])
        Us, Vs = [u], [v]
        if two_point(p.scheme):
            u_prev, ks, shift = u, range(N), 1
        else:
            X, u_prev, ks, shift = p.disc.step(X, u, hk[0])[0], ca.MX.zeros(NU), range(1, N), 0
        lam_prev, lams = lam0, ([] if two_point(p.scheme) else [lam0])
        for k in ks:
            j = k + shift                   # the control index of the control lambda_k determines
            X, lam, u_prev, v = step(X, lam_prev, u_prev, self.modes[:, j], ca.vertcat(*mags[j]), hk[k])
            Us.append(u_prev), Vs.append(v), lams.append(lam)
            lam_prev = lam
        self.lamN, self.XN = lam_prev, X
        V = ca.horzcat(*Vs)
        S = ca.vertcat(*[ca.norm_2(V[U_FORCE if blk == 0 else U_MOMENT, j]) - 1.0 for blk, j in self.partial])
        term = self._terminal(X, lam_prev)
        F = ca.vertcat(term, S)
        self.fun = ca.Function("structured", [x], [F, ca.jacobian(F, x), ca.horzcat(*Us), V, ca.horzcat(*lams)],
                               ["x"], ["F", "J", "U", "V", "lam"])

    def _first(self, lam0, mag):
        """(u_0, v_0) of the first control node from the unknown (lgvi: u_0 = law(-(2/h_0) W^-1 B_c(h_0)^T
        lambda_{-1}); first_order: u_1 = law(-(1/h_0) W^-1 B_c(h_0)^T lambda_0)), h_0 the size of step 0."""
        p, h0 = self.problem, float(self.hk[0])
        Bc = control_matrix(p.disc)(h0)
        v = -control_scale(p.disc) * ca.mtimes(ca.DM(np.linalg.inv(p.control.W)), ca.mtimes(Bc.T, lam0)) / h0
        c = p.control
        u = ca.vertcat(*[_law(v[sl], self.modes[i, 0], bound.b, mag[i]) for i, (sl, bound) in
                         enumerate(((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound)))])
        return u, v

    def _terminal(self, XN, lamN):
        """The terminal rows: an orbit target's [g; K^T lambda_{N-1}] (:mod:`.orbit`), else a state target's z_N with
        lambda_{N-1} on its free components."""
        p = self.problem
        if isinstance(p.terminal, TargetOrbit):
            return orbit_shooting_function(p.terminal, p.model.mass, p.model.mu)(XN, lamN)[0]
        z = terminal_residual_function()(XN, p.terminal.X)
        free = np.repeat([c in p.terminal.free for c in STATE_COMPONENTS], 3)   # lambda_{N-1} = 0 there (§10 b)
        return ca.vertcat(*[lamN[i] if free[i] else z[i] for i in range(NZ)])

    def check(self, x) -> str:
        """'' when the solution x is consistent with its structure (S > 0 on, S < 0 off, 0 < m < b), else why not."""
        V = self.fun(x)[3]
        S = np.array([np.linalg.norm(np.array(V)[sl], axis=0) - 1.0 for sl in (U_FORCE, U_MOMENT)])
        bad = [f"{name} on at S = {S[i][self.modes[i] == 1].min():.1e}" for i, name in enumerate(("force", "moment"))
               if np.any(S[i][self.modes[i] == 1] < 0)]
        bad += [f"{name} off at S = {S[i][self.modes[i] == 0].max():.1e}" for i, name in enumerate(("force", "moment"))
                if np.any(S[i][self.modes[i] == 0] > 0) and self._bound(i) > 0]
        m = np.asarray(x[NZ:])
        b = np.array([self._bound(blk) for blk, _ in self.partial])
        if np.any(m <= 0) or np.any(m >= b):
            bad.append("a partial node's magnitude outside (0, b)")
        return "; ".join(bad)

    def repaired(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(modes, U) for another try after an inconsistent solution x: on nodes with S < 0 and off nodes with S > 0
        become partial, partial nodes with m <= 0 off and with m >= b on (an active-set step); U the rollout's."""
        _, _, U, V, _ = self.fun(x)
        U, V, modes = np.array(U), np.array(V), self.modes.copy()
        for i, sl in enumerate((U_FORCE, U_MOMENT)):
            if self._bound(i) == 0:
                continue
            S = np.linalg.norm(V[sl], axis=0) - 1.0
            modes[i][((modes[i] == 1) & (S < 0)) | ((modes[i] == 0) & (S > 0))] = -1
        for (blk, j), m in zip(self.partial, np.asarray(x[NZ:])):
            b = self._bound(blk)
            modes[blk, j] = 0 if m <= 0 else 1 if m >= b else -1
            sl = U_FORCE if blk == 0 else U_MOMENT
            U[sl, j] *= (0.0 if m <= 0 else b / m if m >= b else 1.0)
        return modes, U

    def _bound(self, blk: int) -> float:
        c = self.problem.control
        return (c.force_bound if blk == 0 else c.moment_bound).b

    def solve(self, lam0, U, tol: float, max_iter: int) -> NewtonResult:
        """Newton-Armijo from lambda_0 and the magnitudes of the partial nodes of U (max_iter: the fuel law's)."""
        m0 = np.array([np.linalg.norm(U[U_FORCE if blk == 0 else U_MOMENT, j]) for blk, j in self.partial])
        x0 = np.r_[np.asarray(lam0, float), m0]

        def residual(x):
            return np.array(self.fun(x)[0]).ravel(), 0.0

        def jacobian(x):
            return np.array(self.fun(x)[1])

        return newton_armijo(x0, residual, jacobian, tol=tol, max_iter=max_iter, floor_factor=10.0, floor_accept=1e-8)
