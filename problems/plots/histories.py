"""The figures against time (attitude error, velocities, controls, orbital elements, costates,
path-constraint margins) and against iterations (convergence)."""
from __future__ import annotations

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from ...transcription.geometry.so3 import quaternions, rotation_angle
from ...transcription.ocp import MaxAngularRate, MinRadius, Problem
from ...transcription.results.solution import figures_of_merit
from ..units import units
from ..elements import rtn
from .orbits import osculating_elements
from .runs import Run, node_cells
from .style import BOUND, COMP, FAIL, QUAT, W, _finish, _shade, _subplots, _time_axes
from .targets import _bound_of, _describe, _target_elements, _target_R, removed


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


def _components(runs, problem, key_fn, ylabels, what, bound=None, impulses=None, controls=False, quantity=None):
    """Three stacked component plots, methods overlaid; a box (an actuator bounding each component) draws ±b_i
    and shades where a component is at its limit.  ``controls``: the values are the run's controls (drawn by
    Run.plot_control: per-step controls as steps).  ``quantity``: the values are drawn times
    ``units(problem).factor(quantity)`` (a km file's kN in N), bounds too."""
    f = units(problem).factor(quantity) if quantity else 1.0
    box = None if bound is None or bound.removed else bound.variable_box()
    fig, axs = _subplots(3, figsize=(W, 6.0))
    for run in runs:
        t, Y = key_fn(run)
        if Y is None:
            continue
        for i, ax in enumerate(axs):
            if controls:
                run.plot_control(ax, f * Y[:, i], lw=1.5, label=run.name)
            else:
                ax.plot(t, f * Y[:, i], color=run.color, ls=run.ls, lw=1.5, label=run.name)
        if box is not None:
            for i, ax in enumerate(axs):
                _shade(ax, run.control_edges, bound.active_channels(Y)[:, i], run.color,
                       label=f"{run.label} at bound")
        if impulses is not None:
            jumps = impulses(run)
            if jumps is not None:
                for i, ax in enumerate(axs):
                    for tt, before, after in jumps:
                        ax.plot([tt, tt], [before[i], after[i]], ":", color=run.color, lw=1.2)
                        ax.plot(tt, before[i], "o", mfc="white", color=run.color, ms=5)
                        ax.plot(tt, after[i], "o", color=run.color, ms=5)
    if box is not None:
        for i, ax in enumerate(axs):
            for sgn in (1, -1):
                ax.axhline(sgn * f * box[1][i], color=BOUND, ls="-.", lw=1.1, gid="bound-line",
                           label=f"bound ±{f * box[1][i]:.3g}" if sgn > 0 else None)
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


#: per control: its Solution attribute, component symbol and title
_CONTROL_FIGURES = {"force": ("u_f", "f", "control force u_f, {frame} components"),
                    "moment": ("u_m", "m", "control moment u_m, body components")}


def _control_components(runs, problem: Problem, which: str):
    """The components of one control ('force' or 'moment') against time, with its bound."""
    attr, sym, title = _CONTROL_FIGURES[which]
    return _components([r for r in runs if r.sol.controls is not None], problem, lambda r: (r.tu, getattr(r.sol, attr)),
                       [f"$u_{{{sym},{i}}}$" for i in (1, 2, 3)],
                       units(problem).label(title.format(frame=problem.disc.force_frame), which),
                       bound=_bound_of(problem, which), controls=True, quantity=which)


def fig_force(runs, problem: Problem):
    return _control_components(runs, problem, "force")


def fig_moment(runs, problem: Problem):
    return _control_components(runs, problem, "moment")


def _active(u: np.ndarray, bound) -> np.ndarray:
    return bound.active(u)


def fig_control_norms(runs, problem: Problem):
    """|u_f| and |u_m| over time: a bound on |u| (a norm, an engine's max) is a line; where a bound is active
    the time is shaded, so the switching structure (bang-bang, saturated arcs) reads at a glance.
    A control removed by a norm bound of 0 gets no panel (it is absent, not "at its bound")."""
    runs = [r for r in runs if r.sol.controls is not None]
    un = units(problem)
    gone = removed(problem)
    panels = [(w, k, f"$|{k}|$") for w, k in (("force", "u_f"), ("moment", "u_m")) if w not in gone]
    fig, axs = _subplots(len(panels), figsize=(W, 5.2 if len(panels) == 2 else 3.4))
    for ax, (which, key, ylab) in zip(axs, panels):
        bound = _bound_of(problem, which)
        f = un.factor(which)  # drawn in the shown unit (a km file's kN in N); activity on the file's values
        for run in runs:
            u = getattr(run.sol, key)
            run.plot_control(ax, f * np.linalg.norm(u, axis=1), lw=1.6, label=run.name)
            if bound is not None:
                act = _active(u, bound)
                tab = figures_of_merit(run.sol).get(f"{which}_time_at_bound", float("nan"))
                _shade(ax, run.control_edges, act, run.color,
                       label=f"{run.label} at bound ({un.duration(tab)})" if bound.norm_limit is not None else
                       f"{run.label}: a component at its bound ({un.duration(tab)})")
        if bound is not None and bound.norm_limit is not None:
            ax.axhline(f * bound.norm_limit, color=BOUND, ls="-.", lw=1.2, gid="bound-line",
                       label=f"bound {bound.describe('u', f)}")
        elif bound is not None and bound.variable_box() is not None:  # |u| reaches |b| only with every component at its bound
            nb = f * bound.largest_norm()
            ax.axhline(nb, color=BOUND, ls=":", lw=1.2, label=f"|b| = {nb:.3g}: every component at its bound")
            ax.plot([], [], ls="", label=f"box bound {bound.describe('u', f)}: see {which}")
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
        return run.tu, rtn(s.trajectory.x[k], s.trajectory.v[k], s.f_inertial)   # the applied (inertial) force

    return _components([r for r in runs if r.sol.controls is not None], problem, comp,
                       ["radial $u_R$", "along-track $u_T$", "normal $u_N$"],
                       units(problem).label("control force in the orbit frame: radial, along-track, normal", "force"),
                       controls=True, quantity="force")


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
    _min_radius_lines(axs[0], problem)
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


def _min_radius_lines(ax, problem: Problem) -> None:
    """Each MinRadius as a line -- when it lies within the radii drawn widened by their own span on
    either side; a limit far below (the Earth's radius under a 10 km raise) is named in the legend
    only, so that it does not stretch the axis until the maneuver is a flat line."""
    ys = np.concatenate([np.asarray(ln.get_ydata(), float) for ln in ax.get_lines()] or [np.zeros(0)])
    ys = ys[np.isfinite(ys)]
    lo, hi = (float(ys.min()), float(ys.max())) if ys.size else (-np.inf, np.inf)
    span = hi - lo
    for c in problem.constraints:
        if not isinstance(c, MinRadius):
            continue
        if lo - span <= c.radius <= hi + span:
            ax.axhline(c.radius, color=BOUND, ls="-.", lw=1.1, gid="bound-line", label=f"min radius {c.radius:.6g}")
        else:
            ax.plot([], [], color=BOUND, ls="-.", lw=1.1,
                    label=f"min radius {c.radius:.6g} ({'below' if c.radius < lo else 'above'} the axis)")


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
