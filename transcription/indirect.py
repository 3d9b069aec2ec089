"""Indirect method: discrete necessary conditions and Newton-Armijo shooting (docs/mathematics.md §6).

Scheme: the first-order modified scheme of docs/mathematics.md §3, eqs. (21)-(25), one control
per step, ``X_{k+1} = step(X_k, u_{k+1}, h)``, k = 0 .. N-1 (the second-order LGVI
is also supported, see the end of this docstring).  States X (18) in the
layout of :mod:`transcription.layout`; controls u = [u_f (inertial); u_m (body)];
tangent coordinates z = [dx; dgamma; zeta; dPi] with dR = R S(zeta) (docs/mathematics.md §4).

Lagrangian and sign convention
------------------------------
With z-coordinates for the step defect (the difference ``step(X_k, u_{k+1}) ⊖
X_{k+1}`` read in the left-trivialized chart of docs/mathematics.md §4 around X_{k+1}),

    L = sum_{k=0}^{N-1} [ (h/2) u_{k+1}^T W u_{k+1}
                          + lambda_k^T ( step(X_k, u_{k+1}) ⊖ X_{k+1} ) ],
    W = blkdiag(W_f, W_m),

lambda_k in R^12 the multiplier of step k (X_k -> X_{k+1}).  First variation with
z_{k+1} = A_k z_k + B_k du_{k+1} (eq. 18, A_k, B_k from
``Discretization.variation``):

    dL = sum_k [ h u_{k+1}^T W du_{k+1} + lambda_k^T (A_k z_k + B_k du_{k+1} - z_{k+1}) ].

* stationarity in u_{k+1}:  h W u_{k+1} + B_k^T lambda_k = 0, and since the
  first-order scheme has B_k = [0; h I; 0; 0 | 0; 0; 0; h I] (control enters
  additively, eqs. 22, 25) this is (26)-(27):
  u_f,k+1 = -W_f^-1 lambda^2_k,  u_m,k+1 = -W_m^-1 lambda^4_k.
  The code uses the general form u = -(1/h) W^-1 B_k^T lambda_k with B_k taken
  from the graph (tested equal to the block form).
* stationarity in z_k, k = 1 .. N-1:  A_k^T lambda_k - lambda_{k-1} = 0, i.e. (28)
  lambda_{k-1} = A_k^T lambda_k.
* z_0 is fixed (initial state); z_N is fixed (all terminal states given), so
  lambda_{N-1} is free: it is the multiplier of the terminal conditions.

A_k does not depend on u_{k+1} in this scheme (checked symbolically when the
functions are built), so the recursion runs forward:

    (X_k, lambda_{k-1}) -> lambda_k = A_k^-T lambda_{k-1},
                           u_{k+1} = -(1/h) W^-1 B_k^T lambda_k,
                           X_{k+1} = step(X_k, u_{k+1}, h).

The only unknown is lambda_0 in R^12; the shooting residual (12 conditions) is

    z_N(lambda_0) = [x_N - x_d; gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d],

and Psi_12 = dz_N/dlambda_0 (the linearized coupled state-multiplier recursion,
(29)-(31)) is computed by exact forward-mode AD through the rollout.

Functions built once per (Discretization, N) (see :func:`shooting_functions`):

    costate_map  (X[18], lam_prev[12], h, Winv[6x6]) -> (X1[18], lam[12], u[6], res, lam_res)
    first_step   (X0[18], lam0[12], h, Winv[6x6])    -> (X1[18], u[6], res)
    shoot        (lam0, X0, Xd, h, Winv) -> (zN[12], X[18xN], lam[12xN], U[6xN], res, lam_res)
    residual     (lam0, X0, Xd, h, Winv) -> (zN[12], res_max)
    shoot_jac    (lam0, X0, Xd, h, Winv) -> (zN[12], Psi[12x12])

Winv = blkdiag(W_f, W_m)^-1; X0, Xd, h, Winv are inputs, so one build serves
every problem with the same scheme, model and N.

Newton-Armijo (transcription.newton, shared with the impulsive TPBVP) runs in :func:`solve_indirect`.

Second-order LGVI (beyond the paper)
------------------------------------
For the scheme of docs/mathematics.md §2 (node controls u_0..u_N, trapezoidal cost weights) the
same Lagrangian gives explicit conditions too, because u_k enters step k as a
momentum kick: u_j = -W^-1 [lambda^2_{j-1}; lambda^4_{j-1}] for j = 0..N with
lambda_{-1} = A_0^T lambda_0, and lambda_k = A_k(X_k, u_k)^-T lambda_{k-1}.  The
shooting unknown is then lambda_{-1}; see :data:`LGVI_CONDITIONS`.

Round-off
---------
Forward costate shooting amplifies rounding: on E3/E4 the rod-axis rotation (tiny
J_11) turns ulp-level errors of the recursion into ~1e-13..1e-12 of z_N.  Two
measures keep the floor there: A_k^-T by Gaussian elimination
(:func:`solve_unpivoted`; CasADi's symbolic QR gave a floor ~1e-10 at N = 100) and
R re-orthonormalized in the argument of A_k (:func:`orthonormalized`; without it
the floor was ~1e-11 at N = 500, with it ~6e-13).  The floor is *measured*
(:func:`noise_level`), and the iteration stops there at once.
"""
from __future__ import annotations

