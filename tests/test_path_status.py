"""Path constraints between the nodes decide the status (issue 42): the continuous flight's margins, judged against
``solver.constraints_tolerance`` (default transcription.results.check.PATH_MARGIN_TOL, 1e-5 rad = 5.7e-4 deg for a
cone), are said on the status line (the message), in the CLI table, and refined on alone.

The bundled keep-out slew (configs/slew_keep_out.yaml) and its N = 20 variant (``--set horizon.N=20``).  Every
violation is measured again here, independently of the package's flight engine and constraint code: the plan's
controls flown by scipy's DOP853 (test_path_refinement.dense_flight: unit quaternion, NumPy right-hand side) at
DENSE samples per node interval, and the cone angle arccos((R e1) . s / |s|) formed here.
"""
from __future__ import annotations

import time

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.cli.progress import table
from se3ocp.transcription.results.check import PATH_MARGIN_TOL, ContinuousCheck, margin_kind, path_tolerances

from support import maneuver
from test_path_refinement import SOURCE, dense_flight

#: samples per node interval of the independent flight (the package's check flies 4)
DENSE = 32
#: the issue's acceptance: a continuous margin >= -1e-3 deg, or a status that says it is not
ACCEPT_DEG = 1e-3


def independent_margin_deg(sol) -> float:
    """min over the DOP853 flight of angle(R e1, s) - 20 deg (deg): the keep-out cone's margin between the nodes."""
    _, R, _ = dense_flight(sol, DENSE)
    c = R[:, :, 0] @ (SOURCE / np.linalg.norm(SOURCE))
    return float(np.min(np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))) - 20.0)


def note_value_deg(message: str) -> float:
    """The violation the path note names: 'keep_out by 0.137 deg' -> 0.137."""
    return float(message.split("keep_out by ")[1].split(" deg")[0])


@pytest.fixture(scope="module")
def plain():
    """The keep-out slew as bundled (N = 100) and at N = 20, solved with the defaults."""
    return {N: se3ocp.solve(maneuver("slew_keep_out", N)) for N in (100, 20)}


@pytest.mark.parametrize("N", [100, 20])
def test_by_default_a_plan_that_leaves_its_cone_between_the_nodes_says_so(plain, N):
    """Default solve: the plan converges (nodes within the cone to 1e-9 deg) but its flight leaves the cone by more
    than the issue's 1e-3 deg (independently: 5.7e-3 deg at N = 100, 0.137 deg at N = 20), so the message names
    keep_out, the violation in deg (the independent one to 3 %: the package samples 4 points per node interval, 32
    here; at N = 20 its minimum is 2.0 % short of the dense one) and the cure; the CLI table lists the flown margin
    and a warning line with the same number; summary.json keeps the tolerance."""
    sol = plain[N]
    margin = independent_margin_deg(sol)
    print(f"N = {N}: independent continuous margin {margin:.4g} deg, node margin "
          f"{sol.summary()['min_margin_keep_out']:.2e} deg; message: {sol.message}")
    assert sol.converged and sol.summary()["min_margin_keep_out"] > -1e-9
    assert margin < -ACCEPT_DEG                      # the first branch of the acceptance fails: the status must say
    assert "the path leaves its constraints between the nodes: keep_out by" in sol.message
    assert "solver.constraints_tolerance" in sol.message and "solver.accuracy" in sol.message
    assert note_value_deg(sol.message) == pytest.approx(-margin, rel=0.03)
    lines = table([sol])
    warn = [ln for ln in lines if ln.startswith("warning: direct's path leaves its constraints")]
    assert len(warn) == 1 and f"keep_out by {-sol.continuous.min_margins['min_margin_keep_out']:.3g} deg" in warn[0]
    assert "set solver.constraints_tolerance" in warn[0], lines
    assert any(f"keep_out {sol.continuous.min_margins['min_margin_keep_out']:.3g} deg (allowed down to -0.000573 deg)"
               in ln for ln in lines), lines
    assert sol.summary()["continuous_tolerance_min_margin_keep_out"] == pytest.approx(np.degrees(PATH_MARGIN_TOL),
                                                                                      rel=1e-12)


