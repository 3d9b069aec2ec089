"""Every SO(3) operation of the project, in one place (conventions: docs/mathematics.md §1).

The maps accept NumPy arrays (returning NumPy) or CasADi SX/MX/DM (returning the same type), except where a
docstring says NumPy; :func:`is_symbolic` is the one backend check.  The state-space charts are in
:mod:`transcription.geometry.state`.  ``hat(a) @ b == cross(a, b)``; ``vee`` is its inverse.  exp/log take their
small-angle coefficients from theta^2 behind a branch, so neither values nor derivatives become NaN at the identity.

Quaternions q = (w, x, y, z): scalar first, unit, Hamilton's convention (i j = k); the quaternion of an attitude R
(body -> inertial) rotates body vectors into the inertial frame, (0, v_inertial) = q (0, v_body) q*, i.e.
R(q) = (w^2 - |v|^2) I + 2 v v^T + 2 w S(v), v = (x, y, z).  Along a path the sign is continuous (q_k . q_{k-1} >= 0),
w >= 0 at the start.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

# below this theta^2 the Taylor branches are used (truncation O(theta^6) relative, < 1e-18)
_SMALL_THETA2 = 1e-6


def is_symbolic(a) -> bool:
    """Whether ``a`` is a CasADi matrix (SX, MX or DM) rather than NumPy: the one check by which every function of
    the method layer that takes either picks its backend."""
    return isinstance(a, (ca.SX, ca.MX, ca.DM))


def hat(a):
    """Hat map R^3 -> so(3): ``hat(a) @ b = a x b``.  a: (3,) or (3,1)."""
    if is_symbolic(a):
        return ca.skew(a)
    a = np.asarray(a, dtype=float).reshape(3)
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def vee(A):
    """Inverse of :func:`hat` for a skew 3x3 matrix (reads the lower triangle)."""
    if is_symbolic(A):
        return ca.vertcat(A[2, 1], A[0, 2], A[1, 0])
    A = np.asarray(A, dtype=float)
    return np.array([A[2, 1], A[0, 2], A[1, 0]])


def vee_skew(A):
    """vee of the skew part (A - A^T)/2; agrees with vee(log A) to first order."""
    return vee(0.5 * (A - A.T))


def _where(cond, a, b):
    if is_symbolic(cond) or is_symbolic(a) or is_symbolic(b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def _dot(a, b):
    if is_symbolic(a) or is_symbolic(b):
        return ca.dot(a, b)
    return float(np.dot(np.ravel(a), np.ravel(b)))


def _eye(like):
    return ca.DM.eye(3) if is_symbolic(like) else np.eye(3)


def mtimes(A, B):
    """A B: CasADi's product if either is CasADi (a NumPy operand becomes a constant), else NumPy's."""
    if is_symbolic(A) or is_symbolic(B):
        return ca.mtimes(A, B)
    return A @ B


def cayley(c):
    """Cayley map R^3 -> SO(3): (I + S(c))(I - S(c))^-1 = I + 2/(1 + |c|^2) (S(c) + S(c)^2) (docs/mathematics.md §2);
    rotation angle 2 atan|c|."""
    S = hat(c)
    return _eye(c) + (2.0 / (1.0 + _dot(c, c))) * (S + mtimes(S, S))


def cayley_inv(F):
    """Inverse Cayley map cay^-1(F) = vee(F - F^T) / (1 + tr F) (F not a rotation by pi); NumPy: F may be a stack
    (..., 3, 3) -> (..., 3)."""
    if not is_symbolic(F) and np.ndim(F) > 2:
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
    if is_symbolic(t2_safe):
        t = ca.sqrt(t2_safe)
        sin, cos = ca.sin, ca.cos
    else:
        t = np.sqrt(t2_safe)
        sin, cos = np.sin, np.cos
    a = _where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, sin(t) / t)
    b = _where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - cos(t)) / t2_safe)
    S = hat(w)
    return _eye(w) + a * S + b * mtimes(S, S)


def log_so3(R):
    """Logarithm SO(3) -> R^3 for angles in [0, pi], safe at the identity.  NumPy: theta = atan2(sin, cos); near pi
    (cos theta < -0.9) the axis from (R + R^T)/2 - cos(theta) I = (1 - cos theta) n n^T, its sign from the skew part.
    CasADi (differentiable): theta/(2 sin theta) vee(R - R^T), a Taylor branch at the identity; singular at pi."""
    if not is_symbolic(R):
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
    # sin(theta) as sqrt((1 - cos)(1 + cos)): 1 - cos^2 would lose eps/theta^2 near theta = 0
    sin_t = ca.sqrt((1.0 - cos_safe) * (1.0 + cos_safe))
    coef = _where(small, 0.5 + t2 / 12.0 + 7.0 * t2 * t2 / 720.0, t / (2.0 * sin_t))
    return coef * vee(R - R.T)


def log_so3_small(R):
    """Logarithm SO(3) -> R^3 for angles below ~0.9 pi by the NumPy branch's formula, theta = atan2(|vee(R - R^T)|/2,
    (tr R - 1)/2), theta/(2 sin theta) vee(R - R^T): NumPy and CasADi agree to round-off (:func:`log_so3`'s acos loses
    eps/theta^2).  CasADi: values only (the norm is not differentiable at the identity); the flight's tracking error."""
    if not is_symbolic(R):
        return _log_so3_np(np.asarray(R, dtype=float))
    w2 = vee(R - R.T)
    s = 0.5 * ca.norm_2(w2)
    t = ca.atan2(s, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0))
    t2 = t * t
    small = t2 < _SMALL_THETA2
    coef = _where(small, 0.5 + t2 / 12.0 + 7.0 * t2 * t2 / 720.0, t / (2.0 * _where(small, 1.0, s)))
    return coef * w2


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


