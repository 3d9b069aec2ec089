"""Flying a plan (issue 25; problems/flight): the flight block, the sampling of errors, the Monte Carlo on any
executor, the saved runs re-flown independently, the figures of merit, and ``se3ocp fly``.

Every claim with its tolerance:

* A run's errors depend on the seed and the run's index only: the same statistics, bit for bit, in-process
  and on a pool of 2 workers; switching one error on leaves the other draws unchanged.
* Saved runs (runs/NNNN.npz) re-flown by the re-flight of tests/test_flight.py (scipy's DOP853 on its own
  right-hand side: quaternions, the dumbbell's gravity with the textbook J2 term, its own control
  interpolation and actuator model) from the saved errors and applied commands land within 1e-8 relative
  of the recorded truth at every node (measured 6e-13).
* The figures of merit against independent arithmetic: the open-loop delta-v of a flight with a force scale
  s is (1 + s) times the plan's to 1e-9; without errors every miss is the continuous flight's own.
* Closed loop on the continuous truth (few runs; the 500-run figures are scripts/bench_flight.py's): E3 with
  J2, thrust scale and misalignment, initial dispersions: the LQR's position miss <= 1e-3 of open loop;
  the slew planned with bounds_margin 0.1 under torque and inertia errors: <= 0.01 deg and 1e-4 rad/s.
* The command: exit 0 with every file; a results directory as the plan; bad input exit 2 and nothing
  written; a plan that does not converge exit 1 and nothing written; Ctrl-C exit 130 with the finished runs
  written and marked INCOMPLETE.
"""
from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.cli import main
from se3ocp.problems.flight import fly, load_flight, parse_flight
from se3ocp.problems.flight.output import write_flights
from se3ocp.problems.flight.plan import run_seeds, sample_errors
from se3ocp.problems.flight.command import table as fly_table
from se3ocp.problems.flight.run import run_flights, worse_than_open
from se3ocp.problems.schema import ConfigError
from se3ocp.problems.sweep.executors import PoolExecutor, SerialExecutor
from se3ocp.transcription.results.check import continuous_check

from support import ROOT, config, maneuver
from test_flight import gravity, reflight

E3_FLIGHT = {"truth": {"gravity": {"kind": "j2", "J2": 1.08e-3, "radius": 0.9}},
             "errors": {"initial": {"position": 1e-4, "velocity": 1e-4, "attitude_deg": 0.5, "angular_velocity": 1e-3},
                        "force_scale": 0.02, "force_misalignment_deg": 0.5}, "runs": 4, "seed": 3}


@pytest.fixture(scope="module")
def e3_plan():
    man = maneuver("e3", 50, "lgvi")
    sol = se3ocp.solve(man, "direct")
    assert sol.converged
    return man, sol


# ------------------------------------------------------------------------------------ the flight block
def test_the_flight_block_defaults_and_its_one_line_errors(tmp_path):
    spec = parse_flight({})
    assert spec.modes == ("none", "lqr") and spec.runs == 100 and spec.seed == 0 and spec.gravity is None
    assert spec.errors["force_scale"] == 0.0 and spec.errors["initial"]["attitude_deg"] == 0.0
    assert parse_flight(spec.resolved).resolved == spec.resolved           # the resolved block is a valid block
    for doc, message in (({"runs": 0}, "flight.runs: expected a positive integer"),
                         ({"feedback": "pid"}, "flight.feedback: expected one of none, lqr, mpc, both, all"),
                         ({"errors": {"force_scale": -0.1}}, "flight.errors.force_scale: expected a non-negative"),
                         ({"errors": {"initial": {"attitude": 1}}}, "flight.errors.initial.attitude: unknown key"),
                         ({"truth": {"gravity": {"kind": "j2"}}}, "flight.truth.gravity.J2: missing required key"),
                         ({"truth": {"integrator": "dop853"}}, "flight.truth.integrator: expected one of cvodes"),
                         ({"weights": {"bandwith": 1}}, "flight.weights.bandwith: unknown key"),
                         ({"seed": -1}, "flight.seed: expected a non-negative number")):
        with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
            parse_flight(doc, "f.yaml")
    # in a maneuver file the block is checked when the file is read
    with pytest.raises(ConfigError, match="flight.runs: expected a positive integer"):
        se3ocp.load(config("e3"), ["flight.runs=0"])
    assert se3ocp.load(config("e3"), ["flight.runs=7"]).resolved["flight"]["runs"] == 7
    f = tmp_path / "f.yaml"
    f.write_text("runs: 3\n")
    with pytest.raises(ConfigError, match="flight: missing"):
        load_flight(f)
    f.write_text("flight: {runs: 3, errors: {moment_scale: 0.01}}\n")
    assert load_flight(f).runs == 3 and load_flight(f).errors["moment_scale"] == 0.01


