"""Path constraints enforced at every node: minimum radius, keep-out and keep-in cones (about a fixed inertial
direction, the nadir or the velocity), maximum angular rate, a reaction wheel's momentum.

Each has ``expression(X, inertia)`` (>= 0 where it holds; CasADi or NumPy, the smooth form the direct method
enforces), ``margin(trajectory)`` (in the constraint's own unit, >= 0 where it holds; for reports), ``row_scale(L)``
(the NLP's scale of its row, L the problem's length scale) and ``margin_scale(L)`` (what takes its margin into the
units of the flown miss, transcription.results.check)."""
from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache

import casadi as ca
import numpy as np

from ..geometry.state import NX, split_state
from ..geometry.so3 import is_symbolic, mtimes
from .errors import ProblemError, positive, unit


#: the state vectors a norm limit may bound: name -> (v(X, inertia) (CasADi or NumPy), its Trajectory attribute)
NORM_VECTORS = {"position": (lambda X, inertia: split_state(X)[0], "x"),
                "angular_velocity": (lambda X, inertia: mtimes(np.linalg.inv(inertia), split_state(X)[3]), "Omega")}


class _NormLimit:
    """A limit on the norm of the state vector ``of`` (a key of NORM_VECTORS) at every node, given by one positive
    number (its only field, checked on construction): ``lower``: |v| >= limit, smooth form |v| - limit >= 0; else
    |v| <= limit, smooth form limit^2 - |v|^2 >= 0 (smooth at v = 0).  A subclass names its ``kind``, the
    ``dimension`` of its margin, ``of`` and ``lower`` in its class line."""

    def __init_subclass__(cls, kind: str, dimension: str, of: str, lower: bool, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.kind, cls.dimension, cls.needs, cls.lower = kind, dimension, (of,), lower

    def __post_init__(self):
        name = fields(self)[0].name
        positive(getattr(self, name), f"constraints.{self.kind}.{name}")

    @property
    def limit(self) -> float:
        return getattr(self, fields(self)[0].name)

    def expression(self, X, inertia):
        v = NORM_VECTORS[self.needs[0]][0](X, inertia)
        if self.lower:
            return (ca.norm_2(v) if is_symbolic(X) else np.linalg.norm(v)) - self.limit
        return self.limit**2 - (ca.dot(v, v) if is_symbolic(X) else v @ v)

    def margin(self, traj) -> np.ndarray:
        n = np.linalg.norm(getattr(traj, NORM_VECTORS[self.needs[0]][1]), axis=1)
        return n - self.limit if self.lower else self.limit - n


@dataclass(frozen=True)
class MinRadius(_NormLimit, kind="min_radius", dimension="length", of="position", lower=True):
    """|x_k| >= radius at every node (stay above a sphere about the central body's centre); margin in length units."""

    radius: float

    def row_scale(self, length: float) -> float:
        return length

    def margin_scale(self, length: float) -> float:
        return 1.0 / length


#: the directions a cone may follow besides a fixed inertial one: the nadir -x/|x| and the direction of
#: motion gamma/|gamma| (docs/mathematics.md §10)
MOVING_DIRECTIONS = ("nadir", "velocity")


def cone_direction(X, direction):
    """The unit inertial direction d(X) (CasADi (3,1)) a cone is about at the symbolic state X (18,1):
    -x/|x| ('nadir'), gamma/|gamma| ('velocity', the direction of the velocity), or the fixed unit vector s."""
    x, g, _, _ = split_state(X)
    if isinstance(direction, str):
        v = -x if direction == "nadir" else g
        return v / ca.norm_2(v)
    return ca.DM(np.asarray(direction, float))


@lru_cache(maxsize=None)
def cone_function(body_axis: tuple, direction) -> ca.Function:
    """X (18) -> (cos, d): cos = (R b) . d(X), the cosine of the angle between the inertial image of the
    body axis b and the cone's direction d(X) (:func:`cone_direction`).  The one expression of a cone that
    the direct method's rows (called on SX, inlined), the margins on trajectories and the figures evaluate.
    ``body_axis`` and a fixed ``direction`` as tuples (hashable; the Function is built once per cone)."""
    X = ca.SX.sym("X", NX)
    _, _, R, _ = split_state(X)
    d = cone_direction(X, direction)
    return ca.Function("cone", [X], [ca.dot(mtimes(R, ca.DM(np.asarray(body_axis, float))), d), d], ["X"], ["cos", "d"])


@dataclass(frozen=True)
class _Cone:
    """A cone about a direction that is fixed (a unit 3-vector, e.g. the Sun) or moves with the state:
    'nadir' (-x/|x|) or 'velocity' (gamma/|gamma|)."""

    body_axis: np.ndarray
    direction: np.ndarray | str
    angle_deg: float

    def __post_init__(self):
        object.__setattr__(self, "body_axis", unit(self.body_axis, f"constraints.{self.kind}.body_axis"))
        if isinstance(self.direction, str):
            if self.direction not in MOVING_DIRECTIONS:
                raise ProblemError(f"constraints.{self.kind}.direction",
                                   f"expected {' or '.join(MOVING_DIRECTIONS)} or a 3-vector, got {self.direction!r}")
        else:
            object.__setattr__(self, "direction", unit(self.direction, f"constraints.{self.kind}.direction"))
        if not (np.isfinite(self.angle_deg) and 0 < self.angle_deg < 180):
            raise ProblemError(f"constraints.{self.kind}.angle", "expected an angle strictly between 0 and 180 degrees")

    @property
    def moving(self) -> bool:
        """True if the direction follows the state (nadir, velocity)."""
        return isinstance(self.direction, str)

    @property
    def needs(self) -> tuple[str, ...]:
        """The state components the cone is a function of (names of STATE_COMPONENTS)."""
        return ("attitude",) + {"nadir": ("position",), "velocity": ("velocity",)}.get(
            self.direction if self.moving else "", ())

    @property
    def function(self) -> ca.Function:
        """:func:`cone_function` of this cone."""
        d = self.direction if self.moving else tuple(float(a) for a in self.direction)
        return cone_function(tuple(float(a) for a in self.body_axis), d)

    def cos_angle(self, X):
        """(R b) . d(X) at one state X (CasADi symbolic: an expression; NumPy (18,): a float)."""
        c = self.function(X)[0]
        return c if is_symbolic(X) else float(c)

    def _along(self, traj, out: int) -> np.ndarray:
        K = traj.X.shape[0]
        return np.array(self.function.map(K)(np.asarray(traj.X, float).T)[out])

    def directions(self, traj) -> np.ndarray:
        """d(X_k) (K, 3) along a Trajectory (the moving direction a figure draws)."""
        return self._along(traj, 1).T

    def row_scale(self, length: float) -> float:
        return 1.0

    def margin_scale(self, length: float) -> float:
        """A degree in radians: the angle's margin as the flown attitude miss."""
        return np.pi / 180.0

    def angles_deg(self, traj) -> np.ndarray:
        """angle(R_k b, d(X_k)) in degrees (K,) along a Trajectory."""
        c = self._along(traj, 0).ravel()
        return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


@dataclass(frozen=True)
class KeepOut(_Cone):
    """angle(R_k b, d_k) >= angle_deg at every node: the body axis b stays out of a cone about the
    direction d_k (fixed: e.g. a camera and the Sun; or nadir, velocity).  Smooth form: cos(angle) - (R b).d >= 0."""

    kind = "keep_out"
    dimension = "angle"

    def expression(self, X, inertia):
        return np.cos(np.radians(self.angle_deg)) - self.cos_angle(X)

    def margin(self, traj) -> np.ndarray:
        return self.angles_deg(traj) - self.angle_deg


@dataclass(frozen=True)
class KeepIn(_Cone):
    """angle(R_k b, d_k) <= angle_deg at every node (e.g. an antenna towards the ground: d = nadir).
    Smooth form: (R b).d - cos(angle) >= 0."""

    kind = "keep_in"
    dimension = "angle"

    def expression(self, X, inertia):
        return self.cos_angle(X) - np.cos(np.radians(self.angle_deg))

    def margin(self, traj) -> np.ndarray:
        return self.angle_deg - self.angles_deg(traj)


@dataclass(frozen=True)
class MaxAngularRate(_NormLimit, kind="max_angular_rate", dimension="angular_rate", of="angular_velocity",
                     lower=False):
    """|Omega_k| <= value at every node (Omega = J^-1 Pi, body frame)."""

    value: float

    def row_scale(self, length: float) -> float:
        return self.value**2

    def margin_scale(self, length: float) -> float:
        return 1.0


@dataclass(frozen=True)
class WheelMomentum:
    """|h_i| <= limit at every node: the momentum of reaction wheel ``wheel`` (1-based) of a set on the body axes A
    (3, n) that produces the plan's moment u_m (body frame).  The wheels start at rest relative to the body and only
    the wheels turn the body, so the body's and the wheels' angular momentum H = R (Pi + A h_w) (inertial) keeps its
    initial value H_0 = R_0 Pi_0, and the wheels, commanded by the pseudo-inverse A^+ (as the flight's wheels are,
    transcription.dynamics.wheels), hold

        h_w = A^+ (R^T H_0 - Pi),    h_i = a_i^T (R^T H_0 - Pi),    a_i = ``row`` (3,), the i-th row of A^+.

    Exact without external torques (a slew without a central body: a maneuver file refuses it with one, whose
    gravity-gradient torque changes H).  Smooth form limit^2 - h_i^2 >= 0 (row scale limit^2); margin limit - |h_i|
    (angular momentum units: N m s in an SI file)."""

    row: tuple
    H0: tuple
    limit: float
    wheel: int = 1

    kind = "wheel_momentum"
    dimension = "angular_impulse"
    needs = ("attitude", "angular_velocity")

    def __post_init__(self):
        positive(self.limit, f"constraints.{self.kind}.limit")
        for name in ("row", "H0"):
            a = np.asarray(getattr(self, name), float).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ProblemError(f"constraints.{self.kind}.{name}", "expected 3 finite numbers")
            object.__setattr__(self, name, tuple(float(x) for x in a))

    def momentum(self, X):
        """h_i at one state X (CasADi symbolic: an expression; NumPy (18,): a float)."""
        _, _, R, Pi = split_state(X)
        body = mtimes(R.T, np.asarray(self.H0)) - Pi
        return ca.dot(ca.DM(self.row), body) if is_symbolic(X) else float(np.asarray(self.row) @ body)

    def expression(self, X, inertia):
        h = self.momentum(X)
        return self.limit**2 - h * h

    def margin(self, traj) -> np.ndarray:
        body = np.einsum("kji,j->ki", traj.R, np.asarray(self.H0)) - traj.Pi
        return self.limit - np.abs(body @ np.asarray(self.row))

    def row_scale(self, length: float) -> float:
        return self.limit**2

    def margin_scale(self, length: float) -> float:
        """The margin as a fraction of the limit."""
        return 1.0 / self.limit


def wheel_momentum_constraints(axes, limits, R0, Pi0) -> tuple[WheelMomentum, ...]:
    """One :class:`WheelMomentum` per wheel of axes (3, n) with momentum limits (n,), for the initial attitude R0
    (3, 3) and body angular momentum Pi0 (3,) (the wheels at rest relative to the body at t = 0)."""
    A = np.asarray(axes, float)
    H0 = np.asarray(R0, float) @ np.asarray(Pi0, float)
    P = np.linalg.pinv(A)
    return tuple(WheelMomentum(P[i], H0, float(lim), i + 1) for i, lim in enumerate(np.broadcast_to(limits, (A.shape[1],))))


#: the path constraints a Problem accepts
PATH_CONSTRAINTS = (MinRadius, KeepOut, KeepIn, MaxAngularRate, WheelMomentum)
#: the dimension of each path constraint's margin, by kind ('length', 'angle' in degrees, 'angular_rate'):
#: the unit labels come from problems.units (normalized orbit units only with a central body)
MARGIN_DIMENSION = {c.kind: c.dimension for c in PATH_CONSTRAINTS}