def log_so3_batch(R: np.ndarray) -> np.ndarray:
    """Log of rotations R (M, 3, 3) -> (M, 3), vectorized, for angles away from pi (the small differences of a
    step's local error, transcription.strategy.mesh): t / (2 sin t) vee(R - R^T), t = atan2(sin, cos), 1/2 near 0."""
    R = np.asarray(R, dtype=float)
    w2 = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    s = 0.5 * np.linalg.norm(w2, axis=1)
    t = np.arctan2(s, 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0))
    t2 = t * t
    coef = np.where(t2 < _SMALL_THETA2, 0.5 + t2 / 12.0 + 7.0 * t2 * t2 / 720.0, t / (2.0 * np.where(s > 0, s, 1.0)))
    return coef[:, None] * w2


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


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """The rotation angle in [0, pi] of rotation matrices R (..., 3, 3): atan2(|vee(R - R^T)|/2, (tr R - 1)/2),
    accurate at every angle (arccos of the trace alone loses half the digits near 0 and pi)."""
    R = np.asarray(R, dtype=float)
    s = 0.5 * np.linalg.norm(np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                                       R[..., 1, 0] - R[..., 0, 1]], axis=-1), axis=-1)
    return np.arctan2(s, 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0))


def quaternions(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) of rotation matrices R (n, 3, 3) -> (n, 4), in the convention of the
    module docstring (scalar first, Hamilton, R body -> inertial), by Shepperd's method (accurate at every
    angle); the signs are chosen continuous along the sequence (q_k . q_{k-1} >= 0), w >= 0 at the start."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    q = np.empty((len(R), 4))
    for k, M in enumerate(R):
        tr = np.trace(M)
        i = int(np.argmax([tr, M[0, 0], M[1, 1], M[2, 2]]))
        if i == 0:
            s = 2.0 * np.sqrt(max(1.0 + tr, 0.0))
            q[k] = (0.25 * s, (M[2, 1] - M[1, 2]) / s, (M[0, 2] - M[2, 0]) / s, (M[1, 0] - M[0, 1]) / s)
        elif i == 1:
            s = 2.0 * np.sqrt(max(1.0 + M[0, 0] - M[1, 1] - M[2, 2], 0.0))
            q[k] = ((M[2, 1] - M[1, 2]) / s, 0.25 * s, (M[0, 1] + M[1, 0]) / s, (M[0, 2] + M[2, 0]) / s)
        elif i == 2:
            s = 2.0 * np.sqrt(max(1.0 - M[0, 0] + M[1, 1] - M[2, 2], 0.0))
            q[k] = ((M[0, 2] - M[2, 0]) / s, (M[0, 1] + M[1, 0]) / s, 0.25 * s, (M[1, 2] + M[2, 1]) / s)
        else:
            s = 2.0 * np.sqrt(max(1.0 - M[0, 0] - M[1, 1] + M[2, 2], 0.0))
            q[k] = ((M[1, 0] - M[0, 1]) / s, (M[0, 2] + M[2, 0]) / s, (M[1, 2] + M[2, 1]) / s, 0.25 * s)
    if len(q) and q[0, 0] < 0:
        q[0] = -q[0]
    for k in range(1, len(q)):
        if q[k] @ q[k - 1] < 0:
            q[k] = -q[k]
    return q


