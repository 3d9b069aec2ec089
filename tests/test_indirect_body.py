"""The indirect method with a body-fixed force (docs/mathematics.md §15): the body-momentum costate coordinates,
E3 with force_frame 'body' against inertial E3 and the direct method, one body-fixed engine (ThrusterBound)
against an independent single-shooting NLP, both schemes.  Numbers measured are printed (run with -s)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NU, NX, U_FORCE, U_MOMENT, X_ROT, Z_ANG, Z_MOM
from se3ocp.transcription.dynamics.lgvi import discretization
from se3ocp.transcription.solve import solve_direct
from se3ocp.transcription.methods.indirect.control import bound_data, control_matrix, weight_inverse
from se3ocp.transcription.methods.indirect.coordinates import terminal_costate_function
from se3ocp.transcription.methods.indirect.shooting import shooting_functions
from se3ocp.transcription.methods.indirect.solve import lam0_from_costates, solve_indirect
from se3ocp.transcription.options import IndirectOptions
from se3ocp.transcription.ocp import (BoxBound, SmoothControl, TargetState, ThrusterBound, quadrature_weights, state_residual)
from se3ocp.transcription.objectives import Effort
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
    (initial_costate: from_direct, mapped by lam0_from_costates) Newton needs <= 3 iterations."""
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
    lam0 = lam0_from_costates(p, d.costates[0], d.controls[:, 0], u1=d.controls[:, 1])  # lgvi: A_0(X_0, [u_0; u_1])^T
    assert np.abs(lam0 - sb.warm.lam0).max() <= 1e-9 * np.abs(sb.warm.lam0).max()
    # iterations to |z_N| <= 1e-11 (those after it wander at the round-off level until the floor is detected: 0-2 more,
    # by the machine's rounding); the direct multipliers may already start there (0)
    reached = next(it.iteration for it in r.history if it.accepted and it.residual <= 1e-11)
    assert r.converged and r.stats["initial_costate"] == "from_direct" and reached <= 3
    assert r.terminal_error <= 1e-11


# ---------------------------------------------------------------- free terminal components (transversality)
@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_free_attitude_in_the_body_frame(scheme):
    """E3 (body frame, N = 40) with the attitude and its rate free: lambda_{N-1} = T(X_N)^T lambda'_{N-1} is zero on
    those blocks (<= 1e-12 of the largest; T mixes the attitude block with p x lambda'_p, so this checks the
    mapping and its derivative Q in the Jacobian) and the direct method agrees in cost to 1e-10."""
    p = body(support.problem("e3", 40, scheme))
    p = p.replace(terminal=TargetState(p.Xd, frozenset({"attitude", "angular_velocity"})))
    s = solve_indirect(p, IndirectOptions(eps_S=0.0))
    d = solve_direct(p)
    rel = abs(d.cost - s.cost) / d.cost
    lamN = s.costates[-1]
    print(f"E3 body {scheme}, attitude free: indirect {s.cost:.14g} ({s.iterations} it), direct {d.cost:.14g}: rel "
          f"{rel:.1e}; |lambda_N-1| on the free blocks {np.abs(lamN[6:]).max() / np.abs(lamN).max():.1e}")
    assert s.converged and d.converged and rel <= 1e-10
    assert np.abs(lamN[6:]).max() <= 1e-12 * np.abs(lamN).max()


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_box_bound_on_a_body_force(scheme, e3_solutions):
    """E3 (body frame, first order N = 100, LGVI N = 50) with the body-frame force boxed at 90 % of the free
    optimum's peaks per body axis: from lambda_0 = 0 (bound continuation) the indirect method reaches the floor,
    the box holds exactly and is active, and the direct method agrees (cost 1e-8, controls 1e-5 of the largest:
    its tolerance with bounds active; measured 1.0e-9 / 6.7e-10 and 1.5e-6 / 1.9e-6; 117 / 125 Newton iterations
    over the continuation's stages)."""
    p = e3_solutions[scheme][1].problem
    b = 0.9 * np.abs(e3_solutions[scheme][1].controls[U_FORCE]).max(axis=1)
    p = p.replace(control=SmoothControl(W_f=p.control.W_f, W_m=p.control.W_m, force_bound=BoxBound(b), objective=Effort()))
    s, d = solve_indirect(p, IndirectOptions(eps_S=0.0)), solve_direct(p)
    rel = abs(s.cost - d.cost) / d.cost
    u_rel = np.abs(s.controls - d.controls).max() / np.abs(d.controls).max()
    at = np.sum(np.abs(s.controls[U_FORCE]) == b[:, None])
    print(f"E3 body {scheme}, box: {s.result.value} in {s.iterations} it, direct {d.result.value}: cost {rel:.1e}, "
          f"controls {u_rel:.1e}; {at} components at the box")
    assert s.converged and s.terminal_error <= 1e-11 and d.converged
    assert np.all(np.abs(s.controls[U_FORCE]) <= b[:, None]) and at >= 3
    assert rel <= 1e-8 and u_rel <= 1e-5


