"""Trade studies: parameter sweeps over a maneuver, with continuation, on a local
process pool or a Dask cluster (issue 8).

Sweep file (unknown keys rejected; every error is a one-line
``FILE: FIELD: expected ...`` :class:`~problems.maneuvers.ConfigError`)::

    name: e3_T_sweep                      # optional (default: the file's stem)
    base: ../e3_inclination_change.yaml   # the maneuver file, relative to this file
    set: {horizon.N: 100}                 # optional overrides applied to every point
    axes:                                 # one or more; the grid is their product
      horizon.T: [0.45, 0.5, 0.55]        # a dotted key -> a list of values
      solver.direct.tol: {geomspace: [1.0e-8, 1.0e-12, 3]}
      model.length: {linspace: [0.05, 0.15, 5]}        # [start, stop, num], ends included
      inclination_deg:                    # a linked axis: each value sets several keys
        values: [10, 30]
        set:
          terminal.velocity: [[0, -6.1876, -1.0911], [0, -5.4414, -3.1416]]
          terminal.attitude: [{rotations: [[x, 10], [z, 180]]}, {rotations: [[x, 30], [z, 180]]}]
    methods: [direct, indirect]           # default [direct]; impulsive maneuvers: [direct]
    continuation: true                    # default false
    continuation_axis: horizon.T          # default: the first axis

Every grid point's overrides are validated through
:func:`~problems.maneuvers.load_maneuver` (and the raw IPOPT options are checked)
before any solve starts, so a bad axis value is bad input, not a failed point.

Execution.  A *task* is :func:`solve_point` applied to a plain dict (the base file
name and text, the override strings, the method, an optional warm-start payload of
numpy arrays); it returns a plain dict (the result row and the payload for the next
point).  Tasks run in-process (``workers=1``), on a local
:class:`~concurrent.futures.ProcessPoolExecutor` (forkserver/spawn context: CasADi
is not fork-safe once threads exist) or, with ``scheduler=ADDRESS``, on an existing
``dask.distributed`` cluster (its workers need this package installed).

Continuation.  Along one axis the points form chains (one per value of the other
axes and per method); the chains are independent and run in parallel, the points of
a chain in order.  Each point starts from the last converged point(s) of its chain:
with one, their solution itself (``start = neighbour``); with two, a secant
predictor, the linear extrapolation in the axis value of both solutions
(``start = secant``).  Direct: trajectory X, controls U and NLP multipliers nu
(primal and dual warm start, :func:`transcription.direct.solve_direct`); indirect:
the shooting unknown lambda_0.  A warm start that does not converge is followed by
a cold solve (``start = cold_after_failed_warm``; ``iterations_total`` counts both).
"""
from __future__ import annotations

import concurrent.futures as cf
import copy
import csv
import io
import itertools
import json
import math
import multiprocessing
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .io import atomic_write_bytes, write_json, write_yaml
from .maneuvers import Maneuver, load_maneuver, parse_maneuver
from .schema import (ConfigError, Validator, apply_override, blame_overrides, describe, join_field, read_yaml_file,
                     yaml_load)

SWEEP_KEYS = ("name", "base", "set", "axes", "methods", "continuation", "continuation_axis")
METHODS = ("direct", "indirect")
RANGE_FORMS = ("linspace", "geomspace")
#: the result columns after ``point``, ``method`` and one column per axis
RESULT_COLUMNS = ("status", "converged", "cost", "terminal_error", "iterations", "iterations_total",
                  "build_s", "solve_s", "warm_started", "start", "message")
#: a secant step larger than this multiple of the last spacing falls back to the neighbour
MAX_SECANT_RATIO = 3.0
#: limits that keep a typo from expanding into millions of solves, and bound the validation of the
#: grid (every point's maneuver is validated before any solve: about 1-3 ms a point, so at most
#: some 10-30 s, with a progress line every second, for the largest grid)
MAX_AXIS_VALUES = 10_000
MAX_GRID_POINTS = 10_000


# ---------------------------------------------------------------------------- schema
@dataclass(frozen=True)
class Axis:
    """One axis of the grid.  ``name`` is the result column (a dotted key, or the label
    of a linked axis); ``values`` the column values; ``sets[i]`` the (dotted key, value)
    assignments of value i."""

    name: str
    values: tuple
    sets: tuple
    numeric: bool


@dataclass(frozen=True)
class Point:
    """A grid point: ``coords`` (index along each axis), ``values`` {axis name: value},
    ``overrides`` the ``KEY=VALUE`` strings (the sweep's ``set`` first, then the axes)."""

    index: int
    coords: tuple
    values: dict
    overrides: tuple


