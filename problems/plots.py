"""Figures of a maneuver, in the style of the paper's Figs. 1-4, drawn from saved results.

Every function takes ``runs``: a list of :class:`Run` (one per method, so that
``compare`` overlays them) and returns a matplotlib Figure.  Units are the
normalized ones of SPEC §1: length in reference-orbit radii, time in orbital
periods, mass in dumbbell masses.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .dumbbell import Dumbbell  # noqa: E402
from .io import save_figure  # noqa: E402

COLORS = {"direct": "#1f77b4", "indirect": "#d62728", "impulsive": "#2ca02c", "simulate": "#555555"}
STYLES = {"direct": "-", "indirect": "--", "impulsive": "-", "simulate": "-"}
T_LABEL = "time t (orbital periods)"


@dataclass
class Run:
    """One method's saved result: arrays of its .npz and its summary block."""

    label: str
    arrays: dict[str, np.ndarray]
    summary: dict[str, Any] = field(default_factory=dict)
    history: list[dict[str, Any]] = field(default_factory=list)

    @property
    def color(self):
        return COLORS.get(self.label, None)

    @property
    def ls(self):
        return STYLES.get(self.label, "-")


def _body(config: dict) -> Dumbbell:
    m = config.get("model", {})
    return Dumbbell(mass=m.get("mass", 1.0), length=m.get("length", 0.1),
                    sphere_radius=m.get("sphere_radius", 0.02), mu=m.get("mu", Dumbbell().mu))


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


def fig_maneuver(runs: list[Run], config: dict, *, n_bodies: int = 9):
    """3-D maneuver: central body, initial and desired orbits, path, dumbbell drawn at intervals."""
    body = _body(config)
    fig = plt.figure(figsize=(6.4, 5.6))
    ax = fig.add_subplot(projection="3d")
    ax.scatter([0], [0], [0], s=120, color="#3b6ea8", label="central body")
    first = runs[0].arrays
    x0, v0 = first["x"][0], first["gamma"][0] / body.mass
    orb = _orbit_circle(x0, v0, body.mu)
    if orb is not None:
        ax.plot(*orb.T, color="0.6", lw=1, ls=":", label="initial orbit")
    term = config.get("terminal") or {}
    if "orbit" in term:
        c = _circle(term["orbit"]["radius"], term["orbit"]["normal"])
        ax.plot(*c.T, color="k", lw=1, ls="--", label="desired orbit")
    elif "position" in term:
        orb = _orbit_circle(term["position"], term["velocity"], body.mu)
        if orb is not None:
            ax.plot(*orb.T, color="k", lw=1, ls="--", label="desired orbit")
        ax.scatter(*np.asarray(term["position"], float), marker="x", s=60, color="k", label="desired position")
    scale = 1.0
    for run in runs:
        X, R = run.arrays["x"], run.arrays["R"]
        ax.plot(*X.T, color=run.color, ls=run.ls, lw=1.6, label=f"{run.label} path")
    # dumbbells of the first run, enlarged to be visible at orbit scale
    X, R = first["x"], first["R"]
    span = np.ptp(np.vstack([X, [[0, 0, 0]]]), axis=0).max()
    scale = max(1.0, round(0.1 * span / body.length))
    idx = np.linspace(0, len(X) - 1, n_bodies).round().astype(int)
    for k in idx:
        ends = np.array([X[k] + scale * R[k] @ q for q in body.rho])
        ax.plot(*ends.T, color="0.2", lw=1.2)
        ax.scatter(*ends.T, s=14, color=["#e67e22", "#8e44ad"])
    if "dgamma0" in first:
        for k, key in ((0, "dgamma0"), (-1, "dgammaN")):
            d = np.asarray(first[key], float) / body.mass
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
    ax.set_title(f"{config.get('name', '')}: maneuver (dumbbell drawn ×{scale:.0f})")
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


def fig_velocity(runs, config):
    m = _body(config).mass

    def after(run):
        a = run.arrays
        if "dgamma0" not in a:
            return None
        t, g = a["t"], a["gamma"]
        return [(t[0], (g[0] - a["dgamma0"]) / m, g[0] / m), (t[-1], g[-1] / m, (g[-1] + a["dgammaN"]) / m)]

    imp = after if any("dgamma0" in r.arrays for r in runs) else None
    return _components(runs, lambda r: (r.arrays["t"], r.arrays["gamma"] / m), "$v_#$",
                       "velocity v = γ/m, inertial (radii/period)", imp)


def fig_angular_velocity(runs, config):
    Jinv = np.linalg.inv(_body(config).inertia)

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


def fig_force(runs, config):
    return _components([r for r in runs if "u_f" in r.arrays],
                       lambda r: (_control_time(r), r.arrays["u_f"]), "$u_{f,#}$",
                       "control force u_f, inertial (mass·radii/period²)")


def fig_moment(runs, config):
    return _components([r for r in runs if "u_m" in r.arrays],
                       lambda r: (_control_time(r), r.arrays["u_m"]), "$u_{m,#}$",
                       "control moment u_m, body (mass·radii²/period²)")


