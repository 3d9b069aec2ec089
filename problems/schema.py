"""The YAML layer shared by every file the project reads (maneuvers, sweeps).

* :func:`yaml_load` / :func:`read_yaml_file`: the project's YAML loader (YAML 1.2 numbers).
* :class:`ConfigError`: every problem with an input file, as one line ``FILE: FIELD: what was expected``.
* :class:`Validator`: the value checks (mappings with known keys, numbers, vectors, weights,
  choices, attitudes) bound to a file name, so that every message names the file and the field.
* :func:`apply_override`: the ``--set dotted.key=value`` overrides.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..transcription.lie import exp_so3, rot_x, rot_y, rot_z

#: a rotation matrix given in a file must satisfy |R^T R - I|_F <= this (it is then projected onto SO(3))
ORTHOGONALITY_TOL = 1e-6


class _Loader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 floats: ``1e4`` and ``1.0e4`` are numbers (PyYAML's
    YAML 1.1 rule would read them as strings)."""


_Loader.yaml_implicit_resolvers = {k: list(v) for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}
for _ch in "-+0123456789.":
    _Loader.yaml_implicit_resolvers[_ch] = [
        (tag, rx) for tag, rx in _Loader.yaml_implicit_resolvers.get(_ch, []) if tag != "tag:yaml.org,2002:float"
    ]
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def yaml_load(text: str):
    """Parse YAML text with the project's loader (YAML 1.2 floats)."""
    return yaml.load(text, Loader=_Loader)


class ConfigError(ValueError):
    """Invalid maneuver file: ``str(err)`` is ``FILE: FIELD: expected ...``."""

    def __init__(self, source: str, fieldname: str, message: str):
        self.source, self.field, self.detail = source, fieldname, message
        super().__init__(f"{source}: {fieldname or '<document>'}: {message}")


