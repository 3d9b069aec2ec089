"""The indirect method with a body-fixed force (docs/mathematics.md §15): the body-momentum costate coordinates,
E3 with force_frame 'body' against inertial E3 and the direct method, one body-fixed engine (ThrusterBound)
against an independent single-shooting NLP, both schemes.  Numbers measured are printed (run with -s)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.layout import NU, NX, U_FORCE, U_MOMENT, X_ROT, Z_ANG, Z_MOM
from se3ocp.transcription.lgvi import discretization
from se3ocp.transcription.methods.direct import solve_direct
from se3ocp.transcription.methods.indirect.control import bound_data, control_matrix, weight_inverse
from se3ocp.transcription.methods.indirect.coordinates import terminal_costate_function
from se3ocp.transcription.methods.indirect.shooting import shooting_functions
from se3ocp.transcription.methods.indirect.solve import lam0_from_costates, solve_indirect
from se3ocp.transcription.options import IndirectOptions
from se3ocp.transcription.problem import SmoothControl, TargetState, ThrusterBound, quadrature_weights, state_residual
import support

#: E3 sizes per scheme (as tests/test_indirect.py: first order N = 100, LGVI N = 50)
SIZES = {"first_order": 100, "lgvi": 50}


def body(p):
    """The Problem p with its force in the body frame (same model, scheme, data)."""
    return p.replace(disc=discretization(p.model, p.scheme, p.disc.newton_iters, "body"))


def attitudes(sol) -> np.ndarray:
    """R_j (n_controls, 3, 3) at the nodes the controls belong to (first order u_1..u_N at X_1..X_N)."""
    X = sol.trajectory.X
    X = X if sol.problem.scheme == "lgvi" else X[1:]
    return X[:, X_ROT].reshape(-1, 3, 3).transpose(0, 2, 1)


def frames(X):
    """(T(X)^T, T(X)^-1) as NumPy arrays."""
    _, Tt, _, Tinv = terminal_costate_function()(X, np.zeros(12))
    return np.array(Tt), np.array(Tinv)


# ------------------------------------------------------------- the change of coordinates
@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_body_momentum_coordinates_make_the_recursion_explicit(scheme):
    """In z, A_k of a body-force step depends on u_{k+1} (the term -c R_{k+1} S(u_f) of the rotation column); in
    z' = T z, A'_k = T(X_{k+1}) A_k T(X_k)^-1 does not (to 1e-13 relative), and T(X_{k+1}) B_k is the inertial
    scheme's constant control matrix (to 1e-15)."""
    p = body(support.problem("e3", 10, scheme))
    d, rng = p.disc, np.random.default_rng(7)
    X = np.array(d.step(p.X0, rng.standard_normal(d.nw), p.h)[0]).ravel()    # a state with gamma, R generic
    Bc = np.array(control_matrix(d)(p.h))
    for _ in range(3):
        w = rng.standard_normal(d.nw) * 3.0
        w2 = np.r_[w[:-NU], rng.standard_normal(NU) * 3.0]                   # another u_{k+1}
        out = []
        for ww in (w, w2):
            A, B = (np.array(a) for a in d.variation(X, ww, p.h))
            X1 = np.array(d.step(X, ww, p.h)[0]).ravel()
            T1 = frames(X1)[0].T
            out.append((A, T1 @ A @ frames(X)[1], T1 @ B[:, -NU:]))
        (A, Ap, TB), (A2, Ap2, TB2) = out
        assert np.abs(A - A2).max() > 1e-3 * np.abs(A).max()                 # z: depends on u_{k+1}
        assert np.abs(Ap - Ap2).max() <= 1e-13 * np.abs(Ap).max()
        assert np.abs(TB - Bc).max() <= 1e-15 and np.abs(TB2 - Bc).max() <= 1e-15


