"""YAML maneuver schema: validation, defaults, and conversion to problem objects.

Schema (unknown keys are rejected everywhere; see README "Maneuver files")::

    name: str
    model: {kind: dumbbell, mass: 1.0, length: 0.1, sphere_radius: 0.02,
            mu: 39.478..., central_body_radius: 0.0}          # all but kind optional
    horizon: {T: 0.5, N: 500}
    discretization: lgvi | first_order                         # default lgvi
    initial: {position: [3], velocity: [3], attitude: ATT, angular_velocity: [3]}
    terminal: {position, velocity, attitude, angular_velocity} | {orbit: {radius: r, normal: [3]}}
    control: {kind: smooth | impulsive, weights: {force: W, moment: W}}   # W: scalar | [3] | 3x3 SPD
    solver: {direct: {...}, indirect: {...}}

Velocities are inertial, angular velocities body-frame; momenta follow as
gamma = m v, Pi = J Omega.  ATT is ``identity``, ``{matrix: 3x3}``,
``{axis_angle: [ax, ay, az, angle_deg]}`` or ``{rotations: [[x|y|z, deg], ...]}``
(product left to right).  A matrix must satisfy |R^T R - I|_F <= 1e-6 and
det R > 0; it is then projected onto SO(3) (polar decomposition) so that the
integrator starts exactly on the group.  An orbit normal must be non-zero; it is
normalized.

Every error is a :class:`ConfigError` whose text is one line
``FILE: FIELD: what was expected``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..transcription.layout import pack_state
from ..transcription.lgvi import SCHEMES, discretization
from ..transcription.options import DirectOptions, IndirectOptions, OptionError
from ..transcription.problem import ImpulsiveControl, Problem, ProblemError, SmoothControl, TargetOrbit, TargetState, _spd

from .dumbbell import GM_NORMALIZED, Dumbbell
from .schema import ConfigError, Validator, apply_override, describe, join_field, load_with_overrides, read_yaml_file, yaml_load  # noqa: F401

MODEL_DEFAULTS: dict[str, Any] = {
    "kind": "dumbbell",
    "mass": 1.0,
    "length": 0.1,
    "sphere_radius": 0.02,
    "mu": GM_NORMALIZED,
    "central_body_radius": 0.0,
}


# ----------------------------------------------------------------- data types
@dataclass(frozen=True)
class StateSpec:
    """A state given by velocities: position, velocity (inertial), R (body->inertial), omega (body)."""

    position: np.ndarray
    velocity: np.ndarray
    R: np.ndarray
    omega: np.ndarray

    def vector(self, body: Dumbbell) -> np.ndarray:
        """18-vector with momenta gamma = m v, Pi = J omega."""
        return pack_state(self.position, body.mass * self.velocity, self.R, body.inertia @ self.omega)


@dataclass(frozen=True)
class Maneuver:
    """A validated maneuver file: the :class:`~transcription.problem.Problem` it states, the options
    of each method (its ``solver`` blocks), and the resolved document (defaults and overrides
    applied; itself a valid maneuver file).  ``initial`` and ``terminal`` are the states as given
    (velocities), ``body`` the dumbbell."""

    name: str
    source: str
    problem: Problem
    direct: DirectOptions
    indirect: IndirectOptions
    body: Dumbbell
    central_body_radius: float
    initial: StateSpec
    terminal: StateSpec | TargetOrbit | None
    resolved: dict[str, Any] = field(repr=False)

    # the Problem's headline numbers, for messages and summaries
    control_kind: str | None = field(init=False, repr=False)
    discretization: str = field(init=False, repr=False)
    N: int = field(init=False, repr=False)
    T: float = field(init=False, repr=False)
    h: float = field(init=False, repr=False)

    def __post_init__(self):
        p = self.problem
        for k, v in (("control_kind", p.kind), ("discretization", p.scheme), ("N", p.N), ("T", p.T), ("h", p.h)):
            object.__setattr__(self, k, v)


# ------------------------------------------------------------------ loading
TOP_KEYS = ("name", "model", "horizon", "discretization", "initial", "terminal", "control", "solver")
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

    m = dict(MODEL_DEFAULTS)
    mdoc = v.mapping(doc.get("model", {"kind": "dumbbell"}), "model", MODEL_DEFAULTS.keys(), required=("kind",))
    v.choice(mdoc["kind"], "model.kind", ("dumbbell",))
    for k in ("mass", "length", "sphere_radius", "mu"):
        if k in mdoc:
            m[k] = v.number(mdoc[k], f"model.{k}", positive=True)
    if "central_body_radius" in mdoc:
        m["central_body_radius"] = v.number(mdoc["central_body_radius"], "model.central_body_radius", nonneg=True)
    body = Dumbbell(mass=m["mass"], length=m["length"], sphere_radius=m["sphere_radius"], mu=m["mu"])

    hz = v.mapping(doc["horizon"], "horizon", ("T", "N"), required=("T", "N"))
    T = v.number(hz["T"], "horizon.T", positive=True)
    N = v.number(hz["N"], "horizon.N", positive=True, integer=True)

    disc = v.choice(doc.get("discretization", "lgvi"), "discretization", SCHEMES)

    initial = _state(v, doc["initial"], "initial", body, m["central_body_radius"], all_required=True)

    control_kind = None
    W_f = np.ones(3)
    W_m = np.full(3, 1e4)
    weights_doc = {"force": 1.0, "moment": 1e4}
    if "control" in doc:
        c = v.mapping(doc["control"], "control", ("kind", "weights"), required=("kind",))
        control_kind = v.choice(c["kind"], "control.kind", ("smooth", "impulsive"))
        if "weights" in c:
            if control_kind == "impulsive":
                v.fail("control.weights", "weights apply to smooth controls only (the impulsive cost is a sum of impulse norms)")
            wd = v.mapping(c["weights"], "control.weights", ("force", "moment"))
            if "force" in wd:
                W_f = _weight(v, wd["force"], "control.weights.force")
                weights_doc["force"] = wd["force"]
            if "moment" in wd:
                W_m = _weight(v, wd["moment"], "control.weights.moment")
                weights_doc["moment"] = wd["moment"]

    terminal = None
    if "terminal" in doc:
        t = doc["terminal"]
        if isinstance(t, dict) and "orbit" in t:
            v.mapping(t, "terminal", ("orbit",))
            o = v.mapping(t["orbit"], "terminal.orbit", ("radius", "normal"), required=("radius", "normal"))
            r = v.number(o["radius"], "terminal.orbit.radius", positive=True)
            n = v.vec3(o["normal"], "terminal.orbit.normal")
            if np.linalg.norm(n) < 1e-12:
                v.fail("terminal.orbit.normal", "expected a non-zero vector (it is normalized)")
            if not r > m["central_body_radius"] + body.sphere_radius + 0.5 * body.length:
                v.fail("terminal.orbit.radius", "expected an orbit outside the central body")
            terminal = TargetOrbit(r, n / np.linalg.norm(n))
            if control_kind == "smooth":
                v.fail("terminal.orbit", "a relaxed orbit target is supported for impulsive maneuvers only; "
                                         "give position, velocity, attitude and angular_velocity for smooth control")
        else:
            terminal = _state(v, t, "terminal", body, m["central_body_radius"], all_required=True)
    if control_kind is not None and terminal is None:
        v.fail("terminal", f"a {control_kind} maneuver needs a terminal block")
    if terminal is not None and control_kind is None:
        v.fail("control", "a terminal block needs a control block (kind: smooth or impulsive)")

    sdoc = v.mapping(doc.get("solver", {}), "solver", ("direct", "indirect"))
    direct = _options(v, DirectOptions, sdoc.get("direct", {}), "solver.direct")
    indirect = _options(v, IndirectOptions, sdoc.get("indirect", {}), "solver.indirect")

    disc_obj = discretization(body.body_model(), disc)
    X0 = initial.vector(body)
    if isinstance(terminal, StateSpec):
        target = TargetState(terminal.vector(body))
    else:
        target = terminal
    control = None
    if control_kind == "smooth":
        control = SmoothControl(W_f=W_f, W_m=W_m)
    elif control_kind == "impulsive":
        control = ImpulsiveControl()
    problem = Problem(disc=disc_obj, N=N, T=T, X0=X0, terminal=target, control=control, name=name.strip())

    resolved = copy.deepcopy(doc)
    resolved["model"] = dict(m)
    resolved["discretization"] = disc
    if control_kind == "smooth":
        resolved["control"] = {"kind": control_kind, "weights": weights_doc}
    resolved["solver"] = {"direct": direct.as_dict(), "indirect": indirect.as_dict()}
    return Maneuver(name=name.strip(), source=source, problem=problem, direct=direct, indirect=indirect, body=body,
                    central_body_radius=m["central_body_radius"], initial=initial, terminal=terminal,
                    resolved=resolved)


def _state(v: Validator, d, where, body: Dumbbell, central_radius: float, all_required: bool) -> StateSpec:
    v.mapping(d, where, STATE_KEYS, required=("position", "velocity", "angular_velocity") if all_required else ())
    x = v.vec3(d["position"], f"{where}.position")
    vel = v.vec3(d["velocity"], f"{where}.velocity")
    R = v.attitude(d.get("attitude", "identity"), f"{where}.attitude")
    w = v.vec3(d["angular_velocity"], f"{where}.angular_velocity")
    # The dumbbell's bounding sphere (radius l/2 + r_s about x) must lie outside
    # the central body; this also keeps |x + R rho_q| away from 0 (U singular).
    clearance = central_radius + 0.5 * body.length + body.sphere_radius
    if not np.linalg.norm(x) > clearance:
        v.fail(f"{where}.position",
               f"expected the dumbbell outside the central body: |position| = {np.linalg.norm(x):.3g} "
               f"(needs > central_body_radius + length/2 + sphere_radius = {clearance:.3g})")
    with np.errstate(over="ignore", invalid="ignore"):
        momenta = np.concatenate([body.mass * vel, body.inertia @ w])
    if not np.all(np.isfinite(momenta)):
        v.fail(where, "expected finite momenta m v and J Omega (the values overflow)")
    return StateSpec(x, vel, R, w)


def _weight(v: Validator, val, where) -> np.ndarray:
    """A weight: a positive number, 3 positive numbers (a diagonal) or a symmetric positive definite
    3x3 matrix (3 rows of 3 numbers), the forms every method accepts."""
    if isinstance(val, (list, tuple)) and len(val) == 3 and all(isinstance(r, (list, tuple)) for r in val):
        W = np.array([v.vec3(r, f"{where}[{i}]") for i, r in enumerate(val)])
        try:
            return _spd(W, where)
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
