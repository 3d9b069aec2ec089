"""The Dymos peer of scripts/peer_dymos.py (optional extra ``peer-dymos``): its hand-written ODE against
our model, the re-flight it shares with ours, and its optimum of Betts' reorientation.  Skipped
cleanly where OpenMDAO or Dymos is not installed."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from support import maneuver, problem

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

#: Betts (2010) sect. 6.8, the minimum time of configs/slew_time_optimal.yaml
BETTS_T = 28.6304077


def _peer(openmdao: bool = True):
    pytest.importorskip("scipy")
    if openmdao:
        pytest.importorskip("openmdao")
    import peer_dymos

    return peer_dymos


def test_the_peer_ode_is_our_model():
    """OrbitRaiseODE (quaternion kinematics and MacCullagh's force and moment written out by hand, as a
    Dymos user does) equals (1)-(4) with the force and moment of our model by AD, at random states, to
    round-off: the peer solves our problem, not a neighbour of it."""
    pd = _peer()
    from peer_rockit import _rhs_functions

    from se3ocp.transcription.geometry.state import pack_state
    from se3ocp.transcription.ocp import orbit_residual

    prob = problem("orbit_raise_fuel", 30)
    model, target = prob.model, prob.terminal
    rng = np.random.default_rng(7)
    nn = 6
    r = rng.normal(size=(nn, 3)) + np.array([1.2, 0.0, 0.0])
    v, w = rng.normal(size=(nn, 3)) * 6, rng.normal(size=(nn, 3))
    q = rng.normal(size=(nn, 4))
    q *= 1.3 / np.linalg.norm(q, axis=1, keepdims=True)      # not unit: the transcription does not keep |q| = 1
    s_f, s_m = rng.uniform(0, 40, nn), rng.uniform(0, 1, nn)
    d_f, d_m = rng.normal(size=(nn, 3)), rng.normal(size=(nn, 3))
    ode = pd.OrbitRaiseODE(num_nodes=nn, mass=float(model.mass), inertia=np.asarray(model.inertia, float),
                           mu=float(model.mu), radius=float(target.radius), basis=target.plane_basis(),
                           body_axis=target.body_axis, weights=(1.0, 1.0))
    out: dict = {}
    ode.compute({"r": r, "v": v, "q": q, "w": w, "s_f": s_f, "d_f": d_f, "s_m": s_m, "d_m": d_m}, out)
    rhs = _rhs_functions(model)
    J = model.inertia
    for k in range(nn):
        R = pd.quat_to_R(q[k])
        X = pack_state(r[k], model.mass * v[k], R, J @ w[k])
        dX = np.asarray(rhs(X, np.concatenate([s_f[k] * d_f[k], s_m[k] * d_m[k]]))).ravel()
        np.testing.assert_allclose(out["r_dot"][k], dX[0:3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(model.mass * out["v_dot"][k], dX[3:6], rtol=1e-13, atol=1e-11)
        # dPi/dt = Pi x Omega + M + u_m = J dw/dt for the body rates w = Omega
        np.testing.assert_allclose(J @ out["w_dot"][k], dX[15:18], rtol=1e-12, atol=1e-11)
        # d(R(q))/dt from dq/dt equals R S(w) (the kinematics (3)), also for |q| != 1
        eps = 1e-7
        dR = (pd.quat_to_R(q[k] + eps * out["q_dot"][k]) - pd.quat_to_R(q[k] - eps * out["q_dot"][k])) / (2 * eps)
        np.testing.assert_allclose(dR.reshape(-1, order="F"), dX[6:15], rtol=0, atol=1e-8)
        # the orbit-target rows are ours (orbit_residual's first seven, the momentum row in velocity)
        rows = orbit_residual(X, target, model.mass, model.mu)
        peer = np.concatenate([[out["radius_err"][k], out["plane_err"][k]], out["axis_err"][k], out["v_err"][k]])
        np.testing.assert_allclose(peer, rows[:7] / np.r_[1, 1, 1, 1, [model.mass] * 3], rtol=0, atol=1e-12)


def test_refly_is_exact_on_a_rigid_rotation():
    """The DOP853 re-flight (rtol = atol = 1e-12) under a constant torque about a principal axis from rest:
    Omega = tau t / J_1, R = R_x(tau t^2 / (2 J_1)); terminal error of the attitude and rate ~ 1e-11."""
    pd = _peer(openmdao=False)
    from se3ocp.transcription.geometry.state import unpack_states

    prob = problem("slew_time_optimal", 30)
    J1, tau, T = prob.model.inertia[0, 0], 50.0, 20.0
    times = np.linspace(0.0, T, 31)
    U = np.zeros((6, 31))
    U[3] = tau
    control, breaks = pd.hold(times, U)
    XN = pd.refly(prob.model, prob.X0, control, breaks)
    s = unpack_states(XN[None])
    th = tau * T**2 / (2 * J1)
    Rx = np.array([[1, 0, 0], [0, np.cos(th), -np.sin(th)], [0, np.sin(th), np.cos(th)]])
    assert np.abs(s.R[0] - Rx).max() < 1e-10
    assert abs(s.Pi[0][0] - tau * T) < 1e-9 * tau * T and np.abs(s.Pi[0][1:]).max() < 1e-12


def test_the_peers_reflight_agrees_with_the_continuous_check():
    """The script's DOP853 flight (which flies the peer) and the project's continuous check (CVODES,
    transcription.flight) fly our N = 30 solution of the symmetric slew to the same terminal error, to
    1e-8 relative (measured 6e-12 on Betts' slew): two integrators, one reading of the LGVI's controls."""
    pd = _peer(openmdao=False)
    import se3ocp
    from se3ocp.transcription.results.check import continuous_check
    from se3ocp.transcription.ocp import terminal_error

    s = se3ocp.solve(maneuver("slew_time_optimal_symmetric", 30), "direct")
    assert s.converged, s.message
    control, breaks = pd.hold(np.asarray(s.control_times, float), np.asarray(s.controls, float))
    mine = terminal_error(pd.refly(s.problem.model, s.problem.X0, control, breaks), s.problem)
    theirs = continuous_check(s).target_error
    assert mine > 1e-6 and abs(mine - theirs) <= 1e-8 * theirs, (mine, theirs)


def test_hold_is_the_schemes_control():
    """Ours between the nodes: the LGVI's node controls linear (first-order hold), the first-order scheme's
    u_k+1 constant on [t_k, t_k+1)."""
    pd = _peer(openmdao=False)
    t = np.linspace(0.0, 1.0, 5)
    U = np.arange(30.0).reshape(6, 5)
    f, breaks = pd.hold(t, U)
    np.testing.assert_allclose(f(0.375), 0.5 * (U[:, 1] + U[:, 2]), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(breaks, t)
    g, breaks1 = pd.hold(t[1:], U[:, 1:])
    np.testing.assert_array_equal(g(0.3), U[:, 2])
    np.testing.assert_array_equal(g(0.0), U[:, 1])
    np.testing.assert_array_equal(breaks1, t)


@pytest.mark.slow
def test_the_peer_reaches_betts_optimum():
    """Dymos (Radau, 10 segments of order 3, SLSQP) on Betts' reorientation converges, its T* lies within
    its discretization error of 28.6304077 (measured: see docs/bench_notes.md), and its controls flown
    by DOP853 arrive within the same order of the target."""
    pytest.importorskip("dymos")
    pd = _peer()
    rec = pd.solve_peer("slew", 30)
    assert rec["converged"], rec["status"]
    assert abs(rec["T"] - BETTS_T) < 0.02 * BETTS_T, rec["T"]
    assert rec["terminal_error"] < 0.05, rec["terminal_error"]