@dataclass(frozen=True)
class Sweep:
    source: str
    name: str
    base: Path
    fixed: tuple           # override strings from ``set``
    axes: tuple            # of Axis
    methods: tuple
    continuation: bool
    continuation_axis: int
    control_kind: str | None
    doc: dict = field(repr=False, default_factory=dict)

    @property
    def shape(self) -> tuple:
        return tuple(len(a.values) for a in self.axes)

    def points(self) -> list[Point]:
        """Grid points in C order (the last axis varies fastest)."""
        out = []
        for i, coords in enumerate(itertools.product(*(range(n) for n in self.shape))):
            values = {a.name: a.values[c] for a, c in zip(self.axes, coords)}
            ov = list(self.fixed)
            for a, c in zip(self.axes, coords):
                ov += [_override(k, v) for k, v in a.sets[c]]
            out.append(Point(i, coords, values, tuple(ov)))
        return out

    def chains(self, continuation: bool) -> list[list[int]]:
        """Point indices grouped into chains: along the continuation axis if
        ``continuation``, else one point per chain."""
        pts = self.points()
        if not continuation:
            return [[p.index] for p in pts]
        c = self.continuation_axis
        groups: dict[tuple, list[int]] = {}
        for p in pts:
            groups.setdefault(p.coords[:c] + p.coords[c + 1:], []).append(p.index)
        return [sorted(g, key=lambda i: pts[i].coords[c]) for g in groups.values()]

    def row_methods(self) -> tuple:
        """Method labels of the rows (impulsive sweeps are validated to use the direct method only)."""
        return self.methods


def _override(key: str, value) -> str:
    return f"{key}={_flow(value)}"


def _flow(x) -> str:
    """YAML flow text of a plain value: JSON (floats round-trip exactly by repr), except
    non-finite floats, written the YAML way (.nan, .inf) so the validator names them."""
    if isinstance(x, float) and not math.isfinite(x):
        return ".nan" if math.isnan(x) else (".inf" if x > 0 else "-.inf")
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_flow(a) for a in x) + "]"
    if isinstance(x, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_flow(a)}" for k, a in x.items()) + "}"
    return json.dumps(x)


def _clean(x: float) -> float:
    """linspace/geomspace values without representation noise (0.47000000000000003 -> 0.47)."""
    return float(f"{x:.15g}")


def _axis_values(v: Validator, spec, where) -> list:
    """A list, or ``{linspace|geomspace: [start, stop, num]}``."""
    if isinstance(spec, dict):
        if len(spec) != 1 or next(iter(spec)) not in RANGE_FORMS:
            v.fail(where, f"expected a list of values or one of {{linspace: [start, stop, num]}}, "
                          f"{{geomspace: [start, stop, num]}}, got a mapping with keys {sorted(map(str, spec))}")
        (form, args), = spec.items()
        w = join_field(where, form)
        if not isinstance(args, (list, tuple)) or len(args) != 3:
            v.fail(w, f"expected [start, stop, num], got {describe(args)}")
        a = v.number(args[0], f"{w}[0]")
        b = v.number(args[1], f"{w}[1]")
        n = v.number(args[2], f"{w}[2]", integer=True, positive=True)
        if n > MAX_AXIS_VALUES:
            v.fail(f"{w}[2]", f"expected at most {MAX_AXIS_VALUES} values, got {n}")
        if form == "geomspace":
            if not (a > 0 and b > 0):
                v.fail(w, f"expected positive start and stop for geomspace, got {a!r}, {b!r}")
            vals = np.geomspace(a, b, n)
        else:
            vals = np.linspace(a, b, n)
        vals = [_clean(x) for x in vals]
    elif isinstance(spec, (list, tuple)):
        vals = list(spec)
    else:
        v.fail(where, f"expected a list of values or {{linspace: [start, stop, num]}}, got {describe(spec)}")
    if not vals:
        v.fail(where, "expected at least one value")
    if len(vals) > MAX_AXIS_VALUES:
        v.fail(where, f"expected at most {MAX_AXIS_VALUES} values, got {len(vals)}")
    for i, x in enumerate(vals):
        if x is None:
            v.fail(f"{where}[{i}]", "expected a value, got nothing (null)")
        for j in range(i):
            if vals[j] == x and type(vals[j]) is type(x):
                v.fail(f"{where}[{i}]", f"expected distinct values; {x!r} repeats {where}[{j}]")
    return vals


def _dotted(v: Validator, key, where) -> str:
    if not isinstance(key, str) or not all(p and p.isidentifier() for p in key.split(".")):
        v.fail(where, f"expected a dotted maneuver key such as horizon.T, got {describe(key)}")
    return key


def _axis(v: Validator, name, spec, where) -> Axis:
    if isinstance(spec, dict) and ("values" in spec or "set" in spec):  # linked axis
        if not isinstance(name, str) or not name or not name.isprintable():
            v.fail(where, "expected a printable axis name")
        v.mapping(spec, where, ("values", "set"), required=("values", "set"))
        vals = _axis_values(v, spec["values"], join_field(where, "values"))
        sets = spec["set"]
        if not isinstance(sets, dict) or not sets:
            v.fail(join_field(where, "set"), f"expected a non-empty mapping of dotted key -> list of values, got {describe(sets)}")
        per_key = {}
        for k, lst in sets.items():
            wk = f"{where}.set.{k}"
            _dotted(v, k, wk)
            if not isinstance(lst, (list, tuple)) or len(lst) != len(vals):
                v.fail(wk, f"expected a list of {len(vals)} values (one per axis value), got {describe(lst)}")
            per_key[k] = list(lst)
        assigns = tuple(tuple((k, per_key[k][i]) for k in per_key) for i in range(len(vals)))
    else:
        _dotted(v, name, where)
        vals = _axis_values(v, spec, where)
        assigns = tuple(((name, x),) for x in vals)
    numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in vals)
    return Axis(str(name), tuple(vals), assigns, numeric)


