"""Figures of a maneuver, drawn from Solutions (in memory, or read back from a results directory).

:func:`figures` takes a Solution or a Comparison and returns {name: matplotlib Figure}; every
figure function takes ``runs`` (one :class:`Run` per method, so that both methods overlay, each
named in a legend) and the Problem, and draws what the Problem carries: control bounds (limit
lines, shading where a bound is active), path constraints (margins with their zero line), the
target (orbit, position, attitude).  A run that did not converge is marked in the title and by a
red corner banner with its result code, so it is never mistaken for a good one.

Importing this module does not choose a matplotlib backend (the CLI picks a non-interactive one
itself; :func:`animate` renders on its own Agg canvas).  Every unit in a label comes from
:func:`problems.units.units` of the Problem: the normalized orbit units (radii, orbital periods) with
a central body of GM = 4π², the dimension only ("mass·length/time²", "time t") without one.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import FixedLocator, MaxNLocator

from ..transcription.problem import (BoxBound, KeepIn, KeepOut, MaxAngularRate, MinRadius, NormBound, Problem,
                                     TargetOrbit, TargetState)
from ..transcription.lie import quaternions, rotation_angle
from ..transcription.results import Solution, figures_of_merit
from ..transcription.solve import Comparison
from .io import save_figure
from .units import units

#: colours of the methods (distinct from those of the components and body axes below)
COLORS = {"direct": "#5e3c99", "indirect": "#e66101", "impulsive": "#5e3c99", "simulate": "#555555"}
STYLES = {"direct": "-", "indirect": "--", "impulsive": "-", "simulate": "-"}
#: colours of vector components (and of the body axes e1, e2, e3)
COMP = ("#d62728", "#2ca02c", "#1f77b4")
QUAT = ("#333333", "#d62728", "#2ca02c", "#1f77b4")
FAIL = "#c0392b"
THRUST = "#e7298a"
BOUND = "#444444"
#: colours of cone constraints (keep-out, keep-in): not those of a body axis or a method
CONE = {"keep_out": "#b8860b", "keep_in": "#00838f"}
W, H = 7.2, 5.4  # the default figure size (inches)


@dataclass
class Run:
    """One method's solution as the figures see it: the Solution, its name, colour and line style."""

    label: str
    sol: Solution
    #: path-constraint margins below -tol are violations (store.path_tolerance); above, round-off
    tol: float = 1e-8

    @classmethod
    def of(cls, sol: Solution, tol: float = 1e-8) -> "Run":
        return cls(sol.method, sol, tol)

    @property
    def color(self):
        return COLORS.get(self.label, None)

    @property
    def ls(self):
        return STYLES.get(self.label, "-")

    @property
    def failed(self) -> bool:
        return not self.sol.converged

    @property
    def name(self) -> str:
        """The legend name: the method, and the result code when it did not converge."""
        return f"{self.label} (FAILED: {self.sol.result.value})" if self.failed else self.label

    @property
    def t(self) -> np.ndarray:
        return self.sol.trajectory.t

    @property
    def tu(self) -> np.ndarray | None:
        return self.sol.control_times

    @property
    def per_step(self) -> bool:
        """Whether the controls are one per step (first order: u_{k+1} acts over [t_k, t_{k+1}]),
        rather than node values (LGVI: u_k at t_k, entering the steps on either side)."""
        return self.sol.controls is not None and self.sol.controls.shape[1] == self.sol.N

    @property
    def control_edges(self) -> np.ndarray:
        """Edges (n+1,) of the time each control stands for, so that its quadrature weight ω_j (the
        cost's, Δv's and time at a bound's) is edges[j+1] - edges[j]: first order, the steps
        [t_k, t_{k+1}] (ω = h); LGVI, the node cells [t_k - h/2, t_k + h/2] within [0, T]
        (ω = h (½, 1, ..., 1, ½))."""
        return self.t if self.per_step else node_cells(self.t)

    def plot_control(self, ax, y: np.ndarray, **kw):
        """Draw control values y (n,) against time: per-step controls as steps held over their step
        (a bang-bang switch is a jump, not a ramp); node controls as node values joined by lines."""
        kw = {"color": self.color, "ls": self.ls, **kw}
        if self.per_step:
            return ax.plot(self.control_edges, np.r_[y[:1], y], drawstyle="steps-pre", **kw)
        return ax.plot(self.tu, y, **kw)

    @property
    def node_of_control(self) -> np.ndarray:
        """The node index of each control (first order: u_1..u_N at nodes 1..N; lgvi: 0..N)."""
        n = self.sol.controls.shape[1]
        return np.arange(1, n + 1) if n == self.sol.N else np.arange(n)


