"""The optimal control problem: physics, boundary conditions and cost -- no method.

A :class:`Problem` is what every method solves (rockit's shape: the problem apart from the
method; the method and its options are chosen at ``solve`` time).  It carries numbers and a
:class:`~transcription.lgvi.Discretization` (the body model and the scheme: both methods solve
the *same* discrete problem).  States are 18-vectors in the layout of
:mod:`transcription.layout` (momenta, not velocities); ``state_from_velocities`` builds them from
velocities.  The maneuver files (``problems.maneuvers``) build Problems; so can a Python user.

The terminal conditions, the cost and their weights are defined here once and used by every
method, the re-simulation and the reports (docs/mathematics.md §5-§6):

* :func:`terminal_residual` -- [x_N - x_d; gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d]
  (the components a target leaves free are dropped), CasADi or NumPy alike;
* :func:`orbit_conditions` -- the relaxed target (any point of a circular orbit);
* :func:`quadrature_weights` and :func:`effort_cost` -- sum_j omega_j (1/2) u_j^T W u_j;
* :func:`impulse_cost` -- the sum of the impulse norms.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Union

import casadi as ca
import numpy as np

from .layout import NU, NX, U_FORCE, U_MOMENT, pack_state, split_state
from .lgvi import Discretization
from .lie import log_so3, unit_direction

#: the components of a state target, in the order of the terminal residual's blocks
STATE_COMPONENTS = ("position", "velocity", "attitude", "angular_velocity")


class ProblemError(ValueError):
    """An inconsistent Problem: ``field`` names the offending attribute."""

    def __init__(self, fieldname: str, message: str):
        self.field = fieldname
        super().__init__(f"{fieldname}: {message}")


# ----------------------------------------------------------------------------- targets
@dataclass(frozen=True)
class TargetState:
    """Terminal target: the state X (18) with the components named in ``free`` left free
    (a subset of :data:`STATE_COMPONENTS`; 'velocity' frees gamma_N, 'angular_velocity' Pi_N)."""

    X: np.ndarray
    free: frozenset = frozenset()

    def __post_init__(self):
        X = np.asarray(self.X, dtype=float).reshape(-1)
        if X.shape != (NX,) or not np.all(np.isfinite(X)):
            raise ProblemError("terminal.X", f"expected a finite state of {NX} numbers")
        object.__setattr__(self, "X", X)
        free = frozenset(self.free)
        unknown = free - set(STATE_COMPONENTS)
        if unknown:
            raise ProblemError("terminal.free", f"unknown components {sorted(unknown)}; expected some of {STATE_COMPONENTS}")
        if free == set(STATE_COMPONENTS):
            raise ProblemError("terminal.free", "at least one terminal component must be given")
        object.__setattr__(self, "free", free)

    @property
    def fixed(self) -> tuple[str, ...]:
        return tuple(c for c in STATE_COMPONENTS if c not in self.free)


@dataclass(frozen=True)
class TargetOrbit:
    """Relaxed terminal set: any point of the circular orbit of radius ``radius`` about the unit
    ``normal`` (through the central body at the origin), with the circular orbit's velocity, the
    body axis ``body_axis`` along +-normal and the body angular momentum ``Pi`` (default 0: at rest
    in attitude) -- after the terminal impulse (impulsive control) or at arrival (smooth control)
    (docs/mathematics.md §5)."""

    radius: float
    normal: np.ndarray
    body_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    Pi: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        _positive(self.radius, "terminal.radius")
        Pi = np.asarray(self.Pi, dtype=float).reshape(-1)
        if Pi.shape != (3,) or not np.all(np.isfinite(Pi)):
            raise ProblemError("terminal.Pi", "expected a finite 3-vector")
        object.__setattr__(self, "Pi", Pi)
        for name in ("normal", "body_axis"):
            object.__setattr__(self, name, _unit(getattr(self, name), f"terminal.{name}"))

    def plane_basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The unit normal e_n and an orthonormal basis (a, b) of the orbit plane."""
        n = self.normal
        t = np.eye(3)[int(np.argmin(np.abs(n)))]
        a = np.cross(n, t)
        a /= np.linalg.norm(a)
        return n, a, np.cross(n, a)


