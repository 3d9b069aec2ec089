"""The optimal control problem: physics, boundary conditions and cost -- no method.

A :class:`Problem` is what every method solves (the method is chosen at ``solve`` time): numbers and a
:class:`~transcription.dynamics.lgvi.Discretization` (body model and scheme: both methods solve the *same* discrete
problem).  States are 18-vectors (:mod:`transcription.geometry.state`; momenta, not velocities:
``state_from_velocities``).  The terminal conditions and costs are defined here once for every method, the
re-simulation and the reports (docs/mathematics.md §5-§6):

* :func:`terminal_residual` -- [x_N - x_d; gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d]
  (the components a target leaves free are dropped), CasADi or NumPy alike;
* :func:`orbit_conditions` -- the relaxed target (any point of a circular orbit);
* :func:`rendezvous_residual` -- a target moving on a circular orbit, met at the final time;
* :func:`quadrature_weights` and :func:`effort_cost` -- sum_j omega_j (1/2) u_j^T W u_j;
* :func:`impulse_cost` -- the sum of the impulse norms.

Modules: :mod:`.targets`, :mod:`.actuators`, :mod:`.controls`, :mod:`.constraints`, :mod:`.problem`,
:mod:`.conditions`, :mod:`.costs`, :mod:`.objective`; every name is importable from the package.
"""
from __future__ import annotations

from .conditions import (orbit_conditions, orbit_residual, rendezvous_residual, rendezvous_state, state_residual, terminal_error, terminal_residual, terminal_rows)
from .constraints import (MARGIN_DIMENSION, MOVING_DIRECTIONS, PATH_CONSTRAINTS, KeepIn, KeepOut, MaxAngularRate, MinRadius,
                          WheelMomentum, wheel_momentum_constraints)
from .actuators import AT_BOUND_RTOL, Actuator, BoxBound, NormBound, ThrusterBound
from .controls import Bound, Control, ImpulsiveControl, SmoothControl, actuator_bounds, spd_weight
from .costs import (ENGINE_ON_RTOL, control_activity, effort_cost, engine_figures, engine_reference, fuel_cost, impulse_cost, objective_value, quadrature_weights)
from .objective import Objective
from .problem import Problem, state_from_velocities
from .errors import ProblemError
from .targets import STATE_COMPONENTS, Target, TargetOrbit, TargetRendezvous, TargetState, ascending_node

__all__ = ["AT_BOUND_RTOL", "Actuator", "Bound", "BoxBound", "Control", "ENGINE_ON_RTOL", "ImpulsiveControl", "KeepIn", "KeepOut",
           "MARGIN_DIMENSION", "MOVING_DIRECTIONS", "MaxAngularRate", "MinRadius", "WheelMomentum",
           "wheel_momentum_constraints", "NormBound", "Objective",
           "PATH_CONSTRAINTS", "Problem", "ProblemError", "STATE_COMPONENTS", "SmoothControl", "Target", "TargetOrbit",
           "TargetRendezvous", "TargetState", "ThrusterBound", "actuator_bounds", "ascending_node", "control_activity",
           "effort_cost", "engine_figures", "engine_reference", "fuel_cost", "impulse_cost", "objective_value", "orbit_conditions",
           "orbit_residual", "quadrature_weights", "rendezvous_residual", "rendezvous_state", "spd_weight",
           "state_from_velocities", "state_residual", "terminal_error", "terminal_residual", "terminal_rows"]
