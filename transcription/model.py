"""The rigid-body model seen by the method layer.

The method layer needs only the mass, the inertia matrix and a potential
U(x, R) as a CasADi Function; force and moment (SPEC §1 eqs. 5-6) are derived
from U by automatic differentiation here, so any potential works.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np


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


@dataclass(frozen=True)
class BodyModel:
    """A rigid body in a potential field.

    mass: m > 0.  inertia: J (3x3, body frame, symmetric positive definite).
    potential: CasADi Function U(x[3] inertial, R[3x3] body->inertial) -> scalar.
    forces: (x, R) -> (f inertial, M body), derived from ``potential`` unless given.
    """

    mass: float
    inertia: np.ndarray
    potential: ca.Function
    forces: ca.Function = field(default=None)  # type: ignore[assignment]

    def __post_init__(self):
        J = np.asarray(self.inertia, dtype=float)
        if J.shape != (3, 3) or not np.allclose(J, J.T) or np.min(np.linalg.eigvalsh(J)) <= 0:
            raise ValueError("inertia must be a symmetric positive definite 3x3 matrix")
        if not self.mass > 0:
            raise ValueError("mass must be positive")
        object.__setattr__(self, "inertia", J)
        if self.forces is None:
            object.__setattr__(self, "forces", forces_from_potential(self.potential))

    def energy(self) -> ca.Function:
        """E(X) = |gamma|^2/2m + Pi^T J^-1 Pi / 2 + U(x, R)  (SPEC §8)."""
        from .layout import NX, split_state

        X = ca.SX.sym("X", NX)
        x, gamma, R, Pi = split_state(X)
        Jinv = np.linalg.inv(self.inertia)
        E = ca.dot(gamma, gamma) / (2 * self.mass) + 0.5 * ca.mtimes([Pi.T, Jinv, Pi]) + self.potential(x, R)
        return ca.Function("energy", [X], [E], ["X"], ["E"])
