"""Actuators: how a control part -- the force u_f or the moment u_m -- is produced and bounded (docs/mathematics.md
§10, §14, §21).

An actuator acts in its part's frame (the force: inertial, or the body's with ``force_frame: body``; the moment: the
body's) through three channels T = Q^T u (Q a rotation whose columns are the channels' directions) held in a box
lo <= T <= hi, and, gimballed, within a ball |u| <= radius:

    BoxBound(b)                 Q = I, -b <= T <= b             thrusters in opposed pairs, or wheels, on the axes
    NormBound(b)                |u| <= b                        a gimballed force, a torque of any direction
    NormBound(0)                u = 0                           the part removed
    ThrusterBound(a, max, min)  Q = [a, a_perp], min <= T_1 <= max, T_2 = T_3 = 0
                                                                one engine fixed in the body (force_frame body)

Whatever depends on the kind of actuator asks it, here and nowhere else (:meth:`Actuator.margin`,
:meth:`~Actuator.project`, :meth:`~Actuator.variable_box`, :attr:`~Actuator.channel_rows`, ...).  Fuel: counted
channel by channel, sum_i |T_i|, where every channel is bounded and there is no ball (a box, an engine: each thruster
pair, wheel or engine spends its own; :attr:`~Actuator.fuel_channels`) -- an engine's is its thrust T_1 = a^T u = |u|,
linear; otherwise the 2-norm |u|.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..geometry.so3 import rotation_with_first_column
from .errors import ProblemError

#: a control counts as "at its bound" within this fraction of the limit (an interior-point solution sits inside)
AT_BOUND_RTOL = 1e-3


class Actuator:
    """A control part's actuator (module docstring): :attr:`channels` (Q, lo, hi) and :attr:`radius`; the rest is
    derived from them, but for what a subclass says in words (:meth:`describe`), the scaling of its limits
    (:meth:`scaled`) and its switch times (:meth:`switches`).  Controls u are (n, 3) in the part's frame."""

    #: the key of the actuator in a maneuver file's ``control.bounds`` and in the figures of merit
    kind: ClassVar[str] = ""
    #: what the indirect method's words call it ('a box bound', 'an engine', ...)
    noun: ClassVar[str] = ""
    #: whether it exists only in the body frame (an engine fixed in the body: force_frame body)
    body_fixed: ClassVar[bool] = False
    #: the exhaust velocity c = Isp g0 of an engine, in the problem's velocity units (None: not given; the burns'
    #: propellant, transcription.results.burns, needs it); the dynamics keep the mass constant
    exhaust_velocity: float | None = None

    @property
    def channels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q (3x3 rotation), lo (3), hi (3)): T = Q^T u in [lo, hi] (+-inf where a channel is free)."""
        return np.eye(3), np.full(3, -np.inf), np.full(3, np.inf)

    @property
    def radius(self) -> float:
        """|u| <= radius (inf: no ball; 0: the part removed)."""
        return np.inf

    @property
    def removed(self) -> bool:
        """The part is absent (u = 0): a radius of 0."""
        return self.radius == 0.0

    @property
    def channel_rows(self) -> bool:
        """Whether the channels are stated as rows Q^T u in [lo, hi] (channels other than the part's axes, or some
        held fixed: an engine), not as bounds of the part's components (a box)."""
        Q, lo, hi = self.channels
        return not np.array_equal(Q, np.eye(3)) or bool(np.any(lo == hi))

    @property
    def engine_axis(self) -> np.ndarray | None:
        """a, where the actuator is an engine: one free channel, one-sided (lo >= 0), the others held at 0 -- then
        |u| = a^T u on every admissible u, linear (the fuel objective's magnitude); None otherwise."""
        Q, lo, hi = self.channels
        free = ~self.fixed
        if np.count_nonzero(free) != 1 or np.any(lo[~free] != 0.0):
            return None
        i = int(np.flatnonzero(free)[0])
        return Q[:, i] if lo[i] >= 0.0 else None

    @property
    def fuel_channels(self) -> np.ndarray | None:
        """Q, where the actuator's fuel is counted channel by channel, sum_i |T_i| (thrusters, wheels and an engine:
        every channel bounded, no ball -- a box, an engine, whose |u| = T_1; a removed part, whose channels are held
        at 0); None where it is the 2-norm |u| (a gimballed actuator)."""
        Q, lo, hi = self.channels
        bounded = not np.isfinite(self.radius) and np.all(np.isfinite(lo) & np.isfinite(hi))
        return Q if bounded or self.removed else None

    def fuel(self, u: np.ndarray) -> np.ndarray:
        """(n,) the fuel rate of controls u (n, 3): sum_i |T_i| over the channels (:attr:`fuel_channels`), else |u|."""
        u = np.asarray(u, float)
        return np.linalg.norm(u, axis=-1) if self.fuel_channels is None else np.abs(self.T(u)).sum(axis=-1)

    @property
    def engine_range(self) -> tuple[float, float] | None:
        """(min, max) of an engine's thrust (:attr:`engine_axis`); None otherwise."""
        if self.engine_axis is None:
            return None
        Q, lo, hi = self.channels
        i = int(np.flatnonzero(~self.fixed)[0])
        return float(lo[i]), float(hi[i])

    def variable_box(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lo, hi) (3 each) bounds of the part's own components (the channels are the axes, or the part is
        removed), or None where the actuator is stated by rows (:attr:`channel_rows`, a ball) or its channels are free."""
        if self.removed:
            return np.zeros(3), np.zeros(3)
        Q, lo, hi = self.channels
        if self.channel_rows or not (np.isfinite(lo).any() or np.isfinite(hi).any()):
            return None
        return lo, hi

    def T(self, u: np.ndarray) -> np.ndarray:
        """The channels T = Q^T u (n, 3) of controls u (n, 3)."""
        return np.asarray(u, float) @ self.channels[0]

    @property
    def fixed(self) -> np.ndarray:
        """(3,) bool: the channels held at one value (an engine's off-axis force, held at 0)."""
        Q, lo, hi = self.channels
        return lo == hi

    def unavailable(self, u: np.ndarray) -> np.ndarray:
        """(n,) the size of what the fixed channels cannot give of the controls u (n, 3) (an engine's off-axis
        force; 0 for an admissible control)."""
        Q, lo, hi = self.channels
        fixed = self.fixed
        return np.linalg.norm(self.T(u)[:, fixed] - lo[fixed], axis=1)

    def margin(self, u: np.ndarray) -> np.ndarray:
        """(n,) >= 0 where the controls u (n, 3) are admissible: the least distance of a free channel to its limits
        and of |u| to the radius, less the size of the fixed channels (the off-axis force of an engine)."""
        Q, lo, hi = self.channels
        T = self.T(u)
        out = np.full(len(T), np.inf)
        for i in np.flatnonzero(~self.fixed):
            out = np.minimum(out, np.minimum(hi[i] - T[:, i], T[:, i] - lo[i]))
        if np.isfinite(self.radius):
            out = np.minimum(out, self.radius - np.linalg.norm(T, axis=1))
        return out - self.unavailable(u)

    def project(self, u: np.ndarray) -> np.ndarray:
        """The admissible control nearest u (..., 3) channel by channel: each channel clipped into its box, then
        the part scaled into its ball (docs/mathematics.md §10 and §14: an engine's force onto its axis, the
        thrust into [min, max])."""
        Q, lo, hi = self.channels
        u = np.asarray(u, float)
        v = np.clip(u @ Q, lo, hi) @ Q.T
        if np.isfinite(self.radius):
            n = np.linalg.norm(v, axis=-1, keepdims=True)
            v = v * np.minimum(1.0, self.radius / np.maximum(n, 1e-300))
        return v

    def active(self, u: np.ndarray) -> np.ndarray:
        """(n,) bool: some free channel, or |u|, within AT_BOUND_RTOL of its limit (of the channel's largest limit
        for a one-sided channel's lower end; never for a removed part)."""
        Q, lo, hi = self.channels
        T = self.T(u)
        out = np.zeros(len(T), dtype=bool)
        for i in np.flatnonzero(lo < hi):
            tol = AT_BOUND_RTOL * np.max(np.abs([x for x in (lo[i], hi[i]) if np.isfinite(x)] or [0.0]))
            out |= (T[:, i] >= hi[i] - tol) | (T[:, i] <= lo[i] + tol)
        if np.isfinite(self.radius) and self.radius > 0:
            out |= np.linalg.norm(T, axis=1) >= self.radius * (1.0 - AT_BOUND_RTOL)
        return out

    def scale(self) -> float:
        """The actuator's size: its largest finite limit (0 for a removed part)."""
        Q, lo, hi = self.channels
        limits = np.r_[np.abs(lo), np.abs(hi), self.radius]
        limits = limits[np.isfinite(limits)]
        return float(limits.max()) if limits.size else np.inf

    def sizes(self) -> np.ndarray:
        """(3,) a size per component of the part (a box's limits; otherwise :meth:`scale` on each): the NLP's
        control scales and the tracker's characteristic controls."""
        return np.full(3, self.scale())

    def largest_norm(self) -> float:
        """The largest |u|_2 the actuator gives: its radius, or the norm of the channels' largest magnitudes (a
        box's corner, an engine's max)."""
        if np.isfinite(self.radius):
            return float(self.radius)
        Q, lo, hi = self.channels
        return float(np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi))))

    #: what :meth:`magnitude` is, for a figure's axis
    magnitude_label: ClassVar[str] = "|u|"

    def magnitude(self, u: np.ndarray) -> np.ndarray:
        """(n,) what a figure plots against :meth:`scale`: the largest component |u_i| of a box, else |u|."""
        return np.linalg.norm(np.asarray(u, float), axis=-1)

    @property
    def norm_limit(self) -> float | None:
        """The largest |u| as one number a plot of |u| can draw (the radius, an engine's max); None where it depends
        on the direction (a box) or there is none."""
        if np.isfinite(self.radius):
            return float(self.radius)
        return None if self.engine_axis is None else self.engine_range[1]

    def active_channels(self, u: np.ndarray) -> np.ndarray:
        """(n, 3) bool: each channel T_i of the controls u (n, 3) within AT_BOUND_RTOL of a finite limit."""
        Q, lo, hi = self.channels
        T = self.T(u)
        with np.errstate(invalid="ignore"):
            tol = AT_BOUND_RTOL * np.where(np.isfinite(hi), np.abs(hi), 0.0)
            return (lo < hi)[None, :] & ((T >= hi - tol) | (T <= lo + tol))

    def effort_rate(self, W: np.ndarray) -> float:
        """The largest u^T W u the actuator allows with channels W-orthogonal (the indirect method's weights):
        sum_i q_i^T W q_i max(|lo_i|, |hi_i|)^2 over the bounded channels, or W_11 radius^2."""
        if np.isfinite(self.radius):
            return float(W[0, 0] * self.radius**2)
        Q, lo, hi = self.channels
        m = np.maximum(np.abs(lo), np.abs(hi))
        ok = np.isfinite(m)
        return float(sum(Q[:, i] @ W @ Q[:, i] * m[i] ** 2 for i in np.flatnonzero(ok)))

    def switches(self, u: np.ndarray, t: np.ndarray) -> list:
        """The times the controls u (n, 3) at the node times t (n,) enter or leave the bound (midpoints)."""
        at = self.active(u)
        return [float(0.5 * (t[j] + t[j + 1])) for j in np.flatnonzero(at[:-1] != at[1:])]

    def describe(self, sym: str, factor: float = 1.0, unit: str = "") -> str:
        """The bound in words for the control ``sym`` ('u_f'), its numbers times ``factor`` in ``unit`` (' N')."""
        raise NotImplementedError

    def scaled(self, s: float) -> "Actuator":
        """The actuator with its limits times s > 0 (a bounds margin: s = 1 - m for the plan, 1 / (1 - m) back)."""
        raise NotImplementedError


