"""The second-order check of a converged NLP point (docs/mathematics.md §10, "Saddles"): the least curvature of the
Lagrangian on the tangent space of the active constraints, and its direction.

At a KKT point w* with multipliers (lam_g, lam_x), a local minimum needs d^T H d >= 0 for every d in the tangent space
{d : A d = 0, d_i = 0 for the variables at a bound}, H = Hessian of f + lam_g^T g, A the Jacobian rows of the
equalities and of the inequalities at a bound.  IPOPT converges to any KKT point whose neighbourhood it reaches,
saddles included: it adds a multiple of the identity to H when the KKT matrix lacks a minimum's inertia
(Iterate.regularization), and its regularized steps do not follow a direction of negative curvature where the
gradient vanishes, e.g. at a point of symmetry that its start shares.  The least eigenvalue of P H P (P the
orthogonal projector onto the tangent space, applied through a sparse factorization of A A^T) by Lanczos (scipy's
eigsh) tells which: negative beyond round-off, and its eigenvector leads lower.  All in the NLP's own (scaled)
variables.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .structured import StructuredNLP


@dataclass(frozen=True)
class Curvature:
    """The curvature of the Lagrangian on the tangent space at a point: ``least`` and ``largest`` eigenvalue of
    P H P and ``direction`` (n,), the unit eigenvector of ``least`` (zero on the variables at a bound)."""

    least: float
    largest: float
    direction: np.ndarray

    def saddle(self, rtol: float) -> bool:
        """Negative curvature beyond ``rtol`` times the largest: the point is not a minimum (False when unknown)."""
        return bool(self.least < -rtol * max(abs(self.largest), 1e-300))


def _sparse(m):
    """A CasADi DM as a scipy CSC matrix."""
    import scipy.sparse as sp
    return sp.csc_matrix(m.sparse())


def _near(v: np.ndarray, bound: np.ndarray, tol: float) -> np.ndarray:
    """Where v is within tol (1 + |bound|) of a finite bound."""
    fin = np.isfinite(bound)
    out = np.zeros(len(v), dtype=bool)
    out[fin] = np.abs(v[fin] - bound[fin]) <= tol * (1 + np.abs(bound[fin]))
    return out


def least_curvature(nlp: StructuredNLP, lbx: np.ndarray, ubx: np.ndarray, x: np.ndarray, lam_g: np.ndarray,
                    active_tol: float = 1e-7, tol: float = 1e-6, maxiter: int = 60) -> Curvature:
    """The curvature of the Lagrangian of ``nlp`` at ``x`` (scaled, n) with constraint multipliers ``lam_g`` on the
    tangent space of the constraints active there (module docstring).  Active: every equality row, every inequality
    row and variable bound within ``active_tol`` (1 + |bound|) of its bound (weakly active ones too: the check then
    sees fewer directions, never one that leaves the feasible set).  Lanczos gets ``maxiter`` restarts to reach
    the relative accuracy ``tol``; when it does not (the least eigenvalues clustered near zero, as at a degenerate
    minimum), the curvature is nan: no sign is claimed."""
    import scipy.sparse as sp             # here, not at the top: the CLI's commands that solve nothing skip its 0.3 s
    import scipy.sparse.linalg as spla
    fns = nlp.derivative_functions()
    x = np.asarray(x, float)
    g, J = fns["jac_g"](x, [])
    g = np.asarray(g).ravel()
    J = sp.csr_matrix(_sparse(J))
    Hu = _sparse(fns["hess_lag"](x, [], 1.0, np.asarray(lam_g, float)))
    H = (Hu + sp.triu(Hu, 1).T).tocsr()
    lbg, ubg = np.asarray(nlp.lbg, float), np.asarray(nlp.ubg, float)
    rows = (lbg == ubg) | _near(g, lbg, active_tol) | _near(g, ubg, active_tol)
    at_bound = _near(x, lbx, active_tol) | _near(x, ubx, active_tol)
    free = np.flatnonzero(~at_bound)
    A = J[np.flatnonzero(rows)][:, free].tocsr()
    Hf = H[free][:, free]
    AAt = (A @ A.T).tocsc()
    AAt = AAt + sp.identity(AAt.shape[0], format="csc") * (1e-14 * max(AAt.diagonal().max(initial=0.0), 1e-300))
    lu = spla.splu(AAt)

    def project(v):
        return v - A.T @ lu.solve(A @ v)

    n = len(free)
    seed = project(np.random.default_rng(0).standard_normal(n))
    tangent = spla.LinearOperator((n, n), matvec=lambda v: project(Hf @ project(np.ravel(v))), dtype=float)
    try:
        hi = float(spla.eigsh(tangent, k=1, which="LA", v0=seed, tol=1e-3, maxiter=maxiter,
                              return_eigenvectors=False)[0])
        # the normal directions (range A^T, where P H P is 0) moved up to the largest curvature, out of the way
        shifted = spla.LinearOperator((n, n), dtype=float,
                                      matvec=lambda v: tangent @ v + abs(hi) * (np.ravel(v) - project(np.ravel(v))))
        lo, vec = spla.eigsh(shifted, k=1, which="SA", v0=seed, tol=tol, maxiter=maxiter)
    except spla.ArpackNoConvergence:      # a cluster near zero curvature: no clear sign, not taken for a saddle
        return Curvature(float("nan"), float("nan"), np.zeros(len(x)))
    d = np.zeros(len(x))
    d[free] = project(vec[:, 0])
    d /= max(np.linalg.norm(d), 1e-300)
    return Curvature(float(lo[0]), hi, d)


__all__ = ["Curvature", "least_curvature"]
