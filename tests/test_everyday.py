"""The everyday-maneuver suite (configs/everyday/): maneuvers a mission planner would try first -- large
radius changes, large plane changes, multi-orbit horizons, a detumble, a fast-tumble capture, slews with
transfers, both schemes, dumbbell and rigid body -- must converge with the default settings; and the
objective's default strategy (transcription.objectives: its ``compose``) tries its starts in
order and reports each one.

Tolerances: the re-simulated terminal error <= 1e-8 and max |R^T R - I| <= 1e-12, as for E3/E4 in
tests/test_direct.py.  The long horizons (N = 600 over three periods, N = 1000 over five) are slow tests.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import se3ocp
from se3ocp.transcription.strategy import starts
from se3ocp.transcription.objectives.effort import EffortStrategy
from se3ocp.transcription.objectives.fuel.plan import FuelStrategy
from se3ocp.transcription.strategy.core import BestOf, CoarseToFine, Solve
from se3ocp.transcription.nlp.scaling import scaled_terminal_miss
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from support import CONFIGS, maneuver

EVERYDAY = sorted(p.stem for p in (CONFIGS / "everyday").glob("*.yaml"))
SLOW = {"raise_3_orbits", "phasing_5_orbits"}


def test_the_suite_is_everyday():
    """At least 8 cases, both schemes, both body models (the acceptance of issue 15, item 7)."""
    mans = [se3ocp.load(CONFIGS / "everyday" / f"{n}.yaml") for n in EVERYDAY]
    assert len(mans) >= 8
    assert {m.discretization for m in mans} == {"lgvi", "first_order"}
    assert {m.resolved["model"]["kind"] for m in mans} == {"dumbbell", "rigid_body"}
    assert all(m.direct == se3ocp.DirectOptions() for m in mans)      # the defaults, nothing tuned


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in EVERYDAY])
def test_everyday_converges_with_defaults(name):
    sol = se3ocp.solve(se3ocp.load(CONFIGS / "everyday" / f"{name}.yaml"))
    assert sol.converged, sol.message
    assert sol.terminal_error <= 1e-8, sol.terminal_error          # on the re-simulation, not the NLP's nodes
    assert sol.trajectory.orthogonality()["max_orthogonality_error"] <= 1e-12
    last = sol.trace[-1]
    assert last.label == sol.stats["initial_guess"] and last.result is se3ocp.Result.converged


# --------------------------------------------------------------------- the objective's strategy
def _labels(name, *sets):
    """The starts the objective's default strategy tries for the bundled maneuver, as (label, budget) (budget: the
    most iterations of its own solve), and how it picks: 'first' (the first that converges), 'best' (the lowest
    converged cost), 'coarse' (a coarser grid's start, the others the fallback)."""
    man = maneuver(name, None, None, *sets)
    p, mx = man.problem, man.direct.max_iter
    strategy = p.control.objective.strategy(p, man.direct).compose(p, man.direct)
    strategy = getattr(strategy, "inner", strategy) or strategy       # the fuel guard's inner strategy
    if isinstance(strategy, Solve):
        return [(strategy.label, strategy.budget or mx)], "first"
    entries, pick = strategy.strategies, "best" if isinstance(strategy, BestOf) else "first"
    if isinstance(entries[0], CoarseToFine):
        entries, pick = (entries[0], *entries[1].strategies), "coarse"
    said = []
    for e in entries:
        label = (f"the best start on {e.grid(p)} steps, resampled" if isinstance(e, CoarseToFine) else e.label)
        said.append((label, min(e.budget, mx) if getattr(e, "budget", None) else mx))
    return said, pick


def test_plan_order():
    """Effort: the rollout first when it ends within ROLLOUT_FIRST_MISS characteristic scales of the target
    (E3: 0.52), else the interpolation whose path needs less effort (orbit doubling: 3.05; the orbit's), the first with the budget AUTO_FIRST_BUDGET,
    the other with the rest; bounded effort: the relaxed problem's solution first; fuel: the best start on a
    coarser grid, then the rollout (its own budget) and the interpolation, and on the coarsest grid the
    multistart of the homotopy, the rollout and the interpolation; an explicit choice: that guess only."""
    b, mx = EffortStrategy().first_budget, se3ocp.DirectOptions().max_iter
    assert _labels("e3") == ([("rollout", b), ("interpolate", mx)], "first")
    assert _labels("everyday/orbit_double") == ([("interpolate, attitude of orbit", b), ("rollout", mx)], "first")
    entries, _ = _labels("e3_bounded")
    assert [lb for lb, _ in entries] == ["the solution without bounds and path constraints", "rollout", "interpolate"]
    bf = FuelStrategy().first_budget
    assert _labels("orbit_raise_fuel") == ([("the best start on 50 steps, resampled", mx), ("rollout", bf),
                                            ("interpolate", mx)], "coarse")
    assert _labels("orbit_raise_fuel", "horizon.N=25") == ([("the fuel homotopy from the effort optimum", mx),
                                                            ("rollout", bf), ("interpolate", bf)], "best")
    assert _labels("e3", "solver.direct.initial_guess=rollout")[0] == [("rollout", mx)]


@pytest.mark.parametrize("name, far", [("e3", False), ("e4", False), ("everyday/orbit_double", True),
                                       ("everyday/capture_fast_tumble", True)])
def test_rollout_miss_is_the_solvers_terminal_rows(name, far):
    """scaled_terminal_miss (which orders the plan) equals the max-norm of the NLP's own terminal rows (the
    scaled constraint values IPOPT sees) at the rollout, to round-off; and it puts these cases on the
    documented side of ROLLOUT_FIRST_MISS."""
    import casadi as ca
    import numpy as np

    man = maneuver(name, None, None)
    p = man.problem
    g = starts.rollout(p)
    tr = SmoothTranscription(p, man.direct)
    rows = np.asarray(ca.Function("g", [tr.nlp.w], [tr.nlp.g])(tr.initial_point(g))).ravel()[tr.nlp.rows("terminal")]
    miss = scaled_terminal_miss(p, g.X[-1])
    assert abs(miss - np.abs(rows).max()) <= 1e-12 * max(1.0, miss)
    assert (miss > EffortStrategy().rollout_first_miss) == far


def test_failing_first_guess_leads_to_the_next(monkeypatch):
    """The first guess stopped by its budget (2 iterations) -> the interpolation is tried and converges;
    the attempts list both, iterations count both, and the message and summary.json say them in words."""
    sol = se3ocp.solve(maneuver("e3", 60, "lgvi"), strategy=EffortStrategy(first_budget=2))
    first, second = sol.trace
    assert sol.converged and (first.label, first.result, first.iterations) == ("rollout", se3ocp.Result.max_iterations, 2)
    assert (second.label, second.result) == ("interpolate", se3ocp.Result.converged) and second.cost == sol.cost
    assert sol.iterations == 2 + second.iterations and sol.stats["initial_guess"] == "interpolate"
    assert first.line() == "rollout: max_iterations in 2 iterations"
    assert "initial guesses tried: rollout: max_iterations in 2 iterations; interpolate: converged" in sol.message
    assert sol.summary()["guesses_tried"] == [first.line(), second.line()]   # and summary.json carries them
    assert "hint" not in sol.stats                                 # converged: nothing to suggest


def test_failure_says_what_was_tried_and_what_to_try():
    sol = se3ocp.solve(maneuver("e3", 20, "lgvi", "solver.direct.max_iter=2"))
    assert sol.result is se3ocp.Result.max_iterations
    assert [(a.label, a.result, a.iterations) for a in sol.trace] == [
        ("rollout", se3ocp.Result.max_iterations, 2), ("interpolate", se3ocp.Result.max_iterations, 2)]
    assert "solver.direct.max_iter" in sol.stats["hint"] and "continuation" in sol.stats["hint"]
    assert sol.message.endswith(sol.stats["hint"])
    one = se3ocp.solve(maneuver("e3", 20, "lgvi", "solver.direct.max_iter=2", "solver.direct.initial_guess=rollout"))
    assert "solver.direct.initial_guess=auto" in one.stats["hint"]


def test_quiet_failure_is_one_line(tmp_path):
    """--quiet prints nothing on success, and one line on stderr on failure (exit 1)."""
    from test_cli import run

    base = ("solve", CONFIGS / "e3_inclination_change.yaml", "--set", "horizon.N=20", "--method", "direct",
            "--no-figures", "--quiet")
    r = run(*base, "--set", "solver.direct.max_iter=2", "--out", tmp_path / "bad")
    assert r.returncode == 1 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "not converged" in lines[0] and "rollout: max_iterations" in lines[0]
    assert "try " in lines[0], lines[0]
    s = json.loads((Path(tmp_path / "bad") / "summary.json").read_text())
    assert [t.split(":")[0] for t in s["methods"]["direct"]["guesses_tried"]] == ["rollout", "interpolate"]
    ok = run(*base, "--out", tmp_path / "ok")
    assert ok.returncode == 0 and ok.stdout == "" and "not converged" not in ok.stderr
