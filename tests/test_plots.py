"""Figures (problems/plots.py) drawn from in-memory Solutions, without touching the backend."""
from __future__ import annotations

import subprocess
import sys

import pytest

import se3ocp
from support import maneuver

FIGS = {"maneuver", "velocity", "angular_velocity", "force", "moment", "convergence"}


@pytest.fixture(scope="module")
def figures():
    import matplotlib.pyplot as plt

    res = se3ocp.solve(maneuver("e3", 30, "first_order"), "both")
    figs = se3ocp.plot(res)
    yield res, figs
    for f in figs.values():
        plt.close(f)


def test_every_figure_is_drawn_with_both_methods(figures):
    res, figs = figures
    assert set(figs) == FIGS
    for name, fig in figs.items():
        lines = [ln for ax in fig.axes for ln in ax.get_lines()]
        labels = {ln.get_label() for ln in lines}
        assert lines, name
        if name in ("velocity", "angular_velocity", "force", "moment"):
            assert {"direct", "indirect"} <= labels, (name, labels)
        if name == "maneuver":
            assert {"direct path", "indirect path"} <= labels
        assert all(ax.get_xlabel() or ax.name == "3d" or ax.get_ylabel() for ax in fig.axes), name


def test_impulsive_figures_skip_controls():
    import matplotlib.pyplot as plt

    figs = se3ocp.plot(se3ocp.solve(maneuver("e1", 40)))
    assert "force" not in figs and {"maneuver", "velocity", "angular_velocity", "convergence"} <= set(figs)
    for f in figs.values():
        plt.close(f)


def test_importing_and_plotting_keep_the_users_backend():
    """A notebook sets its backend before importing the package: importing se3ocp and drawing a
    figure must leave it as it was (the CLI chooses Agg itself, not the library)."""
    code = ("import matplotlib; matplotlib.use('svg'); import se3ocp, se3ocp.problems.plots; "
            "m = se3ocp.load('configs/e3_inclination_change.yaml', ['horizon.N=10']); "
            "se3ocp.plot(se3ocp.simulate(m)); print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         cwd=str(__import__("support").ROOT))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "svg"