def parse_sweep(doc: Any, source: str) -> Sweep:
    """Validate the sweep document's structure (not yet the grid points)."""
    v = Validator(source)
    v.mapping(doc, "", SWEEP_KEYS, required=("base", "axes"))
    name = doc.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        v.fail("name", f"expected a non-empty string, got {describe(name)}")
    if not isinstance(doc["base"], str) or not doc["base"].strip():
        v.fail("base", f"expected the path of a maneuver file (relative to the sweep file), got {describe(doc['base'])}")
    base = Path(source).parent / doc["base"]
    fixed_doc = doc.get("set", {}) or {}
    if not isinstance(fixed_doc, dict):
        v.fail("set", f"expected a mapping of dotted key -> value, got {describe(fixed_doc)}")
    fixed = tuple(_override(_dotted(v, k, f"set.{k}"), x) for k, x in fixed_doc.items())
    axes_doc = doc["axes"]
    if not isinstance(axes_doc, dict) or not axes_doc:
        v.fail("axes", f"expected a non-empty mapping of dotted key -> values, got {describe(axes_doc)}")
    axes = tuple(_axis(v, k, s, join_field("axes", k) if isinstance(k, str) and "." not in k else f"axes.{k}")
                 for k, s in axes_doc.items())
    size = math.prod(len(a.values) for a in axes)
    if size > MAX_GRID_POINTS:
        v.fail("axes", f"expected at most {MAX_GRID_POINTS} grid points, got {size}")
    reserved = {"point", "method", *RESULT_COLUMNS}
    for a in axes:
        if a.name in reserved:
            v.fail(f"axes.{a.name}", f"expected an axis name other than the result columns {sorted(reserved)}")
    keys = [k for a in axes for k, _ in a.sets[0]]
    dup = next((k for i, k in enumerate(keys) if k in keys[:i] or k in fixed_doc), None)
    if dup:
        v.fail("axes", f"expected each maneuver key to be set once; {dup} is set twice")
    # one key inside another (control.bounds and control.bounds.moment.norm): whichever is applied
    # last would replace the other's values, and rows would be labelled with values never applied
    every = list(fixed_doc) + keys
    nested = next(((a, b) for a in every for b in every if b.startswith(a + ".")), None)
    if nested:
        v.fail("axes" if nested[1] in keys else "set", f"expected keys that do not overlap; {nested[1]} lies inside "
                                                      f"{nested[0]} (set both through {nested[0]})")
    methods = doc.get("methods", ["direct"])
    if not isinstance(methods, (list, tuple)) or not methods:
        v.fail("methods", f"expected a non-empty list of {', '.join(METHODS)}, got {describe(methods)}")
    methods = tuple(v.choice(m, f"methods[{i}]", METHODS) for i, m in enumerate(methods))
    if len(set(methods)) != len(methods):
        v.fail("methods", "expected each method once")
    cont = doc.get("continuation", False)
    if not isinstance(cont, bool):
        v.fail("continuation", f"expected true or false, got {describe(cont)}")
    c_axis = 0
    if "continuation_axis" in doc:
        names = [a.name for a in axes]
        c_axis = names.index(v.choice(doc["continuation_axis"], "continuation_axis", names))
    return Sweep(source=source, name=name.strip(), base=base, fixed=fixed, axes=axes, methods=methods,
                 continuation=cont, continuation_axis=c_axis, control_kind=None, doc=copy.deepcopy(doc))


def load_sweep(path: str | Path, progress: Callable[[int, int], None] | None = None) -> Sweep:
    """Read and validate a sweep file, then every grid point through load_maneuver
    (and the raw IPOPT options): raises ConfigError before any solve.  ``progress(done, total)``
    is called as the grid points are validated (at most one call a second, and at the end)."""
    return sweep_from_doc(read_yaml_file(path), str(path), progress)


def sweep_from_doc(doc: Any, source: str, progress: Callable[[int, int], None] | None = None) -> Sweep:
    """parse_sweep, then the base maneuver and every grid point (its overrides on the base
    document, read once, through parse_maneuver) and the raw IPOPT options: a valid Sweep or
    a ConfigError, before any solve.  The work is bounded by MAX_GRID_POINTS parses of a base
    file of at most yamlfile.MAX_FILE_BYTES; ``progress``: see :func:`load_sweep`."""
    sw = parse_sweep(doc, source)
    if not sw.base.is_file():
        raise ConfigError(source, "base", f"expected a maneuver file; {sw.base} does not exist")
    try:  # the base itself, so its own errors are reported as such
        base_man = load_maneuver(sw.base)
    except ConfigError as e:
        raise ConfigError(source, "base", f"the base maneuver is invalid: {e}") from None
    kind = base_man.control_kind
    if kind is None:
        raise ConfigError(source, "base", f"expected a maneuver with a control and a terminal block ({sw.base} has none)")
    if kind == "impulsive" and "indirect" in sw.methods:
        raise ConfigError(source, "methods", "the indirect method applies to smooth maneuvers; "
                                             "impulsive maneuvers are swept with methods: [direct]")
    base_doc = read_yaml_file(sw.base) or {}
    points = sw.points()
    last = time.monotonic()
    for n, p in enumerate(points):
        if progress is not None and time.monotonic() - last >= 1.0:
            progress(n, len(points))
            last = time.monotonic()
        try:
            man = _maneuver_from_doc(base_doc, str(sw.base), p.overrides)
        except ConfigError as e:
            raise ConfigError(source, _blame(sw, p, e.field), f"grid point {_label(p.values)}: "
                                                              f"{e.field or '<document>'}: {e.detail}") from None
        if man.control_kind != kind:
            raise ConfigError(source, _blame(sw, p, "control"), f"grid point {_label(p.values)}: "
                                                                f"the control kind changes across the grid")
    if progress is not None:
        progress(len(points), len(points))
    return Sweep(**{**sw.__dict__, "control_kind": kind})


