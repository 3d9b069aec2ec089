"""The 3-D figures: the maneuver (path, orbits, body frames; a filmstrip for a slew without a
central body) and the attitude on the unit sphere."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from ...transcription.ocp import KeepIn, KeepOut, Problem, TargetOrbit, TargetRendezvous, TargetState
from ...transcription.results.solution import Solution
from ..units import units
from .orbits import _circle, _orbit_ellipse
from .runs import Run
from .style import COMP, CONE, THRUST, W, _finish
from .targets import _target_orbit, _target_R, _vec


def _body_points(problem: Problem) -> tuple[np.ndarray, float]:
    """Body-fixed points to draw (the model's markers, or the tips of its principal axes) and a
    characteristic size of the body (the largest point distance)."""
    pts = problem.model.markers
    if not len(pts):
        J = problem.model.inertia
        size = float(np.sqrt(np.trace(J) / problem.model.mass))
        pts = size * np.vstack([np.eye(3), -np.eye(3)])
    return pts, float(np.linalg.norm(pts, axis=1).max())


def _cube(ax, lim, center=(0.0, 0.0, 0.0)):
    c = np.asarray(center, float)
    ax.set_xlim(c[0] - lim, c[0] + lim)
    ax.set_ylim(c[1] - lim, c[1] + lim)
    ax.set_zlim(c[2] - lim, c[2] + lim)
    ax.set_box_aspect((1, 1, 1))
    for a in (ax.xaxis, ax.yaxis, ax.zaxis):
        a.set_major_locator(MaxNLocator(nbins=4))


def _triad(ax, origin, R, length, lw=1.6, alpha=1.0, ls="-", zorder=3):
    for i in range(3):
        tip = origin + length * R[:, i]
        ax.plot(*np.vstack([origin, tip]).T, color=COMP[i], lw=lw, alpha=alpha, ls=ls, zorder=zorder)


def _bodies(ax, problem: Problem, sol: Solution, L: float, n_bodies: int):
    """The body frame (and the dumbbell's rod) at n_bodies nodes of sol, axes of length L."""
    pts, size = _body_points(problem)
    X, R = sol.trajectory.x, sol.trajectory.R
    for k in np.unique(np.linspace(0, sol.N, n_bodies).round().astype(int)):
        if np.all(np.isfinite(R[k])) and np.all(np.isfinite(X[k])):
            if len(problem.model.markers):
                ends = X[k] + (L / size) * problem.model.markers @ R[k].T
                ax.plot(*ends.T, color="0.35", lw=3, alpha=0.6, solid_capstyle="round", zorder=2)
            _triad(ax, X[k], R[k], L, lw=1.5, zorder=3)


def _paths(ax, runs: list[Run], label=True):
    for run in runs:
        x = run.sol.trajectory.x
        ax.plot(*x.T, color=run.color, ls=run.ls, lw=2.2, label=f"{run.name} path" if label else None, zorder=5)
        ax.scatter(*x[0], marker="o", s=30, color=run.color, zorder=6)
        ax.scatter(*x[-1], marker="s", s=30, color=run.color, zorder=6)


def fig_maneuver(runs: list[Run], problem: Problem, *, n_bodies: int = 7):
    """3-D maneuver: central body, initial and desired orbits, both paths (start o, end ■), the body
    frame (e1 red, e2 green, e3 blue; the dumbbell's rod in grey) at a few nodes, drawn large
    enough to see its rotation; impulse directions for impulsive maneuvers.  When the path is
    short against the orbit (a slew), a second panel zooms on it with the body frame drawn at the
    path's scale.  Without a central body there is no orbit to show: see :func:`_maneuver_free`."""
    model = problem.model
    if not model.mu:
        return _maneuver_free(runs, problem, n_bodies)
    _, size = _body_points(problem)
    first = runs[0].sol
    paths = np.vstack([r.sol.trajectory.x for r in runs])
    paths = paths[np.all(np.isfinite(paths), axis=1)]
    allx = np.vstack([paths, np.zeros((1, 3))])
    v0 = first.trajectory.v[0] if first.impulses is None else \
        (first.trajectory.gamma[0] - first.impulses["dgamma0"]) / model.mass
    orb = _orbit_ellipse(first.trajectory.x[0], v0, model.mu)
    if orb is not None:
        allx = np.vstack([allx, orb])
    target = _target_orbit(problem)
    if target is not None:
        allx = np.vstack([allx, target])
    lim = max(np.abs(allx).max() * 1.05, 1e-9)  # the view is centred on the central body
    extent = float(np.ptp(paths, axis=0).max()) if len(paths) else 0.0
    zoom = extent < 0.3 * lim
    fig = plt.figure(figsize=(W * 1.6 if zoom else W, 6.4), layout="constrained")
    ax = fig.add_subplot(1, 2 if zoom else 1, 1, projection="3d")
    ax.computed_zorder = False  # paths above the body frames, whatever the view's depth order
    ax.scatter([0], [0], [0], s=160, color="#3b6ea8", label="central body", zorder=1)
    if orb is not None:
        ax.plot(*orb.T, color="0.55", lw=1, ls=":", label="initial orbit", zorder=1)
    if target is not None:
        ax.plot(*target.T, color="k", lw=1, ls="--", label="desired orbit", zorder=1)
    if _has_target_position(problem):
        ax.scatter(*problem.terminal.X[0:3], marker="x", s=70, color="k", label="desired position", zorder=6)
    _rendezvous_marks(ax, problem, first)
    L = 0.14 * lim  # the body frame at a seventh of the view, so that its rotation shows at orbit scale
    if not zoom:
        _bodies(ax, problem, first, L, n_bodies)
    _paths(ax, runs)
    if first.impulses is not None:
        _impulse_arrows(ax, first, 0.3 * lim)
    _cube(ax, lim, np.zeros(3))
    un = units(problem)
    for a, lab in ((ax.set_xlabel, "x₁"), (ax.set_ylabel, "x₂"), (ax.set_zlabel, "x₃")):
        a(un.label(lab, "length"))
    what = f"maneuver (body frame ×{L / size:.2g})"
    if zoom:
        ax.set_title("orbit", fontsize=10)
        _zoom_on_path(fig.add_subplot(1, 2, 2, projection="3d"), runs, problem, paths, lim, n_bodies)
        what = "maneuver"
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color=c, lw=1.5) for c in COMP]
    labels += [f"body e{i + 1}" for i in range(3)]
    handles.append(Line2D([], [], color="0.3", marker="o", ls="", ms=5))
    labels.append("start (o), end (■)")
    fig.legend(handles, labels, loc="outside lower center", ncols=5 if zoom else 3, fontsize=10 if zoom else 8.5,
               frameon=False)  # the wide figure is shown wider: the same size on the page
    return _finish(fig, runs, problem, what)


