"""Flights in an orbit's terms (issue 44): terminal misses in osculating elements, units in the tables.

Every claim with its tolerance:

* problems.elements.element_differences returns a known change of a circular orbit's a, i, Ω and u (states built
  here by hand from the circular-orbit formulas, not by problems.elements.state_of) to 1e-9 km and 1e-9 deg; on a
  near-circular orbit (e = 1e-7, ω 123 deg away from the reference's) Δu is the built-in change to 1e-9 deg while
  ω and ν alone each differ by ~100 deg.
* A flight's element misses (flights.csv columns miss_a ... miss_u_deg) equal an independent computation from the
  saved flown terminal state and the plan's last node (vis-viva, the eccentricity vector, the angular momentum and
  the node line, written here) to 1e-9 (km, deg).
* The command's table and the report give units: km, m/s, deg for a km file; the velocity miss in m/s is 1000 times
  its km/s value.
* A j2 truth on an Earth-preset maneuver (configs/leo_raise_slew.yaml) without numbers takes the preset's J2 and
  radius (IERS 2010, km); an explicit J2 wins; the output names those taken.  The open-loop node miss is the
  first-order J2 regression of the node -3/2 n J2 (R/a)^2 cos i T to 1 % (measured 0.2 %; with J2 = 2e-3, 0.4 %).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.elements import element_differences, elements_of
from se3ocp.problems.flight.command import table
from se3ocp.problems.flight.output import write_flights
from se3ocp.problems.flight.task import ELEMENT_METRICS

from support import maneuver

MU = 398600.4418  # km^3/s^2


def circular(a, i_deg, raan_deg, u_deg, mu=MU):
    """Position and velocity on a circular orbit of radius a, by hand: Rz(Ω) Rx(i) (cos u, sin u, 0)."""
    i, O, u = map(math.radians, (i_deg, raan_deg, u_deg))
    p = np.array([math.cos(u), math.sin(u), 0.0])
    q = np.array([-math.sin(u), math.cos(u), 0.0])
    Rx = np.array([[1, 0, 0], [0, math.cos(i), -math.sin(i)], [0, math.sin(i), math.cos(i)]])
    Rz = np.array([[math.cos(O), -math.sin(O), 0], [math.sin(O), math.cos(O), 0], [0, 0, 1]])
    return Rz @ Rx @ (a * p), Rz @ Rx @ (math.sqrt(mu / a) * q)


def test_element_differences_of_a_known_change_of_a_circular_orbit():
    ref = circular(6778.137, 51.6, 30.0, 40.0)
    for da, di, dO, du in ((0.5, 0.0, 0.0, 0.0), (0.0, 0.01, 0.0, 0.0), (-2.0, -0.3, 0.2, 1.5), (0.0, 0.0, -0.7, -3.0)):
        d = element_differences(MU, *circular(6778.137 + da, 51.6 + di, 30.0 + dO, 40.0 + du), *ref)
        assert d["a"] == pytest.approx(da, abs=1e-9) and abs(d["e"]) < 1e-12
        for key, want in (("i_deg", di), ("raan_deg", dO), ("u_deg", du)):
            assert d[key] == pytest.approx(want, abs=1e-9), key
    # the wrap: u from 359.5 to 0.5 deg is +1 deg, not -359
    d = element_differences(MU, *circular(7000.0, 10.0, 0.0, 0.5), *circular(7000.0, 10.0, 0.0, 359.5))
    assert d["u_deg"] == pytest.approx(1.0, abs=1e-9)


def test_near_circular_orbit_the_argument_of_latitude_is_defined_where_periapsis_is_not():
    a, e, i, O, w, u = 6778.137, 1e-7, 51.6, 30.0, 123.0, 40.0
    nu = math.radians(u - w)
    p = a * (1 - e * e)
    r = p / (1 + e * math.cos(nu))
    iR, OR, wR = map(math.radians, (i, O, w))
    # the perifocal state rotated by Rz(Ω) Rx(i) Rz(ω), written out
    Rz = lambda t: np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])  # noqa: E731
    Rx = np.array([[1, 0, 0], [0, math.cos(iR), -math.sin(iR)], [0, math.sin(iR), math.cos(iR)]])
    Q = Rz(OR) @ Rx @ Rz(wR)
    x = Q @ np.array([r * math.cos(nu), r * math.sin(nu), 0.0])
    v = Q @ (math.sqrt(MU / p) * np.array([-math.sin(nu), e + math.cos(nu), 0.0]))
    ref = circular(a, i, O, u - 0.25)                      # the plan: circular, 0.25 deg behind
    d = element_differences(MU, x, v, *ref)
    assert d["u_deg"] == pytest.approx(0.25, abs=1e-9)
    assert d["a"] == pytest.approx(0.0, abs=1e-6) and d["e"] == pytest.approx(e, abs=1e-12)
    flown, plan = elements_of(MU, x, v), elements_of(MU, *ref)
    assert abs(flown["argp_deg"] - plan["argp_deg"]) > 100 and abs(flown["nu_deg"] - plan["nu_deg"]) > 100


def independent_elements(mu, x, v):
    """(a, e, i, Ω, u) in deg, from vis-viva, the eccentricity vector, h and the node line (not problems.elements)."""
    r, h = np.linalg.norm(x), np.cross(x, v)
    a = -mu / (2 * (v @ v / 2 - mu / r))
    e = np.linalg.norm(((v @ v - mu / r) * x - (x @ v) * v) / mu)
    n = np.cross([0.0, 0.0, 1.0], h)
    i = math.degrees(math.acos(h[2] / np.linalg.norm(h)))
    O = math.degrees(math.atan2(n[1], n[0]))
    u = math.degrees(math.atan2(np.cross(h, n) @ x / np.linalg.norm(h), n @ x))
    return a, e, i, O, u


@pytest.fixture(scope="module")
def leo_flight():
    man = maneuver("leo_raise_slew", 40)
    sol = se3ocp.solve(man, "direct")
    assert sol.converged
    flight = {"truth": {"gravity": {"kind": "j2", "J2": 1.0826359e-3, "radius": 6378.1366}},
              "errors": {"initial": {"position": 1e-3, "velocity": 1e-6}, "force_scale": 0.02}, "runs": 2, "seed": 5}
    return man, sol, se3ocp.fly(sol, flight, maneuver=man, save_runs=2)


def test_a_flights_element_misses_against_an_independent_computation(leo_flight):
    man, sol, res = leo_flight
    m = man.problem.model.mass
    plan = independent_elements(MU, sol.trajectory.X[-1, 0:3], sol.trajectory.X[-1, 3:6] / m)
    assert man.problem.model.mu == pytest.approx(MU, rel=1e-12)
    for row in res.rows:
        X = res.saved[row["run"]][f"{row['feedback']}_X"][-1]
        flown = independent_elements(MU, X[0:3], X[3:6] / m)
        want = [f - p for f, p in zip(flown, plan)]
        want[3:] = [(w + 180) % 360 - 180 for w in want[3:]]
        assert row["status"] == "ok"
        got = [row[k] for k in ELEMENT_METRICS]
        assert np.allclose(got, want, rtol=0, atol=1e-9), (row["feedback"], got, want)
    # the open loop under J2 drifts the node by a visible amount; the tracker holds it
    none = [r for r in res.rows if r["feedback"] == "none"]
    assert min(abs(r["miss_raan_deg"]) for r in none) > 0.1


def test_tables_and_report_give_units(leo_flight, tmp_path):
    man, sol, res = leo_flight
    lines = table(res)
    byname = {ln.split()[0]: ln for ln in lines}
    assert byname["position_miss"].split()[1] == "km" and byname["velocity_miss"].split()[1] == "m/s"
    for k in ("attitude_miss_deg", "miss_i_deg", "miss_raan_deg", "miss_u_deg"):
        assert byname[k].split()[1] == "deg", k
    assert byname["miss_a"].split()[1] == "km" and byname["delta_v_overhead"].split()[1] == "%"
    p95 = res.statistics()["none"]["velocity_miss"]["p95"]
    assert float(byname["velocity_miss"].split()[2]) == pytest.approx(1000 * p95, rel=1e-3)   # printed to 4 digits
    write_flights(tmp_path, res, sol.arrays(), figures=False)
    html = (tmp_path / "report.html").read_text()
    for part in ("terminal miss in osculating semi-major axis a</td><td class=\"unit\">km",
                 "terminal miss in osculating argument of latitude u = ω + ν</td><td class=\"unit\">deg",
                 "terminal velocity miss</td><td class=\"unit\">m/s"):
        assert part in html, part
    assert set(ELEMENT_METRICS) <= set((tmp_path / "flights.csv").read_text().splitlines()[0].split(","))


def test_no_element_misses_without_a_central_body():
    from se3ocp.problems.flight.task import metric_keys

    assert not set(ELEMENT_METRICS) & set(metric_keys(maneuver("slew_time_optimal", 20).problem))
    assert set(ELEMENT_METRICS) <= set(metric_keys(maneuver("e3", 20).problem))


# ------------------------------------------------------------------------------ the truth's J2 from the preset
def nodal_regression_deg(a, i_deg, J2, R, T, mu=MU):
    """The secular drift of Ω over T under J2 (deg): -3/2 n J2 (R/a)^2 cos i T, circular orbit."""
    n = math.sqrt(mu / a**3)
    return math.degrees(-1.5 * n * J2 * (R / a) ** 2 * math.cos(math.radians(i_deg)) * T)


def test_a_j2_truth_takes_the_earth_presets_numbers_and_an_explicit_one_wins():
    man = maneuver("leo_raise_slew", 40)
    sol = se3ocp.solve(man, "direct")
    open_loop = {"feedback": "none", "runs": 1}
    res = se3ocp.fly(sol, {"truth": {"gravity": {"kind": "j2"}}, **open_loop}, maneuver=man)
    assert res.spec.gravity == {"kind": "j2", "J2": 1.0826359e-3, "radius": 6378.1366}     # IERS 2010, in km
    assert res.summary()["truth_from_preset"]["values"] == {"J2": 1.0826359e-3, "radius": 6378.1366}
    # the open-loop node miss is the J2 regression of the node over the ~1 orbit flown (the plan has none): to 1 %
    a = 0.5 * (6778.137 + 6788.137)
    want = nodal_regression_deg(a, 51.6, 1.0826359e-3, 6378.1366, man.T)
    assert res.rows[0]["miss_raan_deg"] == pytest.approx(want, rel=1e-2)
    # J2 given: it wins, the radius still the preset's, and the output says which
    res2 = se3ocp.fly(sol, {"truth": {"gravity": {"kind": "j2", "J2": 2e-3}}, **open_loop}, maneuver=man)
    assert res2.spec.gravity["J2"] == 2e-3 and res2.summary()["truth_from_preset"]["values"] == {"radius": 6378.1366}
    assert res2.rows[0]["miss_raan_deg"] == pytest.approx(want * 2e-3 / 1.0826359e-3, rel=1e-2)


def test_the_maneuvers_own_flight_block_and_the_command_take_the_preset(tmp_path, capsys):
    from se3ocp.problems.cli import main

    man = se3ocp.load("configs/leo_raise_slew.yaml", ["horizon.N=40", "flight={truth: {gravity: {kind: j2}}}"])
    assert man.resolved["flight"]["truth"]["gravity"] == {"kind": "j2", "J2": 1.0826359e-3, "radius": 6378.1366}
    f = tmp_path / "flight.yaml"
    f.write_text("flight: {truth: {gravity: {kind: j2, radius: 6400.0}}, feedback: none, runs: 1}\n")
    assert main(["fly", "configs/leo_raise_slew.yaml", "--set", "horizon.N=40", "--flight", str(f), "--workers", "1",
                 "--out", str(tmp_path / "o"), "--no-figures"]) == 0
    out = capsys.readouterr().out
    assert "the truth's J2 = 0.0010826359 is the earth preset's (IERS Conventions (2010), Table 1.1)" in out
    assert "J2 = 0.0010826359 is the earth preset" in (tmp_path / "o" / "report.html").read_text()


def test_a_j2_truth_without_a_preset_needs_its_numbers():
    from se3ocp.problems.flight.schema import parse_flight
    from se3ocp.problems.schema import ConfigError

    man = maneuver("e3", 20)
    with pytest.raises(ConfigError, match=r"flight.truth.gravity.J2: missing required key .*central_body: earth"):
        se3ocp.fly(se3ocp.solve(man, "direct"), {"truth": {"gravity": {"kind": "j2"}}}, maneuver=man)
    with pytest.raises(ConfigError, match=r"flight.truth.gravity.radius: missing"):
        parse_flight({"truth": {"gravity": {"kind": "j2", "J2": 1e-3}}})


# ------------------------------------------------------------------------- MPC on an Earth-preset maneuver
def test_mpc_flies_an_earth_preset_maneuver_and_keeps_its_clearance(tmp_path):
    """configs/leo_raise_slew.yaml (N = 40): the preset adds the Earth's clearance min_radius 6378.1366 km, which made
    every MPC flight exit 2; the re-plans check it on their predicted nodes and the flight's margin on every sample
    is min |x(t)| - R of the flown path (computed here from the saved flight, to 1e-9 km).  J2 truth, 2 % thrust
    scale: MPC's position miss <= 2 % of open loop's (measured 0.6 %), no re-plan rejected."""
    from se3ocp.problems.cli import main

    man = maneuver("leo_raise_slew", 40)
    assert [c.kind for c in man.problem.constraints] == ["min_radius"]
    sol = se3ocp.solve(man, "direct")
    block = {"truth": {"gravity": {"kind": "j2"}}, "errors": {"force_scale": 0.02}, "mpc": {"replan_every": 10},
             "runs": 1, "seed": 2}
    res = se3ocp.fly(sol, {**block, "feedback": "all"}, maneuver=man, save_runs=1)
    rows = {r["feedback"]: r for r in res.rows}
    assert all(r["status"] == "ok" for r in rows.values())
    assert rows["mpc"]["replans"] == 4 and rows["mpc"]["replans_rejected"] == 0
    assert rows["mpc"]["position_miss"] <= 0.02 * rows["none"]["position_miss"]
    for mode in ("none", "mpc"):
        flown = np.linalg.norm(res.saved[0][f"{mode}_X"][:, :3], axis=1).min() - 6378.1366
        assert rows[mode]["min_margin_min_radius"] == pytest.approx(flown, abs=1e-9) and flown > 390.0
    assert res.summary()["mpc"]["checked_constraints"] == ["min_radius 6378.14"]
    assert "polished by the indirect method" in res.summary()["mpc"]["warm_start"]
    f = tmp_path / "flight.yaml"
    f.write_text(f"flight: {block}\n")
    assert main(["fly", "configs/leo_raise_slew.yaml", "--set", "horizon.N=40", "--flight", str(f), "--feedback", "mpc",
                 "--workers", "1", "--out", str(tmp_path / "o"), "--quiet", "--no-figures"]) == 0
    assert "The re-plans leave\nmin_radius 6378.14 out of their Newton step" in (tmp_path / "o" / "report.html").read_text()


def test_a_replan_whose_prediction_cuts_inside_the_radius_is_rejected():
    """The same plan under a radius of 6783 km (between its initial 6778 and final 6788 km orbits): re-planned from
    its own first node, the prediction is the plan itself, whose first nodes are inside: rejected, with the reason;
    under the Earth's radius accepted.  A plan that touches the radius is refused for MPC; other path constraints
    are still not covered."""
    from se3ocp.problems.schema import ConfigError
    from se3ocp.transcription.closedloop.mpc import Replanner, replan_not_covered, touching
    from se3ocp.transcription.ocp.constraints import MinRadius

    man = maneuver("leo_raise_slew", 40)
    sol = se3ocp.solve(man, "direct")
    for radius, accepted in ((6378.1366, True), (6783.0, False)):
        p = man.problem.replace(constraints=(MinRadius(radius=radius),))
        rp = Replanner(p, sol.h)
        new, rec = rp.replan(sol.trajectory.X[0], rp.start(sol.warm).tail(0))
        assert rec.accepted == accepted and (new is not None) == accepted
        inside = 6783.0 - np.linalg.norm(sol.trajectory.X[1:, :3], axis=1).min()
        assert accepted or rec.message == (f"the re-plan's prediction violates its min_radius 6783 by {inside:.3g} "
                                           f"at a node")
        assert bool(touching(p, sol.trajectory.X, 1e-6)) != accepted
    e3 = maneuver("e3_min_radius", 60)
    with pytest.raises(ConfigError, match=r"flight.feedback: mpc: the plan touches its min_radius 0.995 \(margin "):
        se3ocp.fly(se3ocp.solve(e3, "direct"), {"feedback": "mpc", "runs": 1}, maneuver=e3)
    assert replan_not_covered(maneuver("slew_keep_out", 20).problem) == "path constraints"      # a fixed keep-out cone


def test_the_replans_start_from_costates_polished_by_the_indirect_method():
    """A direct plan's costates are IPOPT's multipliers: re-planned from the LEO raise's own first node (N = 40) they
    leave the shooting residual 1.5e-4 (km, kg km/s), which a re-plan's acceptance (better than its warm start) then
    measures against; polished by the indirect method 1.6e-11 (asserted <= 1e-9), the same plan (controls 4e-7)."""
    from se3ocp.transcription.closedloop.mpc import Replanner, polished

    man = maneuver("leo_raise_slew", 40)
    sol = se3ocp.solve(man, "direct")
    better, note = polished(sol)
    assert note.startswith("the direct plan's costates polished by the indirect method (|z_N| ")
    rp = Replanner(man.problem, sol.h)
    before = [rp.replan(sol.trajectory.X[0], rp.start(s.warm).tail(0))[1].residual_before for s in (sol, better)]
    assert before[0] > 1e-5 and before[1] <= 1e-9
    assert np.array_equal(better.controls, sol.controls) and better.warm is not sol.warm


def test_a_plan_no_feedback_can_hold_on_the_truths_j2_is_said_before_flying_and_kept(tmp_path, capsys):
    """leo_body_engine (a 1 N engine) planned about a point mass and flown on the preset's J2: the command says before
    the flights that the plane's turn needs more delta-v than the engine has (problems.flight.forces.j2_plane_drift),
    and summary.json and report.html keep the line; flown on its own gravity, nothing is said."""
    from se3ocp.problems.cli import main

    f = tmp_path / "flight.yaml"
    f.write_text("flight: {truth: {gravity: {kind: j2}}, feedback: none, runs: 1}\n")
    args = ["fly", "configs/leo_body_engine.yaml", "--set", "horizon.N=40", "--workers", "1", "--no-figures"]
    assert main([*args, "--flight", str(f), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    said = [ln for ln in out.splitlines() if "warning: the truth's J2 is not in the plan" in ln]
    assert len(said) == 1 and out.index(said[0]) < out.index("p95 (mean)"), out
    line = said[0].split("warning: ", 1)[1]
    assert "needs at least 2" in line and "m/s, and the force bound leaves" in line
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["plane_drift"] == line
    assert "No feedback can hold this plan:" in (tmp_path / "o" / "report.html").read_text()
    f.write_text("flight: {feedback: none, runs: 1}\n")
    assert main([*args, "--flight", str(f), "--out", str(tmp_path / "p")]) == 0
    assert "J2 is not in the plan" not in capsys.readouterr().out
    assert "plane_drift" not in json.loads((tmp_path / "p" / "summary.json").read_text())
