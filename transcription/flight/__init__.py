"""Continuous-time flight (docs/mathematics.md §11): the equations of motion (1)-(4) of a body under
the controls a scheme defines between its nodes, integrated by an adaptive integrator (SUNDIALS
CVODES) node interval by node interval, and the continuous check of a Solution.

    from se3ocp.transcription.flight import fly, OpenLoop, continuous_check
    flight = fly(model, X0, times, OpenLoop.of_controls("lgvi", U))     # a Flight (dense samples)
    check = continuous_check(solution)                                   # a ContinuousCheck

Issue 25 reuses :func:`fly` with a truth model, :class:`Actuators` errors and a :class:`ClosedLoop` law.
"""
from .engine import (ATOL, DEFAULT_SAMPLES, RTOL, Actuators, ClosedLoop, ControlLaw, Flight, FlightError, OpenLoop,
                     actuator_output, equations_of_motion, fly, interval_commands, interval_integrator)
from .check import ContinuousCheck, continuous_check, margin_keys

__all__ = ["ATOL", "DEFAULT_SAMPLES", "RTOL", "Actuators", "ClosedLoop", "ContinuousCheck", "ControlLaw", "Flight",
           "FlightError", "continuous_check", "margin_keys",
           "OpenLoop", "actuator_output", "equations_of_motion", "fly", "interval_commands", "interval_integrator"]
