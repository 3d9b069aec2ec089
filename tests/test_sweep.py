"""Sweeps (issue 8): sweep-file validation, local pool vs a Dask LocalCluster,
continuation against cold solves, failures as rows, the ``se3ocp sweep`` command.

Small grids at N <= 60 so the file runs in about a minute on 2 cores.
"""
from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from se3ocp.problems import sweep as sw
from se3ocp.problems.schema import ConfigError

ROOT = Path(__file__).resolve().parents[1]
E3 = ROOT / "configs" / "e3_inclination_change.yaml"
E1 = ROOT / "configs" / "e1_impulsive_tpbvp.yaml"
N = 40


def write_sweep(tmp_path: Path, body: str, name="s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(f"base: {E3}\n" + body if "base:" not in body else body)
    return p


GRID_2x3 = f"""
set: {{horizon.N: {N}}}
axes:
  horizon.T: [0.48, 0.53]
  control.weights.moment: [5000.0, 10000.0, 20000.0]
methods: [direct, indirect]
continuation: true
"""

T_SWEEP = f"""
set: {{horizon.N: {N}}}
axes:
  horizon.T: {{linspace: [0.46, 0.56, 6]}}
methods: [direct, indirect]
continuation: true
"""


# ------------------------------------------------------------------ validation
BAD = [
    ("axes: {horizon.T: [0.5]}\n", "base", "missing required key", True),
    ("axes: {horizon.T: [0.5]}\nfoo: 1\n", "foo", "unknown key", False),
    ("axes: {}\n", "axes", "non-empty mapping", False),
    ("axes: {horizon.T: 0.5}\n", "axes.horizon.T", "expected a list of values", False),
    ("axes: {horizon.T: []}\n", "axes.horizon.T", "at least one value", False),
    ("axes: {horizon.T: [0.5, 0.5]}\n", "axes.horizon.T[1]", "distinct", False),
    ("axes: {horizon.T: {linspace: [0.4, 0.5, 0]}}\n", "axes.horizon.T.linspace[2]", "positive integer", False),
    ("axes: {horizon.T: {linspace: [0.4, 0.5]}}\n", "axes.horizon.T.linspace", "[start, stop, num]", False),
    ("axes: {horizon.T: {geomspace: [-1, 0.5, 3]}}\n", "axes.horizon.T.geomspace", "positive start and stop", False),
    ("axes: {horizon.T: {arange: [0.4, 0.5, 3]}}\n", "axes.horizon.T", "linspace", False),
    ("axes: {horizon..T: [1]}\n", "axes.horizon..T", "dotted maneuver key", False),
    ("axes: {horizon.T: [0.5, -0.1]}\n", "axes.horizon.T[1]", "horizon.T: expected a positive number", False),
    ("axes: {horizon.N: [10, 2.5]}\n", "axes.horizon.N[1]", "expected an integer", False),
    ("axes: {horizon.M: [1]}\n", "axes.horizon.M[0]", "unknown key", False),
    ("axes: {horizon.T: [0.5]}\nmethods: [direct, shooting]\n", "methods[1]", "expected one of direct, indirect", False),
    ("axes: {horizon.T: [0.5]}\nmethods: []\n", "methods", "non-empty list", False),
    ("axes: {horizon.T: [0.5]}\ncontinuation: yes please\n", "continuation", "true or false", False),
    ("axes: {horizon.T: [0.5]}\ncontinuation_axis: horizon.N\n", "continuation_axis", "expected one of horizon.T", False),
    ("axes: {horizon.T: [0.5]}\nset: {horizon.T: 0.4}\n", "axes", "set twice", False),
    ("axes: {status: [1]}\n", "axes.status", "other than the result columns", False),
    ("axes:\n  inc:\n    values: [10, 20]\n    set: {terminal.velocity: [[0, -6, -1]]}\n",
     "axes.inc.set.terminal.velocity", "list of 2 values", False),
    ("axes:\n  inc:\n    values: [10, 20]\n    set: {terminal.velocity: [[0, -6, -1], [0, -6]]}\n",
     "axes.inc.set.terminal.velocity[1]", "terminal.velocity: expected a list of 3 numbers", False),
    ("axes: {solver.direct.options.no_such_ipopt_option: [1]}\n", "axes.solver.direct.options.no_such_ipopt_option[0]",
     "unknown IPOPT option", False),
    ("axes: {horizon.T: [0.5]\n", "line", "not valid YAML", False),
]


@pytest.mark.parametrize("body,fieldname,detail,no_base", BAD)
def test_bad_sweep_files(tmp_path, body, fieldname, detail, no_base):
    p = tmp_path / "bad.yaml"
    p.write_text(body if no_base else f"base: {E3}\n" + body)
    with pytest.raises(ConfigError) as ei:
        sw.load_sweep(p)
    msg = str(ei.value)
    assert "\n" not in msg and msg.startswith(f"{p}: ")
    assert ei.value.field.startswith(fieldname), msg
    assert detail in msg, msg


def test_base_errors(tmp_path):
    p = write_sweep(tmp_path, "base: nowhere.yaml\naxes: {horizon.T: [0.5]}\n")
    with pytest.raises(ConfigError, match="base: expected a maneuver file"):
        sw.load_sweep(p)
    p = write_sweep(tmp_path, f"base: {E1}\naxes: {{horizon.T: [0.8]}}\nmethods: [direct, indirect]\n")
    with pytest.raises(ConfigError, match="methods: the indirect method applies to smooth maneuvers"):
        sw.load_sweep(p)


def test_grid_points_and_chains(tmp_path):
    s = sw.load_sweep(write_sweep(tmp_path, GRID_2x3))
    pts = s.points()
    assert s.shape == (2, 3) and len(pts) == 6
    assert pts[4].values == {"horizon.T": 0.53, "control.weights.moment": 10000.0}
    assert pts[4].overrides == ("horizon.N=40", "horizon.T=0.53", "control.weights.moment=10000.0")
    assert s.chains(False) == [[i] for i in range(6)]
    assert sorted(s.chains(True)) == [[0, 3], [1, 4], [2, 5]]  # along T, one chain per weight
    lin = sw.load_sweep(write_sweep(tmp_path, T_SWEEP, "t.yaml"))
    assert lin.axes[0].values == (0.46, 0.48, 0.5, 0.52, 0.54, 0.56)  # no representation noise


def test_secant_predictor_extrapolates_the_warm_starts():
    """The neighbour's warm start, or the secant through the last two (transcription.results.start.secant) when the
    step is at most MAX_SECANT_RATIO spacings."""
    from se3ocp.problems.sweep.run import _predict as predict
    from se3ocp.transcription.results.start import Start

    def warm(lam0):
        X = np.tile(np.r_[np.zeros(6), np.eye(3).ravel(), np.zeros(3)], (3, 1))
        return Start(t=np.linspace(0, 1, 3), X=X, U=np.zeros((6, 2)), scheme="first_order", source="indirect",
                         lam0=np.asarray(lam0, float))

    a, b = warm(np.arange(12.0)), warm(np.arange(12.0) + 1.0)
    p = predict([(0.5, a), (0.6, b)], 0.75, numeric=True)
    assert p["kind"] == "secant" and np.allclose(p["start"].lam0, np.arange(12.0) + 2.5, rtol=0, atol=1e-14)
    assert predict([(0.5, a)], 0.6, numeric=True) == {"start": a, "kind": "neighbour"}
    assert predict([(0.5, a), (0.6, b)], 2.0, numeric=True)["kind"] == "neighbour"  # too far: no extrapolation
    assert predict([], 0.6, numeric=True) is None


# ------------------------------------------------------------------ execution
@pytest.fixture(scope="module")
def grid_file(tmp_path_factory):
    return write_sweep(tmp_path_factory.mktemp("grid"), GRID_2x3)


@pytest.fixture(scope="module")
def local_result(grid_file):
    return sw.run_sweep(sw.load_sweep(grid_file), workers=2)


def _costs(res):
    return {(r["point"], r["method"]): r["cost"] for r in res.rows}


def test_local_pool_2x3(local_result):
    res = local_result
    assert res.executor == "local" and len(res.rows) == 12 and res.all_converged
    assert [(r["point"], r["method"]) for r in res.rows] == [(i, m) for i in range(6) for m in ("direct", "indirect")]
    for i in range(6):  # the two methods find the same extremal at every point
        d, ind = res.rows[2 * i], res.rows[2 * i + 1]
        assert abs(d["cost"] - ind["cost"]) <= 1e-8 * d["cost"]
    # the second T value of each chain was warm-started from the first
    assert [r["warm_started"] for r in res.rows if r["horizon.T"] == 0.53] == [True] * 6
    assert {r["start"] for r in res.rows if r["horizon.T"] == 0.48} == {"cold"}


def test_dask_local_cluster_identical(grid_file, local_result):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, protocol="tcp") as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        res = sw.run_sweep(sw.load_sweep(grid_file), scheduler=cluster.scheduler_address)
        out = grid_file.parent / "dask_cli"
        r = run(grid_file, "--out", out, "--scheduler", cluster.scheduler_address, "--quiet")
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "summary.json").read_text())["executor"] == "dask"
    cli_costs = [float(x["cost"]) for x in csv.DictReader((out / "results.csv").open())]
    assert cli_costs == [r["cost"] for r in res.rows]  # repr round-trips the floats
    assert res.executor == "dask" and res.all_converged
    a, b = _costs(local_result), _costs(res)
    assert a.keys() == b.keys()
    for k in a:
        assert abs(a[k] - b[k]) <= 1e-10 * abs(a[k]), (k, a[k], b[k])
    assert [r["iterations"] for r in res.rows] == [r["iterations"] for r in local_result.rows]


