"""Adaptive (non-uniform) meshes for refinement to a tolerance (issue 26, docs/mathematics.md §16).

Two pieces, used by :func:`transcription.accuracy.refine`:

* :func:`step_errors` -- the local error of every step of a plan, by step doubling with the plan's own scheme:
  step k from the plan's node X_k is taken again as two half steps of size h_k / 2 with the controls the
  continuous flight applies (the LGVI's node controls interpolated linearly, u_{k+1/2} = (u_k + u_{k+1}) / 2;
  the first-order control u_{k+1} held), and the difference to the plan's X_{k+1} is measured in the units of
  the continuous miss (position / L, velocity / V, attitude angle, rate).  With a local error C_k h_k^{p+1}
  (p the scheme's order) that difference is C_k h_k^{p+1} (1 - 2^-p), so e_k = difference / (1 - 2^-p).
* :func:`equidistributed_steps` -- the new step sizes: with the error density C(t) = e_k / h_k^{p+1} piecewise
  constant over the old steps, sum_k C_k h_k^{p+1} is least for a given number of steps when the steps are
  h(t) = a C(t)^(-1/p), i.e. when every step's error per unit time is the same (equidistribution); then
  sum_k e_k = a^p T, and a is chosen for the sum asked.  The node density 1/h(t) is bounded per level to at
  most GROWTH times the old one and at least 1/MERGE of it (a step may be split into up to GROWTH, and up to
  MERGE steps merged), and each step's density is the largest of its own and its neighbours' (a margin where
  the error changes fast).
"""
from __future__ import annotations

import numpy as np

from .layout import NZ, unpack_states
from .lie import log_so3_batch

#: per level, a step is split into at most GROWTH steps and at most MERGE steps are merged into one
GROWTH, MERGE = 32.0, 4.0


def local_errors(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, order: int) -> np.ndarray:
    """The local error z_k (N, 12) of each step of the plan X (N+1, 18), controls U (6, n_controls), step sizes
    ``steps`` (N,), by step doubling (module docstring), in the tangent coordinates [dx; dgamma; zeta; dPi] at
    X_{k+1} (transcription.layout.tangent_basis): two half steps minus the plan's step, over (1 - 2^-p)."""
    disc, N = problem.disc, len(steps)
    W = np.asarray(disc.stage_controls(U), dtype=float)
    if disc.scheme == "lgvi":
        nu = W.shape[0] // 2
        mid = 0.5 * (W[:nu] + W[nu:])
        Wa, Wb = np.vstack([W[:nu], mid]), np.vstack([mid, W[nu:]])
    else:
        Wa = Wb = W
    F = disc.step.map(N)
    half = 0.5 * np.asarray(steps, dtype=float)[None, :]
    X1, _ = F(X[:-1].T, Wa, half)
    X2, _ = F(X1, Wb, half)
    a, b = unpack_states(X[1:]), unpack_states(np.asarray(X2.full()).T)
    zeta = log_so3_batch(np.einsum("kji,kjl->kil", a.R, b.R))
    return np.hstack([b.x - a.x, b.gamma - a.gamma, zeta, b.Pi - a.Pi]) / (1.0 - 2.0 ** (-order))


