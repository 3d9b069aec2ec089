"""The continuous check's terminal miss in one dimensionless number (docs/mathematics.md §11, §16): the number
``solver.accuracy`` bounds and every display of "continuous miss" shows.  Its own module, importing nothing of the
project, so that :class:`~transcription.results.solution.Solution` can show it and :mod:`transcription.strategy.refine` bound it
without an import cycle (accuracy -> flight -> mesh -> results)."""
from __future__ import annotations

import numpy as np


def scaled_miss(check, problem) -> float:
    """The one scalar refinement drives below ``solver.accuracy``: the largest of the continuous check's terminal
    position miss relative to the characteristic length L, velocity miss relative to V, attitude miss (rad) and
    rate miss (rad per time unit).  With a central body L = |x_0| (the orbit radius: 1 in normalized units) and
    V = sqrt(mu / L) (the circular speed, 2 pi normalized); without one L = V = 1 (the file's units).  nan if the
    flight failed."""
    mu, L = problem.model.mu, characteristic_length(problem)
    V = float(np.sqrt(mu / L)) if mu else 1.0
    return float(max(check.terminal_position / L, check.terminal_velocity / V, check.terminal_attitude,
                     check.terminal_rate))


def characteristic_length(problem) -> float:
    """The characteristic length L of :func:`scaled_miss`: |x_0| with a central body, else 1."""
    L = float(np.linalg.norm(problem.X0[0:3])) if problem.model.mu else 1.0
    return L if L > 0 else 1.0


__all__ = ["characteristic_length", "scaled_miss"]
