"""Optimal impulsive control (docs/mathematics.md §5): impulses at t = 0 and t = T, free motion between.

Unknowns p = (gamma_0^+, Pi_0^+) in R^6 (inertial linear momentum, body angular momentum just
after the initial impulse; this order follows the state layout).  X_0^+ = X0 with its momenta
replaced by p; X_N = free rollout of the problem's discretization (u = 0) from X_0^+; the terminal
impulse brings (gamma_N, Pi_N) to the required (gamma_N^+, Pi_N^+).

Sensitivity (eqs. 18-20): Phi = A_{N-1} ... A_0 (12 x 12) is the product of the left-trivialized
step Jacobians ``disc.variation`` along the rollout; since dgamma_0 and dPi_0 are additive tangent
directions, dz_N/dp = Phi[:, (gamma, Pi) columns].  :func:`.sensitivity.sensitivity` builds Phi that way;
:func:`.sensitivity.sensitivity_ad` differentiates the whole rollout composed with the chart at X_0 and reads
back at X_N (a second AD route, for the tests).

* TPBVP (a state target, E1): the six conditions r(p) = [x_N - x_d; vee log(R_d^T R_N)] = 0 are
  solved by the shared Newton-Armijo (transcription.methods.newton); the Jacobian is
  [Phi_xp; Jr^-1(vee log(R_d^T R_N)) Phi_zeta p] (Jr^-1 the inverse right Jacobian of SO(3), exact
  for the log residual).  The impulses follow: gamma_N^+ = gamma_d, Pi_N^+ = Pi_d.  There is
  nothing left to optimize: the six conditions fix p (a Lambert problem on SE(3)).
* Relaxed (an orbit target, E2): the four terminal conditions C = 0 of
  :func:`~transcription.ocp.orbit_conditions`, the post-impulse momenta they require, and the
  cost sum_i |v_i| of the four impulses written directly, from a feasible start
  (:func:`.relaxed.relaxed_start`: a TPBVP to a point of the target set).  Two transcriptions
  (``DirectOptions.transcription``):

  - ``single_shooting`` (default; the paper's formulation): the six unknowns p, X_N(p) by the free
    rollout, four constraints.  :class:`.reduced.ReducedRelaxed` gives exact derivatives: dX_N/dp by the
    forward sweep of the step Jacobians (Phi, in ambient coordinates) and the Hessian of the
    Lagrangian by the second-order adjoint sweep; the per-step Functions are compiled to C
    (``jit``).  :func:`.reduced.relaxed_reduced` is Newton's method on the constraint manifold (a
    feasible-point SQP: null-space Newton step, projection back onto C = 0, Armijo on the cost).
    A plain SQP with an l1 merit function crawled (see there): the terminal conditions are
    strongly curved in p.  At N = 800 it takes 6 iterations (22 rollouts) against IPOPT's 127 on the multiple-shooting NLP below.
  - ``multiple_shooting``: the NLP of the one builder (transcription.nlp) -- the dynamics blocks
    with u = 0, x_0 and R_0 fixed, (gamma_0, Pi_0) free -- solved by IPOPT with the exact Hessian.
    An independent formulation of the same problem (the tests compare the two optima).  Along the
    spin about the dumbbell's axis the cost is nearly flat (reduced curvature 5e-5 .. 1e-3 in scaled
    units) with several minima: at N = 400 single shooting stops at 2.51878 and multiple shooting
    at 2.47736 from the same start (both are local minima; at N = 100 and 800 the two agree).

  Why no epigraph: the sum of norms is smooth wherever every impulse is nonzero, and at this
  optimum all four are (the solve reports ``min_impulse_norm``; a value near 0 means the optimum
  sits on a kink: Result.kink).  Both smooth epigraphs were tried, |v|^2 <= s^2 and the convex
  perspective form |v|^2/s <= s with s >= 0: IPOPT converged to ~1e-6 and then, when the barrier
  parameter fell, took a huge step along the nearly flat direction of the spin about the
  dumbbell's axis (the cost is invariant to its phase; its curvature is ~1e-5 in scaled units)
  and ended in restoration failure, at N = 100 and N = 800 and with several option sets.
  :func:`.relaxed.relaxed_jacobian` gives the Phi-based gradient dC/dp, used by the tests to check the
  reduced KKT conditions of the returned solution.

Options: the direct method's (:class:`~transcription.options.DirectOptions`): ``transcription`` (relaxed); ``tol``,
``max_iter`` (single shooting: the scaled reduced gradient and the iteration limit; multiple shooting: IPOPT's;
``max_iter`` also bounds the TPBVP's Newton iterations, at most newton_max_iter); ``options`` (raw IPOPT options,
multiple shooting); ``jit``; ``initial_guess`` 'rollout' (no impulse) or 'interpolate' (Pi_0^+ = J log(R_0^T R_d)/T)
for the TPBVP, which restarts from the other guess if Newton fails from the first; ``terminal_tol`` the largest
max |C| of a converged relaxed solve.  Numerical parameters: :class:`ImpulsiveSettings`, a field of :class:`Impulsive`.

Modules: :mod:`.sensitivity` (Phi), :mod:`.tpbvp` (the state target), :mod:`.relaxed` (the orbit target's start,
gradient and multiple-shooting NLP), :mod:`.reduced` (its single shooting), :mod:`.solve` (the solve; :class:`Impulsive`,
the method).
"""
from __future__ import annotations

from .solve import Impulsive, ImpulsiveSettings, not_covered, solve_impulsive

__all__ = ["Impulsive", "ImpulsiveSettings", "not_covered", "solve_impulsive"]
