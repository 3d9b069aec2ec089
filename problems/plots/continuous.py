"""The continuous check's figure (issue 26, docs/mathematics.md §11): how far the plan's controls, flown through the
continuous equations, stray from the plan's own nodes along the path."""
from __future__ import annotations

import numpy as np

from ...transcription.ocp import Problem
from ..units import units
from .runs import Run
from .style import W, _finish, _subplots


def flown(runs: list[Run]) -> list[Run]:
    """The runs whose Solution carries a continuous check with finite deviations."""
    return [r for r in runs if r.sol.continuous is not None and np.isfinite(r.sol.continuous.position_deviation).all()]


def fig_continuous(runs: list[Run], problem: Problem):
    """Position deviation |x(t_k) - x_k| (length unit) and attitude deviation angle(R_k^T R(t_k)) (deg) of the
    continuous flight from the plan's nodes, log scale (node 0 is exact and left out); the terminal values are
    the continuous check's terminal position and attitude misses."""
    un = units(problem)
    moved = any(r.sol.continuous.position_deviation.max() > 0 for r in flown(runs))  # a slew: no position panel
    fig, axs = _subplots(2 if moved else 1, figsize=(W, 5.2 if moved else 3.2))
    for run in flown(runs):
        c = run.sol.continuous
        dx = c.position_deviation * un.factor("length")
        dR = np.degrees(c.attitude_deviation)
        for ax, y in zip(axs, (dx, dR) if moved else (dR,)):
            ax.semilogy(c.t[1:], np.where(y[1:] > 0, y[1:], np.nan), color=run.color, ls=run.ls, lw=1.5,
                        label=f"{run.name} (N = {run.sol.N})")
    if moved:
        axs[0].set_ylabel(un.label("$|x(t_k) - x_k|$", "length"))
    axs[-1].set_ylabel(r"$\angle(R_k^{\mathsf{T}}R(t_k))$ (deg)")
    axs[0].legend(fontsize=8, loc="best")
    for ax in axs:
        ax.grid(alpha=0.3, which="both")
    axs[-1].set_xlabel(un.time_label)
    return _finish(fig, runs, problem, "continuous flight against the plan's nodes")
