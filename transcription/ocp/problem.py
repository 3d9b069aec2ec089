"""The Problem: discretization, horizon, initial state, target, control, constraints."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..geometry.state import NU, NX, pack_state
from ..dynamics.lgvi import Discretization
from .constraints import PATH_CONSTRAINTS
from .controls import Control, ImpulsiveControl, SmoothControl
from .errors import ProblemError
from .targets import Target, TargetOrbit, TargetRendezvous, TargetState


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
    """An optimal control problem on the discretization ``disc`` (body model and scheme).

    N steps of size h = T/N from the initial state X0 (18) to ``terminal`` under ``control``.
    ``terminal`` and ``control`` may both be None: a motion to simulate only.
    time_bounds: (min, max) makes the final time free in [min, max] (T is then the guess).
    constraints: path constraints enforced at every node (MinRadius, KeepOut, KeepIn, MaxAngularRate).
    mesh: None (uniform steps h = T/N) or the relative step sizes r (N,), r_k > 0, stored normalized to mean 1:
        step k has size h_k = h r_k (:attr:`steps`), so sum_k h_k = T, and a free final time scales every step
        together.  Node times are :attr:`times`.
    """

    disc: Discretization
    N: int
    T: float
    X0: np.ndarray
    terminal: Target | None = None
    control: Control | None = None
    name: str = ""
    time_bounds: tuple[float, float] | None = None
    constraints: tuple = ()
    mesh: np.ndarray | None = None
    #: caps (6,) on the characteristic control magnitudes where this problem has no bound to give them: the sizes
    #: of the bounds of the problem it relaxes (objectives.effort.relaxation); None: from this problem's boundary
    #: data and bounds alone (nlp.scaling.control_magnitudes)
    control_scales: tuple | None = None
    #: what the problem's numbers are in: a label its author attaches (problems.units: the maneuver file's
    #: UnitSystem), kept by :meth:`replace`, never read by the numerical core; None: unnamed
    units: object = None
    #: what methods build from this (immutable) Problem and keep with it (its NLP, by the options it depends on):
    #: :meth:`memo`
    _memo: dict = dataclasses.field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        if isinstance(self.N, bool) or not isinstance(self.N, (int, np.integer)) or self.N < 1:
            raise ProblemError("N", f"expected a positive integer, got {self.N!r}")
        object.__setattr__(self, "N", int(self.N))
        if not (np.isfinite(self.T) and self.T > 0):
            raise ProblemError("T", f"expected a positive number, got {self.T!r}")
        X0 = np.asarray(self.X0, dtype=float).reshape(-1)
        if X0.shape != (NX,) or not np.all(np.isfinite(X0)):
            raise ProblemError("X0", f"expected a finite state of {NX} numbers")
        object.__setattr__(self, "X0", X0)
        if (self.terminal is None) != (self.control is None):
            raise ProblemError("terminal" if self.terminal is None else "control",
                               "a terminal target and a control go together (both, or neither for a simulation)")
        if isinstance(self.terminal, (TargetOrbit, TargetRendezvous)) and self.disc.model.mu is None:
            raise ProblemError("terminal", "an orbit or rendezvous target needs a model with a central body (mu)")
        if isinstance(self.terminal, TargetRendezvous) and not isinstance(self.control, SmoothControl):
            raise ProblemError("terminal", "a rendezvous target needs smooth control")
        if isinstance(self.control, ImpulsiveControl) and isinstance(self.terminal, TargetState) and self.terminal.free:
            raise ProblemError("terminal.free", "an impulsive state target must give every component")
        if self.time_bounds is not None:
            lo, hi = (float(v) for v in self.time_bounds)
            if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= self.T <= hi):
                raise ProblemError("time_bounds", f"expected 0 < min <= T (the guess) <= max, got {self.time_bounds} and "
                                                  f"T = {self.T}")
            if self.kind != "smooth":
                raise ProblemError("time_bounds", "a free final time needs smooth control")
            object.__setattr__(self, "time_bounds", (lo, hi))
        elif isinstance(self.control, SmoothControl) and self.control.objective.free_time:
            raise ProblemError("time_bounds", f"the {self.control.objective} objective needs a free final time "
                                              "(time_bounds)")
        if isinstance(self.control, SmoothControl) and getattr(self.control.force_bound, "body_fixed", False) \
                and self.disc.force_frame != "body":
            raise ProblemError("control.force_bound", "a thruster is fixed in the body: it needs the force in the body "
                                                      f"frame (disc.force_frame 'body', got {self.disc.force_frame!r})")
        if self.mesh is not None:
            r = np.asarray(self.mesh, dtype=float).reshape(-1)
            if r.shape != (self.N,) or not np.all(np.isfinite(r)) or not np.all(r > 0):
                raise ProblemError("mesh", f"expected {self.N} positive finite relative step sizes (one per step)")
            uniform = bool(np.all(r == r[0]))      # all equal: uniform, whatever the round-off of their mean
            r = r / r.mean()
            object.__setattr__(self, "mesh", None if uniform or np.all(r == 1.0) else r)
        if self.control_scales is not None:
            cs = np.asarray(self.control_scales, dtype=float).reshape(-1)
            if cs.shape != (NU,) or not np.all(np.isfinite(cs) & (cs > 0)):
                raise ProblemError("control_scales", f"expected {NU} positive finite control magnitudes")
            object.__setattr__(self, "control_scales", tuple(float(v) for v in cs))
        object.__setattr__(self, "constraints", tuple(self.constraints))
        for c in self.constraints:
            if not isinstance(c, PATH_CONSTRAINTS):
                raise ProblemError("constraints", f"expected path constraints, got {type(c).__name__}")
        if self.constraints and self.kind == "impulsive":
            raise ProblemError("constraints", "path constraints need smooth control")

    @property
    def h(self) -> float:
        """T / N (with a free final time: of the guess T)."""
        return self.T / self.N

    @property
    def uniform(self) -> bool:
        """True when every step has the size h = T/N (no ``mesh``)."""
        return self.mesh is None

    @property
    def steps(self) -> np.ndarray:
        """The step sizes h_k (N,), k = 0..N-1: h r_k (h for a uniform mesh); they sum to T."""
        return np.full(self.N, self.h) if self.mesh is None else self.h * self.mesh

    @property
    def times(self) -> np.ndarray:
        """The node times t_k (N+1,): t_0 = 0, t_{k+1} = t_k + h_k."""
        return np.concatenate([[0.0], np.cumsum(self.steps)])

    @property
    def fractions(self) -> np.ndarray | None:
        """The normalized node times t_k / T (N+1,) of a non-uniform mesh (what a warm start is resampled
        onto, transcription.results.start); None on a uniform mesh."""
        return None if self.mesh is None else self.times / self.times[-1]

    def steps_of(self, h: float) -> float | np.ndarray:
        """The step sizes for the mean step h (a free final time's solution): h itself on a uniform mesh (one
        number, so that uniform solves stay bit-identical), else h r_k (N,)."""
        return float(h) if self.mesh is None else float(h) * self.mesh

    def times_of(self, h: float) -> np.ndarray:
        """The node times (N+1,) for the mean step h: k h on a uniform mesh, else the cumulative sums of h r_k."""
        if self.mesh is None:
            return float(h) * np.arange(self.N + 1)
        return np.concatenate([[0.0], np.cumsum(float(h) * self.mesh)])

    @property
    def free_time(self) -> bool:
        return self.time_bounds is not None

    @property
    def kind(self) -> str | None:
        """'smooth', 'impulsive' or None (simulation only)."""
        if isinstance(self.control, SmoothControl):
            return "smooth"
        if isinstance(self.control, ImpulsiveControl):
            return "impulsive"
        return None

    @property
    def model(self):
        return self.disc.model

    @property
    def scheme(self) -> str:
        return self.disc.scheme

    @property
    def Xd(self) -> np.ndarray | None:
        """The target state (18) of a state target, else None."""
        return self.terminal.X if isinstance(self.terminal, TargetState) else None

    def __getstate__(self) -> dict:
        """Pickled without its :meth:`memo` (what methods built from it is rebuilt on first use; an NLP holds
        objects that do not pickle), so a solved Problem can go to another process."""
        return {**self.__dict__, "_memo": {}}

    def memo(self, key, build):
        """``build()`` once per ``key`` for this Problem, kept with it (a method's NLP of it: the Problem is
        immutable, so what is built from it stays valid; :meth:`replace` starts a new memo)."""
        if key not in self._memo:
            self._memo[key] = build()
        return self._memo[key]

    def replace(self, **changes) -> "Problem":
        """A copy with some fields changed (e.g. ``N``)."""
        return dataclasses.replace(self, **changes)


def state_from_velocities(model, position, velocity, R, omega) -> np.ndarray:
    """The 18-vector of a state given by position, inertial velocity, attitude (body -> inertial)
    and body angular velocity: gamma = m v, Pi = J Omega."""
    return pack_state(np.asarray(position, float), model.mass * np.asarray(velocity, float), np.asarray(R, float),
                      model.inertia @ np.asarray(omega, float))