Target = Union[TargetState, TargetOrbit]


# ----------------------------------------------------------------------------- controls
def _spd(W, name: str) -> np.ndarray:
    """A weight given as a scalar, a diagonal (3,) or a 3x3 matrix -> a 3x3 SPD matrix."""
    W = np.asarray(W, dtype=float)
    if W.ndim == 0:
        W = W * np.eye(3)
    elif W.shape == (3,):
        W = np.diag(W)
    if W.shape != (3, 3) or not np.all(np.isfinite(W)):
        raise ProblemError(name, "expected a positive number, 3 positive numbers or a symmetric positive definite 3x3 matrix")
    if not np.allclose(W, W.T, rtol=1e-12, atol=0.0) or np.linalg.eigvalsh(0.5 * (W + W.T)).min() <= 0:
        raise ProblemError(name, "expected a symmetric positive definite weight")
    return 0.5 * (W + W.T)


#: a control counts as "at its bound" where it is within this fraction of the limit (an interior-point
#: solution sits a little inside: the fuel-optimal burns of configs/orbit_raise_fuel.yaml at 1 - 4e-5)
AT_BOUND_RTOL = 1e-3


@dataclass(frozen=True)
class BoxBound:
    """|u_i| <= b_i for each component i of a 3-vector control (b_i > 0), in the control's frame
    (inertial for the force, body for the moment)."""

    b: np.ndarray

    def __post_init__(self):
        b = np.asarray(self.b, dtype=float).reshape(-1)
        if b.shape != (3,) or not np.all(np.isfinite(b)) or not np.all(b > 0):
            raise ProblemError("bounds.box", "expected 3 positive finite limits")
        object.__setattr__(self, "b", b)

    def margin(self, u: np.ndarray) -> np.ndarray:
        """min_i (b_i - |u_i|) for controls u (n, 3): >= 0 where the bound holds."""
        return np.min(self.b[None, :] - np.abs(np.asarray(u, float)), axis=1)

    def scale(self) -> float:
        return float(self.b.max())

    def active_components(self, u: np.ndarray) -> np.ndarray:
        """(n, 3) bool: |u_i| within AT_BOUND_RTOL of b_i."""
        return np.abs(np.asarray(u, float)) >= self.b[None, :] * (1.0 - AT_BOUND_RTOL)

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: some component at its bound."""
        return np.any(self.active_components(u), axis=1)


@dataclass(frozen=True)
class NormBound:
    """|u|_2 <= b (b >= 0; b = 0 removes the control)."""

    b: float

    def __post_init__(self):
        if not (np.isfinite(self.b) and self.b >= 0):
            raise ProblemError("bounds.norm", "expected a non-negative finite limit")
        object.__setattr__(self, "b", float(self.b))

    def margin(self, u: np.ndarray) -> np.ndarray:
        """b - |u| for controls u (n, 3)."""
        return self.b - np.linalg.norm(np.asarray(u, float), axis=1)

    def scale(self) -> float:
        return self.b

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: |u| within AT_BOUND_RTOL of b (never for b = 0: a removed control is absent)."""
        return (np.linalg.norm(np.asarray(u, float), axis=1) >= self.b * (1.0 - AT_BOUND_RTOL)) & (self.b > 0)


Bound = Union[BoxBound, NormBound]
OBJECTIVES = ("effort", "time", "fuel")