def test_a_plan_within_its_constraints_tolerance_is_not_warned_and_not_refined():
    """constraints_tolerance 1e-3 rad (0.057 deg) at N = 100, where the flight leaves the cone by 5.7e-3 deg: one
    level, no path note, no warning line, the margin line with the tolerance in deg."""
    sol = se3ocp.solve(maneuver("slew_keep_out"), constraints_tolerance=1e-3)
    assert sol.converged and len(sol.mesh) == 1 and sol.stats["accuracy_met"] is True, sol.message
    assert "leaves its constraints" not in sol.message
    lines = table([sol])
    assert not any(ln.startswith("warning") for ln in lines)
    assert any(f"(allowed down to {-np.degrees(1e-3):.3g} deg)" in ln for ln in lines), lines


@pytest.mark.parametrize("N", [100, 20])
def test_constraints_tolerance_alone_refines_the_mesh_until_the_flight_holds(N):
    """solver.constraints_tolerance 1e-5 rad alone: the mesh refined on the path violation (not the terminal miss,
    which stays above 1e-5: not refined) until the flight stays within 1e-5 rad of the cone -- checked by the
    independent DOP853 flight (margin >= -1e-5 rad = -5.73e-4 deg, and the package's check agrees with it to 3 %);
    no path note in the message.  Measured: N = 100 -> 275 (margin -4.04e-4 deg), N = 20 -> 294 (-5.37e-4 deg),
    about 1 s each with the dense flight."""
    t0 = time.perf_counter()
    sol = se3ocp.solve(maneuver("slew_keep_out", N), constraints_tolerance=1e-5)
    wall = time.perf_counter() - t0
    margin = independent_margin_deg(sol)
    levels = [r["N"] for r in sol.mesh]
    print(f"N = {N}: levels {levels}, path violations {[r['path_violation'] for r in sol.mesh]}, independent margin "
          f"{margin:.4g} deg, solve {wall:.1f} s")
    assert sol.converged and sol.stats["accuracy_met"] is True, sol.message
    assert levels[0] == N and len(levels) >= 2 and sol.mesh[0]["path_violation"] > 1e-5
    assert margin >= -np.degrees(1e-5) and margin < 0.0
    assert margin == pytest.approx(sol.continuous.min_margins["min_margin_keep_out"], rel=0.03)
    assert sol.mesh[-1]["miss"] > 1e-5 and "refined to constraints tolerance 1e-05" in sol.message
    assert "leaves its constraints" not in sol.message


def test_the_tolerance_in_each_margins_own_unit_and_read_back(plain):
    """path_tolerances: tol * 180 / pi deg for a cone, tol * L (the orbit radius |x_0|) for a radius, tol for a rate;
    margin keys of repeated kinds; a check read back from its summary and arrays judges the same."""
    cone = path_tolerances(maneuver("slew_keep_out").problem, 2e-5)
    assert cone == {"min_margin_keep_out": pytest.approx(2e-5 * 180 / np.pi, rel=1e-14)}
    prob = maneuver("e3_min_radius").problem
    L = float(np.linalg.norm(prob.X0[0:3]))
    assert path_tolerances(prob) == {"min_margin_min_radius": pytest.approx(PATH_MARGIN_TOL * L, rel=1e-14)}
    assert [margin_kind(k) for k in ("min_margin_keep_out", "min_margin_keep_out_2", "min_margin_max_angular_rate")] \
        == ["keep_out", "keep_out", "max_angular_rate"]
    sol = plain[20]
    back = ContinuousCheck.from_record(sol.summary(), sol.continuous.arrays())
    assert back.path_violations() == sol.continuous.path_violations() and back.path_note() == sol.continuous.path_note()


@pytest.mark.parametrize("value, said", [(-1, "expected a number > 0, got -1"), ("abc", "expected a number")])
def test_a_bad_constraints_tolerance_is_one_line_exit_2(value, said):
    import subprocess
    import sys

    from test_cli import CONFIGS, ROOT

    r = subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", "validate", str(CONFIGS / "slew_keep_out.yaml"),
                        "--set", f"solver.constraints_tolerance={value}"], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and r.stdout == "" and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "solver.constraints_tolerance" in r.stderr and said in r.stderr
