"""State and control layout: defined here once, used everywhere.

State vector X in R^18 (docs/mathematics.md §1), stacked as

    X = [x (3, inertial position); gamma (3, inertial linear momentum);
         vec(R) (9, column-major: R[:, 0], R[:, 1], R[:, 2]); Pi (3, body angular momentum)]

Control vector u in R^6: [u_f (3, inertial force); u_m (3, body moment)].

Tangent (variation) vector z in R^12 (docs/mathematics.md §4): [dx; dgamma; zeta; dPi] with
dR = R S(zeta).

The chart around a state (``chart``), its read-back (``tangent_readback``) and the tangent basis (``tangent_basis``,
dX = D(X) z) are here too.  Trajectories are node-major (N+1, 18) in NumPy, 18 x (N+1) in CasADi.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .so3 import cayley, hat, is_symbolic, step_cayley_vectors, vee_skew

NX = 18
NU = 6
NZ = 12

X_POS = slice(0, 3)
X_MOM = slice(3, 6)
X_ROT = slice(6, 15)
X_ANG = slice(15, 18)

U_FORCE = slice(0, 3)
U_MOMENT = slice(3, 6)

Z_POS = slice(0, 3)
Z_MOM = slice(3, 6)
Z_ROT = slice(6, 9)
Z_ANG = slice(9, 12)


def split_state(X):
    """One state (18,) -> (x, gamma, R (3x3), Pi); CasADi (18,1) or NumPy (18,) alike."""
    if is_symbolic(X):
        return X[X_POS], X[X_MOM], ca.reshape(X[X_ROT], 3, 3), X[X_ANG]
    X = np.asarray(X, dtype=float).reshape(NX)
    return X[X_POS], X[X_MOM], X[X_ROT].reshape(3, 3, order="F"), X[X_ANG]


def join_state(x, gamma, R, Pi):
    """(x, gamma, R (3x3), Pi) -> one state: CasADi (18,1) if any part is CasADi, else NumPy (18,)."""
    if any(is_symbolic(a) for a in (x, gamma, R, Pi)):
        return ca.vertcat(x, gamma, ca.reshape(R, 9, 1), Pi)
    return pack_state(x, gamma, R, Pi)


def pack_state(x, gamma, R, Pi) -> np.ndarray:
    """NumPy: one node (shapes (3,), (3,), (3,3), (3,)) or many ((M,3),(M,3),(M,3,3),(M,3))
    -> (18,) or (M, 18)."""
    x, gamma, Pi = (np.asarray(a, dtype=float) for a in (x, gamma, Pi))
    R = np.asarray(R, dtype=float)
    Rv = np.swapaxes(R, -1, -2).reshape(R.shape[:-2] + (9,))  # column-major vec
    return np.concatenate([x, gamma, Rv, Pi], axis=-1)


@dataclass(frozen=True)
class States:
    """Named view of stacked states: x, gamma, Pi (M,3) and R (M,3,3)."""

    x: np.ndarray
    gamma: np.ndarray
    R: np.ndarray
    Pi: np.ndarray


def unpack_states(X) -> States:
    """NumPy (M,18) or (18,) (or CasADi DM 18 x M) -> :class:`States` (node-major)."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 2 and X.shape[0] == NX and X.shape[1] != NX:
        X = X.T
    X = np.atleast_2d(X)
    R = np.swapaxes(X[:, X_ROT].reshape(-1, 3, 3), -1, -2)
    return States(x=X[:, X_POS].copy(), gamma=X[:, X_MOM].copy(), R=R.copy(), Pi=X[:, X_ANG].copy())


# ------------------------------------------------------------- charts of the state space (docs/mathematics.md §4)


def chart(X, z):
    """Left-trivialized chart around a state X (18) (docs/mathematics.md §4): additive on x, gamma, Pi;
    R -> R cay(zeta/2) (cay(c) = I + 2 S(c) + O(c^2): halved so dR = R S(zeta) to first order).  CasADi."""
    x, gamma, R, Pi = split_state(X)
    return join_state(x + z[Z_POS], gamma + z[Z_MOM], ca.mtimes(R, cayley(0.5 * z[Z_ROT])), Pi + z[Z_ANG])


def tangent_readback(Xbar, dX):
    """Map a differential dX (18 x n) at Xbar to tangent coordinates z (12 x n) (CasADi): dzeta = vee(skew(Rbar^T
    dR)); the other blocks are copied."""
    Rbar = ca.reshape(Xbar[X_ROT], 3, 3)
    cols = []
    for j in range(dX.shape[1]):
        dR = ca.reshape(dX[X_ROT, j], 3, 3)
        cols.append(ca.vertcat(dX[X_POS, j], dX[X_MOM, j], vee_skew(ca.mtimes(Rbar.T, dR)), dX[X_ANG, j]))
    return ca.horzcat(*cols)


def tangent_basis(X: np.ndarray) -> np.ndarray:
    """D(X) (18 x 12, NumPy): dX = D z for z = [dx; dgamma; zeta; dPi], dR = R S(zeta), vec column-major."""
    R = np.asarray(X, dtype=float)[X_ROT].reshape(3, 3, order="F")
    D = np.zeros((NX, NZ))
    D[X_POS, 0:3] = np.eye(3)
    D[X_MOM, 3:6] = np.eye(3)
    D[X_ANG, 9:12] = np.eye(3)
    for i in range(3):
        D[X_ROT, 6 + i] = (R @ hat(np.eye(3)[i])).ravel(order="F")
    return D


def cayley_vectors(X: np.ndarray) -> np.ndarray:
    """c_k = cay^-1(R_k^T R_{k+1}) (N, 3) of node states X (N+1, 18): the Cayley vectors of the steps, consistent with
    the attitudes (:func:`~transcription.geometry.so3.step_cayley_vectors`)."""
    return step_cayley_vectors(unpack_states(X).R)
