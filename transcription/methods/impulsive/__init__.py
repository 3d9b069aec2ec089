"""Optimal impulsive control (docs/mathematics.md §5): impulses at t = 0 and t = T, free motion between.

Unknowns p = (gamma_0^+, Pi_0^+) in R^6 (inertial linear, body angular momentum after the first impulse);
X_N is the free rollout (u = 0) from X0 with momenta p; dz_N/dp = Phi[:, (gamma, Pi) columns], Phi = A_{N-1} ...
A_0 (eqs. 18-20).  A state target (E1) is a TPBVP r(p) = [x_N - x_d; vee log(R_d^T R_N)] = 0 solved by
Newton-Armijo; an orbit target (E2) minimizes the sum of the four impulse norms subject to the terminal conditions
C = 0 of :func:`~transcription.ocp.orbit_conditions`, from a feasible start, by single shooting (default: a
feasible-point SQP with exact derivatives) or by the multiple-shooting NLP of transcription.nlp under IPOPT
(``DirectOptions.transcription``).  Why the sum of norms without an epigraph: §5.  Options: the direct method's
(:class:`~transcription.options.DirectOptions`); numerical parameters: :class:`ImpulsiveSettings`.

Modules: :mod:`.sensitivity` (Phi, by the step Jacobians and by AD), :mod:`.tpbvp` (the state target),
:mod:`.relaxed` (the orbit target's start, gradient dC/dp and multiple-shooting NLP), :mod:`.reduced` (its single
shooting), :mod:`.solve` (the solve; :class:`Impulsive`, the method).
"""
from __future__ import annotations

from .solve import Impulsive, ImpulsiveSettings, not_covered, solve_impulsive

__all__ = ["Impulsive", "ImpulsiveSettings", "not_covered", "solve_impulsive"]