import time
from functools import lru_cache
from typing import Callable

import casadi as ca
import numpy as np

from . import codegen
from .layout import NU, NX, NZ, join_state, split_state
from .lgvi import Discretization
from .newton import newton_armijo
from .options import DirectOptions, IndirectOptions
from .problem import Problem, TargetState, effort_cost, quadrature_weights, state_residual, terminal_error
from .results import Iterate, Result, Solution, Trajectory


def terminal_residual_function() -> ca.Function:
    """(XN[18], Xd[18]) -> zN[12]: :func:`~transcription.problem.state_residual` with every component
    (positions and linear momenta inertial, Pi body; the attitude error the rotation vector of
    R_d^T R_N, body frame at the target, three conditions)."""
    XN = ca.SX.sym("XN", NX)
    Xd = ca.SX.sym("Xd", NX)
    return ca.Function("terminal_residual", [XN, Xd], [state_residual(XN, Xd)], ["XN", "Xd"], ["zN"])


def solve_unpivoted(M, b):
    """Solve M y = b (SX, n x n dense) by Gaussian elimination without pivoting.

    Used for lambda_k = A_k^-T lambda_{k-1}.  A_k is close to a block-triangular
    matrix with identity diagonal blocks (x, gamma, Pi) and the rotation block F_k^T
    (zeta), so the pivots stay away from 0 while the rotation per step is well below
    a right angle, and elimination without pivoting is accurate: on E3 its error is
    ~1 ulp per component (against an exact rational solve), as good as LAPACK LU,
    whereas CasADi's symbolic QR (``ca.solve`` on SX) erred by ~1e-11 on |lambda| ~ 1e2
    and raised the round-off floor of z_N to ~1e-10 (E3, N = 100).  The caller
    reports the relative residual |M y - b|_inf / |b|_inf (lam_res) so a breakdown
    would be visible.
    """
    n = M.shape[0]
    a = [[M[i, j] for j in range(n)] for i in range(n)]
    r = [b[i] for i in range(n)]
    for c in range(n):
        for i in range(c + 1, n):
            f = a[i][c] / a[c][c]
            for j in range(c + 1, n):
                a[i][j] = a[i][j] - f * a[c][j]
            r[i] = r[i] - f * r[c]
    y = [None] * n
    for i in reversed(range(n)):
        acc = r[i]
        for j in range(i + 1, n):
            acc = acc - a[i][j] * y[j]
        y[i] = acc / a[i][i]
    return ca.vertcat(*y)


def orthonormalized(X):
    """X with R replaced by R (3 I - R^T R) / 2 (one Newton-Schulz step towards the polar factor).

    Identity on SO(3) (and its derivative is the identity on tangent vectors R S(zeta)),
    so it changes nothing in exact arithmetic; off the manifold by E = R^T R - I it
    leaves O(E^2).  Used only for the argument of A_k: the readback vee(skew(Rbar^T dR))
    of docs/mathematics.md §4 is sensitive to R^T R != I, and the round-off drift of R^T R, which
    persists from step to step, would otherwise dominate the round-off floor of the
    shooting residual (measured on E3, N = 100: 1-ulp per-step perturbations of R normal
    to SO(3) moved z_N 4x more than tangent ones).
    """
    x, gamma, R, Pi = split_state(X)
    Rp = 0.5 * ca.mtimes(R, 3 * ca.DM.eye(3) - ca.mtimes(R.T, R))
    return join_state(x, gamma, Rp, Pi)


