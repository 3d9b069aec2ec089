"""Gaussian elimination without pivoting on SX matrices: lambda_k = A_k^-T lambda_{k-1} and its linearization
(the accuracy argument is in :func:`solve_unpivoted`)."""
from __future__ import annotations

import casadi as ca


def solve_unpivoted(M, b):
    """Solve M Y = b (SX, M n x n dense, b n x m) by Gaussian elimination without pivoting: lambda_k = A_k^-T
    lambda_{k-1} and, with 12 columns sharing one elimination, its linearization.  A_k is near block-triangular
    (identity blocks for x, gamma, Pi; F_k^T for zeta), so the pivots stay away from 0 while the rotation per step is
    well below a right angle: ~1 ulp per component, where a symbolic QR (``ca.solve`` on SX) raised the round-off
    floor of z_N (docs/mathematics.md §6).  The caller reports the relative residual (lam_res), so a breakdown shows.
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
