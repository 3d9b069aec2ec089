"""The one entry point (transcription/solve.py and se3ocp.solve): dispatch, options, comparison,
simulation, and the hand-off from the direct to the indirect method."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.outcome import Result
from se3ocp.transcription.results.solution import Solution
from se3ocp.transcription.dynamics.trajectory import Trajectory
from se3ocp.transcription.solve import compare
from se3ocp.transcription.results.trace import Attempt
from support import maneuver


def test_both_methods_agree_and_compare():
    """E3 (first order, N = 60): one call solves by both methods; they agree to 1e-8 in cost and
    1e-6 in controls, and the Comparison says so."""
    c = se3ocp.solve(maneuver("e3", 60), "both")
    assert isinstance(c, se3ocp.Comparison) and c.direct.method == "direct" and c.indirect.method == "indirect"
    assert c.converged and c.same_extremal and c.verdict == "agree: same extremal"
    assert c.cost_relative_difference <= 1e-8 and c.control_max_difference_relative <= 1e-6


@pytest.fixture
def direct_solves(monkeypatch) -> list:
    """The direct method's solves by the entry point, counted (one entry per call)."""
    import se3ocp.transcription.solve as registry

    calls = []
    direct = registry.solve_direct

    def counted(*a, **k):
        calls.append(1)
        return direct(*a, **k)

    monkeypatch.setattr(registry, "solve_direct", counted)
    return calls


def test_from_direct_hand_off_reuses_the_direct_solution(direct_solves):
    """With initial_costate: from_direct, 'both' runs the direct method once and starts the indirect
    method from its multipliers (at most 3 Newton iterations: they already nearly satisfy the conditions)."""
    calls = direct_solves
    c = se3ocp.solve(maneuver("e4", 60, "first_order"), "both", indirect={"initial_costate": "from_direct"})
    assert len(calls) == 1
    assert c.indirect.stats["initial_costate"] == "from_direct" and c.indirect.iterations <= 3
    assert c.same_extremal


def test_weights_are_handled_alike_by_both_methods():
    """A full (non-diagonal) SPD weight matrix is accepted by both methods and both reach the same
    optimum (cost to 1e-8, controls to 1e-6); the first-order stationarity u_{k+1} = -W^-1 [lam2; lam4]
    holds with the full matrix (to 1e-9)."""
    man = maneuver("e3", 40, "first_order", "control.weights.force=[[2, 0.5, 0], [0.5, 1, 0.2], [0, 0.2, 1]]")
    c = se3ocp.solve(man, "both")
    assert c.converged and c.same_extremal, (c.direct.message, c.indirect.message)
    assert c.cost_relative_difference <= 1e-8 and c.control_max_difference_relative <= 1e-6
    W, lam, U = man.problem.control.W, c.direct.costates, c.direct.controls
    u = -np.linalg.solve(W, np.r_[lam[:, 3:6].T, lam[:, 9:12].T])
    assert np.abs(u - U).max() <= 1e-9 * np.abs(U).max()


def _fake(method, cost, U, result=Result.converged):
    return Solution(method=method, solver="x", result=result, verdict="", trajectory=Trajectory(np.zeros(3), np.zeros((3, 18))),
                    cost=cost, terminal_error=1e-14, controls=U, trace=(Attempt("x", result, 7),))


def test_compare_reports_different_extremals():
    """Two converged solutions with different costs are flagged, the lower one named."""
    base = _fake("direct", 9.47, np.ones((6, 2)))
    other = _fake("indirect", 3.2 * 9.47, -np.ones((6, 2)))
    c = compare(base, other)
    assert c.same_extremal is False and c.verdict.startswith("MISMATCH")
    assert "direct cost 9.47" in c.verdict and "ratio 3.2" in c.verdict
    assert c.control_max_difference_relative == 2.0
    same = compare(base, dataclasses.replace(other, cost=9.47 * (1 + 1e-9), controls=base.controls))
    assert same.same_extremal is True and same.verdict.startswith("agree")
    failed = compare(base, dataclasses.replace(other, result=Result.max_iterations))
    assert failed.same_extremal is False and failed.verdict.startswith("not comparable")


def test_options_from_keywords_mappings_and_objects():
    man = maneuver("e3", 20, "first_order")
    s = se3ocp.solve(man, max_iter=1)                                   # keyword: the chosen method's option
    assert s.result is Result.max_iterations
    s = se3ocp.solve(man, direct={"max_iter": 1})                       # a mapping of changes
    assert s.result is Result.max_iterations
    s = se3ocp.solve(man, direct=se3ocp.DirectOptions(tol=1e-8))        # an options object
    assert s.converged and s.stats["kkt_tol"] == 1e-8
    with pytest.raises(TypeError, match="direct=.*indirect="):
        se3ocp.solve(man, "both", max_iter=3)
    with pytest.raises(se3ocp.OptionError, match="max_iterations"):
        se3ocp.solve(man, max_iterations=3)
    with pytest.raises(ValueError, match="method must be one of"):
        se3ocp.solve(man, "shooting")


def test_a_problem_built_in_python_solves_like_its_file():
    """The Problem of a file, rebuilt field by field in Python, gives the same solution (bitwise cost)."""
    man = maneuver("e3", 30, "first_order")
    p = man.problem
    q = se3ocp.Problem(disc=p.disc, N=p.N, T=p.T, X0=p.X0.copy(), terminal=se3ocp.TargetState(p.terminal.X.copy()),
                       control=se3ocp.SmoothControl(W_f=1.0, W_m=[1e4, 1e4, 1e4], objective=se3ocp.Effort()), name="python")
    a, b = se3ocp.solve(man), se3ocp.solve(q)                           # the file's solver block is the default
    assert a.converged and b.converged and a.cost == b.cost


