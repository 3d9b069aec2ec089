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
(29)-(31)) is computed exactly, by the linearized recursion in tangent coordinates along the
rollout (:func:`linearization_functions`; equal to forward-mode AD through the rollout).

Per-step Functions, built once per Discretization (compiled to C by default, IndirectOptions.jit):

    costate_map      (X[18], lam_prev[12], h, Winv[6x6]) -> (X1[18], lam[12], u[6], res, lam_res, A, c)
    first_step       (X0[18], lam0[12], h, Winv[6x6])    -> (X1[18], u[6], res)
    costate_hessian  (X, lam_prev, lam, c, h, Winv)      -> H[12x12]
    linearized_map   (dZ[12x12], dlam[12x12], A, H, h, Winv) -> (dZ1, dlam1)

and once per (Discretization, N) (see :func:`shooting_functions`):

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

import dataclasses
import time
from functools import lru_cache
from typing import Any, Callable

import casadi as ca
import numpy as np

from . import codegen
from .layout import NU, NX, NZ, U_FORCE, U_MOMENT, join_state, split_state
from .lgvi import Discretization
from .lie import chart, tangent_readback
from .newton import newton_armijo
from .options import DirectOptions, IndirectOptions
from .problem import (STATE_COMPONENTS, BoxBound, NormBound, Problem, TargetState, effort_cost, quadrature_weights,
                      state_residual, terminal_error)
from .results import Iterate, Result, Solution, Trajectory

#: nesting base of CasADi's mapaccum (default 10): the same evaluation, but with base 10 building the Function
#: took 0.04-0.18 s at N = 1000 (a single chain element N = 10^3), with base 4 0.004-0.014 s
MAPACCUM_OPTS = {"base": 4}


def terminal_residual_function() -> ca.Function:
    """(XN[18], Xd[18]) -> zN[12]: :func:`~transcription.problem.state_residual` with every component
    (positions and linear momenta inertial, Pi body; the attitude error the rotation vector of
    R_d^T R_N, body frame at the target, three conditions)."""
    XN = ca.SX.sym("XN", NX)
    Xd = ca.SX.sym("Xd", NX)
    return ca.Function("terminal_residual", [XN, Xd], [state_residual(XN, Xd)], ["XN", "Xd"], ["zN"])

def solve_unpivoted(M, b):
    """Solve M Y = b (SX, M n x n dense, b n x m) by Gaussian elimination without pivoting.

    Used for lambda_k = A_k^-T lambda_{k-1} (and, with 12 columns, for its linearization).  A_k is
    close to a block-triangular matrix with identity diagonal blocks (x, gamma, Pi) and the
    rotation block F_k^T (zeta), so the pivots stay away from 0 while the rotation per step is
    well below a right angle, and elimination without pivoting is accurate: on E3 its error is
    ~1 ulp per component (against an exact rational solve), as good as LAPACK LU,
    whereas CasADi's symbolic QR (``ca.solve`` on SX) erred by ~1e-11 on |lambda| ~ 1e2
    and raised the round-off floor of z_N to ~1e-10 (E3, N = 100).  The caller
    reports the relative residual |M y - b|_inf / |b|_inf (lam_res) so a breakdown
    would be visible.  The columns of b share one elimination; each column goes through the same
    operations as a single right-hand side.
    """
    return unpivoted_substitution(unpivoted_elimination(M), b)


def unpivoted_elimination(M):
    """The elimination of :func:`solve_unpivoted` (SX, n x n): LU with the multipliers below the diagonal and
    the eliminated upper triangle (pivots on the diagonal), entries of M's structural zeros stay exact zeros."""
    n = M.shape[0]
    # row operations on whole rows: per entry the same operations in the same order as the scalar algorithm,
    # with far fewer Python-level CasADi calls (build time)
    a = ca.densify(ca.SX(M))
    for c in range(n - 1):
        f = a[c + 1:, c] / a[c, c]
        a[c + 1:, c + 1:] = a[c + 1:, c + 1:] - ca.mtimes(f, a[c, c + 1:])
        a[c + 1:, c] = f
    return a


def unpivoted_substitution(LU, b):
    """Y with M Y = b from LU = unpivoted_elimination(M) (b n x m): forward elimination of b with the stored
    multipliers, then back substitution; per column the operations of the single-column algorithm."""
    n = LU.shape[0]
    r = ca.densify(ca.SX(b))
    for c in range(n - 1):
        r[c + 1:, :] = r[c + 1:, :] - ca.mtimes(LU[c + 1:, c], r[c, :])
    y = [None] * n
    for i in reversed(range(n)):
        acc = r[i, :]
        for j in range(i + 1, n):
            acc = acc - LU[i, j] * y[j]
        y[i] = acc / LU[i, i]
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


def _costate_map_function(scheme: str, ins: list, outs: list) -> ca.Function:
    """``{scheme}_costate_map`` (X, lam_prev, h, Winv, bd) -> (X1, lam, u, res, lam_res, A, c, D), one signature for
    both schemes."""
    return ca.Function(f"{scheme}_costate_map", ins, outs, ["X", "lam_prev", "h", "Winv", "bd"],
                       ["X1", "lam", "u", "res", "lam_res", "A", "c", "D"])