@dataclass(frozen=True)
class BoxBound(Actuator):
    """|u_i| <= b_i for each component i (b_i > 0), in the part's frame: thrusters in opposed pairs (or three
    wheels) along its axes."""

    b: np.ndarray
    kind: ClassVar[str] = "box"
    noun: ClassVar[str] = "a box bound"

    def __post_init__(self):
        b = np.asarray(self.b, dtype=float).reshape(-1)
        if b.shape != (3,) or not np.all(np.isfinite(b)) or not np.all(b > 0):
            raise ProblemError("bounds.box", "expected 3 positive finite limits")
        object.__setattr__(self, "b", b)

    @property
    def channels(self):
        return np.eye(3), -self.b, self.b

    def scaled(self, s: float) -> "BoxBound":
        return BoxBound(self.b * s)

    def sizes(self) -> np.ndarray:
        return self.b.copy()

    magnitude_label: ClassVar[str] = "max_i |u_i|"

    def magnitude(self, u: np.ndarray) -> np.ndarray:
        return np.abs(np.asarray(u, float)).max(axis=-1)

    def switches(self, u: np.ndarray, t: np.ndarray) -> list[list[float]]:
        """Every sign change of each component (a bang-bang control's switches; linear interpolation in t)."""
        u, out = np.asarray(u, float), []
        for i in range(3):
            ui = u[:, i]
            k = np.flatnonzero(ui[:-1] * ui[1:] < 0)
            out.append([float(t[j] + (t[j + 1] - t[j]) * ui[j] / (ui[j] - ui[j + 1])) for j in k])
        return out

    def describe(self, sym: str, factor: float = 1.0, unit: str = "") -> str:
        sub = f"{sym},i" if "_" in sym else f"{sym}_i"
        return f"|{sub}| ≤ ({', '.join(f'{factor * b:g}' for b in self.b)}){unit}"