def _maneuver_from_doc(base_doc, source: str, overrides) -> Maneuver:
    """load_maneuver(source, overrides) on the already-read base document (not read again per point);
    an error in a field an override set names --set, as load_maneuver does."""
    doc = copy.deepcopy(base_doc)
    keys = [apply_override(doc, a) for a in overrides] if isinstance(doc, dict) else []
    try:
        return parse_maneuver(doc, source)
    except ConfigError as e:
        raise blame_overrides(e, keys) from None


def _blame(sw: Sweep, p: Point, fieldname: str) -> str:
    """The sweep-file field responsible for an error in a point's maneuver field."""
    for a, c in zip(sw.axes, p.coords):
        for k, _ in a.sets[c]:
            if fieldname == k or fieldname.startswith(k + ".") or fieldname.startswith(k + "[") \
                    or k.startswith(fieldname + "."):
                return f"axes.{a.name}[{c}]" if k == a.name else f"axes.{a.name}.set.{k}[{c}]"
    for a in sw.fixed:
        k = a.partition("=")[0]
        if fieldname == k or fieldname.startswith(k + ".") or fieldname.startswith(k + "["):
            return f"set.{k}"
    return "axes"


def _label(values: dict) -> str:
    return ", ".join(f"{k}={_fmt(x)}" for k, x in values.items())


def _fmt(x) -> str:
    return f"{x:g}" if isinstance(x, float) else json.dumps(x) if not isinstance(x, str) else x


# ---------------------------------------------------------------------------- the task
def _maneuver_from_text(source: str, text: str, overrides):
    """load_maneuver on a file's text (workers of a remote cluster need not see the file)."""
    doc = yaml_load(text) or {}
    doc = copy.deepcopy(doc)
    for a in overrides:
        apply_override(doc, a)
    return parse_maneuver(doc, source)


def _warm_solution(problem, warm: dict):
    """A direct warm start (a Solution carrying X, U and the NLP multipliers) from a payload
    {X, U, nu}, or None if it does not fit the problem."""
    from ..transcription.direct import trajectory
    from ..transcription.layout import NX
    from ..transcription.results import Result, Solution

    X, U = np.asarray(warm.get("X")), np.asarray(warm.get("U"))
    if X.shape != (problem.N + 1, NX) or U.shape != (6, problem.disc.n_controls(problem.N)):
        return None
    return Solution(method="direct", solver="ipopt", result=Result.converged, message="continuation payload",
                    trajectory=trajectory(problem, X), cost=float("nan"), terminal_error=float("nan"), iterations=0,
                    build_s=0.0, solve_s=0.0, problem=problem, controls=U,
                    stats={"nlp_nu": warm.get("nu")} if warm.get("nu") is not None else {})


def _payload(method: str, sol) -> dict | None:
    if not sol.converged or sol.controls is None:
        return None
    if method == "direct":
        return {"X": np.asarray(sol.trajectory.X), "U": np.asarray(sol.controls),
                "nu": None if sol.stats.get("nlp_nu") is None else np.asarray(sol.stats["nlp_nu"])}
    if method == "indirect":
        lam = sol.stats.get("lam0")
        return {"lam0": np.asarray(lam if lam is not None else sol.costates[0], float)}
    return None


def _solve(man, method: str, warm: dict | None):
    """(final Solution, warm_started, start, iterations_total): a warm solve from the payload, and a
    cold one if there is none or it fails (through the one dispatcher, transcription.solve)."""
    from ..transcription.solve import solve
    from .api import check_clearance

    problem = man.problem

    def run(ws=None):
        return check_clearance(man, solve(problem, method, direct=man.direct, indirect=man.indirect, warm_start=ws))

    ws = None
    if warm and man.control_kind == "smooth":
        if method == "direct":
            ws = _warm_solution(problem, warm)
        elif warm.get("lam0") is not None and np.shape(warm["lam0"]) == (12,):
            ws = np.asarray(warm["lam0"], float)
    if ws is None:
        sol = run()
        return sol, False, "cold" if not warm else "cold_warm_start_does_not_fit", sol.iterations
    try:
        sol = run(ws)
    except Exception:  # noqa: BLE001 - a warm start that breaks the solver is a failed warm start
        sol = None
    if sol is not None and sol.converged:
        return sol, True, warm.get("kind", "neighbour"), sol.iterations
    first = sol.iterations if sol is not None else 0
    sol = run()
    return sol, False, "cold_after_failed_warm", first + sol.iterations


