"""The outcome of a solve and its progress records, shared by every solver of the project: one result code
(:class:`Result`, whose values are readable messages) and one progress record (:class:`Iterate`).  The bottom of the
method layer: it imports nothing of the project, so that every layer may report in its terms."""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, fields
from typing import Any


class Code(str, enum.Enum):
    """An enumeration whose members are their own codes: ``str(member)`` is its value (a file's, a message's word)."""

    def __str__(self) -> str:
        return self.value


class Result(Code):
    """The outcome of a solve, shared by every method.  ``str(Result.x)`` is the code,
    ``Result.x.message`` a sentence, ``Result.x.successful`` whether the solution can be used."""

    converged = "converged"
    round_off_floor = "round_off_floor"
    max_iterations = "max_iterations"
    time_limit = "time_limit"
    acceptable = "acceptable"
    infeasible = "infeasible"
    terminal_error = "terminal_error"
    cayley_failed = "cayley_failed"
    line_search_failed = "line_search_failed"
    singular_jacobian = "singular_jacobian"
    stagnated = "stagnated"
    floor_too_high = "floor_too_high"
    non_finite = "non_finite"
    kink = "kink"
    solver_failed = "solver_failed"
    invalid_option = "invalid_option"
    not_applicable = "not_applicable"
    interrupted = "interrupted"
    inside_central_body = "inside_central_body"

    @property
    def successful(self) -> bool:
        return self in (Result.converged, Result.round_off_floor)

    @property
    def message(self) -> str:
        return _MESSAGES[self]


_MESSAGES = {
    Result.converged: "converged to the requested tolerance",
    Result.round_off_floor: "converged to the measured round-off floor of the residual",
    Result.max_iterations: "stopped at the iteration limit without converging",
    Result.time_limit: "stopped at the time limit without converging",
    Result.acceptable: "stopped at the solver's 'acceptable' level, short of the requested tolerance",
    Result.infeasible: "the solver found the problem (locally) infeasible",
    Result.terminal_error: "the solver converged, but the re-simulated trajectory misses the terminal conditions",
    Result.cayley_failed: "the implicit Cayley equation of a step was not solved: the rotation per step is too large",
    Result.line_search_failed: "the line search found no decrease",
    Result.singular_jacobian: "the Newton matrix is singular or ill-conditioned",
    Result.stagnated: "the iteration stagnated",
    Result.floor_too_high: "stopped at a round-off floor above the accepted level",
    Result.non_finite: "a residual, a derivative or a state became non-finite",
    Result.kink: "the optimum lies at a kink of a non-smooth cost, where the smooth formulation does not apply",
    Result.solver_failed: "the solver failed",
    Result.invalid_option: "an option or an initial guess is not usable",
    Result.not_applicable: "the method does not cover this problem",
    Result.interrupted: "interrupted by the user",
    Result.inside_central_body: "the re-simulated path enters the central body: the maneuver is impossible as solved",
}

#: IPOPT's (and fatrop's) return statuses as results
_SOLVER_STATUS = {
    "Solve_Succeeded": Result.converged,
    "Solved_To_Acceptable_Level": Result.acceptable,
    "Maximum_Iterations_Exceeded": Result.max_iterations,
    "Maximum_CpuTime_Exceeded": Result.time_limit,
    "Maximum_WallTime_Exceeded": Result.time_limit,
    "Infeasible_Problem_Detected": Result.infeasible,
    "Restoration_Failed": Result.solver_failed,
    "Error_In_Step_Computation": Result.solver_failed,
    "Search_Direction_Becomes_Too_Small": Result.stagnated,
    "Diverging_Iterates": Result.non_finite,
    "Invalid_Number_Detected": Result.non_finite,
    "User_Requested_Stop": Result.interrupted,
}


def result_of_solver_status(status: str) -> Result:
    """The :class:`Result` of an NLP solver's return status (unknown statuses: solver_failed)."""
    return _SOLVER_STATUS.get(status, Result.solver_failed)


@dataclass(frozen=True)
class Iterate:
    """One progress record, the same for every method (history entries and progress callbacks).

    iteration: outer iteration (NLP iteration, Newton step); trial: 0 for the iterate, 1, 2, ... for a Newton
    step's line-search trials; residual: the shooting residual's 2-norm (Newton) or the primal infeasibility (NLP);
    residual_inf: its max-norm where known; cost: the objective (NLP); dual: the dual infeasibility (NLP); step: the
    line-search step (Newton c; IPOPT alpha_pr); regularization: the multiple of the identity IPOPT added to the
    Lagrangian's Hessian for the step's KKT matrix to have the inertia of a minimum (0: none; > 0 at a converged
    point: the Hessian on the active constraints' tangent space is not positive definite there, a saddle or a
    degenerate minimum of the NLP -- :mod:`transcription.nlp.curvature`); accepted: the trial became the next iterate; aux: the largest
    relative Cayley residual of the trial's rollout (Newton); phase: which solve of a multi-phase solve, nested
    ('coarse N=25 / effort / rollout'); elapsed_s: seconds since the top-level ``solve``; budget: the most
    iterations this phase may take (0: not known; IPOPT's restoration may call back a few times more); method: set
    by ``solve`` on the records it passes to ``progress`` ('' in a history).  Absent values are nan.
    """

    iteration: int
    residual: float = math.nan
    residual_inf: float = math.nan
    cost: float = math.nan
    dual: float = math.nan
    step: float = math.nan
    regularization: float = math.nan
    trial: int = 0
    accepted: bool = True
    aux: float = math.nan
    phase: str = ""
    elapsed_s: float = math.nan
    budget: int = 0
    method: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def line(self) -> str:
        """One readable line with the fields that are known (progress output)."""
        parts = [f"iter {self.iteration:4d}"]
        if math.isfinite(self.cost):
            parts.append(f"cost {self.cost:.10g}")
        if not math.isnan(self.residual):
            parts.append(f"residual {self.residual:.3e}")
        if math.isfinite(self.dual):
            parts.append(f"dual {self.dual:.2e}")
        if math.isfinite(self.step):
            parts.append(f"step {self.step:.3g}")
        within = [self.phase] if self.phase else []
        if self.budget > 0:
            within.append(f"<= {self.budget} it")
        if within:
            parts.append(f"({'; '.join(within)})")
        return "  ".join(parts)

    def progress_line(self) -> str:
        """:meth:`line` after the method and the seconds since the solve started, where known:
        '[direct 123 s] iter   45  cost ...  (eps 1e-01; <= 500 it)'."""
        head = " ".join(p for p in (self.method, f"{self.elapsed_s:.0f} s" if math.isfinite(self.elapsed_s) else "")
                        if p)
        return f"[{head}] {self.line()}" if head else self.line()
