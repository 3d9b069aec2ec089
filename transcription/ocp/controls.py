"""Controls: smooth (weights, objective, bounds) or impulsive."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np

from ..geometry.state import NU, U_FORCE, U_MOMENT
from .actuators import Actuator
from .errors import ProblemError
from .objective import Objective


def spd_weight(W, name: str) -> np.ndarray:
    """A weight given as a scalar, a diagonal (3,) or a 3x3 matrix -> a 3x3 SPD matrix."""
    W = np.asarray(W, dtype=float)
    if W.ndim == 0:
        W = W * np.eye(3)
    elif W.shape == (3,):
        W = np.diag(W)
    if W.shape != (3, 3) or not np.all(np.isfinite(W)):
        raise ProblemError(name, "expected a positive number, 3 positive numbers or a symmetric positive definite 3x3 matrix")
    if not np.allclose(W, W.T, rtol=1e-12, atol=0.0) or np.linalg.eigvalsh(0.5 * (W + W.T)).min() <= 0:
        raise ProblemError(name, "expected a symmetric positive definite weight")
    return 0.5 * (W + W.T)


#: what bounds a control part: an actuator (:mod:`.actuators`)
Bound = Actuator

@dataclass(frozen=True)
class SmoothControl:
    """Controls u_f (inertial force) and u_m (body moment) at the nodes of the scheme.

    objective: an :class:`~transcription.ocp.objective.Objective` (docs/mathematics.md §6, §10: effort
      min sum_j omega_j (1/2)(u_f^T W_f u_f + u_m^T W_m u_m), time min T, fuel min sum_j omega_j (w_f |u_f,j| +
      w_m |u_m,j|), ...), which says what it needs of the weights W_f, W_m (SPD: scalars, diagonals or matrices).
    force_bound, moment_bound: an :class:`~transcription.ocp.actuators.Actuator` or None (unbounded);
    NormBound(0) removes the control.
    bounds_margin: m in [0, 1): the plan respects a fraction 1 - m of the actuators' bounds
    (:func:`actuator_bounds`), so a tracker keeps authority.
    """

    W_f: np.ndarray = field(default_factory=lambda: np.eye(3))
    W_m: np.ndarray = field(default_factory=lambda: np.eye(3))
    force_bound: Bound | None = None
    moment_bound: Bound | None = None
    bounds_margin: float = 0.0
    objective: Objective = field(kw_only=True)

    def __post_init__(self):
        m = self.bounds_margin
        if isinstance(m, bool) or not isinstance(m, (int, float, np.number)) or not (np.isfinite(m) and 0.0 <= m < 1.0):
            raise ProblemError("control.bounds_margin", f"expected a number in [0, 1), got {self.bounds_margin!r}")
        object.__setattr__(self, "W_f", spd_weight(self.W_f, "control.W_f"))
        object.__setattr__(self, "W_m", spd_weight(self.W_m, "control.W_m"))
        if not isinstance(self.objective, Objective):
            raise ProblemError("control.objective", f"expected an Objective (transcription.objectives), got "
                                                    f"{self.objective!r}")
        for name in ("force_bound", "moment_bound"):
            b = getattr(self, name)
            if b is not None and not isinstance(b, Actuator):
                raise ProblemError(f"control.{name}", "expected an Actuator (a BoxBound, a NormBound, a ThrusterBound) "
                                                      "or None")
        if self.moment_bound is not None and self.moment_bound.body_fixed:
            raise ProblemError("control.moment_bound", "a thruster bounds the force; the moment takes a box or a norm bound")
        self.objective.check(self)

    @property
    def W(self) -> np.ndarray:
        """blkdiag(W_f, W_m) (6x6)."""
        W = np.zeros((NU, NU))
        W[U_FORCE, U_FORCE] = self.W_f
        W[U_MOMENT, U_MOMENT] = self.W_m
        return W

    @property
    def bounded(self) -> bool:
        return self.force_bound is not None or self.moment_bound is not None

    @property
    def removed(self) -> tuple[bool, bool]:
        """(force removed, moment removed): a NormBound of 0."""
        return tuple(b is not None and b.removed for b in (self.force_bound, self.moment_bound))


def actuator_bounds(control: SmoothControl) -> tuple[Bound | None, Bound | None]:
    """(force, moment): the actuators' bounds, the plan's bounds divided by 1 - bounds_margin
    (the plan's own without a margin; a removed control stays removed)."""
    s = 1.0 / (1.0 - control.bounds_margin)
    force, moment = (b if b is None or s == 1.0 else b.scaled(s) for b in (control.force_bound, control.moment_bound))
    return force, moment


@dataclass(frozen=True)
class ImpulsiveControl:
    """Impulses on the momenta at t = 0 and t = T, free motion between; cost: the sum of their norms."""

Control = Union[SmoothControl, ImpulsiveControl]
