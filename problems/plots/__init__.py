"""Figures of a maneuver, drawn from Solutions (in memory, or read back from a results directory).

:func:`figures` takes a Solution or a Comparison and returns {name: matplotlib Figure}; every
figure function takes ``runs`` (one :class:`Run` per method, so that both methods overlay, each
named in a legend) and the Problem, and draws what the Problem carries: control bounds (limit
lines, shading where a bound is active), path constraints (margins with their zero line), the
target (orbit, position, attitude).  A run that did not converge is marked in the title and by a
red corner banner with its result code, so it is never mistaken for a good one.

Importing this package does not choose a matplotlib backend (the CLI picks a non-interactive one
itself; :func:`animate` renders on its own Agg canvas).  Every unit in a label comes from
:func:`problems.units.units` of the Problem: the normalized orbit units (radii, orbital periods) with
a central body of GM = 4π², the dimension only ("mass·length/time²", "time t") without one.

Modules: ``style`` (colours, panels, titles), ``runs`` (:class:`Run`), ``orbits`` (osculating
elements, RTN frame, orbit ellipses; NumPy only), ``targets`` (what the Problem asks for, as drawn),
``views3d`` (maneuver, attitude), ``histories`` (figures against time or iterations), ``catalogue``
(names, captions, drawing into a results directory), ``animation`` (``maneuver.gif``).
"""
from __future__ import annotations

from .animation import Animation, animate, write_animation
from .catalogue import CAPTIONS, FIGURES, applicable, caption, draw, draw_all, draw_run, figures, is_fresh
from .histories import (fig_angular_velocity, fig_attitude_error, fig_constraints, fig_control_norms, fig_convergence, fig_costates, fig_force, fig_moment, fig_orbital_elements, fig_thrust_rtn, fig_velocity, quaternions)
from ..elements import rtn
from .orbits import osculating_elements
from .runs import Run, _runs, node_cells
from .style import BOUND, COLORS, COMP, CONE, FAIL, QUAT, STYLES, THRUST
from .targets import _describe, removed
from .views3d import _body_points, fig_attitude, fig_maneuver

__all__ = ["Animation", "animate", "write_animation", "CAPTIONS", "FIGURES", "applicable", "caption", "draw",
           "draw_all", "draw_run", "figures", "is_fresh", "fig_angular_velocity", "fig_attitude_error", "fig_constraints",
           "fig_control_norms", "fig_convergence", "fig_costates", "fig_force", "fig_moment", "fig_orbital_elements",
           "fig_thrust_rtn", "fig_velocity", "quaternions", "osculating_elements", "rtn", "Run", "_runs", "node_cells",
           "BOUND", "COLORS", "COMP", "CONE", "FAIL", "QUAT", "STYLES", "THRUST", "_describe", "removed",
           "_body_points", "fig_attitude", "fig_maneuver"]
