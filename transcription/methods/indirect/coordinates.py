"""The body-fixed force in the indirect method (docs/mathematics.md §15): the costate of the end kick, the control
law's body-frame costate, and the body-momentum coordinates of the linearization.

With an inertial force the costates live in the tangent coordinates z = [dx; dgamma; zeta; dPi] of §4 and nothing
here applies.  With a body-fixed force node j applies R_j u_{f,j}, and A_k depends on the next control through the
term -kick R_{k+1} S(u_{f,k+1}) of its rotation column (the end kick's Jacobian K_z); the forward recursion stays
explicit, in z, because K_z^T changes only the zeta block and the control reads only the gamma and Pi blocks
(:func:`kicked_costate`, :func:`rotated`).  In the coordinates of the body-frame momentum p = R^T gamma,

    z' = T(X) z = [dx; dp; zeta; dPi],   dp = R^T dgamma + S(p) zeta,
    T(X) = [[I, 0, 0, 0], [0, R^T, S(p), 0], [0, 0, I, 0], [0, 0, 0, I]],
    T(X)^-1 = [[I, 0, 0, 0], [0, R, -R S(p), 0], [0, 0, I, 0], [0, 0, 0, I]],

A'_k = T(X_{k+1}) A_k T(X_k)^-1 does not depend on u_{k+1} and T(X_{k+1}) B_k is the inertial constant matrix, so
the linearization (Psi) runs in z' on the inertial code.  The values do not: lambda'_zeta = lambda_zeta + p x
lambda'_p carries a large cancelling term whose rounding raises the round-off floor (§15).  All SX.
"""
from __future__ import annotations

import casadi as ca

from ...geometry.state import NX, NZ, Z_MOM, Z_ROT, chart, split_state, tangent_readback
from ...dynamics.lgvi import Discretization
from ...geometry.so3 import hat


def body_coordinates(disc: Discretization) -> bool:
    """Whether the indirect method of ``disc`` uses the body-momentum coordinates z' (a body-fixed force)."""
    return disc.force_frame == "body"


def _momentum(X):
    _, gamma, R, _ = split_state(X)
    return R, ca.mtimes(R.T, gamma)


def frame(X):
    """T(X) (12x12): z' = T(X) z, the body-momentum coordinates of a tangent vector z at X (module docstring)."""
    R, p = _momentum(X)
    T = ca.SX.eye(NZ)
    T[Z_MOM, Z_MOM] = R.T
    T[Z_MOM, Z_ROT] = hat(p)
    return T


def frame_inverse(X):
    """T(X)^-1 (12x12): z = T(X)^-1 z'."""
    R, p = _momentum(X)
    T = ca.SX.eye(NZ)
    T[Z_MOM, Z_MOM] = R
    T[Z_MOM, Z_ROT] = -ca.mtimes(R, hat(p))
    return T


def costate_chart(disc: Discretization):
    """(chart, readback) of the costate coordinates: :func:`~transcription.geometry.state.chart` and
    :func:`~transcription.geometry.state.tangent_readback` (inertial force), or their composition with T (body force):
    chart'(X, z') = chart(X, T(X)^-1 z'), readback'_X(dX) = T(X) readback_X(dX); first-order charts of the
    same state space, so derivatives taken through them are those in z'."""
    if not body_coordinates(disc):
        return chart, tangent_readback
    return (lambda X, z: chart(X, ca.mtimes(frame_inverse(X), z)),
            lambda X, dX: ca.mtimes(frame(X), tangent_readback(X, dX)))


def terminal_costate_function() -> ca.Function:
    """``terminal_costate`` (X[18], lam[12]) -> (lam_z[12], Tt[12x12], Q[12x12], Tinv[12x12]): a costate lam' in
    body-momentum coordinates at X as the tangent-coordinate costate lam_z = T(X)^T lam', Tt = T(X)^T,
    Q = d lam_z / d z' (X moved along chart'(X, z'), lam fixed) and Tinv = T(X)^-1: what the shooting needs to
    turn derivatives in z' at X_N into those of z_N and of lambda_{N-1} in z."""
    X, lam, z = ca.SX.sym("X", NX), ca.SX.sym("lam", NZ), ca.SX.sym("z", NZ)
    Xz = chart(X, ca.mtimes(frame_inverse(X), z))
    Q = ca.substitute(ca.jacobian(ca.mtimes(frame(Xz).T, lam), z), z, ca.DM.zeros(NZ))
    return ca.Function("terminal_costate", [X, lam], [ca.mtimes(frame(X).T, lam), frame(X).T, Q, frame_inverse(X)],
                       ["X", "lam"], ["lam_z", "Tt", "Q", "Tinv"])


def initial_costate_function() -> ca.Function:
    """``initial_costate`` (X[18], lam[12]) -> (Tit[12x12], Qi[12x12]): a tangent-coordinate costate lam at X in
    body-momentum coordinates is lam' = T(X)^-T lam; Tit = T(X)^-T and Qi = d lam' / d z' (X moved along
    chart'(X, z'), lam fixed): the start of the linearized recursion in z' when the shooting unknown is a
    tangent-coordinate costate."""
    X, lam, z = ca.SX.sym("X", NX), ca.SX.sym("lam", NZ), ca.SX.sym("z", NZ)
    Xz = chart(X, ca.mtimes(frame_inverse(X), z))
    Qi = ca.substitute(ca.jacobian(ca.mtimes(frame_inverse(Xz).T, lam), z), z, ca.DM.zeros(NZ))
    return ca.Function("initial_costate", [X, lam], [frame_inverse(X).T, Qi], ["X", "lam"], ["Tit", "Qi"])


def rotated(lam, R):
    """lam with its linear-momentum block in the body frame, R^T lam_gamma (the p-block of T(X)^-T lam, which does
    not depend on p): what the control law of a body-fixed force reads, B_c(R)^T lam = B_c^T rotated(lam, R)."""
    return ca.vertcat(lam[:3], ca.mtimes(R.T, lam[Z_MOM]), lam[6:])


def kicked_costate(mu, R1, u_f, kick):
    """lambda_k = K_z^-T mu_k from mu_k = Abar_k^-T lambda_{k-1} (docs/mathematics.md §15; SX): K_z, the Jacobian of
    the end kick gamma += kick R_{k+1} u_f, is I with -kick R_{k+1} S(u_f) in the (gamma, zeta) block, so only the
    zeta block changes: lambda_zeta = mu_zeta - kick u_f x (R_{k+1}^T mu_gamma)."""
    corr = kick * ca.cross(u_f, ca.mtimes(R1.T, mu[Z_MOM]))
    return ca.vertcat(mu[:6], mu[Z_ROT] - corr, mu[9:])
