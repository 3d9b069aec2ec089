"""A slew planned within its reaction wheels' momentum (issue 43; transcription.ocp.WheelMomentum, configs/
slew_wheel_momentum.yaml; docs/mathematics.md §10, *Wheel momentum*).

Every claim with its tolerance:

* the constraint's momentum h_w = A^+ (R^T H_0 - Pi) is the momentum the flight's wheels (transcription/dynamics/
  wheels.py, another code path: their torques integrated) carry: a tumbling body turned by four pyramid wheels with
  random moment commands, every node to 1e-10 of the largest (measured ~1e-13); the smooth CasADi expression, the
  NumPy one and the margin agree to round-off;
* the bundled slew respects 500 N m s at every node (to 1e-6 relative), the limit is active (within 1e-4), and the
  slew takes longer than without it (30.49 s against 28.61 s);
* bad input: axes that do not span three dimensions, a limit per wheel of the wrong count, a terminal state that
  already violates the limit -- one line naming the field;
* (slow) flown on its wheels (600 N m s, 1.2x the plan's; torques 1.1x the plan's wheel torque peaks; 2 % inertia,
  0.57 deg axes, 0.005 deg attitude noise through the EKF), the LQR lands within 0.02 deg p95 and no wheel passes a
  limit, where the unconstrained time-optimal slew flown the same way saturates and misses by degrees.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.problems.schema import ConfigError
from se3ocp.transcription.closedloop.actuated import fly_actuated
from se3ocp.transcription.dynamics.flight import OpenLoop
from se3ocp.transcription.dynamics.trajectory import Trajectory
from se3ocp.transcription.dynamics.wheels import Wheels
from se3ocp.transcription.geometry.so3 import exp_so3
from se3ocp.transcription.ocp import wheel_momentum_constraints

from support import CONFIGS, maneuver
from test_wheels import PYRAMID, J, free_body, state


def test_the_constraints_wheel_momentum_is_what_the_flights_wheels_carry():
    rng = np.random.default_rng(11)
    N, h = 40, 0.2
    a, b = np.zeros((6, N)), np.zeros((6, N))
    a[3:], b[3:] = rng.standard_normal((3, N)), rng.standard_normal((3, N))
    X0 = state(exp_so3(np.array([0.3, -0.4, 0.2])), np.array([0.2, -0.1, 0.3]))
    run = fly_actuated(free_body(), X0, h * np.arange(N + 1), OpenLoop(a, b),
                       wheels=Wheels(PYRAMID, np.full(4, 1e3), np.full(4, 1e3)))
    X, hw = run.flight.X, np.array(run.wheels.h_w)
    cons = wheel_momentum_constraints(PYRAMID, 7.0, X0[6:15].reshape(3, 3, order="F"), X0[15:18])
    assert [c.wheel for c in cons] == [1, 2, 3, 4]
    plan = np.array([[c.momentum(x) for c in cons] for x in X])
    assert np.abs(hw).max() > 0.3                                       # the wheels did turn the body (0.64)
    assert np.abs(plan - hw).max() <= 1e-10 * np.abs(hw).max()
    traj = Trajectory(np.zeros(len(X)), X, 1.0, J)
    margins = np.array([c.margin(traj) for c in cons]).T
    assert np.abs(margins - (7.0 - np.abs(plan))).max() <= 1e-12 * 7.0
    x = ca.SX.sym("X", 18)
    fn = ca.Function("e", [x], [ca.vertcat(*[c.expression(x, J) for c in cons])])
    smooth = np.array(fn(X.T)).T
    assert np.abs(smooth - (49.0 - plan**2)).max() <= 1e-12 * 49.0


def _wheels_momentum(sol, limit_axes=np.eye(3)) -> np.ndarray:
    """|h_w| per node and wheel of a slew from rest (H_0 = 0): A^+ (-Pi)."""
    return np.abs(sol.trajectory.Pi @ np.linalg.pinv(limit_axes).T)


def test_the_bundled_slew_keeps_its_wheels_within_their_momentum():
    sol = se3ocp.solve(maneuver("slew_wheel_momentum"))
    free = se3ocp.solve(maneuver("slew_time_optimal"))
    assert sol.converged and free.converged, (sol.message, free.message)
    h = _wheels_momentum(sol)
    assert h.max() <= 500.0 * (1 + 1e-6) and h.max() >= 500.0 * (1 - 1e-4)
    assert _wheels_momentum(free).max() > 700.0                  # unconstrained: 797 N m s on the y wheel
    assert sol.T > free.T * 1.03
    print(f"slew within 500 N m s: T {sol.T:.6g} s against {free.T:.6g} s; peak |h_w| {h.max():.6g}")


@pytest.mark.parametrize("constraint, field, message", [
    ({"axes": [[1, 0, 0], [0, 1, 0], [1, 1, 0]], "limit": 500.0}, "constraints[0].axes",
     "expected axes spanning three dimensions"),
    ({"axes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "limit": [500.0, 500.0]}, "constraints[0].limit",
     "expected one positive number or 3"),
    ({"axes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "limit": -1.0}, "constraints[0].limit", "expected a positive"),
])
def test_a_bad_wheel_momentum_constraint_is_refused_in_one_line(constraint, field, message):
    import json
    with pytest.raises(ConfigError, match=field.replace("[", r"\[").replace("]", r"\]") + ": " + message):
        se3ocp.load(CONFIGS / "slew_wheel_momentum.yaml", [f"constraints=[{json.dumps({'kind': 'wheel_momentum', **constraint})}]"])


def test_a_terminal_state_beyond_the_wheels_momentum_is_refused():
    # ends turning at 0.2 rad/s about x: the x wheel holds 5621 x 0.2 = 1124 N m s > 500
    with pytest.raises(ConfigError, match=r"constraints\[0\]: the terminal state already violates this wheel_momentum"):
        se3ocp.load(CONFIGS / "slew_wheel_momentum.yaml", ["terminal.angular_velocity=[0.2, 0, 0]"])


@pytest.mark.slow
def test_the_slew_planned_within_its_wheels_flies_on_them_where_the_unconstrained_one_saturates():
    """(slow: two plans and 2 x 20 flights on wheels, ~40 s.)"""
    from se3ocp.problems.flight import load_flight, with_changes
    from se3ocp.problems.flight.run import run_flights
    from se3ocp.problems.sweep.executors import SerialExecutor

    p95 = {}
    for name in ("slew_wheel_momentum", "slew_time_optimal"):
        man = maneuver(name)
        sol = se3ocp.solve(man)
        assert sol.converged, sol.message
        spec = with_changes(load_flight(CONFIGS / "flights" / "slew_wheel_momentum.yaml", man), "f", runs=20)
        res = run_flights(man, sol, spec, executor=SerialExecutor())
        lqr = [r for r in res.rows if r["feedback"] == "lqr"]
        p95[name] = float(np.percentile([r["attitude_miss_deg"] for r in lqr], 95))
        if name == "slew_wheel_momentum":
            used = [k for k in res.metrics if k.startswith("wheel")]
            assert max(r[k] for r in lqr for k in used) <= 1.0 + 1e-9
    print(f"p95 attitude miss on 600 N m s wheels: planned within them {p95['slew_wheel_momentum']:.3e} deg, "
          f"unconstrained {p95['slew_time_optimal']:.3e} deg")
    assert p95["slew_wheel_momentum"] <= 0.02 and p95["slew_time_optimal"] >= 1.0


def test_wheel_momentum_is_refused_around_a_central_body():
    with pytest.raises(ConfigError, match=r"constraints\[0\]: applies without a central body only"):
        se3ocp.load(CONFIGS / "leo_body_engine.yaml", ['constraints=[{"kind": "wheel_momentum", '
                                                       '"axes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "limit": 1.0}]'])
