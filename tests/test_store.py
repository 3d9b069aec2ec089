"""Results directories (problems/store.py): what a run writes is what is read back."""
from __future__ import annotations

import json

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.store import read_run, summary, write_run
from se3ocp.transcription.solve import Comparison
from support import maneuver


@pytest.fixture(scope="module")
def both():
    man = maneuver("e4", 30, "first_order")
    return man, se3ocp.solve(man, "both")


def test_write_then_read_gives_the_same_solutions(both, tmp_path):
    man, res = both
    written = write_run(tmp_path, man, res)
    assert {p.name for p in written} == {"config.resolved.yaml", "direct.npz", "indirect.npz", "summary.json"}
    run = read_run(tmp_path)
    assert isinstance(run.result, Comparison) and run.result.verdict == res.verdict
    for m, s in res.solutions.items():
        r = run.solutions[m]
        np.testing.assert_array_equal(r.trajectory.X, s.trajectory.X)
        np.testing.assert_array_equal(r.controls, s.controls)
        np.testing.assert_array_equal(r.costates, s.costates)
        assert (r.result, r.cost, r.iterations, r.message) == (s.result, s.cost, s.iterations, s.message)
        assert [h.residual for h in r.history] == [h.residual for h in s.history]
        assert r.problem.N == s.problem.N and np.array_equal(r.problem.X0, s.problem.X0)


def test_summary_fields(both):
    man, res = both
    s = summary(man, res)
    assert s["converged"] is True and set(s["methods"]) == {"direct", "indirect"}
    assert s["comparison"]["same_extremal"] is True
    for b in s["methods"].values():
        assert {"status", "message", "cost", "terminal_error", "iterations", "history", "N", "T", "h"} <= set(b)
        json.dumps(b, allow_nan=True)                                   # JSON-ready


def test_impulsive_and_simulate_round_trip(tmp_path):
    man = maneuver("e1", 60)
    sol = se3ocp.solve(man)
    write_run(tmp_path / "e1", man, sol)
    r = read_run(tmp_path / "e1").solutions["direct"]
    assert set(r.impulses) == {"dgamma0", "dPi0", "dgammaN", "dPiN"} and r.controls is None
    np.testing.assert_array_equal(r.impulses["dPi0"], sol.impulses["dPi0"])
    man = maneuver("free", 500, None, "horizon.T=0.5")
    sim = se3ocp.simulate(man)
    write_run(tmp_path / "sim", man, sim)
    r = read_run(tmp_path / "sim").solutions["simulate"]
    assert r.result is se3ocp.Result.converged and r.stats["max_orthogonality_error"] == sim.stats["max_orthogonality_error"]


def test_not_a_results_directory(tmp_path):
    with pytest.raises(se3ocp.ConfigError, match="not a results directory"):
        read_run(tmp_path)
