"""The ``flight.actuators`` block: the actuators the truth flies with instead of the plan's exact controls.

    flight:
      actuators:
        pulses:                        # on/off thrusters (transcription.closedloop.pulses)
          minimum_impulse: 5.0e-5      # the minimum impulse bit, the file's force x time (kN s for a km file: 0.05 N s)
          thrust: 1.0e-3               # the on level (the file's force); default: the plan's engine maximum or norm bound
        wheels:                        # reaction wheels (transcription.dynamics.wheels)
          axes: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]    # 3 or more spin axes (body frame; normalized)
          torque_limit: 55.0           # per wheel (one number, or one per wheel), the file's moment
          momentum_limit: 120.0        # per wheel, the file's angular impulse (moment x time)
          axis_error_deg: 0.57         # 1-sigma misalignment of each truth axis (a rotation by Gaussian angles), default 0

Numbers are in the maneuver file's units, as its force bounds are; the report shows them in N s and N.
"""
from __future__ import annotations

import numpy as np

from ..bounds import per_wheel, wheel_axes
from ..schema import Validator

ACTUATOR_KEYS = ("pulses", "wheels")
PULSE_KEYS = ("minimum_impulse", "thrust")
WHEEL_KEYS = ("axes", "torque_limit", "momentum_limit", "axis_error_deg")


def parse_actuators(v: Validator, doc, where: str) -> dict:
    """The resolved actuators block ({} when absent); ConfigError naming ``where.FIELD``."""
    d = v.mapping({} if doc is None else doc, where, ACTUATOR_KEYS)
    out = {}
    if "pulses" in d:
        p = v.mapping(d["pulses"], f"{where}.pulses", PULSE_KEYS, required=("minimum_impulse",))
        out["pulses"] = {"minimum_impulse": v.number(p["minimum_impulse"], f"{where}.pulses.minimum_impulse", nonneg=True)}
        if "thrust" in p:
            out["pulses"]["thrust"] = v.number(p["thrust"], f"{where}.pulses.thrust", positive=True)
    if "wheels" in d:
        out["wheels"] = _wheels(v, d["wheels"], f"{where}.wheels")
    return out


def _wheels(v: Validator, doc, where: str) -> dict:
    """The resolved wheels block: unit axes (lists of 3), limits one per wheel, the axis error (deg)."""
    w = v.mapping(doc, where, WHEEL_KEYS, required=("axes", "torque_limit", "momentum_limit"))
    A = wheel_axes(v, w["axes"], f"{where}.axes")
    out = {"axes": A.tolist()}
    for k in ("torque_limit", "momentum_limit"):
        out[k] = per_wheel(v, w[k], len(A), f"{where}.{k}")
    out["axis_error_deg"] = v.number(w.get("axis_error_deg", 0.0), f"{where}.axis_error_deg", nonneg=True, hi=90.0)
    return out


def wheels_of(actuators: dict):
    """The wheels' flight software (transcription.dynamics.wheels.Wheels, nominal axes) of a resolved block, or None."""
    from ...transcription.dynamics.wheels import Wheels

    block = actuators.get("wheels")
    if block is None:
        return None
    return Wheels(np.array(block["axes"], float).T, np.array(block["torque_limit"]), np.array(block["momentum_limit"]))


def truth_axes(actuators: dict, seed) -> np.ndarray | None:
    """The truth's wheel axes (3, n) of one run: each nominal axis a_i turned by Exp(theta n_i), n_i three standard
    normals of the run's own child generator (``seed.spawn(1)[0]``: the other errors' draws unchanged), theta the
    1-sigma axis error in rad; None without wheels."""
    from ...transcription.geometry.so3 import exp_so3

    block = actuators.get("wheels")
    if block is None:
        return None
    A = np.array(block["axes"], float)
    rng = np.random.default_rng(seed.spawn(1)[0])
    z = np.radians(block["axis_error_deg"]) * rng.standard_normal((len(A), 3))
    return np.column_stack([exp_so3(zi) @ a for zi, a in zip(z, A)])


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


def actuator_keys(actuators: dict) -> tuple:
    """The figures of merit a flight with these actuators adds (the pulses' counts, the wheels' headroom used)."""
    from ...transcription.closedloop.pulses import PULSE_COLUMNS
    from ...transcription.dynamics.wheels import wheel_columns

    pulses = PULSE_COLUMNS if "pulses" in actuators else ()
    return pulses + (wheel_columns(len(actuators["wheels"]["axes"])) if "wheels" in actuators else ())


def actuator_lines(actuators: dict, problem, un) -> list[str]:
    """What the truth's actuators are, one line each, in the units a person reads (``un``: problems.units.Units of the
    maneuver; a km file's kN s shown as N s): 'on/off thrusters: 1 N pulses, minimum impulse 0.05 N·s (carried ...)'."""
    out = []
    block = actuators.get("pulses")
    if block is not None:
        F, _ = pulse_thrust(block, problem)
        fu, ff = un.shown("force")
        iu, fi = un.shown("impulse") if un.system is not None else (un.unit("force") + "·" + un.unit("time"), 1.0)
        out.append(f"on/off thrusters: {ff * F:.4g} {fu} pulses, minimum impulse {fi * block['minimum_impulse']:.4g} "
                   f"{iu} (an impulse under it carried to the next period)")
    block = actuators.get("wheels")
    if block is not None:
        mu, fm = un.shown("moment")
        hu, fh = un.shown("angular_impulse")
        tl, hl = (", ".join(f"{f * x:.4g}" for x in block[k]) for k, f in (("torque_limit", fm), ("momentum_limit", fh)))
        out.append(f"{len(block['axes'])} reaction wheels: torque limits {tl} {mu}, momentum limits {hl} {hu}, axis "
                   f"error {block['axis_error_deg']:.3g} deg (1-sigma)")
    return out


def check_actuators(maneuver, actuators: dict) -> tuple[str, str] | None:
    """(field, message) when the maneuver's plan cannot fly these actuators, else None."""
    block = actuators.get("pulses")
    if block is not None:
        F, why = pulse_thrust(block, maneuver.problem)
        if F is None:
            return "actuators.pulses.thrust", why
    if "wheels" in actuators and maneuver.problem.control.removed[1]:
        return "actuators.wheels", "the plan has no moment for the wheels to give"
    return None
