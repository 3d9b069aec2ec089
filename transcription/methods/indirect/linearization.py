"""The linearization of the indirect method's forward map (docs/mathematics.md §6 (29)-(31)): the exact
Jacobian Psi of the shooting residual by the linearized recursion along the rollout."""
from __future__ import annotations


import casadi as ca

from ...geometry.state import NU, NX, NZ, chart, split_state
from ...dynamics.lgvi import Discretization, per_discretization
from .conditions import costate_functions, node_law, orthonormalized, terminal_residual_function, theta_symbol
from .control import NB, control_matrix, control_scale
from .coordinates import costate_chart
from .elimination import unpivoted_elimination, unpivoted_substitution


@per_discretization
def adjoint_variation_jacobian(disc: Discretization, parametric: bool = False) -> ca.Function:
    """``{scheme}_adjoint_variation_jacobian`` (X, w, lam, h, c0[, theta]) -> H[12x12] = d/dz [A(chart(X, z), w)^T lam]
    at z = 0 (``parametric``: theta the last input, :func:`.conditions.theta_symbol`).  A^T lam is the gradient in z
    of lam^T readback(step(chart(X, z))) (one reverse sweep; the readback is linear) and H its Jacobian (12 forward
    directions), cheaper than 12 directions through the 144 entries of A.  The step is the seeded one (two Newton
    iterations from the Cayley root c0: exact to third derivatives), so H is exact.  With a body-fixed force: in the
    body-momentum coordinates (:func:`.coordinates.costate_chart`), H' of A'(X) = T(X_{k+1}) A(X) T(X)^-1.
    """
    X = ca.SX.sym("X", NX)
    w = ca.SX.sym("w", disc.nw)
    lam = ca.SX.sym("lam", NZ)
    h = ca.SX.sym("h")
    c0 = ca.SX.sym("c0", 3)
    z, zp = ca.SX.sym("z", NZ), ca.SX.sym("zp", NZ)
    chart_c, readback_c = costate_chart(disc)  # z (inertial force) or the body-momentum z' (§15)
    d, theta = theta_symbol(disc, parametric)
    X1z = d.step_seeded(chart_c(chart_c(X, zp), z), w, h, c0)
    base = ca.SX.sym("base", NX)  # the readback point X_{k+1}(zp), not differentiated in z
    g = ca.gradient(ca.dot(lam, readback_c(base, X1z)), z)
    # one substitution for both, so that the step at z = 0 is one graph (not two copies, each differentiated)
    v, X1p = ca.substitute([g, X1z], [z], [ca.DM.zeros(NZ)])
    v = ca.substitute(v, base, X1p)
    H = ca.substitute(ca.jacobian(v, zp), zp, ca.DM.zeros(NZ))
    return ca.Function(f"{disc.scheme}_adjoint_variation_jacobian{'_p' if theta else ''}", [X, w, lam, h, c0, *theta],
                       [H], ["X", "w", "lam", "h", "c0"] + (["theta"] if theta else []), ["H"])


def linearization_functions(disc: Discretization) -> tuple[ca.Function, ca.Function]:
    """(costate_hessian, linearized_map): the linearization of the costate forward map (docs/mathematics.md §6
    (29)-(31)) along the rollout of ``costate_functions(disc, parametric=True)``.

    costate_hessian (X[18], lam_prev[12], lam[12], c[3], h, Winv[6x6], bd[NB], theta) -> H[12x12]  (theta =
        ``model.parameters`` as data: one Function for every model of the structure)
        H_k = d/dz [A(chart(X_k, z), w_k)^T lambda_k] at z = 0 (:func:`adjoint_variation_jacobian` at
        orthonormalized(X_k), as A_k; w_k its stage control, lgvi: u_k from lam_prev; seeded with the costate map's
        Cayley root c).  With a body-fixed force lam is lambda'_k (the map's lamp) and H, A, dZ, dlam are in
        body-momentum coordinates (§15); lam_prev stays the tangent-coordinate costate u_k is read from.
    linearized_map (dZ[12x12], dlam[12x12], A[12x12], H[12x12], Dk[6x6], D1[6x6], h, Winv[6x6]) -> (dZ1, dlam1)
        the derivatives of z_k (tangent coordinates, §4) and lambda_{k-1} by the shooting unknown to those of
        z_{k+1} and lambda_k; iterated (``mapaccum``) from the first step's: dz_N/dlambda_0 = Psi_12.

    Differentiating lambda_{k-1} = A_k^T lambda_k and z_{k+1} = A_k z_k + B du_{k+1}:

        dlambda_k = A_k^-T (dlambda_{k-1} - H_k dz~_k)
        dz_{k+1}  = A_k dz~_k + B_c du_{k+1},     du_{k+1} = -(s/h) D_{k+1} Winv B_c^T dlambda_k

    (D_{k+1} the saturation's Jacobian at u_{k+1}; I without bounds), dz~_k = dz_k (first_order) or dz_k + B^b du_k,
    du_k = -(s/h) D_k Winv B_c^T dlambda_{k-1} (lgvi: u_k is the momentum kick B^b u_k, so A(X_k, u_k + du) =
    A(chart(X_k, B^b du), u_k) and B^a_k = A_k B^b; LGVI_CONDITIONS).  The 12 right-hand sides share one elimination
    (:func:`unpivoted_elimination` of A_k^T, :func:`unpivoted_substitution` per column).

    Three per-step Functions (costate map, H, this update) rather than one: each smaller to compile, compiled
    concurrently, and X_k, lambda_k, A_k those of the residual's own rollout (their sizes: docs/mathematics.md §6).
    Psi equals forward AD through the rollout (tests/test_perf_structure.py).
    """
    hessian = _costate_hessian_function(disc)
    return hessian, _linearized_map_function(disc, hessian.sparsity_out("H"))


