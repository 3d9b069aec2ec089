"""YAML maneuver schema: validation, defaults, and conversion to problem objects.

Schema (unknown keys are rejected everywhere; see README "Maneuver files")::

    name: str
    model: {kind: dumbbell, mass: 1.0, length: 0.1, sphere_radius: 0.02,
            mu: 39.478..., central_body_radius: 0.0}          # all but kind optional
    horizon: {T: 0.5, N: 500}
    discretization: lgvi | first_order                         # default lgvi
    initial: {position: [3], velocity: [3], attitude: ATT, angular_velocity: [3]}
    terminal: {position, velocity, attitude, angular_velocity} | {orbit: {radius: r, normal: [3]}}
    control: {kind: smooth | impulsive, weights: {force: [3] | scalar, moment: [3] | scalar}}
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

from ..transcription.direct import DIRECT_OPTION_DEFAULTS
from ..transcription.indirect import DEFAULT_OPTIONS as INDIRECT_OPTION_DEFAULTS
from ..transcription.layout import pack_state
from ..transcription.lgvi import SCHEMES, Discretization
from ..transcription.problem import ImpulsiveProblem, OrbitTarget, SmoothProblem

from .dumbbell import GM_NORMALIZED, Dumbbell
from .schema import ConfigError, Validator, apply_override, describe, join_field, read_yaml_file, yaml_load  # noqa: F401


#: solver option blocks: the keys and defaults are the method modules' own, so the
#: schema and the solvers cannot disagree; values are type-checked in _solver_block.
DIRECT_DEFAULTS: dict[str, Any] = dict(DIRECT_OPTION_DEFAULTS)
INDIRECT_DEFAULTS: dict[str, Any] = {k: v for k, v in INDIRECT_OPTION_DEFAULTS.items() if k != "direct_options"}
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
class OrbitSpec:
    radius: float
    normal: np.ndarray  # unit


@dataclass(frozen=True)
class Maneuver:
    """A validated maneuver.  ``resolved`` is the config after defaults and overrides."""

    name: str
    source: str
    body: Dumbbell
    central_body_radius: float
    T: float
    N: int
    discretization: str
    initial: StateSpec
    terminal: StateSpec | OrbitSpec | None
    control_kind: str | None
    W_f: np.ndarray
    W_m: np.ndarray
    direct: dict[str, Any]
    indirect: dict[str, Any]
    resolved: dict[str, Any] = field(repr=False)

    @property
    def h(self) -> float:
        return self.T / self.N

    def discretization_object(self, scheme: str | None = None) -> Discretization:
        return Discretization(self.body.body_model(), scheme or self.discretization)

    def X0(self) -> np.ndarray:
        return self.initial.vector(self.body)

    def require_terminal(self, kinds=("smooth", "impulsive")):
        if self.control_kind not in kinds or self.terminal is None:
            raise ConfigError(self.source, "control/terminal",
                              "solving needs a 'control' block (kind smooth or impulsive) and a 'terminal' block")

    def smooth_problem(self, method: str = "direct", disc: Discretization | None = None) -> SmoothProblem:
        """The smooth-control problem, carrying the ``solver.<method>`` options."""
        self.require_terminal(("smooth",))
        disc = disc or self.discretization_object()
        opts = self.direct if method == "direct" else dict(self.indirect, direct_options=dict(self.direct))
        return SmoothProblem(disc=disc, N=self.N, T=self.T, X0=self.X0(), Xd=self.terminal.vector(self.body),
                             W_f=self.W_f, W_m=self.W_m, options=dict(opts))

    def impulsive_problem(self, disc: Discretization | None = None) -> ImpulsiveProblem:
        self.require_terminal(("impulsive",))
        disc = disc or self.discretization_object()
        term = self.terminal
        target = OrbitTarget(term.radius, term.normal) if isinstance(term, OrbitSpec) else term.vector(self.body)
        return ImpulsiveProblem(disc=disc, N=self.N, T=self.T, X0=self.X0(), terminal=target,
                                mu=self.body.mu, options=dict(self.direct))


# ------------------------------------------------------------------ loading
TOP_KEYS = ("name", "model", "horizon", "discretization", "initial", "terminal", "control", "solver")
STATE_KEYS = ("position", "velocity", "attitude", "angular_velocity")


def load_maneuver(path: str | Path, overrides: tuple[str, ...] | list[str] = ()) -> Maneuver:
    """Read, override (``--set``) and validate a maneuver file."""
    source = str(path)
    doc = read_yaml_file(path)
    if doc is None:
        doc = {}
    if isinstance(doc, dict):
        doc = copy.deepcopy(doc)
        for a in overrides:
            apply_override(doc, a)
    return parse_maneuver(doc, source)


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
                W_f = v.weights(wd["force"], "control.weights.force")
                weights_doc["force"] = wd["force"]
            if "moment" in wd:
                W_m = v.weights(wd["moment"], "control.weights.moment")
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
            terminal = OrbitSpec(r, n / np.linalg.norm(n))
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
    direct = _solver_block(v, sdoc.get("direct", {}), "solver.direct", DIRECT_DEFAULTS)
    indirect = _solver_block(v, sdoc.get("indirect", {}), "solver.indirect", INDIRECT_DEFAULTS)

    resolved = copy.deepcopy(doc)
    resolved["model"] = dict(m)
    resolved["discretization"] = disc
    if control_kind == "smooth":
        resolved["control"] = {"kind": control_kind, "weights": weights_doc}
    resolved["solver"] = {"direct": _plain(direct), "indirect": _plain(indirect)}
    return Maneuver(name=name.strip(), source=source, body=body, central_body_radius=m["central_body_radius"],
                    T=T, N=N, discretization=disc, initial=initial, terminal=terminal, control_kind=control_kind,
                    W_f=W_f, W_m=W_m, direct=direct, indirect=indirect, resolved=resolved)


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


_CHOICES = {"solver": ("ipopt", "fatrop"), "initial_guess": ("rollout", "interpolate")}


def _solver_block(v: Validator, d, where, defaults) -> dict[str, Any]:
    """Validate a solver.<method> block against the method's option defaults (by type)."""
    v.mapping(d, where, defaults.keys())
    out = copy.deepcopy(defaults)
    for k, val in d.items():
        w = f"{where}.{k}"
        default = defaults[k]
        if k in _CHOICES:
            out[k] = v.choice(val, w, _CHOICES[k])
        elif k == "alpha":
            out[k] = v.number(val, w, lo=0.0, hi=1.0)
        elif k == "eps_S":
            out[k] = v.number(val, w, nonneg=True)
        elif k == "initial_costate":
            if isinstance(val, str):
                out[k] = v.choice(val, w, ("zero", "from_direct"))
            elif isinstance(val, (list, tuple)) and len(val) == 12:
                out[k] = [v.number(a, f"{w}[{i}]") for i, a in enumerate(val)]
            else:
                v.fail(w, f"expected zero, from_direct or a list of 12 numbers, got {describe(val)}")
        elif isinstance(default, bool):
            if not isinstance(val, bool):
                v.fail(w, f"expected true or false, got {describe(val)}")
            out[k] = val
        elif isinstance(default, int):
            out[k] = v.number(val, w, positive=True, integer=True)
        elif isinstance(default, float):
            out[k] = v.number(val, w, positive=True)
        elif isinstance(default, dict):
            out[k] = dict(v.mapping(val, w, val.keys() if isinstance(val, dict) else ()))
        else:  # pragma: no cover - a new option type in a method module
            v.fail(w, f"option of unsupported type {type(default).__name__}")
    return out


def _plain(d):
    return {k: (list(x) if isinstance(x, tuple) else x) for k, x in d.items()}