def test_continuation_same_costs_fewer_iterations(tmp_path):
    s = sw.load_sweep(write_sweep(tmp_path, T_SWEEP))
    warm = sw.run_sweep(s, workers=2)
    cold = sw.run_sweep(s, workers=2, continuation=False)
    assert warm.all_converged and cold.all_converged
    a, b = _costs(warm), _costs(cold)
    for k in a:
        assert abs(a[k] - b[k]) <= 1e-8 * abs(b[k]), (k, a[k], b[k])
    for m in ("direct", "indirect"):
        it_w = sum(r["iterations_total"] for r in warm.rows if r["method"] == m)
        it_c = sum(r["iterations_total"] for r in cold.rows if r["method"] == m)
        assert it_w < it_c, (m, it_w, it_c)
    assert {r["start"] for r in warm.rows if r["horizon.T"] >= 0.5} == {"secant"}
    assert not any(r["warm_started"] for r in cold.rows)


def test_failing_point_recorded_chain_continues(tmp_path):
    """A point that cannot converge (max_iter 1) in the middle of a chain: its warm start fails,
    the cold fallback fails too (both recorded), and the next point starts from the last converged one."""
    s = sw.load_sweep(write_sweep(tmp_path, f"""
set: {{horizon.N: {N}}}
axes:
  case:
    values: [1, 2, 3]
    set: {{horizon.T: [0.5, 0.52, 0.54], solver.direct.max_iter: [3000, 1, 3000]}}
continuation: true
"""))
    res = sw.run_sweep(s, workers=1)
    assert [r["converged"] for r in res.rows] == [True, False, True]
    bad = res.rows[1]
    assert bad["status"] == "max_iterations" and bad["start"] == "cold_after_failed_warm"
    # warm start 1 iteration, then the cold 'auto' solve: rollout 1 + interpolation 1
    assert bad["iterations_total"] == 3 and bad["warm_started"] is False
    assert res.rows[2]["start"] == "neighbour" and res.rows[2]["warm_started"] is True
    assert not res.all_converged