def _costate_hessian_function(disc: Discretization) -> ca.Function:
    """``{scheme}_costate_hessian`` of :func:`linearization_functions`."""
    X = ca.SX.sym("X", NX)
    lam_prev = ca.SX.sym("lam_prev", NZ)
    lam = ca.SX.sym("lam", NZ)
    c = ca.SX.sym("c", 3)
    h = ca.SX.sym("h")
    Winv = ca.SX.sym("Winv", NU, NU)
    bd = ca.SX.sym("bd", NB)
    theta = ca.SX.sym("theta", disc.model.parameters.size)
    zero = ca.DM.zeros(NU)
    R = split_state(X)[2]
    wA = zero if disc.scheme == "first_order" else ca.vertcat(node_law(disc, h, Winv, bd)(lam_prev, R)[0], zero)
    H = adjoint_variation_jacobian(disc, True)(orthonormalized(X), wA, lam, h, c, theta)
    return ca.Function(f"{disc.scheme}_costate_hessian_p", [X, lam_prev, lam, c, h, Winv, bd, theta], [H],
                       ["X", "lam_prev", "lam", "c", "h", "Winv", "bd", "theta"], ["H"])


def _linearized_map_function(disc: Discretization, spH: ca.Sparsity) -> ca.Function:
    """``{scheme}_linearized_map`` of :func:`linearization_functions`, at the MX level (matrix products, a map
    of the column solve): compact C, cheap to compile."""
    spA = costate_functions(disc, True)[0].sparsity_out("A")         # its structural zeros save operations
    As = ca.SX.sym("A", spA)
    LUs = unpivoted_elimination(As.T)
    factor = ca.Function(f"{disc.scheme}_costate_factor", [As], [LUs], ["A"], ["LU"])
    LUc, col = ca.SX.sym("LU", LUs.sparsity()), ca.SX.sym("b", NZ)
    column_solve = ca.Function(f"{disc.scheme}_costate_column_solve", [LUc, col], [unpivoted_substitution(LUc, col)],
                               ["LU", "b"], ["y"])
    A = ca.MX.sym("A", spA)
    Hm = ca.MX.sym("H", spH)
    dZ = ca.MX.sym("dZ", NZ, NZ)
    dlam = ca.MX.sym("dlam", NZ, NZ)
    Dk = ca.MX.sym("Dk", NU, NU)
    D1 = ca.MX.sym("D1", NU, NU)
    hm = ca.MX.sym("h")
    Wm = ca.MX.sym("Winv", NU, NU)
    Bm = control_matrix(disc)(hm)
    G = -control_scale(disc) * ca.mtimes(Wm, Bm.T) / hm             # the unsaturated control by lambda

    def M(D):                                                      # dz_{k+1} by lambda through the control
        return ca.mtimes(Bm, ca.mtimes(D, G))

    dZk = dZ if disc.scheme == "first_order" else dZ + ca.mtimes(M(Dk), dlam)
    solve_columns = column_solve.map(f"{disc.scheme}_costate_column_solve_map", "serial", NZ, [0], [])
    dlam1 = solve_columns(factor(A), dlam - ca.mtimes(Hm, dZk))
    dZ1 = ca.mtimes(A, dZk) + ca.mtimes(M(D1), dlam1)
    return ca.Function(f"{disc.scheme}_linearized_map", [dZ, dlam, A, Hm, Dk, D1, hm, Wm], [dZ1, dlam1],
                       ["dZ", "dlam", "A", "H", "Dk", "D1", "h", "Winv"], ["dZ1", "dlam1"])


def terminal_residual_jacobian() -> ca.Function:
    """(XN[18], Xd[18]) -> (zN[12], J[12x12]): J = dzN(chart(XN, z))/dz at z = 0 (tangent coordinates)."""
    XN, Xd, z = ca.SX.sym("XN", NX), ca.SX.sym("Xd", NX), ca.SX.sym("z", NZ)
    zt = terminal_residual_function()(chart(XN, z), Xd)
    J = ca.substitute(ca.jacobian(zt, z), z, ca.DM.zeros(NZ))
    return ca.Function("terminal_residual_jac", [XN, Xd], [terminal_residual_function()(XN, Xd), J], ["XN", "Xd"],
                       ["zN", "J"])
