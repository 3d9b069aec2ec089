"""The burns of a plan with a force (docs/mathematics.md §14): where the force is on, what each burn gives (delta-v),
and the propellant it takes when the engine has an exhaust velocity.

A burn is a maximal run of consecutive controls u_f,j with |u_f,j| > threshold * F_ref (F_ref of
:func:`~transcription.ocp.engine_reference`: the largest |u_f| the force bound allows, or the peak |u_f| without a
bound; ``threshold`` defaults to :data:`~transcription.ocp.ENGINE_ON_RTOL` = 1e-3, the threshold of
``engine_on_time``, so the burns' durations add up to it).  Each control j holds over its quadrature cell: the cells
tile [t_0, t_N] with widths the quadrature weights omega_j of the plan's delta-v (:func:`~.check.delta_v`): the
trapezoid's half-steps about a node for the LGVI (u_0..u_N), the step before t_j for first_order (u_1..u_N).  A burn
runs from the first cell's left edge to the last cell's right edge (for the LGVI the midpoints between the nodes,
as the switching times of a norm bound), so its duration is sum_j omega_j over it, and

    delta_v = sum_j omega_j |u_f,j| / m,  mean thrust = sum_j omega_j |u_f,j| / duration,  peak = max_j |u_f,j|,
    propellant = m delta_v / c  (c = Isp g0 the exhaust velocity; mass flow |u_f| / c)

over the burn, in the problem's units.  The nodes between burns (|u_f| <= the threshold) carry the rest of the
plan's delta-v: the burns' delta-v and theirs add up to the plan's to round-off.  The dynamics keep the mass
constant: the propellant is the plan's impulse over c, the rocket equation's m (1 - exp(-delta_v / c)) to first
order in delta_v / c.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..ocp import ENGINE_ON_RTOL, engine_reference
from .check import control_weights


@dataclass(frozen=True)
class Burn:
    """One burn, in the problem's units: start, stop (time: the edges of its first and last controls' quadrature
    cells), duration = stop - start = sum_j omega_j, delta_v (velocity), mean_thrust, peak_thrust (force: the
    impulse over the duration, the largest |u_f,j|), propellant (mass; nan when the engine has no exhaust
    velocity), nodes (how many controls)."""

    start: float
    stop: float
    duration: float
    delta_v: float
    mean_thrust: float
    peak_thrust: float
    propellant: float
    nodes: int


def burn_table(u_f: np.ndarray, weights: np.ndarray, t0: float, mass: float, reference: float,
               threshold: float = ENGINE_ON_RTOL, exhaust_velocity: float | None = None) -> tuple[Burn, ...]:
    """The :class:`Burn` s of force controls u_f (n, 3) with quadrature weights (n,) (cells tiling [t0, t0 + sum
    omega]), the body's ``mass``, on above ``threshold`` * ``reference`` (F_ref > 0; with F_ref = 0 nothing burns),
    propellant with ``exhaust_velocity`` c > 0 (None: nan).  Pure."""
    nf = np.linalg.norm(np.asarray(u_f, dtype=float), axis=1)
    om = np.asarray(weights, dtype=float)
    edges = t0 + np.r_[0.0, np.cumsum(om)]
    on = nf > threshold * reference if reference > 0 else np.zeros(nf.shape, bool)
    flips = np.flatnonzero(np.diff(np.r_[0, on.astype(np.int8), 0]))     # starts and (exclusive) ends of the runs
    out = []
    for a, b in zip(flips[::2], flips[1::2]):
        impulse = float(om[a:b] @ nf[a:b])
        duration = float(edges[b] - edges[a])
        dv = impulse / mass
        out.append(Burn(start=float(edges[a]), stop=float(edges[b]), duration=duration, delta_v=dv,
                        mean_thrust=impulse / duration if duration > 0 else float("nan"),
                        peak_thrust=float(nf[a:b].max()),
                        propellant=impulse / exhaust_velocity if exhaust_velocity else float("nan"), nodes=int(b - a)))
    return tuple(out)


def burns(sol, threshold: float = ENGINE_ON_RTOL) -> tuple[Burn, ...]:
    """The burns of a Solution's force controls (module docstring), above ``threshold`` of F_ref (the force bound
    of its Problem's control, the peak |u_f| without one); its engine's exhaust velocity for the propellant.  ()
    without smooth controls (an impulsive plan, a simulation) or with the force removed."""
    if sol.controls is None or sol.u_f.shape[0] == 0:
        return ()
    bound = getattr(getattr(sol.problem, "control", None), "force_bound", None)
    return burn_table(sol.u_f, control_weights(sol), float(sol.trajectory.t[0]), sol.trajectory.mass,
                      engine_reference(bound, sol.u_f), threshold, None if bound is None else bound.exhaust_velocity)
