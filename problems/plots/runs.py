"""What a figure draws: :class:`Run`, one method's Solution with its name, colour and line style,
and the runs of a Solution or a Comparison."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ...transcription.results.solution import Solution
from ...transcription.dynamics.trajectory import Trajectory
from ...transcription.solve import Comparison
from .style import COLORS, STYLES


@dataclass
class Run:
    """One method's solution as the figures see it: the Solution, its name, colour and line style."""

    label: str
    sol: Solution
    #: path-constraint margins below -tol are violations (store.path_tolerance); above, round-off
    tol: float = 1e-8

    @classmethod
    def of(cls, sol: Solution, tol: float = 1e-8) -> "Run":
        """The Run of a Solution; a failed one is drawn from :func:`drawable` values."""
        return cls(sol.method, sol if sol.converged else drawable(sol), tol)

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
        """The legend name: the method, the result code when it did not converge, and a mark when
        values of the run could not be drawn (:func:`drawable`)."""
        if not self.failed:
            return self.label
        gaps = "; values beyond 1e100 or not finite left out" if self.sol.stats.get("not_drawn") else ""
        return f"{self.label} (FAILED: {self.sol.result.value}{gaps})"

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


#: a failed run's values beyond this magnitude are not drawn (gaps): matplotlib's scales, ticks and
#: layout overflow on values near the largest double, and a run that ended there shows nothing at that scale
DRAWABLE = 1e100


def drawable(sol: Solution) -> Solution:
    """A copy of a failed Solution whose states, controls, costates and history hold NaN (a gap in
    every figure) where they are not finite or beyond :data:`DRAWABLE`; ``stats['not_drawn']``
    says whether anything was left out (the legend then says so).  The record on disk is not changed."""
    def clean(a):
        if a is None:
            return None, False
        a = np.asarray(a, dtype=float)
        bad = ~(np.abs(a) <= DRAWABLE)
        return (np.where(bad, np.nan, a), True) if bad.any() else (a, False)

    X, bx = clean(sol.trajectory.X)
    U, bu = clean(sol.controls)
    lam, bl = clean(sol.costates)
    history, bh = [], False
    for rec in sol.history:
        changes = {k: math.nan for k, v in rec.as_dict().items()
                   if isinstance(v, float) and not abs(v) <= DRAWABLE and not math.isnan(v)}
        bh |= bool(changes)
        history.append(dataclasses.replace(rec, **changes) if changes else rec)
    if not (bx or bu or bl or bh):
        return sol
    tr = sol.trajectory
    return dataclasses.replace(sol, trajectory=Trajectory(t=tr.t, X=X, mass=tr.mass, inertia=tr.inertia),
                               controls=U, costates=lam, history=history, stats={**sol.stats, "not_drawn": True})


def node_cells(t: np.ndarray) -> np.ndarray:
    """Edges (n+1,) of the cells of node values at times t (n,): half-way to the neighbours, the
    first and last cells ending at t_0 and t_N."""
    t = np.asarray(t, float)
    return np.concatenate([t[:1], 0.5 * (t[:-1] + t[1:]), t[-1:]])


def _runs(result: Solution | Comparison, tol: float | None = None) -> list[Run]:
    """The runs to draw: every method that applies to the problem (not Result.not_applicable);
    ``tol``: the path-constraint tolerance (store.path_tolerance; None: its default)."""
    from ..store import DEFAULT_PATH_TOL
    from ..store import applicable as applicable_methods

    return [Run.of(s, DEFAULT_PATH_TOL if tol is None else tol) for s in applicable_methods(result).values()]
