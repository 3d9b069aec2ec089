"""The trace of a solve: one typed record per method solve a strategy made (:class:`Attempt`), from which the
Solution's iterations, times and message are derived -- never parsed back."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..outcome import Result


@dataclass(frozen=True)
class Attempt:
    """One solve of a strategy, or one start it could not make.

    ``label``: what was tried ('rollout', 'the best start on 25 steps, resampled', 'eps 1e-01'); ``result``: how its
    solve ended (None: it was not run, ``note`` says why); ``iterations``, ``build_s``, ``solve_s``: its own solve's;
    ``cost`` (nan unless converged); ``parts``: the attempts that made its start (a coarser grid's solves, the
    relaxed problem's, a homotopy's levels), described together as ``prepared_on`` ('the relaxed problem');
    ``note``: a sentence on it.  The totals (its own and its parts') are what it cost."""

    label: str
    result: Result | None
    iterations: int = 0
    cost: float = math.nan
    build_s: float = 0.0
    solve_s: float = 0.0
    parts: tuple["Attempt", ...] = ()
    prepared_on: str = ""
    note: str = ""

    @property
    def total_iterations(self) -> int:
        return self.iterations + sum(p.total_iterations for p in self.parts)

    @property
    def total_build_s(self) -> float:
        return self.build_s + sum(p.total_build_s for p in self.parts)

    @property
    def total_solve_s(self) -> float:
        return self.solve_s + sum(p.total_solve_s for p in self.parts)

    @property
    def converged(self) -> bool:
        return self.result is not None and self.result.successful

    def prepared(self, parts: tuple["Attempt", ...], on: str) -> "Attempt":
        """This attempt with ``parts`` (the solves that made its start, on ``on``) before its own."""
        return replace(self, parts=tuple(parts) + self.parts, prepared_on=on if parts else self.prepared_on)

    def line(self) -> str:
        """The sentence of the message and of summary.json's ``attempts``: 'rollout: max_iterations in 200
        iterations', 'relaxed: converged in 43 iterations (6 of them on the relaxed problem), cost 22.6'."""
        if self.result is None:
            return f"{self.label}: {self.note}"
        made = self.total_iterations - self.iterations
        out = f"{self.label}: {self.result} in {self.total_iterations} iterations"
        if made:
            out += f" ({made} of them on {self.prepared_on})"
        if self.result.successful and math.isfinite(self.cost):
            out += f", cost {self.cost:.10g}"
        return out


def totals(trace: tuple[Attempt, ...]) -> tuple[int, float, float]:
    """(iterations, build seconds, solve seconds) of a trace: every solve in it, parts included."""
    return (sum(a.total_iterations for a in trace), sum(a.total_build_s for a in trace),
            sum(a.total_solve_s for a in trace))


def flattened(trace: tuple[Attempt, ...]) -> list[Attempt]:
    """Every attempt of a trace, parts first (in the order they were solved)."""
    out = []
    for a in trace:
        out += flattened(a.parts)
        out.append(replace(a, parts=()))
    return out