@dataclass(frozen=True)
class SmoothControl:
    """Controls u_f (inertial force) and u_m (body moment) at the nodes of the scheme.

    objective (docs/mathematics.md §6, §10):
      'effort' min sum_j omega_j (1/2)(u_f^T W_f u_f + u_m^T W_m u_m), W_f, W_m symmetric positive
               definite (given as scalars, diagonals or matrices);
      'time'   min T (a free final time; every control bounded);
      'fuel'   min sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|), the weights scalars (W = w I).
    force_bound, moment_bound: a BoxBound, a NormBound or None (unbounded); NormBound(0) removes the
    control (attitude-only or translation-only maneuvers).
    """

    W_f: np.ndarray = field(default_factory=lambda: np.eye(3))
    W_m: np.ndarray = field(default_factory=lambda: np.eye(3))
    objective: str = "effort"
    force_bound: Bound | None = None
    moment_bound: Bound | None = None

    def __post_init__(self):
        object.__setattr__(self, "W_f", _spd(self.W_f, "control.W_f"))
        object.__setattr__(self, "W_m", _spd(self.W_m, "control.W_m"))
        if self.objective not in OBJECTIVES:
            raise ProblemError("control.objective", f"expected one of {', '.join(OBJECTIVES)}, got {self.objective!r}")
        for name in ("force_bound", "moment_bound"):
            b = getattr(self, name)
            if b is not None and not isinstance(b, (BoxBound, NormBound)):
                raise ProblemError(f"control.{name}", "expected a BoxBound, a NormBound or None")
        if self.objective == "fuel":
            for name in ("W_f", "W_m"):
                W = getattr(self, name)
                if not np.allclose(W, W[0, 0] * np.eye(3), rtol=1e-12, atol=0.0):
                    raise ProblemError(f"control.{name}", "for the fuel objective a weight is one number (the weight of the norm)")
        if self.objective == "time" and (self.force_bound is None or self.moment_bound is None):
            raise ProblemError("control.bounds", "the time objective needs a bound on every control (force and moment; "
                                                 "a norm bound of 0 removes one)")

    @property
    def W(self) -> np.ndarray:
        """blkdiag(W_f, W_m) (6x6)."""
        W = np.zeros((NU, NU))
        W[U_FORCE, U_FORCE] = self.W_f
        W[U_MOMENT, U_MOMENT] = self.W_m
        return W

    @property
    def bounded(self) -> bool:
        return self.force_bound is not None or self.moment_bound is not None

    @property
    def removed(self) -> tuple[bool, bool]:
        """(force removed, moment removed): a NormBound of 0."""
        return tuple(isinstance(b, NormBound) and b.b == 0 for b in (self.force_bound, self.moment_bound))


# ------------------------------------------------------------------------ path constraints
def _unit(v, name):
    """The unit direction of v (:func:`~transcription.lie.unit_direction`: any magnitude), else ProblemError."""
    u = unit_direction(v)
    if u is None:
        raise ProblemError(name, "expected a non-zero finite 3-vector")
    return u


def _positive(value: float, name: str) -> None:
    """ProblemError naming ``name`` unless ``value`` is a positive finite number."""
    if not (np.isfinite(value) and value > 0):
        raise ProblemError(name, "expected a positive number")


class _PositiveLimit:
    """A path constraint given by one positive number (its only field), checked on construction."""

    def __post_init__(self):
        name = fields(self)[0].name
        _positive(getattr(self, name), f"constraints.{self.kind}.{name}")


@dataclass(frozen=True)
class MinRadius(_PositiveLimit):
    """|x_k| >= radius at every node (stay above a sphere about the central body's centre)."""

    radius: float
    kind = "min_radius"
    dimension = "length"

    def expression(self, X, inertia):
        """g(X) >= 0 (CasADi or NumPy): |x| - r (in length units; the margin)."""
        x, _, _, _ = split_state(X)
        return (ca.norm_2(x) if isinstance(X, (ca.SX, ca.MX, ca.DM)) else np.linalg.norm(x)) - self.radius

    def margin(self, traj) -> np.ndarray:
        return np.linalg.norm(traj.x, axis=1) - self.radius


