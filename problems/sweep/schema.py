"""The sweep file: its schema (see the package docstring), the grid it spans (:class:`Axis`,
:class:`Point`, :class:`Sweep`), and its validation -- the file, then every grid point's maneuver
-- before any solve."""
from __future__ import annotations

import copy
import itertools
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ...transcription.strategy.refine import out_of_reach
from ...transcription.solve import not_covered
from ..maneuvers import Maneuver, load_maneuver, parse_maneuver
from ..schema import ConfigError, Validator, apply_override, blame_overrides, describe, join_field, read_yaml_file

SWEEP_KEYS = ("name", "base", "set", "axes", "methods", "continuation", "continuation_axis")
METHODS = ("direct", "indirect")
RANGE_FORMS = ("linspace", "geomspace")
#: the result columns after ``point``, ``method`` and one column per axis
RESULT_COLUMNS = ("status", "converged", "cost", "terminal_error", "iterations", "iterations_total",
                  "build_s", "solve_s", "warm_started", "start", "message")
#: limits that keep a typo from expanding into millions of solves, and bound the validation of the
#: grid (every point's maneuver is validated before any solve: about 1-3 ms a point, so at most
#: some 10-30 s, with a progress line every second, for the largest grid)
MAX_AXIS_VALUES = 10_000
MAX_GRID_POINTS = 10_000


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
    reason = next(filter(None, (not_covered(base_man.problem, m) for m in sw.methods)), "")
    if reason:                                      # which methods solve which problems: decided there
        raise ConfigError(source, "methods", f"{reason} (methods: [direct])")
    reason = out_of_reach(base_man.problem, base_man.accuracy)   # solver.accuracy: the N it needs, said at once
    if reason:
        raise ConfigError(source, "base", f"solver.{base_man.accuracy.tolerance_key}: {reason}")
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