def test_exception_in_a_task_is_a_row(tmp_path, monkeypatch):
    s = sw.load_sweep(write_sweep(tmp_path, "set: {horizon.N: 20}\naxes: {horizon.T: [0.5, 0.52]}\n"))
    from se3ocp.problems.sweep import task

    real = task._solve

    def flaky(man, method, warm):
        if man.T == 0.5:
            raise RuntimeError("solver blew up\nwith a two-line message")
        return real(man, method, warm)

    monkeypatch.setattr(task, "_solve", flaky)
    res = sw.run_sweep(s, workers=1)
    assert [r["status"] for r in res.rows] == ["error", "converged"]
    assert res.rows[0]["message"] == "RuntimeError: solver blew up with a two-line message"


def test_warm_start_that_raises_falls_back_cold(tmp_path, monkeypatch):
    import se3ocp.transcription.solve as registry

    direct = registry.solve_direct

    def no_warm(problem, options=None, progress=None, warm=None, strategy=None):
        if warm is not None:
            raise RuntimeError("warm start broke the solver")
        return direct(problem, options, progress, None, strategy)

    monkeypatch.setattr(registry, "solve_direct", no_warm)
    s = sw.load_sweep(write_sweep(tmp_path, "set: {horizon.N: 20}\naxes: {horizon.T: [0.5, 0.52]}\ncontinuation: true\n"))
    res = sw.run_sweep(s, workers=1)
    assert [r["start"] for r in res.rows] == ["cold", "cold_after_failed_warm"]
    assert res.all_converged and res.rows[1]["iterations_total"] == res.rows[1]["iterations"]


