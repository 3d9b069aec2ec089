"""The dumbbell spacecraft in a central gravity field (docs/mathematics.md §1).

Two equal spheres of mass m/2 and radius r_s at body-fixed rho_1 = +(l/2) e1,
rho_2 = -(l/2) e1, joined by a massless rod; a fixed central body of
gravitational parameter mu = GM at the origin (restricted full two-body problem).
Normalized units: mass m, orbit radius 1, orbital period 1, so GM = 4 pi^2.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..transcription.model import BodyModel

GM_NORMALIZED = 4.0 * np.pi**2


@dataclass(frozen=True)
class Dumbbell:
    """Dumbbell parameters: mass m, rod length l, sphere radius r_s, central body mu = GM."""

    mass: float = 1.0
    length: float = 0.1
    sphere_radius: float = 0.02
    mu: float = GM_NORMALIZED

    @property
    def rho(self) -> np.ndarray:
        """Body-fixed sphere centres, shape (2, 3)."""
        e1 = np.array([1.0, 0.0, 0.0])
        return np.array([0.5 * self.length * e1, -0.5 * self.length * e1])

    @property
    def inertia(self) -> np.ndarray:
        """J = sum_q (m/2)(|rho_q|^2 I - rho_q rho_q^T) + 2 (2/5)(m/2) r_s^2 I (body frame)."""
        m2 = 0.5 * self.mass
        J = sum(m2 * (q @ q * np.eye(3) - np.outer(q, q)) for q in self.rho)
        return J + 2 * 0.4 * m2 * self.sphere_radius**2 * np.eye(3)

    def potential(self) -> ca.Function:
        """U(x, R) = -sum_q mu (m/2) / |x + R rho_q|."""
        x = ca.SX.sym("x", 3)
        R = ca.SX.sym("R", 3, 3)
        U = 0
        for q in self.rho:
            U -= self.mu * 0.5 * self.mass / ca.norm_2(x + ca.mtimes(R, ca.DM(q)))
        return ca.Function("dumbbell_potential", [x, R], [U], ["x", "R"], ["U"])

    def moment_point_masses(self) -> ca.Function:
        """The alternative moment formula M = sum_q rho_q x (R^T f_q) (docs/mathematics.md §1), for checks."""
        x = ca.SX.sym("x", 3)
        R = ca.SX.sym("R", 3, 3)
        M = ca.SX.zeros(3, 1)
        for q in self.rho:
            y = x + ca.mtimes(R, ca.DM(q))
            fq = -self.mu * 0.5 * self.mass * y / ca.norm_2(y) ** 3
            M += ca.cross(ca.DM(q), ca.mtimes(R.T, fq))
        return ca.Function("dumbbell_moment_pm", [x, R], [M], ["x", "R"], ["M"])

    def body_model(self) -> BodyModel:
        """The BodyModel: U by this potential, mu for orbit targets, the sphere centres as markers
        for the figures, and a key so that equal dumbbells share their Functions."""
        return BodyModel(mass=self.mass, inertia=self.inertia, potential=self.potential(), mu=self.mu,
                         markers=self.rho, key=("dumbbell", self.mass, self.length, self.sphere_radius, self.mu),
                         name="dumbbell")