def _costate_back_solve(A, lam_prev):
    """lambda_k from lambda_{k-1} = A_k^T lambda_k (eq. 28), with its relative residual."""
    lam = solve_unpivoted(A.T, lam_prev)
    return lam, ca.norm_inf(ca.mtimes(A.T, lam) - lam_prev) / ca.fmax(ca.norm_inf(lam_prev), 1e-300)


def _costate_map_function(scheme: str, ins: list, outs: list) -> ca.Function:
    """``{scheme}_costate_map`` (X, lam_prev, h, Winv) -> (X1, lam, u, res, lam_res), one signature for both schemes."""
    return ca.Function(f"{scheme}_costate_map", ins, outs, ["X", "lam_prev", "h", "Winv"],
                       ["X1", "lam", "u", "res", "lam_res"])


def costate_functions(disc: Discretization) -> tuple[ca.Function, ca.Function | None]:
    """The forward map of the necessary conditions for ``disc``.

    Returns (costate_map, first_step); both built from ``disc.variation`` (A_k, B_k: the
    Jacobian of the same step Function) and ``disc.step``.

    first_order (module docstring):

    * costate_map (X[18], lam_prev[12], h, Winv[6x6]) -> (X1[18], lam[12], u[6], res, lam_res):
      X = X_k, lam_prev = lambda_{k-1}; lam = lambda_k = A_k^-T lambda_{k-1} (28);
      u = u_{k+1} = -(1/h) Winv B_k^T lambda_k (26)-(27); X1 = X_{k+1} = step(X_k, u_{k+1});
      res the Cayley residual of the step; lam_res = |A_k^T lam - lam_prev|_inf / |lam_prev|_inf.
    * first_step (X0[18], lam0[12], h, Winv) -> (X1[18], u[6], res): the k = 0 step,
      where lambda_0 is the unknown itself.

    lgvi (see :data:`LGVI_CONDITIONS`): costate_map has the same signature with
    u = u_{k+1}; it also computes u_k = -(2/h) Winv B^b^T lambda_{k-1} and
    A_k = A(X_k, u_k).  first_step is None (the map is applied N times from lambda_{-1}).
    """
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    lam0 = ca.SX.sym("lam0", NZ)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    w = ca.SX.sym("w", disc.nw)

    A_w, B_w = disc.variation(X, w, h)
    if disc.scheme == "first_order":
        if ca.depends_on(A_w, w) or ca.depends_on(B_w, w):
            raise ValueError("A_k or B_k depends on the stage control: the forward costate recursion does not apply")
        A, B = disc.variation(orthonormalized(X), ca.DM.zeros(disc.nw), h)

        def control(lam):
            return -ca.mtimes(Winv, ca.mtimes(B.T, lam)) / h

        lam, lam_res = _costate_back_solve(A, lam_prev)
        u = control(lam)
        X1, res = disc.step(X, u, h)
        costate_map = _costate_map_function(disc.scheme, [X, lam_prev, h, Winv], [X1, lam, u, res, lam_res])
        u0 = control(lam0)
        X1, res = disc.step(X, u0, h)
        first_step = ca.Function(
            "first_order_costate_first_step", [X, lam0, h, Winv], [X1, u0, res], ["X0", "lam0", "h", "Winv"],
            ["X1", "u", "res"]
        )
        return costate_map, first_step

    # lgvi: w = [u_k; u_{k+1}]; A_k and B^a_k depend on u_k only, B^b = dX_{k+1}/du_{k+1} is constant
    Bb_w = B_w[:, NU:]
    if ca.depends_on(A_w, w[NU:]) or ca.depends_on(Bb_w, w):
        raise ValueError("A_k depends on u_{k+1} or B^b is not constant: the forward costate recursion does not apply")
    Bb = ca.substitute(Bb_w, w, ca.DM.zeros(disc.nw))
    Xo = orthonormalized(X)

    def control(lam):
        return -2.0 * ca.mtimes(Winv, ca.mtimes(Bb.T, lam)) / h

    uk = control(lam_prev)
    A, _ = disc.variation(Xo, ca.vertcat(uk, ca.DM.zeros(NU)), h)
    lam, lam_res = _costate_back_solve(A, lam_prev)
    uk1 = control(lam)
    X1, res = disc.step(X, ca.vertcat(uk, uk1), h)
    costate_map = _costate_map_function(disc.scheme, [X, lam_prev, h, Winv], [X1, lam, uk1, res, lam_res])
    return costate_map, None


