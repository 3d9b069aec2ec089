"""The ``flight:`` block: how a plan is flown (truth model, errors, feedback, runs, seed).

Schema (every key optional; unknown keys are rejected; errors are one line naming the field)::

    flight:
      truth:
        gravity: {kind: j2, J2: 1.08e-3, radius: 0.9}   # the truth's gravity (default: the plan's); J2 and radius
                                                       # default to the maneuver's central_body preset's
        drag: {cd: 2.2, area_m2: 4.0}                  # exponential atmosphere (problems.flight.forces); default none
        srp: {cr: 1.3, area_m2: 4.0}                   # solar radiation pressure, a cannonball; default none
        integrator: cvodes                             # the continuous engine: cvodes (transcription/flight) or
                                                       # basilisk (Basilisk's spacecraft, problems.flight.basilisk;
                                                       # the optional extra se3ocp[basilisk])
        substeps: 16                                   # basilisk only: its RK4 steps per node interval (an even
                                                       # multiple of samples; third order in the step)
        samples: 4                                     # states per node interval (margins between nodes)
      errors:                                          # 1-sigma, Gaussian, seeded; default 0
        initial: {position: 1.0e-4, velocity: 1.0e-4, attitude_deg: 0.5, angular_velocity: 1.0e-3}
        force_scale: 0.02
        force_misalignment_deg: 0.5
        moment_scale: 0.02
        moment_misalignment_deg: 0.0
        inertia_scale: 0.01
      actuators: {pulses: {minimum_impulse: 5.0e-5}}   # on/off thrusters (problems.flight.actuators)
      feedback: both          # none | lqr | mpc | both (none and lqr side by side) | all (none, lqr, mpc)
      mpc: {replan_every: 10, iterations: 1, min_horizon: 1, between: lqr}   # re-planning (transcription/mpc.py)
      weights: {bandwidth: 2.0, attitude: 0.01}        # tracking scales (transcription.closedloop.tracking.SCALE_KEYS)
      navigation:                                      # measurements and an estimator between them and the tracker
        noise: {position: 1.0e-4, velocity: 1.0e-4, attitude_deg: 0.01, angular_velocity: 1.0e-4}   # 1-sigma
        bias: {angular_velocity: 1.0e-4}               # 1-sigma of a constant bias per run (default 0), estimated
        period: 0.005                                  # between measurements (time unit; default: every node)
        estimator: ekf                                 # ekf (transcription.closedloop.estimator) | none (raw)
      runs: 200
      seed: 1

The block lives in a maneuver file (validated when the file is read) or in a file of its own
(``se3ocp fly --flight FILE``, a document ``{flight: {...}}``).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

from ...transcription.dynamics.flight import DEFAULT_SAMPLES
from ...transcription.closedloop.mpc import DEFAULT_ITERATIONS, DEFAULT_REPLAN_EVERY
from ...transcription.closedloop.estimator import ESTIMATORS
from ...transcription.closedloop.tracking import SCALE_KEYS
from ..bodies import PRESETS
from ..models import parse_gravity
from .actuators import parse_actuators
from .basilisk import DEFAULT_SUBSTEPS
from .forces import FORCE_KEYS
from ..schema import Validator

FLIGHT_KEYS = ("truth", "errors", "actuators", "feedback", "mpc", "weights", "navigation", "runs", "seed")
TRUTH_KEYS = ("gravity", "drag", "srp", "integrator", "substeps", "samples")
ERROR_KEYS = ("initial", "force_scale", "force_misalignment_deg", "moment_scale", "moment_misalignment_deg",
              "inertia_scale")
INITIAL_KEYS = ("position", "velocity", "attitude_deg", "angular_velocity")
#: the ``navigation`` block (measurement noise: the same quantities as the initial errors, 1-sigma)
NAVIGATION_KEYS = ("noise", "bias", "period", "estimator")
#: feedback modes flown for each value of ``feedback``
FEEDBACK = {"none": ("none",), "lqr": ("lqr",), "mpc": ("mpc",), "both": ("none", "lqr"), "all": ("none", "lqr", "mpc")}
#: the ``mpc`` block: re-plan every this many node steps, Newton steps per re-plan, no re-plan with fewer
#: steps left than min_horizon, and between re-plans the LQR tracker around the current plan or nothing
#: (transcription.closedloop.mpc)
MPC_KEYS = ("replan_every", "iterations", "min_horizon", "between")
MPC_DEFAULTS = {"replan_every": DEFAULT_REPLAN_EVERY, "iterations": DEFAULT_ITERATIONS, "min_horizon": 1,
                "between": "lqr"}
MPC_BETWEEN = ("lqr", "none")
MAX_ITERATIONS = 50
INTEGRATORS = ("cvodes", "basilisk")
MAX_SUBSTEPS = 4096
#: the most runs one flight may ask for, and the largest seed (NumPy's SeedSequence takes any
#: non-negative integer; the cap keeps the resolved file readable)
MAX_RUNS = 1_000_000
MAX_SEED = 2**63 - 1
MAX_SAMPLES = 64


@dataclass(frozen=True)
class FlightSpec:
    """A validated flight block.  gravity: the truth's gravity block (None: the plan's own);
    samples: states per node interval; integrator: the truth's engine (INTEGRATORS); substeps: Basilisk's steps per
    node interval (0 with cvodes); errors: 1-sigma values (initial: position, velocity (inertial),
    attitude_deg, angular_velocity (body); the others dimensionless scale factors or degrees);
    modes: the feedback modes flown ('none', 'lqr', 'mpc'); weights: tracking scales; mpc: the re-planning
    options (MPC_KEYS); actuators: the truth's actuators (problems.flight.actuators; {}: exact); runs; seed;
    resolved: the block with its defaults (itself a valid flight block); navigation: {noise, bias: {INITIAL_KEYS:
    1-sigma}, period (time unit, None: every node), estimator} or None."""

    gravity: dict | None
    samples: int
    errors: dict
    modes: tuple
    weights: dict
    runs: int
    seed: int
    resolved: dict = field(repr=False)
    mpc: dict = field(default_factory=lambda: dict(MPC_DEFAULTS))
    actuators: dict = field(default_factory=dict)
    navigation: dict | None = None
    integrator: str = "cvodes"
    substeps: int = 0


def default_errors() -> dict:
    return {"initial": {k: 0.0 for k in INITIAL_KEYS}, **{k: 0.0 for k in ERROR_KEYS if k != "initial"}}


def preset_gravity(physical) -> dict | None:
    """{name, source, J2, radius} of a maneuver's central-body preset (problems.bodies.PRESETS; radius in the file's
    length unit) from its ``Maneuver.physical``, or None (no preset)."""
    if physical is None or physical.preset is None:
        return None
    body = PRESETS[physical.preset]
    values = body.in_units(physical.units.length)
    return {"name": physical.preset, "source": body.source, "J2": values["J2"], "radius": values["radius"]}


def truth_from_preset(gravity: dict | None, physical) -> dict:
    """{preset, source, values: {J2, radius}} when the truth's j2 gravity (FlightSpec.gravity) has numbers of the
    maneuver's central-body preset (:func:`preset_gravity` of its ``physical``): those :func:`parse_flight` took from
    it (and any typed equal to it); {} without a preset or a j2 truth (summary.json ``truth_from_preset``)."""
    preset = preset_gravity(physical)
    if not gravity or gravity.get("kind") != "j2" or preset is None:
        return {}
    values = {k: gravity[k] for k in ("J2", "radius") if gravity[k] == preset[k]}
    return {"preset": preset["name"], "source": preset["source"], "values": values} if values else {}


def preset_text(taken: dict, length_unit: str) -> str:
    """One line saying which truth numbers are the preset's, from :func:`truth_from_preset` ({preset, source,
    values}): 'the truth's J2 = 0.0010826359 and radius = 6378.1366 km are the earth preset's (IERS ...)'."""
    if not taken:
        return ""
    unit = {"J2": "", "radius": f" {length_unit}" if length_unit else ""}
    what = " and ".join(f"{k} = {v:.10g}{unit[k]}" for k, v in taken["values"].items())
    return f"the truth's {what} {'are' if len(taken['values']) > 1 else 'is'} the {taken['preset']} preset's ({taken['source']})"


def parse_flight(doc: Any, source: str = "<flight>", where: str = "flight", preset: dict | None = None) -> FlightSpec:
    """Validate a flight block (the mapping under ``flight:``); FlightSpec or ConfigError naming ``where.FIELD``.
    ``preset``: the maneuver's central-body preset (:func:`preset_gravity`), whose J2 and radius a j2 truth gravity
    takes where it does not give them (what it gives wins); the resolved block holds the numbers."""
    v = Validator(source)
    d = v.mapping({} if doc is None else doc, where, FLIGHT_KEYS)
    t = v.mapping(d.get("truth", {}), f"{where}.truth", TRUTH_KEYS)
    g = t.get("gravity")
    if isinstance(g, dict) and g.get("kind") == "j2":
        if preset is not None:
            g = {**g, "J2": g.get("J2", preset["J2"]), "radius": g.get("radius", preset["radius"])}
        for k in ("J2", "radius"):
            if k not in g:
                v.fail(f"{where}.truth.gravity.{k}", "missing required key (the j2 truth needs J2 and the central "
                                                     "body's radius; a maneuver with central_body: earth takes its preset's)")
    gravity = parse_gravity(v, g, f"{where}.truth.gravity") if "gravity" in t else None
    forces = {}
    for name, keys in FORCE_KEYS.items():
        if name in t:
            block = v.mapping(t[name], f"{where}.truth.{name}", keys, required=keys)
            forces[name] = {k: v.number(block[k], f"{where}.truth.{name}.{k}", positive=True) for k in keys}
    integrator = v.choice(t.get("integrator", "cvodes"), f"{where}.truth.integrator", INTEGRATORS)
    samples = v.number(t.get("samples", DEFAULT_SAMPLES), f"{where}.truth.samples", positive=True, integer=True,
                       at_most=MAX_SAMPLES)
    engine = {"integrator": integrator, **_substeps(v, t, integrator, samples, f"{where}.truth")}
    errors = _errors(v, d.get("errors", {}), f"{where}.errors")
    actuators = parse_actuators(v, d.get("actuators"), f"{where}.actuators")
    feedback = v.choice(d.get("feedback", "both"), f"{where}.feedback", tuple(FEEDBACK))
    w = v.mapping(d.get("weights", {}), f"{where}.weights", SCALE_KEYS)
    weights = {}
    for k, val in w.items():
        if isinstance(val, (list, tuple)) and k not in ("bandwidth", "terminal_ratio"):
            weights[k] = [float(x) for x in v.vec3(val, f"{where}.weights.{k}")]
            if min(weights[k]) < 0:
                v.fail(f"{where}.weights.{k}", "expected non-negative numbers")
        else:
            weights[k] = v.number(val, f"{where}.weights.{k}", positive=True)
    m = v.mapping(d.get("mpc", {}), f"{where}.mpc", MPC_KEYS)
    mpc = {k: v.number(m.get(k, dv), f"{where}.mpc.{k}", positive=True, integer=True,
                       at_most=MAX_ITERATIONS if k == "iterations" else MAX_RUNS)
           for k, dv in MPC_DEFAULTS.items() if k != "between"}
    mpc["between"] = v.choice(m.get("between", "lqr"), f"{where}.mpc.between", MPC_BETWEEN)
    runs = v.number(d.get("runs", 100), f"{where}.runs", positive=True, integer=True, at_most=MAX_RUNS)
    seed = v.number(d.get("seed", 0), f"{where}.seed", nonneg=True, integer=True, at_most=MAX_SEED)
    navigation = _navigation(v, d["navigation"], f"{where}.navigation") if d.get("navigation") is not None else None
    if navigation is not None and "mpc" in FEEDBACK[feedback]:
        v.fail(f"{where}.navigation", f"not flown with feedback {feedback!r}: the re-plans (mpc) read the flown state; "
                                      f"fly navigation with none, lqr or both")
    if actuators and integrator == "basilisk":
        v.fail(f"{where}.actuators", "not flown in Basilisk (its wheel and thruster effectors are not mapped); fly "
                                     "actuators with integrator cvodes")
    resolved = {"truth": {**({"gravity": gravity} if gravity else {}), **forces, **engine, "samples": samples},
                "errors": errors, **({"actuators": actuators} if actuators else {}), "feedback": feedback, "mpc": mpc,
                "weights": weights, **({"navigation": navigation} if navigation else {}), "runs": runs, "seed": seed}
    return FlightSpec(gravity=gravity, samples=samples, errors=errors, modes=FEEDBACK[feedback], weights=weights,
                      runs=runs, seed=seed, resolved=resolved, mpc=mpc, actuators=actuators, navigation=navigation,
                      integrator=integrator, substeps=engine.get("substeps", 0))


def _navigation(v: Validator, doc, where: str) -> dict:
    """The navigation block with its defaults: noise and bias (1-sigma, non-negative, default 0), period (positive,
    None: every node), estimator (ESTIMATORS, default ekf)."""
    n = v.mapping(doc, where, NAVIGATION_KEYS)
    out = {}
    for key in ("noise", "bias"):
        block = v.mapping(n.get(key, {}), f"{where}.{key}", INITIAL_KEYS)
        out[key] = {k: v.number(block.get(k, 0.0), f"{where}.{key}.{k}", nonneg=True) for k in INITIAL_KEYS}
    if n.get("period") is not None:
        out["period"] = v.number(n["period"], f"{where}.period", positive=True)
    out["estimator"] = v.choice(n.get("estimator", "ekf"), f"{where}.estimator", ESTIMATORS)
    return out


def _substeps(v: Validator, truth: dict, integrator: str, samples: int, where: str) -> dict:
    """{substeps: n} of a Basilisk truth (default basilisk.DEFAULT_SUBSTEPS; an even multiple of samples: its loads are
    held in pairs of steps, problems.flight.basilisk), {} for cvodes."""
    if integrator != "basilisk":
        if "substeps" in truth:
            v.fail(f"{where}.substeps", f"applies to integrator basilisk only (integrator is {integrator})")
        return {}
    n = v.number(truth.get("substeps", DEFAULT_SUBSTEPS), f"{where}.substeps", positive=True, integer=True,
                 at_most=MAX_SUBSTEPS)
    if n % samples or n % 2:
        v.fail(f"{where}.substeps", f"expected an even multiple of samples ({samples}), got {n}")
    return {"substeps": n}


def _errors(v: Validator, doc, where: str) -> dict:
    """The errors block with every field (default 0): non-negative 1-sigma values."""
    e = v.mapping(doc, where, ERROR_KEYS)
    out = default_errors()
    ini = v.mapping(e.get("initial", {}), f"{where}.initial", INITIAL_KEYS)
    for k in INITIAL_KEYS:
        if k in ini:
            out["initial"][k] = v.number(ini[k], f"{where}.initial.{k}", nonneg=True)
    for k in ERROR_KEYS[1:]:
        if k in e:
            out[k] = v.number(e[k], f"{where}.{k}", nonneg=True, hi=0.5 if k.endswith("scale") else 180.0)
    return out


def with_changes(spec: FlightSpec, source: str, **changes) -> FlightSpec:
    """The spec with some resolved fields changed (runs, feedback, seed: the command line's options)."""
    doc = copy.deepcopy(spec.resolved)
    doc.update({k: val for k, val in changes.items() if val is not None})
    return parse_flight(doc, source)
