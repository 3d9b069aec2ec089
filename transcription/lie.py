"""The Lie group helpers of the project, in one place: SO(3) maps and the charts of the state space.

SO(3) (symbolic CasADi SX/MX and numeric NumPy alike): hat/vee, the Cayley map and its
inverse, exp/log (log also at exactly pi, with a chosen sign), the inverse right Jacobian,
elementary rotations, orthogonality errors, unit directions.  State space T*SE(3) (docs/mathematics.md §4): the
left-trivialized chart ``chart`` around a state, its read-back ``tangent_readback`` and the
tangent basis ``tangent_basis`` (dX = D(X) z).

Conventions (docs/mathematics.md §1): ``hat(a) @ b == cross(a, b)``; ``vee`` is its inverse on
skew matrices.  The Cayley map is ``cay(c) = (I + S(c)) (I - S(c))^-1``, written in
closed form ``I + 2/(1 + |c|^2) (S(c) + S(c)^2)`` so that it is exactly the same
expression whatever the backend.  ``exp``/``log`` handle small angles by computing
their coefficients from theta^2 behind a branch on theta^2 (jaxlie style), so that
neither values nor derivatives become NaN at the identity.

Every function accepts either NumPy arrays (returns NumPy) or CasADi SX/MX/DM
(returns the same CasADi type).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .layout import NX, NZ, X_ANG, X_MOM, X_POS, X_ROT, join_state, split_state

# Below this theta^2 the Taylor branches are used (their truncation error is
# O(theta^6) relative, i.e. < 1e-18 here).
_SMALL_THETA2 = 1e-6


def _is_casadi(a) -> bool:
    return isinstance(a, (ca.SX, ca.MX, ca.DM))


def hat(a):
    """Hat map R^3 -> so(3): ``hat(a) @ b = a x b``.  a: (3,) or (3,1)."""
    if _is_casadi(a):
        return ca.skew(a)
    a = np.asarray(a, dtype=float).reshape(3)
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def vee(A):
    """Inverse of :func:`hat` for a skew 3x3 matrix (reads the lower triangle)."""
    if _is_casadi(A):
        return ca.vertcat(A[2, 1], A[0, 2], A[1, 0])
    A = np.asarray(A, dtype=float)
    return np.array([A[2, 1], A[0, 2], A[1, 0]])


def vee_skew(A):
    """vee of the skew part (A - A^T)/2; agrees with vee(log A) to first order."""
    return vee(0.5 * (A - A.T))


def _where(cond, a, b):
    if _is_casadi(cond) or _is_casadi(a) or _is_casadi(b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def _dot(a, b):
    if _is_casadi(a) or _is_casadi(b):
        return ca.dot(a, b)
    return float(np.dot(np.ravel(a), np.ravel(b)))


def _eye(like):
    return ca.DM.eye(3) if _is_casadi(like) else np.eye(3)


def _mm(A, B):
    if _is_casadi(A) or _is_casadi(B):
        return ca.mtimes(A, B)
    return A @ B


def cayley(c):
    """Cayley map R^3 -> SO(3): ``(I + S(c))(I - S(c))^-1`` (docs/mathematics.md §2).

    Exactly orthogonal in exact arithmetic for every c; rotation angle 2 atan|c|.
    """
    S = hat(c)
    return _eye(c) + (2.0 / (1.0 + _dot(c, c))) * (S + _mm(S, S))


def cayley_inv(F):
    """Inverse Cayley map SO(3) -> R^3 (F must not be a rotation by pi).

    cay^-1(F) = vee(F - F^T) / (1 + tr F).  NumPy: F may be a stack (..., 3, 3) -> (..., 3).
    """
    if not _is_casadi(F) and np.ndim(F) > 2:
        F = np.asarray(F, dtype=float)
        A = F - np.swapaxes(F, -1, -2)
        tr = np.trace(F, axis1=-2, axis2=-1)
        return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1) / (1.0 + tr)[..., None]
    tr = F[0, 0] + F[1, 1] + F[2, 2]
    return vee(F - F.T) / (1.0 + tr)


def exp_so3(w):
    """Exponential map R^3 -> SO(3) (Rodrigues), safe at w = 0."""
    t2 = _dot(w, w)
    small = t2 < _SMALL_THETA2
    t2_safe = _where(small, 1.0, t2)
    if _is_casadi(t2_safe):
        t = ca.sqrt(t2_safe)
        sin, cos = ca.sin, ca.cos
    else:
        t = np.sqrt(t2_safe)
        sin, cos = np.sin, np.cos
    a = _where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, sin(t) / t)
    b = _where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - cos(t)) / t2_safe)
    S = hat(w)
    return _eye(w) + a * S + b * _mm(S, S)


def log_so3(R):
    """Logarithm SO(3) -> R^3 for angles in [0, pi], safe at the identity.

    NumPy: theta = atan2(sin, cos) from the skew part and the trace (well
    conditioned for every angle); near pi (cos theta < -0.9) the axis is read
    from the symmetric part (R + R^T)/2 - cos(theta) I = (1 - cos theta) n n^T,
    its sign from the skew part, so the result stays accurate to round-off.

    CasADi (symbolic, differentiable): theta/(2 sin theta) vee(R - R^T) with a
    Taylor branch at the identity.  Its derivative is singular at pi, as is the
    logarithm's; the method layer evaluates it near the identity (terminal
    attitude error).
    """
    if not _is_casadi(R):
        return _log_so3_np(np.asarray(R, dtype=float))
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    cos_t = ca.fmin(ca.fmax(0.5 * (tr - 1.0), -1.0), 1.0)
    # theta^2 ~ 2 (1 - cos theta) for small angles
    one_minus = 1.0 - cos_t
    small = one_minus < 0.5 * _SMALL_THETA2
    cos_safe = _where(small, 0.0, cos_t)
    t = ca.acos(cos_safe)
    # theta / (2 sin theta); Taylor: 1/2 + theta^2/12 + 7 theta^4/720
    t2 = 2.0 * one_minus
    # sin(theta) as sqrt((1 - cos)(1 + cos)): 1 - cos is exact near theta = 0, whereas
    # 1 - cos^2 loses eps/theta^2 (relative 1e-10 just above the switch at theta = 1e-3)
    sin_t = ca.sqrt((1.0 - cos_safe) * (1.0 + cos_safe))
    coef = _where(small, 0.5 + t2 / 12.0 + 7.0 * t2 * t2 / 720.0, t / (2.0 * sin_t))
    return coef * vee(R - R.T)


def _log_so3_np(R: np.ndarray) -> np.ndarray:
    w2 = vee(R - R.T)                      # 2 sin(theta) n
    s = 0.5 * np.linalg.norm(w2)
    c = 0.5 * (np.trace(R) - 1.0)
    t = np.arctan2(s, c)
    if c > -0.9:
        t2 = t * t
        coef = 0.5 + t2 / 12.0 + 7.0 * t2 * t2 / 720.0 if t2 < _SMALL_THETA2 else t / (2.0 * s)
        return coef * w2
    B = 0.5 * (R + R.T) - c * np.eye(3)    # (1 - cos theta) n n^T
    j = int(np.argmax(np.diag(B)))
    n = B[:, j] / np.sqrt(B[j, j] * (1.0 - c))
    n /= np.linalg.norm(n)
    if n @ w2 < 0:
        n = -n
    return t * n


def log_so3_any(R: np.ndarray, prefer: np.ndarray | None = None) -> np.ndarray:
    """vee log R for every rotation (accurate up to pi), with the sign of the axis at exactly pi --
    where the skew part carries no sign -- chosen so that n^T prefer >= 0 (NumPy only)."""
    R = np.asarray(R, dtype=float)
    w = np.asarray(log_so3(R), dtype=float)
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if prefer is not None and np.linalg.norm(skew) <= 1e-9 and w @ prefer < 0:
        w = -w
    return w


def right_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Jr^-1(phi) (3x3, NumPy): Log(Exp(phi) Exp(d)) = phi + Jr^-1(phi) d + O(d^2)."""
    t2 = float(phi @ phi)
    S = hat(phi)
    if t2 < 1e-8:
        coef = 1.0 / 12.0 + t2 / 720.0
    else:
        t = np.sqrt(t2)
        coef = 1.0 / t2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t))
    return np.eye(3) + 0.5 * S + coef * (S @ S)