def linearized_map(disc: Discretization) -> ca.Function:
    """The costate forward map and its linearization (docs/mathematics.md §6, (29)-(31)) as one SX Function.

    linearized_map (X[18], lam_prev[12], dX[18x12], dlam[12x12], h, Winv[6x6])
        -> (X1[18], lam[12], dX1[18x12], dlam1[12x12])

    (X1, lam) as in :func:`costate_functions`; (dX1, dlam1) = d(X1, lam)/d(X, lam_prev) @ (dX, dlam),
    i.e. the sensitivities of the coupled state-multiplier recursion carried forward.  Starting
    from (dX, dlam) = d(X_1, lambda_0)/d lambda_0 and iterating gives dX_N/dlambda_0, hence Psi_12.

    The derivative is taken with every Cayley root held as a seed c0 (``disc.step_seeded``,
    ``disc.variation_seeded``: two Newton iterations from c0, exact up to third derivatives at the
    root), then c0 is set to the solved root.  Forward AD through the 8 unrolled Newton iterations
    of ``costate_map`` gives the same numbers with a graph ~6x larger (measured: 266k instructions for
    12 directions against 40k here).
    """
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    dX = ca.SX.sym("dX", NX, NZ)
    dlam = ca.SX.sym("dlam", NZ, NZ)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    cv = ca.SX.sym("cv", 3)
    cs = ca.SX.sym("cs", 3)
    Xo = orthonormalized(X)
    zero = ca.DM.zeros(NU)
    if disc.scheme == "first_order":
        A, B = disc.variation_seeded(Xo, zero, h, cv)
        lam = solve_unpivoted(A.T, lam_prev)
        u = -ca.mtimes(Winv, ca.mtimes(B.T, lam)) / h
        X1 = disc.step_seeded(X, u, h, cs)
        # g = h Pi_k: the roots do not depend on the control
        gv, gs = disc.cayley_rhs(Xo, zero, h), disc.cayley_rhs(X, zero, h)
    else:
        w0 = ca.SX.sym("w", disc.nw)
        Bb = ca.substitute(disc.variation(X, w0, h)[1][:, NU:], w0, ca.DM.zeros(disc.nw))
        uk = -2.0 * ca.mtimes(Winv, ca.mtimes(Bb.T, lam_prev)) / h
        A, _ = disc.variation_seeded(Xo, ca.vertcat(uk, zero), h, cv)
        lam = solve_unpivoted(A.T, lam_prev)
        uk1 = -2.0 * ca.mtimes(Winv, ca.mtimes(Bb.T, lam)) / h
        X1 = disc.step_seeded(X, ca.vertcat(uk, uk1), h, cs)
        # g = h (Pi_k + (h/2)(M_k + u_k)): independent of u_{k+1}
        gv, gs = disc.cayley_rhs(Xo, ca.vertcat(uk, zero), h), disc.cayley_rhs(X, ca.vertcat(uk, zero), h)
    out = ca.vertcat(X1, lam)
    dout = ca.jtimes(out, ca.vertcat(X, lam_prev), ca.vertcat(dX, dlam))
    core = ca.Function("linearized_core", [X, lam_prev, dX, dlam, h, Winv, cv, cs],
                       [X1, lam, dout[:NX, :], dout[NX:, :]])
    outs = core(X, lam_prev, dX, dlam, h, Winv, disc.cayley_solve(gv)[0], disc.cayley_solve(gs)[0])
    return ca.Function(f"{disc.scheme}_linearized_map", [X, lam_prev, dX, dlam, h, Winv], outs,
                       ["X", "lam_prev", "dX", "dlam", "h", "Winv"], ["X1", "lam", "dX1", "dlam1"])


