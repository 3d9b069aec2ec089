"""End to end: `se3ocp solve`, `compare` and `plot` on small N — files, fields, exit codes."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
FIGS = ("maneuver", "velocity", "angular_velocity", "force", "moment", "convergence")
METHOD_KEYS = {"status", "converged", "cost", "terminal_error", "max_orthogonality_error", "iterations", "build_s",
               "solve_s", "N", "h", "discretization", "solver", "message", "history"}


def se3ocp(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", *map(str, args)], cwd=cwd, capture_output=True,
                          text=True, timeout=900)


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp") / "e3"
    r = se3ocp("compare", CONFIGS / "e3_inclination_change.yaml", "--set", "horizon.N=60", "--out", out, "--animate")
    return out, r


def test_compare_writes_everything(compared):
    out, r = compared
    assert r.returncode == 0, r.stderr
    for f in ("summary.json", "config.resolved.yaml", "direct.npz", "indirect.npz", "maneuver.gif"):
        assert (out / f).is_file(), f
    for fig in FIGS:
        for ext in ("png", "pdf"):
            assert (out / f"fig_{fig}.{ext}").stat().st_size > 1000, (fig, ext)
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is True and set(s["methods"]) == {"direct", "indirect"}
    for m in ("direct", "indirect"):
        assert METHOD_KEYS <= set(s["methods"][m]), METHOD_KEYS - set(s["methods"][m])
        assert s["methods"][m]["N"] == 60 and s["methods"][m]["terminal_error"] <= 1e-10
        assert s["methods"][m]["max_orthogonality_error"] <= 1e-12
    # the two methods solve the same discretization: same optimum (SPEC §6), stated in the summary
    assert s["comparison"]["same_extremal"] is True and s["comparison"]["cost_relative_difference"] <= 1e-8
    assert "agree" in s["comparison"]["verdict"]
    # the table is printed
    assert "direct" in r.stdout and "indirect" in r.stdout and "agree: same extremal" in r.stdout


def test_npz_contents(compared):
    out, _ = compared
    with np.load(out / "direct.npz") as z:
        assert {"t", "x", "gamma", "Pi", "R", "u_f", "u_m", "lam"} <= set(z.files)
        assert z["R"].shape == (61, 3, 3) and z["u_f"].shape == (60, 3) and z["lam"].shape == (60, 12)
    with np.load(out / "indirect.npz") as z:
        assert {"t", "x", "gamma", "Pi", "R", "u_f", "u_m", "lam"} <= set(z.files)
    cfg = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert cfg["horizon"]["N"] == 60 and cfg["solver"]["direct"]["solver"] == "ipopt"


def test_plot_redraws(compared, tmp_path):
    out, _ = compared
    (out / "fig_force.png").unlink()
    r = se3ocp("plot", out, "--json")
    assert r.returncode == 0, r.stderr
    assert str(out / "fig_force.png") in json.loads(r.stdout.strip().splitlines()[-1])
    assert (out / "fig_force.png").is_file()
    r = se3ocp("plot", tmp_path)
    assert r.returncode == 2 and "not a results directory" in r.stderr


def test_solve_impulsive_and_json(tmp_path):
    r = se3ocp("solve", CONFIGS / "e1_impulsive_tpbvp.yaml", "--set", "horizon.N=80", "--out", tmp_path / "e1",
               "--json", "--no-figures")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["converged"] is True and s["methods"]["direct"]["terminal_error"] <= 1e-12
    with np.load(tmp_path / "e1" / "direct.npz") as z:
        assert {"dgamma0", "dPi0", "dgammaN", "dPiN"} <= set(z.files)
    r = se3ocp("solve", CONFIGS / "e1_impulsive_tpbvp.yaml", "--method", "indirect", "--out", tmp_path / "x")
    assert r.returncode == 2 and "control.kind" in r.stderr


def test_not_converged_exit_1_results_flagged(tmp_path):
    r = se3ocp("solve", CONFIGS / "e4_orbital_capture.yaml", "--set", "horizon.N=40", "--set", "solver.direct.max_iter=2",
               "--out", tmp_path / "o", "--no-figures", "--json")
    assert r.returncode == 1
    s = json.loads(r.stdout)
    assert s["converged"] is False and s["methods"]["direct"]["status"] == "Maximum_Iterations_Exceeded"
    assert (tmp_path / "o" / "direct.npz").is_file()


def test_compare_reports_different_extremals():
    """Two converged solutions with different costs are flagged, the lower one named (issue 4)."""
    import dataclasses

    from se3ocp.problems.cli import compare_solutions
    from se3ocp.transcription.results import Solution, Trajectory

    base = Solution(method="direct", solver="ipopt", discretization="first_order", N=2, h=0.1,
                    trajectory=Trajectory(t=np.zeros(3), X=np.zeros((3, 18))), status="Solve_Succeeded",
                    message="", converged=True, cost=9.47, terminal_error=1e-14, iterations=7, build_s=0.0,
                    solve_s=0.0, controls=np.ones((6, 2)))
    other = dataclasses.replace(base, method="indirect", cost=3.2 * 9.47, controls=-np.ones((6, 2)))
    c = compare_solutions(base, other)
    assert c["same_extremal"] is False and c["verdict"].startswith("MISMATCH")
    assert "direct cost 9.47" in c["verdict"] and "ratio 3.2" in c["verdict"]
    assert c["control_max_difference_relative"] == 2.0
    same = compare_solutions(base, dataclasses.replace(other, cost=9.47 * (1 + 1e-9), controls=base.controls))
    assert same["same_extremal"] is True and same["verdict"].startswith("agree")
    failed = compare_solutions(base, dataclasses.replace(other, converged=False))
    assert failed["same_extremal"] is False and failed["verdict"].startswith("not comparable")
