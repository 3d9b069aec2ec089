"""The sensitivity of the free rollout to the initial momenta (docs/mathematics.md §5, eqs. 18-20): Phi =
A_{N-1} ... A_0 (12 x 12) along the rollout, and a second route by AD of the whole rollout (for the tests)."""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...geometry.state import NX, NZ, X_ANG, X_MOM, Z_ANG, Z_MOM, chart, tangent_readback
from ...dynamics.lgvi import per_discretization

#: tangent coordinates of the unknowns p = (gamma_0^+, Pi_0^+) inside z
P_COLS = np.r_[np.arange(Z_MOM.start, Z_MOM.stop), np.arange(Z_ANG.start, Z_ANG.stop)]
P_ROWS_X = np.r_[np.arange(X_MOM.start, X_MOM.stop), np.arange(X_ANG.start, X_ANG.stop)]


def with_momenta(X0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """X0 (18,) with (gamma, Pi) replaced by p = (gamma^+, Pi^+) (6,)."""
    X = np.array(X0, dtype=float).reshape(NX)
    X[P_ROWS_X] = np.asarray(p, dtype=float).ravel()
    return X


@per_discretization
def _variation_map(disc, N: int) -> ca.Function:
    return disc.variation.map(N)


def sensitivity(disc, X: np.ndarray, h: float, W: np.ndarray | None = None) -> np.ndarray:
    """Phi = A_{N-1} ... A_0 (12 x 12, eq. 19) along node states X (N+1, 18).

    W: stage controls (nw x N) or None (free motion).  A_k = disc.variation(X_k, w_k, h).
    """
    N = X.shape[0] - 1
    W = np.zeros((disc.nw, N)) if W is None else W
    A, _ = _variation_map(disc, N)(X[:-1].T, W, h)
    A = np.array(A)
    Phi = np.eye(NZ)
    for k in range(N):
        Phi = A[:, NZ * k: NZ * (k + 1)] @ Phi
    return Phi


@per_discretization
def _sensitivity_ad_fn(disc, N: int) -> ca.Function:
    X0 = ca.MX.sym("X0", NX)
    z = ca.MX.sym("z", NZ)
    h = ca.MX.sym("h")
    roll = disc.rollout(N)
    XN = roll(chart(X0, z), ca.DM.zeros(disc.nw, N), h)[0][:, -1]
    dXN = ca.jacobian(XN, z)
    XNbar = roll(X0, ca.DM.zeros(disc.nw, N), h)[0][:, -1]
    dXN = ca.substitute(dXN, z, ca.DM.zeros(NZ))
    return ca.Function("phi_ad", [X0, h], [tangent_readback(XNbar, dXN)], ["X0", "h"], ["Phi"])


def sensitivity_ad(disc, X0: np.ndarray, h: float, N: int) -> np.ndarray:
    """Phi by AD of the whole free rollout composed with the chart at X0, read back at X_N (12 x 12)."""
    return np.array(_sensitivity_ad_fn(disc, N)(X0, h))
