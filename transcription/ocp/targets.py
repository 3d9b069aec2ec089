"""Terminal targets: a state (some components free), any point of a circular orbit, or the point of a circular
orbit where a target moving on it is at the final time (rendezvous)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import casadi as ca
import numpy as np

from ..geometry.state import NX
from ..geometry.so3 import is_symbolic
from .errors import ProblemError, positive, unit

#: the components of a state target, in the order of the terminal residual's blocks
STATE_COMPONENTS = ("position", "velocity", "attitude", "angular_velocity")


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
        positive(self.radius, "terminal.radius")
        Pi = np.asarray(self.Pi, dtype=float).reshape(-1)
        if Pi.shape != (3,) or not np.all(np.isfinite(Pi)):
            raise ProblemError("terminal.Pi", "expected a finite 3-vector")
        object.__setattr__(self, "Pi", Pi)
        for name in ("normal", "body_axis"):
            object.__setattr__(self, name, unit(getattr(self, name), f"terminal.{name}"))

    def plane_basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The unit normal e_n and an orthonormal basis (a, b) of the orbit plane."""
        n = self.normal
        t = np.eye(3)[int(np.argmin(np.abs(n)))]
        a = np.cross(n, t)
        a /= np.linalg.norm(a)
        return n, a, np.cross(n, a)

def ascending_node(normal: np.ndarray) -> np.ndarray:
    """The unit direction of the ascending node e_3 x n / |e_3 x n| of the plane with the unit normal n (the
    reference of the argument of latitude); e_1 for an equatorial plane (|e_3 x n| < 1e-12)."""
    a = np.cross([0.0, 0.0, 1.0], normal)
    return a / np.linalg.norm(a) if np.linalg.norm(a) >= 1e-12 else np.array([1.0, 0.0, 0.0])


@dataclass(frozen=True)
class TargetRendezvous:
    """Rendezvous with a target on the circular orbit of radius ``radius`` about the unit ``normal`` (through
    the central body at the origin), moving in the positive sense about the normal at the rate
    omega = sqrt(mu / r^3).  Its argument of latitude is u(t) = phase + omega t, measured from the unit
    ``node`` (in the plane; default the ascending node, :func:`ascending_node`):

        p(t) = r (cos u a + sin u (n x a)),    v(t) = r omega (-sin u a + cos u (n x a))     (inertial)

    The terminal position and velocity must equal the target's at t = T (with a free final time the point
    moves with T).  ``R`` (3x3) and ``Pi`` (3, body) give the terminal attitude and angular momentum, each
    optional (None: free).  Smooth control only (docs/mathematics.md §10)."""

    radius: float
    normal: np.ndarray
    phase: float
    node: np.ndarray | None = None
    R: np.ndarray | None = None
    Pi: np.ndarray | None = None

    def __post_init__(self):
        positive(self.radius, "terminal.radius")
        if not np.isfinite(self.phase):
            raise ProblemError("terminal.phase", "expected a finite angle (radians)")
        n = unit(self.normal, "terminal.normal")
        object.__setattr__(self, "normal", n)
        a = ascending_node(n) if self.node is None else unit(self.node, "terminal.node")
        if abs(a @ n) > 1e-9:
            raise ProblemError("terminal.node", "expected a direction in the orbit plane (perpendicular to the normal)")
        object.__setattr__(self, "node", a)
        if self.R is not None:
            R = np.asarray(self.R, dtype=float)
            if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) <= 0:
                raise ProblemError("terminal.R", "expected a rotation matrix")
            object.__setattr__(self, "R", R)
        if self.Pi is not None:
            Pi = np.asarray(self.Pi, dtype=float).reshape(-1)
            if Pi.shape != (3,) or not np.all(np.isfinite(Pi)):
                raise ProblemError("terminal.Pi", "expected a finite 3-vector")
            object.__setattr__(self, "Pi", Pi)

    @property
    def fixed(self) -> tuple[str, ...]:
        """The given components, in the order of :data:`STATE_COMPONENTS` (position and velocity always)."""
        return ("position", "velocity") + (("attitude",) if self.R is not None else ()) + \
            (("angular_velocity",) if self.Pi is not None else ())

    def rate(self, mu: float) -> float:
        """omega = sqrt(mu / r^3), the target's angular rate."""
        return float(np.sqrt(mu / self.radius**3))

    def advanced(self, dt: float, mu: float) -> "TargetRendezvous":
        """The same target with the clock started dt later (phase + omega dt): for a re-plan from time dt,
        whose final time T - dt is the same instant."""
        return TargetRendezvous(self.radius, self.normal, self.phase + self.rate(mu) * dt, self.node, self.R, self.Pi)

    def point(self, T, mu: float):
        """(p(T), v(T)): the target's position and velocity (inertial) at time T (a number, or CasADi symbolic:
        then CasADi (3,1) expressions of T)."""
        a, n = self.node, self.normal
        b = np.cross(n, a)
        w, r = self.rate(mu), float(self.radius)
        u = self.phase + w * T
        if is_symbolic(T):
            c, s = ca.cos(u), ca.sin(u)
            return r * (c * ca.DM(a) + s * ca.DM(b)), r * w * (-s * ca.DM(a) + c * ca.DM(b))
        c, s = np.cos(u), np.sin(u)
        return r * (c * a + s * b), r * w * (-s * a + c * b)


Target = Union[TargetState, TargetOrbit, TargetRendezvous]
