"""A motion at its nodes: node times, states, and the body's mass and inertia, with the quantities an engineer
reads off it (positions, velocities, attitudes, angular velocities)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.so3 import orthogonality_error
from ..geometry.state import unpack_states


@dataclass(frozen=True)
class Trajectory:
    """Node values of a motion: times t (N+1,), states X (N+1, 18) (layout of transcription.geometry.state),
    and the body's mass and inertia, so that velocities are at hand.

    Derived (node-major, computed once): x (N+1, 3) inertial position; gamma linear momentum and
    v = gamma/m inertial velocity; R (N+1, 3, 3) body -> inertial; Pi body angular momentum and
    Omega = J^-1 Pi body angular velocity.
    """

    t: np.ndarray
    X: np.ndarray
    mass: float = 1.0
    inertia: np.ndarray = field(default_factory=lambda: np.eye(3))
    x: np.ndarray = field(init=False, repr=False)
    gamma: np.ndarray = field(init=False, repr=False)
    v: np.ndarray = field(init=False, repr=False)
    R: np.ndarray = field(init=False, repr=False)
    Pi: np.ndarray = field(init=False, repr=False)
    Omega: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        s = unpack_states(self.X)
        derived = {"x": s.x, "gamma": s.gamma, "v": s.gamma / self.mass, "R": s.R, "Pi": s.Pi,
                   "Omega": np.linalg.solve(self.inertia, s.Pi.T).T}
        for k, a in derived.items():
            object.__setattr__(self, k, a)

    def orthogonality(self) -> dict[str, float]:
        """max_k |R_k^T R_k - I|_F and max_k |det R_k - 1| (docs/mathematics.md §8)."""
        orth, det = orthogonality_error(self.R)
        return {"max_orthogonality_error": float(orth.max()), "max_determinant_error": float(det.max())}

    def __repr__(self) -> str:
        return f"Trajectory(N = {len(self.t) - 1}, T = {float(self.t[-1]):.6g}, mass {self.mass:g})"


def trajectory(problem, X: np.ndarray, h: float | None = None) -> Trajectory:
    """The Trajectory of node states X (N+1, 18) of ``problem``: the node times of its mesh for the (mean) step h
    (the problem's by default): k h on a uniform mesh, t_k = sum_{i<k} h r_i on a non-uniform one
    (:meth:`~transcription.ocp.Problem.times_of`); the problem's mass and inertia."""
    m, h = problem.model, (problem.h if h is None else h)
    t = problem.times_of(h) if X.shape[0] == problem.N + 1 else h * np.arange(X.shape[0])
    return Trajectory(t=t, X=X, mass=m.mass, inertia=m.inertia)