# ------------------------------------------------------------------------ geometry
def osculating_elements(x: np.ndarray, v: np.ndarray, mu: float) -> dict[str, np.ndarray]:
    """Radius, inclination (deg, of the orbit normal to e3), eccentricity and semi-major axis of the
    osculating orbits of positions and velocities x, v (n, 3) about a point mass mu."""
    x, v = np.atleast_2d(np.asarray(x, float)), np.atleast_2d(np.asarray(v, float))
    r = np.linalg.norm(x, axis=1)
    h = np.cross(x, v)
    hn = np.linalg.norm(h, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        inc = np.degrees(np.arccos(np.clip(h[:, 2] / hn, -1.0, 1.0)))
        e = np.linalg.norm(np.cross(v, h) / mu - x / r[:, None], axis=1)
        a = 1.0 / (2.0 / r - np.einsum("ij,ij->i", v, v) / mu)
    return {"radius": r, "inclination": inc, "eccentricity": e, "semi_major_axis": a}


def rtn(x: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Components (n, 3) of inertial vectors u in the osculating orbit's radial, along-track
    (transverse: n x r) and normal (h/|h|) directions at positions and velocities x, v (n, 3)."""
    r_hat = x / np.linalg.norm(x, axis=1)[:, None]
    h = np.cross(x, v)
    n_hat = h / np.linalg.norm(h, axis=1)[:, None]
    t_hat = np.cross(n_hat, r_hat)
    return np.stack([np.einsum("ij,ij->i", u, e) for e in (r_hat, t_hat, n_hat)], axis=1)


def _orbit_ellipse(x, v, mu, n=200):
    """The osculating orbit of (x, v) about a point mass mu, as points (n, 3) (None if unbound)."""
    x, v = np.asarray(x, float), np.asarray(v, float)
    r = np.linalg.norm(x)
    hvec = np.cross(x, v)
    if not mu or np.linalg.norm(hvec) < 1e-12:
        return None
    evec = np.cross(v, hvec) / mu - x / r
    e = np.linalg.norm(evec)
    a = 1.0 / (2.0 / r - v @ v / mu)
    if e >= 1 or a <= 0:
        return None
    p_hat = evec / e if e > 1e-10 else x / r
    w_hat = hvec / np.linalg.norm(hvec)
    q_hat = np.cross(w_hat, p_hat)
    nu = np.linspace(0, 2 * np.pi, n)
    rad = a * (1 - e**2) / (1 + e * np.cos(nu))
    return (rad * np.cos(nu))[:, None] * p_hat + (rad * np.sin(nu))[:, None] * q_hat


def _circle(radius, normal, n=200):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    t = np.linspace(0, 2 * np.pi, n)
    return radius * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b)


def _target_R(problem: Problem) -> np.ndarray | None:
    """R_d of a state target that fixes the attitude, else None."""
    term = problem.terminal
    if isinstance(term, TargetState) and "attitude" in term.fixed:
        return term.X[6:15].reshape(3, 3, order="F")
    return None


def _target_orbit(problem: Problem) -> np.ndarray | None:
    """Points of the desired orbit (a TargetOrbit's circle, or the osculating orbit of a state
    target that fixes position and velocity), or None."""
    term, model = problem.terminal, problem.model
    if isinstance(term, TargetOrbit):
        return _circle(term.radius, term.normal)
    if isinstance(term, TargetState) and {"position", "velocity"} <= set(term.fixed) and model.mu:
        return _orbit_ellipse(term.X[0:3], term.X[3:6] / model.mass, model.mu)
    return None


def _target_elements(problem: Problem) -> dict[str, float] | None:
    term, model = problem.terminal, problem.model
    if isinstance(term, TargetOrbit):
        return {"radius": term.radius, "inclination": float(np.degrees(np.arccos(np.clip(term.normal[2], -1, 1)))),
                "eccentricity": 0.0}
    if isinstance(term, TargetState) and {"position", "velocity"} <= set(term.fixed) and model.mu:
        el = osculating_elements(term.X[0:3], term.X[3:6] / model.mass, model.mu)
        return {k: float(v[0]) for k, v in el.items()}
    return None


def _intervals(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [i0, i1] of the runs of True in a boolean array."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        elif not m and start is not None:
            out.append((start, i - 1))
            start = None
    if start is not None:
        out.append((start, len(mask) - 1))
    return out


def node_cells(t: np.ndarray) -> np.ndarray:
    """Edges (n+1,) of the cells of node values at times t (n,): half-way to the neighbours, the
    first and last cells ending at t_0 and t_N."""
    t = np.asarray(t, float)
    return np.concatenate([t[:1], 0.5 * (t[:-1] + t[1:]), t[-1:]])


def _shade(ax, edges, mask, color, label=None, alpha=0.15):
    """Shade the cells [edges[i], edges[i+1]] where mask[i] holds (edges: Run.control_edges for
    controls, node_cells(t) for node values), so that the shaded time is the sum of the cells'
    quadrature weights -- for a control at its bound, the time_at_bound of figures_of_merit."""
    if not np.any(mask):
        return
    for n, (i0, i1) in enumerate(_intervals(mask)):
        ax.axvspan(edges[i0], edges[i1 + 1], color=color, alpha=alpha, lw=0,
                   label=label if n == 0 else None, gid="bound-active")


def removed(problem: Problem) -> set[str]:
    """The controls a norm bound of 0 removes: a subset of {"force", "moment"}."""
    rm = getattr(problem.control, "removed", (False, False))
    return {name for name, r in zip(("force", "moment"), rm) if r}


def _active(u: np.ndarray, bound) -> np.ndarray:
    return bound.active(u)


# ------------------------------------------------------------------------ common decoration
def _subplots(nrows: int, ncols: int = 1, figsize=(W, H), sharex=True, **kw):
    fig, axs = plt.subplots(nrows, ncols, figsize=figsize, sharex=sharex, squeeze=False, layout="constrained", **kw)
    return fig, axs.ravel()


def _time_axes(axs, problem: Problem):
    """Few, non-overlapping time ticks; the time label (in the problem's units) on the lowest axes
    only; grids."""
    for ax in axs:
        ax.xaxis.set_major_locator(MaxNLocator(nbins=6))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.grid(alpha=0.3)
        _no_offset(ax)
    axs[-1].set_xlabel(units(problem).time_label)


def _no_offset(ax):
    """Plain tick labels; a (nearly) constant quantity gets a sensible window -- one tick at 0 for
    a quantity that is zero throughout (not ±0.00004: precision it does not have)."""
    try:
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    except AttributeError:  # a log axis
        return
    ys = [np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()]
    ys = np.concatenate([y[np.isfinite(y)] for y in ys]) if ys else np.zeros(0)
    lo, hi = (float(ys.min()), float(ys.max())) if ys.size else ax.get_ylim()
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    if half < 1e-6 * max(1.0, abs(mid)):
        if abs(mid) < 1e-6:
            ax.set_ylim(-1.0, 1.0)
            ax.yaxis.set_major_locator(FixedLocator([0.0]))
            return
        w = 0.05 * abs(mid)
        ax.set_ylim(mid - w, mid + w)


def _text_width(text: str, size: float, weight: str = "normal") -> float:
    """Width in points of one line of text (no canvas needed)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    return TextToPath().get_text_width_height_descent(text, FontProperties(size=size, weight=weight), ismath=False)[0]


def _finish(fig, runs: list[Run], problem: Problem, what: str):
    """The figure's title (the maneuver and what is shown); a failed run marks it (a red title with
    a line NOT CONVERGED) and adds a red banner in the top right corner naming each failed method
    and its result code.  The title is wrapped (and if need be made smaller) so that it never runs
    into the banner."""
    failed = [r for r in runs if r.failed]
    name = problem.name or "maneuver"
    banner = [f"{r.label}: {r.sol.result.value}" for r in failed]
    room = fig.get_figwidth() * 72.0 - 16.0
    if banner:
        room -= max(_text_width(b, 9, "bold") for b in banner) + 24.0
    size = 11.0
    lines = [f"{name}: {what}"]
    if max(_text_width(ln, size) for ln in lines) > room:
        lines = [f"{name}:", what]
    if failed:
        lines.append("NOT CONVERGED")
    while size > 7 and max(_text_width(ln, size) for ln in lines) > room:
        size -= 0.5
    fig.suptitle("\n".join(lines), x=0.01, ha="left", fontsize=size, color=FAIL if failed else "black",
                 linespacing=1.15)
    if failed:
        fig.text(0.995, 0.995, "\n".join(banner), ha="right", va="top", fontsize=9, color="white",
                 fontweight="bold", gid="failure-banner",
                 bbox=dict(boxstyle="round,pad=0.35", facecolor=FAIL, edgecolor="none"))
    return fig


# ------------------------------------------------------------------------ 3-D views
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
    X0 = first.trajectory.x
    paths = np.vstack([r.sol.trajectory.x for r in runs])
    paths = paths[np.all(np.isfinite(paths), axis=1)]
    allx = np.vstack([paths, np.zeros((1, 3))])
    orb = None
    if model.mu:
        v0 = first.trajectory.v[0] if first.impulses is None else \
            (first.trajectory.gamma[0] - first.impulses["dgamma0"]) / model.mass
        orb = _orbit_ellipse(X0[0], v0, model.mu)
        if orb is not None:
            allx = np.vstack([allx, orb])
    target = _target_orbit(problem)
    if target is not None:
        allx = np.vstack([allx, target])
    center = 0.5 * (allx.max(0) + allx.min(0)) if not model.mu else np.zeros(3)
    lim = max(np.abs(allx - center).max() * 1.05, 1e-9)
    extent = float(np.ptp(paths, axis=0).max()) if len(paths) else 0.0
    zoom = extent < 0.3 * lim
    fig = plt.figure(figsize=(W * 1.6 if zoom else W, 6.4), layout="constrained")
    ax = fig.add_subplot(1, 2 if zoom else 1, 1, projection="3d")
    ax.computed_zorder = False  # paths above the body frames, whatever the view's depth order
    if model.mu:
        ax.scatter([0], [0], [0], s=160, color="#3b6ea8", label="central body", zorder=1)
    if orb is not None:
        ax.plot(*orb.T, color="0.55", lw=1, ls=":", label="initial orbit", zorder=1)
    if target is not None:
        ax.plot(*target.T, color="k", lw=1, ls="--", label="desired orbit", zorder=1)
    has_xd = isinstance(problem.terminal, TargetState) and "position" in problem.terminal.fixed
    if has_xd:
        ax.scatter(*problem.terminal.X[0:3], marker="x", s=70, color="k", label="desired position", zorder=6)
    L = 0.14 * lim  # the body frame at a seventh of the view, so that its rotation shows at orbit scale
    if not zoom:
        _bodies(ax, problem, first, L, n_bodies)
    _paths(ax, runs)
    if first.impulses is not None:
        for k, key in ((0, "dgamma0"), (-1, "dgammaN")):
            d = np.asarray(first.impulses[key], float)
            n = np.linalg.norm(d)
            if n > 0:
                ax.quiver(*X0[k], *(0.3 * lim * d / n), color=THRUST, arrow_length_ratio=0.25, lw=2, zorder=7)
        ax.plot([], [], color=THRUST, lw=2, label="impulse direction")
    _cube(ax, lim, center)
    un = units(problem)
    for a, lab in ((ax.set_xlabel, "x₁"), (ax.set_ylabel, "x₂"), (ax.set_zlabel, "x₃")):
        a(un.label(lab, "length"))
    what = f"maneuver (body frame ×{L / size:.2g})"
    if zoom:
        ax.set_title("orbit", fontsize=10)
        az = fig.add_subplot(1, 2, 2, projection="3d")
        az.computed_zorder = False
        c = 0.5 * (paths.max(0) + paths.min(0)) if len(paths) else X0[0]
        lz = max(0.65 * extent, 1e-3 * lim, 2.0 * size)
        Lz = 0.3 * lz
        _bodies(az, problem, first, Lz, n_bodies)
        _paths(az, runs, label=False)
        if has_xd:
            az.scatter(*problem.terminal.X[0:3], marker="x", s=70, color="k", zorder=6)
        _cube(az, lz, c)
        az.set_xlabel("x₁")
        az.set_ylabel("x₂")
        az.set_zlabel("x₃")
        az.set_title(f"zoom on the path: ±{lz:.2g}{' ' + un.unit('length') if un.normalized else ''}, "
                     f"body frame ×{Lz / size:.2g}", fontsize=10)
        what = "maneuver"
    handles, labels = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color=c, lw=1.5) for c in COMP]
    labels += [f"body e{i + 1}" for i in range(3)]
    handles.append(Line2D([], [], color="0.3", marker="o", ls="", ms=5))
    labels.append("start (o), end (■)")
    fig.legend(handles, labels, loc="outside lower center", ncols=5 if zoom else 3, fontsize=10 if zoom else 8.5,
               frameon=False)  # the wide figure is shown wider: the same size on the page
    return _finish(fig, runs, problem, what)


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
        if isinstance(problem.terminal, TargetState) and "position" in problem.terminal.fixed:
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
        cones = [c for c in problem.constraints if isinstance(c, (KeepOut, KeepIn))]
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


def _cones(ax, problem: Problem) -> list:
    """Draw each cone constraint (keep-out, keep-in) on the unit sphere of a 3-D axes: its boundary
    about its direction s (dotted); returns the cones."""
    cones = [c for c in problem.constraints if isinstance(c, (KeepOut, KeepIn))]
    for c in cones:
        th = np.radians(c.angle_deg)
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
    for c in _cones(ax, problem):
        col = CONE[c.kind]
        i = next((i for i in range(3) if np.allclose(np.abs(c.body_axis), np.eye(3)[i])), None)
        axis = f"e{i + 1}" if i is not None else f"b = {_vec(c.body_axis)}"
        if i is None:  # a body axis that is not a principal one: its path too
            for run in runs:
                Rb = np.einsum("kij,j->ki", run.sol.trajectory.R, c.body_axis)
                ax.plot(*Rb.T, color=col, ls=run.ls, lw=1.2, zorder=3)
        handles.append(Line2D([], [], color=col, lw=1.6,
                              label=f"{c.kind.replace('_', '-')} cone of {axis}: {c.angle_deg:g}° about s"))
    ax.set_xlabel("inertial x₁")
    ax.set_ylabel("inertial x₂")
    ax.set_zlabel("inertial x₃")
    _cube(ax, 1.15)
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    return _finish(fig, runs, problem, "attitude (body axes on the unit sphere, inertial frame)")


# ------------------------------------------------------------------------ time histories
def fig_attitude_error(runs: list[Run], problem: Problem):
    """Angle of the attitude error R_d^T R(t) (deg; without an attitude target the rotation from
    the initial attitude, R_0^T R(t)) and the quaternion of that rotation (continuous signs)."""
    Rd = _target_R(problem)
    fig, axs = _subplots(2, figsize=(W, 5.6), height_ratios=(1.2, 1))
    for run in runs:
        R = run.sol.trajectory.R
        E = np.einsum("ji,kjl->kil", Rd if Rd is not None else R[0], R)
        ang = np.degrees(rotation_angle(E))
        axs[0].plot(run.t, ang, color=run.color, ls=run.ls, lw=1.6, label=run.name)
        q = quaternions(E)
        for i in range(4):
            axs[1].plot(run.t, q[:, i], color=QUAT[i], ls=run.ls, lw=1.4)
    axs[0].set_ylabel("angle of $R_d^TR$ (deg)" if Rd is not None else "angle of $R_0^TR$ (deg)")
    axs[0].set_ylim(bottom=0)
    axs[1].set_ylabel("quaternion")
    axs[1].set_ylim(-1.05, 1.05)
    axs[0].legend(fontsize=8, loc="best")
    axs[1].legend([Line2D([], [], color=c) for c in QUAT], ["q_w", "q_x", "q_y", "q_z"], fontsize=8,
                  loc="center left", bbox_to_anchor=(1.005, 0.5), frameon=False)  # beside: q spans [-1, 1]
    _time_axes(axs, problem)
    what = "attitude error to the target" if Rd is not None else "rotation from the initial attitude"
    return _finish(fig, runs, problem, what)


def _components(runs, problem, key_fn, ylabels, what, bound=None, impulses=None, controls=False):
    """Three stacked component plots, methods overlaid; a BoxBound draws ±b_i and shades where a
    component is at its limit.  ``controls``: the values are the run's controls (drawn by
    Run.plot_control: per-step controls as steps)."""
    fig, axs = _subplots(3, figsize=(W, 6.0))
    for run in runs:
        t, Y = key_fn(run)
        if Y is None:
            continue
        for i, ax in enumerate(axs):
            if controls:
                run.plot_control(ax, Y[:, i], lw=1.5, label=run.name)
            else:
                ax.plot(t, Y[:, i], color=run.color, ls=run.ls, lw=1.5, label=run.name)
        if isinstance(bound, BoxBound):
            for i, ax in enumerate(axs):
                _shade(ax, run.control_edges, bound.active_components(Y)[:, i], run.color,
                       label=f"{run.label} at bound")
        if impulses is not None:
            jumps = impulses(run)
            if jumps is not None:
                for i, ax in enumerate(axs):
                    for tt, before, after in jumps:
                        ax.plot([tt, tt], [before[i], after[i]], ":", color=run.color, lw=1.2)
                        ax.plot(tt, before[i], "o", mfc="white", color=run.color, ms=5)
                        ax.plot(tt, after[i], "o", color=run.color, ms=5)
    if isinstance(bound, BoxBound):
        for i, ax in enumerate(axs):
            for sgn in (1, -1):
                ax.axhline(sgn * bound.b[i], color=BOUND, ls="-.", lw=1.1, gid="bound-line",
                           label=f"bound ±{bound.b[i]:.3g}" if sgn > 0 else None)
    for i, ax in enumerate(axs):
        ax.set_ylabel(ylabels[i])
    handles, labels = axs[0].get_legend_handles_labels()
    if impulses is not None:
        handles += [Line2D([], [], marker="o", mfc="white", color="0.3", ls=""),
                    Line2D([], [], marker="o", color="0.3", ls=":")]
        labels += ["before impulse", "after impulse"]
    axs[0].legend(handles, labels, fontsize=8, loc="best", ncols=2 if len(labels) > 3 else 1)
    _time_axes(axs, problem)
    return _finish(fig, runs, problem, what)


def fig_velocity(runs, problem: Problem):
    m = problem.model.mass

    def after(run):
        s = run.sol
        if s.impulses is None:
            return None
        g = s.trajectory.gamma
        return [(run.t[0], (g[0] - s.impulses["dgamma0"]) / m, g[0] / m),
                (run.t[-1], g[-1] / m, (g[-1] + s.impulses["dgammaN"]) / m)]

    imp = after if any(r.sol.impulses is not None for r in runs) else None
    return _components(runs, problem, lambda r: (r.t, r.sol.trajectory.v), ["$v_1$", "$v_2$", "$v_3$"],
                       units(problem).label("velocity v = γ/m, inertial", "velocity"), impulses=imp)


def fig_angular_velocity(runs, problem: Problem):
    """Body angular velocity components and its norm (with a MaxAngularRate limit)."""
    Jinv = np.linalg.inv(problem.model.inertia)
    limits = [c.value for c in problem.constraints if isinstance(c, MaxAngularRate)]
    fig, axs = _subplots(4, figsize=(W, 6.8))
    for run in runs:
        s = run.sol
        Om = s.trajectory.Omega
        for i in range(3):
            axs[i].plot(run.t, Om[:, i], color=run.color, ls=run.ls, lw=1.5, label=run.name)
        axs[3].plot(run.t, np.linalg.norm(Om, axis=1), color=run.color, ls=run.ls, lw=1.5, label=run.name)
        if s.impulses is not None:
            P = s.trajectory.Pi
            for tt, before, after in ((run.t[0], Jinv @ (P[0] - s.impulses["dPi0"]), Jinv @ P[0]),
                                      (run.t[-1], Jinv @ P[-1], Jinv @ (P[-1] + s.impulses["dPiN"]))):
                for i in range(3):
                    axs[i].plot([tt, tt], [before[i], after[i]], ":", color=run.color, lw=1.2)
                    axs[i].plot(tt, before[i], "o", mfc="white", color=run.color, ms=5)
                    axs[i].plot(tt, after[i], "o", color=run.color, ms=5)
    for lim in limits:
        axs[3].axhline(lim, color=BOUND, ls="-.", lw=1.1, gid="bound-line", label=f"max rate {lim:.3g}")
    for i in range(3):
        axs[i].set_ylabel(f"$\\Omega_{i + 1}$")
    axs[3].set_ylabel("$|\\Omega|$")
    axs[0].legend(fontsize=8, loc="best")
    if limits:
        axs[3].legend(fontsize=8, loc="best")
    _time_axes(axs, problem)
    return _finish(fig, runs, problem, units(problem).label("angular velocity Ω = J⁻¹Π, body frame", "angular_rate"))


def _bound_of(problem: Problem, which: str):
    return getattr(problem.control, f"{which}_bound", None)


def fig_force(runs, problem: Problem):
    b = _bound_of(problem, "force")
    return _components([r for r in runs if r.sol.controls is not None], problem, lambda r: (r.tu, r.sol.u_f),
                       ["$u_{f,1}$", "$u_{f,2}$", "$u_{f,3}$"],
                       units(problem).label("control force u_f, inertial components", "force"), bound=b, controls=True)


def fig_moment(runs, problem: Problem):
    b = _bound_of(problem, "moment")
    return _components([r for r in runs if r.sol.controls is not None], problem, lambda r: (r.tu, r.sol.u_m),
                       ["$u_{m,1}$", "$u_{m,2}$", "$u_{m,3}$"],
                       units(problem).label("control moment u_m, body components", "moment"), bound=b, controls=True)


def fig_control_norms(runs, problem: Problem):
    """|u_f| and |u_m| over time: a NormBound is a line at b; where a bound (norm or box) is active
    the time is shaded, so the switching structure (bang-bang, saturated arcs) reads at a glance.
    A control removed by a norm bound of 0 gets no panel (it is absent, not "at its bound")."""
    runs = [r for r in runs if r.sol.controls is not None]
    un = units(problem)
    gone = removed(problem)
    panels = [(w, k, f"$|{k}|$") for w, k in (("force", "u_f"), ("moment", "u_m")) if w not in gone]
    fig, axs = _subplots(len(panels), figsize=(W, 5.2 if len(panels) == 2 else 3.4))
    for ax, (which, key, ylab) in zip(axs, panels):
        bound = _bound_of(problem, which)
        for run in runs:
            u = getattr(run.sol, key)
            run.plot_control(ax, np.linalg.norm(u, axis=1), lw=1.6, label=run.name)
            if bound is not None:
                act = _active(u, bound)
                tab = figures_of_merit(run.sol).get(f"{which}_time_at_bound", float("nan"))
                _shade(ax, run.control_edges, act, run.color,
                       label=f"{run.label} at bound ({un.duration(tab)})" if isinstance(bound, NormBound) else
                       f"{run.label}: a component at its bound ({un.duration(tab)})")
        if isinstance(bound, NormBound):
            ax.axhline(bound.b, color=BOUND, ls="-.", lw=1.2, gid="bound-line", label=f"bound |u| ≤ {bound.b:.3g}")
        elif isinstance(bound, BoxBound):  # |u| reaches |b| only with every component at its bound
            ax.axhline(float(np.linalg.norm(bound.b)), color=BOUND, ls=":", lw=1.2,
                       label=f"|b| = {np.linalg.norm(bound.b):.3g}: every component at its bound")
            ax.plot([], [], ls="", label=f"box bound ±({', '.join(f'{b:.3g}' for b in bound.b)}): see {which}")
        ax.set_ylim(0.0, 1.12 * max(ax.get_ylim()[1] / 1.05, 1e-300))  # room above a bound the data ride on
        ax.legend(fontsize=8, loc="best")
        ax.set_ylabel(un.label(ylab, which))
    _time_axes(axs, problem)
    what = "control magnitudes" + "".join(f" (the {w} is removed: a norm bound of 0)" for w in sorted(gone))
    return _finish(fig, runs or [], problem, what)


def fig_thrust_rtn(runs, problem: Problem):
    """The force in the osculating orbit's frame: radial, along-track (transverse) and normal."""
    def comp(run):
        s = run.sol
        k = run.node_of_control
        return run.tu, rtn(s.trajectory.x[k], s.trajectory.v[k], s.u_f)

    return _components([r for r in runs if r.sol.controls is not None], problem, comp,
                       ["radial $u_R$", "along-track $u_T$", "normal $u_N$"],
                       units(problem).label("control force in the orbit frame: radial, along-track, normal", "force"),
                       controls=True)


def fig_orbital_elements(runs, problem: Problem):
    """Radius, inclination and eccentricity of the osculating orbit over time, with the target's
    values (dashed) and a MinRadius limit; impulsive runs show the elements after each impulse."""
    mu, m = problem.model.mu, problem.model.mass
    fig, axs = _subplots(3, figsize=(W, 6.0))
    keys = ("radius", "inclination", "eccentricity")
    for run in runs:
        s = run.sol
        el = osculating_elements(s.trajectory.x, s.trajectory.v, mu)
        for ax, k in zip(axs, keys):
            ax.plot(run.t, el[k], color=run.color, ls=run.ls, lw=1.6, label=run.name)
        if s.impulses is not None:
            g = s.trajectory.gamma
            x = s.trajectory.x
            pre = osculating_elements(x[0], (g[0] - s.impulses["dgamma0"]) / m, mu)
            post = osculating_elements(x[-1], (g[-1] + s.impulses["dgammaN"]) / m, mu)
            for ax, k in zip(axs, keys):
                ax.plot(run.t[0], pre[k][0], "o", mfc="white", color=run.color, ms=5)
                ax.plot(run.t[-1], post[k][0], "o", color=run.color, ms=5)
    tgt = _target_elements(problem)
    if tgt is not None:
        for ax, k in zip(axs, keys):
            ax.axhline(tgt[k], color="k", ls="--", lw=1.0, label="target")
    for c in problem.constraints:
        if isinstance(c, MinRadius):
            axs[0].axhline(c.radius, color=BOUND, ls="-.", lw=1.1, gid="bound-line", label=f"min radius {c.radius:.3g}")
    axs[0].set_ylabel(units(problem).label("radius |x|", "length"))
    axs[1].set_ylabel("inclination (deg)")
    axs[2].set_ylabel("eccentricity")
    handles, labels = [], []
    for ax in axs:  # one legend below the panels: inside, it covered the radius near its target
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8.5, frameon=False)
    _time_axes(axs, problem)
    return _finish(fig, runs, problem, "osculating orbit")


