"""The direct method: the discrete equations stacked into a multiple-shooting NLP (docs/mathematics.md §6-§7).

Smooth control (effort objective)::

    min  sum_j omega_j (1/2) u_j^T W u_j,        W = blkdiag(W_f, W_m)
    s.t. X_{k+1} = step(X_k, w_k, h),   k = 0..N-1   (eqs. 7-11 or 21-25)
         X_0 = X0,   terminal_residual(X_N) = 0     (the fixed components of the target)

with the quadrature weights of :func:`~transcription.ocp.quadrature_weights`; the time and fuel
objectives, bounds and path constraints (§10) are blocks of the same NLP.  Impulsive control is the
impulsive method's (:mod:`transcription.methods.impulsive`).

Modules: :mod:`.scaling` (characteristic scales), :mod:`.transcription` (the NLP, costates from the
multipliers), :mod:`.plan` (the initial guesses and what to try after a failure), :mod:`.solution` (the
Solution of a finished NLP solve), :mod:`.fatrop` (the stage-ordered NLP for fatrop), :mod:`.solve` (the
solve; :data:`DIRECT`, the method).
"""
from __future__ import annotations

from ...options import DirectOptions
from ..base import Implementation
from .solve import not_covered, solve_direct

#: the direct method on smooth control (a :class:`~transcription.methods.base.Method`)
DIRECT = Implementation("direct", "smooth", DirectOptions, solve_direct, not_covered)

__all__ = ["DIRECT", "not_covered", "solve_direct"]
