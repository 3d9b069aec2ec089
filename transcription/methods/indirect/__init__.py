"""Indirect method: discrete necessary conditions and Newton-Armijo shooting (docs/mathematics.md §6).

Scheme: the first-order modified scheme (docs/mathematics.md §3), ``X_{k+1} = step(X_k, u_{k+1}, h)``, or the LGVI
(§2).  States X (18) as in :mod:`transcription.geometry.state`; u = [u_f (inertial); u_m (body)]; tangent
coordinates z = [dx; dgamma; zeta; dPi] with dR = R S(zeta) (§4).  With the defect written as step ⊖ X_{k+1},

    L = sum_k [ (h/2) u_{k+1}^T W u_{k+1} + lambda_k^T ( step(X_k, u_{k+1}) ⊖ X_{k+1} ) ],   W = blkdiag(W_f, W_m),

stationarity gives u_{k+1} = -(1/h) W^-1 B_k^T lambda_k (eqs. 26-27; B_k from the graph) and lambda_{k-1} =
A_k^T lambda_k (eq. 28).  A_k does not depend on u_{k+1} (checked when the Functions are built), so the recursion
runs forward: lambda_k = A_k^-T lambda_{k-1}, u_{k+1} from lambda_k, X_{k+1} = step(X_k, u_{k+1}, h).  The unknown
is lambda_0 (12; LGVI: lambda_{-1} = A_0^T lambda_0, :data:`.conditions.LGVI_CONDITIONS`); the residual is

    z_N(lambda_0) = [x_N - x_d; gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d],

and Psi = dz_N/dlambda_0 (eqs. 29-31) is exact: the linearized recursion along the rollout
(:func:`.linearization.linearization_functions`).

Per-step Functions, built once per Discretization (compiled to C by default, IndirectOptions.jit):

    costate_map      (X[18], lam_prev[12], h, Winv[6x6]) -> (X1[18], lam[12], u[6], res, lam_res, A, c)
    first_step       (X0[18], lam0[12], h, Winv[6x6])    -> (X1[18], u[6], res)
    costate_hessian  (X, lam_prev, lam, c, h, Winv)      -> H[12x12]
    linearized_map   (dZ[12x12], dlam[12x12], A, H, h, Winv) -> (dZ1, dlam1)

and once per (Discretization, N) (:func:`.shooting.shooting_functions`):

    shoot        (lam0, X0, Xd, h, Winv) -> (zN[12], X[18xN], lam[12xN], U[6xN], res, lam_res)
    residual     (lam0, X0, Xd, h, Winv) -> (zN[12], res_max)
    shoot_jac    (lam0, X0, Xd, h, Winv) -> (zN[12], Psi[12x12])

Winv = blkdiag(W_f, W_m)^-1; X0, Xd, h, Winv are inputs, so one build serves every problem with the same scheme,
model and N.  h is the row of step sizes h_k (1 x N; a scalar is broadcast): a non-uniform mesh keeps the
conditions' form (§17).  Newton-Armijo (transcription.methods.newton) runs in :func:`.solve.solve_indirect`.

Body-fixed force (§15): u_f reads R_j^T lambda_gamma, A_k depends on u_{k+1} through the end kick, and the
recursion stays explicit in triangular form; the linearization runs in body-momentum coordinates
(:mod:`.coordinates`); one engine is the clip T = clip(q^T v_f, T_min, T_max) of :func:`.control.saturate`.

Round-off: the rod's tiny J_11 amplifies ulp-level errors of the recursion to ~1e-13..1e-12 of z_N.  A_k^-T by
unpivoted Gaussian elimination (:func:`.elimination.solve_unpivoted`) and R re-orthonormalized in the argument of
A_k (:func:`.conditions.orthonormalized`; floor ~1e-11 -> ~6e-13 at N = 500) keep it there; the floor is measured
(:func:`~transcription.methods.newton.noise_level`) and the iteration stops at it.

Modules: :mod:`.elimination`, :mod:`.control` (the saturated law, bounds as data, the effort cost),
:mod:`.conditions` (the forward map), :mod:`.linearization` (its exact linearization), :mod:`.shooting` (per N),
:mod:`.continuation` (bounds, free final time), :mod:`.coordinates` (body-fixed force), :mod:`.orbit` (orbit
target's transversality, §19), :mod:`.switching` and :mod:`.fuel` (fuel on/off law, homotopy in eps, §19),
:mod:`.objectives` (the time objective, §18), :mod:`.laws` (each objective's conditions), :mod:`.solve`
(:class:`Indirect`, the method).
"""
from __future__ import annotations

from .solve import Indirect, not_covered, solve_indirect

__all__ = ["Indirect", "not_covered", "solve_indirect"]
