"""Terminal targets: a state (some components free) or any point of a circular orbit."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np

from ..layout import NX
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

Target = Union[TargetState, TargetOrbit]
