"""Figures of a maneuver, drawn from Solutions (in memory, or read back from a results directory).

:func:`figures` takes a Solution or a Comparison and returns {name: matplotlib Figure}; every
figure function takes ``runs`` (one :class:`Run` per method, so that both methods overlay) and the
Problem.  Importing this module does not choose a matplotlib backend (the CLI picks a
non-interactive one itself).  Units are the normalized ones of docs/mathematics.md §1: length in
reference-orbit radii, time in orbital periods, mass in body masses.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from ..transcription.problem import Problem, TargetOrbit, TargetState
from ..transcription.results import Solution
from ..transcription.solve import Comparison
from .io import atomic_output, save_figure

COLORS = {"direct": "#1f77b4", "indirect": "#d62728", "impulsive": "#2ca02c", "simulate": "#555555"}
STYLES = {"direct": "-", "indirect": "--", "impulsive": "-", "simulate": "-"}
T_LABEL = "time t (orbital periods)"


@dataclass
class Run:
    """One method's solution as the figures see it: its label, arrays (Solution.arrays) and history."""

    label: str
    arrays: dict[str, np.ndarray]
    summary: dict[str, Any] = field(default_factory=dict)
    history: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def of(cls, sol: Solution) -> "Run":
        return cls(sol.method, sol.arrays(), sol.summary(), [h.as_dict() for h in sol.history])

    @property
    def color(self):
        return COLORS.get(self.label, None)

    @property
    def ls(self):
        return STYLES.get(self.label, "-")




def _orbit_circle(x, v, mu, n=200):
    """The osculating orbit of (x, v) about a point mass mu, as points (n, 3) (ellipse; None if unbound)."""
    x, v = np.asarray(x, float), np.asarray(v, float)
    r = np.linalg.norm(x)
    hvec = np.cross(x, v)
    if np.linalg.norm(hvec) < 1e-12:
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


def _body_points(problem: Problem) -> tuple[np.ndarray, float]:
    """Body-fixed points to draw (the model's markers, or the tips of its principal axes) and a
    characteristic size of the body (the largest point distance)."""
    pts = problem.model.markers
    if not len(pts):
        J = problem.model.inertia
        size = float(np.sqrt(np.trace(J) / problem.model.mass))
        pts = size * np.vstack([np.eye(3), -np.eye(3)])
    return pts, float(np.linalg.norm(pts, axis=1).max())


def fig_maneuver(runs: list[Run], problem: Problem, *, n_bodies: int = 9):
    """3-D maneuver: central body, initial and desired orbits, path, the body drawn at intervals."""
    model = problem.model
    pts, size = _body_points(problem)
    fig = plt.figure(figsize=(6.4, 5.6))
    ax = fig.add_subplot(projection="3d")
    first = runs[0].arrays
    if model.mu is not None:
        ax.scatter([0], [0], [0], s=120, color="#3b6ea8", label="central body")
        orb = _orbit_circle(first["x"][0], first["gamma"][0] / model.mass, model.mu)
        if orb is not None:
            ax.plot(*orb.T, color="0.6", lw=1, ls=":", label="initial orbit")
    term = problem.terminal
    if isinstance(term, TargetOrbit):
        c = _circle(term.radius, term.normal)
        ax.plot(*c.T, color="k", lw=1, ls="--", label="desired orbit")
    elif isinstance(term, TargetState) and "position" in term.fixed:
        xd, vd = term.X[0:3], term.X[3:6] / model.mass
        orb = _orbit_circle(xd, vd, model.mu) if model.mu is not None and "velocity" in term.fixed else None
        if orb is not None:
            ax.plot(*orb.T, color="k", lw=1, ls="--", label="desired orbit")
        ax.scatter(*xd, marker="x", s=60, color="k", label="desired position")
    for run in runs:
        ax.plot(*run.arrays["x"].T, color=run.color, ls=run.ls, lw=1.6, label=f"{run.label} path")
    # the body of the first run, enlarged to be visible at orbit scale
    X, R = first["x"], first["R"]
    span = max(np.ptp(np.vstack([X, [[0, 0, 0]]]), axis=0).max(), 1e-12)
    scale = max(1.0, round(0.05 * span / size))
    idx = np.linspace(0, len(X) - 1, n_bodies).round().astype(int)
    for k in idx:
        ends = X[k] + scale * pts @ R[k].T
        if len(model.markers):
            ax.plot(*ends.T, color="0.2", lw=1.2)
            ax.scatter(*ends.T, s=14, color=["#e67e22", "#8e44ad"][: len(ends)] if len(ends) <= 2 else "#e67e22")
        else:
            for i, col in enumerate(("#d62728", "#2ca02c", "#1f77b4")):
                ax.plot(*np.vstack([X[k], ends[i]]).T, color=col, lw=1.2)
    if "dgamma0" in first:
        for k, key in ((0, "dgamma0"), (-1, "dgammaN")):
            d = np.asarray(first[key], float) / model.mass
            n = np.linalg.norm(d)
            if n > 0:
                L = 0.25 * span * d / n
                ax.quiver(*X[k], *L, color="#c0392b", arrow_length_ratio=0.25, lw=2)
        ax.plot([], [], color="#c0392b", lw=2, label="impulse direction")
    ax.set_xlabel("x₁ (radii)")
    ax.set_ylabel("x₂ (radii)")
    ax.set_zlabel("x₃ (radii)")
    lim = np.abs(np.vstack([X, [[1, 1, 1]]])).max() * 1.05
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1, 1, 1))
    ax.set_title(f"{problem.name}: maneuver ({model.name} drawn ×{scale:.0f})")
    ax.legend(loc="upper left", fontsize=8)
    return fig