# ------------------------------------------------------------------------ E3 in the body frame
@pytest.fixture(scope="module")
def e3_solutions():
    """Indirect E3, inertial and body frame, from lambda_0 = 0 to the round-off floor, both schemes."""
    out = {}
    for scheme, N in SIZES.items():
        p = support.problem("e3", N, scheme)
        out[scheme] = (solve_indirect(p, IndirectOptions(eps_S=0.0)), solve_indirect(body(p), IndirectOptions(eps_S=0.0)))
    return out


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_e3_in_the_body_frame_is_inertial_e3(scheme, e3_solutions):
    """W_f = I, so u_f -> R u_f is a change of variables: the body-frame optimum is inertial E3's, cost to 1e-10
    relative (measured ~1e-15), controls u_{f,j} = R_j^T u_{f,j}(inertial) to 1e-9 of the largest; Newton from
    lambda_0 = 0 stops at the round-off floor with the re-simulated terminal error <= 1e-11."""
    si, sb = e3_solutions[scheme]
    assert si.converged and sb.converged and sb.terminal_error <= 1e-11
    rel = abs(sb.cost - si.cost) / si.cost
    R = attitudes(sb)
    uf = np.einsum("kji,jk->ik", R, si.controls[U_FORCE])                     # R_j^T u_f,j (inertial)
    du = max(np.abs(sb.controls[U_FORCE] - uf).max(), np.abs(sb.controls[U_MOMENT] - si.controls[U_MOMENT]).max())
    print(f"E3 {scheme}: body {sb.cost:.14g} ({sb.iterations} it, |z_N| {sb.terminal_error:.1e}), inertial "
          f"{si.cost:.14g} ({si.iterations} it): rel {rel:.1e}, controls {du / np.abs(si.controls).max():.1e}")
    assert rel <= 1e-10
    assert du <= 1e-9 * np.abs(si.controls).max()


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_e3_body_frame_conditions_and_the_direct_method(scheme, e3_solutions):
    """The costates (tangent coordinates) satisfy the conditions of §15 written in z: lambda_{k-1} = A_k(X_k, w_k)^T
    lambda_k with the full stage control, u_{f,j} = -(s/h) W_f^-1 R_j^T (B^T lambda)_gamma; the direct method on
    the same body-frame problem agrees (cost 1e-10, controls and multipliers 1e-6), and from its multipliers
    (initial_costate: from_direct, mapped by lam0_from_costates) Newton needs <= 2 iterations."""
    _, sb = e3_solutions[scheme]
    p = sb.problem
    X, U, lam = sb.trajectory.X, sb.controls, sb.costates
    W = p.disc.stage_controls(U)
    for k in range(1, p.N):
        A = np.array(p.disc.variation(X[k], W[:, k], p.h)[0])
        assert np.abs(A.T @ lam[k] - lam[k - 1]).max() <= 1e-9 * np.abs(lam[k - 1]).max()
    R = attitudes(sb)
    lam_prev = lam if scheme == "first_order" else None
    if scheme == "lgvi":   # u_j from lambda_{j-1}, lambda_{-1} = A_0^T lambda_0
        A0 = np.array(p.disc.variation(X[0], W[:, 0], p.h)[0])
        lam_prev = np.vstack([A0.T @ lam[0], lam])
    uf = -np.einsum("kji,kj->ik", R, lam_prev[:, Z_MOM])                      # W_f = I; s B^T / h picks lambda_gamma
    assert np.abs(U[U_FORCE] - uf).max() <= 1e-10 * np.abs(U).max()
    assert np.abs(U[U_MOMENT] + lam_prev[:, Z_ANG].T / 1e4).max() <= 1e-10 * np.abs(U).max()
    d = solve_direct(p)
    r = se3ocp.solve(p, "indirect", indirect=IndirectOptions(eps_S=0.0, initial_costate="from_direct"))
    rel = abs(d.cost - sb.cost) / sb.cost
    u_rel = np.abs(d.controls - U).max() / np.abs(U).max()
    l_rel = np.abs(d.costates - lam).max() / np.abs(lam).max()
    print(f"E3 body {scheme}: direct {d.cost:.14g} rel {rel:.1e}, controls {u_rel:.1e}, multipliers {l_rel:.1e}; "
          f"from_direct: {r.iterations} it, |z_N| {r.terminal_error:.1e}")
    assert d.converged and rel <= 1e-10 and u_rel <= 1e-6 and l_rel <= 1e-6
    assert r.converged and r.stats["initial_costate"] == "from_direct" and r.iterations <= 2
    assert r.terminal_error <= 1e-11