@dataclass(frozen=True)
class _Cone:
    body_axis: np.ndarray
    direction: np.ndarray
    angle_deg: float

    def __post_init__(self):
        object.__setattr__(self, "body_axis", _unit(self.body_axis, f"constraints.{self.kind}.body_axis"))
        object.__setattr__(self, "direction", _unit(self.direction, f"constraints.{self.kind}.direction"))
        if not (np.isfinite(self.angle_deg) and 0 < self.angle_deg < 180):
            raise ProblemError(f"constraints.{self.kind}.angle", "expected an angle strictly between 0 and 180 degrees")

    def cos_angle(self, X):
        """(R b) . s, the cosine of the angle between the inertial image of the body axis and the direction."""
        _, _, R, _ = split_state(X)
        return (ca.dot(ca.mtimes(R, ca.DM(self.body_axis)), ca.DM(self.direction))
                if isinstance(X, (ca.SX, ca.MX, ca.DM)) else (R @ self.body_axis) @ self.direction)

    def angles_deg(self, traj) -> np.ndarray:
        c = np.einsum("kij,j,i->k", traj.R, self.body_axis, self.direction)
        return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


@dataclass(frozen=True)
class KeepOut(_Cone):
    """angle(R_k b, s) >= angle_deg at every node: the body axis b stays out of a cone about the
    inertial direction s (e.g. a camera and the Sun).  Smooth form: cos(angle) - (R b).s >= 0."""

    kind = "keep_out"
    dimension = "angle"

    def expression(self, X, inertia):
        return np.cos(np.radians(self.angle_deg)) - self.cos_angle(X)

    def margin(self, traj) -> np.ndarray:
        return self.angles_deg(traj) - self.angle_deg


@dataclass(frozen=True)
class KeepIn(_Cone):
    """angle(R_k b, s) <= angle_deg at every node (e.g. an antenna towards the ground).
    Smooth form: (R b).s - cos(angle) >= 0."""

    kind = "keep_in"
    dimension = "angle"

    def expression(self, X, inertia):
        return self.cos_angle(X) - np.cos(np.radians(self.angle_deg))

    def margin(self, traj) -> np.ndarray:
        return self.angle_deg - self.angles_deg(traj)


@dataclass(frozen=True)
class MaxAngularRate(_PositiveLimit):
    """|Omega_k| <= value at every node (Omega = J^-1 Pi, body frame).  Smooth form: value^2 - |Omega|^2 >= 0."""

    value: float
    kind = "max_angular_rate"
    dimension = "angular_rate"

    def expression(self, X, inertia):
        _, _, _, Pi = split_state(X)
        Jinv = np.linalg.inv(inertia)
        if isinstance(X, (ca.SX, ca.MX, ca.DM)):
            Om = ca.mtimes(ca.DM(Jinv), Pi)
            return self.value**2 - ca.dot(Om, Om)
        Om = Jinv @ Pi
        return self.value**2 - Om @ Om

    def margin(self, traj) -> np.ndarray:
        return self.value - np.linalg.norm(traj.Omega, axis=1)


PathConstraint = Union[MinRadius, KeepOut, KeepIn, MaxAngularRate]
#: the dimension of each path constraint's margin, by kind ('length', 'angle' in degrees, 'angular_rate'):
#: the unit labels come from problems.units (normalized orbit units only with a central body)
MARGIN_DIMENSION = {c.kind: c.dimension for c in (MinRadius, KeepOut, KeepIn, MaxAngularRate)}


@dataclass(frozen=True)
class ImpulsiveControl:
    """Impulses on the momenta at t = 0 and t = T, free motion between; cost: the sum of their norms."""


Control = Union[SmoothControl, ImpulsiveControl]