#: The second-order LGVI (docs/mathematics.md §2, node controls u_0..u_N, stage control w_k = [u_k; u_{k+1}],
#: cost sum_j omega_j (1/2) u_j^T W u_j with trapezoidal omega = h (1/2, 1, ..., 1, 1/2), as in
#: the direct method), derived with the same Lagrangian L = J + sum_k lambda_k^T (step ⊖ X_{k+1}).
LGVI_CONDITIONS = """
z_{k+1} = A_k z_k + B^a_k du_k + B^b du_{k+1}.  Stationarity in z_k (k = 1..N-1):
lambda_{k-1} = A_k^T lambda_k.  In u_j:  omega_j W u_j + B^a_j^T lambda_j + B^b^T lambda_{j-1} = 0
(terms absent for j = N resp. j = 0).  In eqs. (7)-(11) u_k enters exactly as a momentum kick
(gamma_k, Pi_k) += (h/2) u_k before the step, with f_k, M_k unchanged, so B^a_k = A_k B^b
(tested) and, with lambda_{-1} := A_0^T lambda_0 (the multiplier of the initial condition),
stationarity reads uniformly for j = 0..N

    u_j = -(2/h) W^-1 B^b^T lambda_{j-1} = -W^-1 [lambda^2_{j-1}; lambda^4_{j-1}]   (omega_j = h inside,
                                                                              h/2 at both ends)

A_k depends on u_k but not on u_{k+1}, so the recursion runs forward from the unknown lambda_{-1}:
u_k from lambda_{k-1}; lambda_k = A_k(X_k, u_k)^-T lambda_{k-1}; u_{k+1} from lambda_k;
X_{k+1} = step(X_k, [u_k; u_{k+1}]).  The shooting unknown is lambda_{-1} (12), the residual z_N.
"""


class ShootingFunctions:
    """Shooting residual and its Jacobian for one (Discretization, N), built once.

    The unknown ``lam0`` is lambda_0 (first_order) or lambda_{-1} (lgvi, see LGVI_CONDITIONS).

    shoot(lam0[12], X0[18], Xd[18], h, Winv[6x6])
        -> (zN[12], X[18 x N] nodes 1..N, lam[12 x N] lambda_0..lambda_{N-1},
            U[6 x n_controls] (first_order u_1..u_N; lgvi u_0..u_N), res[1 x N] Cayley residuals,
            lam_res[1 x N] relative residuals of the costate solves, 0 for k = 0 in first_order)
    residual(lam0, X0, Xd, h, Winv) -> (zN[12], res_max)  (line-search trials; res_max = max
        relative Cayley residual over the steps: a rollout with res_max > cayley_tol is not
        a solution of the discrete equations and is rejected)
    shoot_jac(lam0, X0, Xd, h, Winv) -> (zN[12], Psi[12 x 12]),  Psi = dzN/dlam0 by
        forward-mode AD (12 directions) through the mapaccum'ed rollout.
    """

    def __init__(self, disc: Discretization, N: int, jit: bool = False):
        if N < 1:
            raise ValueError("N must be >= 1")
        self.disc, self.N, self.jit = disc, int(N), bool(jit)
        sch = disc.scheme
        self.costate_map, self.first_step = costate_functions(disc)
        self.linearized_map = linearized_map(disc)
        # the per-step Functions evaluated N times per rollout; compiled to C with jit (values only)
        step_map, lin_map = self.costate_map, self.linearized_map
        if self.jit:
            step_map, lin_map = (codegen.compiled(f) for f in (step_map, lin_map))
        self.compiled = self.jit and isinstance(lin_map, ca.Function) and lin_map.class_name() == "External"
        self.terminal_residual = terminal_residual_function()

        lam0 = ca.MX.sym("lam0", NZ)
        X0 = ca.MX.sym("X0", NX)
        Xd = ca.MX.sym("Xd", NX)
        h = ca.MX.sym("h")
        Winv = ca.MX.sym("Winv", NU, NU)
        if sch == "first_order":
            X1, u1, r1 = self.first_step(X0, lam0, h, Winv)
            Xs, lams, Us, res, lres = [X1], [lam0], [u1], [r1], [ca.MX(0)]
            if N > 1:
                acc = step_map.mapaccum(f"{sch}_costate_acc{N - 1}", N - 1, 2)
                Xr, Lr, Ur, Rr, LRr = acc(X1, lam0, ca.repmat(h, 1, N - 1), ca.repmat(Winv, 1, N - 1))
                Xs.append(Xr)
                lams.append(Lr)
                Us.append(Ur)
                res.append(Rr)
                lres.append(LRr)
        else:
            acc = step_map.mapaccum(f"{sch}_costate_acc{N}", N, 2)
            Xr, Lr, Ur, Rr, LRr = acc(X0, lam0, ca.repmat(h, 1, N), ca.repmat(Winv, 1, N))
            u0 = self._lgvi_u0(lam0, h, Winv)
            Xs, lams, Us, res, lres = [Xr], [Lr], [u0, Ur], [Rr], [LRr]
        Xs, lams, Us, res, lres = (ca.horzcat(*a) for a in (Xs, lams, Us, res, lres))
        zN = self.terminal_residual(Xs[:, -1], Xd)
        names_in = ["lam0", "X0", "Xd", "h", "Winv"]
        args = [lam0, X0, Xd, h, Winv]
        self.shoot = ca.Function(
            f"{sch}_shoot{N}",
            args,
            [zN, Xs, lams, Us, res, lres],
            names_in,
            ["zN", "X", "lam", "U", "res", "lam_res"],
        )
        res_max = ca.mmax(res)
        self.residual = ca.Function(f"{sch}_shoot_residual{N}", args, [zN, res_max], names_in, ["zN", "res_max"])
        # Psi = dzN/dlam0 by the linearized coupled recursion (forward sensitivities carried step by
        # step, see linearized_map): the same derivative as forward AD through the rollout, ~6x cheaper
        n_lin = N if sch == "lgvi" else N - 1  # first_order: step 0 is handled below; N = 1 has none left
        lin_acc = lin_map.mapaccum(f"{sch}_linearized_acc{N}", n_lin, 4) if n_lin > 0 else None
        if sch == "first_order":
            dX1 = ca.jacobian(X1, lam0)                      # first step: u_1 linear in lam0, c_0 independent
            XN, dXN = X1, dX1
            if N > 1:
                XL, _, dXL, _ = lin_acc(X1, lam0, dX1, ca.MX.eye(NZ), ca.repmat(h, 1, N - 1),
                                        ca.repmat(Winv, 1, N - 1))
                XN, dXN = XL[:, -1], dXL[:, -NZ:]
        else:
            XL, _, dXL, _ = lin_acc(X0, lam0, ca.MX.zeros(NX, NZ), ca.MX.eye(NZ), ca.repmat(h, 1, N),
                                    ca.repmat(Winv, 1, N))
            XN, dXN = XL[:, -1], dXL[:, -NZ:]
        xs, xds = ca.SX.sym("XN", NX), ca.SX.sym("Xd", NX)
        zs = self.terminal_residual(xs, xds)
        term_jac = ca.Function("terminal_residual_jac", [xs, xds], [zs, ca.jacobian(zs, xs)], ["XN", "Xd"], ["zN", "J"])
        zL, JT = term_jac(XN, Xd)
        self.shoot_jac = ca.Function(f"{sch}_shoot_jac{N}", args, [zL, ca.mtimes(JT, dXN)], names_in, ["zN", "Psi"])

    def _lgvi_u0(self, lam_init, h, Winv):
        """u_0 = -(2/h) Winv B^b^T lambda_{-1}, B^b from the graph."""
        X = ca.SX.sym("X", NX)
        w = ca.SX.sym("w", self.disc.nw)
        hs = ca.SX.sym("h")
        Bb = ca.substitute(self.disc.variation(X, w, hs)[1][:, NU:], w, ca.DM.zeros(self.disc.nw))
        Bb_fun = ca.Function("lgvi_Bb", [hs], [Bb])  # constant in X (checked in costate_functions)
        return -2.0 * ca.mtimes(Winv, ca.mtimes(Bb_fun(h).T, lam_init)) / h