def _components(runs, key_fn, ylabel, title, impulses=None):
    fig, axs = plt.subplots(3, 1, figsize=(6.4, 5.6), sharex=True)
    for run in runs:
        t, Y = key_fn(run)
        if Y is None:
            continue
        for i, ax in enumerate(axs):
            ax.plot(t, Y[:, i], color=run.color, ls=run.ls, lw=1.4, label=run.label)
        if impulses is not None:
            jumps = impulses(run)
            if jumps is not None:
                for i, ax in enumerate(axs):
                    for tt, before, after in jumps:
                        ax.plot([tt, tt], [before[i], after[i]], ":", color=run.color, lw=1.2)
                        ax.plot(tt, before[i], "o", mfc="white", color=run.color, ms=5)
                        ax.plot(tt, after[i], "o", color=run.color, ms=5)
    for i, ax in enumerate(axs):
        ax.set_ylabel(ylabel.replace("#", str(i + 1)))  # template, e.g. "$u_{f,#}$"
        ax.grid(alpha=0.3)
        _no_offset(ax)
    axs[0].set_title(title)
    axs[-1].set_xlabel(T_LABEL)
    handles, labels = axs[0].get_legend_handles_labels()
    if len(set(labels)) > 1 or impulses is not None:
        if impulses is not None:
            handles += [plt.Line2D([], [], marker="o", mfc="white", color="0.3", ls=""),
                        plt.Line2D([], [], marker="o", color="0.3", ls=":")]
            labels += ["before impulse", "after impulse"]
        axs[0].legend(handles, labels, fontsize=8, loc="best")
    fig.tight_layout()
    return fig


def _no_offset(ax):
    """Plain tick labels; a (nearly) constant component gets a sensible window."""
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    lo, hi = ax.get_ylim()
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    if half < 1e-6 * max(1.0, abs(mid)):
        w = 0.05 * max(abs(mid), 1e-3)
        ax.set_ylim(mid - w, mid + w)


def fig_velocity(runs, problem: Problem):
    m = problem.model.mass

    def after(run):
        a = run.arrays
        if "dgamma0" not in a:
            return None
        t, g = a["t"], a["gamma"]
        return [(t[0], (g[0] - a["dgamma0"]) / m, g[0] / m), (t[-1], g[-1] / m, (g[-1] + a["dgammaN"]) / m)]

    imp = after if any("dgamma0" in r.arrays for r in runs) else None
    return _components(runs, lambda r: (r.arrays["t"], r.arrays["gamma"] / m), "$v_#$",
                       "velocity v = γ/m, inertial (radii/period)", imp)


def fig_angular_velocity(runs, problem: Problem):
    Jinv = np.linalg.inv(problem.model.inertia)

    def after(run):
        a = run.arrays
        if "dPiN" not in a:
            return None
        t, P = a["t"], a["Pi"]
        return [(t[0], Jinv @ (P[0] - a["dPi0"]), Jinv @ P[0]), (t[-1], Jinv @ P[-1], Jinv @ (P[-1] + a["dPiN"]))]

    imp = after if any("dPiN" in r.arrays for r in runs) else None
    return _components(runs, lambda r: (r.arrays["t"], r.arrays["Pi"] @ Jinv.T), r"$\Omega_#$",
                       "angular velocity Ω = J⁻¹Π, body frame (rad/period)", imp)


def _control_time(run):
    a = run.arrays
    t = a["t"]
    n = len(a["u_f"])
    return t[1:] if n == len(t) - 1 else t  # first-order scheme: u_1..u_N at t_1..t_N


def fig_force(runs, problem: Problem):
    return _components([r for r in runs if "u_f" in r.arrays],
                       lambda r: (_control_time(r), r.arrays["u_f"]), "$u_{f,#}$",
                       "control force u_f, inertial (mass·radii/period²)")


