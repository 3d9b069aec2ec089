"""YAML maneuver schema: validation, defaults, and conversion to the Problem it states.

Schema (unknown keys are rejected everywhere; see the README's "Writing your own maneuver")::

    name: str
    model: {kind: dumbbell, mass: 1.0, length: 0.1, sphere_radius: 0.02, mu: 39.478...,
            central_body_radius: 0.0}                              # all but kind optional
         | {kind: rigid_body, mass: 1.0, inertia: [3] | 3x3, mu: 39.478..., central_body_radius: 0.0}
    gravity: {kind: point_mass}          # none | point_mass (default) | gravity_gradient | j2 (with J2, radius)
    horizon: {N: 500, T: 0.5}            # or T: {free: true, guess: 30.0, min: 1.0, max: 100.0}
    discretization: lgvi_kepler | lgvi | first_order   # default lgvi_kepler with a central body, else lgvi
    initial: {position: [3], velocity: [3], attitude: ATT, angular_velocity: [3]}
    terminal: {position, velocity, attitude, angular_velocity}   # smooth control: any left out is free
            | {orbit: {radius: r, normal: [3], body_axis: [3], angular_velocity: [3]}}
            | {rendezvous: {radius: r, normal: [3] (or inclination_deg, raan_deg), phase_deg: u0, attitude: ATT,
                            angular_velocity: [3]}}          # problems/moving.py
    control:
      kind: smooth | impulsive
      objective: effort                  # smooth; default effort: a name of transcription.objectives.OBJECTIVES
                                         # (effort, time, fuel, ...) or {kind: name, <its parameters>}
      weights: {force: W, moment: W}     # W: scalar | [3] | 3x3 SPD (fuel: scalars)
      force_frame: inertial | body       # the frame of u_f (default inertial); body: engines fixed in the body
      bounds: {force: {box: [3]} | {norm: b} | {thruster: {axis: [3], max: F, min: 0, isp: s}}, moment: ...}
                                         # norm 0 removes the control; thruster: force_frame body only;
                                         # isp (s; or exhaust_velocity in the file's unit) optional
      bounds_margin: 0.1                 # plan with 90 % of each bound (the actuators' are the bounds
                                         # above), so that a tracker keeps authority; default 0
    constraints:                         # path constraints at every node (smooth control)
      - {kind: min_radius, radius: r}
      - {kind: keep_out, body_axis: [3], direction: [3] | nadir | velocity, min_angle_deg: deg}
      - {kind: keep_in, body_axis: [3], direction: [3] | nadir | velocity, max_angle_deg: deg}
      - {kind: max_angular_rate, value: w}
      - {kind: wheel_momentum, axes: [[3], ...], limit: h | [h, ...]}   # reaction wheels (3+, body axes) that
                                         # turn the body, at rest at t = 0: |h_i| <= h (transcription.ocp.WheelMomentum)
    solver: {direct: {...}, indirect: {...}}
    flight: {...}                        # how `se3ocp fly` flies the plan (problems/flight/schema.py)

``central_body_radius`` (default 0) is the radius of the central body.  The initial and terminal
positions must keep the *clearance* central_body_radius + the body's bounding radius (the dumbbell's
length/2 + sphere_radius) from its centre; every solution's re-simulated path is checked against the
same clearance (a path that comes closer is reported ``inside_central_body``, exit 1); and when the
radius is > 0 a smooth maneuver also gets the path constraint ``{kind: min_radius, radius:
clearance}`` (added to the resolved file; not when a min_radius at least as large is given), so
that the direct method keeps the path outside.  With the default 0 nothing is added: the indirect
method, which does not cover path constraints, stays applicable to the bundled maneuvers.

Velocities are inertial, angular velocities body-frame; momenta follow as gamma = m v,
Pi = J Omega.  ATT is ``identity``, ``{matrix: 3x3}``, ``{axis_angle: [ax, ay, az, angle_deg]}``
or ``{rotations: [[x|y|z, deg], ...]}`` (product left to right).  A matrix must satisfy
|R^T R - I|_F <= 1e-6 and det R > 0; it is then projected onto SO(3).  Directions and axes of any
magnitude are normalized (scaled by their largest component first: transcription.geometry.so3.unit_direction);
only zero and non-finite ones are refused.  The initial state and an impulsive terminal state give all
four components (a smooth terminal state leaves out what is free).  Control bounds, rate limits and
principal moments lie in [MIN_MAGNITUDE, MAX_MAGNITUDE]; principal moments satisfy J1 + J2 >= J3; at
most one control is removed.  A constraint that the initial (or a given terminal) state already
violates is bad input.  A check that involves several fields names the others (``also``), so that a
``--set`` on any of them is named as the cause.

Every error is a :class:`ConfigError` whose text is one line ``FILE: FIELD: what was expected``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..transcription.geometry.state import pack_state
from ..transcription.dynamics.lgvi import FORCE_FRAMES, SCHEMES, discretization
from ..transcription.options import AccuracyOptions, DirectOptions, IndirectOptions, OptionError
from ..transcription.ocp import (ImpulsiveControl, KeepIn, KeepOut, MaxAngularRate, MinRadius, Problem, ProblemError, SmoothControl, TargetOrbit, TargetRendezvous, TargetState, spd_weight, wheel_momentum_constraints)
from ..transcription.dynamics.trajectory import Trajectory
from ..transcription.ocp.estimate import control_sizes
from ..transcription.objectives import OBJECTIVES, named

from . import moving as _moving
from .bounds import MAX_MAGNITUDE, MIN_MAGNITUDE, bounds_margin, control_bound, magnitude, per_wheel, wheel_axes
from . import physical as _physical
from .models import GM_NORMALIZED, Dumbbell, Gravity, RigidBody, parse_gravity
from .schema import Validator, describe, join_field, load_with_overrides
from .units import units_for

MODEL_DEFAULTS: dict[str, Any] = {
    "kind": "dumbbell",
    "mass": 1.0,
    "length": 0.1,
    "sphere_radius": 0.02,
    "mu": GM_NORMALIZED,
    "central_body_radius": 0.0,
}
RIGID_BODY_KEYS = ("kind", "mass", "inertia", "mu", "central_body_radius")
CONSTRAINT_KEYS = {"min_radius": ("radius",), "keep_out": ("body_axis", "direction", "min_angle_deg"),
                   "keep_in": ("body_axis", "direction", "max_angle_deg"), "max_angular_rate": ("value",),
                   "wheel_momentum": ("axes", "limit")}
#: the most steps a horizon may have (a typo such as N = 1e9 is refused before anything is allocated;
#: 10^7 steps of the 18-number state already take 1.4 GB)
MAX_N = 10_000_000
#: the step h = T/N must lie in [MIN_STEP, MAX_STEP]: the discrete equations use h^2 and 1/h^2, which
#: must stay finite and non-zero in double precision (a T so small that h underflows is bad input,
#: not a solver failure)
MIN_STEP, MAX_STEP = MIN_MAGNITUDE, MAX_MAGNITUDE
#: a principal moment may exceed the sum of the other two by at most this fraction (round-off of the
#: eigenvalues) -- J1 + J2 >= J3 holds for every rigid body
TRIANGLE_RTOL = 1e-12
#: the most path constraints a file may give (each adds N + 1 rows to the NLP; the bound also keeps the
#: validation of a file, and of every point of a sweep, short)
MAX_CONSTRAINTS = 64
#: ProblemError fields -> the file's fields
_PROBLEM_FIELDS = {"time_bounds": "horizon.T", "control.bounds": "control.bounds", "control.W_f": "control.weights.force",
                   "control.W_m": "control.weights.moment", "control.objective": "control.objective",
                   "terminal": "terminal", "terminal.free": "terminal", "constraints": "constraints"}
#: the other fields a ProblemError's check involves (an override of any of them is named as the cause)
_PROBLEM_ALSO = {"time_bounds": ("control.objective",), "control.bounds": ("control.objective",),
                 "control.W_f": ("control.objective",), "control.W_m": ("control.objective",)}


# ----------------------------------------------------------------- data types
@dataclass(frozen=True)
class StateSpec:
    """A state given by velocities: position, velocity (inertial), R (body->inertial), omega (body)."""

    position: np.ndarray | None
    velocity: np.ndarray | None
    R: np.ndarray | None
    omega: np.ndarray | None

    def vector(self, body, fill: "StateSpec | None" = None) -> np.ndarray:
        """18-vector with momenta gamma = m v, Pi = J omega; components not given (None) are taken
        from ``fill`` (a target's free components: placeholders, used for scaling and guesses)."""
        x, vel, R, w = (a if a is not None else getattr(fill, k)
                        for a, k in ((self.position, "position"), (self.velocity, "velocity"), (self.R, "R"),
                                     (self.omega, "omega")))
        return pack_state(x, body.mass * vel, R, body.inertia @ w)

    @property
    def free(self) -> frozenset:
        """The components not given."""
        return frozenset(n for n, a in (("position", self.position), ("velocity", self.velocity),
                                        ("attitude", self.R), ("angular_velocity", self.omega)) if a is None)


@dataclass(frozen=True)
class Maneuver:
    """A validated maneuver file: the :class:`~transcription.ocp.Problem` it states, the options
    of each method (its ``solver`` blocks), and the resolved document (defaults and overrides
    applied; itself a valid maneuver file).  ``initial`` and ``terminal`` are the states as given
    (velocities), ``body`` the dumbbell."""

    name: str
    source: str
    problem: Problem
    direct: DirectOptions
    indirect: IndirectOptions
    body: Dumbbell | RigidBody
    central_body_radius: float
    initial: StateSpec
    terminal: StateSpec | TargetOrbit | TargetRendezvous | None
    resolved: dict[str, Any] = field(repr=False)
    #: epoch, frame, units and preset central body (problems.physical)
    physical: _physical.Physical | None = field(default=None, repr=False)
    accuracy: AccuracyOptions = field(default_factory=AccuracyOptions.default, repr=False)  # the solver block's own keys

    # the Problem's headline numbers, for messages and summaries
    control_kind: str | None = field(init=False, repr=False)
    discretization: str = field(init=False, repr=False)
    N: int = field(init=False, repr=False)
    T: float = field(init=False, repr=False)
    h: float = field(init=False, repr=False)

    @property
    def clearance(self) -> float | None:
        """The distance from the central body's centre the body must keep (:func:`clearance`)."""
        return clearance(self.central_body_radius, self.body)

    def __post_init__(self):
        p = self.problem
        for k, v in (("control_kind", p.kind), ("discretization", p.scheme), ("N", p.N), ("T", p.T), ("h", p.h)):
            object.__setattr__(self, k, v)


# ------------------------------------------------------------------ loading
TOP_KEYS = ("name", "model", "gravity", "horizon", "discretization", "initial", "terminal", "control", "constraints",
            "solver", "flight") + _physical.KEYS
STATE_KEYS = ("position", "velocity", "attitude", "angular_velocity")


def load_maneuver(path: str | Path, overrides: tuple[str, ...] | list[str] = ()) -> Maneuver:
    """Read, override (``--set``) and validate a maneuver file; an error in a field an override set
    names ``--set`` rather than the file."""
    return load_with_overrides(path, overrides, parse_maneuver)


def parse_maneuver(doc: Any, source: str = "<config>") -> Maneuver:
    """Validate a parsed YAML document; return a :class:`Maneuver` or raise ConfigError."""
    v = Validator(source)
    v.mapping(doc, "", TOP_KEYS, required=("name", "horizon", "initial"))
    name = doc["name"]
    if not isinstance(name, str) or not name.strip():
        v.fail("name", f"expected a non-empty string, got {describe(name)}")
    if name.strip() in (".", ".."):  # the default results directory is results/<name>/
        v.fail("name", f"expected a name other than '.' or '..' (it names the results directory results/<name>/), "
                       f"got {name.strip()!r}")
    resolved = copy.deepcopy(doc)
    doc, phys = _physical.expand(v, doc)  # presets and orbital elements (the resolved file keeps their form)

    body, central_radius, resolved["model"], resolved["gravity"] = _body(v, doc.get("model", {"kind": "dumbbell"}),
                                                                         doc.get("gravity", {"kind": "point_mass"}))
    N, T, time_bounds, resolved["horizon"] = _horizon(v, doc["horizon"])
    # a central body's orbit is flown exactly by the Kepler-split LGVI (docs/mathematics.md §2a): the default there
    disc = v.choice(doc.get("discretization", "lgvi_kepler" if body.central_mu else "lgvi"), "discretization", SCHEMES)
    resolved["discretization"] = disc
    extent = clearance(central_radius, body)
    initial = _state(v, doc["initial"], "initial", body, extent, all_required=True)
    _physical.check_units(v, phys, body.central_mu, initial.position, initial.velocity, T)

    control_kind, control, resolved_control = _control(v, doc.get("control"), phys.units)
    if resolved_control is not None:
        resolved["control"] = resolved_control

    terminal = None
    if "terminal" in doc:
        t = doc["terminal"]
        if isinstance(t, dict) and "orbit" in t:
            terminal = _orbit(v, t, body, extent)
        elif _moving.is_rendezvous(t):
            terminal = _moving.rendezvous(v, t, body, extent)
        else:
            terminal = _state(v, t, "terminal", body, extent, all_required=control_kind != "smooth")
    if control_kind is not None and terminal is None:
        v.fail("terminal", f"a {control_kind} maneuver needs a terminal block")
    if terminal is not None and control_kind is None:
        v.fail("control", "a terminal block needs a control block (kind: smooth or impulsive)")

    constraints = _constraints(v, doc.get("constraints", []), body, initial, terminal)
    if constraints and control_kind != "smooth":
        v.fail("constraints", "path constraints apply to smooth control")
    body_constraint = _central_body_constraint(central_radius, body, control_kind, constraints)
    if body_constraint is not None:
        constraints += (body_constraint,)
        resolved["constraints"] = list(resolved.get("constraints", [])) + [{"kind": "min_radius",
                                                                            "radius": body_constraint.radius}]

    if "flight" in doc:  # how the plan is flown (problems/flight): checked here, used by `se3ocp fly`
        from .flight.schema import parse_flight, preset_gravity
        resolved["flight"] = parse_flight(doc["flight"], source, preset=preset_gravity(phys)).resolved
    sdoc = v.mapping(doc.get("solver", {}), "solver", ("direct", "indirect", *AccuracyOptions.KEYS))
    direct = _options(v, DirectOptions, sdoc.get("direct", {}), "solver.direct")
    indirect = _options(v, IndirectOptions, sdoc.get("indirect", {}), "solver.indirect")
    accuracy = _options(v, AccuracyOptions, {k: x for k, x in sdoc.items() if k in AccuracyOptions.KEYS}, "solver")
    resolved["solver"] = {"direct": direct.as_dict(), "indirect": indirect.as_dict(), **accuracy.given(sdoc)}

    target = TargetState(terminal.vector(body, initial), terminal.free) if isinstance(terminal, StateSpec) else terminal
    try:
        frame = (resolved_control or {}).get("force_frame", "inertial")
        problem = Problem(disc=discretization(body.body_model(), disc, force_frame=frame), N=N, T=T,
                          X0=initial.vector(body),
                          terminal=target, control=control, name=name.strip(), time_bounds=time_bounds,
                          constraints=constraints)
    except ProblemError as e:
        v.fail(_PROBLEM_FIELDS.get(e.field, e.field), str(e).split(": ", 1)[1], also=_PROBLEM_ALSO.get(e.field, ()))
    if resolved_control is not None and (doc.get("control") or {}).get("weights", "auto") == "auto":
        problem = _weights_in_actuator_terms(problem, resolved_control)
    problem = _physical.in_units(problem, phys)
    return Maneuver(name=name.strip(), source=source, problem=problem, direct=direct, indirect=indirect, body=body,
                    central_body_radius=central_radius, initial=initial, terminal=terminal, resolved=resolved,
                    physical=phys, accuracy=accuracy)


def _weights_in_actuator_terms(problem: Problem, resolved_control: dict) -> Problem:
    """A smooth orbit maneuver whose file gives no weights and bounds its force: each control measured in units of its
    size (:func:`~transcription.ocp.estimate.control_sizes`, the objective's ``unit_weights``), and the resolved file
    says the numbers.  Otherwise the problem as it is (weights force 1, moment 1e4: the normalized examples')."""
    c = problem.control
    sizes = control_sizes(problem) if isinstance(c, SmoothControl) else None
    W = None if sizes is None else c.objective.unit_weights(*sizes)
    if W is None:
        return problem
    control = replace(c, W_f=W[0], W_m=W[1])
    resolved_control["weights"] = {"force": float(W[0][0, 0]), "moment": float(W[1][0, 0])}
    return problem.replace(control=replace(control, objective=control.objective.with_weights(control)))


def _body(v: Validator, mdoc, gdoc):
    """(body, central_body_radius, resolved model, resolved gravity) from the model and gravity blocks."""
    if isinstance(mdoc, dict) and mdoc.get("kind") == "rigid_body":
        v.mapping(mdoc, "model", RIGID_BODY_KEYS, required=("kind", "inertia"))
    else:
        v.mapping(mdoc, "model", MODEL_DEFAULTS.keys(), required=("kind",))
        v.choice(mdoc["kind"], "model.kind", ("dumbbell", "rigid_body"))
    m = {"kind": mdoc["kind"], "mass": 1.0, "mu": GM_NORMALIZED, "central_body_radius": 0.0}
    for k in ("mass", "length", "sphere_radius", "mu"):
        if k in mdoc:
            m[k] = v.number(mdoc[k], f"model.{k}", positive=True)
    if "central_body_radius" in mdoc:
        m["central_body_radius"] = v.number(mdoc["central_body_radius"], "model.central_body_radius", nonneg=True)
    rg = parse_gravity(v, gdoc, "gravity")
    kind = rg["kind"]
    if m["kind"] == "rigid_body":
        J = _inertia(v, mdoc["inertia"], "model.inertia")
        m["inertia"] = J.tolist()
        body = RigidBody(mass=m["mass"], inertia=J,
                         gravity=Gravity(kind, m["mu"], rg.get("J2", 0.0), rg.get("radius", 0.0)))
    else:
        m = {**MODEL_DEFAULTS, **m}
        body = Dumbbell(mass=m["mass"], length=m["length"], sphere_radius=m["sphere_radius"], mu=m["mu"], gravity=kind,
                        J2=rg.get("J2", 0.0), J2_radius=rg.get("radius", 0.0))
    return body, m["central_body_radius"], m, rg


def _inertia(v: Validator, val, where) -> np.ndarray:
    """Principal moments [3] (positive) or a symmetric positive definite 3x3 matrix."""
    if isinstance(val, (list, tuple)) and len(val) == 3 and all(isinstance(r, (list, tuple)) for r in val):
        J = np.array([v.vec3(r, f"{where}[{i}]") for i, r in enumerate(val)])
    elif isinstance(val, (list, tuple)) and len(val) == 3:
        J = np.diag(v.vec3(val, where))
    else:
        v.fail(where, f"expected 3 principal moments or a 3x3 matrix, got {describe(val)}")
    if not np.allclose(J, J.T, rtol=1e-12, atol=0.0) or not np.all(np.diag(J) > 0):
        v.fail(where, "expected a symmetric positive definite inertia")
    # the diagonal of a positive definite J lies between its extreme eigenvalues: checked first, so
    # that the eigenvalues are taken of J / max|J| (entries of 1e308 overflowed eigvalsh) without underflow
    span = (MIN_MAGNITUDE, MAX_MAGNITUDE)
    if not np.all((np.diag(J) >= span[0]) & (np.diag(J) <= span[1])):
        v.fail(where, f"expected principal moments from {span[0]:g} to {span[1]:g} (their squares and inverses "
                      f"enter the equations), got {', '.join(f'{x:.6g}' for x in np.diag(J))} on the diagonal")
    scale = float(np.abs(J).max())
    S = 0.5 * (J / scale + J.T / scale)
    lam = np.linalg.eigvalsh(S)
    if not lam.min() > 0:
        v.fail(where, "expected a symmetric positive definite inertia")
    lo, mid, hi = lam * scale
    if not (span[0] <= lo and hi <= span[1]):
        v.fail(where, f"expected principal moments from {span[0]:g} to {span[1]:g} (their squares and inverses "
                      f"enter the equations), got {lo:.6g}, {mid:.6g}, {hi:.6g}")
    if hi - (lo + mid) > TRIANGLE_RTOL * hi:
        v.fail(where, f"expected principal moments that satisfy the triangle inequality J1 + J2 >= J3 (every rigid "
                      f"body does: J1 + J2 - J3 = 2 * integral of z^2 dm), got {lo:.6g} + {mid:.6g} < {hi:.6g}")
    return S * scale


def _step(v: Validator, T: float, N: int, where: str) -> None:
    """The step h = T/N within [:data:`MIN_STEP`, :data:`MAX_STEP`], else ConfigError naming ``where``."""
    h = T / N
    if not MIN_STEP <= h <= MAX_STEP:
        v.fail(where, f"expected a step h = T/N from {MIN_STEP:g} to {MAX_STEP:g} (the discrete equations use h^2 and "
                      f"1/h^2, which must be finite, non-zero double-precision numbers), got h = {T:g}/{N} = {h:.3g}")


def _horizon(v: Validator, hdoc):
    """(N, T (or its guess), time_bounds or None, resolved horizon)."""
    hz = v.mapping(hdoc, "horizon", ("T", "N"), required=("T", "N"))
    N = v.number(hz["N"], "horizon.N", positive=True, integer=True, at_most=MAX_N)
    if isinstance(hz["T"], dict):
        t = v.mapping(hz["T"], "horizon.T", ("free", "guess", "min", "max"), required=("free", "guess", "min", "max"))
        if t["free"] is not True:
            v.fail("horizon.T.free", f"expected true (or give T as a number), got {describe(t['free'])}")
        guess, lo, hi = (v.number(t[k], f"horizon.T.{k}", positive=True) for k in ("guess", "min", "max"))
        if lo > hi:
            v.fail("horizon.T", f"expected min <= max, got min {lo:g} > max {hi:g}")
        if not lo <= guess <= hi:
            v.fail("horizon.T.guess", f"expected a guess in [min, max] = [{lo:g}, {hi:g}], got {guess:g}")
        _step(v, lo, N, "horizon.T.min")
        _step(v, hi, N, "horizon.T.max")
        return N, guess, (lo, hi), {"N": N, "T": {"free": True, "guess": guess, "min": lo, "max": hi}}
    T = v.number(hz["T"], "horizon.T", positive=True)
    _step(v, T, N, "horizon.T")
    return N, T, None, {"N": N, "T": T}


def _objective(v: Validator, given) -> tuple:
    """(the Objective, its resolved document) of ``control.objective``: a name of transcription.objectives.OBJECTIVES,
    or a mapping {kind: name, <parameter>: value, ...} of its class's fields."""
    if isinstance(given, dict):
        params = dict(given)
        name = v.choice(params.pop("kind", None), "control.objective.kind", tuple(OBJECTIVES))
    else:
        name, params = v.choice(given, "control.objective", tuple(OBJECTIVES)), {}
    try:
        objective = named(name, **params)
    except ProblemError as e:
        v.fail("control.objective", str(e).split(": ", 1)[1])
    return objective, ({"kind": name, **params} if params else name)


def _control(v: Validator, c, units=None):
    """(kind, SmoothControl | ImpulsiveControl | None, resolved control block or None); ``units``: the file's
    UnitSystem (None: normalized or unnamed), for an engine's isp."""
    if c is None:
        return None, None, None
    c = v.mapping(c, "control", ("kind", "objective", "weights", "bounds", "bounds_margin", "force_frame"),
                  required=("kind",))
    kind = v.choice(c["kind"], "control.kind", ("smooth", "impulsive"))
    if kind == "impulsive":
        for k in ("weights", "objective", "bounds", "bounds_margin", "force_frame"):
            if k in c:
                v.fail(f"control.{k}", f"{k} apply to smooth controls only (the impulsive cost is a sum of impulse norms)")
        return kind, ImpulsiveControl(), {"kind": kind}
    objective, objective_doc = _objective(v, c.get("objective", "effort"))
    frame = v.choice(c.get("force_frame", "inertial"), "control.force_frame", FORCE_FRAMES)
    W = {"force": np.ones(3), "moment": np.full(3, 1e4)}
    weights_doc = {"force": 1.0, "moment": 1e4}
    if c.get("weights", "auto") != "auto":            # 'auto' (or none): in the actuators' terms where they have some
        if isinstance(c["weights"], str):
            v.fail("control.weights", f"expected a mapping with keys force, moment, or 'auto' (each control in units "
                                      f"of its size), got {c['weights']!r}")
        wd = v.mapping(c["weights"], "control.weights", ("force", "moment"))
        for k in ("force", "moment"):
            if k in wd:
                W[k] = _weight(v, wd[k], f"control.weights.{k}")
                weights_doc[k] = wd[k]
    bounds, bounds_doc = {}, {}
    if "bounds" in c:
        bd = v.mapping(c["bounds"], "control.bounds", ("force", "moment"))
        for k in ("force", "moment"):
            if k in bd:
                bounds[k], bounds_doc[k] = control_bound(v, bd[k], f"control.bounds.{k}", thruster=k == "force",
                                                           units=units)
        if getattr(bounds.get("force"), "body_fixed", False) and frame != "body":
            v.fail("control.bounds.force.thruster", "a thruster is fixed in the body: it needs control.force_frame: "
                                                    f"body (got {frame})", also=("control.force_frame",))
    margin = bounds_margin(v, c, bounds)
    try:
        control = SmoothControl(W_f=W["force"], W_m=W["moment"], objective=objective, force_bound=bounds.get("force"),
                                moment_bound=bounds.get("moment"), bounds_margin=margin)
    except ProblemError as e:
        v.fail(_PROBLEM_FIELDS.get(e.field, e.field), str(e).split(": ", 1)[1], also=_PROBLEM_ALSO.get(e.field, ()))
    if control.removed == (True, True):
        v.fail("control.bounds", "expected at most one control removed: a norm bound of 0 on both the force and the "
                                 "moment leaves nothing to steer the body (its free motion is `se3ocp simulate`)")
    out = {"kind": kind, "objective": objective_doc, "weights": weights_doc}
    if bounds_doc:
        out["bounds"] = bounds_doc
    if "bounds_margin" in c:
        out["bounds_margin"] = margin
    if "force_frame" in c:
        out["force_frame"] = frame
    return kind, control, out


def _orbit(v: Validator, t, body, extent) -> TargetOrbit:
    v.mapping(t, "terminal", ("orbit",))
    o = v.mapping(t["orbit"], "terminal.orbit", ("radius", "normal", "body_axis", "angular_velocity"),
                  required=("radius", "normal"))
    if body.body_model().mu is None:
        v.fail("terminal.orbit", "an orbit target needs a central body (gravity kind other than none)")
    r = v.number(o["radius"], "terminal.orbit.radius", positive=True)
    n = v.unit_vector(o["normal"], "terminal.orbit.normal")
    if extent is not None and not r > extent:
        v.fail("terminal.orbit.radius", "expected an orbit outside the central body",
               also=("model.central_body_radius", "model.length", "model.sphere_radius"))
    axis = v.unit_vector(o.get("body_axis", [1.0, 0.0, 0.0]), "terminal.orbit.body_axis")
    spin = v.vec3(o.get("angular_velocity", [0.0, 0.0, 0.0]), "terminal.orbit.angular_velocity")
    return TargetOrbit(r, n, axis, body.inertia @ spin)


def _constraints(v: Validator, cdoc, body, initial: StateSpec, terminal) -> tuple:
    """The path constraints; each must hold at the initial state and at the given terminal components."""
    if not isinstance(cdoc, (list, tuple)):
        v.fail("constraints", f"expected a list of constraints, got {describe(cdoc)}")
    if len(cdoc) > MAX_CONSTRAINTS:
        v.fail("constraints", f"expected at most {MAX_CONSTRAINTS} path constraints (maneuvers.MAX_CONSTRAINTS), "
                              f"got {len(cdoc)}")
    out = []
    for i, c in enumerate(cdoc):
        w = f"constraints[{i}]"
        if not isinstance(c, dict) or "kind" not in c:
            v.fail(w, f"expected a mapping with a kind ({', '.join(CONSTRAINT_KEYS)}), got {describe(c)}")
        kind = v.choice(c["kind"], f"{w}.kind", tuple(CONSTRAINT_KEYS))
        v.mapping(c, w, ("kind",) + CONSTRAINT_KEYS[kind], required=("kind",) + CONSTRAINT_KEYS[kind])
        for con in _constraint(v, c, kind, w, body, initial):
            _holds_at_the_ends(v, con, kind, w, body, initial, terminal)
            out.append(con)
    return tuple(out)


def _constraint(v: Validator, c: dict, kind: str, w: str, body, initial: StateSpec) -> tuple:
    """The path constraint(s) of one entry ``c`` of the list: one, or one per wheel of a wheel_momentum entry."""
    if kind == "min_radius":
        return (MinRadius(v.number(c["radius"], f"{w}.radius", positive=True)),)
    if kind == "max_angular_rate":
        rate = v.number(c["value"], f"{w}.value", positive=True)
        magnitude(v, rate, f"{w}.value", "a rate limit")
        return (MaxAngularRate(rate),)
    if kind == "wheel_momentum":
        if body.central_mu:
            v.fail(w, "applies without a central body only: its gravity-gradient torque changes the body's and the "
                      "wheels' angular momentum, which this constraint takes as constant (gravity kind none)")
        A = wheel_axes(v, c["axes"], f"{w}.axes").T
        lims = per_wheel(v, c["limit"], A.shape[1], f"{w}.limit")
        X0 = initial.vector(body, initial)
        return wheel_momentum_constraints(A, lims, X0[6:15].reshape(3, 3, order="F"), X0[15:18])
    vecs = {"body_axis": v.unit_vector(c["body_axis"], f"{w}.body_axis"),
            "direction": _moving.cone_direction(v, c["direction"], f"{w}.direction")}
    ak = CONSTRAINT_KEYS[kind][2]
    angle = v.number(c[ak], f"{w}.{ak}", lo=0.0, hi=180.0)
    return ((KeepOut if kind == "keep_out" else KeepIn)(vecs["body_axis"], vecs["direction"], angle),)


def _holds_at_the_ends(v: Validator, con, kind: str, w: str, body, initial: StateSpec, terminal) -> None:
    """Bad input unless ``con`` holds at the initial state and at the terminal components given."""
    for label, st in (("initial", initial), ("terminal", terminal)):
        if not isinstance(st, StateSpec):
            continue
        if set(con.needs) & st.free:  # a component the constraint is a function of is not given
            continue
        X = st.vector(body, initial)
        margin = float(con.margin(Trajectory(np.zeros(1), X[None, :], body.mass, body.inertia))[0])
        if not np.isfinite(margin):  # a moving cone's direction at a zero position or velocity
            v.fail(w, f"the {label} state leaves the direction {con.direction!r} undefined (it is zero)", also=(label,))
        if margin < 0:
            unit = units_for(body.central_mu).unit(con.dimension)
            v.fail(w, f"the {label} state already violates this {kind} constraint (margin {margin:.4g}"
                      f"{' ' + unit if unit else ''})", also=(label,))


def clearance(central_radius: float, body) -> float | None:
    """The distance from the central body's centre that the body's centre of mass must keep:
    central_body_radius + the body's bounding-sphere radius (the dumbbell's l/2 + r_s, 0 for a
    rigid body); None without a central body (gravity none).  The initial and terminal states
    are validated against it, and every solution's re-simulated path is checked against it
    (problems.api.check_clearance)."""
    return None if body.central_mu is None else central_radius + body.extent


def _central_body_constraint(central_radius: float, body, control_kind, constraints) -> MinRadius | None:
    """The central body enforced as a path constraint ``min_radius: clearance`` of a smooth maneuver
    whose file gives a ``central_body_radius`` > 0 (the default 0 adds nothing: the bundled maneuvers,
    and the indirect method, which does not cover path constraints, are unchanged).  None if there is
    no central body, no smooth control, or a given min_radius already keeps at least that distance."""
    need = clearance(central_radius, body)
    if need is None or not central_radius > 0 or control_kind != "smooth":
        return None
    if any(isinstance(c, MinRadius) and c.radius >= need for c in constraints):
        return None
    return MinRadius(need)


def _state(v: Validator, d, where, body, extent: float | None, all_required: bool) -> StateSpec:
    """A state block; ``extent``: the distance from the central body's centre the body must keep
    (None: no central body).  Without ``all_required`` any component may be left out (free), but
    at least one must be given."""
    v.mapping(d, where, STATE_KEYS)
    for k in STATE_KEYS if all_required else ():  # identity is written out: an attitude left out is never assumed
        if k not in d:
            v.fail(f"{where}.{k}", "missing required key (this state is complete: only the terminal state of a "
                                   "smooth maneuver may leave components out, and those are free)")
    if not all_required and not any(k in d for k in STATE_KEYS):
        v.fail(where, f"expected at least one of {', '.join(STATE_KEYS)} (the others are then free)")
    x = v.vec3(d["position"], f"{where}.position") if "position" in d else None
    vel = v.vec3(d["velocity"], f"{where}.velocity") if "velocity" in d else None
    R = v.attitude(d["attitude"], f"{where}.attitude") if "attitude" in d else None
    w = v.vec3(d["angular_velocity"], f"{where}.angular_velocity") if "angular_velocity" in d else None
    # The body's bounding sphere must lie outside the central body; this also keeps the potential
    # away from its singularity at the centre.
    if x is not None and extent is not None and not np.linalg.norm(x) > extent:
        what = "the dumbbell" if isinstance(body, Dumbbell) else "the body"
        v.fail(f"{where}.position",
               f"expected {what} outside the central body: |position| = {np.linalg.norm(x):.3g} (needs > "
               f"{extent:.3g}: central_body_radius{' + length/2 + sphere_radius' if isinstance(body, Dumbbell) else ''})",
               also=("model.central_body_radius", "model.length", "model.sphere_radius"))
    with np.errstate(over="ignore", invalid="ignore"):
        momenta = np.concatenate([body.mass * (vel if vel is not None else np.zeros(3)),
                                  body.inertia @ (w if w is not None else np.zeros(3))])
    if not np.all(np.isfinite(momenta)):
        v.fail(where, "expected finite momenta m v and J Omega (the values overflow)", also=("model",))
    return StateSpec(x, vel, R, w)


def _weight(v: Validator, val, where) -> np.ndarray:
    """A weight: a positive number, 3 positive numbers (a diagonal) or a symmetric positive definite
    3x3 matrix (3 rows of 3 numbers), the forms every method accepts."""
    if isinstance(val, (list, tuple)) and len(val) == 3 and all(isinstance(r, (list, tuple)) for r in val):
        W = np.array([v.vec3(r, f"{where}[{i}]") for i, r in enumerate(val)])
        try:
            return spd_weight(W, where)
        except ProblemError as e:
            v.fail(where, str(e).split(": ", 1)[1])
    return v.weights(val, where)


def _options(v: Validator, cls, d, where):
    """A method's options from its YAML block; an OptionError becomes a ConfigError naming the field."""
    v.mapping(d, where, [f for f in cls.__dataclass_fields__])
    try:
        return cls.from_mapping(d)
    except OptionError as e:
        v.fail(join_field(where, e.field) if "." not in e.field else f"{where}.{e.field}", e.detail)