@lru_cache(maxsize=None)
def shooting_functions(disc: Discretization, N: int, jit: bool = False) -> ShootingFunctions:
    """Cached :class:`ShootingFunctions` (one per Discretization object, N and jit)."""
    return ShootingFunctions(disc, N, jit)



# ------------------------------------------------------------------------- helpers
def weight_inverse(problem: Problem) -> np.ndarray:
    """blkdiag(W_f, W_m)^-1 (6x6) of a smooth-control problem."""
    return np.linalg.inv(problem.control.W)


def control_cost(problem: Problem, U: np.ndarray) -> float:
    """The effort cost of controls U (6 x n_controls) with the quadrature weights of the scheme."""
    return effort_cost(U, problem.control, quadrature_weights(problem.scheme, problem.N, problem.h))


def lam0_from_direct(problem: Problem, dsol: Solution) -> np.ndarray:
    """The shooting unknown from a direct solution's mapped multipliers (docs/mathematics.md §6).

    first_order: lambda_0 = dsol.costates[0]; lgvi: lambda_{-1} = A_0(X_0, u_0)^T lambda_0.
    Raises ValueError if the direct solution carries no costates.
    """
    if dsol.costates is None or dsol.controls is None:
        raise ValueError("the direct solution carries no costates")
    lam = np.asarray(dsol.costates[0], dtype=float).reshape(NZ)
    if problem.scheme == "lgvi":  # the unknown is lambda_{-1} = A_0(X_0, u_0)^T lambda_0
        w0 = np.r_[dsol.controls[:, 0], np.zeros(NU)]
        A0 = np.array(problem.disc.variation(problem.X0, w0, problem.h)[0])
        lam = A0.T @ lam
    return lam