def fig_moment(runs, problem: Problem):
    return _components([r for r in runs if "u_m" in r.arrays],
                       lambda r: (_control_time(r), r.arrays["u_m"]), "$u_{m,#}$",
                       "control moment u_m, body (mass·radii²/period²)")


def _positive(values):
    """Values for a log axis: non-positive or missing entries become NaN (not drawn)."""
    y = np.array([np.nan if v is None else v for v in values], float)
    y[~(y > 0)] = np.nan
    return y


def fig_convergence(runs, problem: Problem):
    """Residual (log) against iterations; for Newton-Armijo every line-search trial, iterations circled."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    drew = False
    for run in runs:
        hist = run.history
        if not hist:
            continue
        if any(h.get("trial", 0) > 0 for h in hist):  # Newton-Armijo: one record per rollout
            errs = _positive([h.get("residual") for h in hist])
            ax.semilogy(np.arange(len(errs)), errs, ".-", color=run.color, lw=1, ms=4,
                        label=f"{run.label}: all line-search trials")
            acc = [i for i, h in enumerate(hist) if h.get("accepted")]
            ax.semilogy(acc, errs[acc], "o", mfc="none", color=run.color, ms=8, label=f"{run.label}: iterations")
        else:  # NLP solver: one record per iteration
            x = np.arange(len(hist))
            for key, mark, lab in (("residual", "-", "primal infeasibility"), ("dual", ":", "dual infeasibility")):
                y = _positive([h.get(key) for h in hist])
                if np.isfinite(y).any():
                    ax.semilogy(x, y, mark, color=run.color, lw=1.4, label=f"{run.label}: {lab}")
        drew = True
    if not drew:
        ax.text(0.5, 0.5, "no iteration history recorded", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("iteration (Newton–Armijo: line-search trial)")
    ax.set_ylabel("residual (log scale)")
    ax.set_title(f"{problem.name}: convergence")
    ax.grid(alpha=0.3, which="both")
    if drew:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


FIGURES = {
    "maneuver": fig_maneuver,
    "velocity": fig_velocity,
    "angular_velocity": fig_angular_velocity,
    "force": fig_force,
    "moment": fig_moment,
    "convergence": fig_convergence,
}


def figures(result: Solution | Comparison, which: tuple[str, ...] | None = None) -> dict:
    """{name: Figure} of a Solution or a Comparison (both methods overlaid), drawn from memory."""
    from .store import applicable

    sols = list(applicable(result).values())
    runs = [Run.of(s) for s in sols]
    problem = sols[0].problem
    out = {}
    for name, fn in FIGURES.items():
        if which and name not in which:
            continue
        if name in ("force", "moment") and not any("u_f" in r.arrays for r in runs):
            continue
        if name == "convergence" and not any(r.history for r in runs):
            continue
        out[name] = fn(runs, problem)
    return out


def draw_all(results_dir: Path, which: tuple[str, ...] | None = None) -> list[Path]:
    """(Re)draw every figure of a results directory as PNG and PDF; returns the paths written."""
    from .store import read_run

    run = read_run(results_dir)
    written = []
    for name, fig in figures(run.result, which).items():
        written += save_figure(fig, Path(results_dir) / f"fig_{name}")
        plt.close(fig)
    return written


def animate(results_dir: Path, frames: int = 80) -> Path:
    """Write an animated GIF of the maneuver (Pillow writer, ships with matplotlib)."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    from .store import read_run

    rd = read_run(results_dir)
    sol = next(iter(rd.solutions.values()))
    problem = sol.problem
    pts, size = _body_points(problem)
    X, R, t = sol.trajectory.x, sol.trajectory.R, sol.trajectory.t
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    lim = np.abs(X).max() * 1.1
    ax.scatter([0], [0], [0], s=100, color="#3b6ea8")
    ax.plot(*X.T, color="0.7", lw=1)
    span = 2 * lim
    scale = max(1.0, 0.03 * span / size)
    (rod,) = ax.plot([], [], [], color="k", lw=2)
    (dots,) = ax.plot([], [], [], "o", color="#e67e22", ms=5)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x₁")
    ax.set_ylabel("x₂")
    ax.set_zlabel("x₃")
    idx = np.linspace(0, len(X) - 1, frames).round().astype(int)

    def update(i):
        k = idx[i]
        ends = X[k] + scale * pts @ R[k].T
        rod.set_data_3d(ends[:, 0], ends[:, 1], ends[:, 2])
        dots.set_data_3d(ends[:, 0], ends[:, 1], ends[:, 2])
        ax.set_title(f"{problem.name} ({sol.method})  t = {t[k]:.3f}")
        return rod, dots

    anim = FuncAnimation(fig, update, frames=len(idx), blit=False)
    out = Path(results_dir) / "maneuver.gif"
    with atomic_output(out) as tmp:
        anim.save(tmp, writer=PillowWriter(fps=20))
    plt.close(fig)
    return out
