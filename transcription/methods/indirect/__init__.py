"""Indirect method: discrete necessary conditions and Newton-Armijo shooting (docs/mathematics.md §6).

Scheme: the first-order modified scheme of docs/mathematics.md §3, eqs. (21)-(25), one control
per step, ``X_{k+1} = step(X_k, u_{k+1}, h)``, k = 0 .. N-1 (the second-order LGVI
is also supported, see the end of this docstring).  States X (18) in the
layout of :mod:`transcription.geometry.state`; controls u = [u_f (inertial); u_m (body)];
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
rollout (:func:`.linearization.linearization_functions`; equal to forward-mode AD through the rollout).

Per-step Functions, built once per Discretization (compiled to C by default, IndirectOptions.jit):

    costate_map      (X[18], lam_prev[12], h, Winv[6x6]) -> (X1[18], lam[12], u[6], res, lam_res, A, c)
    first_step       (X0[18], lam0[12], h, Winv[6x6])    -> (X1[18], u[6], res)
    costate_hessian  (X, lam_prev, lam, c, h, Winv)      -> H[12x12]
    linearized_map   (dZ[12x12], dlam[12x12], A, H, h, Winv) -> (dZ1, dlam1)

and once per (Discretization, N) (see :func:`.shooting.shooting_functions`):

    shoot        (lam0, X0, Xd, h, Winv) -> (zN[12], X[18xN], lam[12xN], U[6xN], res, lam_res)
    residual     (lam0, X0, Xd, h, Winv) -> (zN[12], res_max)
    shoot_jac    (lam0, X0, Xd, h, Winv) -> (zN[12], Psi[12x12])

Winv = blkdiag(W_f, W_m)^-1; X0, Xd, h, Winv are inputs, so one build serves
every problem with the same scheme, model and N.  In the per-N Functions h is the row of step sizes h_k
(1 x N; a scalar is broadcast): on a non-uniform mesh step k runs at its own h_k, and the conditions keep
their form (docs/mathematics.md §17: the per-step quadrature meets the steps' kicks, so u = -W^-1 E^T lambda).

Newton-Armijo (transcription.methods.newton, shared with the impulsive TPBVP) runs in :func:`.solve.solve_indirect`.

Second-order LGVI (beyond the paper)
------------------------------------
For the scheme of docs/mathematics.md §2 (node controls u_0..u_N, trapezoidal cost weights) the
same Lagrangian gives explicit conditions too, because u_k enters step k as a
momentum kick: u_j = -W^-1 [lambda^2_{j-1}; lambda^4_{j-1}] for j = 0..N with
lambda_{-1} = A_0^T lambda_0, and lambda_k = A_k(X_k, u_k)^-T lambda_{k-1}.  The
shooting unknown is then lambda_{-1}; see :data:`.conditions.LGVI_CONDITIONS`.

Body-fixed force (docs/mathematics.md §15)
-------------------------------------------
With ``force_frame = 'body'`` the control at node j applies R_j u_{f,j}: u_f reads R_j^T lambda_gamma, A_k
depends on u_{k+1} through the end kick, and the recursion stays explicit in triangular form
(mu_k = Abar_k^-T lambda_{k-1}, u_{k+1} at R_{k+1}, then lambda_k's zeta block corrected); the linearization
runs in body-momentum coordinates (:mod:`.coordinates`).  One body-fixed engine (ThrusterBound) is the clip
T = clip(q^T v_f, T_min, T_max) of :func:`.control.saturate`.

Round-off
---------
Forward costate shooting amplifies rounding: on E3/E4 the rod-axis rotation (tiny
J_11) turns ulp-level errors of the recursion into ~1e-13..1e-12 of z_N.  Two
measures keep the floor there: A_k^-T by Gaussian elimination
(:func:`.elimination.solve_unpivoted`; CasADi's symbolic QR gave a floor ~1e-10 at N = 100) and
R re-orthonormalized in the argument of A_k (:func:`.conditions.orthonormalized`; without it
the floor was ~1e-11 at N = 500, with it ~6e-13).  The floor is *measured*
(:func:`~transcription.methods.newton.noise_level`), and the iteration stops there at once.

Modules: :mod:`.elimination` (unpivoted Gaussian elimination), :mod:`.control` (the saturated control law,
the bounds as data, the effort cost), :mod:`.conditions` (the forward map of the necessary conditions),
:mod:`.linearization` (its exact linearization), :mod:`.shooting` (the shooting Functions per N),
:mod:`.continuation` (bound continuation, free final time), :mod:`.coordinates` (the body-fixed force),
:mod:`.orbit` (an orbit target's transversality conditions, docs/mathematics.md §19), :mod:`.switching` and :mod:`.fuel`
(the fuel objective's on/off law and its homotopy in eps, §19),
:mod:`.laws` (each objective's conditions), :mod:`.solve` (the solve; :class:`Indirect`, the method).

The time objective (docs/mathematics.md §18): :mod:`.objectives` -- the switching function, the Hamiltonian's
minimizer over the bounds, and min T + eps (effort) with the saturated law above, Newton on (lambda_0, h).
"""
from __future__ import annotations

from .solve import Indirect, not_covered, solve_indirect

__all__ = ["Indirect", "not_covered", "solve_indirect"]