def _initial_costate(problem: Problem, opts: IndirectOptions, warm_start, direct_options: DirectOptions | None):
    """(lambda_0, source, direct Solution or None) from ``warm_start`` (an array, an indirect Solution
    or a direct Solution with costates) or ``opts.initial_costate``: 'zero', 12 numbers, or
    'from_direct' -- the direct method is run here unless its solution is passed as warm_start
    (the one place of the direct -> indirect hand-off)."""
    if isinstance(warm_start, Solution):
        if warm_start.method == "indirect" and warm_start.stats.get("lam0") is not None:
            return np.asarray(warm_start.stats["lam0"], float).reshape(NZ), "warm_start", None
        return lam0_from_direct(problem, warm_start), "from_direct", warm_start
    if warm_start is not None:
        return np.asarray(warm_start, dtype=float).reshape(NZ), "argument", None
    spec = opts.initial_costate
    if spec == "zero":
        return np.zeros(NZ), "zero", None
    if spec == "from_direct":
        from .direct import solve_direct  # the direct method is needed only here

        dsol = solve_direct(problem, direct_options or DirectOptions())
        return lam0_from_direct(problem, dsol), "from_direct", dsol
    return np.asarray(spec, dtype=float).reshape(NZ), "explicit", None


def not_covered(problem: Problem) -> str:
    """What of a smooth-control problem the indirect method does not cover ('' if nothing): its
    necessary conditions are those of the effort objective with every terminal component given."""
    c = problem.control
    reasons = []
    if c.objective != "effort":
        reasons.append(f"the {c.objective} objective")
    if problem.constraints:
        reasons.append("path constraints")
    if not isinstance(problem.terminal, TargetState):
        reasons.append("an orbit target")
    elif problem.terminal.free:
        reasons.append("free terminal components")
    if problem.free_time:
        reasons.append("a free final time")
    if c.bounded:
        reasons.append("bounded controls")
    return ", ".join(reasons)