def solve_point(task: dict) -> dict:
    """One grid point by one method: the unit of work sent to a pool or a Dask cluster.

    task: {'source': base file name, 'text': its YAML text, 'overrides': [KEY=VALUE, ...],
    'method': 'direct' | 'indirect', 'warm': None | payload (+ 'kind')}.
    Returns {'row': result fields (RESULT_COLUMNS), 'payload': warm start for the next
    point or None}.  Never raises for a failing solve: the error is the row's status.
    """
    t0 = time.perf_counter()
    try:
        man = _maneuver_from_text(task["source"], task["text"], task["overrides"])
        sol, warm_started, start, total = _solve(man, task["method"], task.get("warm"))
    except Exception as exc:  # a failing point is data; the sweep goes on
        row = dict(status="error", converged=False, cost=float("nan"), terminal_error=float("nan"), iterations=0,
                   iterations_total=0, build_s=0.0, solve_s=time.perf_counter() - t0, warm_started=False,
                   start="cold" if not task.get("warm") else task["warm"].get("kind", "neighbour"),
                   message=f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500])
        return {"row": row, "payload": None}
    row = dict(status=sol.result.value, converged=bool(sol.converged), cost=float(sol.cost),
               terminal_error=float(sol.terminal_error), iterations=int(sol.iterations), iterations_total=int(total),
               build_s=float(sol.build_s), solve_s=float(sol.solve_s), warm_started=bool(warm_started), start=start,
               message=" ".join(str(sol.message).split()))
    return {"row": row, "payload": _payload(task["method"], sol)}


# ---------------------------------------------------------------------------- executors
def _ignore_sigint():  # pool workers: Ctrl-C is the driver's to handle
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _Serial:
    """In-process execution with the executor interface (``workers=1``)."""

    kind = "serial"

    def submit(self, fn, arg):
        f = cf.Future()
        try:
            f.set_result(fn(arg))
        except Exception as exc:
            f.set_exception(exc)
        return f

    def wait_first(self, pending):
        return cf.wait(pending, return_when=cf.FIRST_COMPLETED)

    def shutdown(self, interrupted=False):
        pass


class _Pool:
    """A local ProcessPoolExecutor (forkserver context where available, else spawn)."""

    kind = "local"

    def __init__(self, workers: int):
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
        self.workers = workers
        self.pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_ignore_sigint)

    def submit(self, fn, arg):
        return self.pool.submit(fn, arg)

    def wait_first(self, pending):
        return cf.wait(pending, return_when=cf.FIRST_COMPLETED)

    def shutdown(self, interrupted=False):
        if getattr(self, "_closed", False):
            return
        self._closed = True
        if interrupted:  # do not wait for running solves: stop the workers
            procs = list((getattr(self.pool, "_processes", None) or {}).values())
            self.pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()
            for p in procs:
                p.join(5)
        else:
            self.pool.shutdown(wait=True)


class _Dask:
    """Tasks submitted to an existing dask.distributed cluster (``Client(address)``)."""

    kind = "dask"

    def __init__(self, address: str, timeout: float = 10.0):
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--scheduler", address, "dask.distributed is not installed; "
                                                      "pip install 'dask[distributed]' (or se3ocp[sweep])") from None
        try:
            self.client = Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as e:
            raise ConfigError("--scheduler", address, f"cannot connect to a Dask scheduler there ({e})") from None
        self._futures: dict = {}

    def submit(self, fn, arg):
        """A concurrent.futures.Future completed from the Dask future's done callback,
        so that the driver waits on every executor the same way (cf.wait)."""
        dfut = self.client.submit(fn, arg, pure=False)
        fut = cf.Future()

        def done(d):
            try:
                fut.set_result(d.result())
            except BaseException as exc:  # noqa: BLE001 - handed to the driver, which records it
                fut.set_exception(exc)

        dfut.add_done_callback(done)
        self._futures[fut] = dfut
        return fut

    def wait_first(self, pending):
        done = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
        for f in done.done:
            self._futures.pop(f, None)
        return done

    def shutdown(self, interrupted=False):
        if getattr(self, "_closed", False):
            return
        self._closed = True
        if interrupted and self._futures:
            self.client.cancel(list(self._futures.values()))
        self.client.close()


def default_workers() -> int:
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def make_executor(workers: int | None = None, scheduler: str | None = None):
    """_Dask(scheduler) if given, else in-process for workers == 1, else a local pool
    (default: one worker per available core)."""
    if scheduler:
        return _Dask(scheduler)
    workers = workers or default_workers()
    return _Serial() if workers == 1 else _Pool(workers)


# ---------------------------------------------------------------------------- driver
def _predict(history: list, value, numeric: bool) -> dict | None:
    """Warm-start payload for the point at axis ``value`` from the last converged
    (value, payload) pairs of its chain: the neighbour, or the secant extrapolation."""
    if not history:
        return None
    v1, p1 = history[-1]
    out = dict(p1, kind="neighbour")
    if len(history) >= 2 and numeric:
        v0, p0 = history[-2]
        r = (value - v1) / (v1 - v0) if v1 != v0 else math.inf
        if math.isfinite(r) and abs(r) <= MAX_SECANT_RATIO:
            sec = {}
            for k, a in p1.items():
                b = p0.get(k)
                if a is None or b is None or np.shape(a) != np.shape(b):
                    break
                sec[k] = np.asarray(a) + r * (np.asarray(a) - np.asarray(b))
            else:
                out = dict(sec, kind="secant")
    return out


