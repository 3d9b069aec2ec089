"""End-to-end checks of the se3ocp command: files, fields, exit codes, no tracebacks."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_simulate_writes_results(tmp_path):
    out = tmp_path / "sim"
    r = run("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=2000", "--set", "horizon.T=2.0", "--out", out)
    assert r.returncode == 0, r.stderr
    with np.load(out / "trajectory.npz") as z:
        assert set(z.files) == {"t", "x", "gamma", "Pi", "R"}
        assert z["t"].shape == (2001,) and z["R"].shape == (2001, 3, 3) and z["x"].shape == (2001, 3)
        assert abs(z["t"][-1] - 2.0) <= 1e-12
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is True and s["N"] == 2000
    assert s["max_orthogonality_error"] <= 1e-12 and s["max_determinant_error"] <= 1e-12
    assert (out / "config.resolved.yaml").exists()
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporaries


def test_results_dir_not_mixed(tmp_path):
    out = tmp_path / "sim"
    args = ("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=100", "--set", "horizon.T=0.1", "--out", out)
    assert run(*args).returncode == 0
    r = run(*args)
    assert r.returncode == 2 and "--force" in r.stderr and "Traceback" not in r.stderr
    assert run(*args, "--force").returncode == 0


def test_default_out_gets_fresh_sibling(tmp_path):
    args = ("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=50", "--set", "horizon.T=0.05", "--quiet")
    assert run(*args, cwd=tmp_path).returncode == 0
    assert run(*args, cwd=tmp_path).returncode == 0
    assert (tmp_path / "results" / "free_tumble" / "summary.json").exists()
    assert (tmp_path / "results" / "free_tumble.1" / "summary.json").exists()


def test_cayley_failure_is_reported(tmp_path):
    """A rotation per step too large: exit 1, flagged, with advice to reduce h."""
    r = run("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=10", "--set", "horizon.T=10",
            "--set", "initial.angular_velocity=[300, 0, 0]", "--out", tmp_path / "o", "--json")
    assert r.returncode == 1, r.stdout + r.stderr
    s = json.loads(r.stdout)
    assert s["converged"] is False and s["status"] == "cayley_not_converged" and "smaller step" in s["message"]
    assert (tmp_path / "o" / "trajectory.npz").exists()


def test_bad_config_exit_2_one_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text((CONFIGS / "free_tumble.yaml").read_text().replace("N: 10000", "N: -3"))
    r = run("validate", p)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(p) in lines[0] and "horizon.N" in lines[0], r.stderr
    r = run("simulate", p, "--set", "horizon.N=oops", "--out", tmp_path / "x")
    assert r.returncode == 2 and "horizon.N" in r.stderr and "Traceback" not in r.stderr


def test_validate_json(tmp_path):
    r = run("validate", CONFIGS / "e3_inclination_change.yaml", "--json")
    assert r.returncode == 0
    s = json.loads(r.stdout)
    assert s["valid"] is True and s["N"] == 500 and s["control"] == "smooth"