@lru_cache(maxsize=None)
def control_matrix(disc: Discretization) -> ca.Function:
    """``{scheme}_control_matrix`` (h) -> B_c[12x6]: the tangent-coordinate derivative of X_{k+1} by the
    control that the costate lambda_k determines (first_order: B_k w.r.t. u_{k+1}; lgvi: B^b).

    Taken from the graph (``disc.variation_seeded``) and checked, when built, to be constant (no
    dependence on X_k or the stage control), and the Cayley right-hand side g_k to be independent of
    that control: the assumptions of the forward costate recursion.  The controls are
    u = -(s/h) Winv B_c^T lambda with s = 1 (first_order) or 2 (lgvi, see LGVI_CONDITIONS).
    """
    X = ca.SX.sym("X", NX)
    w = ca.SX.sym("w", disc.nw)
    h = ca.SX.sym("h")
    c0 = ca.SX.sym("c0", 3)
    A, B = disc.variation_seeded(X, w, h, c0)
    wb = w if disc.scheme == "first_order" else w[NU:]  # the control lambda_k determines
    Bc = B[:, -NU:]
    if ca.depends_on(A, wb) or ca.depends_on(Bc, ca.vertcat(X, w, c0)) or \
            ca.depends_on(disc.cayley_rhs(X, w, h), wb):
        raise ValueError("A_k or the Cayley equation depends on the control determined by lambda_k, or its B is not "
                         "constant: the forward costate recursion does not apply")
    return ca.Function(f"{disc.scheme}_control_matrix", [h], [Bc], ["h"], ["B"])


#: length of the bound data ``bd`` of the per-step Functions: the box half-widths b (6; inf where a
#: component has no box, 0 where a norm bound of 0 removes the control) and the squared norm bounds
#: (2: force, moment; NO_NORM where a block has no norm bound)
NB = 8
NO_NORM = 1e300


def saturate(v, bd):
    """u = the minimizer of (1/2) u^T W u - u^T W v over the control bounds, for the unconstrained minimizer v
    (6; docs/mathematics.md §10): each component clipped to its box, then each block scaled into its norm ball,

        u_i = min(max(v_i, -b_i), b_i),   u_blk <- u_blk sqrt(n_blk^2 / max(|u_blk|^2, n_blk^2)).

    Exact for the weights the indirect method accepts (a box with a diagonal block of W, a norm with an
    isotropic one, see :func:`not_covered`; a block has one kind of bound).  Without bounds (b = inf,
    n^2 = NO_NORM) u = v bit for bit.  The squared form keeps the derivative finite at u = 0.
    """
    u = ca.fmin(ca.fmax(v, -bd[:NU]), bd[:NU])
    blocks = []
    for i, sl in enumerate((slice(0, 3), slice(3, 6))):
        ub, n2 = u[sl], bd[NU + i]
        blocks.append(ub * ca.sqrt(n2 / ca.fmax(ca.dot(ub, ub), n2)))
    return ca.vertcat(*blocks)


@lru_cache(maxsize=None)
def saturation() -> ca.Function:
    """``saturation`` (v[6], bd[NB]) -> (u[6], D[6x6]): :func:`saturate` and its (generalized) Jacobian
    D = du/dv, the element of the Clarke Jacobian that CasADi's derivatives of min/max pick (the active
    branch; 1/2 at an exact tie) -- what the semismooth Newton method differentiates through."""
    v, bd = ca.SX.sym("v", NU), ca.SX.sym("bd", NB)
    u = saturate(v, bd)
    return ca.Function("saturation", [v, bd], [u, ca.jacobian(u, v)], ["v", "bd"], ["u", "D"])


def bound_data(problem: Problem) -> np.ndarray:
    """The bound data ``bd`` (NB) of a smooth-control problem (see :data:`NB`)."""
    bd = np.r_[np.full(NU, np.inf), NO_NORM, NO_NORM]
    for i, (sl, bound) in enumerate(((U_FORCE, problem.control.force_bound), (U_MOMENT, problem.control.moment_bound))):
        if isinstance(bound, BoxBound):
            bd[sl] = bound.b
        elif isinstance(bound, NormBound) and bound.b == 0:
            bd[sl] = 0.0
        elif isinstance(bound, NormBound):
            bd[NU + i] = bound.b ** 2
    return bd


def _forward_step(disc: Discretization, X, lam_prev, h, Winv, bd) -> dict:
    """One step of the forward map of the necessary conditions, as SX expressions.

    The Cayley equation of step k is solved once (``disc.cayley_solve``; its right-hand side does
    not depend on u_{k+1}) for the step (``disc.step_given_c``: X1 and res are those of ``disc.step``).
    A_k = ``disc.variation`` at orthonormalized(X) (forward AD through the unrolled Newton iterations).
    ``disc.variation_seeded`` (two Newton iterations from the root) would be a smaller graph, equally
    accurate, but its different rounding changes the iteration counts at the round-off floor that tests
    pin; the costate map gives the same values as before, bit for bit.
    Returns a dict with c (the Cayley root), A, lam, u (u_{k+1}), D (its saturation Jacobian), X1, res
    and control (lambda -> (u, D)).
    """
    Bc = control_matrix(disc)(h)
    scale = 1.0 if disc.scheme == "first_order" else 2.0

    def control(lam):
        return saturation()(-scale * ca.mtimes(Winv, ca.mtimes(Bc.T, lam)) / h, bd)

    zero = ca.DM.zeros(NU)
    if disc.scheme == "first_order":
        wA, stage = zero, (lambda u1: u1)
    else:
        uk = control(lam_prev)[0]
        wA, stage = ca.vertcat(uk, zero), (lambda u1: ca.vertcat(uk, u1))
    c, hist = disc.cayley_solve(disc.cayley_rhs(X, wA, h))
    A = disc.variation(orthonormalized(X), wA, h)[0]
    lam = solve_unpivoted(A.T, lam_prev)
    u, D = control(lam)
    X1 = disc.step_given_c(X, c, stage(u), h)[0]
    return {"c": c, "A": A, "lam": lam, "u": u, "D": D, "X1": X1, "res": hist[-1], "control": control}


