"""se3ocp: geometrically exact optimal control of a rigid body on SE(3).

Lie group variational integrators on SE(3), and two methods on the same discretization: a
direct multiple-shooting NLP (IPOPT) and the indirect Newton-Armijo shooting on the discrete
necessary conditions.

    import se3ocp
    man = se3ocp.load("configs/e3_inclination_change.yaml", ["horizon.N=200"])
    res = se3ocp.solve(man, method="both")      # Comparison: res.direct, res.indirect, res.verdict
    print(res.direct.result, res.direct.cost, res.verdict)
    figs = se3ocp.plot(res)                     # {name: matplotlib Figure}

Layers: ``se3ocp.transcription`` (the methods, independent of any body or maneuver) and
``se3ocp.problems`` (models, maneuver files, results on disk, figures, the ``se3ocp`` CLI).
The names below are imported on first use, so that the command-line tool can install its
Ctrl-C handler before NumPy and CasADi load.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.2.0"

#: public name -> module (relative to this package) that defines it
_EXPORTS = {
    "load": "problems.api", "solve": "problems.api", "simulate": "problems.api", "plot": "problems.api",
    "export": "problems.export", "ExportError": "problems.export",
    "Maneuver": "problems.maneuvers", "ConfigError": "problems.schema",
    "DirectOptions": "transcription.options", "IndirectOptions": "transcription.options",
    "OptionError": "transcription.options", "AccuracyOptions": "transcription.strategy.refine",
    "Problem": "transcription.ocp", "ProblemError": "transcription.ocp",
    "SmoothControl": "transcription.ocp", "ImpulsiveControl": "transcription.ocp",
    "TargetState": "transcription.ocp", "TargetOrbit": "transcription.ocp",
    "TargetRendezvous": "transcription.ocp",
    "state_from_velocities": "transcription.ocp",
    "Solution": "transcription.results.solution", "Trajectory": "transcription.dynamics.trajectory", "Result": "transcription.outcome",
    "Iterate": "transcription.outcome", "SolveError": "transcription.results.solution", "Attempt": "transcription.results.trace",
    "Start": "transcription.results.start", "Effort": "transcription.objectives", "Time": "transcription.objectives",
    "Fuel": "transcription.objectives", "EffortTime": "transcription.objectives",
    "BoxBound": "transcription.ocp", "NormBound": "transcription.ocp", "ThrusterBound": "transcription.ocp",
    "Comparison": "transcription.solve", "compare": "transcription.solve",
    "tracking_gains": "transcription.closedloop.tracking", "fly": "problems.flight",
}
__all__ = [*_EXPORTS, "__version__"]


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from .problems.api import load, plot, simulate, solve  # noqa: F401
    from .problems.export import ExportError, export  # noqa: F401
    from .problems.maneuvers import Maneuver  # noqa: F401
    from .problems.schema import ConfigError  # noqa: F401
    from .transcription.options import DirectOptions, IndirectOptions, OptionError  # noqa: F401
    from .transcription.strategy.refine import AccuracyOptions  # noqa: F401
    from .transcription.ocp import (ImpulsiveControl, Problem, ProblemError, SmoothControl, TargetOrbit, TargetRendezvous, TargetState, state_from_velocities)
    from .transcription.results.solution import SolveError, Solution  # noqa: F401
    from .transcription.results.trace import Attempt  # noqa: F401
    from .transcription.outcome import Iterate, Result
    from .transcription.dynamics.trajectory import Trajectory  # noqa: F401
    from .transcription.results.start import Start  # noqa: F401
    from .transcription.objectives import Effort, EffortTime, Fuel, Time  # noqa: F401
    from .transcription.ocp import BoxBound, NormBound, ThrusterBound  # noqa: F401
    from .transcription.solve import Comparison, compare  # noqa: F401
    from .transcription.closedloop.tracking import tracking_gains  # noqa: F401
    from .problems.flight import fly  # noqa: F401