def test_simulate_reports_diagnostics_and_the_miss():
    sim = se3ocp.simulate(maneuver("e3", 100, "lgvi"))
    assert sim.method == "simulate" and sim.result is Result.converged
    assert sim.stats["max_orthogonality_error"] <= 1e-13 and sim.stats["max_relative_energy_error"] <= 1e-4
    # free motion misses E3's target (a 30 degree plane change): the miss is the terminal error
    assert sim.terminal_error > 0.5
    X, _ = sim.problem.disc.simulate(sim.problem.X0, None, sim.h, sim.N)
    np.testing.assert_array_equal(X, sim.trajectory.X)
    # with the optimal controls the simulation reaches the target
    s = se3ocp.solve(maneuver("e3", 100, "lgvi"))
    assert se3ocp.simulate(maneuver("e3", 100, "lgvi"), s.controls).terminal_error <= 1e-10


def test_solutions_carry_velocities_and_angular_velocities():
    s = se3ocp.solve(maneuver("e4", 20, "first_order"))
    tr, m = s.trajectory, s.problem.model
    np.testing.assert_allclose(tr.v * m.mass, tr.gamma, rtol=1e-15)
    np.testing.assert_allclose(tr.Omega @ m.inertia.T, tr.Pi, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(tr.Omega[0], [1.0, -2.0, 3.0], rtol=1e-14)         # E4's initial tumble
    assert s.u_f.shape == (20, 3) and s.control_times.shape == (20,) and s.control_times[0] == s.h


def test_impulsive_maneuvers_take_the_direct_method_only():
    with pytest.raises(ValueError, match="impulsive maneuvers are solved by the direct method"):
        se3ocp.solve(maneuver("e1", 50), "both")
    with pytest.raises(ValueError, match="nothing to solve"):
        se3ocp.solve(maneuver("free", 50))


# ------------------------------------------------------------------------------ the registry
def test_which_methods_solve_which_problems():
    """not_covered(problem, method) is the one place that says it ('' when the method can run), solve raises
    exactly that, and the registry picks the implementation by the kind of control."""
    from se3ocp.transcription.methods.direct import Direct
    from se3ocp.transcription.methods.impulsive import Impulsive
    from se3ocp.transcription.methods.indirect import Indirect
    from se3ocp.transcription.solve import implementation, not_covered

    e1, e3, free = (maneuver(name, 10).problem for name in ("e1", "e3", "free"))
    assert [not_covered(e3, m) for m in ("direct", "indirect", "both")] == ["", "", ""]
    assert not_covered(e1, "direct") == ""
    assert not_covered(e1, "indirect") == not_covered(e1, "both") == (
        "the indirect method applies to smooth maneuvers; impulsive maneuvers are solved by the direct method")
    assert not_covered(free, "direct") == ("the problem has no terminal target and no control: there is nothing to "
                                           "solve (simulate it)")
    assert not_covered(e3, "shooting") == "method must be one of direct, indirect, both, got 'shooting'"
    with pytest.raises(ValueError) as err:
        se3ocp.solve(e1, "both")
    assert str(err.value) == not_covered(e1, "both")
    assert type(implementation(e3, "direct")) is Direct and type(implementation(e1, "direct")) is Impulsive
    assert type(implementation(e3, "indirect")) is Indirect and implementation(e1, "indirect") is None
    # what a method does not cover inside a problem it solves is its own: a Solution saying so
    r = maneuver("e3_min_radius", 10).problem.constraints[0].radius
    assert Indirect().not_covered(maneuver("e3_min_radius", 10).problem) == f"path constraints (min_radius {r:.6g})"


def test_progress_is_one_signature_naming_the_method():
    """progress(Iterate) for every method, the Iterate naming its method: the direct iterations first."""
    recs = []
    c = se3ocp.solve(maneuver("e3", 20, "first_order"), "both", progress=recs.append)
    methods = [r.method for r in recs]
    assert c.converged and set(methods) == {"direct", "indirect"}
    assert methods == sorted(methods) and methods.count("indirect") == c.indirect.iterations
    assert all(r.method == "" for r in c.direct.history + c.indirect.history)   # a Solution knows its method


def test_indirect_from_direct_alone_runs_the_direct_method_first(direct_solves):
    """'indirect' with initial_costate: from_direct runs the direct method once (the registry, not the indirect
    method) and says so in the indirect Solution's stats; the indirect method asked for from_direct without a
    direct solution says what is missing."""
    calls = direct_solves
    s = se3ocp.solve(maneuver("e3", 30, "first_order"), "indirect", initial_costate="from_direct")
    assert len(calls) == 1 and s.converged and s.stats["initial_costate"] == "from_direct"
    assert s.stats["direct_status"] == "converged" and s.stats["direct_cost"] == pytest.approx(s.cost, rel=1e-9)
    from se3ocp.transcription.methods.indirect import solve_indirect
    from se3ocp.transcription.options import IndirectOptions

    alone = solve_indirect(maneuver("e3", 30, "first_order").problem, IndirectOptions(initial_costate="from_direct"))
    assert alone.result is Result.invalid_option and "no direct solution with costates was given" in alone.message