# ---------------------------------------------------------------------------- one body-fixed engine
#: the engine test problem per scheme: T_max (chosen so that the engine is at max and at 0 on some nodes)
ENGINE_MAX = {"first_order": 3.5, "lgvi": 3.8}
#: a weight that is neither diagonal nor isotropic (q = W_f a / (a^T W_f a) != a)
ENGINE_WF = np.array([[1.0, 0.2, 0.0], [0.2, 2.0, 0.0], [0.0, 0.0, 0.5]])


def engine_problem(scheme: str, N: int = 50):
    """E3's body and start with the force in the body frame from one engine along body +y (the along-track
    direction at the start: the dumbbell turns with its orbit), 0 <= T <= ENGINE_MAX, to the state reached
    under T(t) = 6 max(0, sin(3 pi t / T_f)) with no moment (an orbit raise, so the target is reachable)."""
    p = body(support.problem("e3", N, scheme))
    n = p.disc.n_controls(N)
    U = np.zeros((NU, n))
    U[1] = 6.0 * np.maximum(0.0, np.sin(3.0 * np.pi * np.linspace(0.0, 1.0, n)))
    X, _ = p.disc.simulate(p.X0, U, p.h, N)
    engine = ThrusterBound([0.0, 1.0, 0.0], ENGINE_MAX[scheme], 0.0)
    return p.replace(terminal=TargetState(X[-1]),
                     control=SmoothControl(W_f=ENGINE_WF, W_m=p.control.W_m, force_bound=engine, objective=Effort()))


def independent_nlp(p):
    """The engine problem by a formulation independent of both methods: IPOPT (exact Hessian, tol 1e-12, no bound
    relaxation) on the thrusts T_j, the moments and the node states, rows step(X_k, w_k) - X_{k+1} with
    disc.step and the terminal residual.  Returns (status, cost, controls 6 x n)."""
    d, N, n, a = p.disc, p.N, p.disc.n_controls(p.N), p.control.force_bound.axis
    Xs, ws = ca.SX.sym("X", NX), ca.SX.sym("w", d.nw)
    step_x = ca.Function("step_x", [Xs, ws], [d.step(Xs, ws, p.h)[0]])     # the states only (no residual norm)
    V, Xv = ca.MX.sym("V", 4, n), ca.MX.sym("Xv", NX, N)
    U = ca.vertcat(ca.mtimes(ca.DM(a), V[0, :]), V[1:, :])
    defects = step_x.map(N)(ca.horzcat(ca.DM(p.X0), Xv[:, :-1]), d.stage_controls(U)) - Xv
    omega = ca.DM(quadrature_weights(p.scheme, N, p.h)).T
    J = 0.5 * ca.sum2(omega * ca.sum1(U * ca.mtimes(ca.DM(p.control.W), U)))
    g = ca.vertcat(ca.vec(defects), state_residual(Xv[:, -1], ca.DM(p.Xd)))
    S = ca.nlpsol("engine_nlp", "ipopt", {"x": ca.vertcat(ca.vec(V), ca.vec(Xv)), "f": J, "g": g},
                  {"ipopt.tol": 1e-12, "ipopt.print_level": 0, "print_time": False, "ipopt.bound_relax_factor": 0.0,
                   "ipopt.sb": "yes"})
    b = p.control.force_bound
    V0 = np.vstack([np.full(n, 0.5 * b.max), np.zeros((3, n))])
    X0 = d.simulate(p.X0, np.vstack([np.outer(a, V0[0]), V0[1:]]), p.h, N)[0][1:].T
    inf = np.full(3, np.inf)
    r = S(x0=np.r_[V0.ravel(order="F"), X0.ravel(order="F")], lbg=0, ubg=0,
          lbx=np.r_[np.tile(np.r_[b.min, -inf], n), np.full(NX * N, -np.inf)],
          ubx=np.r_[np.tile(np.r_[b.max, inf], n), np.full(NX * N, np.inf)])
    Vs = np.array(r["x"])[:4 * n].reshape(4, n, order="F")
    return S.stats()["return_status"], float(r["f"]), np.vstack([np.outer(a, Vs[0]), Vs[1:]])


