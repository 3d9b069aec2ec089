"""The public API as a user meets it: the README's Python example runs, `import se3ocp` is the
whole surface, and the repository stands on its own."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest

import se3ocp
from support import ROOT


def readme_example() -> str:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"<!-- api-example -->\s*```python\n(.*?)```", text, re.S)
    assert m, "the README's Python example (after <!-- api-example -->) is missing"
    return m.group(1)


def test_the_readme_python_example_runs(monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    scope: dict = {}
    exec(compile(readme_example(), "README.md", "exec"), scope)
    sol, both, ind, sim, refined = scope["sol"], scope["both"], scope["ind"], scope["sim"], scope["refined"]
    assert sol.converged and both.same_extremal and ind.converged and sim.converged
    assert ind.stats["initial_costate"] == "from_direct"
    assert refined.converged and refined.stats["warm_start_resampled"] and refined.N == 200
    assert refined.stats["warm_start"] == "the direct solution (N = 100, first_order)"
    assert set(scope["figs"]) >= {"maneuver", "force", "moment", "convergence"}
    out = capsys.readouterr().out
    assert "converged" in out and "agree: same extremal" in out


def test_help_on_the_entry_point_and_the_exports():
    out = subprocess.run([sys.executable, "-c", "import se3ocp; help(se3ocp.solve)"], capture_output=True, text=True,
                         timeout=120, cwd=str(ROOT))
    assert out.returncode == 0 and "method" in out.stdout and "'both'" in out.stdout
    for name in se3ocp.__all__:
        assert getattr(se3ocp, name) is not None, name


def test_import_is_light_until_a_name_is_used():
    """`import se3ocp` (and the CLI module's first lines) load neither CasADi nor NumPy: the CLI
    installs its Ctrl-C handler before they load."""
    code = "import sys, se3ocp; print('casadi' in sys.modules, 'numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.split() == ["False", "False"], out.stdout + out.stderr


def test_the_installed_names_are_under_se3ocp_only():
    """The layers are se3ocp.transcription and se3ocp.problems; the method layer never imports the
    problems layer."""
    assert se3ocp.solve.__module__ == "se3ocp.problems.api"
    for path in (ROOT / "transcription").rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^\s*(from|import)\s+(\.\.problems|se3ocp\.problems|problems)\b", text, re.M), path
    for path in list((ROOT / "problems").rglob("*.py")) + list((ROOT / "scripts").glob("*.py")) + list(
            (ROOT / "tests").glob("*.py")):
        text = path.read_text()
        assert not re.search(r"^\s*(from|import)\s+(transcription|problems)\b", text, re.M), f"{path}: bare import"
    for path in (ROOT / "scripts").glob("*.py"):
        assert not re.search(r"^\s*(from|import)\s+tests\b", path.read_text(), re.M), f"{path} imports tests"


def test_nothing_refers_outside_the_repository():
    """The project stands on its own: no README, doc, config, docstring or test points at the
    workspace's shared files."""
    pat = re.compile(r"\.\./shared|shared/SPEC|SPEC\.md|SPEC §|seed/000")
    files = [ROOT / "README.md", ROOT / "pyproject.toml"]
    for folder, exts in (("docs", ("*.md",)), ("configs", ("*.yaml", "sweeps/*.yaml")),
                         ("transcription", ("**/*.py",)), ("problems", ("**/*.py",)), ("scripts", ("*.py",)),
                         ("tests", ("*.py",))):
        for ext in exts:
            files += list((ROOT / folder).glob(ext))
    bad = [str(p.relative_to(ROOT)) for p in files if pat.search(p.read_text()) and p.name != "test_api.py"]
    assert not bad, bad


def test_a_solved_problem_and_its_solution_pickle_and_solve_alike():
    """A Problem whose Discretization has built its step Functions (any solve does) and the Solution it gave go
    through pickle (to a process pool, a cache): the Solution's cost and plan come back bit for bit, and the
    unpickled Problem, its Function cache rebuilt on first use, solves to the same cost to round-off (1e-12)."""
    import pickle

    import numpy as np
    from support import problem

    p = problem("e3", 40, "lgvi")
    sol = se3ocp.solve(p)
    p2, sol2 = pickle.loads(pickle.dumps(p)), pickle.loads(pickle.dumps(sol))
    assert sol2.cost == sol.cost and np.array_equal(sol2.controls, sol.controls) and sol2.result is sol.result
    assert dict(sol2.stats) == dict(sol.stats) and sol2.trace == sol.trace
    with pytest.raises(TypeError):
        sol2.stats["iterations"] = 0          # still read-only
    again = se3ocp.solve(p2)
    assert again.converged and abs(again.cost - sol.cost) <= 1e-12 * abs(sol.cost)