@dataclass
class SweepResult:
    sweep: Sweep
    rows: list            # dicts: point, method, axis values, RESULT_COLUMNS
    continuation: bool
    executor: str
    workers: int | None
    wall_s: float
    interrupted: bool = False

    @property
    def n_tasks(self) -> int:
        return len(self.sweep.points()) * len(self.sweep.row_methods())

    def summary(self) -> dict:
        rows = self.rows
        by = {}
        for m in self.sweep.row_methods():
            r = [x for x in rows if x["method"] == m]
            by[m] = {"points": len(r), "converged": sum(x["converged"] for x in r),
                     "iterations": sum(x["iterations"] for x in r),
                     "iterations_total": sum(x["iterations_total"] for x in r),
                     "warm_started": sum(x["warm_started"] for x in r),
                     "fallbacks_to_cold": sum(x["start"] == "cold_after_failed_warm" for x in r)}
        return {"name": self.sweep.name, "sweep": self.sweep.source, "base": str(self.sweep.base),
                "axes": {a.name: list(a.values) for a in self.sweep.axes}, "methods": list(self.sweep.row_methods()),
                "continuation": self.continuation,
                "continuation_axis": self.sweep.axes[self.sweep.continuation_axis].name if self.continuation else None,
                "executor": self.executor, "workers": self.workers, "tasks": self.n_tasks, "finished": len(rows),
                "converged": sum(x["converged"] for x in rows), "all_converged": self.all_converged,
                "interrupted": self.interrupted, "wall_s": self.wall_s, "by_method": by}

    @property
    def all_converged(self) -> bool:
        return len(self.rows) == self.n_tasks and all(r["converged"] for r in self.rows)


def run_sweep(sweep: Sweep, *, workers: int | None = None, scheduler: str | None = None,
              continuation: bool | None = None, progress: Callable[[dict, int, int], None] | None = None,
              check_interrupt: Callable[[], None] | None = None, executor=None) -> SweepResult:
    """Run every grid point by every method; failures are rows, never exceptions.

    continuation: None -> the sweep file's setting.  progress(row, done, total) after each task.
    On KeyboardInterrupt the workers are stopped and the exception carries the rows
    finished so far as ``exc.partial`` (a SweepResult).
    """
    cont = sweep.continuation if continuation is None else bool(continuation)
    pts = sweep.points()
    methods = sweep.row_methods()
    text = sweep.base.read_text()
    chains = sweep.chains(cont)
    ax = sweep.axes[sweep.continuation_axis]
    ex = executor or make_executor(workers, scheduler)
    n_workers = getattr(ex, "workers", 1 if isinstance(ex, _Serial) else None)
    total = len(pts) * len(methods)
    rows: list[dict] = []
    t0 = time.perf_counter()
    # chain state per (chain id, method): next position, converged history [(axis value, payload)]
    state = {(c, m): {"pos": 0, "hist": []} for c in range(len(chains)) for m in methods}
    pending: dict = {}

    def submit(key):
        c, m = key
        st = state[key]
        p = pts[chains[c][st["pos"]]]
        warm = _predict(st["hist"], p.values[ax.name], ax.numeric) if cont else None
        task = {"source": str(sweep.base), "text": text, "overrides": list(p.overrides), "method": m, "warm": warm}
        pending[ex.submit(solve_point, task)] = (key, p, warm)

    def finish(fut):
        key, p, warm = pending.pop(fut)
        try:
            out = fut.result()
        except Exception as exc:  # the worker itself died (not a solver failure: those are rows)
            out = {"row": dict(status="worker_failed", converged=False, cost=float("nan"), terminal_error=float("nan"),
                               iterations=0, iterations_total=0, build_s=0.0, solve_s=0.0, warm_started=False,
                               start="cold" if not warm else warm["kind"],
                               message=f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500]),
                   "payload": None}
        row = {"point": p.index, "method": key[1], **p.values, **out["row"]}
        rows.append(row)
        st = state[key]
        if out["payload"] is not None:
            st["hist"] = (st["hist"] + [(p.values[ax.name], out["payload"])])[-2:]
        st["pos"] += 1
        if progress:
            progress(row, len(rows), total)
        if st["pos"] < len(chains[key[0]]):
            submit(key)

    interrupted = False
    try:
        for key in state:
            submit(key)
            if check_interrupt:
                check_interrupt()
        while pending:
            done, _ = ex.wait_first(list(pending))
            for f in done:
                finish(f)
            if check_interrupt:
                check_interrupt()
    except KeyboardInterrupt as exc:
        interrupted = True
        ex.shutdown(interrupted=True)
        exc.partial = SweepResult(sweep, _sorted(rows, methods), cont, ex.kind, n_workers,
                                  time.perf_counter() - t0, interrupted=True)
        raise
    finally:
        if not interrupted and executor is None:
            ex.shutdown()
    return SweepResult(sweep, _sorted(rows, methods), cont, ex.kind, n_workers, time.perf_counter() - t0)


def _sorted(rows, methods):
    order = {m: i for i, m in enumerate(methods)}
    return sorted(rows, key=lambda r: (r["point"], order[r["method"]]))