@pytest.fixture(scope="module")
def engine_solutions():
    return {scheme: solve_indirect(engine_problem(scheme), IndirectOptions(eps_S=0.0)) for scheme in ENGINE_MAX}


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_engine_law_and_bounds(scheme, engine_solutions):
    """From lambda_0 = 0 (bound continuation: the free body force first) Newton reaches the round-off floor
    (terminal error <= 1e-11); the force is T a exactly, 0 <= T <= max with both bounds active at some nodes, and
    T_j = clip(-(s/h) a^T R_j^T lambda_gamma / (a^T W_f a), 0, max) from the tangent-coordinate costates (to 1e-10
    of max), u_m = -W_m^-1 lambda_Pi."""
    s = engine_solutions[scheme]
    p, U, lam = s.problem, s.controls, s.costates
    b = p.control.force_bound
    T = b.thrust(U[U_FORCE].T)
    print(f"engine {scheme}: {s.result.value} in {s.iterations} it ({s.stats.get('bound_continuation')}), |z_N| "
          f"{s.terminal_error:.1e}, cost {s.cost:.14g}; T at 0: {np.sum(T == 0.0)}, at max: {np.sum(T == b.max)} of "
          f"{T.size}")
    assert s.converged and s.terminal_error <= 1e-11
    assert np.abs(b.off_axis(U[U_FORCE].T)).max() <= 1e-15 * b.max
    assert T.min() >= 0.0 and T.max() <= b.max and np.sum(T == 0.0) >= 2 and np.sum(T == b.max) >= 2
    if scheme == "lgvi":
        A0 = np.array(p.disc.variation(p.X0, p.disc.stage_controls(U)[:, 0], p.h)[0])
        lam = np.vstack([A0.T @ lam[0], lam])                                # u_j from lambda_{j-1}
    mu = np.einsum("kji,kj->ki", attitudes(s), lam[:, Z_MOM])                # R_j^T lambda_gamma (body)
    a, Wf = b.axis, p.control.W_f
    law = np.clip(-mu @ a / (a @ Wf @ a), b.min, b.max)                      # s B^T / h = I on the gamma rows
    assert np.abs(T - law).max() <= 1e-10 * b.max
    assert np.abs(U[U_MOMENT] + np.linalg.solve(p.control.W_m, lam[:, Z_ANG].T)).max() <= 1e-10 * np.abs(U).max()


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_engine_agrees_with_an_independent_nlp(scheme, engine_solutions):
    """Direct = indirect with one engine: the independent NLP (IPOPT, tol 1e-12) and the indirect method agree in
    cost to 1e-9 and in controls to 1e-6 relative (measured ~1e-12 and 1e-10..1e-8)."""
    s = engine_solutions[scheme]
    status, cost, U = independent_nlp(s.problem)
    rel = abs(cost - s.cost) / s.cost
    u_rel = np.abs(U - s.controls).max() / np.abs(s.controls).max()
    print(f"engine {scheme}: NLP {status} {cost:.14g}, indirect {s.cost:.14g}: rel {rel:.1e}, controls {u_rel:.1e}")
    assert status == "Solve_Succeeded" and rel <= 1e-9 and u_rel <= 1e-6


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_engine_psi_equals_forward_ad(scheme, engine_solutions):
    """Psi and dlambda_{N-1}/dlambda_0 (body-momentum coordinates, the engine saturating at both ends) equal
    CasADi's forward AD through the rollout, to 1e-10 relative."""
    s = engine_solutions[scheme]
    p = s.problem
    fns = shooting_functions(p.disc, p.N)
    args = (p.X0, p.Xd, p.h, weight_inverse(p), bound_data(p))
    lam0 = s.warm.lam0 * (1.0 + 1e-3 * np.random.default_rng(2).standard_normal(12))
    l = ca.MX.sym("l", 12)
    zN, lamN, _ = fns.residual(l, *args)
    P_ad, L_ad = (np.array(a) for a in ca.Function("ad", [l], [ca.jacobian(zN, l), ca.jacobian(lamN, l)])(lam0))
    _, P, L = (np.array(a) for a in fns.shoot_jac(lam0, *args))
    T = p.control.force_bound.thrust(np.array(fns.shoot(lam0, *args)[3])[U_FORCE].T)
    assert np.sum(T == 0.0) >= 2 and np.sum(T == p.control.force_bound.max) >= 2
    assert np.abs(P - P_ad).max() <= 1e-10 * np.abs(P_ad).max()
    assert np.abs(L - L_ad).max() <= 1e-10 * np.abs(L_ad).max()