# ----------------------------------------------------------------------------- problem
@dataclass(frozen=True, eq=False)
class Problem:
    """An optimal control problem on the discretization ``disc`` (body model and scheme).

    N steps of size h = T/N from the initial state X0 (18) to ``terminal`` under ``control``.
    ``terminal`` and ``control`` may both be None: a motion to simulate only.
    time_bounds: (min, max) makes the final time free in [min, max] (T is then the guess).
    constraints: path constraints enforced at every node (MinRadius, KeepOut, KeepIn, MaxAngularRate).
    """

    disc: Discretization
    N: int
    T: float
    X0: np.ndarray
    terminal: Target | None = None
    control: Control | None = None
    name: str = ""
    time_bounds: tuple[float, float] | None = None
    constraints: tuple = ()

    def __post_init__(self):
        if isinstance(self.N, bool) or not isinstance(self.N, (int, np.integer)) or self.N < 1:
            raise ProblemError("N", f"expected a positive integer, got {self.N!r}")
        object.__setattr__(self, "N", int(self.N))
        if not (np.isfinite(self.T) and self.T > 0):
            raise ProblemError("T", f"expected a positive number, got {self.T!r}")
        X0 = np.asarray(self.X0, dtype=float).reshape(-1)
        if X0.shape != (NX,) or not np.all(np.isfinite(X0)):
            raise ProblemError("X0", f"expected a finite state of {NX} numbers")
        object.__setattr__(self, "X0", X0)
        if (self.terminal is None) != (self.control is None):
            raise ProblemError("terminal" if self.terminal is None else "control",
                               "a terminal target and a control go together (both, or neither for a simulation)")
        if isinstance(self.terminal, TargetOrbit) and self.disc.model.mu is None:
            raise ProblemError("terminal", "an orbit target needs a model with a central body (mu)")
        if isinstance(self.control, ImpulsiveControl) and isinstance(self.terminal, TargetState) and self.terminal.free:
            raise ProblemError("terminal.free", "an impulsive state target must give every component")
        if self.time_bounds is not None:
            lo, hi = (float(v) for v in self.time_bounds)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= self.T <= hi):
                raise ProblemError("time_bounds", f"expected 0 < min <= T (the guess) <= max, got {self.time_bounds} and "
                                                  f"T = {self.T}")
            if self.kind != "smooth":
                raise ProblemError("time_bounds", "a free final time needs smooth control")
            object.__setattr__(self, "time_bounds", (lo, hi))
        elif isinstance(self.control, SmoothControl) and self.control.objective == "time":
            raise ProblemError("time_bounds", "the time objective needs a free final time (time_bounds)")
        object.__setattr__(self, "constraints", tuple(self.constraints))
        for c in self.constraints:
            if not isinstance(c, (MinRadius, KeepOut, KeepIn, MaxAngularRate)):
                raise ProblemError("constraints", f"expected path constraints, got {type(c).__name__}")
        if self.constraints and self.kind == "impulsive":
            raise ProblemError("constraints", "path constraints need smooth control")

    @property
    def h(self) -> float:
        """T / N (with a free final time: of the guess T)."""
        return self.T / self.N

    @property
    def free_time(self) -> bool:
        return self.time_bounds is not None

    @property
    def kind(self) -> str | None:
        """'smooth', 'impulsive' or None (simulation only)."""
        if isinstance(self.control, SmoothControl):
            return "smooth"
        if isinstance(self.control, ImpulsiveControl):
            return "impulsive"
        return None

    @property
    def model(self):
        return self.disc.model

    @property
    def scheme(self) -> str:
        return self.disc.scheme

    @property
    def Xd(self) -> np.ndarray | None:
        """The target state (18) of a state target, else None."""
        return self.terminal.X if isinstance(self.terminal, TargetState) else None

    def replace(self, **changes) -> "Problem":
        """A copy with some fields changed (e.g. ``N``)."""
        import dataclasses

        return dataclasses.replace(self, **changes)


def state_from_velocities(model, position, velocity, R, omega) -> np.ndarray:
    """The 18-vector of a state given by position, inertial velocity, attitude (body -> inertial)
    and body angular velocity: gamma = m v, Pi = J Omega."""
    return pack_state(np.asarray(position, float), model.mass * np.asarray(velocity, float), np.asarray(R, float),
                      model.inertia @ np.asarray(omega, float))


# ------------------------------------------------------------------ terminal conditions
def _mm(A, B):
    if isinstance(A, (ca.SX, ca.MX, ca.DM)) or isinstance(B, (ca.SX, ca.MX, ca.DM)):
        return ca.mtimes(ca.DM(A) if isinstance(A, np.ndarray) else A, B)
    return A @ B