def test_bad_scheduler_is_bad_input():
    pytest.importorskip("distributed")
    with pytest.raises(ConfigError, match="cannot connect"):
        sw.DaskExecutor("tcp://127.0.0.1:9", timeout=1)


# ------------------------------------------------------------------ the command
def run(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", "sweep", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_cli_end_to_end(tmp_path):
    f = write_sweep(tmp_path, f"""
set: {{horizon.N: {N}}}
axes:
  horizon.T: [0.5, 0.52]
  inclination_deg:
    values: [20, 30]
    set:
      terminal.velocity: [[0.0, -5.904262868187098, -2.148975939303298], [0.0, -5.441398092702654, -3.1415926535897927]]
      terminal.attitude: [{{rotations: [[x, 20], [z, 180]]}}, {{rotations: [[x, 30], [z, 180]]}}]
methods: [direct]
continuation: true
""")
    out = tmp_path / "out"
    r = run(f, "--out", out, "--workers", "2")
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    assert r.stderr.count("\n[") + r.stderr.startswith("[") == 4  # one progress line per task (not a TTY)
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert list(rows[0]) == ["point", "method", "horizon.T", "inclination_deg", *sw.RESULT_COLUMNS]
    assert len(rows) == 4 and all(x["converged"] == "true" for x in rows)
    lines = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len(lines) == 4 and lines[0]["overrides"][0] == f"horizon.N={N}"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tasks"] == summary["finished"] == summary["converged"] == 4 and summary["interrupted"] is False
    assert yaml.safe_load((out / "sweep.resolved.yaml").read_text())["axes"]["horizon.T"] == [0.5, 0.52]
    for name in ("cost_vs_horizon.T.png", "cost_vs_inclination_deg.png", "status_map.png"):
        with Image.open(out / name) as im:
            assert im.format == "PNG" and min(im.size) >= 300, (name, im.size)
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["results.csv", "results.jsonl", "summary.json", "sweep.resolved.yaml", "cost_vs_horizon.T.png",
         "cost_vs_inclination_deg.png", "status_map.png"])     # no temporaries
    # a non-empty results directory needs --force
    r = run(f, "--out", out, "--workers", "1", "--quiet")
    assert r.returncode == 2 and r.stderr == (f"se3ocp: error: {out}: results directory already holds files; pass "
                                              f"--force to overwrite, or choose another --out\n")


def test_cli_exit_codes(tmp_path):
    bad = write_sweep(tmp_path, "axes: {horizon.T: [0.5, -1]}\n", "bad.yaml")
    r = run(bad, "--out", tmp_path / "o2")
    assert r.returncode == 2
    assert r.stderr == (f"se3ocp: error: {bad}: axes.horizon.T[1]: grid point horizon.T=-1: horizon.T: expected a "
                        f"positive number, got -1\n")
    assert not (tmp_path / "o2").exists()  # nothing written for bad input
    r = run(bad, "--workers", "0")
    assert r.returncode == 2
    assert r.stderr.splitlines()[-1] == "se3ocp sweep: error: argument --workers: expected a positive integer, got '0'"
    some_fail = write_sweep(tmp_path, "set: {horizon.N: 20}\naxes: {solver.direct.max_iter: [2, 3000]}\n", "f.yaml")
    r = run(some_fail, "--out", tmp_path / "o3", "--workers", "1", "--quiet", "--no-continuation")
    assert r.returncode == 1, r.stderr
    assert r.stdout == "" and "Traceback" not in r.stderr
    rows = list(csv.DictReader((tmp_path / "o3" / "results.csv").open()))
    assert [x["converged"] for x in rows] == ["false", "true"]
    assert [x["start"] for x in rows] == ["cold", "cold"]
    assert json.loads((tmp_path / "o3" / "summary.json").read_text())["continuation"] is False


