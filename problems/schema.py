"""The values of the files the project reads (maneuvers, sweeps), and the ``--set`` overrides.

* :class:`Validator`: the value checks (mappings with known keys, numbers, vectors, directions,
  weights, choices, attitudes) bound to a file name, so that every message names the file and the
  field (a check that involves several fields names the others too: ``fail(..., also=...)``).
* :func:`apply_override` / :func:`load_with_overrides`: the ``--set dotted.key=value`` overrides;
  an error about a value set by ``--set`` -- or caused by one -- names ``--set``, not the file.

The YAML reader and writer, and :class:`ConfigError`, live in :mod:`problems.yamlfile` (re-exported here).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Iterable, TypeVar

import numpy as np

from ..transcription.geometry.so3 import exp_so3, rot_x, rot_y, rot_z, unit_direction
from ..transcription.options import describe, shorten as _short, show as _show
from .physical import check_radians
from .yamlfile import (MAX_DEPTH, MAX_FILE_BYTES, MAX_NODES, ConfigError, _parse, _TextError, read_yaml_file, yaml_dump, yaml_load)

T = TypeVar("T")

#: a rotation matrix given in a file must satisfy |R^T R - I|_F <= this (it is then projected onto SO(3))
ORTHOGONALITY_TOL = 1e-6
#: the largest magnitude of an integer field (a C int: IPOPT's max_iter, CasADi's sizes); a field
#: may set a smaller bound with ``Validator.number(..., integer=True, at_most=...)``
MAX_INTEGER = 2**31 - 1
#: the most elementary rotations in an attitude ``{rotations: [...]}`` (bounds the work of validating one)
MAX_ROTATIONS = 64


# ----------------------------------------------------------------- validators
class Validator:
    """Validation helpers bound to a file name: each check returns the parsed value or raises
    ConfigError("FILE: FIELD: expected ..."). Shared by the maneuver and sweep schemas."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, msg: str, also: tuple[str, ...] = ()):
        """Raise ConfigError naming ``where``; ``also``: the other fields the check involved."""
        raise ConfigError(self.source, where, msg, also)

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

    def number(self, v, where, *, positive=False, nonneg=False, integer=False, lo=None, hi=None, at_most=None):
        """A finite number (``integer``: an integer, also given as 3.0, within +-``at_most``
        (default and cap :data:`MAX_INTEGER`)); ``lo < v < hi`` when given.  Returns float or int."""
        kind = "an integer" if integer else "a number"
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(where, f"expected {kind}, got {describe(v)}")
        if isinstance(v, float) and not math.isfinite(v):
            self.fail(where, f"expected a finite number, got {v!r}")
        if integer:
            if isinstance(v, float) and not v.is_integer():
                self.fail(where, f"expected an integer, got {v!r}")
            cap = MAX_INTEGER if at_most is None else min(int(at_most), MAX_INTEGER)
            if not -MAX_INTEGER <= v <= cap:
                bound = f"<= {cap}" if v > 0 else f">= {-MAX_INTEGER}"
                self.fail(where, f"expected an integer {bound}, got {_show(v)}")
            v = int(v)
        elif isinstance(v, int):
            try:
                float(v)
            except OverflowError:
                self.fail(where, f"expected a finite number, got an integer too large for a float ({_short(v)})")
        if positive and not v > 0:
            self.fail(where, f"expected a positive {'integer' if integer else 'number'}, got {_show(v)}")
        if nonneg and v < 0:
            self.fail(where, f"expected a non-negative number, got {_show(v)}")
        if lo is not None and not v > lo:
            self.fail(where, f"expected a number > {lo}, got {_show(v)}")
        if hi is not None and not v < hi:
            self.fail(where, f"expected a number < {hi}, got {_show(v)}")
        return v if integer else float(v)

    def boolean(self, v, where) -> bool:
        """true or false (YAML 1.2: ``yes``/``no``/``on``/``off`` are strings, and the message says so)."""
        if not isinstance(v, bool):
            hint = ""
            if isinstance(v, str) and v.lower() in ("yes", "no", "on", "off", "y", "n"):
                hint = " (YAML 1.2 reads yes/no/on/off as strings)"
            self.fail(where, f"expected true or false, got {describe(v)}{hint}")
        return v

    def unit_vector(self, v, where, msg: str = "expected a non-zero vector (it is normalized)") -> np.ndarray:
        """A direction given as 3 numbers, normalized by :func:`~transcription.geometry.so3.unit_direction`:
        only an exactly zero vector is rejected (tiny and huge components are scaled first, so that
        neither underflows nor overflows).  Every direction of a file is read here."""
        u = unit_direction(self.vec3(v, where))
        if u is None:
            self.fail(where, msg)
        return u

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
            with np.errstate(all="ignore"):  # huge entries: inf/nan below, and a message, not a warning
                err = np.linalg.norm(R.T @ R - np.eye(3))
                det = np.linalg.det(R) if np.all(np.abs(R) < 1e100) else math.nan
            if not (err <= ORTHOGONALITY_TOL and det > 0):
                self.fail(w, f"expected a rotation matrix (|R^T R - I| <= {ORTHOGONALITY_TOL:g}, det R = +1); "
                             f"got |R^T R - I| = {err:.3g}, det R = {det:.6g}")
            Uu, _, Vt = np.linalg.svd(R)
            return Uu @ Vt
        if kind == "axis_angle":
            if not isinstance(val, (list, tuple)) or len(val) != 4:
                self.fail(w, f"expected [ax, ay, az, angle_deg], got {describe(val)}")
            angle = self.number(val[3], f"{w}[3]")
            axis = self.unit_vector(val[:3], w, "expected a non-zero rotation axis")
            check_radians(self, angle, f"{w}[3]")
            # the angle modulo 360 degrees (exact): large angles keep their accuracy
            return np.asarray(exp_so3(axis * np.deg2rad(math.fmod(angle, 360.0))))
        if kind == "rotations":
            if not isinstance(val, (list, tuple)) or not val:
                self.fail(w, f"expected a non-empty list of [x|y|z, deg] pairs, got {describe(val)}")
            if len(val) > MAX_ROTATIONS:
                self.fail(w, f"expected at most {MAX_ROTATIONS} rotations (schema.MAX_ROTATIONS), got {len(val)}")
            R = np.eye(3)
            elem = {"x": rot_x, "y": rot_y, "z": rot_z}
            for i, pair in enumerate(val):
                if not isinstance(pair, (list, tuple)) or len(pair) != 2 or not isinstance(pair[0], str) or pair[0] not in elem:
                    self.fail(f"{w}[{i}]", f"expected a pair [x|y|z, angle_deg], got {describe(pair)}")
                angle = self.number(pair[1], f"{w}[{i}][1]")
                check_radians(self, angle, f"{w}[{i}][1]")
                R = R @ elem[pair[0]](angle)
            return R
        self.fail(where, f"unknown attitude form {kind!r}; expected one of {forms}")


