"""Results directories: what a run writes, and reading it back as Solutions.

A results directory holds ``config.resolved.yaml`` (the maneuver after defaults and overrides,
itself a valid maneuver file), ``summary.json`` and one ``<method>.npz`` per solution
(``trajectory.npz`` for ``simulate``).  Both ways give a :class:`Run`: :func:`held_run` of the
result a command holds (which :func:`save_run` writes, each file atomically; :func:`write_run`
does both), :func:`read_run` of a directory on disk (rebuilding the Maneuver and the Solutions:
trajectory, controls, impulses, costates, result, cost, history) -- so figures and reports are
drawn from one Run whether it comes from memory or from disk, and a command that has just
written its run draws from what it holds, reading nothing back.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..transcription.results.check import ContinuousCheck
from ..transcription.geometry.state import pack_state
from ..transcription.outcome import Iterate, Result
from ..transcription.results.solution import Solution, to_jsonable
from ..transcription.results.trace import Attempt
from ..transcription.dynamics.trajectory import Trajectory
from ..transcription.solve import Comparison, compare
from .io import atomic_write_bytes, write_json, write_npz, yaml_text
from .maneuvers import Maneuver, parse_maneuver
from .schema import ConfigError, describe, read_yaml_file

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
    """config.resolved.yaml, the .npz of each Solution and summary.json (written last) into ``out``:
    :func:`save_run` of :func:`held_run`.  Returns the paths written."""
    return save_run(out, held_run(man, result))


def save_run(out: Path, run: "Run") -> list[Path]:
    """Write ``run`` (a :class:`Run` held in memory, :func:`held_run`) into the directory ``out``: its
    ``config_text`` as config.resolved.yaml, the .npz of each of its Solutions, its summary document as
    summary.json (written last, each file atomically).  Returns the paths written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "config.resolved.yaml"]
    atomic_write_bytes(written[0], run.config_text.encode())
    for m, s in run.solutions.items():
        p = out / NPZ[m]
        write_npz(p, s.arrays())
        written.append(p)
    write_json(out / "summary.json", run.summary)
    return written + [out / "summary.json"]


@dataclass
class Run:
    """A results directory: the maneuver, its Solutions by method (those with a .npz: the methods that
    apply), the summary document (summary.json), the resolved configuration's text (config.resolved.yaml)
    -- read back (:func:`read_run`), or held by the command that writes it (:func:`held_run`)."""

    maneuver: Maneuver
    solutions: dict[str, Solution]
    summary: dict[str, Any] = field(default_factory=dict)
    config_text: str = ""
    #: the Solution or Comparison the run was made from, when it is held in memory (None: read back)
    held: Solution | Comparison | None = None

    @property
    def result(self) -> Solution | Comparison | None:
        """The result held (:func:`held_run`); read back, the Solution, or the Comparison of a run with both
        methods -- compared again from the Solutions read back (costs, controls, statuses), so that its verdict
        is always the one of what is drawn, whatever summary.json's comparison block says."""
        if self.held is not None:
            return self.held
        if not self.solutions:
            return None                                     # no method applies (no_method_applies)
        if {"direct", "indirect"} <= set(self.solutions):
            return compare(self.solutions["direct"], self.solutions["indirect"])
        return next(iter(self.solutions.values()))


def held_run(man: Maneuver, result: Solution | Comparison) -> Run:
    """The :class:`Run` of a result in memory, as :func:`read_run` would read it back once written (the
    applicable methods' Solutions, the summary document as summary.json holds it, the text of
    config.resolved.yaml) and holding ``result`` itself: what a command that has just solved writes
    (:func:`save_run`) and draws its figures and report from, without reading anything back."""
    return Run(man, applicable(result), to_jsonable(summary(man, result)),
               yaml_text(man.resolved), held=result)


# ----------------------------------------------------------------- summary.json, read back
#: the fields of summary.json that figures and reports use, by kind: "number" (a JSON number, NaN and
#: Infinity included, or null), "count" (an integer >= 0), str, bool.  Other fields are kept, unread.
_NUMBERS = ("cost", "terminal_error", "build_s", "solve_s", "T", "h", "delta_v", "angular_impulse", "peak_force",
            "peak_moment", "force_time_at_bound", "moment_time_at_bound", "max_orthogonality_error",
            "max_determinant_error", "max_relative_energy_error", "final_relative_energy_error", "energy_initial",
            "max_cayley_residual", "terminal_attitude_error_deg", "min_constraint_margin",
            *(f"continuous_{k}" for k in ("terminal_error", "terminal_position", "terminal_velocity",
                                          "terminal_attitude_rad", "terminal_rate", "target_error",
                                          "max_position_deviation", "max_attitude_deviation_rad",
                                          "orthogonality_drift", "check_s", "change_position", "change_velocity",
                                          "change_attitude_rad", "change_target", "maneuver_fraction",
                                          "attitude_growth")))