def rot_x(deg: float) -> np.ndarray:
    """Elementary rotation about e1 by ``deg`` degrees."""
    t = np.deg2rad(deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(deg: float) -> np.ndarray:
    """Elementary rotation about e2 by ``deg`` degrees."""
    t = np.deg2rad(deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(deg: float) -> np.ndarray:
    """Elementary rotation about e3 by ``deg`` degrees."""
    t = np.deg2rad(deg)
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def orthogonality_error(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For R of shape (..., 3, 3): (Frobenius ||R^T R - I||, |det R - 1|), shape (...)."""
    R = np.asarray(R, dtype=float)
    E = np.einsum("...ji,...jk->...ik", R, R) - np.eye(3)
    return np.linalg.norm(E, axis=(-2, -1)), np.abs(np.linalg.det(R) - 1.0)


def unit_direction(v) -> np.ndarray | None:
    """v / |v| for a direction given as 3 numbers of any magnitude (NumPy), or None if it has none.

    The vector is divided by its largest |component| before the norm is taken, so that neither
    |v|^2 overflows (components of 1e200 would give |v| = inf and a zero "unit" vector) nor
    underflows (1e-200 would give |v| = 0): every finite non-zero vector, denormal components
    included, has its direction.  None: not 3 finite numbers, or exactly zero.  The one place
    where a direction given by a user (a cone's axes, an orbit's normal, a rotation axis) is read."""
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        return None
    scale = float(np.max(np.abs(a)))
    if scale == 0.0:
        return None
    u = a / scale
    return u / np.linalg.norm(u)


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation nearest to each 3x3 matrix of R (..., 3, 3) in the Frobenius norm (NumPy): U V^T
    of the SVD R = U S V^T, with the sign of the last singular direction flipped where det(U V^T) < 0
    (the orthogonal polar factor).  Re-projects an attitude integrated as nine entries onto SO(3)."""
    U, _, Vt = np.linalg.svd(np.asarray(R, dtype=float))
    d = np.sign(np.linalg.det(U @ Vt))
    U = U.copy()
    U[..., :, 2] *= np.where(d == 0, 1.0, d)[..., None]
    return U @ Vt


# ------------------------------------------------------------- charts of the state space
def chart(X, z):
    """Left-trivialized chart around a state X (18) (docs/mathematics.md §4): additive on x, gamma,
    Pi; R -> R cay(zeta/2).  CasADi.

    The Cayley map here is (I + S(c))(I - S(c))^-1 = I + 2 S(c) + O(c^2), so the argument is
    halved to make dR = R S(zeta) to first order (the coordinates read back by
    :func:`tangent_readback`); with cay(zeta) the zeta-columns of A_k would be twice the
    left-trivialized Jacobian.
    """
    x, gamma, R, Pi = split_state(X)
    return join_state(x + z[0:3], gamma + z[3:6], ca.mtimes(R, cayley(0.5 * z[6:9])), Pi + z[9:12])


def tangent_readback(Xbar, dX):
    """Map a differential dX (18 x n) at Xbar to tangent coordinates z (12 x n) (CasADi).

    dzeta = vee(skew(Rbar^T dR)); the other blocks are copied.
    """
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
