"""The fuel objective (docs/mathematics.md §10, §19-§25): min sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|), the weights
scalars -- its cost block of the direct method's NLP (:mod:`.nlp`: the magnitude-direction epigraph, smoothed along
the homotopy or on a fixed switching structure), its scales, its conditions in the indirect method (the switching
law, :mod:`transcription.methods.indirect.fuel`) and its default strategy (:mod:`.plan`).

The parameters of the NLP's form are the objective's fields, so that every step of a strategy -- a homotopy level, a
structured finish -- is the solve of a Problem by the direct method: ``smoothing`` eps in [0, 1] and ``reference``
(r_f, r_m) of the smoothed magnitude phi_eps(s) = (1 - eps) s + eps s^2 / (2 r) (eps = 0: the fuel objective);
``burn`` (2, n_controls) bool, a fixed switching structure (None: the epigraph u = s d on every node) with the
magnitudes' ``rounding`` (2,) (a fraction of each part's magnitude scale).

Where every part's actuator counts its fuel channel by channel (:meth:`Fuel.on_channels`: an engine, thrusters,
wheels -- :attr:`~transcription.ocp.actuators.Actuator.fuel_channels`), the cost is linear in the channels' magnitudes
and the NLP a linear program's epigraph of them (:func:`.nlp.channel_node`): it is solved as it stands, from the
effort optimum (:class:`~transcription.objectives.propellant.FromEffort`), with none of the epigraph's homotopy, guard
or structured finish (docs/mathematics.md §27)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from ...geometry.state import U_FORCE, U_MOMENT
from ...methods.indirect.laws import FuelLaw
from ...ocp import Objective, Problem, ProblemError, fuel_cost, quadrature_weights
from ...strategy.core import Warm
from ..propellant import FromEffort
from .homotopy import Homotopy
from .nlp import channel_blocks, fuel_blocks, fuel_slacks, on_channels
from .continuation import through_channels
from .plan import FuelStrategy


@dataclass(frozen=True, eq=False)
class Fuel(Objective):
    """min sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|), w_f = W_f[0, 0], w_m = W_m[0, 0] (module docstring)."""

    smoothing: float = 0.0
    reference: tuple[float, float] | None = None
    burn: np.ndarray | None = field(default=None, repr=False)
    rounding: tuple[float, float] = (0.0, 0.0)
    indirect: ClassVar = FuelLaw()
    fatrop: ClassVar[str] = ("fatrop does not converge on the fuel NLP (the magnitude-direction epigraph's indefinite "
                             "coast nodes): from IPOPT's own optimum of the fuel raise on 25 steps it stops after "
                             "129-3001 iterations 1e-7 to 1e-3 above it")
    name: ClassVar[str] = "fuel"

    def check(self, control) -> None:
        for name in ("W_f", "W_m"):
            W = getattr(control, name)
            if not np.allclose(W, W[0, 0] * np.eye(3), rtol=1e-12, atol=0.0):
                raise ProblemError(f"control.{name}", "for the fuel objective a weight is one number (the weight of the norm)")
        if self.burn is not None and not np.all(np.asarray(self.rounding, float) > 0):
            raise ProblemError("control.objective", "a switching structure (burn) needs its magnitudes' rounding > 0")

    def unit_weights(self, force: float, moment: float) -> tuple[np.ndarray, np.ndarray] | None:
        """I / force, I / moment: the impulses in units of the controls' sizes (the engine's burn time at full
        thrust, the wheels' at full torque)."""
        return np.eye(3) / force, np.eye(3) / moment

    def __eq__(self, other) -> bool:
        same = lambda a, b: a is b or (a is not None and b is not None and np.array_equal(a, b))
        return (type(other) is type(self) and (self.smoothing, self.reference, self.rounding)
                == (other.smoothing, other.reference, other.rounding) and same(self.burn, other.burn))

    def __hash__(self) -> int:
        return hash((self.smoothing, self.reference, self.rounding, None if self.burn is None else self.burn.tobytes()))

    on_channels = staticmethod(on_channels)

    @property
    def epigraph(self) -> bool:
        """The magnitude-direction epigraph on every node (no fixed switching structure)."""
        return self.burn is None

    def smoothed(self, eps: float, reference) -> "Fuel":
        """This objective smoothed by eps with the references (r_f, r_m) (a homotopy level)."""
        return replace(self, smoothing=float(eps), reference=tuple(float(r) for r in reference))

    def structured(self, burn: np.ndarray, rounding) -> "Fuel":
        """This objective on the switching structure ``burn`` with the magnitudes' ``rounding`` (a structured finish)."""
        return replace(self, burn=np.asarray(burn, dtype=bool), rounding=tuple(float(r) for r in rounding))

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return fuel_cost(U, problem.control, quadrature_weights(problem.scheme, problem.N, problem.steps_of(h)))

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        c = problem.control
        rf, rm = c.removed
        return sU, problem.T * ((0.0 if rf else c.W_f[0, 0] * sU[U_FORCE].max())
                                + (0.0 if rm else c.W_m[0, 0] * sU[U_MOMENT].max()))

    def slacks(self, tr) -> int:
        return 6 if self.on_channels(tr.problem) is not None else 8 if self.epigraph else 2

    def slack_scales(self, tr) -> np.ndarray:
        if self.on_channels(tr.problem) is not None:
            return np.repeat(tr.magnitudes, 3)
        return np.r_[tr.magnitudes, np.ones(6)] if self.epigraph else tr.magnitudes

    def slack_values(self, tr, U: np.ndarray) -> np.ndarray:
        channels = self.on_channels(tr.problem)
        if channels is not None:     # |T_i| = |Q^T u|, the force's channels then the moment's
            return np.abs(np.vstack([channels[0].T @ U[U_FORCE], channels[1].T @ U[U_MOMENT]]))
        return fuel_slacks(U)[:self.slacks(tr)]

    def slack_bounds(self, tr, lbx: np.ndarray, ubx: np.ndarray) -> None:
        lay, c = tr.layout, tr.problem.control
        if self.on_channels(tr.problem) is not None:
            # s_i >= 0, free above even where T_i is held (an engine's off-axis channels, a removed part): fixed there,
            # its rows would repeat T_i = 0's and IPOPT meet dependent active rows (3000 iterations on
            # leo_engine_fuel with three wheels, 52 without)
            lbx[lay.iS] = np.maximum(lbx[lay.iS], 0.0)
            return
        lbx[lay.iS[:2]] = np.maximum(lbx[lay.iS[:2]], 0.0)      # the magnitudes s >= 0
        for k, (sl, bound) in enumerate(((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound))):
            if bound is not None and bound.removed:              # a removed part: no magnitude
                lbx[lay.iS[k]] = ubx[lay.iS[k]] = 0.0
            if self.epigraph and bound is not None and bound.engine_axis is not None:   # an engine: no direction
                lbx[lay.iS[2 + 3 * k:5 + 3 * k]] = ubx[lay.iS[2 + 3 * k:5 + 3 * k]] = np.array([[1.0], [0.0], [0.0]])
            if not self.epigraph:                                # a coast node's part: u = 0, s = 0
                coast = np.r_[lay.iU[sl][:, ~self.burn[k]].ravel(), lay.iS[k, ~self.burn[k]]]
                lbx[coast] = ubx[coast] = 0.0

    def blocks(self, tr) -> list:
        channels = self.on_channels(tr.problem)
        return fuel_blocks(self, tr) if channels is None else channel_blocks(tr, channels)

    def failure_tip(self, problem: Problem) -> str:
        """With an engine and a moment of any direction (gimballed or unbounded): three wheels on the body axes, whose
        fuel counts on channels (docs §27: it converges in seconds where the 2-norm of the torque does not, §25), or
        the propellant objective (§26)."""
        c = problem.control
        bound = c.force_bound
        if bound is None or bound.engine_axis is None or c.removed[1] or self.on_channels(problem) is not None:
            return ""
        b = f"{c.moment_bound.radius:g}" if c.moment_bound is not None else "b"
        return (f"control.bounds.moment={{box: [{b}, {b}, {b}]}} (three wheels on the body axes"
                + ("" if c.moment_bound is not None else ", b each one's torque limit")
                + ", each one's torque impulse counted: docs/mathematics.md §27, it converges in seconds where the "
                "2-norm of the torque does not), or control.objective=propellant (the wheels' torque priced by its "
                "effort, §26)")

    def caution(self, problem: Problem) -> str:
        """With an engine and a gimballed moment (a norm bound): the L1 of its 2-norm converges slowly if at all
        (docs §25), and the cure.  An unbounded moment is reached through channels (:mod:`.continuation`)."""
        tip = "" if through_channels(problem) else self.failure_tip(problem)
        return (f"the fuel of an engine with a torque of any direction (its 2-norm) converges slowly if at all "
                f"(docs/mathematics.md §25); consider {tip}") if tip else ""

    def via_lgvi(self, problem: Problem) -> bool:
        """Counted on channels its strategy reaches lgvi_kepler through its effort problem (:class:`FromEffort`), and
        through problems counted on channels (:func:`.continuation.through_channels`) on that scheme itself."""
        return self.on_channels(problem) is None and not through_channels(problem)

    def strategy(self, problem: Problem, options) -> FuelStrategy | FromEffort:
        if self.on_channels(problem) is not None:
            return FromEffort(Homotopy(None).effort_problem, mu_init=Warm.mu_init)
        return FuelStrategy()


__all__ = ["Fuel"]