def test_cli_ctrl_c_writes_finished_rows(tmp_path):
    """SIGINT during a pool sweep: exit 130 promptly (workers stopped), the rows finished so far are written."""
    f = write_sweep(tmp_path, f"set: {{horizon.N: {N}}}\naxes: {{horizon.T: {{linspace: [0.45, 0.63, 10]}}}}\n"
                              "methods: [direct, indirect]\n")
    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "se3ocp.problems.cli", "sweep", str(f), "--out", str(out), "--workers", "2"],
                         cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = p.stderr.readline()  # the first finished task
        assert first.startswith("[ 1/20]"), first
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 130, err
    assert err.splitlines()[-1] == (f"se3ocp: interrupted; {out}/ holds the part finished before the interrupt, "
                                    f"marked INCOMPLETE (nothing half-written)"), err
    assert "Traceback" not in err and "resource_tracker" not in err      # no leaked semaphores of the pool
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert 1 <= len(rows) < 20
    assert (out / "INCOMPLETE").read_text() == f"interrupted (Ctrl-C) after {len(rows)} of 20 tasks\n"
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True


# ------------------------------------------------------------------ fuzz
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**4, 10**4), st.floats(allow_nan=True, allow_infinity=True),
                     st.text(max_size=6), st.sampled_from(["direct", "indirect", "horizon.T", "linspace", "lgvi"]))
_values = st.recursive(_scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                         st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                       max_leaves=10)
_keys = st.sampled_from(["horizon.T", "horizon.N", "control.weights.moment", "terminal.velocity", "discretization",
                         "solver.direct.max_iter", "solver.indirect.alpha", "inc", "horizon", "a..b", "status"])
_axis_specs = st.one_of(
    _values,
    st.lists(st.floats(0.01, 2.0), min_size=1, max_size=4),
    st.fixed_dictionaries({st.sampled_from(["linspace", "geomspace", "range"]): st.lists(_scalars, max_size=4)}),
    st.fixed_dictionaries({"values": st.lists(_scalars, max_size=3), "set": st.dictionaries(_keys, _values, max_size=2)}),
)
_docs = st.fixed_dictionaries(
    {"base": st.just(str(E3)), "axes": st.one_of(
        _values, st.dictionaries(_keys, _axis_specs, max_size=3),
        st.fixed_dictionaries({"horizon.T": st.lists(st.floats(0.05, 2.0), min_size=1, max_size=3, unique=True)},
                              optional={"horizon.N": st.lists(st.integers(-2, 300), min_size=1, max_size=2, unique=True),
                                        "inc": _axis_specs}))},
    optional={"methods": st.one_of(_values, st.lists(st.sampled_from(["direct", "indirect", "x"]), max_size=3)),
              "continuation": st.one_of(st.booleans(), _values),
              "continuation_axis": st.one_of(_keys, _values),
              "set": st.one_of(_values, st.dictionaries(_keys, _values, max_size=2)),
              "name": st.one_of(st.text(min_size=1, max_size=6), _values)})


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_docs)
def test_random_sweep_documents(doc):
    """Any document: a Sweep whose points all load, or a one-line ConfigError naming the file."""
    try:
        s = sw.sweep_from_doc(doc, "fuzz.yaml")
    except ConfigError as e:
        assert str(e).startswith("fuzz.yaml: ") and "\n" not in str(e), str(e)
        return
    assert len(s.points()) == int(np.prod(s.shape)) >= 1