def _failure(problem: Problem, result: Result, message: str, build_s: float = 0.0) -> Solution:
    """A Solution for a solve that could not start: the free rollout."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.h, problem.N)
    m = problem.model
    return Solution(method="indirect", solver="newton-armijo", result=result, message=message,
                    trajectory=Trajectory(t=problem.h * np.arange(problem.N + 1), X=X, mass=m.mass, inertia=m.inertia),
                    cost=float("nan"), terminal_error=terminal_error(X[-1], problem), iterations=0, build_s=build_s,
                    solve_s=0.0, problem=problem)


# -------------------------------------------------------------------------- solver
def solve_indirect(problem: Problem, options: IndirectOptions | None = None,
                   progress: Callable[[Iterate], None] | None = None, warm_start=None,
                   direct_options: DirectOptions | None = None) -> Solution:
    """Newton-Armijo shooting on lambda_0 (docs/mathematics.md §6) for a smooth-control problem
    with a state target ('first_order' or 'lgvi'; for 'lgvi' the unknown is lambda_{-1}, see
    LGVI_CONDITIONS).

    The initial costate comes from ``warm_start`` (12 numbers, an indirect Solution, or a direct
    Solution whose multipliers are mapped to the costates) or from ``options.initial_costate``
    (with 'from_direct' the direct method runs first, with ``direct_options``).  The iteration is
    :func:`~transcription.newton.newton_armijo` on z_N(lambda_0) with the exact Jacobian Psi, the
    round-off floor detection (``floor_factor``, ``floor_accept``) and trials whose rollout does
    not solve the Cayley equation to ``cayley_tol`` rejected.

    The Solution (method 'indirect', solver 'newton-armijo') has the controls (6 x N, u_1..u_N;
    lgvi 6 x N+1, u_0..u_N) from the lambda_k, the costates (N, 12) lambda_0..lambda_{N-1}, the
    trajectory re-simulated from those controls, the terminal error measured on it, the cost, and
    the history (the initial rollout and every line-search trial).
    """
    opts = options or IndirectOptions()
    if problem.kind != "smooth":
        raise ValueError("the indirect method solves smooth-control problems")
    missing = not_covered(problem)
    if missing:
        return _failure(problem, Result.not_applicable,
                        f"the indirect method does not cover {missing}; solve it by the direct method (whose Solution "
                        "carries costate estimates mapped from its multipliers)")
    disc, N, h = problem.disc, problem.N, problem.h
    t0 = time.perf_counter()
    fns = shooting_functions(disc, N, bool(opts.jit))
    build_s = time.perf_counter() - t0
    X0, Xd, Winv = problem.X0, problem.terminal.X, weight_inverse(problem)
    stats: dict = {"jit": bool(fns.compiled)}
    t_init = time.perf_counter()
    try:
        lam, source, dsol = _initial_costate(problem, opts, warm_start, direct_options)
    except ValueError as exc:
        return _failure(problem, Result.invalid_option, str(exc), build_s)
    stats["initial_costate"] = source
    if dsol is not None and source == "from_direct" and warm_start is None:
        stats.update(direct_solve_s=float(time.perf_counter() - t_init), direct_status=dsol.result.value,
                     direct_cost=float(dsol.cost))
    t1 = time.perf_counter()

    def residual(l):
        z, r = fns.residual(l, X0, Xd, h, Winv)
        return np.array(z).ravel(), float(r)

    def jacobian(l):
        # Psi only: z always comes from ``residual`` (one rounding for all comparisons)
        return np.array(fns.shoot_jac(l, X0, Xd, h, Winv)[1])

    z0, r0 = residual(lam)
    if not r0 <= opts.cayley_tol:
        return _failure(problem, Result.invalid_option,
                        f"the rollout from the initial lambda_0 does not solve the Cayley equation (residual {r0:.1e} > "
                        f"cayley_tol {opts.cayley_tol:.0e}): the rotation per step is too large; use a smaller step "
                        f"h = T/N (increase horizon.N) or another initial costate", build_s)
    nr = newton_armijo(lam, residual, jacobian, tol=opts.eps_S, alpha=opts.alpha, max_iter=opts.max_iter,
                       max_halvings=opts.max_halvings, aux_tol=opts.cayley_tol, floor_factor=opts.floor_factor,
                       floor_accept=opts.floor_accept, progress=progress)
    lam = nr.x
    # final rollout: controls and costates from lambda_0, re-simulated trajectory
    _, _, lams, U, _, lres = fns.shoot(lam, X0, Xd, h, Winv)
    U = np.array(U)
    lams = np.array(lams).T
    Xsim, res = disc.simulate(X0, U, h, N)
    solve_s = time.perf_counter() - t1
    finite = bool(np.all(np.isfinite(Xsim)))
    result, message = nr.result, nr.message.replace("|F|", "|z_N|").replace(" x ", " lambda_0 ")
    if not result.successful and nr.rejected_aux:
        message += (f"; {len(nr.rejected_aux)} line-search trials were rejected because their controls turned the body "
                    f"too far per step for the Cayley solve (residual up to {max(nr.rejected_aux):.1e} > cayley_tol "
                    f"{opts.cayley_tol:.0e}): a smaller step h = T/N (increase horizon.N) or a better initial costate "
                    "(initial_costate: from_direct) may help")
    if result.successful and not finite:
        result, message = Result.non_finite, "re-simulation produced non-finite states"
    stats.update(
        residual_norm=float(np.linalg.norm(nr.F)),
        roundoff_floor=nr.floor,
        noise_level=nr.noise,
        max_cayley_residual=float(np.max(res)) if res.size else 0.0,
        max_costate_solve_residual=float(np.max(np.array(lres))),
        lam0=lam.copy(),
        quadratic_C=quadratic_constant(nr.history, floor=10.0 * nr.noise if nr.noise else 0.0),
    )
    return Solution(method="indirect", solver="newton-armijo", result=result, message=message,
                    trajectory=Trajectory(t=h * np.arange(N + 1), X=Xsim, mass=problem.model.mass,
                                          inertia=problem.model.inertia),
                    cost=control_cost(problem, U) if np.all(np.isfinite(U)) else float("inf"),
                    terminal_error=terminal_error(Xsim[-1], problem) if finite else float("inf"),
                    iterations=nr.iterations, build_s=build_s, solve_s=solve_s, problem=problem, controls=U,
                    costates=lams, history=nr.history, stats=stats)


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
