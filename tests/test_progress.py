"""Progress of long solves (transcription.methods.base: phased, clocked; strategy.core.Context): every NLP of a direct solve
reports its iterations to the caller's progress callback, the guesses' own solves too (coarse grids, the fuel
homotopy's effort problem and levels, the structured finish), each record naming its solve (``Iterate.phase``) and
the seconds since the top-level solve started (``elapsed_s``); the CLI and API printers show both."""
from __future__ import annotations

import argparse
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

import se3ocp
from se3ocp.problems.api import _printer
from se3ocp.problems.cli.progress import Progress
from se3ocp.transcription.objectives.fuel.homotopy import Homotopy
from se3ocp.transcription.outcome import Iterate
from support import maneuver

ROOT = Path(__file__).resolve().parents[1]


def _solves(recs):
    """The NLP solves the records came from, in order: [phase, records]; a solve's records are numbered from 0."""
    out = []
    for r in recs:
        if r.iteration == 0:
            out.append([r.phase, 0])
        assert out and out[-1][0] == r.phase, (r.phase, out[-1:])      # one solve's records share its phase
        out[-1][1] += 1
    return out


@pytest.fixture(scope="module")
def fuel50():
    """The fuel raise on 50 steps (~3 s): the homotopy multistart on its 25-step coarse grid (the effort problem
    from the free motion, the jump, the fuel NLP from it, the free motion, the interpolation), then the structured
    finish on the 50 steps (rough, then pruned)."""
    recs = []
    sol = se3ocp.solve(se3ocp.load(ROOT / "configs" / "orbit_raise_fuel.yaml", ("horizon.N=50",)), progress=recs.append,
                       continuous_check=False)
    assert sol.converged, sol.message
    return sol, recs


def test_every_nlp_of_a_fuel_solve_reports_under_its_phase(fuel50):
    """Before, the coarse grid and the homotopy were silent (77 records of 695 iterations, all from the structured
    finish, unlabelled).  Now: the coarse grid's solves under 'coarse N=25 / ...' (its effort problem under
    'effort', the jump, the fuel NLP from the homotopy, the other starts), then the structured finish's; every
    IPOPT iteration is reported (IPOPT calls back once per iteration and iteration 0, and a few times more in its
    restoration phase: at least sol.iterations + one per solve, and the last solve's records are its history's);
    each record with its solve's iteration budget."""
    sol, recs = fuel50
    solves = _solves(recs)
    phases = [p for p, _ in solves]
    for need in ("coarse N=25 / effort / rollout", "coarse N=25 / fuel jump", "coarse N=25 / from homotopy",
                 "coarse N=25 / rollout", "coarse N=25 / interpolate", "structured rough", "structured pruned"):
        assert need in phases, (need, phases)
    assert all(p.startswith(("coarse N=25 / ", "structured ")) for p in phases), phases
    assert phases.index("coarse N=25 / effort / rollout") < phases.index("coarse N=25 / fuel jump") \
        < phases.index("coarse N=25 / from homotopy") < phases.index("structured rough")
    assert sum(n for _, n in solves) == len(recs) >= sol.iterations + len(solves)
    assert phases[-1] == "structured pruned" and solves[-1][1] == len(sol.history)
    jump = [n for p, n in solves if p == "coarse N=25 / fuel jump"]
    assert f"the fuel NLP from the effort optimum: {jump[0] - 1}" in sol.stats["homotopy_levels"]
    budgets = {r.phase: r.budget for r in recs}
    assert budgets["coarse N=25 / fuel jump"] == Homotopy(None).jump_budget
    assert budgets["coarse N=25 / effort / rollout"] == Homotopy(None).effort_rollout_budget
    assert all(r.budget > 0 and r.method == "direct" for r in recs)


def test_elapsed_seconds_are_those_of_the_whole_solve(fuel50):
    """elapsed_s: finite, non-decreasing across every NLP (not restarted per solve), within the solve's time."""
    sol, recs = fuel50
    el = [r.elapsed_s for r in recs]
    assert all(math.isfinite(e) and e >= 0 for e in el)
    assert all(a <= b for a, b in zip(el, el[1:]))
    assert el[-1] <= sol.build_s + sol.solve_s + 5.0      # the plan's set-up and the checks besides
    first_fine = next(r for r in recs if r.phase == "structured rough")
    assert first_fine.elapsed_s > recs[0].elapsed_s       # the finish is timed from the start, not its own


def test_refinement_levels_name_their_grid():
    """Refinement to an accuracy: each level's solves under 'level k N=...', k as in the mesh history."""
    recs = []
    sol = se3ocp.solve(maneuver("e3", 40, "lgvi"), accuracy=1e-3, progress=recs.append)
    assert sol.converged and len(sol.mesh) >= 2, sol.message
    seen = list(dict.fromkeys(r.phase.split(" / ")[0] for r in recs))
    assert seen == [f"level {m['level']} N={m['N']}" for m in sol.mesh], seen


def test_the_printed_line_names_the_method_the_seconds_and_the_phase(capsys):
    """The CLI printer and the API's: '  [direct 123 s] iter   45  cost ...  (eps 1e-01; <= 500 it)'.  The CLI's
    throttle (one line a second after ten) still prints the first record of a new phase."""
    rec = Iterate(iteration=45, cost=0.5, residual=1e-3, phase="eps 1e-01", elapsed_s=123.4, budget=500,
                  method="direct")
    line = "  [direct 123 s] iter   45  cost 0.5  residual 1.000e-03  (eps 1e-01; <= 500 it)"
    _printer(rec)
    assert capsys.readouterr().err == line + "\n"
    show = Progress(argparse.Namespace(quiet=False, json=False))
    show(rec)
    assert capsys.readouterr().out == line + "\n"
    for k in range(12):
        show(Iterate(iteration=k, phase="eps 1e-01", elapsed_s=1.0, method="direct"))
    assert len(capsys.readouterr().out.splitlines()) == 9        # 10 in all, then throttled
    show(Iterate(iteration=0, phase="eps 1e-02", elapsed_s=1.2, method="direct"))
    assert capsys.readouterr().out == "  [direct 1 s] iter    0  (eps 1e-02)\n"
    assert Iterate(iteration=3).progress_line() == "iter    3"        # nothing known: no brackets


def test_the_cli_prints_the_homotopy_with_elapsed_seconds(tmp_path):
    """End to end: `se3ocp solve` on the fuel raise's 25 steps prints the effort problem's and the jump's
    iterations, each line with the seconds since the solve started."""
    r = subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", "solve", str(ROOT / "configs" / "orbit_raise_fuel.yaml"),
                        "--set", "horizon.N=25", "--method", "direct", "--no-figures", "--out", str(tmp_path / "out")],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("  [direct ")]
    pattern = re.compile(r"  \[direct \d+ s\] iter +\d+  cost \S+  residual \S+  \((.+); <= (\d+) it\)$")
    assert lines and all(pattern.match(ln) for ln in lines), lines[:3]
    phases = [pattern.match(ln).group(1) for ln in lines]
    assert {"effort / rollout", "fuel jump", "from homotopy", "rollout", "interpolate"} <= set(phases), set(phases)
    assert max(map(len, lines)) <= 120
