"""The indirect method on a non-uniform mesh (issue 26, docs/mathematics.md §16): step k of size h_k = r_k h in the
discrete necessary conditions of both schemes, checked against an independent formulation -- an NLP written here
with CasADi and IPOPT directly from ``disc.step(X_k, w_k, h_k)`` per step and the per-step quadrature (first order
omega_j = h_{j-1}; LGVI omega_j = (h_{j-1} + h_j) / 2) -- and the exact Jacobian Psi against derivatives taken
through the rollout.  N = 40 and an irregular mesh r_k = 1.5 + sin(2.3 k) (step sizes from 0.5 to 2.5 times the
mean, neighbours differing by up to a factor 4).  Numbers measured are printed (-s)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NU, NX
from se3ocp.transcription.dynamics.lgvi import discretization
from se3ocp.transcription.methods.indirect.control import bound_data, control_cost, weight_inverse
from se3ocp.transcription.methods.indirect.shooting import shooting_functions
from se3ocp.transcription.methods.indirect.solve import lam0_from_costates, solve_indirect
from se3ocp.transcription.options import IndirectOptions
from se3ocp.transcription.ocp import BoxBound, SmoothControl, TargetState, quadrature_weights, terminal_residual
from se3ocp.transcription.objectives import Effort
import support

N = 40
SCHEMES = ["first_order", "lgvi"]


def mesh(n: int = N) -> np.ndarray:
    """The test's relative step sizes: irregular, from 0.5 to 2.5."""
    return 1.5 + np.sin(2.3 * np.arange(n))


def on_mesh(name: str, scheme: str, n: int = N):
    """The bundled example ``name`` (e3, e4) with ``scheme`` on the test mesh."""
    return support.problem(name, n, scheme).replace(mesh=mesh(n))


def independent_nlp(p):
    """``p`` by a formulation independent of both methods: IPOPT (exact Hessian, tol 1e-12, no bound relaxation) on
    the node controls, the node states and, for a free final time, the mean step h; rows step(X_k, w_k, r_k h) -
    X_{k+1} with ``disc.step`` and the terminal residual of the fixed components; cost
    (1/2) sum_j omega_j u_j^T W u_j with omega = quadrature_weights on the steps r_k h.  Box bounds are variable
    bounds.  Started from the free motion on the mesh.  Returns (status, cost, controls 6 x n, T)."""
    d, n, r = p.disc, p.disc.n_controls(p.N), p.mesh
    Xs, ws, hs = ca.SX.sym("X", NX), ca.SX.sym("w", d.nw), ca.SX.sym("h")
    step_x = ca.Function("step_x", [Xs, ws, hs], [d.step(Xs, ws, hs)[0]])
    U, Xv = ca.MX.sym("U", NU, n), ca.MX.sym("Xv", NX, p.N)
    hm = ca.MX.sym("h") if p.free_time else p.h
    defects = step_x.map(p.N)(ca.horzcat(ca.DM(p.X0), Xv[:, :-1]), d.stage_controls(U), hm * ca.DM(r).T) - Xv
    omega = hm * ca.DM(quadrature_weights(p.scheme, p.N, r)).T
    J = 0.5 * ca.sum2(omega * ca.sum1(U * ca.mtimes(ca.DM(p.control.W), U)))
    x = ca.vertcat(ca.vec(U), ca.vec(Xv), *([hm] if p.free_time else []))
    g = ca.vertcat(ca.vec(defects), terminal_residual(Xv[:, -1], p.terminal))
    S = ca.nlpsol("mesh_nlp", "ipopt", {"x": x, "f": J, "g": g},
                  {"ipopt.tol": 1e-12, "ipopt.print_level": 0, "print_time": False, "ipopt.bound_relax_factor": 0.0,
                   "ipopt.sb": "yes"})
    b = p.control.force_bound.b if isinstance(p.control.force_bound, BoxBound) else np.full(3, np.inf)
    ub = np.tile(np.r_[b, np.full(3, np.inf)], n)
    X0 = d.simulate(p.X0, None, p.steps, p.N)[0][1:].T
    lo, hi = (np.array(p.time_bounds) / p.N) if p.free_time else (None, None)
    r_ = S(x0=np.r_[np.zeros(NU * n), X0.ravel(order="F"), [p.h] if p.free_time else []], lbg=0, ubg=0,
           lbx=np.r_[-ub, np.full(NX * p.N, -np.inf), [lo] if p.free_time else []],
           ubx=np.r_[ub, np.full(NX * p.N, np.inf), [hi] if p.free_time else []])
    xs = np.array(r_["x"]).ravel()
    T = xs[-1] * p.N if p.free_time else p.T
    return S.stats()["return_status"], float(r_["f"]), xs[:NU * n].reshape(NU, n, order="F"), T


