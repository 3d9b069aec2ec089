"""The discrete necessary conditions of the indirect method as per-step CasADi Functions (docs/mathematics.md
§6, §10): the forward map of states and costates, and the terminal residual.  The derivation is in the
package docstring (:mod:`transcription.methods.indirect`); the LGVI's in :data:`LGVI_CONDITIONS`."""
from __future__ import annotations

from typing import Callable

import casadi as ca

from ...geometry.state import NU, NX, NZ, U_FORCE, join_state, split_state
from ...dynamics.lgvi import Discretization, per_discretization, two_point
from ...geometry.so3 import cayley, orthonormalize
from ...ocp import state_residual
from .control import NB, control_law
from .coordinates import body_coordinates, frame, frame_inverse, kicked_costate, rotated
from .elimination import solve_unpivoted


def terminal_residual_function() -> ca.Function:
    """(XN[18], Xd[18]) -> zN[12]: :func:`~transcription.ocp.state_residual` with every component
    (positions and linear momenta inertial, Pi body; the attitude error the rotation vector of
    R_d^T R_N, body frame at the target, three conditions)."""
    XN = ca.SX.sym("XN", NX)
    Xd = ca.SX.sym("Xd", NX)
    return ca.Function("terminal_residual", [XN, Xd], [state_residual(XN, Xd)], ["XN", "Xd"], ["zN"])


def orthonormalized(X):
    """X with R replaced by :func:`~transcription.geometry.so3.orthonormalize` (R) = R (3 I - R^T R) / 2: the argument
    of A_k, whose read-back (docs/mathematics.md §4) is sensitive to the round-off drift of R^T R, which would
    otherwise set the round-off floor of the shooting residual (§6)."""
    x, gamma, R, Pi = split_state(X)
    return join_state(x, gamma, orthonormalize(R), Pi)


def _costate_map_function(scheme: str, ins: list, outs: list) -> ca.Function:
    """``{scheme}_costate_map`` (X, lam_prev, h, Winv, bd[, theta]) -> (X1, lam, u, res, lam_res, A, c, D, lamp), one
    signature for both schemes and force frames (``_p``: the model's numbers theta the last input)."""
    theta = len(ins) > 5
    return ca.Function(f"{scheme}_costate_map{'_p' if theta else ''}", ins, outs,
                       ["X", "lam_prev", "h", "Winv", "bd"] + (["theta"] if theta else []),
                       ["X1", "lam", "u", "res", "lam_res", "A", "c", "D", "lamp"])


def theta_symbol(disc: Discretization, parametric: bool) -> tuple:
    """(the Discretization the per-step Functions are built from, their extra inputs): ``disc`` and none, or
    (``parametric``) ``disc.with_theta(theta)`` and [theta], the model's numbers as data (lgvi.WithTheta)."""
    if not parametric:
        return disc, []
    theta = ca.SX.sym("theta", disc.model.parameters.size)
    return disc.with_theta(theta), [theta]


def node_law(disc: Discretization, h, Winv, bd) -> Callable:
    """(lambda, R) -> (u, D): the control law (:func:`~.control.control_law`) of a tangent-coordinate costate for
    a control applied at attitude R; with a body-fixed force it reads R^T lambda_gamma (:func:`.coordinates.rotated`,
    docs/mathematics.md §15), otherwise R is not used."""
    control = control_law(disc, h, Winv, bd)
    if body_coordinates(disc):
        return lambda lam, R: control(rotated(lam, R))
    return lambda lam, R: control(lam)


def _forward_step(disc: Discretization, X, lam_prev, h, Winv, bd) -> dict:
    """One step of the forward map of the necessary conditions, as SX expressions: the step's Cayley equation solved
    once (its right-hand side does not depend on u_{k+1}), A_k = ``disc.variation`` at orthonormalized(X), forward AD
    through the unrolled Newton iterations (``disc.variation_seeded`` would be a smaller graph, but its rounding
    changes the iteration counts at the round-off floor that tests pin).

    With a body-fixed force (docs/mathematics.md §15): Abar_k = A_k without the end kick K_z, mu = Abar_k^-T
    lambda_{k-1}, u_{k+1} from R_{k+1}^T mu_gamma (R_{k+1} = R_k cay(c)), lambda_k = :func:`.coordinates.kicked_costate`
    (mu); for the linearization A = T(Y) Abar_k T(X_k)^-1 (Y: the step without u_{k+1}) and lamp = T(X_{k+1})^-T
    lambda_k (:mod:`.coordinates`).  Otherwise A = A_k and lamp = lam.  Returns a dict: c (the Cayley root), A, Abar,
    mu, lam, lamp, u (u_{k+1}), D (its saturation Jacobian), X1, res, law ((lambda, R) -> (u, D)).
    """
    law = node_law(disc, h, Winv, bd)
    zero = ca.DM.zeros(NU)
    R = split_state(X)[2]
    if disc.scheme == "first_order":
        wA, stage = zero, (lambda u1: u1)
    else:
        uk = law(lam_prev, R)[0]
        wA, stage = ca.vertcat(uk, zero), (lambda u1: ca.vertcat(uk, u1))
    c, hist = disc.cayley_solve(disc.cayley_rhs(X, wA, h))
    Xo = orthonormalized(X)
    A = disc.variation(Xo, wA, h)[0]
    mu = solve_unpivoted(A.T, lam_prev)
    R1 = ca.mtimes(R, cayley(c))
    u, D = law(mu, R1)
    X1 = disc.step_given_c(X, c, stage(u), h)[0]
    out = {"c": c, "A": A, "Abar": A, "mu": mu, "lam": mu, "lamp": mu, "u": u, "D": D, "X1": X1, "res": hist[-1],
           "law": law}
    if body_coordinates(disc):
        kick = 0.5 * h if two_point(disc.scheme) else h
        lam = kicked_costate(mu, R1, u[U_FORCE], kick)
        Ap = ca.mtimes(frame(disc.step_given_c(Xo, c, wA, h)[0]), ca.mtimes(A, frame_inverse(Xo)))
        out.update(lam=lam, A=Ap, lamp=ca.mtimes(frame_inverse(X1).T, lam))
    return out


