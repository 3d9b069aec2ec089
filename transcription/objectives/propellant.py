"""The propellant objective: an engine's impulse, the wheels' torques priced by their effort (docs/mathematics.md §26),

    min sum_j omega_j (w_f T_j + (1/2) u_m,j^T W_m u_m,j),    T_j = a^T u_f,j in [T_min, T_max],

for a spacecraft whose force is one engine (:attr:`~transcription.ocp.actuators.Actuator.engine_axis` a: one
one-sided channel, the others held at 0) and whose moment comes from reaction wheels, which burn no propellant: the
engine's impulse sum omega_j T_j is the propellant (Delta-v = impulse / m, linear in the control), the wheels'
squared torque their electrical effort.  Both parts are smooth, so the NLP is the effort problem's with the force's
quadratic cost replaced by a linear one: no epigraph, no homotopy, no switching structure (the fuel objective's L1
moment, the wheels' torque impulse, is what needs them).  The thrust is bang-off-bang where the switching function
w_f + lambda^T (dstep/dT) leaves the bounds' interior (the nodes at 0 or T_max), as the fuel objective's.

Default strategy (:class:`FromEffort`): the effort problem with the force priced at the same margin at full
thrust -- (1/2) W_f' T^2 with W_f' = w_f / T_max, whose derivative at T_max is w_f -- solved by its own strategy
(the relaxed problem, the aimed start), then this problem from its optimum.  Weights in the actuators' terms
(:meth:`Propellant.unit_weights`): the impulse in seconds of full thrust, the wheels' effort in units of their size.
The indirect method does not cover it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, ClassVar

import casadi as ca
import numpy as np

from ..dynamics.lgvi import per_discretization
from ..geometry.state import NU, U_FORCE, U_MOMENT
from ..nlp.structured import Block, BlockFunction
from ..ocp import Objective, Problem, ProblemError, quadrature_weights
from ..results.start import Start
from ..strategy import starts
from ..strategy.core import Composed, FirstOf, FromRelated, Solve, Warm, chosen
from .effort import Effort


@per_discretization
def propellant_node(disc, free_h: bool) -> BlockFunction:
    """The propellant objective at one control node j: v = [u_j (6); h / h_scale (free_h)], p = [sU (6); omega_j / h;
    h (or h_scale); s_obj; a (3); w_f; vec W_m (9)]; cost omega_j (w_f a^T u_f + (1/2) u_m^T W_m u_m) / s_obj, no
    rows."""
    v = ca.SX.sym("v", NU + (1 if free_h else 0))
    p = ca.SX.sym("p", NU + 3 + 4 + 9)
    u = v[:NU] * p[:NU]
    h = p[NU + 1] * v[NU] if free_h else p[NU + 1]
    a, wf, Wm = p[NU + 3:NU + 6], p[NU + 6], ca.reshape(p[NU + 7:NU + 16], 3, 3)
    cost = p[NU] * h * (wf * ca.dot(a, u[U_FORCE]) + 0.5 * ca.bilin(Wm, u[U_MOMENT], u[U_MOMENT])) / p[NU + 2]
    return BlockFunction(ca.Function(f"propellant_node{'_freeh' if free_h else ''}", [v, p], [cost, ca.SX(0, 1)],
                                     ["v", "p"], ["cost", "rows"]))


@dataclass(frozen=True)
class Propellant(Objective):
    """min sum_j omega_j (w_f a^T u_f,j + (1/2) u_m,j^T W_m u_m,j), w_f = W_f[0, 0] (module docstring)."""

    indirect: ClassVar = None
    name: ClassVar[str] = "propellant"

    def via_lgvi(self, problem: Problem) -> bool:
        """False: its strategy reaches lgvi_kepler through its effort problem (:class:`FromEffort`); a bang-off-bang
        optimum of the LGVI's orbit was a poor start on the exact one (1342 more iterations, to a worse optimum: docs
        §26)."""
        return False

    def check(self, control) -> None:
        bound = control.force_bound
        if bound is None or bound.engine_axis is None:
            raise ProblemError("control.objective", "the propellant objective needs one engine as the force "
                               "(control.bounds.force.thruster with min >= 0); for other actuators use fuel")
        if not np.allclose(control.W_f, control.W_f[0, 0] * np.eye(3), rtol=1e-12, atol=0.0):
            raise ProblemError("control.W_f", "for the propellant objective the force's weight is one number (the "
                               "weight of the engine's impulse)")

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        c = problem.control
        omega = quadrature_weights(problem.scheme, problem.N, problem.steps_of(h))
        U = np.asarray(U, float)
        thrust = c.force_bound.engine_axis @ U[U_FORCE]
        wheels = np.einsum("ik,ij,jk->k", U[U_MOMENT], c.W_m, U[U_MOMENT])
        return float(np.sum(omega * (c.W_f[0, 0] * thrust + 0.5 * wheels)))

    def unit_weights(self, force: float, moment: float) -> tuple[np.ndarray, np.ndarray]:
        """I / force, I / moment^2: the impulse in seconds at full thrust, the wheels' effort in units of their size."""
        return np.eye(3) / force, np.eye(3) / moment**2

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        c = problem.control
        return sU, problem.T * (c.W_f[0, 0] * float(sU[U_FORCE].max())
                                + 0.5 * float(np.diag(c.W_m) @ sU[U_MOMENT] ** 2))

    def blocks(self, tr) -> list:
        problem, sc, c = tr.problem, tr.scales, tr.problem.control
        shared = np.r_[problem.h, sc.objective, c.force_bound.engine_axis, c.W_f[0, 0], c.W_m.ravel(order="F")]
        data = tr.node_parameters(sc.U, shared)
        fn = propellant_node(problem.disc, tr.free_h)
        return [(Block("propellant", fn, tr.node_variables(own=False), data), np.zeros(0))]

    def strategy(self, problem: Problem, options) -> "FromEffort":
        return FromEffort()


