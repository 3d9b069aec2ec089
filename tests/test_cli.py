"""The se3ocp command end to end (problems/cli/): validate, simulate, solve, compare, plot -- files,
fields, exit codes, no tracebacks (small N)."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from se3ocp.transcription.outcome import Result

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_simulate_writes_results(tmp_path):
    out = tmp_path / "sim"
    r = run("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=2000", "--set", "horizon.T=2.0", "--out", out)
    assert r.returncode == 0, r.stderr
    for fig in ("maneuver", "attitude", "attitude_error", "orbital_elements", "angular_velocity"):
        assert (out / f"fig_{fig}.png").stat().st_size > 1000, fig       # simulate draws figures too
    assert not (out / "fig_force.png").exists()                          # free motion: no controls
    assert "fig-attitude" in (out / "report.html").read_text()
    with np.load(out / "trajectory.npz") as z:
        assert set(z.files) == {"t", "x", "v", "gamma", "Omega", "Pi", "R"}
        assert z["t"].shape == (2001,) and z["R"].shape == (2001, 3, 3) and z["x"].shape == (2001, 3)
        assert abs(z["t"][-1] - 2.0) <= 1e-12
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is True and s["N"] == 2000
    assert s["max_orthogonality_error"] <= 1e-12 and s["max_determinant_error"] <= 1e-12
    assert (out / "config.resolved.yaml").exists()
    assert not list(out.glob(".*.tmp"))  # atomic writes leave no temporaries


def test_results_dir_not_mixed(tmp_path):
    out = tmp_path / "sim"
    args = ("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=100", "--set", "horizon.T=0.1", "--out", out,
            "--no-figures")
    assert run(*args).returncode == 0
    before = {f.name: f.stat().st_mtime_ns for f in out.iterdir()}
    r = run(*args)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == (f"se3ocp: error: {out}: results directory already holds files; pass --force to overwrite, "
                        f"or choose another --out\n")
    assert {f.name: f.stat().st_mtime_ns for f in out.iterdir()} == before     # the earlier run untouched
    assert run(*args, "--force").returncode == 0


def test_default_out_gets_fresh_sibling(tmp_path):
    args = ("simulate", CONFIGS / "free_tumble.yaml", "--set", "horizon.N=50", "--set", "horizon.T=0.05", "--quiet",
            "--no-figures")
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
    assert s["converged"] is False and s["status"] == "cayley_failed" and "smaller step" in s["message"]
    assert (tmp_path / "o" / "trajectory.npz").exists()


def test_bad_config_exit_2_one_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text((CONFIGS / "free_tumble.yaml").read_text().replace("N: 10000", "N: -3"))
    r = run("validate", p)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(p) in lines[0] and "horizon.N" in lines[0], r.stderr
    r = run("simulate", p, "--set", "horizon.N=oops", "--out", tmp_path / "x")
    assert r.returncode == 2 and r.stderr == "se3ocp: error: --set: horizon.N: expected an integer, got the string 'oops'\n"
    assert not (tmp_path / "x").exists()


def test_validate_json(tmp_path):
    r = run("validate", CONFIGS / "e3_inclination_change.yaml", "--json")
    assert r.returncode == 0
    s = json.loads(r.stdout)
    assert s["valid"] is True and s["N"] == 500 and s["control"] == "smooth"


FIGS = ("maneuver", "attitude", "attitude_error", "control_norms", "force", "moment", "thrust_rtn", "orbital_elements",
        "velocity", "angular_velocity", "costates", "convergence", "continuous")
METHOD_KEYS = {"status", "converged", "cost", "terminal_error", "max_orthogonality_error", "iterations", "build_s",
               "solve_s", "N", "h", "discretization", "solver", "message", "history"}


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("cmp") / "e3"
    r = run("compare", CONFIGS / "e3_inclination_change.yaml", "--set", "horizon.N=60", "--out", out, "--animate",
            "--frames", "12", "--fps", "10")
    return out, r


def test_compare_writes_everything(compared):
    out, r = compared
    assert r.returncode == 0, r.stderr
    for f in ("summary.json", "config.resolved.yaml", "direct.npz", "indirect.npz", "maneuver.gif", "report.html"):
        assert (out / f).is_file(), f
    from PIL import Image

    with Image.open(out / "maneuver.gif") as im:
        assert im.n_frames == 12 and im.info["duration"] == 100          # --frames 12 --fps 10
    assert (out / "report.html").read_text().count("data:image/png;base64,") == len(FIGS)
    for fig in FIGS:
        for ext in ("png", "pdf"):
            assert (out / f"fig_{fig}.{ext}").stat().st_size > 1000, (fig, ext)
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is True and set(s["methods"]) == {"direct", "indirect"}
    for m in ("direct", "indirect"):
        assert METHOD_KEYS <= set(s["methods"][m]), METHOD_KEYS - set(s["methods"][m])
        assert s["methods"][m]["N"] == 60 and s["methods"][m]["terminal_error"] <= 1e-10
        assert s["methods"][m]["max_orthogonality_error"] <= 1e-12
        assert s["methods"][m]["delta_v"] > 0 and s["methods"][m]["peak_moment"] > 0   # figures of merit
    # the two methods solve the same discretization: same optimum (docs/mathematics.md §6), stated in the summary
    assert s["comparison"]["same_extremal"] is True and s["comparison"]["cost_relative_difference"] <= 1e-8
    assert "agree" in s["comparison"]["verdict"]
    # the table is printed
    assert "direct" in r.stdout and "indirect" in r.stdout and "agree: same extremal" in r.stdout


def test_npz_contents(compared):
    out, _ = compared
    with np.load(out / "direct.npz") as z:
        assert {"t", "x", "v", "gamma", "Omega", "Pi", "R", "u_f", "u_m", "t_u", "lam"} <= set(z.files)
        assert z["R"].shape == (61, 3, 3) and z["u_f"].shape == (60, 3) and z["lam"].shape == (60, 12)
        np.testing.assert_array_equal(z["t_u"], z["t"][1:])                 # first order: u_1..u_N at t_1..t_N
    with np.load(out / "indirect.npz") as z:
        assert {"t", "x", "gamma", "Pi", "R", "u_f", "u_m", "lam"} <= set(z.files)
    cfg = yaml.safe_load((out / "config.resolved.yaml").read_text())
    assert cfg["horizon"]["N"] == 60 and cfg["solver"]["direct"]["solver"] == "ipopt"


@pytest.mark.slow
def test_plot_redraws(compared, tmp_path):
    out, _ = compared
    (out / "fig_force.png").unlink()
    r = run("plot", out, "--json")
    assert r.returncode == 0, r.stderr
    written = json.loads(r.stdout.strip().splitlines()[-1])
    assert str(out / "fig_force.png") in written and str(out / "fig_maneuver.png") in written   # every figure
    assert str(out / "report.html") in written and (out / "fig_force.png").is_file()
    for command in ("plot", "report"):
        r = run(command, tmp_path)
        assert r.returncode == 2 and r.stderr == (f"se3ocp: error: {tmp_path}: not a results directory (needs "
                                                  f"summary.json and config.resolved.yaml)\n"), command
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_plot_animate_draws_only_stale_figures(compared):
    """`plot --animate` writes the animation and leaves up-to-date figures alone."""
    out, _ = compared
    (out / "fig_moment.png").unlink()
    before = (out / "fig_maneuver.png").stat().st_mtime_ns
    r = run("plot", out, "--animate", "--frames", "4", "--json")
    assert r.returncode == 0, r.stderr
    written = json.loads(r.stdout.strip().splitlines()[-1])
    assert set(written) == {str(out / p) for p in ("fig_moment.png", "fig_moment.pdf", "report.html", "maneuver.gif")}
    assert (out / "fig_maneuver.png").stat().st_mtime_ns == before
    r = run("plot", out, "--animate", "--frames", "3", "--json")
    assert json.loads(r.stdout.strip().splitlines()[-1]) == [str(out / "maneuver.gif")]     # nothing stale
    assert run("plot", out, "--animate", "--frames", "1").returncode == 2                  # at least 2 frames


def test_report_command(compared):
    out, _ = compared
    (out / "report.html").unlink()
    r = run("report", out, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == [str(out / "report.html")]
    text = (out / "report.html").read_text()
    assert "agree: same extremal" in text and text.count("data:image/png;base64,") == len(FIGS)


def test_solve_impulsive_and_json(tmp_path):
    r = run("solve", CONFIGS / "e1_impulsive_tpbvp.yaml", "--set", "horizon.N=80", "--out", tmp_path / "e1",
               "--json", "--no-figures")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["converged"] is True and s["methods"]["direct"]["terminal_error"] <= 1e-12
    with np.load(tmp_path / "e1" / "direct.npz") as z:
        assert {"dgamma0", "dPi0", "dgammaN", "dPiN"} <= set(z.files)
    r = run("solve", CONFIGS / "e1_impulsive_tpbvp.yaml", "--method", "indirect", "--out", tmp_path / "x")
    assert r.returncode == 2 and r.stderr == (f"se3ocp: error: {CONFIGS / 'e1_impulsive_tpbvp.yaml'}: control.kind: the "
                                              f"indirect method applies to smooth maneuvers; impulsive maneuvers are "
                                              f"solved by the direct method\n")   # transcription.solve.not_covered
    assert not (tmp_path / "x").exists()


def test_not_converged_exit_1_results_flagged(tmp_path):
    r = run("solve", CONFIGS / "e4_orbital_capture.yaml", "--set", "horizon.N=40", "--set", "solver.direct.max_iter=2",
               "--out", tmp_path / "o", "--no-figures", "--json")
    assert r.returncode == 1
    s = json.loads(r.stdout)
    assert s["converged"] is False and s["methods"]["direct"]["status"] == "max_iterations"
    assert s["methods"]["direct"]["solver_status"] == "Maximum_Iterations_Exceeded"
    assert (tmp_path / "o" / "direct.npz").is_file()


@pytest.mark.parametrize("figures", [False, True])
def test_a_method_that_does_not_apply_alone_is_a_status_not_a_crash(tmp_path, figures):
    """``--method indirect`` on a maneuver with a path constraint (the indirect method does not cover it): exit 1,
    the status not_applicable and why, report.html and summary.json written, no figure and no traceback (the
    report and the figures once took the problem from the first Solution, and there is none)."""
    r = run("solve", CONFIGS / "e3_min_radius.yaml", "--method", "indirect", "--out", tmp_path / "o",
            *(() if figures else ("--no-figures",)))
    assert r.returncode == 1, r.stderr
    assert "internal error" not in r.stderr and "Traceback" not in r.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["methods"]["indirect"]["status"] == "not_applicable" and "path constraints" in r.stdout
    assert (tmp_path / "o" / "report.html").is_file() and not list((tmp_path / "o").glob("fig_*"))
    if figures:
        return
    # read back: report renders it again (the status and why), plot and export say there is no plan (exit 2)
    written = (tmp_path / "o" / "report.html").read_text()
    (tmp_path / "o" / "report.html").unlink()
    r = run("report", tmp_path / "o")
    assert r.returncode == 0 and not r.stderr, r.stderr
    again = (tmp_path / "o" / "report.html").read_text()
    assert "indirect: not applicable" in again and "does not cover path constraints" in again
    stamp = re.compile(r"\d{4}-\d\d-\d\d \d\d:\d\d \w+")                     # the time it was generated
    assert stamp.sub("", again) == stamp.sub("", written)
    for cmd in (("plot",), ("export", "--format", "oem")):
        r = run(*cmd, tmp_path / "o")
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
        assert "the run holds no plan (no method applies: indirect: the indirect method does not cover" in r.stderr
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["config.resolved.yaml", "report.html",
                                                                 "summary.json"]


def test_the_fuel_of_an_engine_with_wheels_is_cautioned_before_solving(tmp_path):
    """``solve`` says before solving, in one warning line, that the fuel of an engine with a torque of any direction
    converges slowly if at all and names three wheels (a box of the norm bound's limit) and objective=propellant (the
    objective's caution); the failure's hint puts that tip first.  A fuel file without an engine, the bundled
    engine file with its three wheels (counted on channels) and leo_body_engine with its torque unbounded (reached
    through channels, docs §25) get no such line."""
    r = run("solve", CONFIGS / "leo_engine_fuel.yaml", "--set", "horizon.N=10", "--set", "solver.direct.max_iter=3",
            "--set", "control.bounds.moment={norm: 1.0e-8}", "--out", tmp_path / "o", "--no-figures")
    assert r.returncode == 1, r.stderr
    lines = r.stdout.splitlines()
    assert lines[1].startswith("warning: the fuel of an engine with a torque of any direction (its 2-norm) converges "
                               "slowly if at all"), lines[:3]
    assert "consider control.bounds.moment={box: [1e-08, 1e-08, 1e-08]}" in lines[1], lines[1]
    assert "or control.objective=propellant" in lines[1] and lines[2] == "solving by the direct method ..."
    assert "try control.bounds.moment={box: [1e-08, 1e-08, 1e-08]}" in json.loads(
        (tmp_path / "o" / "summary.json").read_text())["methods"]["direct"]["message"]
    for name, sets in (("orbit_raise_fuel", []), ("leo_engine_fuel", []),
                       ("leo_body_engine", ["--set", "control.objective=fuel"])):
        r = run("solve", CONFIGS / f"{name}.yaml", "--set", "horizon.N=10", "--set", "solver.direct.max_iter=3",
                *sets, "--out", tmp_path / name, "--no-figures")
        assert "warning" not in r.stdout, r.stdout


def test_solve_default_method_is_direct(tmp_path):
    r = run("solve", CONFIGS / "e3_inclination_change.yaml", "--set", "horizon.N=20", "--out", tmp_path / "o",
            "--no-figures", "--quiet")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "o").glob("*.npz")) == ["direct.npz"]
    assert list(json.loads((tmp_path / "o" / "summary.json").read_text())["methods"]) == ["direct"]


def test_version_from_package_metadata():
    """``se3ocp --version`` prints the installed distribution's version (not a copy that can drift), exit 0."""
    from importlib.metadata import version

    r = run("--version")
    assert r.returncode == 0 and r.stderr == ""
    assert r.stdout.strip() == f"se3ocp {version('se3ocp')}"


def test_status_column_is_never_cut():
    """The CLI table's status column is as wide as its widest status: every Result and a long
    solver status appear whole, and the columns after it stay aligned."""
    from types import SimpleNamespace

    from se3ocp.problems.cli.progress import table

    long = SimpleNamespace(value="Maximum_Iterations_Exceeded")
    sols = [SimpleNamespace(method=m, result=r) for m, r in [("direct", long), *(("x", r) for r in Result)]]
    for s in sols:  # only not_applicable rows are printed without numbers; make every row one
        s.result = SimpleNamespace(value=s.result.value) if s.result is not Result.not_applicable else s.result
        s.trajectory = SimpleNamespace(orthogonality=lambda: {"max_orthogonality_error": 0.0})
        s.cost, s.terminal_error, s.iterations, s.build_s, s.solve_s = 1.0, 0.0, 3, 0.0, 0.0
    rows = table(sols)
    assert "Maximum_Iterations_Exceeded " in rows[2]
    for s, row in zip(sols, rows[2:]):
        assert f" {s.result.value} " in row
    assert len({len(r) for r in rows}) == 1  # aligned


def test_out_of_memory_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    """A MemoryError (a horizon.N the schema allows but the machine cannot hold) is one line on
    stderr and exit 1, and the results transaction leaves nothing behind."""
    from se3ocp.problems import cli
    from se3ocp.transcription import solve as solve_module

    def no_memory(*a, **k):
        raise MemoryError

    monkeypatch.setattr(solve_module, "solve", no_memory)
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["solve", str(CONFIGS / "e3_inclination_change.yaml"), "--set", "horizon.N=10", "--out", "o",
                   "--quiet", "--no-figures"])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1 and "out of memory" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_an_in_process_run_leaves_no_compile_notifier_behind(capsys):
    """The CLI binds codegen's compile notice to its own arguments while a command runs, and unbinds it after:
    a later library call that compiles (a cold cache) must not print through a finished command's arguments
    (it once raised AttributeError in the next test's solve).  And a command without --json (fly) can print it."""
    import argparse

    from se3ocp.problems.cli import main
    from se3ocp.problems.cli.progress import say
    from se3ocp.transcription.compile import codegen

    before = codegen.notify
    assert main(["validate", str(ROOT / "configs" / "e3_inclination_change.yaml")]) == 0
    assert codegen.notify is before
    say(argparse.Namespace(quiet=False), "  [jit] compiling f to C")
    assert capsys.readouterr().out.endswith("compiling f to C\n")