def _rendezvous_marks(ax, problem: Problem, sol: Solution) -> None:
    """A rendezvous target where it is at t = 0 (triangle) and at the solution's final time (x)."""
    if isinstance(problem.terminal, TargetRendezvous) and np.isfinite(sol.trajectory.t[-1]):
        tgt, mu = problem.terminal, problem.model.mu
        ax.scatter(*tgt.point(0.0, mu)[0], marker="^", s=50, color="k", label="target at t = 0", zorder=6)
        ax.scatter(*tgt.point(float(sol.trajectory.t[-1]), mu)[0], marker="x", s=70, color="k",
                   label="target at arrival", zorder=6)


def _has_target_position(problem: Problem) -> bool:
    return isinstance(problem.terminal, TargetState) and "position" in problem.terminal.fixed


def _impulse_arrows(ax, sol: Solution, length: float) -> None:
    """The directions of the initial and final impulses, arrows of the given length at the path's ends."""
    X = sol.trajectory.x
    for k, key in ((0, "dgamma0"), (-1, "dgammaN")):
        d = np.asarray(sol.impulses[key], float)
        n = np.linalg.norm(d)
        if n > 0:
            ax.quiver(*X[k], *(length * d / n), color=THRUST, arrow_length_ratio=0.25, lw=2, zorder=7)
    ax.plot([], [], color=THRUST, lw=2, label="impulse direction")


def _zoom_on_path(az, runs: list[Run], problem: Problem, paths: np.ndarray, lim: float, n_bodies: int) -> None:
    """The second panel of :func:`fig_maneuver` for a path short against the orbit: the paths
    (finite points ``paths``) with the body frame at their own scale; ``lim`` is the orbit view's."""
    _, size = _body_points(problem)
    first = runs[0].sol
    az.computed_zorder = False
    extent = float(np.ptp(paths, axis=0).max()) if len(paths) else 0.0
    c = 0.5 * (paths.max(0) + paths.min(0)) if len(paths) else first.trajectory.x[0]
    lz = max(0.65 * extent, 1e-3 * lim, 2.0 * size)
    Lz = 0.3 * lz
    _bodies(az, problem, first, Lz, n_bodies)
    _paths(az, runs, label=False)
    if _has_target_position(problem):
        az.scatter(*problem.terminal.X[0:3], marker="x", s=70, color="k", zorder=6)
    _cube(az, lz, c)
    az.set_xlabel("x₁")
    az.set_ylabel("x₂")
    az.set_zlabel("x₃")
    un = units(problem)
    az.set_title(f"zoom on the path: ±{lz:.2g}{' ' + un.unit('length') if un.normalized or un.system else ''}, "
                 f"body frame ×{Lz / size:.2g}", fontsize=10)


