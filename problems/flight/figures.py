"""The figures of a Monte Carlo flight (PNG and PDF each):

* ``flight_miss``: terminal misses, one row per feedback mode -- the position miss in the target orbit's
  RTN frame (radial-along-track, along-track-normal; inertial axes without a central motion) and the
  attitude error (body rotation vector, deg), each with its 3-sigma ellipse (mean + 3 sqrt of the
  covariance's eigenvalues along its eigenvectors);
* ``flight_histograms``: log10 of the position, attitude and rate misses and the delta-v overhead, modes overlaid;
* ``flight_tracks``: the position and attitude deviation from the plan's nodes of the first 20 runs;
* ``flight_controls``: the applied controls of the first 20 runs against the actuators' bounds (solid)
  and the plan's (dashed, with a bounds margin);
* ``flight_navigation`` (with navigation): the LQR flights' terminal misses beside their RMS estimation errors.

Figures are made with matplotlib's Figure (no pyplot, no backend chosen)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..io import save_figure
from ..units import units
from .run import FlightResult

MODE_COLORS = {"none": "#e66101", "lqr": "#5e3c99", "mpc": "#1b9e77"}
MODE_LABELS = {"none": "open loop", "lqr": "LQR", "mpc": "MPC"}



def _titled(fig: Figure, result: FlightResult, what: str) -> Figure:
    """``fig`` titled '<maneuver>: <what>' and laid out."""
    fig.suptitle(f"{result.maneuver.name}: {what}")
    fig.tight_layout()
    return fig


def draw_flights(out: Path, result: FlightResult) -> list[Path]:
    """Every figure of the module into ``out``; returns the files written."""
    written = []
    for name, draw in (("flight_miss", _miss), ("flight_histograms", _histograms), ("flight_tracks", _tracks),
                       ("flight_controls", _controls), ("flight_navigation", _navigation)):
        fig = draw(result)
        if fig is not None:
            written += save_figure(fig, Path(out) / name)
    return written


def ellipse(points: np.ndarray, k: float = 3.0, n: int = 120) -> np.ndarray | None:
    """The k-sigma ellipse (n, 2) of 2-D points (m, 2) about their mean; None for fewer than 3 points."""
    if len(points) < 3:
        return None
    C = np.cov(points.T)
    w, V = np.linalg.eigh(C)
    a = np.linspace(0.0, 2.0 * np.pi, n)
    circle = np.stack([np.cos(a), np.sin(a)], axis=1)
    return points.mean(axis=0) + k * (circle * np.sqrt(np.maximum(w, 0.0))) @ V.T


def _ok(result: FlightResult, mode: str) -> list:
    return [r for r in result.rows if r["feedback"] == mode and r["status"] == "ok"]


def _miss(result: FlightResult) -> Figure:
    modes = result.spec.modes
    u = units(result.maneuver.problem)
    names = dict(zip(("miss_r", "miss_t", "miss_n"), ("R", "T", "N") if result.plan["miss_frame"] == "RTN"
                     else ("x", "y", "z")))
    panels = (("miss_r", "miss_t"), ("miss_t", "miss_n"), ("attitude_x_deg", "attitude_y_deg"))
    fig = Figure(figsize=(11.0, 3.4 * len(modes)))
    for i, mode in enumerate(modes):
        rows = _ok(result, mode)
        for j, (a, b) in enumerate(panels):
            ax = fig.add_subplot(len(modes), 3, 3 * i + j + 1)
            pts = np.array([[r[a], r[b]] for r in rows], float).reshape(-1, 2)
            ax.scatter(pts[:, 0], pts[:, 1], s=6, color=MODE_COLORS[mode], alpha=0.6)
            e = ellipse(pts)
            if e is not None:
                ax.plot(e[:, 0], e[:, 1], color="k", lw=1.0, label="3σ")
                ax.legend(loc="upper right", fontsize=7)
            if a in names:
                ax.set_xlabel(u.label(f"{names[a]} miss", "length"))
                ax.set_ylabel(u.label(f"{names[b]} miss", "length"))
            else:
                ax.set_xlabel("attitude error x (deg)")
                ax.set_ylabel("attitude error y (deg)")
            ax.set_title(f"{MODE_LABELS[mode]}: {len(rows)} runs", fontsize=9)
            ax.ticklabel_format(style="sci", scilimits=(-3, 3))
    return _titled(fig, result, f"terminal misses (position in the "
                             f"{'target orbit' + chr(39) + 's RTN' if result.plan['miss_frame'] == 'RTN' else 'inertial'} frame)")


def _histograms(result: FlightResult) -> Figure:
    cols = (("position_miss", "position miss"), ("attitude_miss_deg", "attitude miss (deg)"),
            ("rate_miss", "rate miss"), ("delta_v_overhead", "delta-v overhead"))
    fig = Figure(figsize=(11.0, 3.2))
    for j, (c, label) in enumerate(cols):
        ax = fig.add_subplot(1, 4, j + 1)
        data = {}
        for mode in result.spec.modes:
            a = np.array([r[c] for r in _ok(result, mode)], float)
            a = a[np.isfinite(a)]
            data[mode] = 100.0 * a if c == "delta_v_overhead" else np.log10(np.maximum(a, 1e-300))
        both = np.concatenate(list(data.values()))
        bins = np.linspace(both.min(), both.max() + (both.max() == both.min()), 41) if both.size else 10
        for mode, a in data.items():
            if a.size:
                ax.hist(a, bins=bins, color=MODE_COLORS[mode], alpha=0.6, label=MODE_LABELS[mode])
        ax.set_xlabel(f"{label} (%)" if c == "delta_v_overhead" else f"log10 {label}")
        if both.size:
            ax.legend(fontsize=7)
    return _titled(fig, result, f"{result.finished_runs} runs")


def _navigation(result: FlightResult) -> Figure | None:
    """With navigation: log10 histograms of the LQR flights' terminal misses beside their RMS estimation errors."""
    rows = _ok(result, "lqr")
    if result.spec.navigation is None or not rows:
        return None
    u = units(result.maneuver.problem)
    panels = (("position_miss", "estimation_position", "position", "length"),
              ("velocity_miss", "estimation_velocity", "velocity", "velocity"),
              ("attitude_miss_deg", "estimation_attitude_deg", "attitude", "angle"),
              ("rate_miss", "estimation_rate", "rate", "angular_rate"))
    fig = Figure(figsize=(11.0, 3.2))
    for j, (miss, est, label, q) in enumerate(panels):
        ax = fig.add_subplot(1, 4, j + 1)
        for key, what, color in ((miss, "terminal miss", MODE_COLORS["lqr"]), (est, "RMS estimate error", "#4daf4a")):
            a = np.array([r[key] for r in rows], float)
            a = a[np.isfinite(a) & (a > 0)]
            if a.size:
                ax.hist(np.log10(a), bins=30, color=color, alpha=0.6, label=what)
        ax.set_xlabel(f"log10 {u.label(label, q)}")
        ax.legend(fontsize=7)
    return _titled(fig, result, f"LQR with navigation ({result.spec.navigation['estimator']}): misses and estimation errors")


