"""The continuous-time flight engine and the continuous check (issue 26; docs/mathematics.md §11).

Every claim with its tolerance:

* Independent re-flight: scipy's DOP853 (rtol 1e-13) on a NumPy right-hand side written here --
  velocities and a unit quaternion as the state, gravity chosen by the model (the dumbbell's summed over its
  spheres, a marker-less rigid body's MacCullagh force and gravity-gradient moment), the controls
  interpolated here -- agrees with the engine (CVODES) at every node to 1e-10 relative to the state's
  magnitude (measured <= 1.2e-12): E3 with both schemes, the time-optimal slew (bang-bang, ramps at the
  switches), the fuel raise's rigid body under gravity, and a truth body with a scaled inertia and actuator
  errors (force and moment scale, misalignments).
* Orders: the continuous terminal miss of converged E3 plans over N = 50..400 has fitted slopes
  2 +- 0.15 (LGVI) and 1 +- 0.15 (first order); the LGVI's node controls held instead of interpolated
  lose an order (1 +- 0.15).
* The reference figures of issue 26 (the slew at N = 400: 0.0086 deg and 4.4e-6 rad/s, to 2 %; E3 with
  the LGVI at N = 400: 1e-4 of the orbit radius, within a factor 1.5; first-order E3 at N = 500: about
  1 deg, to 10 %, and 1e-2..2e-2 of the radius).
* Free motion of the dumbbell over one orbit (1000 intervals): energy and spatial angular momentum
  x x gamma + R Pi conserved to 10 N RTOL = 1e-10 relative (each restart of CVODES at a node adds about
  RTOL); R^T R - I drifts by less than 1e-9.
* The closed-loop path of ``fly`` (one call per interval) equals the open-loop path (one chained call)
  to round-off; the applied-control record equals the actuator model applied to the commands.
* A flight into the central body's singularity fails with FlightError, and the check says so.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import se3ocp
from se3ocp.transcription.dynamics.flight import (RTOL, Actuators, ClosedLoop, FlightError, OpenLoop, fly, interval_commands)
from se3ocp.transcription.results.check import continuous_check
from se3ocp.transcription.geometry.so3 import exp_so3, rot_x, rotation_angle

from support import maneuver, perturbed_truth


@lru_cache(maxsize=None)
def solved(name: str, N: int, scheme: str | None = None):
    sol = se3ocp.solve(maneuver(name, N, scheme), "direct")
    assert sol.converged, sol.message
    return sol


# ------------------------------------------------------------------ the test's own re-flight
def quat_to_R(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def R_to_quat(R):
    w = 0.5 * np.sqrt(max(1.0 + np.trace(R), 0.0))
    if w > 0.1:
        return np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    i = int(np.argmax(np.diag(R)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * np.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k])
    q = np.zeros(4)
    q[0], q[1 + i], q[1 + j], q[1 + k] = (R[k, j] - R[j, k]) / s, s / 4, (R[j, i] + R[i, j]) / s, (R[k, i] + R[i, k]) / s
    return q


def gravity(mu, J2=0.0, Re=0.0):
    """The acceleration of a point at y: -mu y/r^3, plus the J2 term about e3 (textbook form)."""
    def a(y):
        r = np.linalg.norm(y)
        z2 = (y[2] / r) ** 2
        j2 = 1.5 * J2 * mu * Re**2 / r**5 * np.array([(5 * z2 - 1) * y[0], (5 * z2 - 1) * y[1], (5 * z2 - 3) * y[2]])
        return -mu * y / r**3 + j2
    return a


def reflight(model, X0, times, start, end, J, sf=1.0, sm=1.0, Af=np.eye(3), Am=np.eye(3), accel=None):
    """DOP853 per node interval of x' = v, m v' = f + s_f R A_f R^T u_f, q' = q (x) (0, Omega)/2,
    J Omega' = J Omega x Omega + M + s_m A_m u_m, u = start + (t - t_k)/h (end - start).  Gravity is read from
    the model itself (``accel``: the field per unit mass at a point, default the point mass -mu y/|y|^3):

    * no central body (``model.mu`` None or 0): none;
    * markers (the dumbbell, ``model.markers`` (2, 3)): ``accel`` on the point masses m/2 at the markers, the
      moment summed over them (the dumbbell's exact potential);
    * no markers (``model.markers`` empty (0, 3), or None/absent on a stand-in): a rigid body known by its
      inertia, U = m V(x) - mu (tr J - 3 rhat^T R J R^T rhat) / (2 r^3) (problems/models.py): m ``accel`` at the
      centre of mass plus the MacCullagh force and the gravity-gradient moment 3 mu / r^5 b x J b (b = R^T x),
      written out here.

    Not flown correctly here: a dumbbell under gravity kind ``gravity_gradient`` (it has markers, but its
    potential is the MacCullagh one).  Returns the nodes as (x, v, R, Omega) arrays."""
    m, mu = model.mass, model.mu or 0.0
    markers = getattr(model, "markers", None)
    markers = np.zeros((0, 3)) if markers is None else np.asarray(markers, dtype=float).reshape(-1, 3)
    assert len(markers) in (0, 2), f"the point masses m/2 are a dumbbell's two spheres, not {len(markers)} markers"
    rho = markers if mu else np.zeros((0, 3))
    maccullagh = bool(mu) and not len(markers)
    Jinv = np.linalg.inv(J)
    accel = accel or gravity(mu)

    def rhs(t, y, t0, h, a, b):
        x, v, q, Om = y[0:3], y[3:6], y[6:10], y[10:13]
        R = quat_to_R(q)
        u = a + (t - t0) / h * (b - a)
        f, M = np.zeros(3), np.zeros(3)
        for r in rho:
            p = x + R @ r
            fq = (m / 2) * accel(p)
            f += fq
            M += np.cross(r, R.T @ fq)
        if maccullagh:      # m accel(x) - grad_x of -mu tr J / (2 r^3) + 3 mu (b^T J b) / (2 r^5)
            r, b = np.linalg.norm(x), R.T @ x
            s = b @ J @ b
            f = m * accel(x) - (1.5 * mu * np.trace(J) * x / r**5
                                + 1.5 * mu * (2.0 * R @ (J @ b) / r**5 - 5.0 * s * x / r**7))
            M = 3.0 * mu / r**5 * np.cross(b, J @ b)
        qd = 0.5 * np.array([-q[1:] @ Om, *(q[0] * Om + np.cross(q[1:], Om))])
        Omd = Jinv @ (np.cross(J @ Om, Om) + M + sm * Am @ u[3:6])
        return np.concatenate([v, (f + sf * R @ Af @ R.T @ u[0:3]) / m, qd, Omd])

    x, g, R, Pi = X0[0:3], X0[3:6], X0[6:15].reshape(3, 3, order="F"), X0[15:18]
    y = np.concatenate([x, g / m, R_to_quat(R), Jinv @ Pi])
    out = [y]
    for k in range(len(times) - 1):
        t0, t1 = times[k], times[k + 1]
        r = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-13, atol=1e-15, args=(t0, t1 - t0, start[:, k], end[:, k]))
        assert r.success, r.message
        y = r.y[:, -1]
        out.append(y)
    Y = np.array(out)
    return Y[:, 0:3], Y[:, 3:6], np.array([quat_to_R(q) for q in Y[:, 6:10]]), Y[:, 10:13]


def relative_difference(flight, ref) -> float:
    """max over the nodes of |d x|, |d v|, |angle|, |d Omega|, each relative to that quantity's largest size."""
    tr = flight.trajectory()
    k = np.arange(len(ref[0])) * flight.samples
    x, v, R, Om = ref
    parts = [np.abs(tr.x[k] - x).max() / max(np.abs(x).max(), 1e-300) if np.abs(x).max() > 0 else np.abs(tr.x[k]).max(),
             np.abs(tr.v[k] - v).max() / max(np.abs(v).max(), 1e-300) if np.abs(v).max() > 0 else np.abs(tr.v[k]).max(),
             rotation_angle(np.einsum("kji,kjl->kil", R, tr.R[k])).max(),
             np.abs(tr.Omega[k] - Om).max() / np.abs(Om).max()]
    return float(max(parts))


@pytest.mark.parametrize("name, N, scheme", [("e3", 100, "lgvi"), ("e3", 100, "first_order"),
                                             ("slew_time_optimal", 100, None)])
def test_independent_reflight(name, N, scheme):
    """The engine's flight of a plan against the test's own DOP853 re-flight: 1e-10 relative at every node
    (measured 2e-13 .. 1.2e-12)."""
    sol = solved(name, N, scheme)
    prob = sol.problem
    start, end = interval_commands(prob.scheme, sol.controls)
    if prob.scheme == "first_order":
        assert np.array_equal(start, sol.controls) and np.array_equal(end, sol.controls)
    else:
        assert np.array_equal(start[:, 1:], end[:, :-1])       # continuous at the nodes
    flight = fly(prob.model, sol.trajectory.X[0], sol.trajectory.t, OpenLoop(start, end))
    ref = reflight(prob.model, sol.trajectory.X[0], sol.trajectory.t, start, end, prob.model.inertia)
    diff = relative_difference(flight, ref)
    print(f"{name} {prob.scheme} N = {N}: engine vs DOP853 {diff:.2e}")
    assert diff <= 1e-10


def test_independent_reflight_of_a_rigid_body_under_gravity():
    """A rigid body known by its inertia (no markers) under the point-mass central body (the fuel raise's body,
    N = 50, LGVI) with a fixed smooth command: the re-flight flies it with gravity (the MacCullagh force and
    gravity-gradient moment, chosen by the model, not by the caller) and agrees with the engine to 1e-10
    relative at every node; a stand-in without the central body (mu = None) flies elsewhere (> 1e-2)."""
    import types

    from support import problem

    prob = problem("orbit_raise_fuel", 50, "lgvi")
    assert prob.model.mu and prob.model.markers.shape == (0, 3)
    s = np.linspace(0.0, 1.0, 51)
    U = np.array([10 * np.cos(3 * s), 5 * s, 2 * np.sin(2 * s), 0.1 * s, -0.05 * np.ones_like(s), 0.02 * s**2])
    sol = se3ocp.simulate(prob, U)
    start, end = interval_commands(prob.scheme, sol.controls)
    flight = fly(prob.model, sol.trajectory.X[0], sol.trajectory.t, OpenLoop(start, end))
    ref = reflight(prob.model, sol.trajectory.X[0], sol.trajectory.t, start, end, prob.model.inertia)
    diff = relative_difference(flight, ref)
    free = types.SimpleNamespace(mass=prob.model.mass, mu=None, markers=prob.model.markers)
    off = relative_difference(flight, reflight(free, sol.trajectory.X[0], sol.trajectory.t, start, end,
                                               prob.model.inertia))
    print(f"rigid body under gravity: engine vs DOP853 {diff:.2e}; without gravity {off:.2e}")
    assert diff <= 1e-10 and off > 1e-2


def test_independent_reflight_truth_and_actuators():
    """A truth body unlike the plan's (J2 gravity as issue 25's example, J2 = 1.08e-3 with R_e = 0.9, and
    the inertia scaled by 1.02) with actuator errors (force scale 1.02, moment scale 0.98, misalignments of
    0.5 deg and 1 deg), flown by the closed-loop path with a constant correction: the test's own re-flight
    (J2 by its textbook gradient) of the same commands agrees to 1e-10 relative (measured 1.2e-12)."""
    import dataclasses

    from se3ocp.problems.models import Dumbbell

    sol = solved("e3", 100, "lgvi")
    prob = sol.problem
    j2 = Dumbbell(gravity="j2", J2=1.08e-3, J2_radius=0.9).body_model()
    assert np.allclose(j2.inertia, prob.model.inertia, rtol=1e-15) and j2.mu == prob.model.mu
    truth = dataclasses.replace(j2, inertia=1.02 * prob.model.inertia, key=None)
    act = Actuators(force_scale=1.02, moment_scale=0.98, force_misalignment=exp_so3(np.radians(0.5) * np.array([0, 0.6, 0.8])),
                    moment_misalignment=rot_x(1.0))
    d = np.r_[0.01, -0.02, 0.03, 1e-4, 0.0, -2e-4]
    plan = OpenLoop.of_controls("lgvi", sol.controls)
    X0 = sol.trajectory.X[0].copy()
    X0[15:18] = truth.inertia @ np.linalg.solve(prob.model.inertia, X0[15:18])    # the same Omega_0
    flight = fly(truth, X0, sol.trajectory.t, ClosedLoop(plan, lambda k, t, X: d), actuators=act)
    assert np.allclose(flight.command_start, plan.start.T + d, rtol=0, atol=1e-15)
    ref = reflight(truth, X0, sol.trajectory.t, plan.start + d[:, None], plan.end + d[:, None], truth.inertia,
                   1.02, 0.98, act.force_misalignment, act.moment_misalignment, gravity(j2.mu, 1.08e-3, 0.9))
    diff = relative_difference(flight, ref)
    nominal = fly(prob.model, sol.trajectory.X[0], sol.trajectory.t, plan)
    off = np.linalg.norm(flight.nodes[-1, :3] - nominal.nodes[-1, :3])
    print(f"truth + actuators: engine vs DOP853 {diff:.2e}; arrival moved by {off:.2e}")
    assert off > 5e-4        # the errors matter (measured 1.0e-3): not a comparison of two nominal flights
    assert diff <= 1e-10
    # the record of the applied control: the actuator model on the flown attitude (nodes: s = 0)
    R = flight.trajectory().R[:: flight.samples][:-1]
    uf = 1.02 * np.einsum("kij,jl,kml,km->ki", R, act.force_misalignment, R, flight.command_start[:, :3])
    um = 0.98 * flight.command_start[:, 3:] @ act.moment_misalignment.T
    scale = np.abs(flight.command_start).max()
    assert np.abs(flight.control[:, 0, :3] - uf).max() <= 1e-12 * scale
    assert np.abs(flight.control[:, 0, 3:] - um).max() <= 1e-12 * scale


def test_closed_loop_path_equals_open_loop():
    """A ClosedLoop with a zero correction (one integrator call per interval) flies exactly like the
    OpenLoop (the intervals chained in one call): same Function, same arithmetic, differences <= 1e-14."""
    sol = solved("e3", 100, "first_order")
    plan = OpenLoop.of_controls("first_order", sol.controls)
    a = fly(sol.problem.model, sol.trajectory.X[0], sol.trajectory.t, plan)
    b = fly(sol.problem.model, sol.trajectory.X[0], sol.trajectory.t, ClosedLoop(plan, lambda k, t, X: np.zeros(6)))
    assert np.abs(a.X - b.X).max() <= 1e-14 * np.abs(a.X).max()
    assert a.X.shape == (100 * a.samples + 1, 18) and a.control.shape == (100, a.samples + 1, 6)
    assert np.array_equal(a.nodes[0], sol.trajectory.X[0]) and np.allclose(a.node_times, sol.trajectory.t, rtol=0, atol=1e-15)


@pytest.mark.parametrize("scheme, N, disturbance, local", [("lgvi", 100, True, True), ("first_order", 60, True, True),
                                                            ("lgvi", 60, False, False)])
def test_the_tracking_loop_in_one_call_flies_as_the_law_asked_per_interval(scheme, N, disturbance, local):
    """The tracker evaluated inside the flight's Function (transcription/flight/loop.py, one mapaccum call) against
    the Tracker asked for each interval's correction from Python (ClosedLoop): E3 with a truth inertia 1 % off,
    a 2 % thrust scale, a misalignment and an initial offset, with (``local``) the plan's local errors fed forward;
    every sample and command agrees to 1e-10 relative (measured 5e-13 for the states, 2e-12 for the commands)."""
    from se3ocp.transcription.closedloop.estimator import local_errors
    from se3ocp.transcription.closedloop.loop import TrackingLoop
    from se3ocp.transcription.closedloop.tracking import tracking_gains

    sol = solved("e3", N, scheme)
    g = tracking_gains(sol)
    if local:
        g = g.with_local_errors(local_errors(g, sol.problem.model, sol.problem.disc.force_frame))
        assert np.abs(g.f).max() > 0
    truth, act, X0 = perturbed_truth(sol)
    tr = g.tracker(disturbance=disturbance)
    old = fly(truth, X0, g.t, ClosedLoop(OpenLoop.of_controls(scheme, g.U), lambda k, t, X: tr.correction(k, X)), act)
    new = fly(truth, X0, g.t, TrackingLoop.of_gains(g, disturbance), act)
    dX = np.max(np.abs(new.X - old.X) / np.abs(old.X).max(axis=0))
    dc = max(np.abs(new.command_start - old.command_start).max(), np.abs(new.command_end - old.command_end).max())
    dc /= np.abs(old.command_start).max()
    print(f"{scheme}, N = {N}, disturbance {disturbance}: states {dX:.1e}, commands {dc:.1e} relative")
    assert dX <= 1e-10 and dc <= 1e-10
    assert np.abs(new.command_start - OpenLoop.of_controls(scheme, g.U).start.T).max() > 1e-6   # it did correct


# ------------------------------------------------------------------------------- orders
def test_orders_of_the_continuous_miss():
    """E3 planned at N = 50, 100, 200, 400 by each scheme and flown: the continuous terminal miss (the
    scalar) has fitted log-log slopes 2 +- 0.15 (LGVI) and 1 +- 0.15 (first order).  Measured: 2.00
    (3.5e-2 .. 5.4e-4) and 1.04 (0.50 .. 0.056)."""
    Ns = np.array([50, 100, 200, 400])
    for scheme, order in (("lgvi", 2.0), ("first_order", 1.0)):
        miss = [continuous_check(solved("e3", int(N), scheme)).terminal_error for N in Ns]
        pos = [continuous_check(solved("e3", int(N), scheme)).terminal_position for N in Ns]
        slope, slope_pos = -np.polyfit(np.log(Ns), np.log(miss), 1)[0], -np.polyfit(np.log(Ns), np.log(pos), 1)[0]
        print(f"{scheme}: miss {np.array(miss)} slope {slope:.3f}; position {np.array(pos)} slope {slope_pos:.3f}")
        assert abs(slope - order) <= 0.15 and abs(slope_pos - order) <= 0.15


def test_holding_the_lgvi_node_control_loses_an_order():
    """docs/mathematics.md §11: the LGVI's node controls held (u_k over [t_k, t_{k+1}]) instead of
    interpolated make the control's impulse wrong by O(h^2) per step: the attitude miss of E3 falls at
    order 1 +- 0.15 (measured 0.99), and is 100 times the interpolant's at N = 400 (measured 380)."""
    Ns = np.array([100, 200, 400])
    held, linear = [], []
    for N in Ns:
        sol = solved("e3", int(N), "lgvi")
        U, tr = sol.controls, sol.trajectory
        for law, out in ((OpenLoop(U[:, :-1], U[:, :-1]), held), (OpenLoop.of_controls("lgvi", U), linear)):
            R = fly(sol.problem.model, tr.X[0], tr.t, law, samples=1).trajectory().R[-1]
            out.append(float(rotation_angle(tr.R[-1].T @ R)))
    slope = -np.polyfit(np.log(Ns), np.log(held), 1)[0]
    print(f"held u_k: attitude miss {np.array(held)} slope {slope:.3f}; linear {np.array(linear)}")
    assert abs(slope - 1.0) <= 0.15 and held[-1] >= 100 * linear[-1]


def test_reference_figures():
    """Issue 26's figures: the time-optimal slew at N = 400 misses by 0.0086 deg and 4.4e-6 rad/s (2 %);
    E3 with the LGVI at N = 400 by ~1e-4 of the orbit radius (measured 7.5e-5); the first-order E3 at its
    default N = 500 by about 1 deg (measured 1.05) and 1.3e-2 of the radius (the issue: 1.8e-2)."""
    slew = continuous_check(solved("slew_time_optimal", 400))
    assert np.degrees(slew.terminal_attitude) == pytest.approx(0.0086, rel=0.02)
    assert slew.terminal_rate == pytest.approx(4.4e-6, rel=0.02)
    e3 = continuous_check(solved("e3", 400, "lgvi"))
    assert 1e-4 / 1.5 <= e3.terminal_position <= 1.5e-4
    fo = continuous_check(solved("e3", 500))
    assert solved("e3", 500).scheme == "first_order"
    assert np.degrees(fo.terminal_attitude) == pytest.approx(1.0, rel=0.1)
    assert 1e-2 <= fo.terminal_position <= 2e-2
    for c in (slew, e3, fo):
        assert c.ok and c.orthogonality_drift <= 1e-9
        assert c.max_position_deviation >= c.terminal_position and c.max_attitude_deviation >= c.terminal_attitude


# ------------------------------------------------------------------------- free motion
def test_free_motion_conserves_energy_and_momentum():
    """The dumbbell tumbling on the reference orbit (free_tumble.yaml's start) flown freely for one
    orbit in N = 1000 intervals: energy and x x gamma + R Pi constant to 10 N RTOL relative (measured
    1.1e-11 and 5.4e-12); R^T R - I below 1e-9 (measured 9e-12)."""
    man = maneuver("free", 1000, None, "horizon.T=1.0")
    prob = man.problem
    flight = fly(prob.model, prob.X0, np.linspace(0.0, 1.0, 1001), OpenLoop.free(1000))
    tr = flight.trajectory()
    E = np.array(prob.model.energy().map(tr.X.shape[0])(tr.X.T)).ravel()
    L = np.cross(tr.x, tr.gamma) + np.einsum("kij,kj->ki", tr.R, tr.Pi)
    dE = np.abs(E - E[0]).max() / abs(E[0])
    dL = np.linalg.norm(L - L[0], axis=1).max() / np.linalg.norm(L[0])
    drift = np.linalg.norm(np.einsum("kji,kjl->kil", tr.R, tr.R) - np.eye(3), axis=(1, 2)).max()
    print(f"free motion, one orbit: energy {dE:.1e}, angular momentum {dL:.1e}, R^T R - I {drift:.1e}")
    assert dE <= 10 * 1000 * RTOL and dL <= 10 * 1000 * RTOL and drift <= 1e-9
    assert np.all(flight.control == 0.0)


# ----------------------------------------------------------------------------- the check
def test_check_of_an_impulsive_plan_and_of_path_constraints():
    """E1 (impulses, free motion between): the check flies from the state after the first impulse and
    its target error is measured after the terminal impulse; the keep-out slew: the cone holds at the
    nodes (to round-off) but the margin between the nodes is reported, and it is the smallest."""
    sol = se3ocp.solve(maneuver("e1", 200), "direct")
    c = continuous_check(sol)
    assert c.ok and 0 < c.terminal_error < 1e-2 and c.target_error < 1e-2
    assert c.t.shape == (201,) and c.position_deviation[0] == 0.0
    s = se3ocp.solve(maneuver("slew_keep_out"), "direct")
    cs = continuous_check(s)
    at_nodes = float(np.min(s.problem.constraints[0].margin(s.trajectory)))
    assert set(cs.min_margins) == {"min_margin_keep_out"}
    assert cs.min_margins["min_margin_keep_out"] < at_nodes
    assert cs.summary()["continuous_min_margin_keep_out"] == cs.min_margins["min_margin_keep_out"]


def test_failed_flight_is_reported():
    """A body dropped from rest at radius 1 falls into the point mass at t = 0.18 < T = 0.5: fly raises
    FlightError naming CVODES, the check of such a 'plan' carries nan and the message."""
    import dataclasses

    from se3ocp.transcription.dynamics.trajectory import Trajectory

    prob = maneuver("free", 100, None, "horizon.T=0.5").problem
    X0 = prob.X0.copy()
    X0[3:6] = 0.0
    X0[15:18] = 0.0
    with pytest.raises(FlightError, match="CVODES"):
        fly(prob.model, X0, np.linspace(0.0, 0.5, 101), OpenLoop.free(100))
    sim = se3ocp.simulate(prob)
    X = sim.trajectory.X.copy()
    X[0] = X0
    c = continuous_check(dataclasses.replace(sim, trajectory=Trajectory(t=sim.trajectory.t, X=X, mass=prob.model.mass,
                                                                        inertia=prob.model.inertia)))
    assert not c.ok and "CVODES" in c.message and np.isnan(c.terminal_error) and c.summary()["continuous_message"]


def test_nearest_rotation():
    """lie.nearest_rotation: the orthogonal polar factor M (M^T M)^(-1/2) for matrices near SO(3) (to 1e-14),
    a rotation (det 1) even for a matrix with det < 0, and the identity map on rotations (to 1e-14)."""
    from se3ocp.transcription.geometry.so3 import nearest_rotation, orthogonality_error

    rng = np.random.default_rng(7)
    Rs = np.array([exp_so3(rng.standard_normal(3)) for _ in range(20)])
    assert np.abs(nearest_rotation(Rs) - Rs).max() <= 1e-14
    M = Rs + 1e-3 * rng.standard_normal(Rs.shape)
    w, V = np.linalg.eigh(np.einsum("kji,kjl->kil", M, M))
    polar = np.einsum("kij,kjl->kil", M, np.einsum("kij,kj,klj->kil", V, w ** -0.5, V))
    assert np.abs(nearest_rotation(M) - polar).max() <= 1e-14
    flipped = nearest_rotation(np.diag([1.0, 1.0, -1.0]) @ Rs[0])
    orth, det = orthogonality_error(flipped)
    assert orth <= 1e-15 and det <= 1e-15
