"""The rigid-body model seen by the method layer.

The method layer needs only the mass, the inertia matrix and a potential U(x, R) as a CasADi
Function; force and moment (docs/mathematics.md §1, eqs. 5-6) are derived from U by automatic
differentiation here, so any potential works.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Hashable

import casadi as ca
import numpy as np

from .layout import NX, split_state


def forces_from_potential(potential: ca.Function) -> ca.Function:
    """Build ``forces(x[3], R[3x3]) -> (f[3] inertial, M[3] body)`` from U(x, R).

    f = -dU/dx (eq. 5);  M = sum_i r_i x u_ri (eq. 6) with r_i the i-th row of R
    and u_ri the i-th row of dU/dR.
    """
    x = ca.SX.sym("x", 3)
    R = ca.SX.sym("R", 3, 3)
    U = potential(x, R)
    f = -ca.gradient(U, x)
    dUdR = ca.jacobian(U, ca.vec(R))  # 1 x 9, column-major entries of dU/dR
    dUdR = ca.reshape(dUdR, 3, 3)
    M = ca.SX.zeros(3, 1)
    for i in range(3):
        M += ca.cross(R[i, :].T, dUdR[i, :].T)
    return ca.Function("forces", [x, R], [f, M], ["x", "R"], ["f", "M"])


@dataclass(frozen=True, eq=False)
class BodyModel:
    """A rigid body in a potential field.

    mass: m > 0.  inertia: J (3x3, body frame, symmetric positive definite).
    potential: CasADi Function U(x[3] inertial, R[3x3] body->inertial) -> scalar.
    forces: (x, R) -> (f inertial, M body), derived from ``potential`` unless given.
    mu: gravitational parameter GM of a central body at the origin, or None (no central body);
        used for orbit targets and orbital elements, never by the dynamics (U carries the gravity).
    markers: body-fixed points (k, 3) drawn by the figures (e.g. the dumbbell's spheres); empty:
        the figures draw the principal axes.
    key: a hashable description of the model (e.g. its kind and parameters), by which a front end may
        share one model object between equal models (problems.models does), and with it its
        Discretizations; None: none.
    name: a label for reports.
    discretizations: the Discretization of each (scheme, Newton iterations) built for this model, kept on it
        (lgvi.discretization), so that the Functions built and compiled for one are reused by every Problem
        of the model.
    """

    mass: float
    inertia: np.ndarray
    potential: ca.Function
    forces: ca.Function = field(default=None)  # type: ignore[assignment]
    mu: float | None = None
    markers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    key: Hashable | None = None
    name: str = "rigid body"
    discretizations: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        J = np.asarray(self.inertia, dtype=float)
        if J.shape != (3, 3) or not np.all(np.isfinite(J)) or not np.allclose(J, J.T) or np.min(np.linalg.eigvalsh(J)) <= 0:
            raise ValueError("inertia must be a symmetric positive definite 3x3 matrix")
        if not self.mass > 0 or not np.isfinite(self.mass):
            raise ValueError("mass must be a positive number")
        if self.mu is not None and not (self.mu >= 0 and np.isfinite(self.mu)):
            raise ValueError("mu must be a non-negative number or None")
        object.__setattr__(self, "inertia", J)
        object.__setattr__(self, "markers", np.asarray(self.markers, dtype=float).reshape(-1, 3))
        if self.forces is None:
            object.__setattr__(self, "forces", forces_from_potential(self.potential))

    def energy(self) -> ca.Function:
        """E(X) = |gamma|^2/2m + Pi^T J^-1 Pi / 2 + U(x, R)  (docs/mathematics.md §8)."""
        X = ca.SX.sym("X", NX)
        x, gamma, R, Pi = split_state(X)
        Jinv = np.linalg.inv(self.inertia)
        E = ca.dot(gamma, gamma) / (2 * self.mass) + 0.5 * ca.mtimes([Pi.T, Jinv, Pi]) + self.potential(x, R)
        return ca.Function("energy", [X], [E], ["X"], ["E"])
