"""On/off thrusters with a minimum impulse bit (transcription/closedloop/pulses.py; docs/mathematics.md §11).

Every claim with its tolerance, checked on a free body (no gravity: the momentum changes by the applied impulse
alone, so the flown gamma is an independent measure of what the pulses delivered):

* each period whose impulse is at or above the bit delivers the commanded impulse h (a + b) / 2 (plus what was
  carried): the flown momentum change over the period equals it to 1e-12 relative (round-off of CVODES at 1e-14);
* a flight of commands around the bit (many carried): the summed delivered impulse (the flown gamma_N - gamma_0)
  equals the summed command less the impulse left carried, to 1e-12 relative, and that is under one bit;
* a command above full thrust fires the whole period and the excess is cut (counted saturated);
* a constant command's pulse is centred in its period; a ramp's sits on its centroid (2/3 of the period for 0 -> b);
* the pulse is flown at the thrust level F: the applied force record is F (to 1e-13: R R^T u of an inertial command) or 0;
* the flight block: minimum_impulse and thrust read in the file's units, bad input one line naming the field.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from se3ocp.transcription.closedloop.actuated import fly_actuated
from se3ocp.transcription.closedloop.pulses import Modulator, Pulses, segments
from se3ocp.transcription.dynamics.flight import OpenLoop
from se3ocp.transcription.dynamics.model import BodyModel
from se3ocp.transcription.geometry.state import X_MOM

MASS, F, BIT = 2.0, 0.5, 0.02


def free_body() -> BodyModel:
    x, R = ca.SX.sym("x", 3), ca.SX.sym("R", 3, 3)
    return BodyModel(mass=MASS, inertia=np.diag([1.0, 2.0, 3.0]), potential=ca.Function("U0", [x, R], [ca.SX(0)]))


def start_state() -> np.ndarray:
    X = np.zeros(18)
    X[3:6] = [0.1, -0.2, 0.05]
    X[6:15] = np.eye(3).ravel(order="F")
    X[15:18] = [0.01, 0.02, -0.01]
    return X


def commands(rng, N, size):
    """Affine force commands (6, N) at both ends of N periods, each of about ``size`` in every component; no moment."""
    a, b = np.zeros((6, N)), np.zeros((6, N))
    a[:3], b[:3] = size * rng.standard_normal((3, N)), size * rng.standard_normal((3, N))
    return a, b


def test_each_period_delivers_its_impulse():
    rng = np.random.default_rng(3)
    N, h = 12, 0.7
    a, b = commands(rng, N, 0.15)              # |I| ~ 0.18 > BIT, below F h = 0.35 (no saturation)
    times = h * np.arange(N + 1)
    run = fly_actuated(free_body(), start_state(), times, OpenLoop(a, b), Pulses(F, BIT))
    flight, mod = run.flight, run.pulses
    gamma = flight.X[np.searchsorted(flight.t, times)][:, X_MOM]
    want = 0.5 * h * (a[:3] + b[:3]).T
    assert mod.fired == N and mod.skipped == 0 and mod.saturated == 0
    assert np.max(np.abs(np.diff(gamma, axis=0) - want)) <= 1e-12 * np.abs(want).max()
    force = np.linalg.norm(flight.control[..., :3], axis=-1)
    assert np.all((np.abs(force - F) <= 1e-13 * F) | (force == 0.0))


def test_sum_over_a_flight_within_one_bit():
    rng = np.random.default_rng(7)
    N, h = 40, 0.5
    a, b = commands(rng, N, 0.012)             # |I| ~ 0.01 around the bit 0.02: many periods carried
    times = h * np.arange(N + 1)
    run = fly_actuated(free_body(), start_state(), times, OpenLoop(a, b), Pulses(F, BIT))
    flight, mod = run.flight, run.pulses
    commanded = 0.5 * h * (a[:3] + b[:3]).sum(axis=1)
    flown = flight.X[-1, X_MOM] - flight.X[0, X_MOM]
    assert mod.skipped >= 10 and mod.fired >= 5
    assert np.max(np.abs(flown - (commanded - mod.carry))) <= 1e-12 * np.abs(commanded).max()
    assert np.linalg.norm(flown - commanded) < BIT
    assert mod.narrowest >= BIT / F * (1 - 1e-12)          # no pulse under the bit


def test_saturated_period_fires_throughout():
    mod = Modulator(Pulses(F, BIT))
    h = 0.4
    p = mod.period(np.array([0.0, 0.8, 0.0]), np.array([0.0, 0.9, 0.0]), h)      # 0.34 > F h = 0.2
    assert (p.start, p.width, mod.saturated) == (0.0, 1.0, 1)
    assert np.allclose(p.delivered, [0.0, F * h, 0.0], rtol=1e-15, atol=0.0) and not mod.carry.any()
    assert [(lo, hi) for lo, hi, _ in segments(p)] == [(0.0, 1.0)]


def test_pulse_placement():
    mod = Modulator(Pulses(F, 0.0))
    c = mod.period(np.array([0.1, 0.0, 0.0]), np.array([0.1, 0.0, 0.0]), 1.0)
    assert abs(c.start + 0.5 * c.width - 0.5) <= 1e-15 and abs(c.width - 0.2) <= 1e-15
    r = mod.period(np.zeros(3), np.array([0.0, 0.0, 0.1]), 1.0)             # 0 -> b: centroid at 2/3
    assert abs(r.start + 0.5 * r.width - 2.0 / 3.0) <= 1e-15
    late = mod.period(np.zeros(3), np.array([0.0, 0.0, 0.9]), 1.0)          # too wide to centre: against the end
    lo_hi = [(lo, hi) for lo, hi, f in segments(late) if f.any()]
    assert lo_hi[0][1] == 1.0 and abs(lo_hi[0][1] - lo_hi[0][0] - 0.9) <= 1e-15


def test_bad_pulses():
    with pytest.raises(ValueError, match="thrust"):
        Pulses(0.0, BIT)
    with pytest.raises(ValueError, match="minimum impulse"):
        Pulses(F, -1.0)


# ------------------------------------------------------------------ through the flight block
def _engine_man():
    from support import maneuver
    from test_body_force import ENGINE_SLEW

    return maneuver("slew_keep_out", None, None, *ENGINE_SLEW)


def _engine_slew():
    import se3ocp

    man = _engine_man()
    sol = se3ocp.solve(man)
    assert sol.converged, sol.message
    return man, sol


@pytest.mark.slow
def test_an_engine_plan_flown_on_pulses_keeps_its_delta_v():
    """(slow: a solve and two flights, ~9 s on the shared machine.)  The engine slew (a body-fixed engine, 0 <= T <= 0.1, N = 40) flown open loop and with the LQR on pulses of the
    engine's full thrust with a bit of 2 % of a full period's impulse: every period fires at 0.1 or not at all; open
    loop, the flight's delta-v (the applied |u_f| integrated) is the plan's less the impulse left carried, to 1e-9
    relative, so within one bit; flights.csv's pulse columns are written."""
    from se3ocp.problems.flight import parse_flight
    from se3ocp.problems.flight.output import columns
    from se3ocp.problems.flight.run import run_flights
    from se3ocp.problems.sweep.executors import SerialExecutor

    man, sol = _engine_slew()
    h = sol.h
    bit = 0.02 * 0.1 * h
    spec = parse_flight({"runs": 1, "feedback": "both", "actuators": {"pulses": {"minimum_impulse": bit}}})
    res = run_flights(man, sol, spec, executor=SerialExecutor())
    rows = {r["feedback"]: r for r in res.rows}
    assert all(r["status"] == "ok" for r in rows.values()), [r["message"] for r in rows.values()]
    none = rows["none"]
    m = man.problem.model.mass
    planned = res.plan["delta_v"]
    assert abs(none["delta_v"] - (planned - none["carried_delta_v"])) <= 1e-9 * planned
    assert none["carried_delta_v"] * m < bit and none["pulses"] > 0 and none["pulses_saturated"] == 0
    assert none["narrowest_pulse"] >= bit / 0.1 * (1 - 1e-12)
    assert set(("pulses", "pulses_skipped", "carried_delta_v")) <= set(columns(res))
    for r in rows.values():
        assert res.tracks[0][r["feedback"]]["control"][..., :3].max() <= 0.1 * (1 + 1e-12)