# ---------------------------------------------------------------------------- command
def cli_sweep(args, check_interrupt: Callable[[], None] | None = None) -> int:
    """``se3ocp sweep``: validate, connect, run, write.  Exit 0 if every point converged,
    1 if some did not (all rows are still written), ConfigError/ResultsDirError for bad
    input; on Ctrl-C the finished rows are written and KeyboardInterrupt propagates."""
    from .io import results_transaction

    say = (lambda *m: None) if args.quiet else (lambda *m: print(*m, flush=True))  # noqa: E731

    def validating(done, total):  # long validations show life (at most once a second)
        if done < total:
            say(f"validating the grid: {done}/{total} points checked ...")

    sw = load_sweep(args.sweep, progress=validating)
    cont = False if args.no_continuation else sw.continuation
    ex = make_executor(args.workers, args.scheduler)  # a bad --scheduler fails before anything is written
    try:
        with results_transaction(args.out, Path("results") / "sweeps" / _safe(sw.name), args.force) as tx:
            n = len(sw.points())
            where = {"serial": "in-process", "local": f"local pool of {getattr(ex, 'workers', '?')} workers",
                     "dask": f"Dask cluster at {args.scheduler}"}[ex.kind]
            axc = sw.axes[sw.continuation_axis].name
            say(f"{sw.name}: {n} points x {len(sw.row_methods())} method(s) = {n * len(sw.row_methods())} tasks on "
                f"{where}; continuation {('along ' + axc) if cont and sw.control_kind != 'impulsive' else 'off'} "
                f"-> {tx.target}/")
            bar = ProgressBar(quiet=args.quiet)
            try:
                res = run_sweep(sw, continuation=cont, progress=bar, check_interrupt=check_interrupt, executor=ex)
            except KeyboardInterrupt as exc:
                bar.close()
                if getattr(exc, "partial", None) is not None:   # the finished rows, clearly marked incomplete
                    write_results(tx.path, exc.partial, figures=False)
                    tx.commit(incomplete=f"interrupted (Ctrl-C) after {len(exc.partial.rows)} of "
                                         f"{exc.partial.n_tasks} tasks")
                raise
            bar.close()
            write_results(tx.path, res)
            if check_interrupt is not None:  # a Ctrl-C swallowed meanwhile: do not commit
                check_interrupt()
        out = tx.target
    finally:
        ex.shutdown()
    s = res.summary()
    for m, b in s["by_method"].items():
        say(f"  {m:<9} {b['converged']}/{b['points']} converged, {b['iterations_total']} iterations "
            f"({b['warm_started']} warm-started, {b['fallbacks_to_cold']} fell back to a cold start)")
    say(f"  {res.wall_s:.1f} s wall; results in {out}/ (results.csv, results.jsonl, figures)")
    return 0 if res.all_converged else 1


# ---------------------------------------------------------------------------- output
class ProgressBar:
    """One line redrawn in place on a terminal; one line per finished task otherwise."""

    def __init__(self, stream=None, quiet: bool = False, width: int = 30):
        self.stream = stream or sys.stderr
        self.quiet, self.width = quiet, width
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self.bad = 0
        self.ended = False

    def __call__(self, row: dict, done: int, total: int):
        if self.quiet:
            return
        self.bad += not row["converged"]
        el = time.perf_counter() - self.t0
        if self.tty:
            k = int(self.width * done / max(total, 1))
            line = (f"\r[{'#' * k}{'.' * (self.width - k)}] {done}/{total} tasks, {self.bad} not converged, "
                    f"{el:.0f} s")
            self.ended = done == total
            self.stream.write(line + ("\n" if self.ended else ""))
        else:
            vals = {k: v for k, v in row.items() if k not in ("point", "method", *RESULT_COLUMNS)}
            self.stream.write(f"[{done:>{len(str(total))}}/{total}] {row['method']:<9} {_label(vals)}: "
                              f"{row['status']}, cost {row['cost']:.10g}, {row['iterations']} it ({row['start']}), "
                              f"{row['build_s'] + row['solve_s']:.2f} s\n")
        self.stream.flush()

    def close(self):
        if self.tty and not self.quiet and not self.ended:
            self.stream.write("\n")
            self.stream.flush()