BLOCK_FIELDS: dict[str, Any] = {"status": str, "message": str, "converged": bool, "cost": "number",
                                "terminal_error": "number", "iterations": "count", "N": "count", "method": str,
                                "solver": str, "discretization": str, **{k: "number" for k in _NUMBERS[2:]},
                                "continuous_samples": "count", "continuous_message": str, "mesh_history": list}
#: required in every method block (simulate: in the summary itself)
BLOCK_REQUIRED = ("status", "message", "converged", "cost", "terminal_error", "iterations")
RUN_FIELDS: dict[str, Any] = {"name": str, "config": str, "command": str, "discretization": str, "N": "count",
                              "T": "number", "converged": bool}
COMPARISON_FIELDS: dict[str, Any] = {"cost_relative_difference": "number", "control_max_difference_relative": "number",
                                     "same_extremal": bool, "verdict": str}
#: the progress records of ``history`` (transcription.results.solution.Iterate)
HISTORY_FIELDS: dict[str, Any] = {"iteration": "count", "trial": "count", "accepted": bool, "phase": str,
                                  "budget": "count",
                                  **{k: "number" for k in ("residual", "residual_inf", "cost", "dual", "step", "aux",
                                                           "elapsed_s")}}
_KINDS = {str: "a string", bool: "true or false", dict: "a JSON object", list: "a list", "number": "a number (or null)",
          "count": "an integer >= 0"}


def _fits(v, kind) -> bool:
    if kind == "number":
        return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
    if kind == "count":
        return isinstance(v, int) and not isinstance(v, bool) and v >= 0
    return isinstance(v, kind)


def _check_fields(d, where: str, fields: dict, required: tuple, fail) -> None:
    if not isinstance(d, dict):
        fail(where, f"expected a JSON object, got {describe(d)}")
    for k in required:
        if k not in d:
            fail(f"{where}.{k}" if where else k, "missing required key")
    margins = ("min_margin_", "continuous_min_margin_", "continuous_tolerance_min_margin_")   # and their tolerances
    for k, v in d.items():
        kind = fields.get(k, "number" if isinstance(k, str) and k.startswith(margins) else None)
        if kind is not None and not _fits(v, kind):
            fail(f"{where}.{k}" if where else k, f"expected {_KINDS[kind]}, got {describe(v)}")


def check_summary(summ: Any, source: str, npz_methods: list[str]) -> None:
    """Validate summary.json as read back (``npz_methods``: the methods whose .npz is present):
    every field figures and reports use has its type, every status is a Result and agrees with its
    ``converged`` flag, and the run's ``converged`` with its methods.  ConfigError naming ``source``
    and the field otherwise -- a tampered or foreign file is refused, never drawn wrongly."""
    def fail(where, msg):
        raise ConfigError(source, where, msg)

    _check_fields(summ, "", RUN_FIELDS, (), fail)
    simulate = npz_methods == ["simulate"]
    if simulate:
        blocks = {"": summ}
    else:
        _check_fields(summ, "", {**RUN_FIELDS, "methods": dict}, ("methods", "converged"), fail)
        blocks = {f"methods.{m}": b for m, b in summ["methods"].items()}
        for m in npz_methods:
            if m not in summ["methods"]:
                fail(f"methods.{m}", f"missing required key ({NPZ[m]} is present)")
        if "comparison" in summ:
            _check_fields(summ["comparison"], "comparison", COMPARISON_FIELDS, (), fail)
    agree = []
    for where, b in blocks.items():
        _check_fields(b, where, BLOCK_FIELDS, BLOCK_REQUIRED, fail)
        at = f"{where}." if where else ""
        if b["status"] not in Result._value2member_map_:
            fail(f"{at}status", f"expected one of {', '.join(Result._value2member_map_)}, got {describe(b['status'])}")
        if b["converged"] != Result(b["status"]).successful:
            fail(f"{at}converged", f"expected {Result(b['status']).successful} for status {b['status']}, got "
                                   f"{b['converged']}")
        if not simulate and b["converged"] and not (b["cost"] is not None and math.isfinite(b["cost"])):
            fail(f"{at}cost", f"expected a finite number for a converged plan, got {describe(b['cost'])}")
        history = b.get("history", [])
        if not isinstance(history, list):
            fail(f"{at}history", f"expected a list of progress records, got {describe(history)}")
        for i, rec in enumerate(history):
            _check_fields(rec, f"{at}history[{i}]", HISTORY_FIELDS, ("iteration",), fail)
        if b["status"] != Result.not_applicable.value:
            agree.append(b["converged"])
    if not simulate and summ["converged"] != (bool(agree) and all(agree)):
        fail("converged", f"expected {bool(agree) and all(agree)} (the methods' converged flags), got "
                          f"{summ['converged']}")