@lru_cache(maxsize=None)
def costate_functions(disc: Discretization) -> tuple[ca.Function, ca.Function | None]:
    """The forward map of the necessary conditions for ``disc``.

    Returns (costate_map, first_step); both built from the step and its variation A_k
    (:func:`_forward_step`; B_k from :func:`control_matrix`).

    first_order (module docstring):

    * costate_map (X[18], lam_prev[12], h, Winv[6x6], bd[NB]) -> (X1[18], lam[12], u[6], res, lam_res, A[12x12],
      c[3], D[6x6]): X = X_k, lam_prev = lambda_{k-1}; lam = lambda_k = A_k^-T lambda_{k-1} (28);
      u = u_{k+1} = sat(-(1/h) Winv B_k^T lambda_k) (26)-(27), saturated to the bounds bd
      (:func:`saturate`; D its Jacobian); X1 = X_{k+1} = step(X_k, u_{k+1});
      res the Cayley residual of the step; lam_res = |A_k^T lam - lam_prev|_inf / |lam_prev|_inf;
      A = A_k and c the root of the step's Cayley equation, for the linearization
      (:func:`linearization_functions`) along the same rollout.
    * first_step (X0[18], lam0[12], h, Winv, bd) -> (X1[18], u[6], res): the k = 0 step,
      where lambda_0 is the unknown itself.

    lgvi (see :data:`LGVI_CONDITIONS`): costate_map has the same signature with
    u = u_{k+1}; it also computes u_k = -(2/h) Winv B^b^T lambda_{k-1} and
    A_k = A(X_k, u_k).  first_step is None (the map is applied N times from lambda_{-1}).
    """
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    bd = ca.SX.sym("bd", NB)
    s = _forward_step(disc, X, lam_prev, h, Winv, bd)
    lam_res = ca.norm_inf(ca.mtimes(s["A"].T, s["lam"]) - lam_prev) / ca.fmax(ca.norm_inf(lam_prev), 1e-300)
    costate_map = _costate_map_function(disc.scheme, [X, lam_prev, h, Winv, bd],
                                        [s["X1"], s["lam"], s["u"], s["res"], lam_res, s["A"], s["c"], s["D"]])
    if disc.scheme != "first_order":
        return costate_map, None
    lam0 = ca.SX.sym("lam0", NZ)
    u0 = s["control"](lam0)[0]
    X1, res = disc.step(X, u0, h)
    first_step = ca.Function(
        "first_order_costate_first_step", [X, lam0, h, Winv, bd], [X1, u0, res], ["X0", "lam0", "h", "Winv", "bd"],
        ["X1", "u", "res"]
    )
    return costate_map, first_step


@lru_cache(maxsize=None)
def adjoint_variation_jacobian(disc: Discretization) -> ca.Function:
    """``{scheme}_adjoint_variation_jacobian`` (X, w, lam, h, c0) -> H[12x12] = d/dz [A(chart(X, z), w)^T lam] at z = 0.

    The derivative of the costate back-solve's matrix along a state variation, contracted with the
    costate first: A^T lam is the gradient in z of lam^T readback(step(chart(X, z))) (one reverse
    sweep; the readback is linear), and H its Jacobian in the chart coordinates of X (12 forward
    directions), instead of 12 forward directions through all 144 entries of A.  The step is the
    seeded one (two Newton iterations from the root c0 of step X's Cayley equation: exact up to
    third derivatives there), so H is exact.
    """
    X = ca.SX.sym("X", NX)
    w = ca.SX.sym("w", disc.nw)
    lam = ca.SX.sym("lam", NZ)
    h = ca.SX.sym("h")
    c0 = ca.SX.sym("c0", 3)
    z, zp = ca.SX.sym("z", NZ), ca.SX.sym("zp", NZ)
    X1z = disc.step_seeded(chart(chart(X, zp), z), w, h, c0)
    base = ca.SX.sym("base", NX)  # the readback point X_{k+1}(zp), not differentiated in z
    g = ca.gradient(ca.dot(lam, tangent_readback(base, X1z)), z)
    # one substitution for both, so that the step at z = 0 is one graph (not two copies, each differentiated)
    v, X1p = ca.substitute([g, X1z], [z], [ca.DM.zeros(NZ)])
    v = ca.substitute(v, base, X1p)
    H = ca.substitute(ca.jacobian(v, zp), zp, ca.DM.zeros(NZ))
    return ca.Function(f"{disc.scheme}_adjoint_variation_jacobian", [X, w, lam, h, c0], [H],
                       ["X", "w", "lam", "h", "c0"], ["H"])