def fig_costates(runs, problem: Problem):
    """The discrete costates λ_k (indirect method; direct: mapped from the NLP multipliers) by
    block: position, linear momentum, attitude, angular momentum; λ_k is attached to step k."""
    runs = [r for r in runs if r.sol.costates is not None]
    fig, axs = _subplots(4, figsize=(W, 7.0))
    names = ("$\\lambda_x$", "$\\lambda_\\gamma$", "$\\lambda_R$", "$\\lambda_\\Pi$")
    for run in runs:
        lam = np.asarray(run.sol.costates, float)
        t = run.t[: len(lam)]
        for b, ax in enumerate(axs):
            for i in range(3):
                ax.plot(t, lam[:, 3 * b + i], color=COMP[i], ls=run.ls, lw=1.4)
    for ax, n in zip(axs, names):
        ax.set_ylabel(n)
    handles = [Line2D([], [], color=c, lw=1.4) for c in COMP] + [Line2D([], [], color="k", ls=r.ls) for r in runs]
    labels = ["component 1", "component 2", "component 3"] + [
        r.name + (" (from multipliers)" if r.label == "direct" else "") for r in runs]
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8.5, frameon=False)
    _time_axes(axs, problem)
    axs[-1].set_xlabel(units(problem).time_label.replace("time t", "time t_k of step k"))
    return _finish(fig, runs, problem, "discrete costates λ_k")


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in np.asarray(v, float) + 0.0) + ")"


