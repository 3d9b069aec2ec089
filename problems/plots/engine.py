"""The thrust-direction figure (issue 24; docs/mathematics.md §14): where the applied force points in the body
and how hard the engine pushes -- what a body-fixed engine makes the attitude do."""
from __future__ import annotations

import numpy as np

from ...transcription.ocp import ENGINE_ON_RTOL, Problem, engine_reference
from ..units import units
from .runs import Run
from ..elements import rtn
from .style import BOUND, COMP, THRUST, W, _finish, _shade, _subplots, _time_axes
from .targets import _bound_of


def body_force(run: Run) -> np.ndarray:
    """The applied force in the body frame (n, 3): R_j^T f_j at the node of each control (u_f itself for a
    body-frame force)."""
    R = run.sol.trajectory.R[run.node_of_control]
    return np.einsum("nji,nj->ni", R, run.sol.f_inertial)


def pointing(run: Run, problem: Problem, axis: np.ndarray | None) -> tuple[np.ndarray, list[str]]:
    """The direction the engine points (n, 3): R_j a for a body-fixed engine of axis a, else the applied force's
    direction (nan where it vanishes), at the node of each control -- as cosines with the osculating orbit's
    radial, along-track and normal directions (a central body) or with the inertial axes; and their names."""
    k = run.node_of_control
    tr = run.sol.trajectory
    if axis is not None:
        d = np.einsum("nij,j->ni", tr.R[k], axis)
    else:
        n = np.linalg.norm(run.sol.f_inertial, axis=1)
        d = np.where((n > 0)[:, None], run.sol.f_inertial / np.where(n > 0, n, 1.0)[:, None], np.nan)
    if problem.model.mu:
        return rtn(tr.x[k], tr.v[k], d), ["radial", "along-track", "normal"]
    return d, ["inertial x", "inertial y", "inertial z"]


def fig_thrust_direction(runs: list[Run], problem: Problem):
    """Top: the angle (deg) between the applied force and each body axis e1, e2, e3 (and, dotted, a body-fixed
    engine's axis), drawn where the force exceeds ENGINE_ON_RTOL of its reference (elsewhere the direction is
    undefined: gaps).  Middle: where the engine points -- the angle between the engine axis R a (without an
    engine: the force) and the orbit's radial, along-track and normal directions (inertial axes without a
    central body), the burns shaded: the attitude turning to aim them.  Bottom: |u_f| (in N for a file in km or
    m) against the force bound, the engine-on threshold dotted."""
    runs = [r for r in runs if r.sol.controls is not None]
    un = units(problem)
    f = un.factor("force")
    bound = _bound_of(problem, "force")
    engine = None if bound is None else bound.engine_axis
    fig, axs = _subplots(3, figsize=(W, 7.6), height_ratios=(1, 1.2, 1))
    for run in runs:
        fb = body_force(run)
        n = np.linalg.norm(fb, axis=1)
        on = n > ENGINE_ON_RTOL * engine_reference(bound, run.sol.u_f)
        d = np.where(on[:, None], fb / np.where(n > 0, n, 1.0)[:, None], np.nan)
        many = len(runs) > 1
        for i in range(3):
            run.plot_control(axs[0], np.degrees(np.arccos(np.clip(d[:, i], -1.0, 1.0))), color=COMP[i], lw=1.4,
                             label=f"e{i + 1} ({run.name})" if many else f"body axis e{i + 1}")
        if engine is not None:
            run.plot_control(axs[0], np.degrees(np.arccos(np.clip(d @ engine, -1.0, 1.0))), color="black",
                             ls=":", lw=2.0, label="engine axis" if run is runs[0] else None)
        p, names = pointing(run, problem, engine)
        for i in range(3):
            run.plot_control(axs[1], np.degrees(np.arccos(np.clip(p[:, i], -1.0, 1.0))), color=COMP[i], lw=1.4,
                             label=f"{names[i]} ({run.name})" if many else names[i])
        _shade(axs[1], run.control_edges, on, THRUST, label="engine on" if run is runs[0] else None, alpha=0.12)
        run.plot_control(axs[2], f * n, color=THRUST if run is runs[0] else run.color, lw=1.6,
                         label=f"|u_f| ({run.name})")
    ref = engine_reference(bound, runs[0].sol.u_f) if runs else 0.0
    if bound is not None and bound.norm_limit is not None:
        top = f * bound.norm_limit
        axs[2].axhline(top, color=BOUND, ls="-.", lw=1.2, label=f"bound {top:.3g}")
    if ref > 0:
        axs[2].axhline(f * ENGINE_ON_RTOL * ref, color=BOUND, ls=":", lw=1.0,
                       label=f"engine on above {ENGINE_ON_RTOL:g} of {f * ref:.3g}")
    for ax in axs[:2]:
        ax.set_ylim(0, 180)
        ax.set_yticks([0, 45, 90, 135, 180])
    axs[0].set_ylabel("force to body axis (deg)")
    axs[1].set_ylabel(f"{'engine axis' if engine is not None else 'force'} to (deg)")
    axs[2].set_ylabel(un.label("$|u_f|$", "force"))
    axs[2].set_ylim(bottom=0)
    for ax in axs:
        ax.legend(fontsize=7, loc="best")
    _time_axes(axs, problem)
    return _finish(fig, runs, problem, "thrust direction against the body axes and the orbit, and its magnitude")