@pytest.mark.slow
def test_leo_body_engine_direct_equals_indirect():
    """configs/leo_body_engine.yaml (its lgvi_kepler scheme, N = 400, one engine along body +x, 0 <= T <= 1 N, km;
    measured on it: cost 8.0e-10, controls 1.6e-6, 2 iterations, direct 103 iterations in 8 s) with the moment
    weight 1e13 (the config's 1e10 lets the attitude swing so far that single shooting from the direct solution
    does not converge: 50 iterations, |z_N| 9e-2 km): the direct method, then the indirect method from its
    multipliers (from_direct), reach the same optimum: cost to 1e-6 (measured 1.1e-9), controls to 2e-5 of the
    largest (measured 5.9e-6: the direct solution's accuracy, terminal error 2.6e-10 km, at the engine's switches),
    the round-off floor in <= 10 iterations (measured 8; |z_N| 5.0e-12 km).  The config's MinRadius (added by the central body, inactive) is
    dropped: the indirect method has no path constraints.  The direct solve takes ~20 s on a quiet machine."""
    man = support.maneuver("leo_body_engine", None, None, "control.weights.moment=1.0e13")
    p = man.problem.replace(constraints=())
    d = se3ocp.solve(p, "direct", direct=man.direct)
    r = solve_indirect(p, IndirectOptions(eps_S=0.0), warm=d.warm)
    b = p.control.force_bound
    rel = abs(d.cost - r.cost) / d.cost
    u_rel = np.abs(d.controls - r.controls).max() / np.abs(r.controls).max()
    T = b.thrust(r.controls[U_FORCE].T)
    print(f"leo_body_engine (W_m 1e13): direct {d.cost:.12g} ({d.iterations} it), indirect {r.cost:.12g} ({r.iterations} "
          f"it, |z_N| {r.terminal_error:.1e} km): rel {rel:.1e}, controls {u_rel:.1e}; T at 0 on {np.sum(T == 0)}, at max "
          f"on {np.sum(T == b.max)} of {T.size} nodes")
    assert d.converged and r.converged and r.stats["initial_costate"] == "from_direct" and r.iterations <= 10
    assert r.terminal_error <= 1e-10 and rel <= 1e-6 and u_rel <= 2e-5
    assert np.abs(b.off_axis(r.controls[U_FORCE].T)).max() <= 1e-15 * b.max and T.min() >= 0 and T.max() <= b.max


def test_engine_max_is_continued_from_the_free_peak():
    """The engine problem with W_f = I, LGVI, T_max = 3.5: from lambda_0 = 0 the step from the free-force solution
    straight to the engine fails, and the staged path (T_max shrinking geometrically from the free force's peak,
    stage_bounds) reaches the floor; the optimum is the independent NLP's (cost to 1e-9).  stage_bounds leaves
    the axis and T_min, and gives the bounds themselves at t = 1."""
    from se3ocp.transcription.methods.indirect.continuation import stage_bounds
    from se3ocp.transcription.methods.indirect.control import THRUSTER

    p = engine_problem("lgvi")
    b = ThrusterBound(p.control.force_bound.axis, 3.5, 0.0)
    p = p.replace(control=SmoothControl(W_f=np.eye(3), W_m=p.control.W_m, force_bound=b, objective=Effort()))
    s = solve_indirect(p, IndirectOptions(eps_S=0.0))
    stages = s.stats["bound_continuation"]
    status, cost, _ = independent_nlp(p)
    print(f"engine lgvi, W_f = I, T_max 3.5: {s.result.value} in {s.iterations} it ({stages}); cost {s.cost:.14g}, NLP "
          f"{cost:.14g}")
    assert s.converged and s.terminal_error <= 1e-11 and len(stages) == 6 and "line_search_failed" in stages[1]
    assert status == "Solve_Succeeded" and abs(cost - s.cost) <= 1e-9 * s.cost
    bd = bound_data(p)
    peak = np.r_[np.full(NU, 10.0), 100.0, 100.0, 7.0]
    assert np.array_equal(stage_bounds(bd, peak, 1.0), bd)
    half = stage_bounds(bd, peak, 0.5)
    assert half[THRUSTER][7] == pytest.approx(np.sqrt(3.5 * 7.0), rel=1e-15)
    assert np.array_equal(np.delete(half, THRUSTER.start + 7), np.delete(bd, THRUSTER.start + 7))
