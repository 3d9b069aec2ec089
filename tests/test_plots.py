"""Figures (problems/plots/) drawn from in-memory Solutions, without touching the backend.

Each figure is drawn from a small solve (N = 30) and checked by its artists: the methods named in
a legend, bound lines where the Problem carries bounds, shading where a bound is active, the zero
line of constraint margins, the banner of a failed run, and tick labels that do not overlap.
Bounds and constraints are checked on a simulated Solution of a Problem that carries them (the
direct controls clipped into the bounds), which needs no solver support for them.
"""
from __future__ import annotations

import subprocess
import sys

import matplotlib
import numpy as np
import pytest

import se3ocp
from se3ocp.problems import plots
from se3ocp.transcription.ocp import BoxBound, KeepIn, KeepOut, MaxAngularRate, MinRadius, NormBound, SmoothControl
from se3ocp.transcription.objectives import Effort
from support import ROOT, maneuver, slew_comparison

SMOOTH = {"maneuver", "attitude", "attitude_error", "control_norms", "force", "moment", "thrust_rtn",
          "orbital_elements", "velocity", "angular_velocity", "costates", "convergence",
          "continuous"}  # the continuous check (issue 26), on by default


def _close(figs):
    import matplotlib.pyplot as plt

    for f in figs.values():
        plt.close(f)


@pytest.fixture(autouse=True, scope="module")
def _close_figures():
    """The module leaves no pyplot figure open (they hold memory until closed); its fixtures hold
    the figures of several runs at once, more than pyplot's warning threshold of 20."""
    with matplotlib.rc_context({"figure.max_open_warning": 0}):
        yield
    import matplotlib.pyplot as plt

    plt.close("all")


@pytest.fixture(scope="module")
def both():
    res = se3ocp.solve(maneuver("e3", 30, "first_order"), "both")
    figs = se3ocp.plot(res)
    yield res, figs
    _close(figs)


@pytest.fixture(scope="module")
def bounded(both):
    """A simulation of E3's Problem with a norm bound on the force, a box bound on the moment and
    four path constraints, under the direct controls clipped into the bounds."""
    res, _ = both
    d = res.direct
    prob = d.problem
    bf = 0.6 * np.linalg.norm(d.u_f, axis=1).max()
    bm = 0.6 * np.abs(d.u_m).max(axis=0)
    U = d.controls.copy()
    U[:3] *= np.minimum(1.0, bf / np.linalg.norm(U[:3], axis=0))
    U[3:] = np.clip(U[3:], -bm[:, None], bm[:, None])
    cons = (KeepOut([1, 0, 0], [0, 1, 0], 40.0), MinRadius(0.98), MaxAngularRate(7.0), KeepIn([0, 0, 1], [0, 0, 1], 60.0))
    pb = prob.replace(control=SmoothControl(prob.control.W_f, prob.control.W_m, objective=Effort(), force_bound=NormBound(bf),
                                            moment_bound=BoxBound(bm)), constraints=cons)
    sim = se3ocp.simulate(pb, U)
    figs = se3ocp.plot(sim)
    yield sim, figs, bf, bm
    _close(figs)


@pytest.fixture(scope="module")
def slew():
    """A keep-out slew without a central body (and the force removed): the direct run of
    support.slew_comparison, beside the indirect method's not_applicable."""
    man, res = slew_comparison()
    figs = se3ocp.plot(res)
    yield res, figs
    _close(figs)


@pytest.fixture(scope="module")
def failed():
    res = se3ocp.solve(maneuver("e4", 30, None, "solver.direct.max_iter=2"))
    assert not res.converged and res.result is se3ocp.Result.max_iterations
    figs = se3ocp.plot(res)
    yield res, figs
    _close(figs)