def _tracks(result: FlightResult) -> Figure | None:
    if not result.tracks:
        return None
    t = result.gains.t
    u = units(result.maneuver.problem)
    fig = Figure(figsize=(10.0, 4.0))
    axes = [fig.add_subplot(1, 2, k + 1) for k in range(2)]
    for i, run in sorted(result.tracks.items()):
        for mode, tr in run.items():
            kw = dict(color=MODE_COLORS[mode], lw=0.7, alpha=0.7, label=MODE_LABELS[mode] if i == min(result.tracks)
                      else None)
            axes[0].semilogy(t, np.maximum(tr["dx"], 1e-300), **kw)
            axes[1].semilogy(t, np.maximum(tr["dR_deg"], 1e-300), **kw)
    axes[0].set_ylabel(u.label("|x - x_plan|", "length"))
    axes[1].set_ylabel("angle(R_plan^T R) (deg)")
    for ax in axes:
        ax.set_xlabel(u.time_label)
        ax.legend(fontsize=7)
    return _titled(fig, result, f"deviation from the plan, first {len(result.tracks)} runs")


def _controls(result: FlightResult) -> Figure | None:
    if not result.tracks:
        return None
    g = result.gains
    control = result.maneuver.problem.control
    mode = result.spec.modes[-1]
    fig = Figure(figsize=(10.0, 4.0))
    un = units(result.maneuver.problem)
    for j, (name, sl, act, planned) in enumerate((("force", slice(0, 3), g.force_bound, control.force_bound),
                                                  ("moment", slice(3, 6), g.moment_bound, control.moment_bound))):
        ax = fig.add_subplot(1, 2, j + 1)
        f = un.factor(name)     # a km file's kN drawn in N, its kN·km in N·m
        for i, run in sorted(result.tracks.items()):
            tr = run.get(mode)
            if tr is None:
                continue
            tt, uu = tr["control_t"].ravel(), tr["control"][..., sl].reshape(-1, 3)
            y = act.magnitude(uu) if act is not None else np.linalg.norm(uu, axis=1)
            ax.plot(tt, f * y, color=MODE_COLORS[mode], lw=0.6, alpha=0.6)
        for b, style in ((act, "-"), (planned, "--")):
            if b is not None and b.scale() > 0:
                ax.axhline(f * b.scale(), color="#444444", ls=style, lw=1.0)
        ax.set_xlabel(un.time_label)
        ax.set_ylabel(un.label(f"{name} {act.magnitude_label if act is not None else '|u|'}", name))
        bounded = act is not None
        ax.set_title(f"{name}: {MODE_LABELS[mode]}" + (", actuators' bound solid, plan's dashed" if bounded
                                                       else " (unbounded)"), fontsize=9)
    return _titled(fig, result, f"control usage, first {len(result.tracks)} runs")
