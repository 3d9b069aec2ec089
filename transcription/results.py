"""Result types shared by every method.

A :class:`Solution` is data: a failed solve is a Solution with ``converged =
False`` and a readable ``message``, never an exception.  Its trajectory is the
**re-simulation** of the discrete equations from the initial state with the
returned controls or impulses (SPEC §8), so it lies on SO(3) to round-off and
``terminal_error`` is measured on it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from .layout import States, unpack_states
from .lie import log_so3, orthogonality_error


class SolverOptionError(ValueError):
    """A raw solver option the solver plugin rejects; ``option`` names it (e.g. 'mu_init')."""

    def __init__(self, option: str, message: str):
        self.option = option
        super().__init__(message)


@dataclass(frozen=True)
class Trajectory:
    """Node values t (N+1,), X (N+1, 18) in the layout of transcription.layout."""

    t: np.ndarray
    X: np.ndarray

    @property
    def states(self) -> States:
        return unpack_states(self.X)

    def orthogonality(self) -> dict[str, float]:
        """max_k |R_k^T R_k - I|_F and max_k |det R_k - 1| (SPEC §8)."""
        orth, det = orthogonality_error(self.states.R)
        return {"max_orthogonality_error": float(orth.max()), "max_determinant_error": float(det.max())}


def terminal_error_full(X_N: np.ndarray, Xd: np.ndarray) -> float:
    """SPEC §8: max of the inf-norms of the x, gamma, Pi differences and of vee log(Rd^T R_N)."""
    a = unpack_states(X_N)
    d = unpack_states(Xd)
    e_rot = log_so3(d.R[0].T @ a.R[0])
    return float(max(np.abs(a.x - d.x).max(), np.abs(a.gamma - d.gamma).max(), np.abs(a.Pi - d.Pi).max(), np.abs(e_rot).max()))


@dataclass
class Solution:
    """Outcome of one solve.

    method: 'direct' | 'indirect' | 'impulsive'; solver: e.g. 'ipopt', 'newton-armijo'.
    controls: (6, n_controls) [u_f (inertial); u_m (body)] or None.
    impulses: for impulsive maneuvers, dict with dgamma0, dPi0, dgammaN, dPiN (3,) each.
    costates: (N, 12) multipliers lambda_k (indirect, or mapped from the direct NLP) or None.
    history: per-iteration records (dicts), e.g. Newton-Armijo trials.
    """

    method: str
    solver: str
    discretization: str
    N: int
    h: float
    trajectory: Trajectory
    status: str
    message: str
    converged: bool
    cost: float
    terminal_error: float
    iterations: int
    build_s: float
    solve_s: float
    controls: np.ndarray | None = None
    impulses: dict[str, np.ndarray] | None = None
    costates: np.ndarray | None = None
    history: list[dict[str, Any]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-ready scalar summary (the per-method block of summary.json)."""
        out = {
            "method": self.method,
            "status": self.status,
            "message": self.message,
            "converged": bool(self.converged),
            "cost": float(self.cost),
            "terminal_error": float(self.terminal_error),
            "iterations": int(self.iterations),
            "build_s": float(self.build_s),
            "solve_s": float(self.solve_s),
            "N": int(self.N),
            "h": float(self.h),
            "discretization": self.discretization,
            "solver": self.solver,
        }
        out.update(self.trajectory.orthogonality())
        out.update({k: v for k, v in self.extra.items() if isinstance(v, (int, float, str, bool, type(None)))})
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        """Arrays for the .npz file: t, x, gamma, Pi (N+1,3), R (N+1,3,3), u_f, u_m, lam, ..."""
        s = self.trajectory.states
        out = {"t": self.trajectory.t, "x": s.x, "gamma": s.gamma, "Pi": s.Pi, "R": s.R}
        if self.controls is not None:
            out["u_f"] = self.controls[0:3].T
            out["u_m"] = self.controls[3:6].T
        if self.impulses is not None:
            out.update({k: np.asarray(v) for k, v in self.impulses.items()})
        if self.costates is not None:
            out["lam"] = self.costates
        return out


def to_jsonable(obj):
    """Convert numpy scalars/arrays inside dicts/lists to plain Python for json.dump."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if hasattr(obj, "__dataclass_fields__"):
        return to_jsonable(asdict(obj))
    return obj
