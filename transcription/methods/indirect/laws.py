"""What each objective's necessary conditions are in the indirect method: the objective brings one of these
(``Objective.indirect``; None: the indirect method does not cover it), and the shooting asks it, never the
objective's name.

    EffortLaw   the saturated law of the costate (docs/mathematics.md §6, §10): Newton on lambda_0 at fixed h, from
                lambda_0 = 0 with bounds by the bound continuation, a free final time by the secant on h
    TimeLaw     min T + eps (effort) with the saturated law, Newton on (lambda_0, h), from a solution's switching
                structure (§18, :mod:`.objectives`)
    FuelLaw     the on/off switching law and its homotopy in eps, the structured conditions at eps = 0 (§19, :mod:`.fuel`)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...ocp import Problem, effort_cost, objective_value, quadrature_weights
from .fuel import fuel_not_covered, solve_fuel, warm_controls
from .objectives import solve_time


@dataclass(frozen=True)
class EffortLaw:
    """The effort objective's conditions (module docstring).  ``eps``: the fuel homotopy's parameter in the bound data
    (0: the saturation); ``replannable``: a re-plan's fixed-h Newton step (transcription.closedloop.mpc) covers it;
    ``from_structure``: the law starts from a solution's switching structure (a direct solution at IPOPT's default tol
    may not give it: transcription.solve.fuel_retighten).  The fields: its outer loops' (:mod:`.continuation`)."""

    eps: ClassVar[float] = 0.0
    replannable: ClassVar[bool] = True
    from_structure: ClassVar[bool] = False
    #: from lambda_0 = 0: the stages of the bounds' geometric path from the unbounded peak to the given bounds, tried
    #: when the step from the unbounded solution fails (:func:`~.continuation.bound_continuation`)
    continuation_stages: int = 4
    #: a free final time: outer iterations on the step size, and their relative step tolerance
    free_time_max_outer: int = 30
    free_time_rtol: float = 1e-11

    def not_covered(self, problem: Problem) -> list[str]:
        """What of ``problem``, under this objective, the indirect method does not cover (in words)."""
        return []

    def start_error(self, warm, source: str) -> str:
        """Why the solve cannot start from ``warm`` (a Start or None) and ``source`` ('' when it can)."""
        return ""

    def cost(self, problem: Problem, U: np.ndarray, h: float) -> float:
        """The cost the shooting reports of controls U at the (mean) step h (the effort of its law)."""
        return effort_cost(U, problem.control, quadrature_weights(problem.scheme, problem.N, problem.steps_of(h)))

    def prepare(self, shooting, warm) -> None:
        """What the shooting keeps of the warm start (nothing)."""

    def solve_at(self, shooting, lam, h: float, first: bool, phase: str):
        """The fixed-step problem at h from lam (the shooting's own Newton iteration)."""
        return shooting.fixed(lam, h, first, phase, shooting.bd)

    def run(self, shooting, lam, h: float):
        """The whole solve from lam at h: (NewtonResult, final h) (fixed or free final time)."""
        return shooting.default_run(lam, h)


@dataclass(frozen=True)
class TimeLaw(EffortLaw):
    """The time objective's conditions (module docstring); fields: its homotopy (:func:`.objectives.solve_time`)."""

    replannable: ClassVar[bool] = False
    #: without (or after a failed) structure start: the first eps, raised by start_raise up to start_tries times when
    #: that stage fails (too few nodes in the switching bands for a regular Jacobian: a coarse grid)
    eps_start: float = 1e-2
    start_raise: float = 4.0
    start_tries: int = 3
    #: eps per stage times eps_factor (its square root after a failed stage, up to eps_factor_max), Newton iterations
    #: per stage after the first, and the smallest eps
    eps_factor: float = 0.5
    eps_factor_max: float = 0.9
    stage_iterations: int = 20
    eps_end: float = 1e-8
    max_stages: int = 12        # the most stages of one solve (a bound on its time; the structure start settles in 2)
    #: two stages whose T agree to this (relative) end the homotopy: T is eps = 0's (docs/mathematics.md §18)
    t_rtol: float = 1e-12

    def not_covered(self, problem: Problem) -> list[str]:
        return ["the time objective with a body-fixed force"] if problem.disc.force_frame != "inertial" else []

    def start_error(self, warm, source: str) -> str:
        if warm is not None:
            return ""
        return (f"the time objective starts from a solution (initial_costate from_direct: the direct solution's "
                f"switching structure and T); a cold start from initial_costate {source} is not implemented")

    def run(self, shooting, lam, h: float):
        nr, h, shooting.stats["time_homotopy"], shooting.law = solve_time(shooting, lam, h, self, shooting.primal)
        return nr, h


@dataclass(frozen=True)
class FuelLaw(EffortLaw):
    """The fuel objective's conditions (module docstring); fields: its homotopy and structured finish (:mod:`.fuel`)."""

    eps: ClassVar[float] = 1.0
    replannable: ClassVar[bool] = False
    from_structure: ClassVar[bool] = True
    #: the homotopy: the first eps from lambda_0 = 0 (eps = 1: an effort-like cost) and from a solution's costates,
    #: the factor per stage (its square root after a failed stage, up to eps_factor_max), and the last eps (the
    #: eps-problem's optimum is within eps/2 relative of the fuel optimum, docs/mathematics.md §19)
    eps_cold: float = 1.0
    eps_warm: float = 1e-2
    eps_factor: float = 0.1
    eps_factor_max: float = 0.9
    eps_end: float = 1e-6
    #: the homotopy stops earlier, at eps <= eps_settle, once the fuel cost's estimated change to eps = 0
    #: (:func:`.fuel.remaining`) is at most cost_rtol relative
    eps_settle: float = 1e-2
    cost_rtol: float = 1e-9
    #: active-set repairs of an inconsistent switching structure (:meth:`.structured.StructuredShooting.repaired`)
    structure_repairs: int = 3
    #: a node is partial when its magnitude is further than this fraction of b from 0 and from b (loose: an
    #: interior-point solution sits inside its bounds)
    partial_rtol: float = 1e-3
    #: Newton iterations of the structured conditions (1-3 from a consistent structure; from a wrong one they wander)
    structured_max_iter: int = 8

    def not_covered(self, problem: Problem) -> list[str]:
        return fuel_not_covered(problem)

    def cost(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return objective_value(problem, U, h)

    def prepare(self, shooting, warm) -> None:
        shooting.warm_U = warm_controls(shooting.problem, warm)

    def solve_at(self, shooting, lam, h: float, first: bool, phase: str):
        return solve_fuel(shooting, lam, h, first, phase, self)


__all__ = ["EffortLaw", "FuelLaw", "TimeLaw"]
