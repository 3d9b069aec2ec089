"""The rigid-body model seen by the method layer.

The mass, the inertia and a potential U(x, R) as a CasADi Function; force and moment (docs/mathematics.md §1, eqs.
5-6) are derived from U by automatic differentiation, so any potential works.  A model may also give U(x, R, q) with
q = ``potential_data`` (GM, J2, radius, sizes, ...): :attr:`BodyModel.parameters` is then theta = [m; vec J;
vec (2J)^-1; q], data of the compiled Functions, which serve every model of the same structure without a new compile.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Hashable

import casadi as ca
import numpy as np

from ..geometry.state import NX, split_state


def forces_from_potential(potential: ca.Function) -> ca.Function:
    """Build ``forces(x[3], R[3x3]) -> (f[3] inertial, M[3] body)`` from U(x, R), or
    ``forces(x, R, q) -> (f, M)`` from a parametric U(x, R, q).

    f = -dU/dx (eq. 5);  M = sum_i r_i x u_ri (eq. 6) with r_i the i-th row of R
    and u_ri the i-th row of dU/dR.
    """
    x = ca.SX.sym("x", 3)
    R = ca.SX.sym("R", 3, 3)
    q = [ca.SX.sym("q", potential.size1_in(2))] if potential.n_in() > 2 else []
    U = potential(x, R, *q)
    f = -ca.gradient(U, x)
    dUdR = ca.jacobian(U, ca.vec(R))  # 1 x 9, column-major entries of dU/dR
    dUdR = ca.reshape(dUdR, 3, 3)
    M = ca.SX.zeros(3, 1)
    for i in range(3):
        M += ca.cross(R[i, :].T, dUdR[i, :].T)
    return ca.Function("forces", [x, R, *q], [f, M], ["x", "R", "q"][:2 + len(q)], ["f", "M"])


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
    key: a hashable description of the model, by which a front end may share one model object (and its
        Discretizations) between equal models (problems.models does); None: none.
    name: a label for reports.
    parametric_potential: U(x[3], R[3x3], q) with ``potential(x, R) = parametric_potential(x, R, potential_data)``,
        or None (then the potential's numbers are constants of the compiled Functions: one compile per model).
    potential_data: q (nq,), the numbers of ``parametric_potential``.
    discretizations: the Discretization of each (scheme, Newton iterations, force frame) built for this model
        (lgvi.discretization), shared by every Problem of the model.
    """

    mass: float
    inertia: np.ndarray
    potential: ca.Function
    forces: ca.Function = field(default=None)  # type: ignore[assignment]
    mu: float | None = None
    markers: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    key: Hashable | None = None
    name: str = "rigid body"
    parametric_potential: ca.Function | None = None
    potential_data: np.ndarray = field(default_factory=lambda: np.zeros(0))
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
        object.__setattr__(self, "potential_data", np.asarray(self.potential_data, dtype=float).ravel())
        if self.parametric_potential is not None and self.parametric_potential.size1_in(2) != self.potential_data.size:
            raise ValueError("potential_data must have the size of parametric_potential's input q")
        if self.forces is None:
            object.__setattr__(self, "forces", forces_from_potential(self.potential))

    #: the layout of :attr:`parameters`: mass, vec J (column-major), vec (2J)^-1, then q
    N_FIXED_PARAMETERS = 19

    @property
    def parameters(self) -> np.ndarray:
        """theta = [m; vec J (9); vec (2J)^-1 (9); q] (column-major): every number of the dynamics, the data of
        lgvi.Discretization.parametric.  (2J)^-1 is data, not computed on the graph, so it is NumPy's number."""
        J = self.inertia
        return np.concatenate([[self.mass], J.ravel(order="F"), np.linalg.inv(2 * J).ravel(order="F"),
                               self.potential_data if self.parametric_potential is not None else []])

    def parametric_forces(self) -> ca.Function:
        """(x[3], R[3x3], q) -> (f, M) with q = :attr:`parameters`' tail: the parametric potential's forces, or the
        numeric ``forces`` (q empty) when the model has no parametric potential."""
        if self.parametric_potential is not None:
            return forces_from_potential(self.parametric_potential)
        x, R, q = ca.SX.sym("x", 3), ca.SX.sym("R", 3, 3), ca.SX.sym("q", 0)
        return ca.Function("forces", [x, R, q], list(self.forces(x, R)), ["x", "R", "q"], ["f", "M"])

    def energy(self) -> ca.Function:
        """E(X) = |gamma|^2/2m + Pi^T J^-1 Pi / 2 + U(x, R)  (docs/mathematics.md §8)."""
        X = ca.SX.sym("X", NX)
        x, gamma, R, Pi = split_state(X)
        Jinv = np.linalg.inv(self.inertia)
        E = ca.dot(gamma, gamma) / (2 * self.mass) + 0.5 * ca.mtimes([Pi.T, Jinv, Pi]) + self.potential(x, R)
        return ca.Function("energy", [X], [E], ["X"], ["E"])
