"""The ``flight.actuators`` block: the actuators the truth flies with instead of the plan's exact controls.

    flight:
      actuators:
        pulses:                        # on/off thrusters (transcription.closedloop.pulses)
          minimum_impulse: 5.0e-5      # the minimum impulse bit, the file's force x time (kN s for a km file: 0.05 N s)
          thrust: 1.0e-3               # the on level (the file's force); default: the plan's engine maximum or norm bound

Numbers are in the maneuver file's units, as its force bounds are; the report shows them in N s and N.
"""
from __future__ import annotations

import numpy as np

from ..schema import Validator

ACTUATOR_KEYS = ("pulses",)
PULSE_KEYS = ("minimum_impulse", "thrust")


def parse_actuators(v: Validator, doc, where: str) -> dict:
    """The resolved actuators block ({} when absent); ConfigError naming ``where.FIELD``."""
    d = v.mapping({} if doc is None else doc, where, ACTUATOR_KEYS)
    out = {}
    if "pulses" in d:
        p = v.mapping(d["pulses"], f"{where}.pulses", PULSE_KEYS, required=("minimum_impulse",))
        out["pulses"] = {"minimum_impulse": v.number(p["minimum_impulse"], f"{where}.pulses.minimum_impulse", nonneg=True)}
        if "thrust" in p:
            out["pulses"]["thrust"] = v.number(p["thrust"], f"{where}.pulses.thrust", positive=True)
    return out


def pulse_thrust(block: dict, problem) -> tuple[float | None, str]:
    """(F, '') the on level of a pulses block for ``problem``'s plan -- the block's ``thrust``, else the force
    actuator's engine maximum or norm bound -- or (None, why not)."""
    if "thrust" in block:
        return float(block["thrust"]), ""
    bound = problem.control.force_bound
    if problem.control.removed[0]:
        return None, "the plan has no force to pulse"
    if bound is not None and bound.engine_range is not None and np.isfinite(bound.engine_range[1]):
        return float(bound.engine_range[1]), ""
    if bound is not None and np.isfinite(bound.radius) and bound.radius > 0:
        return float(bound.radius), ""
    return None, "expected a thrust: the plan's force has no engine maximum or norm bound to take it from"


def pulses_of(actuators: dict, problem):
    """The truth's on/off thrusters (transcription.closedloop.pulses.Pulses) of a resolved actuators block, or None."""
    from ...transcription.closedloop.pulses import Pulses

    block = actuators.get("pulses")
    if block is None:
        return None
    F, why = pulse_thrust(block, problem)
    if F is None:
        raise ValueError(f"flight.actuators.pulses: {why}")
    return Pulses(thrust=F, minimum_impulse=float(block["minimum_impulse"]))


def check_actuators(maneuver, actuators: dict) -> tuple[str, str] | None:
    """(field, message) when the maneuver's plan cannot fly these actuators, else None."""
    block = actuators.get("pulses")
    if block is not None:
        F, why = pulse_thrust(block, maneuver.problem)
        if F is None:
            return "actuators.pulses.thrust", why
    return None