def test_a_runs_errors_depend_on_the_seed_and_its_index_only(e3_plan):
    man, sol = e3_plan
    X0, m, J = sol.trajectory.X[0], man.problem.model.mass, man.problem.model.inertia
    spec = parse_flight({"errors": {"force_scale": 0.02, "inertia_scale": 0.01}, "runs": 5, "seed": 9})
    a = sample_errors(spec, 3, run_seeds(spec)[3], X0, m, J)
    again = sample_errors(spec, 3, np.random.SeedSequence(9).spawn(5)[3], X0, m, J)
    assert a.actuators.force_scale == again.actuators.force_scale and np.array_equal(a.inertia, again.inertia)
    # the draws of one error do not depend on the others being switched on
    more = parse_flight({"errors": {"force_scale": 0.02, "inertia_scale": 0.01, "moment_scale": 0.05,
                                    "initial": {"position": 1e-3}}, "runs": 5, "seed": 9})
    b = sample_errors(more, 3, run_seeds(more)[3], X0, m, J)
    assert b.actuators.force_scale == a.actuators.force_scale and np.array_equal(b.inertia, a.inertia)
    assert b.actuators.moment_scale != 1.0 and np.abs(b.z0[:3]).max() > 0
    assert np.array_equal(a.X0[:15], X0[:15])          # no initial offset but Pi_0 = J_truth Omega_0
    other = sample_errors(spec, 4, run_seeds(spec)[4], X0, m, J)
    assert other.actuators.force_scale != a.actuators.force_scale


def test_the_same_seed_gives_the_same_statistics_on_any_number_of_workers(e3_plan):
    man, sol = e3_plan
    spec = parse_flight({**E3_FLIGHT, "runs": 6})
    serial = run_flights(man, sol, spec, executor=SerialExecutor())
    pool = PoolExecutor(2)
    try:
        pooled = run_flights(man, sol, spec, executor=pool)
    finally:
        pool.shutdown()
    assert [r["run"] for r in serial.rows] == [0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5]
    assert serial.rows == pooled.rows
    assert serial.statistics() == pooled.statistics()
    assert pooled.executor == "local" and pooled.workers == 2 and not pooled.failed


# ------------------------------------------------------------------------------------ saved runs
def test_saved_runs_reflown_independently_land_on_the_recorded_truth(e3_plan, tmp_path):
    """runs/0000.npz and 0001.npz of E3 (LGVI, N = 50) under J2, thrust errors and dispersions, open loop and
    LQR: the re-flight of tests/test_flight.py from the saved X0, inertia, actuator errors and commands
    agrees with the recorded truth to 1e-8 relative at every node (measured 5e-13 .. 6.3e-13)."""
    man, sol = e3_plan
    res = run_flights(man, sol, parse_flight(E3_FLIGHT), executor=SerialExecutor(), save_runs=2)
    write_flights(tmp_path, res, sol.arrays(), figures=False)
    flight = load_flight(tmp_path / "flight.resolved.yaml")
    g = flight.gravity
    body = man.problem.model
    for i in (0, 1):
        z = dict(np.load(tmp_path / "runs" / f"{i:04d}.npz"))
        assert int(z["run"]) == i and z["inertia"].shape == (3, 3)
        for mode in ("none", "lqr"):
            t, X = z[f"{mode}_t"], z[f"{mode}_X"]
            nodes = t[:: flight.samples]
            start, end = z[f"{mode}_command_start"].T, z[f"{mode}_command_end"].T
            truth = type("Truth", (), {"mass": body.mass, "mu": body.mu, "markers": body.markers})
            x, v, R, Om = reflight(truth, z["X0"], nodes, start, end, z["inertia"], float(z["force_scale"]),
                                   float(z["moment_scale"]), z["force_misalignment"], z["moment_misalignment"],
                                   gravity(body.mu, g["J2"], g["radius"]))
            rec = X[:: flight.samples]
            Rrec = rec[:, 6:15].reshape(-1, 3, 3).transpose(0, 2, 1)
            Omrec = np.linalg.solve(z["inertia"], rec[:, 15:18].T).T
            diff = max(np.abs(rec[:, :3] - x).max() / np.abs(x).max(),
                       np.abs(rec[:, 3:6] / body.mass - v).max() / np.abs(v).max(),
                       np.abs(Rrec - R).max(), np.abs(Omrec - Om).max() / np.abs(Om).max())
            print(f"run {i} {mode}: re-flight vs recorded truth {diff:.2e}")
            assert diff <= 1e-8, (i, mode, diff)


