"""The objectives, one module each (a class bringing its cost blocks, its indirect conditions where they exist, and its
default strategy), and the registry the maneuver files name them by.

    from se3ocp.transcription.objectives import Effort, Fuel, Time, named
    SmoothControl(objective=Fuel(), W_f=1.0, W_m=1.0)          # or named("fuel")

A new objective is a module here with its class (a frozen dataclass of :class:`~transcription.ocp.objective.
Objective`) and a line in :data:`OBJECTIVES`.  (:mod:`.peak`'s least peak force has no line: the effort strategy asks
it whether an engine is strong enough; it is no file's objective.)
"""
from __future__ import annotations

from typing import Any

from ..ocp import Objective, ProblemError
from .effort import Effort
from .effort_time import EffortTime
from .fuel import Fuel
from .propellant import Propellant
from .time import Time

#: the objectives by the name a maneuver file gives (``control.objective``)
OBJECTIVES: dict[str, type[Objective]] = {cls.name: cls for cls in (Effort, Time, Fuel, EffortTime, Propellant)}


def named(name: str, **parameters: Any) -> Objective:
    """The objective called ``name`` (:data:`OBJECTIVES`) with its ``parameters`` (the fields of its class);
    ProblemError for a name or a parameter it does not know."""
    if name not in OBJECTIVES:
        raise ProblemError("control.objective", f"expected one of {', '.join(OBJECTIVES)}, got {name!r}")
    try:
        return OBJECTIVES[name](**parameters)
    except TypeError as exc:
        raise ProblemError("control.objective", f"the {name} objective: {exc}") from None


__all__ = ["OBJECTIVES", "Effort", "EffortTime", "Fuel", "Propellant", "Time", "named"]