def _describe(c) -> str:
    if isinstance(c, MinRadius):
        return f"min radius: |x| ≥ {c.radius:g}"
    if isinstance(c, KeepOut):
        return f"keep-out: angle(R b, s) ≥ {c.angle_deg:g}°, body axis b = {_vec(c.body_axis)}, direction s = {_vec(c.direction)}"
    if isinstance(c, KeepIn):
        return f"keep-in: angle(R b, s) ≤ {c.angle_deg:g}°, body axis b = {_vec(c.body_axis)}, direction s = {_vec(c.direction)}"
    if isinstance(c, MaxAngularRate):
        return f"max angular rate: |Ω| ≤ {c.value:g}"
    return c.kind


def fig_constraints(runs, problem: Problem):
    """The margin of each path constraint over time (≥ 0 where it holds): the zero line, and the
    times where a method violates it by more than the tolerance (Run.tol: a margin of -1e-11 is
    round-off) shaded red."""
    cons = problem.constraints
    fig, axs = _subplots(len(cons), figsize=(W, 1.2 + 1.7 * len(cons)))
    for ax, c in zip(axs, cons):
        for run in runs:
            mg = c.margin(run.sol.trajectory)
            ax.plot(run.t, mg, color=run.color, ls=run.ls, lw=1.6, label=run.name)
            _shade(ax, node_cells(run.t), mg < -run.tol, FAIL, label=f"violated by more than {run.tol:.0e}" if run is runs[0] else None,
                   alpha=0.12)
        ax.axhline(0.0, color="k", lw=1.0, gid="zero-line")
        ax.set_ylabel(units(problem).label("margin", c.dimension))
        ax.set_title(_describe(c), fontsize=9, loc="left")
        ax.legend(fontsize=8, loc="best")
    _time_axes(axs, problem)
    return _finish(fig, runs, problem, "path-constraint margins")