def linearization_functions(disc: Discretization) -> tuple[ca.Function, ca.Function]:
    """The linearization of the costate forward map (docs/mathematics.md §6 (29)-(31)) along a rollout of the costate map.

    Returns (costate_hessian, linearized_map):

    costate_hessian (X[18], lam_prev[12], lam[12], c[3], h, Winv[6x6], bd[NB]) -> H[12x12]
        H_k = d/dz [A(chart(X_k, z), w_k)^T lambda_k] at z = 0 (:func:`adjoint_variation_jacobian` at
        orthonormalized(X_k), as A_k), w_k the stage control A_k is taken at (lgvi: u_k from lam_prev),
        seeded with the step's Cayley root c (an output of the costate map).
    linearized_map (dZ[12x12], dlam[12x12], A[12x12], H[12x12], Dk[6x6], D1[6x6], h, Winv[6x6])
            -> (dZ1[12x12], dlam1[12x12])
        dZ, dlam: the derivatives of z_k (tangent coordinates of X_k, docs/mathematics.md §4) and of lambda_{k-1} by
        the shooting unknown; (dZ1, dlam1) those of z_{k+1} and lambda_k.  Starting from the first step's
        and iterating (``mapaccum``) gives dz_N/dlambda_0, hence Psi_12.

    Differentiating lambda_{k-1} = A_k^T lambda_k and z_{k+1} = A_k z_k + B du_{k+1}:

        dlambda_k = A_k^-T (dlambda_{k-1} - H_k dz~_k)
        dz_{k+1}  = A_k dz~_k + B_c du_{k+1},     du_{k+1} = -(s/h) D_{k+1} Winv B_c^T dlambda_k

    (D_{k+1} the Jacobian of the saturation at u_{k+1}, an output of the costate map; the identity
    without bounds) with dz~_k = dz_k (first_order) or dz_k + B^b du_k, du_k = -(s/h) D_k Winv B_c^T
    dlambda_{k-1} (lgvi: u_k enters as the momentum kick B^b u_k,
    so A(X_k, u_k + du) = A(chart(X_k, B^b du), u_k) and B^a_k = A_k B^b; see LGVI_CONDITIONS).  The 12
    right-hand sides share one elimination (:func:`unpivoted_elimination` of A_k^T, then
    :func:`unpivoted_substitution` per column, the operations of :func:`solve_unpivoted`).

    Three per-step Functions (costate map, H, this update), each evaluated along the rollout, instead of
    one: each is smaller to compile, the three compile concurrently, and the values (X_k, lambda_k, A_k)
    are those of the residual's costate map, computed once.  First order: H 15k SX instructions
    (LGVI 25k), the costate map 10k (23k); the update is an MX Function (matrix products, a map of the
    column substitution) whose C is 1.5k lines of loops.  The previous construction (forward AD of the
    18-state step in 12 directions) took 111k instructions per step (228k).  Psi equals forward AD
    through the rollout (tests/test_perf_structure.py).
    """
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    lam = ca.SX.sym("lam", NZ)
    c = ca.SX.sym("c", 3)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    bd = ca.SX.sym("bd", NB)
    Bc = control_matrix(disc)(h)
    scale = 1.0 if disc.scheme == "first_order" else 2.0
    zero = ca.DM.zeros(NU)
    wA = zero if disc.scheme == "first_order" else \
        ca.vertcat(saturation()(-scale * ca.mtimes(Winv, ca.mtimes(Bc.T, lam_prev)) / h, bd)[0], zero)
    H = adjoint_variation_jacobian(disc)(orthonormalized(X), wA, lam, h, c)
    hessian = ca.Function(f"{disc.scheme}_costate_hessian", [X, lam_prev, lam, c, h, Winv, bd], [H],
                          ["X", "lam_prev", "lam", "c", "h", "Winv", "bd"], ["H"])

    # the update at the MX level (matrix products, a map of the column solve): compact C, cheap to compile
    spA = costate_functions(disc)[0].sparsity_out("A")               # its structural zeros save operations
    As = ca.SX.sym("A", spA)
    LUs = unpivoted_elimination(As.T)
    factor = ca.Function(f"{disc.scheme}_costate_factor", [As], [LUs], ["A"], ["LU"])
    LUc, col = ca.SX.sym("LU", LUs.sparsity()), ca.SX.sym("b", NZ)
    column_solve = ca.Function(f"{disc.scheme}_costate_column_solve", [LUc, col], [unpivoted_substitution(LUc, col)],
                               ["LU", "b"], ["y"])
    A = ca.MX.sym("A", spA)
    Hm = ca.MX.sym("H", H.sparsity())
    dZ = ca.MX.sym("dZ", NZ, NZ)
    dlam = ca.MX.sym("dlam", NZ, NZ)
    Dk = ca.MX.sym("Dk", NU, NU)
    D1 = ca.MX.sym("D1", NU, NU)
    hm = ca.MX.sym("h")
    Wm = ca.MX.sym("Winv", NU, NU)
    Bm = control_matrix(disc)(hm)
    G = -scale * ca.mtimes(Wm, Bm.T) / hm                          # the unsaturated control by lambda

    def M(D):                                                      # dz_{k+1} by lambda through the control
        return ca.mtimes(Bm, ca.mtimes(D, G))

    dZk = dZ if disc.scheme == "first_order" else dZ + ca.mtimes(M(Dk), dlam)
    solve_columns = column_solve.map(f"{disc.scheme}_costate_column_solve_map", "serial", NZ, [0], [])
    dlam1 = solve_columns(factor(A), dlam - ca.mtimes(Hm, dZk))
    dZ1 = ca.mtimes(A, dZk) + ca.mtimes(M(D1), dlam1)
    lin = ca.Function(f"{disc.scheme}_linearized_map", [dZ, dlam, A, Hm, Dk, D1, hm, Wm], [dZ1, dlam1],
                      ["dZ", "dlam", "A", "H", "Dk", "D1", "h", "Winv"], ["dZ1", "dlam1"])
    return hessian, lin