def state_residual(XN, Xd, fixed=STATE_COMPONENTS):
    """The terminal conditions of a state target (docs/mathematics.md §6): the blocks
    x_N - x_d, gamma_N - gamma_d (inertial), vee log(R_d^T R_N) (body frame at the target: three
    conditions, never nine) and Pi_N - Pi_d (body) of the ``fixed`` components, stacked.
    XN (and Xd): CasADi (18,1) (symbolic, differentiable) or NumPy (18,) (log accurate up to pi)."""
    x, g, R, P = split_state(XN)
    xd, gd, Rd, Pd = split_state(Xd)
    parts = {"position": x - xd, "velocity": g - gd, "attitude": log_so3(_mm(Rd.T, R)), "angular_velocity": P - Pd}
    rows = [parts[c] for c in fixed]
    if isinstance(XN, (ca.SX, ca.MX, ca.DM)) or isinstance(Xd, (ca.SX, ca.MX, ca.DM)):
        return ca.vertcat(*rows)
    return np.concatenate([np.asarray(r, dtype=float).ravel() for r in rows])


def terminal_residual(XN, target: TargetState):
    """:func:`state_residual` of a :class:`TargetState` (its fixed components)."""
    return state_residual(XN, target.X, target.fixed)


def orbit_conditions(XN, target: TargetOrbit, mass: float, mu: float):
    """Relaxed terminal set (docs/mathematics.md §5): (C (4), gamma_N^+ (3), Pi_N^+ (3)).

    C = [|x_N| - r_d; e_n^T x_N; a^T R_N b; b'^T R_N b] with (a, b') a basis of the orbit plane and b
    the body axis; gamma_N^+ = m sqrt(mu/r_d) (e_n x x_N)/r_d (inertial) the momentum of the
    circular orbit after the terminal impulse; Pi_N^+ = the target's Pi (body).  CasADi or NumPy.
    """
    n, a, b = target.plane_basis()
    rd = float(target.radius)
    x, _, R, _ = split_state(XN)
    axis = _mm(R, target.body_axis)
    vc = mass * np.sqrt(mu / rd) / rd
    if isinstance(XN, (ca.SX, ca.MX, ca.DM)):
        C = ca.vertcat(ca.norm_2(x) - rd, ca.dot(ca.DM(n), x), ca.dot(ca.DM(a), axis), ca.dot(ca.DM(b), axis))
        return C, vc * ca.cross(ca.DM(n), x), ca.DM(target.Pi)
    return np.array([np.linalg.norm(x) - rd, n @ x, a @ axis, b @ axis]), vc * np.cross(n, x), target.Pi.copy()


def orbit_residual(XN, target: TargetOrbit, mass: float, mu: float):
    """The orbit target's conditions at arrival under smooth control (10 rows, CasADi or NumPy):
    C (4) of :func:`orbit_conditions`, gamma_N - gamma^+(x_N) (3, inertial), Pi_N - Pi^+ (3, body)."""
    C, gp, Pp = orbit_conditions(XN, target, mass, mu)
    _, g, _, P = split_state(XN)
    if isinstance(XN, (ca.SX, ca.MX, ca.DM)):
        return ca.vertcat(C, g - gp, P - Pp)
    return np.concatenate([C, g - gp, P - Pp])


def terminal_rows(XN, problem: Problem):
    """The terminal residual rows at XN (NumPy or CasADi) of smooth control: an orbit target's
    :func:`orbit_residual`, a state target's :func:`terminal_residual` (its fixed components)."""
    target = problem.terminal
    if isinstance(target, TargetOrbit):
        return orbit_residual(XN, target, problem.model.mass, problem.model.mu)
    return terminal_residual(XN, target)


def terminal_error(XN: np.ndarray, problem: Problem, XN_plus: np.ndarray | None = None) -> float:
    """The terminal error of docs/mathematics.md §8 (NumPy): the max-norm of the terminal residual
    of a state target (for impulsive control evaluated after the terminal impulse, ``XN_plus``),
    of an orbit target max |C| (impulsive) or the max-norm of :func:`orbit_residual` (smooth)."""
    if isinstance(problem.terminal, TargetOrbit):
        rows = terminal_rows(XN, problem) if problem.kind == "smooth" else \
            orbit_conditions(XN, problem.terminal, problem.model.mass, problem.model.mu)[0]
        return float(np.abs(rows).max())
    if isinstance(problem.terminal, TargetState):
        X = XN if XN_plus is None else XN_plus
        if not np.all(np.isfinite(X)):
            return float("inf")
        return float(np.abs(terminal_rows(np.asarray(X, float), problem)).max())
    return float("nan")


