"""Cones about moving directions (nadir, velocity) and the rendezvous target (docs/mathematics.md §10), on the
bundled configs/nadir_pointing_rendezvous.yaml (direct method, free final time) and on closed forms."""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.problems.elements import state_of
from se3ocp.problems.schema import ConfigError
from se3ocp.transcription.results.check import continuous_check
from se3ocp.transcription.geometry.state import NX, pack_state
from se3ocp.transcription.nlp.scaling import terminal_row_scales
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from se3ocp.transcription.methods.indirect.solve import not_covered
from se3ocp.transcription.options import DirectOptions
from se3ocp.transcription.ocp import KeepIn, KeepOut, TargetRendezvous, rendezvous_residual
from se3ocp.transcription.dynamics.trajectory import Trajectory

from support import config, maneuver

NAME = "nadir_pointing_rendezvous"


@lru_cache(maxsize=None)
def _solved(*sets: str):
    man = maneuver(NAME, None, None, *sets)
    return man, se3ocp.solve(man, "direct")


def _cone(problem):
    (con,) = [c for c in problem.constraints if isinstance(c, KeepIn)]
    return con


def test_nadir_cone_holds_at_every_node_and_touches_where_active():
    man, sol = _solved()
    assert sol.result is se3ocp.Result.converged, sol.message
    con = _cone(man.problem)
    assert con.direction == "nadir"
    # the smooth form g = (R b).d - cos(alpha) the NLP enforces, on the re-simulated nodes 1..N
    g = np.array([con.expression(X, man.problem.model.inertia) for X in sol.trajectory.X])
    assert g[1:].min() >= -1e-10                  # held to the solver's tolerance
    assert g[1:].min() <= 1e-8                    # and active: it touches
    margin = con.margin(sol.trajectory)           # degrees
    assert margin.min() >= -1e-8 and margin.min() <= 1e-4
    (report,) = sol.stats["constraints"]
    assert report["max_multiplier"] > 1e-3        # it binds: a positive multiplier
    # without the cone the optimum leaves it by more than 0.1 degree
    _, free = _solved("constraints=[]")
    assert free.result is se3ocp.Result.converged
    assert con.margin(free.trajectory).min() < -0.1
    assert free.cost < sol.cost


def test_rendezvous_terminal_state_is_the_target_orbit_point_at_the_solved_time():
    man, sol = _solved()
    p = man.problem
    lo, hi = p.time_bounds
    T = sol.stats["T"]
    assert lo < T < hi and T == pytest.approx(sol.trajectory.t[-1], rel=1e-14)
    tgt = p.terminal
    mu = p.model.mu
    # independently: the circular orbit's closed form through the orbital elements (a = r, e = 0, i = 0,
    # node = 0, argument of latitude u = phase + sqrt(mu / r^3) T)
    u = 14.0 + np.degrees(np.sqrt(mu / 1.05**3) * T)
    x_d, v_d = state_of(mu, 1.05, 0.0, 0.0, 0.0, 0.0, u % 360.0)
    assert np.abs(sol.trajectory.x[-1] - x_d).max() <= 1e-8
    assert np.abs(sol.trajectory.v[-1] - v_d).max() <= 1e-8
    assert np.abs(sol.trajectory.Omega[-1] - [5.839772380595914, 0, 0]).max() <= 1e-8
    assert tgt.fixed == ("position", "velocity", "angular_velocity")
    assert sol.terminal_error <= 1e-8