def _cell(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return v


def _finite_or_none(v):
    """JSON lines stay strict JSON: NaN/inf (a failed point's cost) become null."""
    return None if isinstance(v, float) and not math.isfinite(v) else v


def columns(sweep: Sweep) -> list[str]:
    return ["point", "method", *(a.name for a in sweep.axes), *RESULT_COLUMNS]


def write_results(out: Path, result: SweepResult, figures: bool = True) -> list[Path]:
    """results.csv, results.jsonl, summary.json, sweep.resolved.yaml and the figures (atomic writes)."""
    out = Path(out)
    cols = columns(result.sweep)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in result.rows:
        w.writerow([_cell(r.get(c)) for c in cols])
    atomic_write_bytes(out / "results.csv", buf.getvalue().encode())
    pts = result.sweep.points()
    lines = [json.dumps({**{c: _finite_or_none(r.get(c)) for c in cols}, "overrides": list(pts[r["point"]].overrides)},
                        allow_nan=False) for r in result.rows]
    atomic_write_bytes(out / "results.jsonl", ("\n".join(lines) + "\n" if lines else "").encode())
    write_json(out / "summary.json", result.summary())
    write_yaml(out / "sweep.resolved.yaml", {**result.sweep.doc, "base": str(result.sweep.base)})
    written = [out / n for n in ("results.csv", "results.jsonl", "summary.json", "sweep.resolved.yaml")]
    if figures and result.rows:
        written += draw_sweep(out, result)
    return written


# ---------------------------------------------------------------------------- figures
def _positions(axis: Axis):
    """x positions and tick labels: the values if numeric, else their indices."""
    if axis.numeric:
        return np.array(axis.values, float), None
    return np.arange(len(axis.values), dtype=float), [_fmt(v) for v in axis.values]


def _save_png(fig, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def draw_sweep(out: Path, result: SweepResult) -> list[Path]:
    """cost_vs_<axis>.png for each axis (one line per method and per combination of the
    other axes, non-converged points marked x); status_map.png for 2-D grids (cost over
    the grid per method, non-converged cells marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plots import COLORS

    sw = result.sweep
    pts = sw.points()
    methods = sw.row_methods()
    cost = {m: np.full(sw.shape, np.nan) for m in methods}
    ok = {m: np.zeros(sw.shape, bool) for m in methods}
    done = {m: np.zeros(sw.shape, bool) for m in methods}
    for r in result.rows:
        c = pts[r["point"]].coords
        cost[r["method"]][c] = r["cost"]
        ok[r["method"]][c] = r["converged"]
        done[r["method"]][c] = True
    written = []
    for i, axis in enumerate(sw.axes):
        x, ticks = _positions(axis)
        fig, axp = plt.subplots(figsize=(6.4, 4.2))
        others = [a for j, a in enumerate(sw.axes) if j != i]
        combos = list(itertools.product(*(range(len(a.values)) for a in others)))
        for m in methods:
            c3 = np.moveaxis(cost[m], i, -1).reshape(-1, len(x))
            k3 = np.moveaxis(ok[m], i, -1).reshape(-1, len(x))
            d3 = np.moveaxis(done[m], i, -1).reshape(-1, len(x))
            for ci, combo in enumerate(combos):
                lab = m if not others else f"{m}: " + _label({a.name: a.values[j] for a, j in zip(others, combo)})
                y = np.where(k3[ci], c3[ci], np.nan)
                axp.plot(x, y, "o-" if m != "indirect" else "s--", color=COLORS.get(m) if len(combos) == 1 else f"C{ci % 10}",
                         ms=4, label=lab if len(combos) * len(methods) <= 12 else None)
                bad = d3[ci] & ~k3[ci]
                if bad.any():
                    yb = np.where(np.isfinite(c3[ci][bad]), c3[ci][bad], np.nanmin(np.where(k3[ci], c3[ci], np.nan))
                                  if k3[ci].any() else 0.0)
                    axp.plot(x[bad], yb, "x", color="k", ms=8, mew=2)
        axp.plot([], [], "x", color="k", ms=8, mew=2, label="not converged")
        if ticks:
            axp.set_xticks(x, ticks)
        axp.set_xlabel(axis.name)
        axp.set_ylabel("cost J")
        axp.set_title(f"{sw.name}: cost against {axis.name}")
        axp.grid(alpha=0.3)
        axp.legend(fontsize=7)
        written.append(_save_png(fig, Path(out) / f"cost_vs_{_safe(axis.name)}.png"))
        plt.close(fig)
    if len(sw.axes) == 2:
        fig, axs = plt.subplots(1, len(methods), figsize=(6.2 * len(methods), 4.6), squeeze=False,
                                layout="constrained")
        nx, ny = len(sw.axes[1].values), len(sw.axes[0].values)
        good = np.concatenate([cost[m][ok[m]] for m in methods])
        lims = dict(vmin=good.min(), vmax=good.max()) if good.size else {}  # one colour scale for all methods
        for axp, m in zip(axs[0], methods):
            Z = np.where(ok[m], cost[m], np.nan)
            ix, iy = np.arange(nx), np.arange(ny)
            im = axp.pcolormesh(ix, iy, np.ma.masked_invalid(Z), shading="nearest", cmap="viridis", **lims)
            fig.colorbar(im, ax=axp, label="cost J")
            bad_y, bad_x = np.nonzero(done[m] & ~ok[m])
            axp.plot(bad_x, bad_y, "x", color="r", ms=12, mew=2.5, label="not converged")
            miss_y, miss_x = np.nonzero(~done[m])
            if miss_x.size:
                axp.plot(miss_x, miss_y, "s", mfc="none", color="0.5", ms=10, label="not run")
            axp.set_xticks(ix, [_fmt(v) for v in sw.axes[1].values], rotation=45)
            axp.set_yticks(iy, [_fmt(v) for v in sw.axes[0].values])
            axp.set_xlabel(sw.axes[1].name)
            axp.set_ylabel(sw.axes[0].name)
            axp.set_title(f"{m}: {int(ok[m].sum())}/{ok[m].size} converged")
            if bad_x.size or miss_x.size:
                axp.legend(fontsize=7, loc="upper right")
        fig.suptitle(f"{sw.name}: status map")
        written.append(_save_png(fig, Path(out) / "status_map.png"))
        plt.close(fig)
    return written
