"""Results directories: what a run writes, and reading it back as Solutions.

A results directory holds ``config.resolved.yaml`` (the maneuver after defaults and overrides,
itself a valid maneuver file), ``summary.json`` and one ``<method>.npz`` per solution
(``trajectory.npz`` for ``simulate``).  :func:`write_run` writes them (each file atomically);
:func:`read_run` rebuilds the Maneuver and the Solutions (trajectory, controls, impulses,
costates, result, cost, history), so figures and reports are drawn from Solutions whether they
come from memory or from disk.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..transcription.layout import pack_state
from ..transcription.results import Iterate, Result, Solution, Trajectory, to_jsonable
from ..transcription.solve import Comparison
from .io import write_json, write_npz, write_yaml
from .maneuvers import Maneuver, parse_maneuver
from .schema import ConfigError, read_yaml_file

#: margins of path constraints more negative than this are violations, smaller ones round-off, when
#: the run's options are not at hand (with them: DirectOptions.terminal_tol, the direct method's own
#: threshold for deeming a run with path constraints converged)
DEFAULT_PATH_TOL = 1e-8

#: the file of a Solution in a results directory
NPZ = {"direct": "direct.npz", "indirect": "indirect.npz", "simulate": "trajectory.npz"}
_IMPULSE_KEYS = ("dgamma0", "dPi0", "dgammaN", "dPiN")


def solutions_of(result: Solution | Comparison) -> dict[str, Solution]:
    """{method: Solution} of a solve's result."""
    return dict(result.solutions) if isinstance(result, Comparison) else {result.method: result}


def applicable(result: Solution | Comparison) -> dict[str, Solution]:
    """The Solutions of the methods that apply to the problem (a method that does not cover it
    returns Result.not_applicable: it is reported, not drawn or stored as a trajectory)."""
    return {m: s for m, s in solutions_of(result).items() if s.result is not Result.not_applicable}


def path_tolerance(man: Maneuver | None = None) -> float:
    """The violation threshold of path-constraint margins (in each constraint's unit): the
    maneuver's DirectOptions.terminal_tol (the resolved ``solver.direct.terminal_tol``), by which
    the direct method judges a path constraint violated; DEFAULT_PATH_TOL without a maneuver."""
    tol = getattr(getattr(man, "direct", None), "terminal_tol", None)
    return float(tol) if tol is not None else DEFAULT_PATH_TOL


def all_converged(result: Solution | Comparison) -> bool:
    """Every applicable method converged (and at least one applies)."""
    sols = applicable(result)
    return bool(sols) and all(s.converged for s in sols.values())


def summary(man: Maneuver, result: Solution | Comparison, with_history: bool = True) -> dict[str, Any]:
    """The summary.json document of a run (see the README's results table)."""
    sols = solutions_of(result)
    if set(sols) == {"simulate"}:
        s = sols["simulate"]
        out = {"command": "simulate", "name": man.name, "config": man.source, **s.summary()}
        out.pop("method", None)
        return out
    out = {"name": man.name, "config": man.source, "control": man.control_kind, "discretization": man.discretization,
           "N": man.N, "T": man.T, "converged": all_converged(result),
           "methods": {m: dict(s.summary(), **({"history": [h.as_dict() for h in s.history]} if with_history else {}))
                       for m, s in sols.items()}}
    if isinstance(result, Comparison):
        out["comparison"] = result.summary()
    return out