def test_rendezvous_point_agrees_with_orbital_elements_for_inclined_planes():
    mu = 4 * np.pi**2
    rng = np.random.default_rng(7)
    for _ in range(20):
        r, i, raan, ph, T = 0.5 + rng.random(), 180 * rng.random(), 360 * rng.random(), 360 * rng.random(), rng.random()
        tgt = se3ocp.load(config(NAME), (f"terminal.rendezvous={{radius: {r!r}, inclination_deg: {i!r}, "
                                        f"raan_deg: {raan!r}, phase_deg: {ph!r}}}",)).problem.terminal
        x, v = tgt.point(T, mu)
        u = ph + np.degrees(np.sqrt(mu / r**3) * T)
        xe, ve = state_of(mu, r, 0.0, i, raan, 0.0, u % 360.0)
        assert np.abs(x - xe).max() <= 1e-12 * r and np.abs(v - ve).max() <= 1e-12 * np.linalg.norm(ve)
        # the same plane by its normal: the ascending node is the reference, so the point is the same
        same = TargetRendezvous(r, tgt.normal, np.radians(ph))
        assert np.abs(same.point(T, mu)[0] - x).max() <= 1e-12 * r
        # a re-plan from t = 0.3 T aims at the same instant
        assert np.abs(tgt.advanced(0.3 * T, mu).point(0.7 * T, mu)[0] - x).max() <= 1e-12 * r


def test_rendezvous_residual_derivative_in_T_matches_finite_differences_and_the_closed_form():
    man = maneuver(NAME)
    p = man.problem
    tr = SmoothTranscription(p, DirectOptions())
    (blk,) = [b for b in tr.nlp.blocks if b.name == "terminal"]
    assert blk.idx[-1, 0] == tr.layout.ih               # the block reads the free step size
    v, data = ca.SX.sym("v", NX + 1), blk.data[:, 0]
    rows = blk.fn(v, data)[1]
    d_dv = ca.Function("d", [v], [ca.jacobian(rows, v[NX])])
    XN = pack_state([0.3, 0.9, 0.1], [-5.0, 2.0, 0.5], np.eye(3), [0.01, 0.0, 0.0])
    tsc = rows.size1()
    for T in (0.7, 1.0, 1.13):
        vv = np.r_[XN / tr.scales.X[:NX], T / p.N / tr.h_scale]
        dT_dv = p.N * tr.h_scale
        ad = np.array(d_dv(vv)).ravel() / dT_dv                 # d(scaled rows)/dT
        scale = 1.0 / terminal_row_scales(p, tr.scales)
        d = 1e-6
        fd = (rendezvous_residual(XN, T + d, p.terminal, 1.0, p.model.mu)
              - rendezvous_residual(XN, T - d, p.terminal, 1.0, p.model.mu)) / (2 * d) * scale
        assert ad.shape == (tsc,) and np.abs(ad - fd).max() <= 1e-7 * np.abs(fd).max()
        # closed form: d(x - p)/dT = -v(T), d(gamma - m v)/dT = m w^2 p(T); the given Pi does not move
        x_t, v_t = p.terminal.point(T, p.model.mu)
        w2 = p.model.mu / 1.05**3
        exact = np.r_[-v_t, w2 * x_t, np.zeros(3)] * scale
        assert np.abs(ad - exact).max() <= 1e-12 * np.abs(exact).max()


def test_a_nadir_cone_equals_the_fixed_cone_about_the_nadir_of_that_node():
    man, sol = _solved()
    traj, J = sol.trajectory, man.problem.model.inertia
    for k in (0, 37, len(traj.t) - 1):
        X = traj.X[k]
        for cls in (KeepIn, KeepOut):
            for moving, d in (("nadir", -traj.x[k]), ("velocity", traj.v[k])):
                a = cls([0.2, 0.1, 1.0], moving, 25.0)
                b = cls([0.2, 0.1, 1.0], d, 25.0)
                one = Trajectory(traj.t[k:k + 1], X[None, :], traj.mass, J)
                assert abs(a.expression(X, J) - b.expression(X, J)) <= 1e-15
                assert abs(a.margin(one)[0] - b.margin(one)[0]) <= 1e-12
                # the symbolic expression (the NLP's row) is the same function
                s = ca.SX.sym("X", NX)
                f = ca.Function("f", [s], [a.expression(s, J)])
                assert abs(float(f(X)) - a.expression(X, J)) <= 1e-15