def _positive(values):
    """Values for a log axis: non-positive or missing entries become NaN (not drawn)."""
    y = np.array([np.nan if v is None else v for v in values], float)
    y[~(y > 0)] = np.nan
    return y


def fig_convergence(runs, problem: Problem):
    """Residual (log) against iterations; for Newton-Armijo every line-search trial, iterations circled."""
    fig, axs = _subplots(1, figsize=(W, 4.2))
    ax = axs[0]
    drew = False
    for run in runs:
        hist = [h.as_dict() for h in run.sol.history]
        if not hist:
            continue
        if any(h.get("trial", 0) > 0 for h in hist):  # Newton-Armijo: one record per rollout
            errs = _positive([h.get("residual") for h in hist])
            ax.semilogy(np.arange(len(errs)), errs, ".-", color=run.color, lw=1, ms=4,
                        label=f"{run.name}: all line-search trials")
            acc = [i for i, h in enumerate(hist) if h.get("accepted")]
            ax.semilogy(acc, errs[acc], "o", mfc="none", color=run.color, ms=8, label=f"{run.name}: iterations")
        else:  # NLP solver (or Newton without rejected trials): one record per iteration
            x = np.arange(len(hist))
            for key, mark, lab in (("residual", "-", "primal infeasibility"), ("dual", ":", "dual infeasibility")):
                y = _positive([h.get(key) for h in hist])
                if np.isfinite(y).any():
                    ax.semilogy(x, y, mark, color=run.color, lw=1.4, marker=".", ms=4, label=f"{run.name}: {lab}")
        drew = True
    if not drew:
        ax.text(0.5, 0.5, "no iteration history recorded", ha="center", va="center", transform=ax.transAxes)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=8, integer=True))
    newton = any(h.trial > 0 for r in runs for h in r.sol.history)
    ax.set_xlabel("iteration (Newton–Armijo: line-search trial)" if newton else "iteration")
    ax.set_ylabel("residual (log scale)")
    ax.grid(alpha=0.3, which="both")
    if drew:
        ax.legend(fontsize=8)
    return _finish(fig, runs, problem, "convergence")


