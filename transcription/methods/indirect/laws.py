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

import numpy as np

from ...ocp import Problem, effort_cost, objective_value, quadrature_weights
from .fuel import fuel_not_covered, solve_fuel, warm_controls
from .objectives import solve_time


class EffortLaw:
    """The effort objective's conditions (module docstring).  ``eps``: the fuel homotopy's parameter in the bound data
    (0: the saturation); ``replannable``: a re-plan's fixed-h Newton step (transcription.closedloop.mpc) covers it;
    ``from_structure``: the law starts from a solution's switching structure (a direct solution at IPOPT's default tol
    may not give it: transcription.solve.fuel_retighten)."""

    eps = 0.0
    replannable = True
    from_structure = False

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


class TimeLaw(EffortLaw):
    """The time objective's conditions (module docstring)."""

    replannable = False

    def not_covered(self, problem: Problem) -> list[str]:
        return ["the time objective with a body-fixed force"] if problem.disc.force_frame != "inertial" else []

    def start_error(self, warm, source: str) -> str:
        if warm is not None:
            return ""
        return (f"the time objective starts from a solution (initial_costate from_direct: the direct solution's "
                f"switching structure and T); a cold start from initial_costate {source} is not implemented")

    def run(self, shooting, lam, h: float):
        nr, h, shooting.stats["time_homotopy"], shooting.law = solve_time(shooting, lam, h, shooting.primal)
        return nr, h


class FuelLaw(EffortLaw):
    """The fuel objective's conditions (module docstring)."""

    eps = 1.0
    replannable = False
    from_structure = True

    def not_covered(self, problem: Problem) -> list[str]:
        return fuel_not_covered(problem)

    def cost(self, problem: Problem, U: np.ndarray, h: float) -> float:
        return objective_value(problem, U, h)

    def prepare(self, shooting, warm) -> None:
        shooting.warm_U = warm_controls(shooting.problem, warm)

    def solve_at(self, shooting, lam, h: float, first: bool, phase: str):
        return solve_fuel(shooting, lam, h, first, phase)


__all__ = ["EffortLaw", "FuelLaw", "TimeLaw"]