@pytest.mark.slow
def test_continuous_check_measures_the_moving_cone_between_nodes():
    """The flight (eqs. (1)-(4), transcription/flight) dips out of the cone between the nodes and near the
    active node by O(h^2) or faster: measured 0.0735 deg at N = 100, 0.0060 at 200, 0.00073 at 400."""
    dips = []
    for N in (None, 200):
        man, sol = _solved(*((f"horizon.N={N}",) if N else ()))
        chk = continuous_check(sol)
        m = chk.min_margins["min_margin_keep_in"]
        node = _cone(man.problem).margin(sol.trajectory).min()
        assert np.isfinite(m) and m < node
        dips.append(-m)
        # the target is taken at the plan's final time (not at the guess T = 0.8, where it is far away): the
        # flight misses it by no more than the flight misses the plan's final state
        J = man.problem.model.inertia
        bound = max(chk.terminal_position, chk.terminal_velocity, np.linalg.norm(J, 2) * chk.terminal_rate)
        assert chk.target_error <= bound + 1e-8
    assert 0 < dips[1] <= dips[0] / 4


def test_the_indirect_method_refuses_both_and_says_why():
    p = maneuver(NAME).problem
    why = not_covered(p)
    assert "keep-in cone about the nadir" in why and "rendezvous target" in why
    sol = se3ocp.solve(maneuver(NAME), "indirect")
    assert sol.result is se3ocp.Result.not_applicable and "rendezvous" in sol.message


@pytest.mark.parametrize("sets, field", [
    (("constraints=[{kind: keep_in, body_axis: [0, 0, 1], direction: zenith, max_angle_deg: 10}]",),
     "constraints[0].direction"),
    (("terminal.rendezvous={radius: 1.05, phase_deg: 10}",), "terminal.rendezvous"),
    (("terminal.rendezvous={radius: 1.05, normal: [0, 0, 1], inclination_deg: 10, raan_deg: 0, phase_deg: 10}",),
     "terminal.rendezvous.inclination_deg"),
    (("terminal.rendezvous={radius: 1.05, inclination_deg: 190, raan_deg: 0, phase_deg: 10}",),
     "terminal.rendezvous.inclination_deg"),
    (("terminal.rendezvous.phase_deg=1.5707963267948966",), "terminal.rendezvous.phase_deg"),
    (("terminal.rendezvous.radius=-1",), "terminal.rendezvous.radius"),
    (("gravity={kind: none}",), "terminal.rendezvous"),
    (("control={kind: impulsive}", "constraints=[]"), "terminal"),
])
def test_bad_moving_input_is_one_line_naming_the_field(sets, field):
    with pytest.raises(ConfigError) as e:
        se3ocp.load(config(NAME), sets)
    msg = str(e.value)
    assert "\n" not in msg and f": {field}: " in msg


def test_a_velocity_cone_at_rest_is_refused():
    sets = ("initial.velocity=[0, 0, 0]",
            "constraints=[{kind: keep_out, body_axis: [1, 0, 0], direction: velocity, min_angle_deg: 10}]")
    with pytest.raises(ConfigError, match=r"constraints\[0\]: the initial state leaves the direction 'velocity' undefined"):
        se3ocp.load(config(NAME), sets)


def test_figures_draw_the_moving_direction_and_the_rendezvous_points():
    import matplotlib.pyplot as plt

    man, sol = _solved()
    figs = se3ocp.plot(sol, ("attitude", "maneuver", "constraints"))
    try:
        nadir = _cone(man.problem).directions(sol.trajectory)
        assert np.allclose(nadir, -sol.trajectory.x / np.linalg.norm(sol.trajectory.x, axis=1)[:, None], atol=1e-15)
        paths = [np.array(ln.get_data_3d()).T for ln in figs["attitude"].axes[0].lines]
        assert any(p.shape == nadir.shape and np.allclose(p, nadir, atol=1e-15) for p in paths)
        margins = figs["constraints"].axes[0].lines[0].get_ydata()
        assert np.allclose(margins, _cone(man.problem).margin(sol.trajectory), rtol=0, atol=1e-12)
        pts = [np.asarray(c._offsets3d, float).T.reshape(-1, 3) for c in figs["maneuver"].axes[0].collections
               if c.get_label() == "target at arrival"]
        assert len(pts) == 1 and np.abs(pts[0][0] - sol.trajectory.x[-1]).max() <= 1e-8
    finally:
        for f in figs.values():
            plt.close(f)