def propagated_errors(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The contribution c_k = A_{N-1} ... A_{k+1} z_k (N, 12) of each step's local error z_k to the error of the
    final node, A_j the step's variation in tangent coordinates (Discretization.variation, docs/mathematics.md §4):
    the linearized global error is sum_k c_k (its terminal miss is what refinement drives below the tolerance)."""
    disc, N = problem.disc, len(steps)
    W = np.asarray(disc.stage_controls(U), dtype=float)
    A, _ = disc.variation.map(N)(X[:-1].T, W, np.asarray(steps, dtype=float)[None, :])
    A = np.asarray(A.full()).reshape(NZ, N, NZ).transpose(1, 0, 2)   # [k, i, j] = A_k[i, j]: (N, 12, 12)
    c = np.empty_like(z)
    P = np.eye(NZ)
    for k in range(N - 1, -1, -1):
        c[k] = P @ z[k]
        P = P @ A[k]
    return c


def tangent_norms(c: np.ndarray, problem, L: float, V: float) -> np.ndarray:
    """max(|dx| / L, |dgamma| / (m V), |zeta|, |J^-1 dPi|) of tangent vectors c (M, 12) -> (M,): the units of the
    continuous miss (transcription.accuracy.scaled_miss)."""
    c = np.atleast_2d(c)
    Jinv = np.linalg.inv(problem.model.inertia)
    return np.max(np.stack([np.linalg.norm(c[:, 0:3], axis=1) / L,
                            np.linalg.norm(c[:, 3:6], axis=1) / (problem.model.mass * V),
                            np.linalg.norm(c[:, 6:9], axis=1), np.linalg.norm(c[:, 9:12] @ Jinv.T, axis=1)]), axis=0)


def error_estimate(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, order: int, L: float,
                   V: float) -> tuple[np.ndarray, float]:
    """(e (N,), predicted): each step's share e_k = |c_k| of the terminal error (:func:`propagated_errors`, in the
    units of :func:`tangent_norms`) and the predicted terminal miss |sum_k c_k|."""
    c = propagated_errors(problem, X, U, steps, local_errors(problem, X, U, steps, order))
    return tangent_norms(c, problem, L, V), float(tangent_norms(c.sum(axis=0), problem, L, V)[0])


def equidistributed_density(steps: np.ndarray, errors: np.ndarray, order: int, total: float) -> np.ndarray:
    """The node density 1/h(t) (N,) on the old steps h (N,) whose local errors, e (N,) now, sum to about ``total``
    equidistributed in time (module docstring; p = ``order``), bounded to [1/MERGE, GROWTH] times the old one."""
    h = np.asarray(steps, dtype=float)
    e = np.asarray(errors, dtype=float)
    T = float(h.sum())
    C = np.where(np.isfinite(e), e, np.nanmax(e, initial=0.0)) / h ** (order + 1)
    C = np.maximum(C, 1e-12 * max(C.max(initial=0.0), 1e-300))
    C = np.max(np.stack([C, np.r_[C[:1], C[:-1]], np.r_[C[1:], C[-1:]]]), axis=0)   # a neighbour's error counts
    a = (max(total, 1e-300) / T) ** (1.0 / order)
    return np.clip(C ** (1.0 / order) / a, 1.0 / (MERGE * h), GROWTH / h)


def density_steps(steps: np.ndarray, density: np.ndarray) -> np.ndarray:
    """New step sizes over the horizon of the old ``steps`` (N,) with the node density ``density`` (N,) (nodes per
    unit time, constant on each old step): the new nodes where its integral passes the integers (rescaled so
    that the last one is the horizon's end, kept exactly)."""
    h = np.asarray(steps, dtype=float)
    phi = np.r_[0.0, np.cumsum(np.asarray(density, dtype=float) * h)]
    n = max(int(np.ceil(phi[-1] - 1e-9)), 1)
    t_old = np.r_[0.0, np.cumsum(h)]
    t_new = np.interp(np.linspace(0.0, phi[-1], n + 1), phi, t_old)
    t_new[-1] = t_old[-1]
    return np.diff(t_new)


def equidistributed_steps(steps: np.ndarray, errors: np.ndarray, order: int, total: float) -> np.ndarray:
    """New step sizes (N',) over the same horizon whose local errors sum to about ``total`` and are
    equidistributed in time (module docstring): steps h (N,), their local errors e (N,), the scheme's order p."""
    return density_steps(steps, equidistributed_density(steps, errors, order, total))


def subdivided_steps(steps: np.ndarray, factor: float) -> np.ndarray:
    """The mesh refined uniformly in its own density: about ``factor`` times as many steps, each old step's
    share kept (refinement for what the local errors do not locate, a path constraint between the nodes)."""
    h = np.asarray(steps, dtype=float)
    n = max(int(np.ceil(factor * len(h))), 1)
    t_old = np.r_[0.0, np.cumsum(h)]
    t_new = np.interp(np.linspace(0.0, len(h), n + 1), np.arange(len(h) + 1), t_old)
    t_new[-1] = t_old[-1]
    return np.diff(t_new)


__all__ = ["GROWTH", "MERGE", "density_steps", "equidistributed_density", "equidistributed_steps", "error_estimate", "local_errors", "propagated_errors",
           "subdivided_steps", "tangent_norms"]