# ----------------------------------------------------------------------------- costs
def quadrature_weights(scheme: str, N: int, h: float) -> np.ndarray:
    """omega_j of the controls (in the order of their nodes): first_order, controls u_1..u_N:
    h (1, ..., 1); lgvi, node controls u_0..u_N: the trapezoidal h (1/2, 1, ..., 1, 1/2), so that
    both approximate the integral of (1/2) u^T W u."""
    if scheme == "lgvi":
        om = np.full(N + 1, float(h))
        om[[0, -1]] = 0.5 * h
        return om
    return np.full(N, float(h))


def effort_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (1/2) u_j^T W u_j for U (6, n_controls), W = blkdiag(W_f, W_m)."""
    U = np.asarray(U, dtype=float)
    return float(0.5 * np.einsum("k,ik,ij,jk->", omega, U, control.W, U))


def fuel_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|) for U (6, n_controls) (the fuel objective)."""
    U = np.asarray(U, dtype=float)
    return float(np.sum(omega * (control.W_f[0, 0] * np.linalg.norm(U[U_FORCE], axis=0)
                                 + control.W_m[0, 0] * np.linalg.norm(U[U_MOMENT], axis=0))))


def objective_value(problem: "Problem", U: np.ndarray, h: float) -> float:
    """The objective of a smooth-control problem for controls U with step size h: effort, fuel
    (with the quadrature weights of the scheme) or the final time N h."""
    control: SmoothControl = problem.control
    if control.objective == "time":
        return float(problem.N * h)
    omega = quadrature_weights(problem.scheme, problem.N, h)
    return fuel_cost(U, control, omega) if control.objective == "fuel" else effort_cost(U, control, omega)


def control_activity(control: SmoothControl, U: np.ndarray, weights: np.ndarray, times: np.ndarray) -> dict:
    """Where the bounded controls sit on their bounds, per control ('force', 'moment'): at_bound_fraction
    (of the control nodes at the bound, :meth:`BoxBound.active` / :meth:`NormBound.active`: within
    AT_BOUND_RTOL), time_at_bound = sum_j omega_j over them (``weights`` the quadrature weights, so that
    it is the time the controls at the bound act), and switch_times: for a box bound every sign change
    of a component (the switches of a bang-bang control; linear interpolation between the node
    ``times``), for a norm bound the times where the control enters or leaves the bound (midpoints).
    Removed and unbounded controls are left out."""
    U = np.asarray(U, dtype=float)
    t = np.asarray(times, dtype=float)
    out = {}
    for name, sl, bound in (("force", U_FORCE, control.force_bound), ("moment", U_MOMENT, control.moment_bound)):
        if bound is None or (isinstance(bound, NormBound) and bound.b == 0):
            continue
        u = U[sl].T
        at = bound.active(u)
        if isinstance(bound, BoxBound):
            switches = []
            for i in range(3):
                ui = u[:, i]
                k = np.flatnonzero(ui[:-1] * ui[1:] < 0)
                switches.append([float(t[j] + (t[j + 1] - t[j]) * ui[j] / (ui[j] - ui[j + 1])) for j in k])
        else:
            k = np.flatnonzero(at[:-1] != at[1:])
            switches = [float(0.5 * (t[j] + t[j + 1])) for j in k]
        out[name] = {"bound": "box" if isinstance(bound, BoxBound) else "norm",
                     "at_bound_fraction": float(at.mean()) if len(at) else 0.0,
                     "time_at_bound": float(np.asarray(weights, float) @ at), "switch_times": switches}
    return out


def impulse_cost(impulses: dict[str, np.ndarray]) -> float:
    """The sum of the norms of the impulses (docs/mathematics.md §5)."""
    return float(sum(np.linalg.norm(v) for v in impulses.values()))