# ------------------------------------------------------------------------------------ figures of merit
def test_figures_of_merit_against_independent_arithmetic(e3_plan):
    """Without errors the open-loop flight is the plan's continuous flight (the misses are its discretization
    error, LQR removes most of it); with a pure thrust scale s the open-loop delta-v is (1 + s) that of the plan."""
    man, sol = e3_plan
    res = run_flights(man, sol, parse_flight({"runs": 1}), executor=SerialExecutor())
    none, lqr = res.rows
    check = continuous_check(sol)
    assert none["position_miss"] == pytest.approx(check.terminal_position, rel=1e-9)
    assert none["attitude_miss_deg"] == pytest.approx(np.degrees(check.terminal_attitude), rel=1e-6)
    assert abs(none["delta_v_overhead"]) <= 1e-12 and none["saturated_fraction"] == 0.0
    assert lqr["position_miss"] <= 0.1 * none["position_miss"]
    res = run_flights(man, sol, parse_flight({"runs": 2, "errors": {"force_scale": 0.03}, "feedback": "none"}),
                      executor=SerialExecutor())
    for r in res.rows:
        assert r["delta_v"] / res.plan["delta_v"] == pytest.approx(r["force_scale"], rel=1e-9)
        assert r["delta_v_commanded_overhead"] == pytest.approx(0.0, abs=1e-12)
    rtn = np.array([[r["miss_r"], r["miss_t"], r["miss_n"]] for r in res.rows])
    assert np.allclose(np.linalg.norm(rtn, axis=1), [r["position_miss"] for r in res.rows], rtol=1e-12)
    assert res.plan["miss_frame"] == "RTN"


# ------------------------------------------------------------------------------------ closed loop
def test_the_tracker_on_the_continuous_truth(e3_plan):
    """E3 (LGVI, N = 50: bandwidth 0.3/h = 30) under J2, thrust errors and dispersions, 4 runs: position miss
    6.5e-3 .. 3.4e-2 open loop, 2.7e-5 .. 4.4e-5 LQR (p95 ratio 1.3e-3; at N = 100, bandwidth 60: 1.7e-6 ..
    2.9e-6); delta-v overhead at most 0.1 % (the thrust scale is corrected).  Asserted: p95 ratio <= 1e-2 (the
    issue's criterion), overhead <= 5 %."""
    man, sol = e3_plan
    res = run_flights(man, sol, parse_flight(E3_FLIGHT), executor=SerialExecutor())
    st = res.statistics()
    assert res.summary()["closed_over_open"]["position_miss_p95"] <= 1e-2
    assert st["lqr"]["delta_v_overhead"]["max"] <= 0.05 and st["none"]["position_miss"]["p95"] >= 1e-2
    assert res.summary()["worse_than_open"] == [] and not any(r.startswith("warning") for r in fly_table(res))


def test_a_closed_loop_worse_than_open_loop_is_said():
    """Issue 43: a feedback that ends farther from the plan than open loop (p95 ratio > 1) is said -- in summary.json's
    ``worse_than_open``, the command's table and the report -- naming each worse miss with its ratio; ratios <= 1 or
    undefined are not."""
    summary = {"closed_over_open": {"position_miss_p95": 9.6, "velocity_miss_p95": 0.5, "attitude_miss_deg_p95": None,
                                    "rate_miss_p95": 1.0},
               "mpc_over_open": {"position_miss_p95": 1.25, "velocity_miss_p95": 2.0}}
    lqr, mpc = worse_than_open(summary)
    assert lqr.startswith("LQR ends farther") and "position_miss x9.6" in lqr and "velocity" not in lqr
    assert "rate" not in lqr and "attitude" not in lqr
    assert "position_miss x1.25" in mpc and "velocity_miss x2" in mpc
    assert worse_than_open({"closed_over_open": {"position_miss_p95": 0.3}}) == [] and worse_than_open({}) == []


def test_the_slew_with_a_bound_margin_meets_the_targets_on_the_continuous_truth():
    """The time-optimal slew planned with bounds_margin 0.1 (N = 200), truth with 2 % torque and 1 % inertia
    errors (1-sigma), 4 runs: LQR at most 0.01 deg and 1e-4 rad/s (measured p95 over 20 runs: 3.3e-3 deg,
    3.2e-5 rad/s), open loop degrees off."""
    man = maneuver("slew_time_optimal", None, None, "control.bounds_margin=0.1")
    res = fly(man, {"errors": {"moment_scale": 0.02, "inertia_scale": 0.01}, "runs": 4, "seed": 2})
    st = res.statistics()
    assert st["lqr"]["attitude_miss_deg"]["max"] <= 0.01 and st["lqr"]["rate_miss"]["max"] <= 1e-4
    assert st["none"]["attitude_miss_deg"]["max"] >= 1.0
    assert res.plan["bounds_margin"] == 0.1 and res.plan["miss_frame"] == "inertial"