def join_field(where, key):
    key = _short(str(key))
    if not key.isprintable() or not key or any(ch in key for ch in " .[]"):
        key = repr(key)  # keep messages on one line and unambiguous
    return f"{where}.{key}" if where else key


# ----------------------------------------------------------------- overrides
def apply_override(doc: dict, assignment: str, source: str = "--set") -> str:
    """Apply ``dotted.key=value`` (the value parsed as YAML, with the loader's limits) to
    ``doc`` in place; returns the key as the Validator names that field.  Every problem is a one-line ConfigError whose
    source is ``source`` (``--set``), never the file."""
    if "=" not in assignment:
        raise ConfigError(source, assignment, "expected KEY=VALUE, e.g. horizon.N=1000")
    key, _, text = assignment.partition("=")
    key = key.strip()
    parts = key.split(".")
    if not key:
        raise ConfigError(source, assignment, "expected a dotted key before '='")
    if not all(parts):
        raise ConfigError(source, key, "expected a dotted key such as horizon.N (an empty part between dots)")
    if any(p.endswith("]") and "[" in p for p in parts):
        raise ConfigError(source, key, "expected a dotted key of mapping keys: --set cannot index a list; give the "
                                       "whole list, e.g. constraints=[{kind: min_radius, radius: 1.1}]")
    try:
        value = _parse(text)
    except _TextError as e:
        raise ConfigError(source, key, f"invalid value{f' ({e.where} of the value)' if e.where else ''}: {e.message}") from None
    if not isinstance(doc, dict):
        raise ConfigError(source, key, f"cannot set a key: the document is {describe(doc)}, not a mapping")
    node = doc
    for p in parts[:-1]:
        child = node.get(p)
        # a copy of each mapping on the path: a node shared through a YAML alias (&a ... *a)
        # is changed only where the override points; a non-mapping is replaced
        node[p] = dict(child) if isinstance(child, dict) else {}
        node = node[p]
    node[parts[-1]] = value
    field = ""
    for p in parts:  # the key as the Validator names it (a part such as 'constraints[0]' quoted)
        field = join_field(field, p)
    return field


def _under(a: str, b: str) -> bool:
    """Field ``a`` is ``b`` or lies inside it (``initial.position[1]`` inside ``initial``)."""
    return a == b or a.startswith((b + ".", b + "["))


def blame_overrides(err: ConfigError, keys: Iterable[str], source: str = "--set") -> ConfigError:
    """``err`` re-attributed to ``source`` when an override caused it: its field was set by one
    (or lies inside a key set: ``initial.position[1]``), a key set lies inside its field (``initial``
    after ``--set initial.velocity=...``), or a key set is one of the other fields the check
    involved (``err.also``: the time objective given by ``--set`` makes the file's fixed T an error;
    the message then says which key).  Else ``err`` unchanged."""
    keys = [k for k in keys if k]
    f = err.field or ""
    if f and any(_under(f, k) or _under(k, f) for k in keys):
        return ConfigError(source, f, err.detail, err.also)
    cause = [k for k in keys if any(_under(k, g) or _under(g, k) for g in err.also if g)]
    if cause:
        return ConfigError(source, f, f"{err.detail} (with {', '.join(cause)} given by --set)", err.also)
    return err


def load_with_overrides(path: str | Path, overrides: Iterable[str], parse: Callable[[Any, str], T]) -> T:
    """Read the YAML file ``path`` (an empty file is an empty mapping), apply the ``--set``
    overrides in order, then ``parse(doc, str(path))``.  A ConfigError about a field that an
    override set names ``--set`` instead of the file (:func:`blame_overrides`)."""
    source = str(path)
    doc = read_yaml_file(path)
    if doc is None:
        doc = {}
    keys = []
    if isinstance(doc, dict):
        for a in overrides:
            keys.append(apply_override(doc, a))
    try:
        return parse(doc, source)
    except ConfigError as e:
        raise blame_overrides(e, keys) from None


__all__ = ["MAX_DEPTH", "MAX_FILE_BYTES", "MAX_INTEGER", "MAX_NODES", "MAX_ROTATIONS", "ORTHOGONALITY_TOL", "ConfigError",
           "Validator", "apply_override", "blame_overrides", "describe", "join_field", "load_with_overrides",
           "read_yaml_file", "yaml_dump", "yaml_load"]