def write_run(out: Path, man: Maneuver, result: Solution | Comparison) -> list[Path]:
    """config.resolved.yaml, the .npz of each Solution and summary.json (written last) into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "config.resolved.yaml"]
    write_yaml(written[0], man.resolved)
    for m, s in applicable(result).items():
        p = out / NPZ[m]
        write_npz(p, s.arrays())
        written.append(p)
    write_json(out / "summary.json", summary(man, result))
    return written + [out / "summary.json"]


@dataclass
class Run:
    """A results directory read back: the maneuver, its Solutions by method, the summary document."""

    maneuver: Maneuver
    solutions: dict[str, Solution]
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def result(self) -> Solution | Comparison:
        """The Solution, or the Comparison of a run with both methods."""
        if {"direct", "indirect"} <= set(self.solutions):
            c = self.summary.get("comparison", {})
            return Comparison(self.solutions["direct"], self.solutions["indirect"],
                              float(c.get("cost_relative_difference", math.nan)),
                              c.get("control_max_difference_relative"), bool(c.get("same_extremal", False)),
                              str(c.get("verdict", "")))
        return next(iter(self.solutions.values()))


def _solution(method: str, arrays: dict[str, np.ndarray], block: dict[str, Any], man: Maneuver) -> Solution:
    model = man.problem.model
    X = pack_state(arrays["x"], arrays["gamma"], arrays["R"], arrays["Pi"])
    controls = np.vstack([arrays["u_f"].T, arrays["u_m"].T]) if "u_f" in arrays else None
    impulses = {k: arrays[k] for k in _IMPULSE_KEYS if k in arrays} or None
    try:
        result = Result(block.get("status", "converged" if method == "simulate" else "solver_failed"))
    except ValueError:
        result = Result.solver_failed
    hist = [Iterate(**{k: (math.nan if v is None else v) for k, v in h.items() if k in Iterate.__dataclass_fields__})
            for h in block.get("history", [])]
    known = ("method", "status", "message", "converged", "cost", "terminal_error", "iterations", "build_s", "solve_s",
             "solver", "history")
    return Solution(method=method, solver=str(block.get("solver", "")), result=result,
                    message=str(block.get("message", "")),
                    trajectory=Trajectory(t=arrays["t"], X=X, mass=model.mass, inertia=model.inertia),
                    cost=float(block.get("cost", math.nan) if block.get("cost") is not None else math.nan),
                    terminal_error=float(block.get("terminal_error") if block.get("terminal_error") is not None
                                         else math.nan),
                    iterations=int(block.get("iterations", 0)), build_s=float(block.get("build_s", 0.0)),
                    solve_s=float(block.get("solve_s", 0.0)), problem=man.problem, controls=controls,
                    impulses=impulses, costates=arrays.get("lam"), history=hist,
                    stats={k: v for k, v in block.items() if k not in known})


def read_run(results_dir: Path) -> Run:
    """Read a results directory written by :func:`write_run`; ConfigError (naming the file) if it
    is not one."""
    d = Path(results_dir)
    for name in ("summary.json", "config.resolved.yaml"):
        if not (d / name).is_file():
            raise ConfigError(str(d), "", f"not a results directory (no {name})")
    try:
        summ = json.loads((d / "summary.json").read_text())
    except (OSError, ValueError) as e:
        raise ConfigError(str(d / "summary.json"), "", f"unreadable ({e})") from None
    if not isinstance(summ, dict):
        raise ConfigError(str(d / "summary.json"), "", "expected a JSON object")
    man = parse_maneuver(read_yaml_file(d / "config.resolved.yaml"), str(d / "config.resolved.yaml"))
    methods = summ.get("methods", {})
    if not isinstance(methods, dict):
        raise ConfigError(str(d / "summary.json"), "methods", "expected a JSON object")
    sols = {}
    for method, fname in NPZ.items():
        p = d / fname
        if not p.is_file():
            continue
        block = summ if method == "simulate" else methods.get(method, {})
        if not isinstance(block, dict):
            raise ConfigError(str(d / "summary.json"), f"methods.{method}", "expected a JSON object")
        # A truncated or foreign file can fail in many ways (zipfile.BadZipFile, zlib.error, a
        # missing or misshapen array): any of them is one line naming the file, never a traceback.
        try:
            with np.load(p) as z:
                arrays = {k: z[k] for k in z.files}
            missing = [k for k in ("t", "x", "gamma", "R", "Pi") if k not in arrays]
            if missing:
                raise ValueError(f"no array {', '.join(missing)}")
            sols[method] = _solution(method, arrays, block, man)
        except Exception as e:  # noqa: BLE001 - see above; KeyboardInterrupt is not an Exception
            raise ConfigError(str(p), "", f"unreadable or not written by se3ocp ({type(e).__name__}: "
                                          f"{str(e).splitlines()[0] if str(e) else 'no details'})") from None
    if not sols:
        raise ConfigError(str(d), "", "no direct.npz, indirect.npz or trajectory.npz")
    return Run(man, sols, summ)


__all__ = ["DEFAULT_PATH_TOL", "NPZ", "Run", "path_tolerance", "read_run", "solutions_of", "summary", "to_jsonable", "write_run"]