@dataclass(frozen=True)
class NormBound(Actuator):
    """|u|_2 <= b (b >= 0; b = 0 removes the part): a gimballed actuator."""

    b: float
    kind: ClassVar[str] = "norm"
    noun: ClassVar[str] = "a norm bound"

    def __post_init__(self):
        if not (np.isfinite(self.b) and self.b >= 0):
            raise ProblemError("bounds.norm", "expected a non-negative finite limit")
        object.__setattr__(self, "b", float(self.b))

    @property
    def radius(self) -> float:
        return self.b

    def scaled(self, s: float) -> "NormBound":
        """The norm bound times s > 0 (a removed control, b = 0, stays removed)."""
        return NormBound(self.b * s)

    def describe(self, sym: str, factor: float = 1.0, unit: str = "") -> str:
        return "removed (a norm bound of 0)" if self.removed else f"|{sym}| ≤ {factor * self.b:g}{unit}"


@dataclass(frozen=True)
class ThrusterBound(Actuator):
    """One engine fixed in the body (force_frame 'body' only): u_f = T a, a the unit engine axis (body frame,
    normalized here) and min <= T <= max (0 <= min < max, finite).  Off-axis force is not available.
    exhaust_velocity: c = Isp g0 > 0 in the problem's velocity units, or None (:attr:`Actuator.exhaust_velocity`)."""

    axis: np.ndarray
    max: float
    min: float = 0.0
    exhaust_velocity: float | None = None
    kind: ClassVar[str] = "thruster"
    noun: ClassVar[str] = "an engine"
    body_fixed: ClassVar[bool] = True

    def __post_init__(self):
        a = np.asarray(self.axis, dtype=float).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise ProblemError("bounds.thruster.axis", "expected a non-zero 3-vector (the engine axis in the body frame)")
        lo, hi = float(self.min), float(self.max)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 <= lo < hi):
            raise ProblemError("bounds.thruster", f"expected 0 <= min < max, finite, got min {lo!r}, max {hi!r}")
        c = self.exhaust_velocity
        if c is not None and not (np.isfinite(c) and c > 0):
            raise ProblemError("bounds.thruster.exhaust_velocity", f"expected a positive finite number, got {c!r}")
        object.__setattr__(self, "axis", a / np.linalg.norm(a))
        object.__setattr__(self, "max", hi)
        object.__setattr__(self, "min", lo)

    @property
    def channels(self):
        """Q = [a, b, c] (:func:`~transcription.geometry.so3.rotation_with_first_column`): the thrust T_1 in
        [min, max], the off-axis force T_2 = T_3 = 0."""
        return rotation_with_first_column(self.axis), np.array([self.min, 0.0, 0.0]), np.array([self.max, 0.0, 0.0])

    def thrust(self, u: np.ndarray) -> np.ndarray:
        """T = a^T u_f for force controls u (n, 3) in the body frame."""
        return np.asarray(u, float) @ self.axis

    def off_axis(self, u: np.ndarray) -> np.ndarray:
        """|u_f - T a| (n,): the force the engine cannot give (0 for a feasible control)."""
        return self.unavailable(u)

    def scaled(self, s: float) -> "ThrusterBound":
        """The engine with its largest thrust times s > 0 (the least thrust, an engine's minimum, and its exhaust
        velocity kept)."""
        return ThrusterBound(self.axis, self.max * s, self.min, self.exhaust_velocity)

    def switches(self, u: np.ndarray, t: np.ndarray) -> list[float]:
        """The times the thrust reaches or leaves max or min (midpoints)."""
        T, tol = self.thrust(u), AT_BOUND_RTOL * self.max
        level = np.where(T >= self.max - tol, 1, np.where(T <= self.min + tol, -1, 0))
        return [float(0.5 * (t[j] + t[j + 1])) for j in np.flatnonzero(level[:-1] != level[1:])]

    def describe(self, sym: str, factor: float = 1.0, unit: str = "") -> str:
        return (f"one engine along body ({', '.join(f'{x:.4g}' for x in self.axis)}), "
                f"{factor * self.min:g} ≤ T ≤ {factor * self.max:g}{unit}")


__all__ = ["AT_BOUND_RTOL", "Actuator", "BoxBound", "NormBound", "ThrusterBound"]