def effort_problem(problem: Problem) -> Problem:
    """``problem`` with the effort objective that prices the thrust at the same margin at full thrust:
    (1/2) W_f' |u_f|^2, W_f' = w_f / T_max (d/dT at T_max: w_f), the wheels' weights kept (module docstring)."""
    c = problem.control
    return problem.replace(control=replace(c, objective=Effort(), W_f=c.W_f / c.force_bound.largest_norm()))


@dataclass(frozen=True)
class FromEffort(Composed):
    """The default of the objectives linear in the thrust (the propellant's, module docstring; the fuel's counted on
    channels, :mod:`.fuel`): from the optimum of the effort problem ``related(problem)`` (here
    :func:`effort_problem`, by its default strategy: on lgvi_kepler through its LGVI optimum, then by its strategy on
    that scheme itself, :func:`~transcription.strategy.core.default_strategy`), then the free motion and the
    interpolation, the first that converges kept; a given start or a chosen ``initial_guess`` is solved from as it
    is.  Neither of the effort problem's routes serves every engine file: with the wheels' torque bounded
    (configs/leo_engine_fuel.yaml, 0.01 N m) the LGVI's optimum is no start on lgvi_kepler, where the own starts
    converge in 69 iterations; with the moment free (leo_body_engine, weights auto) those end at a higher effort
    optimum (1027.6 against 996.1) from which the propellant solve wandered (918 iterations at a residual of 0.03 in
    76 s), where the LGVI's route converges in 118."""

    related: Callable[[Problem], Problem] = effort_problem
    #: the finish from the effort optimum starts IPOPT's barrier here (None: at its own 0.1, :class:`Warm`'s note)
    mu_init: float | None = None

    def compose(self, problem: Problem, options, start: Start | None = None):
        if start is not None:
            return Warm()
        if (one := chosen(problem, options)) is not None:
            return one
        label = "from the effort optimum"
        effort = FromRelated(Solve(label=label) if self.mu_init is None else Warm(label, self.mu_init),
                             self.related, "effort", label, "the effort problem")
        return FirstOf((effort, Solve(starts.rollout, "rollout"), Solve(starts.interpolation, "interpolate")))


__all__ = ["FromEffort", "Propellant", "effort_problem", "propellant_node"]