#: every figure, in the order of the report; the names are the files fig_<name>.png/.pdf
FIGURES = {
    "maneuver": fig_maneuver,
    "attitude": fig_attitude,
    "attitude_error": fig_attitude_error,
    "control_norms": fig_control_norms,
    "force": fig_force,
    "moment": fig_moment,
    "thrust_rtn": fig_thrust_rtn,
    "orbital_elements": fig_orbital_elements,
    "constraints": fig_constraints,
    "velocity": fig_velocity,
    "angular_velocity": fig_angular_velocity,
    "costates": fig_costates,
    "convergence": fig_convergence,
}

#: one line per figure (the report's captions, the README's table)
CAPTIONS = {
    "maneuver": "3-D path of each method about the central body, initial and desired orbits, the body frame at a few nodes",
    "attitude": "the body axes' paths on the unit sphere (inertial), the final frame of each method against the target frame",
    "attitude_error": "angle of the attitude error R_dᵀR(t) (or the rotation from the start) and its quaternion",
    "control_norms": "|u_f| and |u_m| with their bounds; shaded where a bound is active (the switching structure)",
    "force": "control force, inertial components, with box limits ±b_i",
    "moment": "control moment, body components, with box limits ±b_i",
    "thrust_rtn": "control force in the osculating orbit frame: radial, along-track, normal",
    "orbital_elements": "osculating radius, inclination and eccentricity against the target's",
    "constraints": "margin of each path constraint (≥ 0 where it holds), violations shaded",
    "velocity": "inertial velocity components (impulses as jumps)",
    "angular_velocity": "body angular velocity components and |Ω| (with a rate limit)",
    "costates": "discrete costates λ_k by block (direct: mapped from the NLP multipliers)",
    "convergence": "residual per iteration (Newton–Armijo: every line-search trial)",
}


def caption(name: str, problem: Problem) -> str:
    """The caption of a figure for this problem (CAPTIONS, but the maneuver of a problem without a
    central body has no orbits)."""
    if name == "maneuver" and not problem.model.mu:
        return "no central body: the path and the body frame at a few nodes (a slew: the frame at a few times)"
    return CAPTIONS.get(name, name)


def applicable(runs: list[Run], problem: Problem) -> list[str]:
    """The names of the figures that apply to these runs (in FIGURES order)."""
    ctrl = any(r.sol.controls is not None for r in runs)
    central = bool(problem.model.mu)
    gone = removed(problem)
    skip = set(gone)  # a removed control: no component figure ("force", "moment")
    if not ctrl or gone == {"force", "moment"}:
        skip |= {"control_norms", "force", "moment", "thrust_rtn"}
    if "force" in gone:
        skip.add("thrust_rtn")
        if not central:  # no force and no gravity: the velocity is constant, a figure of flat lines
            skip.add("velocity")
    if not central:
        skip |= {"thrust_rtn", "orbital_elements"}
    if not problem.constraints:
        skip.add("constraints")
    if not any(r.sol.costates is not None for r in runs):
        skip.add("costates")
    if not any(r.sol.history for r in runs):
        skip.add("convergence")
    return [n for n in FIGURES if n not in skip]


def draw(name: str, runs: list[Run], problem: Problem):
    """One figure by name (a failed run's non-finite states are drawn as gaps, without warnings)."""
    with np.errstate(all="ignore"):
        return FIGURES[name](runs, problem)


def _runs(result: Solution | Comparison, tol: float | None = None) -> list[Run]:
    """The runs to draw: every method that applies to the problem (not Result.not_applicable);
    ``tol``: the path-constraint tolerance (store.path_tolerance; None: its default)."""
    from .store import DEFAULT_PATH_TOL
    from .store import applicable as applicable_methods

    return [Run.of(s, DEFAULT_PATH_TOL if tol is None else tol) for s in applicable_methods(result).values()]


def figures(result: Solution | Comparison, which: tuple[str, ...] | None = None, *,
            constraint_tol: float | None = None) -> dict:
    """{name: Figure} of a Solution or a Comparison (both methods overlaid), drawn from memory;
    ``which`` limits the names (figures that do not apply are left out); ``constraint_tol``: margins
    of path constraints below -constraint_tol are drawn as violations (default
    store.DEFAULT_PATH_TOL; a results directory uses its maneuver's terminal_tol)."""
    runs = _runs(result, constraint_tol)
    problem = runs[0].sol.problem
    if which:
        unknown = set(which) - set(FIGURES)
        if unknown:
            raise ValueError(f"unknown figures {sorted(unknown)}; expected some of {', '.join(FIGURES)}")
    return {name: draw(name, runs, problem) for name in applicable(runs, problem) if not which or name in which}


