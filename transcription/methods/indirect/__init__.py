"""Indirect method: discrete necessary conditions and Newton-Armijo shooting (docs/mathematics.md §6).

For the first-order scheme (§3) X_{k+1} = step(X_k, u_{k+1}, h), stationarity of L = sum_k [(h/2) u_{k+1}^T W u_{k+1} +
lambda_k^T (step(X_k, u_{k+1}) ⊖ X_{k+1})] gives u_{k+1} = -(1/h) W^-1 B_k^T lambda_k and lambda_{k-1} = A_k^T lambda_k
(eqs. 26-28; the LGVI (§2): §6), run forward from the unknown lambda_0 (12); the residual z_N(lambda_0) = [x_N - x_d;
gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d] and its exact Jacobian Psi = dz_N/dlambda_0 (eqs. 29-31) drive
Newton-Armijo (transcription.methods.newton), which stops at the measured round-off floor.  Per-step Functions are built
once per Discretization, the shooting Functions once per (Discretization, N); X0, Xd, h (1 x N) and W^-1 are inputs.
Body-fixed force: §15; non-uniform mesh: §17; time objective: §18; orbit target and fuel: §19.

Modules: :mod:`.elimination` (unpivoted A_k^-T), :mod:`.control` (the saturated law, bounds as data, the effort cost),
:mod:`.conditions` (the forward map), :mod:`.linearization` (its exact linearization), :mod:`.shooting` (per N),
:mod:`.continuation` (bounds, free final time), :mod:`.coordinates` (body-fixed force), :mod:`.orbit` (orbit target's
transversality), :mod:`.switching` and :mod:`.fuel` (fuel on/off law, homotopy in eps), :mod:`.objectives` (the time
objective), :mod:`.laws` (each objective's conditions), :mod:`.structured` (fuel with its switching structure fixed),
:mod:`.solve` (:class:`Indirect`, the method).
"""
from __future__ import annotations

from .solve import Indirect, not_covered, solve_indirect

__all__ = ["Indirect", "not_covered", "solve_indirect"]