def _maneuver_free(runs: list[Run], problem: Problem, n_bodies: int):
    """The maneuver without a central body: one panel on the path, the body frame at n_bodies
    nodes.  When the body hardly moves (a slew: the path shorter than the body), the frames are laid
    out left to right in time order (a filmstrip; positions on that axis are not positions) with
    their times, and with the direction of each cone constraint (keep-out, keep-in) at every frame."""
    _, size = _body_points(problem)
    first = runs[0].sol
    paths = np.vstack([r.sol.trajectory.x for r in runs])
    paths = paths[np.all(np.isfinite(paths), axis=1)]
    extent = float(np.ptp(paths, axis=0).max()) if len(paths) else 0.0
    slew = extent < size
    fig = plt.figure(figsize=(W * 1.6, 2.7) if slew else (W, 6.4), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    ax.computed_zorder = False
    un = units(problem)
    handles, labels = [], []
    if not slew:  # the body moves: its path, with the body frame at the path's scale
        c = 0.5 * (paths.max(0) + paths.min(0))
        lz = 0.6 * extent
        L = 0.25 * lz
        _bodies(ax, problem, first, L, n_bodies)
        _paths(ax, runs)
        if _has_target_position(problem):
            ax.scatter(*problem.terminal.X[0:3], marker="x", s=70, color="k", label="desired position", zorder=6)
        _cube(ax, lz, c)
        for a, lab in ((ax.set_xlabel, "x₁"), (ax.set_ylabel, "x₂"), (ax.set_zlabel, "x₃")):
            a(un.label(lab, "length"))
        what = f"maneuver (no central body; body frame ×{L / size:.2g})"
        handles, labels = ax.get_legend_handles_labels()
        handles.append(Line2D([], [], color="0.3", marker="o", ls="", ms=5))
        labels.append("start (o), end (■)")
    else:  # a slew: the attitude at a few times, side by side
        ks = np.unique(np.linspace(0, first.N, n_bodies).round().astype(int))
        cones = [c for c in problem.constraints if isinstance(c, (KeepOut, KeepIn)) and not c.moving]
        for j, k in enumerate(ks):
            a = ax if j == 0 else fig.add_subplot(1, len(ks), j + 1, projection="3d")
            if j == 0:
                a.set_subplotspec(fig.add_gridspec(1, len(ks))[0, 0])
            a.computed_zorder = False
            _triad(a, np.zeros(3), np.eye(3), 1.0, lw=0.8, alpha=0.3, zorder=1)   # the inertial axes, faint
            for c in cones:
                a.plot(*np.vstack([np.zeros(3), 1.2 * c.direction]).T, color=CONE[c.kind], ls=":", lw=1.8, zorder=2)
            for run in runs:
                R = run.sol.trajectory.R
                kk = min(int(np.searchsorted(run.t, first.trajectory.t[k])), len(R) - 1)
                if np.all(np.isfinite(R[kk])):
                    _triad(a, np.zeros(3), R[kk], 1.0, lw=2.2, ls=run.ls, zorder=3)
            _cube(a, 1.0)
            a.set_box_aspect((1, 1, 1), zoom=1.45)
            a.set_proj_type("ortho")
            a.view_init(elev=20, azim=-60)
            a.set_axis_off()
            a.set_title(f"t = {first.trajectory.t[k]:.3g}", fontsize=10, y=0.98)
        handles.append(Line2D([], [], color="0.3", lw=0.8, alpha=0.4))
        labels.append("inertial axes")
        for c in cones:
            handles.append(Line2D([], [], color=CONE[c.kind], ls=":", lw=1.8))
            labels.append(f"{c.kind.replace('_', '-')} direction s ({c.angle_deg:g}° cone about it)")
        handles += [Line2D([], [], color="0.3", ls=r.ls, lw=2.2) for r in runs]
        labels += [f"{r.name}: body frame" for r in runs]
        what = f"maneuver: the body does not move; its frame at {len(ks)} times"
    handles += [Line2D([], [], color=c, lw=1.8) for c in COMP]
    labels += [f"body e{i + 1}" for i in range(3)]
    fig.legend(handles, labels, loc="outside lower center", ncols=min(4, len(labels)), fontsize=9, frameon=False)
    return _finish(fig, runs, problem, what)


def _cones(ax, problem: Problem, runs: list[Run] | None = None) -> list:
    """Draw each cone constraint (keep-out, keep-in) on the unit sphere of a 3-D axes: its boundary
    about its direction s (dotted); a moving direction (nadir, velocity) as its path s(t) along the first
    run (dotted) with the cone's boundary at its start and end (not drawn without ``runs``); returns the
    cones drawn."""
    cones = [c for c in problem.constraints if isinstance(c, (KeepOut, KeepIn)) and (runs or not c.moving)]
    for c in cones:
        th = np.radians(c.angle_deg)
        if c.moving:
            d = c.directions(runs[0].sol.trajectory)
            ax.plot(*d.T, color=CONE[c.kind], ls=":", lw=1.8, zorder=2)
            for s in (d[0], d[-1]):
                if np.all(np.isfinite(s)):
                    ax.plot(*(np.cos(th) * s + _circle(np.sin(th), s, 120)).T, color=CONE[c.kind], lw=1.2, zorder=2)
            continue
        ring = np.cos(th) * c.direction + _circle(np.sin(th), c.direction, 120)
        ax.plot(*ring.T, color=CONE[c.kind], lw=1.6, zorder=2)
        ax.plot(*np.vstack([np.zeros(3), 1.15 * c.direction]).T, color=CONE[c.kind], ls=":", lw=1.4, zorder=2)
    return cones


def fig_attitude(runs: list[Run], problem: Problem, *, n_marks: int = 9):
    """The attitude alone, on the unit sphere: the paths of the body axes R(t)e_i (inertial frame),
    the initial frame (thin), the final body frame of each method and the target frame (black,
    dashed; for an orbit target the orbit normal the body axis must point along)."""
    fig = plt.figure(figsize=(W, 6.4), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    ax.computed_zorder = False
    u, v = np.mgrid[0:2 * np.pi:25j, 0:np.pi:13j]
    ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", lw=0.4, zorder=0)
    R0 = runs[0].sol.trajectory.R[0]
    _triad(ax, np.zeros(3), R0, 1.0, lw=1.0, alpha=0.45, zorder=1)
    handles = [Line2D([], [], color=c, lw=1.6, label=f"body e{i + 1} path") for i, c in enumerate(COMP)]
    handles.append(Line2D([], [], color="0.5", lw=1.0, alpha=0.6, label="initial frame"))
    for run in runs:
        R = run.sol.trajectory.R
        ok = np.all(np.isfinite(R), axis=(1, 2))
        Rk = R[ok]
        for i in range(3):
            tip = Rk[:, :, i]
            ax.plot(*tip.T, color=COMP[i], ls=run.ls, lw=1.8, zorder=3)
        if len(Rk):
            _triad(ax, np.zeros(3), Rk[-1], 1.0, lw=2.4, ls=run.ls, zorder=4)
        handles.append(Line2D([], [], color="k", ls=run.ls, lw=1.6, label=f"{run.name}: paths and final frame"))
    first = runs[0].sol.trajectory.R
    marks = np.unique(np.linspace(0, len(first) - 1, n_marks).round().astype(int))
    for i in range(3):
        tips = first[marks][:, :, i]
        ax.scatter(*tips.T, s=10, color=COMP[i], zorder=5, depthshade=False)
    handles.append(Line2D([], [], color="0.3", marker="o", ls="", ms=3, label=f"{runs[0].label} at t = kT/{n_marks - 1}"))
    Rd = _target_R(problem)
    if Rd is not None:
        for i in range(3):
            ax.plot(*np.vstack([np.zeros(3), 1.12 * Rd[:, i]]).T, color="k", ls="--", lw=1.2, zorder=6)
            ax.text(*(1.2 * Rd[:, i]), f"e{i + 1}ᵈ", fontsize=9, zorder=7)
        handles.append(Line2D([], [], color="k", ls="--", lw=1.2, label="target frame R_d"))
    elif isinstance(problem.terminal, TargetOrbit):
        n = problem.terminal.normal
        ax.plot(*np.vstack([-1.15 * n, 1.15 * n]).T, color="k", ls="--", lw=1.2, zorder=6)
        handles.append(Line2D([], [], color="k", ls="--", lw=1.2, label="target: body axis along ± orbit normal"))
    for c in _cones(ax, problem, runs):
        col = CONE[c.kind]
        i = next((i for i in range(3) if np.allclose(np.abs(c.body_axis), np.eye(3)[i])), None)
        axis = f"e{i + 1}" if i is not None else f"b = {_vec(c.body_axis)}"
        if i is None:  # a body axis that is not a principal one: its path too
            for run in runs:
                Rb = np.einsum("kij,j->ki", run.sol.trajectory.R, c.body_axis)
                ax.plot(*Rb.T, color=col, ls=run.ls, lw=1.2, zorder=3)
        handles.append(Line2D([], [], color=col, lw=1.6,
                              label=f"{c.kind.replace('_', '-')} cone of {axis}: {c.angle_deg:g}° about "
                                    + (f"{c.direction} (dotted: its path)" if c.moving else "s")))
    ax.set_xlabel("inertial x₁")
    ax.set_ylabel("inertial x₂")
    ax.set_zlabel("inertial x₃")
    _cube(ax, 1.15)
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    return _finish(fig, runs, problem, "attitude (body axes on the unit sphere, inertial frame)")
