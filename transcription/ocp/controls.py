"""Controls: smooth (weights, objective, bounds) or impulsive."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

import numpy as np

from ..geometry.state import NU, U_FORCE, U_MOMENT
from ..geometry.so3 import rotation_with_first_column
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


#: a control counts as "at its bound" where it is within this fraction of the limit (an interior-point
#: solution sits a little inside: the fuel-optimal burns of configs/orbit_raise_fuel.yaml at 1 - 4e-5)
AT_BOUND_RTOL = 1e-3


@dataclass(frozen=True)
class BoxBound:
    """|u_i| <= b_i for each component i of a 3-vector control (b_i > 0), in the control's frame
    (inertial for the force, body for the moment)."""

    b: np.ndarray

    def __post_init__(self):
        b = np.asarray(self.b, dtype=float).reshape(-1)
        if b.shape != (3,) or not np.all(np.isfinite(b)) or not np.all(b > 0):
            raise ProblemError("bounds.box", "expected 3 positive finite limits")
        object.__setattr__(self, "b", b)

    def margin(self, u: np.ndarray) -> np.ndarray:
        """min_i (b_i - |u_i|) for controls u (n, 3): >= 0 where the bound holds."""
        return np.min(self.b[None, :] - np.abs(np.asarray(u, float)), axis=1)

    def scale(self) -> float:
        return float(self.b.max())

    def scaled(self, s: float) -> "BoxBound":
        """The box with every limit times s > 0 (a bounds margin: s = 1 - m for the plan, 1 / (1 - m) back)."""
        return BoxBound(self.b * s)

    def largest_norm(self) -> float:
        """The largest |u|_2 the bound allows: |b|_2 (a corner of the box)."""
        return float(np.linalg.norm(self.b))

    def active_components(self, u: np.ndarray) -> np.ndarray:
        """(n, 3) bool: |u_i| within AT_BOUND_RTOL of b_i."""
        return np.abs(np.asarray(u, float)) >= self.b[None, :] * (1.0 - AT_BOUND_RTOL)

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: some component at its bound."""
        return np.any(self.active_components(u), axis=1)


@dataclass(frozen=True)
class NormBound:
    """|u|_2 <= b (b >= 0; b = 0 removes the control)."""

    b: float

    def __post_init__(self):
        if not (np.isfinite(self.b) and self.b >= 0):
            raise ProblemError("bounds.norm", "expected a non-negative finite limit")
        object.__setattr__(self, "b", float(self.b))

    def margin(self, u: np.ndarray) -> np.ndarray:
        """b - |u| for controls u (n, 3)."""
        return self.b - np.linalg.norm(np.asarray(u, float), axis=1)

    def scale(self) -> float:
        return self.b

    def scaled(self, s: float) -> "NormBound":
        """The norm bound times s > 0 (a removed control, b = 0, stays removed)."""
        return NormBound(self.b * s)

    def largest_norm(self) -> float:
        """The largest |u|_2 the bound allows: b."""
        return self.b

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: |u| within AT_BOUND_RTOL of b (never for b = 0: a removed control is absent)."""
        return (np.linalg.norm(np.asarray(u, float), axis=1) >= self.b * (1.0 - AT_BOUND_RTOL)) & (self.b > 0)

@dataclass(frozen=True)
class ThrusterBound:
    """One engine fixed in the body (force_frame 'body' only): u_f = T a, a the unit engine axis (body
    frame, normalized here) and min <= T <= max (0 <= min < max, finite).  Off-axis force is not available."""

    axis: np.ndarray
    max: float
    min: float = 0.0

    def __post_init__(self):
        a = np.asarray(self.axis, dtype=float).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise ProblemError("bounds.thruster.axis", "expected a non-zero 3-vector (the engine axis in the body frame)")
        lo, hi = float(self.min), float(self.max)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi):
            raise ProblemError("bounds.thruster", f"expected 0 <= min < max, finite, got min {lo!r}, max {hi!r}")
        object.__setattr__(self, "axis", a / np.linalg.norm(a))
        object.__setattr__(self, "max", hi)
        object.__setattr__(self, "min", lo)

    def thrust(self, u: np.ndarray) -> np.ndarray:
        """T = a^T u_f for force controls u (n, 3) in the body frame."""
        return np.asarray(u, float) @ self.axis

    def off_axis(self, u: np.ndarray) -> np.ndarray:
        """|u_f - T a| (n,): the force the engine cannot give (0 for a feasible control)."""
        u = np.asarray(u, float)
        return np.linalg.norm(u - np.outer(self.thrust(u), self.axis), axis=1)

    def margin(self, u: np.ndarray) -> np.ndarray:
        """min(max - T, T - min) - |off-axis force| for controls u (n, 3): >= 0 where the bound holds."""
        T = self.thrust(u)
        return np.minimum(self.max - T, T - self.min) - self.off_axis(u)

    def scale(self) -> float:
        return self.max

    def scaled(self, s: float) -> "ThrusterBound":
        """The engine with its largest thrust times s > 0 (the least thrust, an engine's minimum, kept)."""
        return ThrusterBound(self.axis, self.max * s, self.min)

    def largest_norm(self) -> float:
        """The largest |u_f|_2 the engine gives: max (|R u_f| = |u_f| = T, in either frame)."""
        return self.max

    def basis(self) -> np.ndarray:
        """Q = [a, b, c] (3x3 rotation, body frame): the engine axis and two perpendicular directions; Q^T u_f
        = [T, off-axis force (2)] (:func:`~transcription.geometry.so3.rotation_with_first_column`)."""
        return rotation_with_first_column(self.axis)

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: the thrust within AT_BOUND_RTOL (of max) of max or of min."""
        T, tol = self.thrust(u), AT_BOUND_RTOL * self.max
        return (T >= self.max - tol) | (T <= self.min + tol)


Bound = Union[BoxBound, NormBound, ThrusterBound]

@dataclass(frozen=True)
class SmoothControl:
    """Controls u_f (inertial force) and u_m (body moment) at the nodes of the scheme.

    objective: an :class:`~transcription.ocp.objective.Objective` (docs/mathematics.md §6, §10; the kinds are the
      modules of :mod:`transcription.objectives`: effort min sum_j omega_j (1/2)(u_f^T W_f u_f + u_m^T W_m u_m),
      time min T, fuel min sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|), ...), which says what it needs of the
      weights W_f, W_m (symmetric positive definite, given as scalars, diagonals or matrices) and of the bounds.
    force_bound, moment_bound: a BoxBound, a NormBound or None (unbounded); NormBound(0) removes the
    control (attitude-only or translation-only maneuvers).
    bounds_margin: m in [0, 1): the bounds above are the ones the plan respects, a fraction 1 - m of the
    actuators' (:func:`actuator_bounds`), so that a tracker keeps authority (a maneuver file's
    ``control.bounds_margin`` shrinks its bounds so).
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
            if b is not None and not isinstance(b, (BoxBound, NormBound, ThrusterBound)):
                raise ProblemError(f"control.{name}", "expected a BoxBound, a NormBound, a ThrusterBound or None")
        if isinstance(self.moment_bound, ThrusterBound):
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
        return tuple(isinstance(b, NormBound) and b.b == 0 for b in (self.force_bound, self.moment_bound))


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