@lru_cache(maxsize=None)
def terminal_residual_jacobian() -> ca.Function:
    """(XN[18], Xd[18]) -> (zN[12], J[12x12]): J = dzN(chart(XN, z))/dz at z = 0 (tangent coordinates)."""
    XN, Xd, z = ca.SX.sym("XN", NX), ca.SX.sym("Xd", NX), ca.SX.sym("z", NZ)
    zt = terminal_residual_function()(chart(XN, z), Xd)
    J = ca.substitute(ca.jacobian(zt, z), z, ca.DM.zeros(NZ))
    return ca.Function("terminal_residual_jac", [XN, Xd], [terminal_residual_function()(XN, Xd), J], ["XN", "Xd"],
                       ["zN", "J"])


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

    The unknown ``lam0`` is lambda_0 (first_order) or lambda_{-1} (lgvi, see LGVI_CONDITIONS); bd the
    bound data of the controls (:func:`bound_data`; no bounds: u = v bit for bit).

    shoot(lam0[12], X0[18], Xd[18], h, Winv[6x6], bd[NB])
        -> (zN[12], X[18 x N] nodes 1..N, lam[12 x N] lambda_0..lambda_{N-1},
            U[6 x n_controls] (first_order u_1..u_N; lgvi u_0..u_N), res[1 x N] Cayley residuals,
            lam_res[1 x N] relative residuals of the costate solves, 0 for k = 0 in first_order)
    residual(lam0, X0, Xd, h, Winv, bd) -> (zN[12], lamN[12], res_max)  (line-search trials; lamN =
        lambda_{N-1}, the multiplier of the last step, for the transversality conditions of free
        terminal components; res_max = max relative Cayley residual over the steps: a rollout with
        res_max > cayley_tol is not a solution of the discrete equations and is rejected)
    shoot_jac(lam0, X0, Xd, h, Winv, bd) -> (zN[12], Psi[12 x 12], dlamN[12 x 12]),  Psi = dzN/dlam0 and
        dlamN = dlambda_{N-1}/dlam0 by the linearized recursion (:func:`linearization_functions`) along the
        mapaccum'ed rollout; equal to forward-mode AD through it (with bounds: the generalized derivative
        of the saturation, for the semismooth Newton method).
    """

    def __init__(self, disc: Discretization, N: int, jit: bool = False):
        if N < 1:
            raise ValueError("N must be >= 1")
        self.disc, self.N, self.jit = disc, int(N), bool(jit)
        sch = disc.scheme
        self.costate_map, self.first_step = costate_functions(disc)
        self.costate_hessian, self.linearized_map = linearization_functions(disc)
        # the per-step Functions evaluated along every rollout; with jit compiled to C (values only), three
        # libraries compiled concurrently, one set per scheme (and model), independent of N and of the data
        step_map, hess_map, lin_map = self.costate_map, self.costate_hessian, self.linearized_map
        if self.jit:
            (hess_map,), (step_map,), (lin_map,) = codegen.compiled_libraries(
                [codegen.Library(hess_map.name(), (hess_map,)),            # the largest first
                 codegen.Library(step_map.name(), (step_map,), cse=True),  # evaluated most often
                 codegen.Library(lin_map.name(), (lin_map,), cflags=tuple(codegen.LOOP_CFLAGS))],  # MX: loops
                cflags=codegen.QUICK_CFLAGS)
        self.compiled = self.jit and all(f.class_name() == "External" for f in (step_map, hess_map, lin_map))
        self.terminal_residual = terminal_residual_function()

        lam0 = ca.MX.sym("lam0", NZ)
        X0 = ca.MX.sym("X0", NX)
        Xd = ca.MX.sym("Xd", NX)
        h = ca.MX.sym("h")
        Winv = ca.MX.sym("Winv", NU, NU)
        bd = ca.MX.sym("bd", NB)
        Bc = control_matrix(disc)(h)
        scale = 1.0 if sch == "first_order" else 2.0
        # the control lam0 determines (first_order u_1, lgvi u_0) and its saturation Jacobian
        u_first, D_first = saturation()(-scale * ca.mtimes(Winv, ca.mtimes(Bc.T, lam0)) / h, bd)
        # the rollout: steps k = k0 .. N-1 by the costate map from (X_k0, lambda_k0-1)
        if sch == "first_order":   # step 0 from lambda_0 itself
            X1, u1, r1 = self.first_step(X0, lam0, h, Winv, bd)
            Xs, lams, Us, res, lres = [X1], [lam0], [u1], [r1], [ca.MX(0)]
            n, Xstart = N - 1, X1
        else:
            Xs, lams, Us, res, lres = [], [], [u_first], [], []
            n, Xstart = N, X0
        if n > 0:
            acc = step_map.mapaccum(f"{sch}_costate_acc{n}", n, 2, MAPACCUM_OPTS)
            Xr, Lr, Ur, Rr, LRr, Ar, Cr, Dr = acc(Xstart, lam0, ca.repmat(h, 1, n), ca.repmat(Winv, 1, n),
                                                  ca.repmat(bd, 1, n))
            for a, b in ((Xs, Xr), (lams, Lr), (Us, Ur), (res, Rr), (lres, LRr)):
                a.append(b)
        Xs, lams, Us, res, lres = (ca.horzcat(*a) for a in (Xs, lams, Us, res, lres))
        zN, lamN = self.terminal_residual(Xs[:, -1], Xd), lams[:, -1]
        names_in = ["lam0", "X0", "Xd", "h", "Winv", "bd"]
        args = [lam0, X0, Xd, h, Winv, bd]
        self.shoot = ca.Function(
            f"{sch}_shoot{N}",
            args,
            [zN, Xs, lams, Us, res, lres],
            names_in,
            ["zN", "X", "lam", "U", "res", "lam_res"],
        )
        res_max = ca.mmax(res)
        self.residual = ca.Function(f"{sch}_shoot_residual{N}", args, [zN, lamN, res_max], names_in,
                                    ["zN", "lamN", "res_max"])
        # Psi = dzN/dlam0 by the linearized coupled recursion along the same rollout (tangent coordinates,
        # see linearization_functions): the same derivative as forward AD through the rollout, cheaper
        if sch == "first_order":   # first step: dz_1 = B du_1, du_1 = -(1/h) D_1 Winv B^T dlambda_0
            dZ = ca.mtimes(Bc, ca.mtimes(D_first, -ca.mtimes(Winv, Bc.T) / h))
        else:
            dZ = ca.MX.zeros(NZ, NZ)
        dlamN = ca.MX.eye(NZ)
        if n > 0:
            Xk = ca.horzcat(Xstart, Xr[:, :n - 1])         # X_k, lambda_{k-1}, lambda_k of the steps
            Lprev = ca.horzcat(lam0, Lr[:, :n - 1])
            # D of the control each step's A_k is taken at (lgvi: u_k) and of the one it determines (u_{k+1})
            Dk = ca.horzcat(D_first, Dr[:, :NU * (n - 1)])
            hs, Ws = ca.repmat(h, 1, n), ca.repmat(Winv, 1, n)
            Hk = hess_map.map(f"{sch}_costate_hessian_map{n}", "serial", n, [4, 5, 6], [])(Xk, Lprev, Lr, Cr, h, Winv,
                                                                                            bd)
            dZs, dlams = lin_map.mapaccum(f"{sch}_linearized_acc{n}", n, 2, MAPACCUM_OPTS)(
                dZ, ca.MX.eye(NZ), Ar, Hk, Dk, Dr, hs, Ws)
            dZ, dlamN = dZs[:, -NZ:], dlams[:, -NZ:]
        zL, JT = terminal_residual_jacobian()(Xs[:, -1], Xd)
        self.shoot_jac = ca.Function(f"{sch}_shoot_jac{N}", args, [zL, ca.mtimes(JT, dZ), dlamN], names_in,
                                     ["zN", "Psi", "dlamN"])


@lru_cache(maxsize=None)
def shooting_functions(disc: Discretization, N: int, jit: bool = False) -> ShootingFunctions:
    """Cached :class:`ShootingFunctions` (one per Discretization object, N and jit)."""
    return ShootingFunctions(disc, N, jit)


@lru_cache(maxsize=None)
def time_gradient_function(disc: Discretization, N: int) -> ca.Function:
    """``{scheme}_step_time_derivative{N}`` (X[18 x N], W[nw x N], lam[12 x N], h) -> g[1 x N]: the derivative
    of each step's constraint term of the Lagrangian by the step size at fixed states, controls and multipliers,

        g_k = lambda_k^T readback_{X_{k+1}}(d step(X_k, w_k, h) / dh),

    X_k the node states 0..N-1, w_k the stage controls, lambda_k the multiplier of step k (the free-final-
    time condition, docs/mathematics.md §10).  Forward AD through the step (its unrolled Cayley Newton
    iterations, converged to round-off)."""
    X, w, lam, h = ca.SX.sym("X", NX), ca.SX.sym("w", disc.nw), ca.SX.sym("lam", NZ), ca.SX.sym("h")
    X1 = disc.step(X, w, h)[0]
    g = ca.dot(lam, tangent_readback(X1, ca.jacobian(X1, h)))
    f = ca.Function(f"{disc.scheme}_step_time_derivative", [X, w, lam, h], [g], ["X", "w", "lam", "h"], ["g"])
    return f.map(f"{disc.scheme}_step_time_derivative{N}", "serial", N, [3], [])


# ------------------------------------------------------------------------- helpers
def weight_inverse(problem: Problem) -> np.ndarray:
    """blkdiag(W_f, W_m)^-1 (6x6) of a smooth-control problem."""
    return np.linalg.inv(problem.control.W)


def control_cost(problem: Problem, U: np.ndarray, h: float | None = None) -> float:
    """The effort cost of controls U (6 x n_controls) with the quadrature weights of the scheme at step
    size h (default: the problem's)."""
    return effort_cost(U, problem.control, quadrature_weights(problem.scheme, problem.N, problem.h if h is None else h))


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


def free_rows(target: TargetState) -> np.ndarray:
    """Boolean (12): the rows of z_N (tangent coordinates [dx; dgamma; zeta; dPi]) of the free terminal
    components, where the shooting residual is lambda_{N-1} instead (stationarity in z_N, docs/mathematics.md §10)."""
    return np.repeat([c in target.free for c in STATE_COMPONENTS], 3)


def bounded(bd: np.ndarray) -> bool:
    """Whether bound data bd bounds a control (a removed control, b = 0, is structure, not a bound)."""
    box = bd[:NU]
    return bool(np.any(np.isfinite(box) & (box > 0)) or np.any(bd[NU:] < NO_NORM))


#: bound continuation (indirect method from lambda_0 = 0): the stages of the bounds' geometric path from
#: the unbounded peak to the given bounds, tried when the step from the unbounded solution fails
CONTINUATION_STAGES = 4


def _bound_continuation(newton, lam, bd, fns, args) -> tuple[Any, list[str]]:
    """Newton from lambda_0 = 0 on the unbounded problem (removed controls stay removed), then on the
    bounded one from its solution; if that fails, along CONTINUATION_STAGES bounds shrinking
    geometrically from the unbounded controls' peaks to bd.  A semismooth Newton method converges
    locally; this brings it there.  Returns the last stage's NewtonResult (its history and iteration
    count those of all stages) and a line per stage."""
    free_bd = np.r_[np.where(bd[:NU] == 0, 0.0, np.inf), NO_NORM, NO_NORM]
    first = newton(lam, free_bd, "unbounded")
    history, iters, stages = list(first.history), first.iterations, [f"unbounded: {first.result.value} in "
                                                                      f"{first.iterations} iterations"]
    if not first.result.successful:
        first.message = f"the unbounded first stage of the bound continuation: {first.message}"
        return first, stages
    U = np.array(fns.shoot(first.x, *args, free_bd)[3])
    peak = np.r_[np.abs(U).max(axis=1), [np.linalg.norm(U[sl], axis=0).max() ** 2 for sl in (U_FORCE, U_MOMENT)]]
    paths = [[1.0], [(j + 1) / CONTINUATION_STAGES for j in range(CONTINUATION_STAGES)]]
    for path in paths:
        x, ok = first.x, True
        for t in path:
            # bounds at fraction t of the way (geometrically) from max(peak, bound) down to the bound
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(np.isfinite(bd) & (bd > 0) & (bd < NO_NORM), np.maximum(peak / bd, 1.0), 1.0)
            stage_bd = np.where(ratio > 1.0, bd * ratio ** (1.0 - t), bd)
            nr = newton(x, stage_bd, f"bounds {t:.2g}")
            history += nr.history
            iters += nr.iterations
            stages.append(f"bounds at {t:.2g} of the way: {nr.result.value} in {nr.iterations} iterations")
            x, ok = nr.x, nr.result.successful
            if not ok:
                break
        if ok:
            break
    nr.history, nr.iterations = history, iters
    return nr, stages


#: free final time (indirect): outer iterations on the step size, and their relative step tolerance
FREE_TIME_MAX_OUTER = 30
FREE_TIME_RTOL = 1e-11


def _free_final_time(solve_at, dL_dh, lam, h, lo, hi, N) -> tuple[Any, float, dict]:
    """The free-final-time condition: the step size h in [lo, hi] with dJ*/dh = dL/dh = 0 (or at a bound
    with dL/dh pointing out of the interval), by a safeguarded secant iteration on the scalar g(h) = dL/dh,
    each g from a fixed-h shooting solved from the previous lambda_0.

    Secant steps keep inside the bracket of a sign change once one is known (bisection when a secant step
    leaves it); before that they are clipped to [lo, hi], and a bound where g keeps its sign is the
    answer.  Stops when the step is below FREE_TIME_RTOL h.  Returns (the NewtonResult at the final h
    -- its history and iterations those of every inner solve --, h, a summary for the stats)."""
    history, iters, evals = [], 0, []

    def at(h, lam, first=False):
        nr = solve_at(lam, h, first, f"T = {N * h:.10g}: ")
        nonlocal iters
        history.extend(nr.history)
        iters += nr.iterations
        g = dL_dh(nr.x, h) if nr.result.successful else np.nan
        evals.append((float(N * h), float(g)))
        return nr, g

    def done(nr, h, converged, message):
        nr.history, nr.iterations = history, iters
        return nr, h, {"converged": converged, "T": N * h, "dL_dh": evals[-1][1], "evaluations": evals,
                       "message": message}

    h = min(max(h, lo), hi)
    nr, g = at(h, lam, first=True)
    below, above = (lo, None), (hi, None)          # the bracket: g < 0 at below, g > 0 at above
    prev = None
    for _ in range(FREE_TIME_MAX_OUTER):
        if not nr.result.successful:
            return done(nr, h, False, f"free final time: the shooting at T = {N * h:.10g} failed")
        if g == 0.0:
            return done(nr, h, True, f"free final time T = {N * h:.12g} (dL/dh = 0)")
        if g < 0:
            below = (h, g)
        else:
            above = (h, g)
        if (g < 0 and h >= hi) or (g > 0 and h <= lo):
            return done(nr, h, True, f"free final time at its bound T = {N * h:.12g} (dL/dh = {g:.3e} points "
                                     "out of the interval)")
        if prev is None:    # a first secant point: a small step downhill
            cand = h * (1.0 - 1e-3 * np.sign(g))
        else:
            hp, gp = prev
            cand = h - g * (h - hp) / (g - gp) if g != gp else np.nan
        a, b = below[0], above[0]
        if below[1] is not None and above[1] is not None:
            if not (min(a, b) < cand < max(a, b)):
                cand = 0.5 * (a + b)
        elif not np.isfinite(cand):
            cand = hi if g < 0 else lo
        cand = min(max(cand, lo), hi)
        step = abs(cand - h)
        prev = (h, g)
        nr, g = at(cand, nr.x)
        h = cand
        if step <= FREE_TIME_RTOL * h and nr.result.successful:
            return done(nr, h, True, f"free final time T = {N * h:.12g} (dL/dh = {g:.3e}, last step "
                                     f"{step / h:.1e} h, {len(evals)} shootings)")
    return done(nr, h, False, f"free final time: no convergence in {FREE_TIME_MAX_OUTER} outer iterations "
                              f"(T = {N * h:.12g}, dL/dh = {g:.3e})")


def not_covered(problem: Problem) -> str:
    """What of a smooth-control problem the indirect method does not cover ('' if nothing): its
    necessary conditions are those of the effort objective to a state target (free components by
    transversality), with box or norm bounds whose saturation is the Hamiltonian's minimizer -- a box
    on a block with a diagonal weight, a norm bound on one with an isotropic weight."""
    c = problem.control
    reasons = []
    if c.objective != "effort":
        reasons.append(f"the {c.objective} objective")
    if problem.constraints:
        reasons.append("path constraints")
    if not isinstance(problem.terminal, TargetState):
        reasons.append("an orbit target")
    for name, W, bound in (("force", c.W_f, c.force_bound), ("moment", c.W_m, c.moment_bound)):
        if isinstance(bound, BoxBound) and np.count_nonzero(W - np.diag(np.diag(W))):
            reasons.append(f"a box bound on the {name} with a non-diagonal weight")
        if isinstance(bound, NormBound) and bound.b > 0 and not np.allclose(W, W[0, 0] * np.eye(3), rtol=1e-14, atol=0):
            reasons.append(f"a norm bound on the {name} with a weight that is not a multiple of the identity")
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
    """Newton-Armijo shooting on lambda_0 (docs/mathematics.md §6, §10) for a smooth-control effort
    problem with a state target ('first_order' or 'lgvi'; for 'lgvi' the unknown is lambda_{-1}, see
    LGVI_CONDITIONS); problems it does not cover (:func:`not_covered`) return Result.not_applicable.

    Beyond the paper: control bounds (the control minimizes the discrete Hamiltonian over them,
    :func:`saturate`; Newton differentiates through the saturation -- a semismooth Newton method --
    and from lambda_0 = 0 it first solves the unbounded problem, :func:`_bound_continuation`); free
    terminal components (lambda_{N-1} = 0 on them, :func:`free_rows`); a free final time (the
    condition dL/dh = 0 by a secant iteration over fixed-T shootings, :func:`_free_final_time`).

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
    X0, Xd, Winv, bd = problem.X0, problem.terminal.X, weight_inverse(problem), bound_data(problem)
    free = free_rows(problem.terminal)
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

    def newton(lam, bd_stage, phase="", h=h):
        def residual(l):
            # the given terminal components, and lambda_{N-1} = 0 on the free ones (transversality)
            z, lamN, r = fns.residual(l, X0, Xd, h, Winv, bd_stage)
            return np.where(free, np.array(lamN).ravel(), np.array(z).ravel()), float(r)

        def jacobian(l):
            # Psi only: z always comes from ``residual`` (one rounding for all comparisons)
            _, Psi, dlamN = fns.shoot_jac(l, X0, Xd, h, Winv, bd_stage)
            return np.where(free[:, None], np.array(dlamN), np.array(Psi))

        tagged = (lambda it: progress(dataclasses.replace(it, phase=phase))) if progress and phase else progress
        nr = newton_armijo(lam, residual, jacobian, tol=opts.eps_S, alpha=opts.alpha, max_iter=opts.max_iter,
                           max_halvings=opts.max_halvings, aux_tol=opts.cayley_tol, floor_factor=opts.floor_factor,
                           floor_accept=opts.floor_accept, progress=tagged)
        if phase:
            nr.history = [dataclasses.replace(it, phase=phase) for it in nr.history]
        return nr

    def solve_at(lam, h, first, phase=""):
        """The fixed-step problem at h from lam; from lambda_0 = 0 with bounds, by the bound continuation."""
        if first and source == "zero" and bounded(bd):
            nr, stages = _bound_continuation(lambda l, b, ph: newton(l, b, f"{phase}{ph}", h), lam, bd, fns,
                                             (X0, Xd, h, Winv))
            stats["bound_continuation"] = stages
            return nr
        return newton(lam, bd, phase, h)

    r0 = float(fns.residual(lam, X0, Xd, h, Winv, bd)[2])
    if not r0 <= opts.cayley_tol:
        return _failure(problem, Result.invalid_option,
                        f"the rollout from the initial lambda_0 does not solve the Cayley equation (residual {r0:.1e} > "
                        f"cayley_tol {opts.cayley_tol:.0e}): the rotation per step is too large; use a smaller step "
                        f"h = T/N (increase horizon.N) or another initial costate", build_s)
    if problem.free_time:
        tg = time_gradient_function(disc, N)

        def dL_dh(lam, h):
            """dJ*/dh = dL/dh at the solution (envelope theorem): J/h (the weights are proportional to h)
            plus the steps' terms (:func:`time_gradient_function`)."""
            _, Xs, lams, U, _, _ = (np.array(a) for a in fns.shoot(lam, X0, Xd, h, Winv, bd))
            Xk = np.column_stack([X0, Xs[:, :-1]])
            return control_cost(problem, U, h) / h + float(np.sum(np.array(tg(Xk, disc.stage_controls(U), lams, h))))

        lo, hi = (t / N for t in problem.time_bounds)
        nr, h, outer = _free_final_time(solve_at, dL_dh, lam, h, lo, hi, N)
        stats["free_time"] = outer
    else:
        nr = solve_at(lam, h, True)
    lam = nr.x
    # final rollout: controls and costates from lambda_0, re-simulated trajectory
    _, _, lams, U, _, lres = fns.shoot(lam, X0, Xd, h, Winv, bd)
    U = np.array(U)
    lams = np.array(lams).T
    Xsim, res = disc.simulate(X0, U, h, N)
    solve_s = time.perf_counter() - t1
    finite = bool(np.all(np.isfinite(Xsim)))
    result, message = nr.result, nr.message.replace("|F|", "|z_N|").replace(" x ", " lambda_0 ")
    if "bound_continuation" in stats:
        message += f" (bound continuation from lambda_0 = 0: {'; '.join(stats['bound_continuation'])})"
    if "free_time" in stats:
        message += f"; {stats['free_time']['message']}"
        if result.successful and not stats["free_time"]["converged"]:
            result = Result.max_iterations
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
                    cost=control_cost(problem, U, h) if np.all(np.isfinite(U)) else float("inf"),
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
