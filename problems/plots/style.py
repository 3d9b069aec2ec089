"""The look shared by every figure: colours, figure size, panels with time axes, shading of
the times a condition holds, and the title that marks a failed run (red, with a corner banner).

Importing this module does not choose a matplotlib backend."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import FixedLocator, MaxNLocator

from ...transcription.ocp import Problem
from ..units import units

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


def _shade(ax, edges, mask, color, label=None, alpha=0.15):
    """Shade the cells [edges[i], edges[i+1]] where mask[i] holds (edges: Run.control_edges for
    controls, node_cells(t) for node values), so that the shaded time is the sum of the cells'
    quadrature weights -- for a control at its bound, the time_at_bound of figures_of_merit."""
    if not np.any(mask):
        return
    for n, (i0, i1) in enumerate(_intervals(mask)):
        ax.axvspan(edges[i0], edges[i1 + 1], color=color, alpha=alpha, lw=0,
                   label=label if n == 0 else None, gid="bound-active")


def _subplots(nrows: int, ncols: int = 1, figsize=(W, H), sharex=True, **kw):
    fig, axs = plt.subplots(nrows, ncols, figsize=figsize, sharex=sharex, squeeze=False, layout="constrained", **kw)
    return fig, axs.ravel()


def _time_axes(axs, problem: Problem):
    """Few, non-overlapping time ticks; the time label (in the problem's units) on the lowest axes
    only; grids."""
    scale = max((_abs_max(ax) for ax in axs), default=0.0)
    for ax in axs:
        ax.xaxis.set_major_locator(MaxNLocator(nbins=6))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.grid(alpha=0.3)
        _no_offset(ax, scale)
    axs[-1].set_xlabel(units(problem).time_label)


def _finite_y(ax) -> np.ndarray:
    ys = [np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()]
    return np.concatenate([y[np.isfinite(y)] for y in ys]) if ys else np.zeros(0)


def _abs_max(ax) -> float:
    y = _finite_y(ax)
    return float(np.abs(y).max()) if y.size else 0.0


#: a panel whose values are all below ZERO_REL times the largest value of its figure is drawn as
#: zero; one that varies by less than FLAT_REL of its mean as constant (both relative: a torque of
#: 1e-10 kN·km is a torque, not zero)
ZERO_REL, FLAT_REL = 1e-12, 1e-6


def _no_offset(ax, scale: float = 0.0):
    """Plain tick labels; a (nearly) constant quantity gets a sensible window -- one tick at 0 for a
    quantity that is zero throughout, or round-off against the figure's ``scale`` (its largest
    value), not ±1e-17: precision it does not have."""
    try:
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    except AttributeError:  # a log axis
        return
    ys = _finite_y(ax)
    if not ys.size:
        return
    lo, hi = float(ys.min()), float(ys.max())
    mid, half, amax = 0.5 * (lo + hi), 0.5 * (hi - lo), max(abs(lo), abs(hi))
    if amax <= ZERO_REL * scale:  # also amax == 0
        ax.set_ylim(-1.0, 1.0)
        ax.yaxis.set_major_locator(FixedLocator([0.0]))
        return
    if half < FLAT_REL * abs(mid):
        w = 0.05 * abs(mid)
        ax.set_ylim(mid - w, mid + w)
    elif amax < 1e-3 or amax >= 1e5:
        ax.ticklabel_format(axis="y", style="sci", scilimits=(0, 0))  # 1.5e-10 shown as 1.5 ×1e-10, not 0.000


def _text_width(text: str, size: float, weight: str = "normal") -> float:
    """Width in points of one line of text (no canvas needed)."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextToPath

    return TextToPath().get_text_width_height_descent(text, FontProperties(size=size, weight=weight), ismath=False)[0]


def _finish(fig, runs: list, problem: Problem, what: str):
    """The figure's title (the maneuver and what is shown); a failed run among ``runs`` (the
    :class:`~problems.plots.runs.Run` drawn) marks it (a red title with a line NOT CONVERGED) and
    adds a red banner in the top right corner naming each failed method and its result code.  The
    title is wrapped (and if need be made smaller) so that it never runs into the banner."""
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