# ----------------------------------------------------------------- validators
class Validator:
    """Validation helpers bound to a file name: each check returns the parsed value or raises
    ConfigError("FILE: FIELD: expected ..."). Shared by the maneuver and sweep schemas."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, msg: str):
        raise ConfigError(self.source, where, msg)

    def mapping(self, d, where, allowed, required=()):
        if not isinstance(d, dict):
            self.fail(where, f"expected a mapping with keys {sorted(allowed)}, got {describe(d)}")
        for k in d:
            if not isinstance(k, str) or k not in allowed:
                self.fail(join_field(where, k), f"unknown key; allowed keys here: {', '.join(sorted(allowed))}")
        for k in required:
            if k not in d:
                self.fail(join_field(where, k), "missing required key")
        return d

    def number(self, v, where, *, positive=False, nonneg=False, integer=False, lo=None, hi=None):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(where, f"expected {'an integer' if integer else 'a number'}, got {describe(v)}")
        if integer and not (isinstance(v, int) or float(v).is_integer()):
            self.fail(where, f"expected an integer, got {v!r}")
        if not math.isfinite(v):
            self.fail(where, f"expected a finite number, got {v!r}")
        if positive and not v > 0:
            self.fail(where, f"expected a positive {'integer' if integer else 'number'}, got {v!r}")
        if nonneg and v < 0:
            self.fail(where, f"expected a non-negative number, got {v!r}")
        if lo is not None and not v > lo:
            self.fail(where, f"expected a number > {lo}, got {v!r}")
        if hi is not None and not v < hi:
            self.fail(where, f"expected a number < {hi}, got {v!r}")
        return int(v) if integer else float(v)

    def vec3(self, v, where):
        if not isinstance(v, (list, tuple)) or len(v) != 3:
            self.fail(where, f"expected a list of 3 numbers, got {describe(v)}")
        return np.array([self.number(a, f"{where}[{i}]") for i, a in enumerate(v)])

    def weights(self, v, where):
        if isinstance(v, (list, tuple)):
            w = self.vec3(v, where)
            for i, a in enumerate(w):
                if not a > 0:
                    self.fail(f"{where}[{i}]", f"expected a positive weight, got {float(a)!r}")
            return w
        return np.full(3, self.number(v, where, positive=True))

    def choice(self, v, where, options):
        if not isinstance(v, str) or v not in options:
            self.fail(where, f"expected one of {', '.join(options)}, got {describe(v)}")
        return v

    def attitude(self, v, where) -> np.ndarray:
        if v == "identity":
            return np.eye(3)
        forms = "'identity', {matrix: 3x3}, {axis_angle: [ax, ay, az, deg]} or {rotations: [[x|y|z, deg], ...]}"
        if not isinstance(v, dict) or len(v) != 1:
            self.fail(where, f"expected one of {forms}, got {describe(v)}")
        (kind, val), = v.items()
        w = join_field(where, kind)
        if kind == "matrix":
            if not isinstance(val, (list, tuple)) or len(val) != 3:
                self.fail(w, f"expected a 3x3 matrix as 3 rows of 3 numbers, got {describe(val)}")
            R = np.array([self.vec3(r, f"{w}[{i}]") for i, r in enumerate(val)])
            err = np.linalg.norm(R.T @ R - np.eye(3))
            if err > ORTHOGONALITY_TOL or np.linalg.det(R) <= 0:
                self.fail(w, f"expected a rotation matrix (|R^T R - I| <= {ORTHOGONALITY_TOL:g}, det R = +1); "
                             f"got |R^T R - I| = {err:.3g}, det R = {np.linalg.det(R):.6g}")
            Uu, _, Vt = np.linalg.svd(R)
            return Uu @ Vt
        if kind == "axis_angle":
            if not isinstance(val, (list, tuple)) or len(val) != 4:
                self.fail(w, f"expected [ax, ay, az, angle_deg], got {describe(val)}")
            a = np.array([self.number(x, f"{w}[{i}]") for i, x in enumerate(val)])
            n = np.linalg.norm(a[:3])
            if n == 0:
                self.fail(w, "expected a non-zero rotation axis")
            return np.asarray(exp_so3(a[:3] / n * np.deg2rad(a[3])))
        if kind == "rotations":
            if not isinstance(val, (list, tuple)) or not val:
                self.fail(w, f"expected a non-empty list of [x|y|z, deg] pairs, got {describe(val)}")
            R = np.eye(3)
            elem = {"x": rot_x, "y": rot_y, "z": rot_z}
            for i, pair in enumerate(val):
                if not isinstance(pair, (list, tuple)) or len(pair) != 2 or not isinstance(pair[0], str) or pair[0] not in elem:
                    self.fail(f"{w}[{i}]", f"expected a pair [x|y|z, angle_deg], got {describe(pair)}")
                R = R @ elem[pair[0]](self.number(pair[1], f"{w}[{i}][1]"))
            return R
        self.fail(where, f"unknown attitude form {kind!r}; expected one of {forms}")


def join_field(where, key):
    key = str(key)
    if not key.isprintable() or not key or any(ch in key for ch in " .[]"):
        key = repr(key)  # keep messages on one line and unambiguous
    return f"{where}.{key}" if where else key


def describe(v) -> str:
    if v is None:
        return "nothing (null)"
    if isinstance(v, bool):
        return f"a boolean ({v})"
    if isinstance(v, str):
        return f"the string {v!r}"
    if isinstance(v, dict):
        return "a mapping"
    if isinstance(v, (list, tuple)):
        return f"a list of length {len(v)}"
    return f"{type(v).__name__} {v!r}"



def apply_override(doc: dict, assignment: str, source: str = "--set") -> None:
    """Apply ``dotted.key=value`` (value parsed as YAML) to ``doc`` in place."""
    if "=" not in assignment:
        raise ConfigError(source, assignment, "expected KEY=VALUE, e.g. horizon.N=1000")
    key, _, text = assignment.partition("=")
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise ConfigError(source, assignment, "expected a dotted key before '='")
    try:
        value = yaml_load(text)
    except yaml.YAMLError as e:
        raise ConfigError(source, key, f"value is not valid YAML: {str(e).splitlines()[0]}") from None
    node = doc
    for p in parts[:-1]:
        if not isinstance(node.get(p), dict):
            node[p] = {}
        node = node[p]
    node[parts[-1]] = value


def read_yaml_file(path: str | Path) -> Any:
    """Read and parse a YAML file; unreadable files and syntax errors become ConfigError
    naming the file (and the line and column of a syntax error)."""
    source = str(path)
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ConfigError(source, "", f"cannot read file ({e.strerror or e})") from None
    try:
        return yaml_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ConfigError(source, where, f"not valid YAML ({getattr(e, 'problem', None) or e})") from None