def draw_all(results_dir: Path, which: tuple[str, ...] | None = None, *, stale_only: bool = False) -> list[Path]:
    """(Re)draw the figures of a results directory as PNG and PDF; returns the paths written.
    ``stale_only``: draw only the figures whose PNG is missing or older than the run's data.
    Redrawing every figure also deletes the files of figures that no longer apply (drawn by an
    earlier version: e.g. a force figure for a run whose force is removed)."""
    from .store import path_tolerance, read_run

    d = Path(results_dir)
    run = read_run(d)
    tol = path_tolerance(run.maneuver)
    if stale_only:
        runs = _runs(run.result, tol)
        todo = tuple(n for n in applicable(runs, runs[0].sol.problem) if not is_fresh(d, n) and (not which or n in which))
        if not todo:
            return []
        which = todo
    runs = _runs(run.result, tol)
    names = applicable(runs, runs[0].sol.problem)
    if not which:
        for name in set(FIGURES) - set(names):
            for ext in (".png", ".pdf"):
                (d / f"fig_{name}{ext}").unlink(missing_ok=True)
    written = []
    for name in names:  # one at a time: one figure in memory
        if which and name not in which:
            continue
        fig = draw(name, runs, runs[0].sol.problem)
        written += save_figure(fig, d / f"fig_{name}")
        plt.close(fig)
    return written


def is_fresh(results_dir: Path, name: str) -> bool:
    """Whether fig_<name>.png exists and is newer than summary.json (the last file a run writes)."""
    d = Path(results_dir)
    png, summ = d / f"fig_{name}.png", d / "summary.json"
    return png.is_file() and summ.is_file() and png.stat().st_mtime_ns >= summ.stat().st_mtime_ns


# ------------------------------------------------------------------------ animation
def animate(results_dir: Path, frames: int = 100, fps: int = 20, out: Path | None = None) -> Path:
    """Write ``maneuver.gif``: every method of the run (named in the legend), the body frame of
    each at orbit scale with its thrust arrow, the initial and desired orbits, and beside it the
    attitude alone (body triads against the target frame) and a timeline of |u_f| and |u_m|.

    Rendered on its own Agg canvas (the backend is not touched): the static parts are drawn once
    and every frame redraws only the moving artists (manual blitting), and the GIF is written by
    Pillow with one palette, so that an 800-frame N is as fast as a 50-frame one."""
    from .store import read_run

    rd = read_run(results_dir)
    path = Path(out) if out is not None else Path(results_dir) / "maneuver.gif"
    return write_animation(rd.result, path, frames=frames, fps=fps)


def write_animation(result: Solution | Comparison, path: Path, frames: int = 100, fps: int = 20) -> Path:
    """The animation of :func:`animate` for a Solution or a Comparison in memory."""
    if frames < 2 or fps < 1:
        raise ValueError("frames must be >= 2 and fps >= 1")
    return Animation(result).save(path, frames, fps)


