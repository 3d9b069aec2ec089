"""Figures and report.html in the units a maneuver names (problems/units.py): the LEO example in km,
s, kg is drawn with thrust in N and torque in N·m (the file's kN and kN·km converted), its time in s,
its 10 km raise not flattened by the Earth's radius; nothing tiny is drawn as zero by an absolute
cut-off; the report says which units it uses."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import se3ocp  # noqa: E402
from se3ocp.problems.plots.style import _time_axes  # noqa: E402
from se3ocp.problems.units import units  # noqa: E402

from support import CONFIGS  # noqa: E402


@pytest.fixture(scope="module")
def leo():
    """The LEO example at N = 60 under a smooth control of about 0.5 N and 1e-4 N·m (file units kN,
    kN·km), simulated: the figures' units, not the optimum, are under test."""
    man = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=60", "discretization=lgvi"])
    p = man.problem
    n = p.disc.n_controls(p.N)
    s = np.linspace(0, 2 * np.pi, n)
    U = np.vstack([5e-4 * np.vstack([np.cos(s), np.sin(s), 0 * s]), 1e-10 * np.vstack([np.sin(s), 0 * s, 1 + 0 * s])])
    sol = se3ocp.simulate(man, U)
    assert sol.converged
    yield man, sol, se3ocp.plot(sol)
    plt.close("all")


def ydata(ax) -> np.ndarray:
    return np.concatenate([np.asarray(ln.get_ydata(), float) for ln in ax.get_lines() if len(ln.get_ydata()) > 1])


def test_leo_figures_in_km_s_newtons(leo):
    man, sol, figs = leo
    un = units(sol.problem)
    assert un.system is not None and un.time_label == "time t (s)"
    norms = figs["control_norms"].axes
    assert norms[0].get_ylabel().endswith("(N)") and norms[1].get_ylabel().endswith("(N·m)")
    assert norms[-1].get_xlabel() == "time t (s)"
    f = ydata(norms[0])
    assert np.max(f) == pytest.approx(1e3 * np.linalg.norm(sol.u_f, axis=1).max(), rel=1e-12)   # kN drawn in N
    m = ydata(norms[1])
    assert np.max(m) == pytest.approx(1e6 * np.linalg.norm(sol.u_m, axis=1).max(), rel=1e-12)   # kN·km in N·m
    assert "(N)" in figs["force"]._suptitle.get_text() and "(N·m)" in figs["moment"]._suptitle.get_text()
    lo, hi = figs["moment"].axes[0].get_ylim()
    assert (lo, hi) != (-1.0, 1.0) and hi > 5e-5       # 1e-4 N·m is drawn, not a flat zero


def test_radius_axis_not_stretched_to_the_central_body(leo):
    man, sol, figs = leo
    ax = figs["orbital_elements"].axes[0]
    r = np.linalg.norm(sol.trajectory.x, axis=1)
    lo, hi = ax.get_ylim()
    assert lo > r.min() - (r.max() - r.min()) and hi < r.max() + (r.max() - r.min())
    assert ax.get_ylabel() == "radius |x| (km)"
    labels = [t.get_text() for t in figs["orbital_elements"].legends[0].get_texts()]
    assert any(t.startswith("min radius 6378.14") and "below the axis" in t for t in labels), labels


def test_tiny_values_are_drawn_not_zeroed():
    """The plots' zero test is relative to the figure: 1.5e-10 against 1.5e-10 is a value; 1e-17
    against 1 (round-off beside a real signal) is drawn as zero."""
    fig, axs = plt.subplots(2)
    axs[0].plot([0, 1, 2], [1.0e-10, 1.5e-10, 1.2e-10])
    axs[1].plot([0, 1, 2], [0.5e-10, 1.0e-10, 0.7e-10])
    _time_axes(axs, None)
    assert axs[0].get_ylim() != (-1.0, 1.0) and axs[0].get_ylim()[1] >= 1.5e-10
    fig, axs = plt.subplots(2)
    axs[0].plot([0, 1, 2], [1.0, 2.0, 3.0])
    axs[1].plot([0, 1, 2], [1e-17, -2e-17, 0.0])
    _time_axes(axs, None)
    assert axs[1].get_ylim() == (-1.0, 1.0) and list(axs[1].get_yticks()) == [0.0]
    plt.close("all")


def test_report_names_the_units(leo):
    from se3ocp.problems.report import _bounds, _horizon, merit_rows

    man, sol, _ = leo
    un = units(sol.problem)
    assert "lengths in km" in un.summary and "forces shown in N" in un.summary
    assert _horizon(sol.problem) == "T = 5560 s"
    rows = {r["label"]: r for r in merit_rows({"simulate": sol})}
    peak = rows["peak |u_f|"]
    assert peak["unit"] == "N" and float(peak["cells"][0]["text"]) == pytest.approx(
        1e3 * np.linalg.norm(sol.u_f, axis=1).max(), rel=1e-5)
    dv = rows["Δv = Σ ω |u_f| / m"]       # a table's velocity in m/s (issue 44: 4.497 m/s, not 0.00449749 km/s)
    assert dv["unit"] == "m/s" and float(dv["cells"][0]["text"]) == pytest.approx(1e3 * sol.delta_v, rel=1e-5)
    bounded = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=10", "control.bounds={force: {norm: 1.0e-3}}"])
    assert _bounds(bounded.problem) == ["force: |u| ≤ 1 N"]
    other = units(se3ocp.load(CONFIGS / "e3_inclination_change.yaml", ["model.mu=39.0"]).problem)
    assert "a central body of GM = 39" in other.summary and "no central body" not in other.summary


def test_a_refined_solution_keeps_the_files_units():
    """A solve refined to a path tolerance returns the Solution of another Problem object (its mesh's) than the file's;
    its margins and misses keep the file's units (N m, N m s in an SI file), not the bare dimension."""
    man = se3ocp.load(CONFIGS / "slew_keep_out_effort.yaml", ["horizon.N=20"])
    sol = se3ocp.solve(man, constraints_tolerance=1e-5)
    assert sol.problem is not man.problem and not sol.problem.uniform
    for q, want in (("moment", "N·m"), ("angular_impulse", "N·m·s")):
        assert units(sol.problem).unit(q) == units(man.problem).unit(q) == want


def test_the_units_travel_with_every_problem_derived_from_the_file():
    """A loaded km file's Problem carries its units, and so does every Problem derived from it by replace (a refined
    level's, a strategy's); a Problem built in Python without them has none."""
    p = se3ocp.load(CONFIGS / "leo_body_engine.yaml").problem
    for q in (p, p.replace(N=10), p.replace(N=10).replace(T=2.0 * p.T)):
        assert units(q).system is not None and units(q).system.length == "km" and units(q).unit("length") == "km"
    bare = se3ocp.load(CONFIGS / "e3_inclination_change.yaml").problem
    assert bare.units is None and units(bare).normalized