def test_the_pulses_block():
    from se3ocp.problems.flight import parse_flight
    from se3ocp.problems.flight.actuators import pulse_thrust
    from se3ocp.problems.schema import ConfigError

    spec = parse_flight({"actuators": {"pulses": {"minimum_impulse": 5e-5}}})
    assert spec.actuators == {"pulses": {"minimum_impulse": 5e-5}}
    assert spec.resolved["actuators"] == spec.actuators and "actuators" not in parse_flight({}).resolved
    for bad, field in (({"pulses": {}}, "flight.actuators.pulses.minimum_impulse"),
                       ({"pulses": {"minimum_impulse": -1.0}}, "flight.actuators.pulses.minimum_impulse"),
                       ({"pulses": {"minimum_impulse": 1.0, "thrust": 0}}, "flight.actuators.pulses.thrust"),
                       ({"pulse": {}}, "flight.actuators.pulse")):
        with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
            parse_flight({"actuators": bad})
    man = _engine_man()
    assert pulse_thrust({"minimum_impulse": 0.0}, man.problem) == (0.1, "")
    assert pulse_thrust({"minimum_impulse": 0.0, "thrust": 0.3}, man.problem) == (0.3, "")


def test_the_leo_pulses_flight_file():
    """configs/flights/leo_pulses_j2.yaml reads for the LEO engine raise: a j2 truth with the earth preset's numbers, a
    bit of 5e-5 kN s (0.05 N s: the file's impulse unit kN s shows as N s times 1e3), the thrust the engine's 1 N; the
    command's line says so in N and N s."""
    from se3ocp.problems.bodies import UnitSystem
    from se3ocp.problems.flight import load_flight
    from se3ocp.problems.flight.actuators import actuator_lines, pulse_thrust
    from se3ocp.problems.units import units
    from support import CONFIGS, maneuver

    man = maneuver("leo_body_engine")
    spec = load_flight(CONFIGS / "flights" / "leo_pulses_j2.yaml", man)
    assert spec.gravity["kind"] == "j2" and spec.gravity["J2"] == pytest.approx(1.0826359e-3, rel=1e-7)
    unit, factor = UnitSystem("km", "kg", "s").display("impulse")
    assert unit == "N·s" and factor * spec.actuators["pulses"]["minimum_impulse"] == pytest.approx(0.05, rel=1e-12)
    assert pulse_thrust(spec.actuators["pulses"], man.problem) == (1.0e-3, "")
    line = actuator_lines(spec.actuators, man.problem, units(man.problem))[0]
    assert line.startswith("on/off thrusters: 1 N pulses, minimum impulse 0.05 N·s"), line
