"""Path constraints enforced at every node: minimum radius, keep-out and keep-in cones, maximum angular rate.

Each has ``expression(X, inertia)`` (>= 0 where it holds; CasADi or NumPy, the smooth form the direct method
enforces) and ``margin(trajectory)`` (in the constraint's own unit, >= 0 where it holds; for reports)."""
from __future__ import annotations

from dataclasses import dataclass, fields

import casadi as ca
import numpy as np

from ..layout import split_state
from ..lie import is_symbolic, mtimes
from .errors import ProblemError, positive, unit


class _PositiveLimit:
    """A path constraint given by one positive number (its only field), checked on construction."""

    def __post_init__(self):
        name = fields(self)[0].name
        positive(getattr(self, name), f"constraints.{self.kind}.{name}")


@dataclass(frozen=True)
class MinRadius(_PositiveLimit):
    """|x_k| >= radius at every node (stay above a sphere about the central body's centre)."""

    radius: float
    kind = "min_radius"
    dimension = "length"

    def expression(self, X, inertia):
        """g(X) >= 0 (CasADi or NumPy): |x| - r (in length units; the margin)."""
        x, _, _, _ = split_state(X)
        return (ca.norm_2(x) if is_symbolic(X) else np.linalg.norm(x)) - self.radius

    def margin(self, traj) -> np.ndarray:
        return np.linalg.norm(traj.x, axis=1) - self.radius


@dataclass(frozen=True)
class _Cone:
    body_axis: np.ndarray
    direction: np.ndarray
    angle_deg: float

    def __post_init__(self):
        object.__setattr__(self, "body_axis", unit(self.body_axis, f"constraints.{self.kind}.body_axis"))
        object.__setattr__(self, "direction", unit(self.direction, f"constraints.{self.kind}.direction"))
        if not (np.isfinite(self.angle_deg) and 0 < self.angle_deg < 180):
            raise ProblemError(f"constraints.{self.kind}.angle", "expected an angle strictly between 0 and 180 degrees")

    def cos_angle(self, X):
        """(R b) . s, the cosine of the angle between the inertial image of the body axis and the direction."""
        _, _, R, _ = split_state(X)
        return (ca.dot(mtimes(R, ca.DM(self.body_axis)), ca.DM(self.direction))
                if is_symbolic(X) else (R @ self.body_axis) @ self.direction)

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
        Om = mtimes(np.linalg.inv(inertia), Pi)
        return self.value**2 - (ca.dot(Om, Om) if is_symbolic(X) else Om @ Om)

    def margin(self, traj) -> np.ndarray:
        return self.value - np.linalg.norm(traj.Omega, axis=1)


#: the path constraints a Problem accepts
PATH_CONSTRAINTS = (MinRadius, KeepOut, KeepIn, MaxAngularRate)
#: the dimension of each path constraint's margin, by kind ('length', 'angle' in degrees, 'angular_rate'):
#: the unit labels come from problems.units (normalized orbit units only with a central body)
MARGIN_DIMENSION = {c.kind: c.dimension for c in (MinRadius, KeepOut, KeepIn, MaxAngularRate)}
