"""The direct method: the discrete equations stacked into a multiple-shooting NLP (docs/mathematics.md §6-§7).

Smooth control (effort objective)::

    min  sum_j omega_j (1/2) u_j^T W u_j,        W = blkdiag(W_f, W_m)
    s.t. X_{k+1} = step(X_k, w_k, h),   k = 0..N-1   (eqs. 7-11 or 21-25)
         X_0 = X0,   terminal_residual(X_N) = 0     (the fixed components of the target)

with the quadrature weights of :func:`~transcription.ocp.quadrature_weights`; the time and fuel
objectives, bounds and path constraints (§10) are blocks of the same NLP.  Impulsive control is the
impulsive method's (:mod:`transcription.methods.impulsive`).

The NLP itself is :mod:`transcription.nlp.transcription`; here are the solve (:mod:`.solve`: :class:`Direct`, one
NLP solve), the Solution of a finished NLP solve (:mod:`.solution`) and fatrop's stage-ordered form (:mod:`.fatrop`).
Which starts to try is the strategy's (:mod:`transcription.strategy`).
"""
from __future__ import annotations

from .solve import Direct, transcription

__all__ = ["Direct", "transcription"]