def agreement(s, nlp) -> tuple[float, float]:
    """(relative cost difference, largest control difference relative to the largest control)."""
    _, cost, U, _ = nlp
    return abs(s.cost - cost) / cost, np.abs(s.controls - U).max() / np.abs(U).max()


def body(p):
    """The Problem p with its force in the body frame (docs/mathematics.md §15)."""
    return p.replace(disc=discretization(p.model, p.scheme, p.disc.newton_iters, "body"))


@pytest.fixture(scope="module")
def from_zero():
    """The indirect solutions of E3 and E4 on the mesh from lambda_0 = 0, both schemes."""
    return {(name, scheme): solve_indirect(on_mesh(name, scheme), IndirectOptions())
            for name in ("e3", "e4") for scheme in SCHEMES}


# ------------------------------------------------------------- the conditions against an independent NLP
@pytest.mark.parametrize("name", ["e3", "e4"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_conditions_on_a_mesh_agree_with_an_independent_nlp(name, scheme, from_zero):
    """E3 and E4 on the mesh: from lambda_0 = 0 the indirect method converges (as on a uniform mesh; 6-9 Newton iterations
    measured), and its optimum is the independent NLP's: cost to 1e-10 relative and controls to 1e-10 of the largest
    (measured <= 8e-15 both; issue 26 asks 1e-8). The mesh matters: the same problem on uniform steps has a cost more
    than 1e-4 away (4.9e-4 for E3 with the LGVI). The Solution's node times are the mesh's and its cost the per-step
    quadrature of its controls."""
    s = from_zero[name, scheme]
    p = s.problem
    nlp = independent_nlp(p)
    rel, u_rel = agreement(s, nlp)
    uniform = solve_indirect(support.problem(name, N, scheme), IndirectOptions())
    print(f"{name} {scheme} on the mesh: indirect {s.result.value} in {s.iterations} it, cost {s.cost:.15g}; NLP "
          f"{nlp[0]} {nlp[1]:.15g}: cost {rel:.1e}, controls {u_rel:.1e}; uniform cost {uniform.cost:.10g}")
    assert s.converged and s.terminal_error <= 1e-11 and nlp[0] == "Solve_Succeeded"
    assert rel <= 1e-10 and u_rel <= 1e-10
    assert abs(uniform.cost - s.cost) > 1e-4 * s.cost
    np.testing.assert_array_equal(s.trajectory.t, p.times)
    assert s.cost == pytest.approx(control_cost(p, s.controls), rel=1e-14)
    w = quadrature_weights(scheme, N, p.steps)
    assert s.cost == pytest.approx(0.5 * np.einsum("k,ik,ij,jk->", w, s.controls, p.control.W, s.controls), rel=1e-14)


def extended(case: str, scheme: str, free_solution):
    """E3 on the mesh with the indirect method's extensions: 'box' the force boxed at 90 % of the unbounded optimum's
    peaks per axis (``free_solution``'s); 'free' free terminal attitude and rate (lambda_{N-1} = 0 on them);
    'body_time' the force in the body frame (docs/mathematics.md §15) and a free final time in [0.8 T, 1.6 T].
    (A box on the body-frame force does not converge from lambda_0 = 0 at N = 40 by the bound continuation, on the
    uniform mesh either; it does at N = 100, tests/test_indirect_body.py.)"""
    p = on_mesh("e3", scheme)
    if case == "box":
        b = 0.9 * np.abs(free_solution.controls[:3]).max(axis=1)
        return p.replace(control=SmoothControl(W_f=p.control.W_f, W_m=p.control.W_m, force_bound=BoxBound(b), objective=Effort()))
    if case == "free":
        return p.replace(terminal=TargetState(p.Xd, frozenset({"attitude", "angular_velocity"})))
    return body(p).replace(time_bounds=(0.8 * p.T, 1.6 * p.T))


@pytest.mark.parametrize("case", ["box", "free", "body_time"])
@pytest.mark.parametrize("scheme", [pytest.param("first_order", marks=pytest.mark.slow), "lgvi"])
def test_extensions_on_a_mesh_agree_with_an_independent_nlp(case, scheme, from_zero):
    """The extensions on the mesh (first order: slow, 2-4 s each), from lambda_0 = 0 (with the bound continuation for the
    box) to the round-off floor, against the independent NLP: cost to 1e-10, controls to 1e-8 of the largest (IPOPT's
    accuracy at the box's corners; measured <= 1.6e-13 and <= 6.8e-11), T to 1e-12 relative. The box holds and is
    active."""
    p = extended(case, scheme, from_zero["e3", scheme])
    s = solve_indirect(p, IndirectOptions(eps_S=0.0))
    nlp = independent_nlp(p)
    rel, u_rel = agreement(s, nlp)
    print(f"e3 {scheme} {case} on the mesh: {s.result.value} in {s.iterations} it, T {s.T:.15g}; NLP {nlp[0]} "
          f"T {nlp[3]:.15g}: cost {rel:.1e}, controls {u_rel:.1e}")
    assert s.converged and s.terminal_error <= 1e-11 and nlp[0] == "Solve_Succeeded"
    assert rel <= 1e-10 and u_rel <= 1e-8 and abs(s.T - nlp[3]) <= 1e-12 * nlp[3]
    if case == "box":
        b = p.control.force_bound.b[:, None]
        assert np.all(np.abs(s.controls[:3]) <= b) and np.sum(np.abs(s.controls[:3]) == b) >= 2
    elif case == "body_time":
        assert abs(s.T - p.T) > 1e-3 * p.T and np.all(np.diff(s.trajectory.t) > 0)
        np.testing.assert_allclose(np.diff(s.trajectory.t), s.T / p.N * p.mesh, rtol=1e-12)


# ------------------------------------------------------------- the Jacobian and the shooting unknown
@pytest.mark.parametrize("frame", ["inertial", "body"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_psi_on_a_mesh(scheme, frame):
    """Psi on the mesh (the linearized recursion at the steps' own h_k) equals forward AD through the rollout to
    1e-10 relative (measured <= 3e-15) and central differences (step 1e-6 of |lambda_0|) to 1e-7 relative (measured
    6e-9); and dlambda_{N-1}/dlambda_0 by AD too.  N = 20, at a lambda_0 with controls of the optimum's size; the
    uniform mesh's Psi differs by more than 1e-3."""
    p = on_mesh("e3", scheme, 20)
    p = body(p) if frame == "body" else p
    fns = shooting_functions(p.disc, p.N)
    args = (p.X0, p.Xd, p.steps, weight_inverse(p), bound_data(p))
    lam = np.random.default_rng(3).standard_normal(12) * 0.01
    assert float(fns.residual(lam, *args)[2]) <= 1e-10
    l = ca.MX.sym("l", 12)
    z, lamN, _ = fns.residual(l, *args)
    P_ad, L_ad = (np.array(ca.Function("ad", [l], [ca.jacobian(e, l)])(lam)) for e in (z, lamN))
    _, P, L = (np.array(a) for a in fns.shoot_jac(lam, *args))
    eps = 1e-6 * np.abs(lam).max()
    P_fd = np.column_stack([(np.array(fns.residual(lam + eps * e, *args)[0]) -
                             np.array(fns.residual(lam - eps * e, *args)[0])).ravel() / (2 * eps) for e in np.eye(12)])
    print(f"{scheme} {frame}: |Psi - AD| {np.abs(P - P_ad).max() / np.abs(P_ad).max():.1e}, |Psi - FD| "
          f"{np.abs(P - P_fd).max() / np.abs(P).max():.1e}")
    assert np.abs(P - P_ad).max() <= 1e-10 * np.abs(P_ad).max()
    assert np.abs(L - L_ad).max() <= 1e-10 * np.abs(L_ad).max()
    assert np.abs(P - P_fd).max() <= 1e-7 * np.abs(P).max()
    # not the uniform mesh's Jacobian
    P_u = np.array(fns.shoot_jac(lam, p.X0, p.Xd, p.h, weight_inverse(p), bound_data(p))[1])
    assert np.abs(P - P_u).max() > 1e-3 * np.abs(P).max()


@pytest.mark.parametrize("frame", ["inertial", "body"])
def test_lam0_from_costates_takes_step_0(frame, from_zero):
    """LGVI on the mesh: the shooting unknown lambda_{-1} = A_0^T lambda_0 from a solution's costates is taken at
    step 0's size h_0 = r_0 h (to 1e-12 of the solution's own unknown; at the mean h it is not), and a warm start
    that carries only the costates (as a direct solution's) converges in <= 2 iterations."""
    s = from_zero["e3", "lgvi"]
    if frame == "body":
        s = solve_indirect(body(s.problem), IndirectOptions())
    p, U = s.problem, s.controls
    lam0 = lam0_from_costates(p, s.costates[0], U[:, 0], u1=U[:, 1])
    assert np.abs(lam0 - s.warm.lam0).max() <= 1e-12 * np.abs(s.warm.lam0).max()
    mean = lam0_from_costates(p.replace(mesh=None), s.costates[0], U[:, 0], u1=U[:, 1])
    assert np.abs(mean - s.warm.lam0).max() > 1e-6 * np.abs(s.warm.lam0).max()
    warm = s.warm.__class__(t=s.warm.t, X=s.warm.X, U=U, scheme="lgvi", source="direct", costates=s.costates)
    again = solve_indirect(p, IndirectOptions(), warm=warm)
    assert again.converged and again.iterations <= 2 and again.cost == pytest.approx(s.cost, rel=1e-12)
    assert not again.stats["warm_start_resampled"]   # fitted to the mesh's own node times: nothing resampled


# ------------------------------------------------------------- direct = indirect on the same mesh (issue 26)
@pytest.mark.parametrize("name", ["e3", "e4"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_direct_equals_indirect_on_a_mesh(name, scheme):
    """Issue 26's acceptance: solve(problem, 'both') on the mesh, E3 and E4, both schemes -- both converge, cost
    and controls agree to 1e-8 (measured <= 6.4e-15 and <= 7.7e-15) and compare says "agree"."""
    c = se3ocp.solve(on_mesh(name, scheme), "both")
    d, i = c.solutions["direct"], c.solutions["indirect"]
    print(f"{name} {scheme} on the mesh: direct {d.iterations} it, indirect {i.iterations} it: cost "
          f"{c.cost_relative_difference:.1e}, controls {c.control_max_difference_relative:.1e}; {c.verdict}")
    assert d.converged and i.converged and c.verdict.startswith("agree")
    assert c.cost_relative_difference <= 1e-8 and c.control_max_difference_relative <= 1e-8
    np.testing.assert_array_equal(d.trajectory.t, i.trajectory.t)


def test_from_direct_with_a_free_final_time_on_a_mesh():
    """The indirect method started from the direct solution on the mesh (initial_costate from_direct: lambda_{-1}
    at step 0's size, T the direct one's) with a free final time, LGVI: converges, T and the cost equal the
    direct ones to 1e-10 (measured T 2e-16, controls 2e-11)."""
    p = on_mesh("e3", "lgvi").replace(time_bounds=(0.4, 0.8))
    d = se3ocp.solve(p, "direct")
    s = se3ocp.solve(p, "indirect", indirect=IndirectOptions(initial_costate="from_direct"), warm_start=d)
    print(f"from_direct, free T on the mesh: {s.result.value} in {s.iterations} it, T {s.T:.15g} (direct {d.T:.15g})")
    assert s.converged and s.stats["initial_costate"] == "from_direct" and s.iterations <= 10
    assert abs(s.T - d.T) <= 1e-10 * d.T and abs(s.cost - d.cost) <= 1e-10 * d.cost


@pytest.mark.parametrize("scheme", SCHEMES)
def test_mpc_replans_on_the_remaining_steps_of_a_mesh(scheme):
    """MPC's re-plan (transcription.closedloop.mpc.Replanner) on a mesh takes the remaining horizon's own steps h_k: from the
    direct plan's own node k (k = 0: its costates mapped at h_0), one Newton step reproduces the remaining plan,
    controls to 1e-10 relative and states to 1e-10 (as on a uniform mesh, tests/test_mpc.py), node times the mesh's."""
    from se3ocp.transcription.closedloop.mpc import Replanner
    p = on_mesh("e3", scheme)
    sol = se3ocp.solve(p, "direct")
    rp = Replanner(p, sol.h, jit=False)
    start = rp.start(sol.warm)
    scale = np.abs(sol.controls).max()
    for k in (0, 13, 30):
        new, rec = rp.replan(sol.trajectory.X[k], start.tail(k), k)
        du = np.abs(new.U - sol.controls[:, k:]).max() / scale
        dX = np.abs(new.X - sol.trajectory.X[k:]).max()
        print(f"mpc {scheme} on the mesh, k = {k}: controls {du:.1e}, states {dX:.1e}")
        assert rec.accepted and du <= 1e-10 and dX <= 1e-10
        np.testing.assert_allclose(new.t, p.times[k:] - p.times[k], rtol=1e-13, atol=1e-16)


def test_the_fallback_from_the_direct_solution_on_a_mesh():
    """A cold start that fails (one Newton iteration allowed, from lambda_0 = 0) is started again from the direct
    solution on the same mesh (its costates at the mesh's node times, lambda_{-1} at h_0), which converges within
    that one iteration to the direct cost (1e-10)."""
    p = on_mesh("e3", "lgvi")
    s = se3ocp.solve(p, "indirect", indirect=IndirectOptions(max_iter=1))
    print(f"fallback on the mesh: {s.result.value}, {s.stats['fallback']}, {s.trace}")
    assert s.converged and s.stats["fallback"] == "from_direct" and not s.trace[0].result.successful
    assert abs(s.cost - s.stats["direct_cost"]) <= 1e-10 * s.cost


@pytest.mark.slow
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_direct_equals_indirect_on_the_adaptive_mesh(name):
    """Both methods refined together to accuracy 1e-4 (LGVI, from the config's N = 500): the last level is an
    adaptive mesh (steps h_max / h_min > 2), both converge on it and agree to 1e-8 (measured E3: N 500 -> 1001,
    h_max / h_min 6.6, cost 1.1e-14, controls 1.6e-14; E4: 500 -> 965, 4.3, 3.8e-15, 2.0e-14; ~20 s each)."""
    b = se3ocp.solve(support.maneuver(name, None, "lgvi"), "both", accuracy=1e-4)
    d, i = b.direct, b.indirect
    steps = np.diff(d.trajectory.t)
    print(f"{name} adaptive: N {[r['N'] for r in d.mesh]}, h_max/h_min {steps.max() / steps.min():.2f}, cost "
          f"{b.cost_relative_difference:.1e}, controls {b.control_max_difference_relative:.1e}; {b.verdict}")
    assert d.mesh[-1]["mesh"] == "adaptive" and steps.max() > 2 * steps.min()
    assert d.converged and i.converged and b.verdict.startswith("agree")
    assert b.cost_relative_difference <= 1e-8 and b.control_max_difference_relative <= 1e-8