def _solution(method: str, arrays: dict[str, np.ndarray], block: dict[str, Any], man: Maneuver) -> Solution:
    model = man.problem.model
    X = pack_state(arrays["x"], arrays["gamma"], arrays["R"], arrays["Pi"])
    controls = np.vstack([arrays["u_f"].T, arrays["u_m"].T]) if "u_f" in arrays else None
    impulses = {k: arrays[k] for k in _IMPULSE_KEYS if k in arrays} or None
    result = Result(block["status"])  # check_summary: a Result's value
    hist = [Iterate(**{k: (math.nan if v is None else v) for k, v in h.items() if k in Iterate.__dataclass_fields__})
            for h in block.get("history", [])]
    known = ("method", "status", "message", "converged", "cost", "terminal_error", "iterations", "build_s", "solve_s",
             "solver", "history", "mesh_history")
    def number(key, default=math.nan):
        return float(default if block.get(key) is None else block[key])

    # the run's message as its verdict, its totals as one attempt (what summary.json keeps of the trace)
    done = Attempt("the run", result, int(block["iterations"]), number("cost"), number("build_s", 0.0),
                   number("solve_s", 0.0))
    return Solution(method=method, solver=str(block.get("solver", "")), result=result, verdict=block["message"],
                    trajectory=Trajectory(t=arrays["t"], X=X, mass=model.mass, inertia=model.inertia),
                    cost=number("cost"), terminal_error=number("terminal_error"), trace=(done,), problem=man.problem,
                    controls=controls, impulses=impulses, costates=arrays.get("lam"), history=hist,
                    stats={k: v for k, v in block.items() if k not in known and not k.startswith("continuous_")},
                    continuous=ContinuousCheck.from_record(block, arrays),
                    mesh=[m for m in block.get("mesh_history", []) if isinstance(m, dict)])


def no_method_applies(summ: Any) -> bool:
    """summary.json (as read) of a run whose every method is not_applicable: the one complete run without a .npz
    (nothing to draw or export; its report is the statuses and their messages)."""
    blocks = summ.get("methods") if isinstance(summ, dict) else None
    return bool(blocks) and isinstance(blocks, dict) and all(
        isinstance(b, dict) and b.get("status") == Result.not_applicable.value for b in blocks.values())


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
    cfg = d / "config.resolved.yaml"
    man = parse_maneuver(read_yaml_file(cfg), str(cfg))
    config_text = cfg.read_text(encoding="utf-8")   # read_yaml_file has checked that it is UTF-8
    present = [m for m, fname in NPZ.items() if (d / fname).is_file()]
    if not present and not no_method_applies(summ):
        raise ConfigError(str(d), "", "no direct.npz, indirect.npz or trajectory.npz")
    check_summary(summ, str(d / "summary.json"), present)
    sols = {}
    for method in present:
        p = d / NPZ[method]
        block = summ if method == "simulate" else summ["methods"][method]
        # A truncated or foreign file can fail in many ways (zipfile.BadZipFile, zlib.error, a
        # missing or misshapen array): any of them is one line naming the file, never a traceback.
        try:
            with open(p, "rb") as f, np.load(f) as z:     # our handle: NumPy leaves its own open on BadZipFile
                arrays = {k: z[k] for k in z.files}
            missing = [k for k in ("t", "x", "gamma", "R", "Pi") if k not in arrays]
            if missing:
                raise ValueError(f"no array {', '.join(missing)}")
            sols[method] = _solution(method, arrays, block, man)
        except Exception as e:  # noqa: BLE001 - see above; KeyboardInterrupt is not an Exception
            raise ConfigError(str(p), "", f"unreadable or not written by se3ocp ({type(e).__name__}: "
                                          f"{str(e).splitlines()[0] if str(e) else 'no details'})") from None
    return Run(man, sols, summ, config_text)


__all__ = ["DEFAULT_PATH_TOL", "NPZ", "Run", "check_summary", "held_run", "no_method_applies", "path_tolerance",
           "read_run", "save_run", "solutions_of", "summary", "to_jsonable", "write_run"]