# ------------------------------------------------------------------------------------ the command
def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", *map(str, args)], cwd=cwd or ROOT,
                          capture_output=True, text=True, timeout=600)


def test_cli_fly_writes_every_file(tmp_path):
    f = tmp_path / "flight.yaml"
    f.write_text(json.dumps({"flight": {**E3_FLIGHT, "runs": 3}}))
    out = tmp_path / "o"
    rc = main(["fly", str(config("e3")), "--set", "horizon.N=40", "--set", "discretization=lgvi", "--flight", str(f),
               "--workers", "1", "--save-runs", "1", "--out", str(out), "--quiet"])
    assert rc == 0
    for name in ("flights.csv", "summary.json", "flight.resolved.yaml", "config.resolved.yaml", "plan.npz",
                 "gains.npz", "runs/0000.npz", "report.html", "flight_miss.png", "flight_histograms.png", "flight_tracks.png",
                 "flight_controls.png"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "runs" / "0001.npz").exists()
    rows = list(csv.DictReader((out / "flights.csv").open()))
    assert [(r["run"], r["feedback"], r["status"]) for r in rows] == [(str(i), m, "ok") for i in range(3)
                                                                       for m in ("none", "lqr")]
    s = json.loads((out / "summary.json").read_text())
    assert set(s["statistics"]) == {"none", "lqr"} and s["finished_runs"] == 3 and s["interrupted"] is False
    assert set(s["statistics"]["lqr"]["position_miss"]) == {"mean", "p50", "p95", "p99_7", "max", "n"}
    assert np.load(out / "gains.npz")["K"].shape == (40, 6, 12)
    # report.html: the flight section, self-contained, the same page when `se3ocp report` redraws it
    html = (out / "report.html").read_text()
    for part in ('id="flight-summary"', 'id="flight-ratios"', "open loop", "LQR", "terminal position miss",
                 'id="fig-flight_miss"', 'id="fig-flight_controls"', "3 of 3 runs", 'id="flight"'):
        assert part in html, part
    assert html.count("data:image/png;base64,") == 4 and "http" not in html.replace("http-equiv", "")
    p95 = s["statistics"]["lqr"]["position_miss"]["p95"]
    assert f"{p95:.3e}" in html
    (out / "report.html").unlink()
    assert main(["report", str(out), "--quiet"]) == 0
    again = (out / "report.html").read_text()
    assert again.split("<footer>")[0] == html.split("<footer>")[0]


def test_cli_fly_a_results_directory_and_bad_input(tmp_path):
    res = tmp_path / "plan"
    assert main(["solve", str(config("slew_time_optimal")), "--set", "horizon.N=40", "--set",
                 "control.bounds_margin=0.1", "--out", str(res), "--quiet", "--no-figures"]) == 0
    out = tmp_path / "o"
    assert main(["fly", str(res), "--runs", "2", "--feedback", "lqr", "--workers", "1", "--no-figures",
                 "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert list(s["statistics"]) == ["lqr"] and s["plan"]["bounds_margin"] == 0.1 and s["runs"] == 2
    r = run_cli("fly", res, "--set", "horizon.N=10", "--out", tmp_path / "bad")
    assert r.returncode == 2 and "--set" in r.stderr and not (tmp_path / "bad").exists()
    r = run_cli("fly", config("e1"), "--out", tmp_path / "bad")
    assert r.returncode == 2 and "control.kind: only smooth-control plans are flown" in r.stderr
    assert not (tmp_path / "bad").exists() and "Traceback" not in r.stderr
    r = run_cli("fly", config("e3"), "--set", "horizon.N=30", "--set", "solver.direct.max_iter=2",
                "--out", tmp_path / "bad")
    assert r.returncode == 1 and "did not converge" in r.stderr and not (tmp_path / "bad").exists()


def test_cli_ctrl_c_keeps_the_finished_runs(tmp_path):
    """SIGINT after the first finished task of a pool flight: exit 130, the finished runs written, INCOMPLETE."""
    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "se3ocp.problems.cli", "fly", str(config("e3")), "--set", "horizon.N=60",
                          "--set", "discretization=lgvi", "--runs", "400", "--workers", "2", "--out", str(out)],
                         cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = p.stderr.readline()
        assert " runs, " in first and "ETA" in first, first
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
    finally:
        p.kill()
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    rows = list(csv.DictReader((out / "flights.csv").open()))
    assert 1 <= len({r["run"] for r in rows}) < 400
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True
    assert (out / "INCOMPLETE").read_text().startswith("interrupted")