def legend_texts(fig) -> set[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    return {t.get_text() for lg in legends for t in lg.get_texts()}


def by_gid(fig, gid):
    return [a for a in fig.findobj() if getattr(a, "get_gid", lambda: None)() == gid]


def held(line):
    """(edges, values) of a line drawn as steps held over intervals (drawstyle steps-pre: the first
    value repeated at the first edge)."""
    assert line.get_drawstyle() == "steps-pre", line.get_drawstyle()
    return np.asarray(line.get_xdata()), np.asarray(line.get_ydata())[1:]


def banner(fig):
    return [t for t in fig.texts if t.get_gid() == "failure-banner"]


def overlaps(boxes) -> bool:
    boxes = sorted(boxes, key=lambda b: b.x0)
    return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def assert_no_overlapping_ticks(name, fig):
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    for ax in fig.axes:
        if ax.name == "3d":
            continue
        for axis in (ax.xaxis, ax.yaxis):
            boxes = [t.get_window_extent(r) for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
            assert not overlaps(boxes), (name, [t.get_text() for t in axis.get_ticklabels()])


# ------------------------------------------------------------------------- every figure, both methods
def test_every_figure_is_drawn_with_both_methods_named(both):
    res, figs = both
    assert set(figs) == SMOOTH
    for name, fig in figs.items():
        texts = legend_texts(fig)
        assert any(t.startswith("direct") for t in texts) and any(t.startswith("indirect") for t in texts), (name, texts)
        assert fig._suptitle.get_text().startswith("e3_inclination_change:"), name
        assert "NOT CONVERGED" not in fig._suptitle.get_text() and banner(fig) == [], name
        for ax in fig.axes:  # every panel says what it shows
            assert ax.name == "3d" or (ax.get_xlabel() + ax.get_ylabel()).strip() != "", name
        assert fig.axes[-1].name == "3d" or fig.axes[-1].get_xlabel().strip() != "", name   # time, or iterations
        assert_no_overlapping_ticks(name, fig)


def test_maneuver_draws_orbits_paths_and_the_body_frame(both):
    res, figs = both
    fig = figs["maneuver"]
    texts = legend_texts(fig)
    assert {"central body", "initial orbit", "desired orbit", "desired position", "direct path", "indirect path",
            "body e1", "body e2", "body e3"} <= texts
    ax = fig.axes[0]
    path = next(ln for ln in ax.get_lines() if ln.get_label() == "direct path")
    np.testing.assert_allclose(np.array(path.get_data_3d()).T, res.direct.trajectory.x)
    # a body frame at 7 nodes: 7 axes of each colour
    for c in plots.COMP:
        assert sum(matplotlib.colors.same_color(ln.get_color(), c) for ln in ax.get_lines()) == 7
    assert len(fig.axes) == 1                                # an orbit-sized path: no zoom panel


def test_a_slew_gets_a_zoom_on_the_path():
    sim = se3ocp.simulate(maneuver("e3", 20, None, "horizon.T=0.02"))   # a fiftieth of an orbit: a slew's path
    fig = se3ocp.plot(sim, ("maneuver",))["maneuver"]
    assert len(fig.axes) == 2 and "zoom on the path" in fig.axes[1].get_title()
    lim = np.ptp(fig.axes[1].get_xlim())
    assert lim < 0.5 * np.ptp(fig.axes[0].get_xlim())       # the zoom is a zoom
    # the wide figure is scaled down on a page more than the others: its legend is not smaller than its tick labels
    size = min(t.get_fontsize() for t in fig.legends[0].get_texts())
    assert size >= max(t.get_fontsize() for t in fig.axes[0].get_xticklabels())
    _close({"m": fig})


def test_a_quantity_zero_throughout_has_one_tick_at_zero(slew):
    """A rotation about z: Ω₁ = Ω₂ = 0 throughout, shown as a line at 0 with one tick, not with
    ticks of ±0.00004 (precision the quantity does not have)."""
    res, figs = slew
    fig = figs["angular_velocity"]
    fig.canvas.draw()
    assert np.abs(res.direct.trajectory.Omega[:, :2]).max() < 1e-12
    for ax in fig.axes[:2]:
        assert [t.get_text() for t in ax.get_yticklabels() if t.get_text()] == ["0"], ax.get_ylabel()
    assert len([t for t in fig.axes[2].get_yticklabels() if t.get_text()]) >= 3


def test_without_a_central_body_no_orbit_panel(slew):
    """No central body: no orbit view (it was a lone dot), no orbital elements, no RTN thrust.  A
    slew (the body does not move) shows its frame at a few times side by side, with the keep-out
    direction; a body that moves gets one panel on its path."""
    res, figs = slew
    assert {"orbital_elements", "thrust_rtn"}.isdisjoint(figs)
    fig = figs["maneuver"]
    titles = [a.get_title() for a in fig.axes]
    assert len(fig.axes) == 7 and titles[0] == "t = 0" and titles[-1] == "t = 10", titles
    texts = legend_texts(fig)
    assert "central body" not in texts and not any("orbit" in t for t in texts | set(titles))
    assert "keep-out direction s (20° cone about it)" in texts
    assert "does not move" in fig._suptitle.get_text()
    anim = plots.Animation(res)                                     # the animation: the body at its own scale
    assert np.ptp(anim.fig.axes[0].get_xlim()) > 2 * plots._body_points(res.direct.problem)[1]
    p = res.direct.problem
    U = np.zeros((6, p.disc.n_controls(p.N)))
    U[0] = 1.0                                                      # a constant push along x: the body moves
    sim = se3ocp.simulate(p.replace(control=SmoothControl(p.control.W_f, p.control.W_m, objective=Effort())), U)
    fig = se3ocp.plot(sim, ("maneuver",))["maneuver"]
    assert len(fig.axes) == 1 and fig.axes[0].get_xlabel() == "x₁"
    assert {"simulate path", "body e1"} <= legend_texts(fig) and "central body" not in legend_texts(fig)
    _close({"m": fig})


def test_attitude_view_shows_the_keep_out_cone(slew):
    res, figs = slew
    fig = figs["attitude"]
    c = res.direct.problem.constraints[0]
    assert "keep-out cone of e1: 20° about s" in legend_texts(fig)
    ring = next(ln for ln in fig.axes[0].get_lines() if matplotlib.colors.same_color(ln.get_color(), plots.CONE["keep_out"])
                and len(ln.get_data_3d()[0]) > 10)
    pts = np.array(ring.get_data_3d()).T
    np.testing.assert_allclose(np.degrees(np.arccos(np.clip(pts @ c.direction, -1, 1))), 20.0, atol=1e-9)


def test_attitude_views_show_target_and_error(both):
    res, figs = both
    fig = figs["attitude"]
    assert {"target frame R_d", "body e1 path", "initial frame"} <= legend_texts(fig)
    fig = figs["attitude_error"]
    ang = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "direct"][0].get_ydata()
    assert ang[0] > 90 and ang[-1] < 1e-6                     # E3 starts ~180 deg off and ends on the target
    quats = [ln.get_ydata() for ln in fig.axes[1].get_lines()][:4]
    np.testing.assert_allclose(np.sum(np.square(quats), axis=0), 1.0, atol=1e-12)
    fig.canvas.draw()                                  # the quaternion spans [-1, 1]: its legend is beside, not on it
    r = fig.canvas.get_renderer()
    assert not fig.axes[1].get_legend().get_window_extent(r).overlaps(fig.axes[1].get_window_extent(r))


def test_rtn_and_orbital_elements_are_those_of_the_orbit(both):
    res, figs = both
    d = res.direct
    ax_r, ax_t, ax_n = figs["thrust_rtn"].axes
    comps = [held(next(ln for ln in ax.get_lines() if ln.get_label() == "direct"))[1] for ax in (ax_r, ax_t, ax_n)]
    np.testing.assert_allclose(np.linalg.norm(comps, axis=0), np.linalg.norm(d.u_f, axis=1), rtol=1e-12)
    # a plane change pushes along the orbit normal: the normal component dominates
    assert np.abs(comps[2]).max() > 3 * np.abs(comps[0]).max()
    fig = figs["orbital_elements"]
    r, i, e = (next(ln for ln in ax.get_lines() if ln.get_label() == "direct").get_ydata() for ax in fig.axes)
    np.testing.assert_allclose(r, np.linalg.norm(d.trajectory.x, axis=1))
    assert abs(i[0]) < 1e-6 and abs(i[-1] - 30.0) < 1e-3 and e[-1] < 1e-6   # 0 -> 30 deg, circular at the end
    targets = [[ln for ln in ax.get_lines() if ln.get_label() == "target"] for ax in fig.axes]
    assert abs(targets[1][0].get_ydata()[0] - 30.0) < 1e-9


def test_costates_of_both_methods(both):
    res, figs = both
    fig = figs["costates"]
    assert len(fig.axes) == 4
    for ax in fig.axes:
        assert len(ax.get_lines()) == 6                        # 3 components x 2 methods
    assert "direct (from multipliers)" in legend_texts(fig)


def test_convergence_draws_every_iteration(both):
    res, figs = both
    ax = figs["convergence"].axes[0]
    trials = next(ln for ln in ax.get_lines() if ln.get_label() == "indirect: all line-search trials")
    assert len(trials.get_ydata()) == len(res.indirect.history)
    assert ax.get_yscale() == "log" and "line-search trial" in ax.get_xlabel()


# ------------------------------------------------------------------------- units
def all_texts(fig) -> list[str]:
    return [t.get_text() for t in fig.findobj(matplotlib.text.Text) if t.get_text()]


def test_units_are_those_of_the_problem(both, slew):
    """Normalized orbit units (radii, orbital periods) only with a central body of GM = 4π²; a
    slew without one is labelled by dimension, never in periods or radii."""
    from se3ocp.problems.units import units

    _, figs = both
    assert figs["control_norms"].axes[-1].get_xlabel() == "time t (orbital periods)"
    assert "radii" in figs["maneuver"].axes[0].get_xlabel()
    assert "(mass·radii/period²)" in figs["force"]._suptitle.get_text()
    res, figs = slew
    assert units(res.direct.problem).normalized is False
    for name, fig in figs.items():
        texts = all_texts(fig)
        assert not [t for t in texts if "period" in t or "radii" in t], (name, texts)
        assert fig.axes[-1].get_xlabel() in ("time t", "time t_k of step k", "") or fig.axes[-1].name == "3d" \
            or name == "convergence", (name, fig.axes[-1].get_xlabel())
    assert figs["moment"]._suptitle.get_text().endswith("(mass·length²/time²)")
    anim = plots.Animation(res)
    anim.frame(1.0)
    assert anim.clock.get_text() == "t = 1.000"
    # a central body of another GM (km and s, say): not the normalized units either
    from types import SimpleNamespace as NS

    assert units(NS(model=NS(mu=398600.4418))).normalized is False
    assert units(NS(model=NS(mu=4 * np.pi**2))).normalized is True


# ------------------------------------------------------------------------- a control removed by a norm bound of 0
def test_a_removed_control_is_absent_not_at_its_bound(both, slew):
    from se3ocp.transcription.results.solution import figures_of_merit

    res, figs = slew
    d = res.direct
    assert d.problem.control.removed == (True, False)
    assert "force_time_at_bound" not in figures_of_merit(d) and "force_time_at_bound" not in d.summary()
    assert {"force", "thrust_rtn", "orbital_elements", "velocity"}.isdisjoint(figs)   # no force, no central body
    assert {"maneuver", "attitude", "control_norms", "moment", "constraints"} <= set(figs)
    fig = figs["control_norms"]
    assert len(fig.axes) == 1 and "u_m" in fig.axes[0].get_ylabel()
    assert not by_gid(fig, "bound-active") and "the force is removed" in fig._suptitle.get_text()
    anim = plots.Animation(res)
    texts = {t.get_text() for lg in anim.fig.legends + [a.get_legend() for a in anim.fig.axes if a.get_legend()]
             for t in lg.get_texts()}
    assert "thrust u_f" not in texts and not any(t.startswith("|u_f|") for t in texts)
    # the moment removed instead: no moment figure, one panel of |u_f|
    e3, _ = both
    p = e3.direct.problem
    U = e3.direct.controls.copy()
    U[3:] = 0.0
    sim = se3ocp.simulate(p.replace(control=SmoothControl(p.control.W_f, p.control.W_m, moment_bound=NormBound(0.0), objective=Effort())), U)
    assert "moment_time_at_bound" not in figures_of_merit(sim)
    figs = se3ocp.plot(sim)
    assert "moment" not in figs and {"force", "thrust_rtn", "velocity"} <= set(figs)
    assert len(figs["control_norms"].axes) == 1 and "u_f" in figs["control_norms"].axes[0].get_ylabel()
    _close(figs)


# ------------------------------------------------------------------------- controls as the scheme applies them
def test_per_step_controls_are_steps_and_the_shaded_time_is_the_time_at_bound(both, bounded, slew):
    """First order: u_{k+1} is held over the step [t_k, t_{k+1}], so it is drawn as a step (a
    bang-bang switch is a jump, not a ramp) and the shading where it is at its bound covers exactly
    figures_of_merit's time at the bound.  LGVI node controls are node values joined by lines, and
    their shading covers the node cells (the trapezoidal weights)."""
    res, figs = both
    d = res.direct
    line = next(ln for ln in figs["force"].axes[0].get_lines() if ln.get_label() == "direct")
    edges, vals = held(line)
    np.testing.assert_array_equal(edges, d.trajectory.t)
    np.testing.assert_array_equal(vals, d.u_f[:, 0])
    sim, bfigs, _, _ = bounded
    assert sim.scheme == "first_order"
    fom = sim.summary()
    for ax, key in zip(bfigs["control_norms"].axes, ("force_time_at_bound", "moment_time_at_bound")):
        spans = by_gid(ax, "bound-active")
        width = sum(p.get_width() for p in spans)
        assert spans and width == pytest.approx(fom[key], rel=1e-12), key
        assert all(np.isclose(p.get_x(), sim.trajectory.t).any() for p in spans)     # cells start at nodes
    res, sfigs = slew
    s = res.direct
    assert s.scheme == "lgvi"
    ln = next(ln for ln in sfigs["moment"].axes[2].get_lines() if ln.get_label() == "direct")
    assert ln.get_drawstyle() == "default"
    np.testing.assert_array_equal(ln.get_xdata(), s.control_times)


# ------------------------------------------------------------------------- bounds and constraints
def test_norm_bound_line_and_active_shading(bounded):
    sim, figs, bf, bm = bounded
    fig = figs["control_norms"]
    ax_f, ax_m = fig.axes
    lines = [ln for ln in ax_f.get_lines() if ln.get_gid() == "bound-line"]
    assert len(lines) == 1 and np.allclose(lines[0].get_ydata(), bf)
    assert by_gid(ax_f, "bound-active") and by_gid(ax_m, "bound-active")      # the switching structure
    assert any(t.startswith("simulate at bound (") for t in legend_texts(fig))
    assert any("box bound" in t for t in legend_texts(fig))
    assert any(t.startswith("simulate: a component at its bound (") for t in legend_texts(fig))
    corner = [ln for ln in ax_m.get_lines() if ln.get_label().startswith("|b| = ")]       # a box's corner
    assert len(corner) == 1 and np.allclose(corner[0].get_ydata(), np.linalg.norm(bm))
    assert sim.summary()["force_time_at_bound"] > 0 and sim.summary()["moment_time_at_bound"] > 0


def test_box_bound_lines_per_component(bounded):
    sim, figs, bf, bm = bounded
    for i, ax in enumerate(figs["moment"].axes):
        ys = sorted(float(ln.get_ydata()[0]) for ln in ax.get_lines() if ln.get_gid() == "bound-line")
        np.testing.assert_allclose(ys, [-bm[i], bm[i]])
        assert by_gid(ax, "bound-active"), i
    # a norm bound has no per-component limits
    assert not any(ln.get_gid() == "bound-line" for ax in figs["force"].axes for ln in ax.get_lines())


def test_constraint_margins_with_zero_line_and_violations(bounded):
    sim, figs, _, _ = bounded
    fig = figs["constraints"]
    cons = sim.problem.constraints
    assert len(fig.axes) == len(cons)
    for ax, c in zip(fig.axes, cons):
        assert [ln for ln in ax.get_lines() if ln.get_gid() == "zero-line"], c.kind
        mg = next(ln for ln in ax.get_lines() if ln.get_label() == "simulate").get_ydata()
        np.testing.assert_allclose(mg, c.margin(sim.trajectory))
        assert se3ocp.problems.units.units(sim.problem).unit(c.dimension) in ax.get_ylabel()
        assert bool(by_gid(ax, "bound-active")) == bool((mg < 0).any()), c.kind   # violations shaded
    assert "min radius 0.98" in legend_texts(figs["orbital_elements"])
    rate = [ln for ln in figs["angular_velocity"].axes[3].get_lines() if ln.get_gid() == "bound-line"]
    assert len(rate) == 1 and np.allclose(rate[0].get_ydata(), 7.0)
    for name, f in figs.items():
        assert_no_overlapping_ticks(name, f)


# ------------------------------------------------------------------------- failure is never drawn like success
def test_failed_run_is_marked(failed):
    res, figs = failed
    assert {"maneuver", "convergence", "force"} <= set(figs)
    assert figs["convergence"].axes[0].get_xlabel() == "iteration"          # IPOPT alone: no line-search trials
    for name, fig in figs.items():
        b = banner(fig)
        assert len(b) == 1 and "direct: max_iterations" in b[0].get_text(), name
        assert "NOT CONVERGED" in fig._suptitle.get_text(), name
        assert any("FAILED: max_iterations" in t for t in legend_texts(fig)), name
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        assert not fig._suptitle.get_window_extent(r).overlaps(b[0].get_window_extent(r)), name


# ------------------------------------------------------------------------- other kinds of run
def test_impulsive_figures_skip_controls():
    figs = se3ocp.plot(se3ocp.solve(maneuver("e1", 40)))
    assert set(figs) == {"maneuver", "attitude", "attitude_error", "orbital_elements", "velocity", "angular_velocity",
                         "convergence"}
    assert "impulse direction" in legend_texts(figs["maneuver"])
    assert {"before impulse", "after impulse"} <= legend_texts(figs["velocity"])
    _close(figs)


def test_simulation_without_target_or_controls():
    figs = se3ocp.plot(se3ocp.simulate(maneuver("free", 200, None, "horizon.T=0.2")))
    assert set(figs) == {"maneuver", "attitude", "attitude_error", "orbital_elements", "velocity", "angular_velocity"}
    assert "rotation from the initial attitude" in figs["attitude_error"]._suptitle.get_text()
    _close(figs)
    with pytest.raises(ValueError, match="unknown figures"):
        se3ocp.plot(se3ocp.simulate(maneuver("free", 20, None, "horizon.T=0.02")), ("bogus",))


def test_redrawing_a_results_directory_removes_figures_that_no_longer_apply(tmp_path):
    """A figure drawn by an earlier version for a run it does not apply to (a force figure of a
    slew whose force is removed) is deleted when the directory's figures are redrawn."""
    from se3ocp.problems import store

    man, res = slew_comparison()
    store.write_run(tmp_path, man, res)
    for stale in ("fig_force.png", "fig_force.pdf", "fig_velocity.png", "fig_orbital_elements.png"):
        (tmp_path / stale).write_bytes(b"stale")
    written = plots.draw_all(tmp_path)
    assert {p.name for p in written} >= {"fig_maneuver.png", "fig_moment.pdf"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(("fig_force", "fig_velocity", "fig_orbital"))]


# ------------------------------------------------------------------------- animation
def test_animation_names_both_methods_and_moves(both, tmp_path):
    from PIL import Image

    res, _ = both
    anim = plots.Animation(res)
    texts = {t.get_text() for lg in anim.fig.legends for t in lg.get_texts()}
    assert {"direct", "indirect", "desired orbit", "thrust u_f", "body e1"} <= texts
    assert "direct (solid)" in anim.fig._suptitle.get_text() and "indirect (dashed)" in anim.fig._suptitle.get_text()
    a, b = anim.frame(0.0), anim.frame(res.direct.T)
    assert a.shape == b.shape and np.abs(a.astype(int) - b.astype(int)).sum() > 0
    p = plots.write_animation(res, tmp_path / "m.gif", frames=5, fps=10)
    with Image.open(p) as im:
        assert im.n_frames == 5 and im.info["duration"] == 100
    with pytest.raises(ValueError):
        plots.write_animation(res, tmp_path / "x.gif", frames=1)


# ------------------------------------------------------------------------- the user's backend
def test_importing_and_plotting_keep_the_users_backend():
    """A notebook sets its backend before importing the package: importing se3ocp and drawing a
    figure must leave it as it was (the CLI chooses Agg itself, not the library)."""
    code = ("import matplotlib; matplotlib.use('svg'); import se3ocp, se3ocp.problems.plots; "
            "m = se3ocp.load('configs/e3_inclination_change.yaml', ['horizon.N=10']); "
            "se3ocp.plot(se3ocp.simulate(m)); print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=str(ROOT))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "svg"


def test_plots_package_never_chooses_a_backend():
    files = sorted((ROOT / "problems" / "plots").glob("*.py"))
    assert len(files) >= 8
    for f in files:
        src = f.read_text()
        assert "matplotlib.use(" not in src and "plt.switch_backend" not in src, f.name


def test_readme_shows_figures_that_exist():
    """Every figure the README's table shows is in docs/figures (scripts/readme_figures.py writes them)."""
    import re

    paths = re.findall(r"\]\((docs/figures/[^)]+\.png)\)", (ROOT / "README.md").read_text())
    assert len(paths) >= 15
    assert [p for p in paths if not (ROOT / p).is_file()] == []