def rotation_of_quaternion(q) -> np.ndarray:
    """The rotation matrix (3, 3) of a unit quaternion q = (w, x, y, z) (module docstring; normalized first),
    R = (w^2 - |v|^2) I + 2 v v^T + 2 w S(v), v = (x, y, z): the inverse of :func:`quaternions` (q and -q give
    the same R)."""
    q = np.asarray(q, dtype=float).reshape(4)
    q = q / np.linalg.norm(q)
    w, v = q[0], q[1:]
    return (w * w - v @ v) * np.eye(3) + 2.0 * np.outer(v, v) + 2.0 * w * hat(v)


def quaternion_product(p, q) -> np.ndarray:
    """Hamilton's product p q of quaternions (w, x, y, z): rotation_of_quaternion(p q) = R(p) R(q)."""
    p, q = np.asarray(p, dtype=float).reshape(4), np.asarray(q, dtype=float).reshape(4)
    return np.r_[p[0] * q[0] - p[1:] @ q[1:], p[0] * q[1:] + q[0] * p[1:] + np.cross(p[1:], q[1:])]


def orthonormalize(R):
    """R (3 I - R^T R) / 2: one Newton-Schulz step towards the polar factor of R (CasADi or NumPy): the identity on
    SO(3) (and on its tangent vectors); off the manifold by E = R^T R - I it leaves O(E^2)."""
    return 0.5 * mtimes(R, 3 * _eye(R) - mtimes(R.T, R))


def step_cayley_vectors(R: np.ndarray) -> np.ndarray:
    """c_k = cay^-1(R_k^T R_{k+1}) (N, 3) of attitudes R (N+1, 3, 3): the Cayley vectors of the steps that take
    each attitude to the next (docs/mathematics.md §2) (NumPy)."""
    R = np.asarray(R, dtype=float)
    return cayley_inv(np.einsum("kji,kjl->kil", R[:-1], R[1:]))


def geodesic_interpolation(R: np.ndarray, t: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Rotations R (n, 3, 3) at increasing times t (n,) interpolated along the geodesic of SO(3) between
    neighbouring nodes, R_a exp(s log(R_a^T R_b)) with s the fraction of the interval, at the times tq (m,)
    -> (m, 3, 3); held at the ends outside [t_0, t_n-1].  On SO(3) to round-off."""
    j = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
    s = np.clip((tq - t[j]) / (t[j + 1] - t[j]), 0.0, 1.0)
    out = np.empty((len(tq), 3, 3))
    for i, (jj, ss) in enumerate(zip(j, s)):
        w = log_so3_any(R[jj].T @ R[jj + 1])
        out[i] = R[jj] @ exp_so3(ss * w)
    return out


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
    """v / |v| for a direction given as 3 numbers of any magnitude (NumPy; scaled by its largest |component| first,
    so |v|^2 neither overflows nor underflows), or None if not 3 finite numbers or zero.  Reads every user direction."""
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


def rotation_with_first_column(a) -> np.ndarray:
    """A rotation Q = [a, b, c] (3x3, NumPy) whose first column is the unit vector a (3,): b perpendicular to a (from
    the coordinate axis least aligned with a), c = a x b.  The frame of a body-fixed engine: a^T u is its thrust."""
    a = np.asarray(a, dtype=float).reshape(3)
    a = a / np.linalg.norm(a)
    e = np.zeros(3)
    e[int(np.argmin(np.abs(a)))] = 1.0
    b = e - (e @ a) * a
    b /= np.linalg.norm(b)
    return np.column_stack([a, b, np.cross(a, b)])


def rotation_between(u, v) -> np.ndarray:
    """The smallest rotations (n, 3, 3) taking the unit vectors u (n, 3) onto the unit vectors v (n, 3) (NumPy):
    Exp(theta n) with n = u x v / |u x v|, theta = angle(u, v) (the identity where u = v; for v = -u a rotation
    by pi about an axis perpendicular to u)."""
    u, v = np.atleast_2d(np.asarray(u, dtype=float)), np.atleast_2d(np.asarray(v, dtype=float))
    out = []
    for a, b in zip(u, v):
        w = np.cross(a, b)
        s = float(np.linalg.norm(w))
        axis = w / s if s > 1e-12 else rotation_with_first_column(a)[:, 1]
        out.append(np.asarray(exp_so3(np.arctan2(s, float(a @ b)) * axis), dtype=float))
    return np.array(out)
