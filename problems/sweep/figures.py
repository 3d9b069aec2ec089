"""The figures of a sweep: the cost against each axis, and a status map of 2-D grids."""
from __future__ import annotations

import io
import itertools
from pathlib import Path

import numpy as np

from ..io import atomic_write_bytes, safe_name
from .run import SweepResult
from .schema import Axis, Sweep, _fmt, _label


def _positions(axis: Axis):
    """x positions and tick labels: the values if numeric, else their indices."""
    if axis.numeric:
        return np.array(axis.values, float), None
    return np.arange(len(axis.values), dtype=float), [_fmt(v) for v in axis.values]


def _save_png(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def draw_sweep(out: Path, result: SweepResult) -> list[Path]:
    """cost_vs_<axis>.png for each axis (one line per method and per combination of the
    other axes, non-converged points marked x); status_map.png for 2-D grids (cost over
    the grid per method, non-converged cells marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sw = result.sweep
    pts = sw.points()
    methods = sw.row_methods()
    cost = {m: np.full(sw.shape, np.nan) for m in methods}
    ok = {m: np.zeros(sw.shape, bool) for m in methods}
    done = {m: np.zeros(sw.shape, bool) for m in methods}
    for r in result.rows:
        c = pts[r["point"]].coords
        cost[r["method"]][c] = r["cost"]
        ok[r["method"]][c] = r["converged"]
        done[r["method"]][c] = True
    written = []
    for i, axis in enumerate(sw.axes):
        fig = _cost_against(sw, i, cost, ok, done)
        written.append(_save_png(fig, Path(out) / f"cost_vs_{safe_name(axis.name)}.png"))
        plt.close(fig)
    if len(sw.axes) == 2:
        fig = _status_map(sw, cost, ok, done)
        written.append(_save_png(fig, Path(out) / "status_map.png"))
        plt.close(fig)
    return written


def _cost_against(sw: Sweep, i: int, cost: dict, ok: dict, done: dict):
    """The cost against axis i: a line per method and per combination of the other axes; the
    points that did not converge marked x.  ``cost``, ``ok``, ``done``: per method, arrays of the
    grid's shape (the cost, converged, finished)."""
    import matplotlib.pyplot as plt

    from ..plots.style import COLORS

    methods = sw.row_methods()
    axis = sw.axes[i]
    x, ticks = _positions(axis)
    fig, axp = plt.subplots(figsize=(6.4, 4.2))
    others = [a for j, a in enumerate(sw.axes) if j != i]
    combos = list(itertools.product(*(range(len(a.values)) for a in others)))
    for m in methods:
        c3 = np.moveaxis(cost[m], i, -1).reshape(-1, len(x))
        k3 = np.moveaxis(ok[m], i, -1).reshape(-1, len(x))
        d3 = np.moveaxis(done[m], i, -1).reshape(-1, len(x))
        for ci, combo in enumerate(combos):
            lab = m if not others else f"{m}: " + _label({a.name: a.values[j] for a, j in zip(others, combo)})
            y = np.where(k3[ci], c3[ci], np.nan)
            axp.plot(x, y, "o-" if m != "indirect" else "s--", color=COLORS.get(m) if len(combos) == 1 else f"C{ci % 10}",
                     ms=4, label=lab if len(combos) * len(methods) <= 12 else None)
            bad = d3[ci] & ~k3[ci]
            if bad.any():
                yb = np.where(np.isfinite(c3[ci][bad]), c3[ci][bad], np.nanmin(np.where(k3[ci], c3[ci], np.nan))
                              if k3[ci].any() else 0.0)
                axp.plot(x[bad], yb, "x", color="k", ms=8, mew=2)
    axp.plot([], [], "x", color="k", ms=8, mew=2, label="not converged")
    if ticks:
        axp.set_xticks(x, ticks)
    axp.set_xlabel(axis.name)
    axp.set_ylabel("cost J")
    axp.set_title(f"{sw.name}: cost against {axis.name}")
    axp.grid(alpha=0.3)
    axp.legend(fontsize=7)
    return fig


def _status_map(sw: Sweep, cost: dict, ok: dict, done: dict):
    """A 2-D grid's cost per method on one colour scale, cells that did not converge (x) or did
    not run (grey square) marked."""
    import matplotlib.pyplot as plt

    methods = sw.row_methods()
    fig, axs = plt.subplots(1, len(methods), figsize=(6.2 * len(methods), 4.6), squeeze=False,
                            layout="constrained")
    nx, ny = len(sw.axes[1].values), len(sw.axes[0].values)
    good = np.concatenate([cost[m][ok[m]] for m in methods])
    lims = dict(vmin=good.min(), vmax=good.max()) if good.size else {}  # one colour scale for all methods
    for axp, m in zip(axs[0], methods):
        Z = np.where(ok[m], cost[m], np.nan)
        ix, iy = np.arange(nx), np.arange(ny)
        im = axp.pcolormesh(ix, iy, np.ma.masked_invalid(Z), shading="nearest", cmap="viridis", **lims)
        fig.colorbar(im, ax=axp, label="cost J")
        bad_y, bad_x = np.nonzero(done[m] & ~ok[m])
        axp.plot(bad_x, bad_y, "x", color="r", ms=12, mew=2.5, label="not converged")
        miss_y, miss_x = np.nonzero(~done[m])
        if miss_x.size:
            axp.plot(miss_x, miss_y, "s", mfc="none", color="0.5", ms=10, label="not run")
        axp.set_xticks(ix, [_fmt(v) for v in sw.axes[1].values], rotation=45)
        axp.set_yticks(iy, [_fmt(v) for v in sw.axes[0].values])
        axp.set_xlabel(sw.axes[1].name)
        axp.set_ylabel(sw.axes[0].name)
        axp.set_title(f"{m}: {int(ok[m].sum())}/{ok[m].size} converged")
        if bad_x.size or miss_x.size:
            axp.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{sw.name}: status map")
    return fig