def _positive(values):
    """Values for a log axis: non-positive or missing entries become NaN (not drawn)."""
    y = np.array([np.nan if v is None else v for v in values], float)
    y[~(y > 0)] = np.nan
    return y


def fig_convergence(runs, config):
    """Error (log) against iterations; for Newton-Armijo every line-search trial, outer iterations marked."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    drew = False
    for run in runs:
        hist = run.history
        if not hist:
            continue
        if any("trial" in h for h in hist):  # Newton-Armijo: one record per trial
            errs = _positive([h.get("error", np.nan) for h in hist])
            ax.semilogy(np.arange(len(errs)), errs, ".-", color=run.color, lw=1, ms=4,
                        label=f"{run.label}: all line-search trials")
            acc = [i for i, h in enumerate(hist) if h.get("accepted")]
            ax.semilogy(acc, errs[acc], "o", mfc="none", color=run.color, ms=8,
                        label=f"{run.label}: outer iterations")
        else:  # NLP solver or Newton: one record per iteration
            it = np.array([h.get("iter", i) for i, h in enumerate(hist)])
            for key, mark, lab in (("inf_pr", "-", "primal infeasibility"), ("inf_du", ":", "dual infeasibility"),
                                   ("residual_inf", "-", "residual (max norm)")):
                y = _positive([h.get(key, np.nan) for h in hist])
                if np.isfinite(y).any():
                    ax.semilogy(it, y, mark, color=run.color, lw=1.4, label=f"{run.label}: {lab}")
        drew = True
    if not drew:
        ax.text(0.5, 0.5, "no iteration history recorded", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("iteration (Newton–Armijo: line-search trial)")
    ax.set_ylabel("error (log scale)")
    ax.set_title(f"{config.get('name', '')}: convergence")
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


def load_runs(results_dir: Path) -> tuple[list[Run], dict, dict]:
    """Read a results directory: (runs, resolved config, summary)."""
    import yaml

    d = Path(results_dir)
    summary = json.loads((d / "summary.json").read_text())
    config = yaml.safe_load((d / "config.resolved.yaml").read_text())
    runs = []
    for label in ("direct", "indirect", "impulsive"):
        p = d / f"{label}.npz"
        if p.exists():
            with np.load(p) as z:
                arrays = {k: z[k] for k in z.files}
            block = summary.get("methods", {}).get(label, {})
            runs.append(Run(label, arrays, block, block.get("history", [])))
    if not runs and (d / "trajectory.npz").exists():
        with np.load(d / "trajectory.npz") as z:
            runs.append(Run("simulate", {k: z[k] for k in z.files}, summary))
    return runs, config, summary


def draw_all(results_dir: Path, which: tuple[str, ...] | None = None) -> list[Path]:
    """(Re)draw every figure of a results directory as PNG and PDF; returns the paths written."""
    runs, config, _ = load_runs(results_dir)
    if not runs:
        raise FileNotFoundError(f"{results_dir}: no direct.npz, indirect.npz, impulsive.npz or trajectory.npz")
    written = []
    for name, fn in FIGURES.items():
        if which and name not in which:
            continue
        if name in ("force", "moment") and not any("u_f" in r.arrays for r in runs):
            continue
        if name == "convergence" and not any(r.history for r in runs):
            continue
        fig = fn(runs, config)
        written += save_figure(fig, Path(results_dir) / f"fig_{name}")
        plt.close(fig)
    return written


def animate(results_dir: Path, frames: int = 80) -> Path:
    """Write an animated GIF of the maneuver (Pillow writer, ships with matplotlib)."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    runs, config, _ = load_runs(results_dir)
    body = _body(config)
    run = runs[0]
    X, R = run.arrays["x"], run.arrays["R"]
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    lim = np.abs(X).max() * 1.1
    ax.scatter([0], [0], [0], s=100, color="#3b6ea8")
    ax.plot(*X.T, color="0.7", lw=1)
    span = 2 * lim
    scale = max(1.0, 0.06 * span / body.length)
    (rod,) = ax.plot([], [], [], color="k", lw=2)
    (pts,) = ax.plot([], [], [], "o", color="#e67e22", ms=5)
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
        ends = np.array([X[k] + scale * R[k] @ q for q in body.rho])
        rod.set_data_3d(ends[:, 0], ends[:, 1], ends[:, 2])
        pts.set_data_3d(ends[:, 0], ends[:, 1], ends[:, 2])
        ax.set_title(f"{config.get('name', '')}  t = {run.arrays['t'][k]:.3f}")
        return rod, pts

    anim = FuncAnimation(fig, update, frames=len(idx), blit=False)
    out = Path(results_dir) / "maneuver.gif"
    tmp = Path(results_dir) / ".maneuver.gif.tmp.gif"
    anim.save(tmp, writer=PillowWriter(fps=20))
    tmp.replace(out)
    plt.close(fig)
    return out