class Animation:
    """The animated figure of a Solution or a Comparison: ``fig`` (its own Agg canvas), ``frame(t)``
    renders the state at time t as an RGB image, ``save(path, frames, fps)`` writes the GIF."""

    def __init__(self, result: Solution | Comparison):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self._setup(result, Figure, FigureCanvasAgg)

    def _setup(self, result, Figure, FigureCanvasAgg):
        runs = _runs(result)
        problem = runs[0].sol.problem
        model = problem.model
        fig = Figure(figsize=(9.6, 5.4), dpi=100)
        canvas = FigureCanvasAgg(fig)
        gs = fig.add_gridspec(2, 2, width_ratios=(1.45, 1), height_ratios=(1.5, 1), left=0.02, right=0.98, bottom=0.15,
                              top=0.9, wspace=0.12, hspace=0.3)
        ax = fig.add_subplot(gs[:, 0], projection="3d")
        axa = fig.add_subplot(gs[0, 1], projection="3d")
        axt = fig.add_subplot(gs[1, 1])
        for a in (ax, axa):
            a.computed_zorder = False
        first = runs[0].sol
        _, size = _body_points(problem)
        allx = np.vstack([r.sol.trajectory.x for r in runs] + ([np.zeros((1, 3))] if model.mu else []))
        allx = allx[np.all(np.isfinite(allx), axis=1)]
        extent = float(np.ptp(allx, axis=0).max()) if len(allx) else 0.0
        still = not model.mu and extent < size  # a slew without a central body: the body at its own scale
        if model.mu:
            ax.scatter([0], [0], [0], s=120, color="#3b6ea8")
            orb = _orbit_ellipse(first.trajectory.x[0], first.trajectory.v[0], model.mu)
            if orb is not None:
                ax.plot(*orb.T, color="0.55", lw=1, ls=":", label="initial orbit")
                allx = np.vstack([allx, orb])
        target = _target_orbit(problem)
        if target is not None:
            ax.plot(*target.T, color="k", lw=1, ls="--", label="desired orbit")
            allx = np.vstack([allx, target])
        center = 0.5 * (allx.max(0) + allx.min(0)) if not model.mu else np.zeros(3)
        lim = max(np.abs(allx - center).max() * 1.05, 1e-9)
        if not model.mu:
            lim = max(lim, 1.6 * size)
        for run in runs:
            ax.plot(*run.sol.trajectory.x.T, color=run.color, ls=run.ls, lw=1.2, alpha=0.6, label=run.name)
        _cube(ax, lim, center)
        ax.set_xlabel("x₁")
        ax.set_ylabel("x₂")
        ax.set_zlabel("x₃")
        # attitude view: target frame and faint unit sphere
        u, v = np.mgrid[0:2 * np.pi:17j, 0:np.pi:9j]
        axa.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.88", lw=0.4)
        Rd = _target_R(problem)
        if Rd is not None:
            for i in range(3):
                axa.plot(*np.vstack([np.zeros(3), 1.1 * Rd[:, i]]).T, color="k", ls="--", lw=1.2)
                axa.text(*(1.2 * Rd[:, i]), f"e{i + 1}ᵈ", fontsize=8)
        elif isinstance(problem.terminal, TargetOrbit):
            n = problem.terminal.normal
            axa.plot(*np.vstack([-1.1 * n, 1.1 * n]).T, color="k", ls="--", lw=1.2)
        _cones(axa, problem)
        _cube(axa, 1.1)
        for a in (axa.xaxis, axa.yaxis, axa.zaxis):
            a.set_ticklabels([])
        has_target = Rd is not None or isinstance(problem.terminal, TargetOrbit)
        axa.set_title("attitude" + (" (target dashed)" if has_target else ""), fontsize=9)
        # timeline of the control magnitudes (or the attitude error without controls)
        scales = []
        gone = removed(problem)
        shown = [(k, lw, a) for k, w, lw, a in (("u_f", "force", 1.3, 1.0), ("u_m", "moment", 0.9, 0.55)) if w not in gone]
        if len(shown) == 1:  # one control: drawn as strongly as the force would be
            shown = [(shown[0][0], 1.3, 1.0)]
        for run in runs:
            s = run.sol
            if s.controls is not None and shown:
                sc = []
                for key, lw, alpha in shown:
                    nu = np.linalg.norm(getattr(s, key), axis=1)
                    sc.append(max(nu.max(), 1e-300))
                    run.plot_control(axt, nu / sc[-1], lw=lw, alpha=alpha)
                scales.append(sc)
            else:
                E = np.einsum("ji,kjl->kil", Rd if Rd is not None else s.trajectory.R[0], s.trajectory.R)
                ang = np.degrees(rotation_angle(E))
                axt.plot(run.t, ang / max(ang.max(), 1e-300), color=run.color, ls=run.ls, lw=1.3)
        if scales:
            axt.set_ylabel("|u| / max", fontsize=8)
            axt.legend([Line2D([], [], color="0.3", lw=lw, alpha=a) for _, lw, a in shown],
                       [f"|{k}| (max {m:.3g})" for (k, _, _), m in zip(shown, scales[0])], fontsize=7, loc="upper right")
        else:
            axt.set_ylabel(("angle to target" if Rd is not None else "rotation from start") + " / max", fontsize=8)
        axt.set_xlim(first.trajectory.t[0], first.trajectory.t[-1])
        axt.set_ylim(-0.05, 1.15)
        axt.xaxis.set_major_locator(MaxNLocator(nbins=5))
        axt.tick_params(labelsize=7)
        axt.set_xlabel(units(problem).time_label, fontsize=8)
        axt.grid(alpha=0.3)
        handles, labels = ax.get_legend_handles_labels()
        handles += [Line2D([], [], color=c, lw=2) for c in COMP]
        labels += ["body e1", "body e2", "body e3"]
        thrust = bool(scales) and "force" not in gone
        if thrust:
            handles.append(Line2D([], [], color=THRUST, lw=2))
            labels.append("thrust u_f")
        fig.legend(handles, labels, loc="lower left", ncols=5, fontsize=8, frameon=False)
        failed = [r for r in runs if r.failed]
        names = ", ".join(f"{r.name} ({'solid' if r.ls == '-' else 'dashed'})" for r in runs)
        fig.suptitle(f"{problem.name}: {names}" + ("  —  NOT CONVERGED" if failed else ""),
                     x=0.01, ha="left", fontsize=11, color=FAIL if failed else "black")
        # moving artists
        L = 0.6 * lim if still else 0.16 * lim
        scale = L / size
        fmax = max([np.linalg.norm(r.sol.u_f, axis=1).max() for r in runs if r.sol.controls is not None] + [1e-300])
        moving = []

        def line(a, **kw):
            (ln,) = a.plot([], [], [], **kw) if a is not axt else a.plot([], [], **kw)
            moving.append(ln)
            return ln

        art = []
        for run in runs:
            d = {"triad": [line(ax, color=COMP[i], lw=2.2, ls=run.ls, zorder=6) for i in range(3)],
                 "rod": line(ax, color="0.3", lw=3, alpha=0.6, zorder=5) if len(model.markers) else None,
                 "thrust": line(ax, color=THRUST, lw=2.2, ls=run.ls, zorder=7),
                 "head": line(ax, color=THRUST, marker="o", ms=4, ls="", zorder=7),
                 "dot": line(ax, color=run.color, marker="o", ms=5, ls="", zorder=8),
                 "att": [line(axa, color=COMP[i], lw=2.2, ls=run.ls) for i in range(3)]}
            art.append(d)
        cursor = axt.axvline(first.trajectory.t[0], color="k", lw=1)
        moving.append(cursor)
        clock = axt.text(0.015, 0.96, "", transform=axt.transAxes, ha="left", va="top", fontsize=9, family="monospace",
                         bbox=dict(facecolor="white", edgecolor="none", alpha=0.85, pad=1.5))
        moving.append(clock)
        if failed:
            fig.text(0.99, 0.995, "\n".join(f"{r.label}: {r.sol.result.value}" for r in failed), ha="right", va="top",
                     fontsize=9, color="white", fontweight="bold",
                     bbox=dict(boxstyle="round,pad=0.3", facecolor=FAIL, edgecolor="none"))
        for a in moving:
            a.set_animated(True)
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        self.fig, self.canvas, self.background = fig, canvas, background
        self.runs, self.art, self.moving = runs, art, moving
        self.cursor, self.clock, self.L, self.scale, self.lim, self.fmax = cursor, clock, L, scale, lim, fmax
        self.thrust = thrust
        self.model, self.t0, self.t1 = model, float(first.trajectory.t[0]), float(first.trajectory.t[-1])
        self.units = units(problem)

    def frame(self, time_: float) -> np.ndarray:
        """The image (height, width, 3) of the state at time ``time_``."""
        canvas, L, scale, lim, fmax, model = self.canvas, self.L, self.scale, self.lim, self.fmax, self.model
        canvas.restore_region(self.background)
        for run, d in zip(self.runs, self.art):
            s = run.sol
            k = int(np.clip(np.searchsorted(s.trajectory.t, time_), 0, s.N))
            x, R = s.trajectory.x[k], s.trajectory.R[k]
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(R))):
                continue
            for i in range(3):
                tip = x + L * R[:, i]
                d["triad"][i].set_data_3d([x[0], tip[0]], [x[1], tip[1]], [x[2], tip[2]])
                d["att"][i].set_data_3d([0, R[0, i]], [0, R[1, i]], [0, R[2, i]])
            if d["rod"] is not None:
                ends = x + scale * model.markers @ R.T
                d["rod"].set_data_3d(*ends.T)
            d["dot"].set_data_3d([x[0]], [x[1]], [x[2]])
            if s.controls is not None and self.thrust:
                j = int(np.clip(np.searchsorted(s.control_times, time_), 0, len(s.control_times) - 1))
                tip = x + 0.45 * lim * s.u_f[j] / fmax
                d["thrust"].set_data_3d([x[0], tip[0]], [x[1], tip[1]], [x[2], tip[2]])
                d["head"].set_data_3d([tip[0]], [tip[1]], [tip[2]])
        self.cursor.set_xdata([time_, time_])
        self.clock.set_text(f"t = {time_:.3f}" + (" periods" if self.units.normalized else ""))
        for a in self.moving:
            self.fig.draw_artist(a)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def save(self, path: Path, frames: int = 100, fps: int = 20) -> Path:
        """Write the GIF (atomically): ``frames`` images evenly spaced in time, ``fps`` a second,
        one palette for all (from the first, middle and last frames)."""
        import io

        from PIL import Image

        from .io import atomic_write_bytes

        images = [Image.fromarray(self.frame(t)) for t in np.linspace(self.t0, self.t1, frames)]
        sample = [images[0], images[len(images) // 2], images[-1]]
        strip = Image.new("RGB", (sample[0].width * 3, sample[0].height))
        for i, im in enumerate(sample):
            strip.paste(im, (i * im.width, 0))
        palette = strip.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
        frames_p = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
        bio = io.BytesIO()
        frames_p[0].save(bio, format="GIF", save_all=True, append_images=frames_p[1:],
                         duration=int(round(1000 / fps)), loop=0, optimize=False)
        atomic_write_bytes(Path(path), bio.getvalue())
        return Path(path)
