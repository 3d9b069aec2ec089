"""Issue 44, burns, delta-v and propellant (transcription/results/burns.py, problems/burns.py): the burn table of a
plan with a force, an engine's isp (seconds) and the propellant it gives, in the units a person reads."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.bounds import G0
from se3ocp.transcription.results.burns import burns

from support import config, maneuver

ISP = 220.0                 # s: a hydrazine thruster's
MAX = 1.0e-3                # kN: leo_body_engine's 1 N engine
RUNS = ((30, 79, 0.8), (150, 181, 0.5), (300, 300, 1.0))     # (first node, last node, thrust / max) of each burn


def _leo(N: int = 400, *sets: str):
    """configs/leo_body_engine.yaml (500 kg, km-kg-s, one engine along body +x, 0 <= T <= 1 N) with an isp of 220 s
    (the LGVI: controls u_0..u_N at the nodes)."""
    return maneuver("leo_body_engine", N, "lgvi", f"control.bounds.force.thruster.isp={ISP!r}", *sets)


def _stepped(man, runs=RUNS):
    """The plan of ``man`` under the engine at ``runs`` (thrust along body +x, zero elsewhere, no moment),
    simulated: a thrust history whose burns are known in closed form."""
    p = man.problem
    U = np.zeros((6, p.disc.n_controls(p.N)))
    for a, b, level in runs:
        U[0, a:b + 1] = level * MAX
    sol = se3ocp.simulate(man, U)
    assert sol.converged, sol.message
    return sol


# ---------------------------------------------------------------------------------------------- the isp
def test_isp_is_the_engine_s_exhaust_velocity_in_the_file_s_units():
    """isp 220 s in a km file: c = 220 x 9.80665 m/s = 2.157463 km/s (to round-off); kept by a bounds margin (the
    plan's scaled engine) and in the resolved configuration, which reads back to the same engine."""
    b = _leo(40).problem.control.force_bound
    assert b.exhaust_velocity == pytest.approx(ISP * 9.80665 / 1000.0, rel=1e-15)
    assert _leo(40, "control.bounds_margin=0.1").problem.control.force_bound.exhaust_velocity == b.exhaust_velocity
    man = _leo(40)
    assert man.resolved["control"]["bounds"]["force"]["thruster"]["isp"] == ISP
    from se3ocp.problems.maneuvers import parse_maneuver

    again = parse_maneuver(man.resolved, "resolved")
    assert again.problem.control.force_bound.exhaust_velocity == b.exhaust_velocity


@pytest.mark.parametrize("value, expected", [("-1", "expected a positive number, got -1"),
                                             ("0", "expected a positive number, got 0"),
                                             ("abc", "expected a number, got the string 'abc'"),
                                             ("1.0e200", "expected a specific impulse in seconds from")])
def test_a_bad_isp_is_one_line_and_exit_2(capsys, value, expected):
    from se3ocp.problems.cli import main

    rc = main(["validate", str(config("leo_body_engine")), "--set", f"control.bounds.force.thruster.isp={value}"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "control.bounds.force.thruster.isp" in err and expected in err


def test_an_isp_needs_the_file_s_units(capsys):
    """Seconds cannot be read in a file without units (e3: normalized): refused, naming the field and the cure."""
    from se3ocp.problems.cli import main

    rc = main(["validate", str(config("e3")), "--set", "control.force_frame=body", "--set",
               "control.bounds={force: {thruster: {axis: [1, 0, 0], max: 10, isp: 300}}}"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1
    assert "control.bounds.force.thruster.isp" in err and "units: or central_body:" in err


E3_ENGINE = "control.bounds={force: {thruster: {axis: [1, 0, 0], max: 10, exhaust_velocity: 50}}}"


def test_a_normalized_file_gives_its_engine_s_exhaust_velocity():
    """e3 (normalized units) with an engine of exhaust velocity 50 radii/period: kept as given, and the propellant
    of a constant 5-unit thrust over the horizon is m dv / 50 = 5 T / 50 (m = 1); the table keeps the file's units
    (mass, radii/period).  isp and exhaust_velocity together are refused (one line, exit 2)."""
    from se3ocp.problems.burns import burn_section
    from se3ocp.problems.cli import main

    man = maneuver("e3", 20, None, "control.force_frame=body", E3_ENGINE)
    assert man.problem.control.force_bound.exhaust_velocity == 50.0
    U = np.zeros((6, man.problem.disc.n_controls(man.problem.N)))
    U[0] = 5.0
    sol = se3ocp.simulate(man, U)
    assert sol.propellant == pytest.approx(5.0 * man.problem.T / 50.0, rel=1e-13)
    sec = burn_section(sol)
    assert "propellant (mass)" in sec["columns"] and "Δv (radii/period)" in sec["columns"]
    rc = main(["validate", str(config("e3")), "--set", "control.force_frame=body", "--set",
               "control.bounds={force: {thruster: {axis: [1, 0, 0], max: 10, exhaust_velocity: 50, isp: 300}}}"])
    assert rc == 2


# ---------------------------------------------------------------------------------------------- the burns
def test_burns_of_a_known_thrust_history():
    """Three burns of constant thrust on nodes a..b of the LGVI (h = T/N): each control holds over the cell
    [t_j - h/2, t_j + h/2], so a burn runs from t_a - h/2 to t_b + h/2, lasts (b - a + 1) h, gives delta-v
    F (b - a + 1) h / m and takes F (b - a + 1) h / (Isp g0) of propellant; mean and peak thrust F.  All to 1e-12
    relative (round-off of the cells' cumulative sum); the burns' durations add up to engine_on_time."""
    sol = _stepped(_leo())
    m, h, c = 500.0, sol.h, ISP * G0 / 1000.0
    assert len(sol.burns) == len(RUNS)
    for burn, (a, b, level) in zip(sol.burns, RUNS):
        F, n = level * MAX, b - a + 1
        assert burn.nodes == n
        assert burn.start == pytest.approx(sol.trajectory.t[a] - h / 2, rel=1e-12)
        assert burn.stop == pytest.approx(sol.trajectory.t[b] + h / 2, rel=1e-12)
        assert burn.duration == pytest.approx(n * h, rel=1e-12)
        assert burn.delta_v == pytest.approx(F * n * h / m, rel=1e-12)
        assert burn.mean_thrust == pytest.approx(F, rel=1e-12) and burn.peak_thrust == pytest.approx(F, rel=1e-15)
        assert burn.propellant == pytest.approx(F * n * h / c, rel=1e-12)
    summ = sol.summary()
    assert sum(b.duration for b in sol.burns) == pytest.approx(summ["engine_on_time"], rel=1e-12)
    assert [b["start"] for b in summ["burns"]] == [b.start for b in sol.burns]


def test_the_switching_times_are_in_the_summary():
    """A burn at the engine's max (the third, a single node) enters and leaves the bound at the midpoints
    between the nodes (ThrusterBound.switches): t_a - h/2 and t_b + h/2, the burn's edges; the burns below max
    start at min's level and leave it there too (the same midpoints).  summary.json lists them under
    switch_times.force (to 1e-12)."""
    sol = _stepped(_leo())
    t, h = sol.trajectory.t, sol.h
    expected = sorted(x for a, b, _ in RUNS for x in (t[a] - h / 2, t[b] + h / 2))
    got = sol.summary()["switch_times"]["force"]
    assert np.allclose(got, expected, rtol=1e-12, atol=0)


def test_burn_delta_v_adds_up_to_the_plan_s():
    """A smooth thrust T_j = max |sin|-shaped (never exactly zero between its humps): the burns' delta-v and the
    nodes below the threshold (summed here by the trapezoid on the node times, np.trapezoid, not the code's
    quadrature weights) give the plan's delta-v to 1e-13 relative; with threshold 0 every node with thrust is in a
    burn and the burns alone give it (1e-13); every gap's thrust is below 1e-3 of the bound."""
    man = _leo()
    p = man.problem
    t = np.linspace(0.0, p.T, p.N + 1)
    T = MAX * np.abs(np.sin(3 * np.pi * t / p.T)) ** 3           # three humps, below 1e-3 max near their ends
    U = np.zeros((6, t.size))
    U[0] = T
    sol = se3ocp.simulate(man, U)
    off = T <= 1e-3 * MAX
    rest = np.trapezoid(np.where(off, T, 0.0), t) / 500.0
    whole = np.trapezoid(T, t) / 500.0
    assert sol.delta_v == pytest.approx(whole, rel=1e-13)
    assert len(sol.burns) == 3
    assert sum(b.delta_v for b in sol.burns) + rest == pytest.approx(sol.delta_v, rel=1e-13)
    assert sum(b.delta_v for b in burns(sol, 0.0)) == pytest.approx(sol.delta_v, rel=1e-13)
    assert 0 < rest < 1e-3 * MAX * p.T / 500.0


def test_a_solved_fuel_plan_s_burns_give_its_delta_v():
    """configs/orbit_raise_fuel.yaml at N = 40 (normalized units, a norm bound of 40, no isp): bang-off-bang, two
    burns, whose delta-v adds up to the plan's to 1e-14 relative (its coasts carry exactly zero thrust); no
    propellant without an isp (nan, and no propellant column)."""
    sol = se3ocp.solve(maneuver("orbit_raise_fuel", 40), continuous_check=False)
    assert sol.converged, sol.message
    assert len(sol.burns) == 2
    assert sum(b.delta_v for b in sol.burns) == pytest.approx(sol.delta_v, rel=1e-14)
    assert all(math.isnan(b.propellant) for b in sol.burns) and math.isnan(sol.propellant)
    from se3ocp.problems.burns import burn_section

    sec = burn_section(sol)
    assert not any("propellant" in c for c in sec["columns"])
    assert "Δv (radii/period)" in sec["columns"] and "start (periods)" in sec["columns"]   # its own units


# ---------------------------------------------------------------------------------------------- propellant
def test_propellant_against_the_rocket_equation():
    """The constant-mass propellant m0 x (x = delta_v / (Isp g0)) against the rocket equation's m0 (1 - exp(-x)):
    m0 x - m0 (1 - exp(-x)) = m0 (x^2/2 - x^3/6 + ...), so the difference lies in [m0 (x^2/2 - x^3/6), m0 x^2/2]
    (an alternating series of decreasing terms, x < 1).  Also the propellant of the burns adds up to it with the
    gaps' delta-v (none here) and summary.json's fraction is propellant / m0."""
    sol = _stepped(_leo())
    m0, c = 500.0, ISP * G0 / 1000.0
    x = sol.delta_v / c
    rocket = -m0 * math.expm1(-x)
    diff = sol.propellant - rocket
    assert m0 * (x * x / 2 - x ** 3 / 6) <= diff <= m0 * x * x / 2
    assert sum(b.propellant for b in sol.burns) == pytest.approx(sol.propellant, rel=1e-13)
    summ = sol.summary()
    assert summ["propellant_fraction"] == pytest.approx(sol.propellant / m0, rel=1e-15)
    assert summ["exhaust_velocity"] == c


# ---------------------------------------------------------------------------------------------- the table
def test_the_cli_table_reads_m_s_n_and_kg():
    """The CLI's lines after its results table, for a km file: delta-v in m/s (1000 x km/s), thrust in N (1000 x
    kN), propellant in kg, to the 4 digits shown; the constant mass said with the fraction; no warning below 1 %."""
    from se3ocp.problems.cli.progress import table

    sol = _stepped(_leo())
    lines = table([sol])
    head = next(i for i, ln in enumerate(lines) if ln.startswith("simulate: 3 burns"))
    assert "Δv (m/s)" in lines[head + 1] and "mean thrust (N)" in lines[head + 1] and "propellant (kg)" in lines[head + 1]
    first = lines[head + 2].split()
    b = sol.burns[0]
    assert float(first[4]) == pytest.approx(1e3 * b.delta_v, rel=5e-4)
    assert float(first[5]) == pytest.approx(1e3 * b.mean_thrust, rel=5e-4)
    assert float(first[7]) == pytest.approx(b.propellant, rel=5e-4)
    total = lines[head + 5].split()
    assert total[0] == "total" and float(total[1]) == pytest.approx(1e3 * sol.delta_v, rel=5e-4)
    text = "\n".join(lines)
    assert "keep the mass constant" in text and f"{100 * sol.propellant / 500.0:.3g} % of the 500 kg" in text
    assert "warning" not in text


def test_a_large_propellant_fraction_is_warned_about():
    """An isp of 0.5 s (c = 4.9 m/s) makes the stepped plan's propellant a large fraction of the mass: the table
    warns, with the delta-v error f/2 of the constant-mass dynamics."""
    from se3ocp.problems.burns import burn_section

    sol = _stepped(_leo(400, "control.bounds.force.thruster.isp=0.5"))
    f = sol.propellant / 500.0
    assert f > 0.01
    sec = burn_section(sol)
    assert f"{100 * f:.3g} % of the mass" in sec["warning"] and f"{50 * f:.2g} % of the Δv" in sec["warning"]


@pytest.mark.slow
def test_the_leo_engine_raise_with_an_isp_end_to_end(tmp_path, capsys):
    """Acceptance (issue 44; slow: one default solve of configs/leo_body_engine.yaml, N = 400, ~10 s): `se3ocp solve`
    with an isp of 220 s prints the burn table in m/s, N and kg; summary.json's burns give the delta-v integrated
    from the plan's thrust (np.trapezoid of |u_f| on the node times, to 1e-12) and the propellant m dv / (Isp g0)
    (Tsiolkovsky to x^2/2); report.html shows the table; the flights' controls figure draws the engine in N."""
    from se3ocp.problems.cli import main

    out = tmp_path / "run"
    rc = main(["solve", str(config("leo_body_engine")), "--set", f"control.bounds.force.thruster.isp={ISP!r}",
               "--out", str(out), "--no-figures"])
    text = capsys.readouterr().out
    assert rc == 0
    summ = json.loads((out / "summary.json").read_text())["methods"]["direct"]
    with np.load(out / "direct.npz") as z:
        dv = np.trapezoid(np.linalg.norm(z["u_f"], axis=1), z["t_u"]) / 500.0
    assert sum(b["delta_v"] for b in summ["burns"]) == pytest.approx(dv, rel=1e-6)   # the gaps' share, measured 3e-9
    assert summ["delta_v"] == pytest.approx(dv, rel=1e-12)
    c = ISP * G0 / 1000.0
    x = dv / c
    assert summ["propellant"] == pytest.approx(500.0 * dv / c, rel=1e-12)
    assert 0 <= summ["propellant"] - -500.0 * math.expm1(-x) <= 500.0 * x * x / 2
    assert "Δv (m/s)" in text and "propellant (kg)" in text and f"{1e3 * dv:.4g}" in text
    html = (out / "report.html").read_text()
    assert 'id="burns-direct"' in html and f"{summ['propellant']:.4g}" in html
    # the flights' controls figure of that plan (issue 44: the engine force was drawn in kN): in N, under 1 N
    from se3ocp.problems.flight import parse_flight
    from se3ocp.problems.flight.figures import _controls
    from se3ocp.problems.flight.run import run_flights
    from se3ocp.problems.store import read_run
    from se3ocp.problems.sweep.executors import SerialExecutor

    run = read_run(out)
    res = run_flights(run.maneuver, run.solutions["direct"], parse_flight({"runs": 1, "feedback": "lqr"}),
                      executor=SerialExecutor())
    force = _controls(res).axes[0]
    assert force.get_ylabel().endswith("(N)") and "actuators' bound" in force.get_title()
    peak = max(np.max(line.get_ydata()) for line in force.get_lines() if len(line.get_ydata()) > 2)
    assert 0.5 < peak <= 1.0 + 1e-6          # the plan's peak thrust 0.85 N, in N (0.00085 in kN)