@per_discretization
def costate_functions(disc: Discretization, parametric: bool = False) -> tuple[ca.Function, ca.Function | None]:
    """(costate_map, first_step): the forward map of the necessary conditions for ``disc`` (:func:`_forward_step`).
    ``parametric``: the model's numbers theta = ``model.parameters`` the last input of both (:func:`theta_symbol`;
    the shooting's maps, compiled once per structure), else constants.

    * costate_map (X[18], lam_prev[12], h, Winv[6x6], bd[NB]) -> (X1[18], lam[12], u[6], res, lam_res, A[12x12],
      c[3], D[6x6], lamp[12]); first_order: lam = lambda_k = A_k^-T lambda_{k-1} (28), u = u_{k+1} =
      sat(-(1/h) Winv B_k^T lambda_k) (26)-(27) (D its Jacobian, :func:`~.control.saturate`), X1 = step(X_k, u_{k+1}),
      res its Cayley residual, lam_res = |A_k^T lam - lam_prev|_inf / |lam_prev|_inf, A = A_k and c the Cayley root
      for the linearization, lamp = lam (body-fixed force: :func:`_forward_step`); lgvi (:data:`LGVI_CONDITIONS`):
      the same with u_k = -(2/h) Winv B^b^T lambda_{k-1} and A_k = A(X_k, u_k).
    * first_step (X0[18], lam0[12], h, Winv, bd) -> (X1[18], u[6], res): first_order's k = 0 step from the unknown
      lambda_0; None for lgvi (the map is applied N times from lambda_{-1}).
    """
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    bd = ca.SX.sym("bd", NB)
    d, theta = theta_symbol(disc, parametric)
    s = _forward_step(d, X, lam_prev, h, Winv, bd)
    lam_res = ca.norm_inf(ca.mtimes(s["Abar"].T, s["mu"]) - lam_prev) / ca.fmax(ca.norm_inf(lam_prev), 1e-300)
    costate_map = _costate_map_function(disc.scheme, [X, lam_prev, h, Winv, bd, *theta],
                                        [s["X1"], s["lam"], s["u"], s["res"], lam_res, s["A"], s["c"], s["D"],
                                         s["lamp"]])
    if disc.scheme != "first_order":
        return costate_map, None
    lam0 = ca.SX.sym("lam0", NZ)
    R1 = ca.mtimes(split_state(X)[2], cayley(d.cayley_solve(d.cayley_rhs(X, ca.DM.zeros(NU), h))[0]))
    u0 = s["law"](lam0, R1)[0]
    X1, res = d.step(X, u0, h)
    first_step = ca.Function(
        f"first_order_costate_first_step{'_p' if theta else ''}", [X, lam0, h, Winv, bd, *theta], [X1, u0, res],
        ["X0", "lam0", "h", "Winv", "bd"] + (["theta"] if theta else []), ["X1", "u", "res"]
    )
    return costate_map, first_step


#: The second-order LGVI (docs/mathematics.md §2, node controls u_0..u_N, stage control w_k = [u_k; u_{k+1}],
#: cost sum_j omega_j (1/2) u_j^T W u_j with trapezoidal omega = h (1/2, 1, ..., 1, 1/2), as in
#: the direct method), derived with the same Lagrangian L = J + sum_k lambda_k^T (step ⊖ X_{k+1}).
LGVI_CONDITIONS = """
z_{k+1} = A_k z_k + B^a_k du_k + B^b du_{k+1}.  Stationarity in z_k (k = 1..N-1):
lambda_{k-1} = A_k^T lambda_k.  In u_j:  omega_j W u_j + B^a_j^T lambda_j + B^b^T lambda_{j-1} = 0
(terms absent for j = N resp. j = 0).  In eqs. (7)-(11) u_k enters exactly as a momentum kick
(gamma_k, Pi_k) += (h/2) u_k before the step, with f_k, M_k unchanged, so B^a_k = A_k B^b
(tested) and, with lambda_{-1} := A_0^T lambda_0 (the multiplier of the initial condition),
stationarity reads uniformly for j = 0..N

    u_j = -(2/h) W^-1 B^b^T lambda_{j-1} = -W^-1 [lambda^2_{j-1}; lambda^4_{j-1}]   (omega_j = h inside,
                                                                              h/2 at both ends)

A_k depends on u_k but not on u_{k+1}, so the recursion runs forward from the unknown lambda_{-1}:
u_k from lambda_{k-1}; lambda_k = A_k(X_k, u_k)^-T lambda_{k-1}; u_{k+1} from lambda_k;
X_{k+1} = step(X_k, [u_k; u_{k+1}]).  The shooting unknown is lambda_{-1} (12), the residual z_N.
"""
