"""The YAML layer shared by every file the project reads (maneuvers, sweeps).

* :func:`read_yaml_file` / :func:`yaml_load`: the project's YAML loader.  It reads YAML 1.2
  with the core schema (``yes``/``on`` are strings, ``1:40`` and ``1_000`` are strings, ``0o17``
  and ``0x1F`` are integers, ``1e4`` is a number; no timestamps, merge keys or other tags),
  rejects duplicate keys, and bounds the input (:data:`MAX_FILE_BYTES`, :data:`MAX_DEPTH`,
  :data:`MAX_NODES`), so that any file, even a hostile one, yields a document or one
  :class:`ConfigError` in bounded time and memory.  :func:`yaml_dump` writes YAML that this
  loader and YAML 1.1 readers (``yaml.safe_load``) both read back as written.
* :class:`ConfigError`: every problem with an input file, as one line ``FILE: FIELD: what was expected``.
* :class:`Validator`: the value checks (mappings with known keys, numbers, vectors, weights,
  choices, attitudes) bound to a file name, so that every message names the file and the field.
* :func:`apply_override` / :func:`load_with_overrides`: the ``--set dotted.key=value`` overrides;
  an error about a value set by ``--set`` names ``--set``, not the file.
"""
from __future__ import annotations

import collections.abc
import math
import os
import re
from pathlib import Path
from typing import Any, Callable, Iterable, TypeVar

import numpy as np
import yaml

from ..transcription.lie import exp_so3, rot_x, rot_y, rot_z
from ..transcription.options import describe, shorten as _short, show as _show
from .physical import check_radians

T = TypeVar("T")

#: a rotation matrix given in a file must satisfy |R^T R - I|_F <= this (it is then projected onto SO(3))
ORTHOGONALITY_TOL = 1e-6
#: the largest magnitude of an integer field (a C int: IPOPT's max_iter, CasADi's sizes); a field
#: may set a smaller bound with ``Validator.number(..., integer=True, at_most=...)``
MAX_INTEGER = 2**31 - 1


# ----------------------------------------------------------------------- the loader
#: the most elementary rotations in an attitude ``{rotations: [...]}`` (bounds the work of validating one)
MAX_ROTATIONS = 64

#: Input limits.  Together they bound the work that the loader, and everything downstream that
#: walks the document, can be made to do: any file, however hostile, is parsed or rejected in
#: bounded time and memory.  A real maneuver file is about 2 kB, 5 levels deep, 100 values.
#: The largest input (a file is refused on its size, before it is read).
MAX_FILE_BYTES = 1_000_000
#: The deepest nesting of sequences and mappings.
MAX_DEPTH = 64
#: The most values (scalars, sequences, mappings) a document may hold, each alias ``*a``
#: counting as a full copy of its anchored node: stops "billion laughs" alias bombs, and
#: bounds the parse time of a file of tiny values (a sweep axis listing 10,000 values of
#: 3-vectors for two keys holds about 90,000).
MAX_NODES = 200_000

_CORE = "tag:yaml.org,2002:"
# The YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1023-core-schema) and nothing else:
# no sexagesimals (1:40), no underscores (1_000), no 0b/0777 forms, no yes/no/on/off
# booleans, no timestamps, no merge keys (<<), no !!binary/!!set/!!omap/!!python/... tags.
_NULL_RE = re.compile(r"~|null|Null|NULL|")
_BOOL_RE = re.compile(r"true|True|TRUE|false|False|FALSE")
_INT_RE = re.compile(r"[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+")
_FLOAT_RE = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                       r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN)")
#: characters YAML allows in a stream (c-printable)
_NON_PRINTABLE = re.compile("[^\x09\x0A\x0D\x20-\x7E\x85\xA0-\uD7FF\uE000-\uFFFD\U00010000-\U0010FFFF]")


class _Rejected(yaml.MarkedYAMLError):
    """A document the loader refuses (a limit, a duplicate key, an unsupported tag): its
    ``problem`` is the whole message, without the 'not valid YAML' prefix."""

    def __init__(self, message: str, mark):
        super().__init__(problem=message, problem_mark=mark)


def _null(v):
    return None


def _bool(v):
    return v.lower() == "true"


def _int(v):
    if v.startswith(("0o", "0x")):
        return int(v[2:], 8 if v[1] == "o" else 16)
    return int(v)  # ValueError beyond Python's 4300 decimal digits: see _scalar


def _float(v):
    low = v.lower()
    if low.endswith(".inf"):
        return -math.inf if low.startswith("-") else math.inf
    return math.nan if low == ".nan" else float(v)


#: tag -> (pattern, conversion, what a value of the tag looks like); str is the fallback
_SCALARS = {
    _CORE + "null": (_NULL_RE, _null, "null, ~ or nothing"),
    _CORE + "bool": (_BOOL_RE, _bool, "true or false"),
    _CORE + "int": (_INT_RE, _int, "an integer (decimal, 0o octal or 0x hexadecimal)"),
    _CORE + "float": (_FLOAT_RE, _float, "a number"),
}
_IMPLICIT = tuple(_SCALARS.items())  # tried in this order: "12" is an int, not a float
_SUPPORTED = "the YAML 1.2 core schema: !!str, !!int, !!float, !!bool, !!null, !!seq, !!map"


def _scalar(ev) -> Any:
    tag = ev.tag
    if tag is None:  # untagged: plain scalars are resolved, quoted ones are strings
        if not ev.implicit[0]:
            return ev.value
        tag = next((t for t, (rx, _c, _w) in _IMPLICIT if rx.fullmatch(ev.value)), None)
        if tag is None:
            return ev.value
    if tag in ("!", _CORE + "str"):
        return ev.value
    if tag not in _SCALARS:
        raise _Rejected(f"unsupported tag {_tag_name(tag)} ({_SUPPORTED})", ev.start_mark)
    rx, conv, what = _SCALARS[tag]
    if not rx.fullmatch(ev.value):
        raise _Rejected(f"expected {what} for the tag {_tag_name(tag)}, got {_show(ev.value)}", ev.start_mark)
    try:
        return conv(ev.value)
    except ValueError:  # an integer beyond Python's limit on decimal digits
        raise _Rejected(f"integer too long ({len(ev.value)} digits)", ev.start_mark) from None


class _Frame:
    """An open sequence or mapping while its events arrive."""

    __slots__ = ("obj", "is_map", "key", "has_key", "lines", "anchor", "start")

    def __init__(self, obj, anchor, start):
        self.obj, self.is_map, self.anchor, self.start = obj, isinstance(obj, dict), anchor, start
        self.key, self.has_key, self.lines = None, False, {}


_OPEN = object()


def _build(events) -> Any:
    """The document of a YAML event stream, built in one iterative pass (no recursion), with
    the limits, the core schema, YAML 1.2 aliases (the latest anchor of a name; an alias
    inside its own anchored node is an error) and duplicate keys rejected."""
    stack: list[_Frame] = []
    anchors: dict = {}       # name -> (value, number of values) or _OPEN while it is being read
    count, docs, root = 0, 0, None

    def add(value, mark):
        nonlocal root
        if not stack:
            root = value
            return
        top = stack[-1]
        if not top.is_map:
            top.obj.append(value)
        elif not top.has_key:
            if not isinstance(value, collections.abc.Hashable):
                raise _Rejected("a sequence or mapping cannot be a mapping key", mark)
            if value in top.obj or value in top.lines:
                raise _Rejected(f"duplicate key {_show(value)} (first given on line {top.lines[value]})", mark)
            top.key, top.has_key = value, True
            top.lines[value] = mark.line + 1
        else:
            top.obj[top.key] = value
            top.has_key = False

    def counted(n, mark):
        nonlocal count
        count += n
        if count > MAX_NODES:
            raise _Rejected(f"the document holds more than {MAX_NODES} values (each alias *name counts as a "
                            f"copy of its node); the limit is schema.MAX_NODES", mark)

    for ev in events:
        kind = type(ev)
        if kind is yaml.ScalarEvent:
            counted(1, ev.start_mark)
            value = _scalar(ev)
            if ev.anchor is not None:
                anchors[ev.anchor] = (value, 1)
            add(value, ev.start_mark)
        elif kind is yaml.SequenceStartEvent or kind is yaml.MappingStartEvent:
            if len(stack) >= MAX_DEPTH:
                raise _Rejected(f"nested more than {MAX_DEPTH} levels deep (the limit is schema.MAX_DEPTH)",
                                ev.start_mark)
            want = _CORE + ("seq" if kind is yaml.SequenceStartEvent else "map")
            if ev.tag not in (None, "!", want):
                raise _Rejected(f"unsupported tag {_tag_name(ev.tag)} ({_SUPPORTED})", ev.start_mark)
            counted(1, ev.start_mark)
            if ev.anchor is not None:
                anchors[ev.anchor] = _OPEN
            stack.append(_Frame([] if kind is yaml.SequenceStartEvent else {}, ev.anchor, count - 1))
        elif kind is yaml.SequenceEndEvent or kind is yaml.MappingEndEvent:
            f = stack.pop()
            if f.anchor is not None and anchors.get(f.anchor) is _OPEN:
                anchors[f.anchor] = (f.obj, count - f.start)
            add(f.obj, ev.start_mark)
        elif kind is yaml.AliasEvent:
            entry = anchors.get(ev.anchor)
            if entry is None:
                raise _Rejected(f"alias *{_short(ev.anchor)} has no anchor &{_short(ev.anchor)} before it",
                                ev.start_mark)
            if entry is _OPEN:
                raise _Rejected(f"alias *{_short(ev.anchor)} is inside its own anchored node (a recursive "
                                f"structure)", ev.start_mark)
            counted(entry[1], ev.start_mark)
            add(entry[0], ev.start_mark)
        elif kind is yaml.DocumentStartEvent:
            docs += 1
            if docs > 1:
                raise _Rejected("expected one YAML document, found a second one (---)", ev.start_mark)
    return root


class _PyParser(yaml.reader.Reader, yaml.scanner.Scanner, yaml.parser.Parser):
    """PyYAML's pure-Python scanner and parser: the event source without libyaml."""

    def __init__(self, stream):
        yaml.reader.Reader.__init__(self, stream)
        yaml.scanner.Scanner.__init__(self)
        yaml.parser.Parser.__init__(self)


try:  # libyaml's C parser when PyYAML was built with it (same events, about 10 times faster)
    from yaml.cyaml import CParser as _CParser
except ImportError:  # pragma: no cover - depends on the PyYAML build
    _CParser = None
#: the event source: libyaml's parser if available, else PyYAML's (the tests run both)
_Parser = _CParser or _PyParser


def _events(parser):
    while parser.check_event():
        yield parser.get_event()


class ConfigError(ValueError):
    """Invalid input: ``str(err)`` is one line ``SOURCE: FIELD: MESSAGE`` (non-printable
    characters in any part are escaped, so a hostile file name or value cannot break the line)."""

    def __init__(self, source: str, fieldname: str, message: str):
        self.source, self.field, self.detail = source, fieldname, message
        super().__init__(f"{_one_line(source)}: {_one_line(fieldname) or '<document>'}: {_one_line(message)}")


def _one_line(text) -> str:
    text = str(text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


def _size_limit() -> str:
    return f"the limit is {MAX_FILE_BYTES} bytes = {MAX_FILE_BYTES / 1e6:g} MB, schema.MAX_FILE_BYTES"


def _tag_name(tag: str) -> str:
    return "!!" + tag[len(_CORE):] if tag.startswith(_CORE) else tag


def _position(mark) -> str:
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""


class _TextError(Exception):
    """A problem with YAML text: ``where`` ('line L, column C' or ''), ``message``."""

    def __init__(self, where: str, message: str):
        super().__init__(message)
        self.where, self.message = where, message


def _yaml_problem(e: yaml.YAMLError) -> tuple[str, str]:
    """(position, message) of a PyYAML error, on one line."""
    if isinstance(e, _Rejected):
        return _position(e.problem_mark), e.problem
    if isinstance(e, yaml.MarkedYAMLError):
        msg = e.problem or e.context or "syntax error"
        if e.problem and e.context:
            cm = e.context_mark
            at = f" that starts on line {cm.line + 1}, column {cm.column + 1}" if cm is not None else ""
            msg = f"{e.problem} {e.context}{at}" if e.context.startswith("while") else f"{e.problem}; {e.context}"
        return _position(e.problem_mark), f"not valid YAML ({msg})"
    return "", f"not valid YAML ({str(e).splitlines()[0] if str(e) else type(e).__name__})"


def _check_text(text: str) -> None:
    if len(text) > MAX_FILE_BYTES or len(text.encode("utf-8", "surrogatepass")) > MAX_FILE_BYTES:
        raise _TextError("", f"too large ({len(text.encode('utf-8', 'surrogatepass'))} bytes; {_size_limit()})")
    m = _NON_PRINTABLE.search(text)
    if m:
        line = text.count("\n", 0, m.start()) + 1
        col = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
        raise _TextError(f"line {line}, column {col}",
                         f"not YAML text: the character U+{ord(m.group()):04X} is not allowed in YAML (control "
                         f"characters such as NUL are not)")


def _parse(text: str) -> Any:
    """Parse one YAML document with the project's loader; raises _TextError."""
    _check_text(text)
    parser = _Parser(text)
    try:
        return _build(_events(parser))
    except yaml.YAMLError as e:
        raise _TextError(*_yaml_problem(e)) from None
    finally:
        parser.dispose()


def _decode(data: bytes) -> str:
    """UTF-8 text of a file (a UTF-8 byte-order mark is allowed); raises _TextError."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise _TextError("line 1, column 1", "not UTF-8 text (it starts with a UTF-16 or UTF-32 byte-order "
                                            "mark); save the file as UTF-8")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        head = data[:e.start]
        line = head.count(b"\n") + 1
        col = len(head[head.rfind(b"\n") + 1:].decode("utf-8", "replace")) + 1
        raise _TextError(f"line {line}, column {col}",
                         f"not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start})") from None


def yaml_load(text: str, source: str = "<string>") -> Any:
    """Parse YAML text with the project's loader (YAML 1.2 core schema, limits, no duplicate
    keys); any problem is a :class:`ConfigError` naming ``source`` and the line and column."""
    try:
        return _parse(text)
    except _TextError as e:
        raise ConfigError(source, e.where, e.message) from None


def read_yaml_file(path: str | Path) -> Any:
    """Read and parse a YAML file.  Unreadable, too large (> :data:`MAX_FILE_BYTES`, refused
    before reading), non-UTF-8 and invalid files become one-line :class:`ConfigError` naming
    the file and, where there is one, the line and column."""
    source = str(path)
    size = 0
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            # special files (pipes, /dev/zero) report no size: read one byte more than allowed
            data = f.read(MAX_FILE_BYTES + 1) if size <= MAX_FILE_BYTES else b""
    except OSError as e:
        raise ConfigError(source, "", f"cannot read file ({e.strerror or e})") from None
    except ValueError as e:  # a path with a NUL byte
        raise ConfigError(source, "", f"cannot read file ({e})") from None
    if size > MAX_FILE_BYTES:
        raise ConfigError(source, "", f"file too large ({size} bytes; {_size_limit()})")
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(source, "", f"file too large ({_size_limit()})")
    try:
        return _parse(_decode(data))
    except _TextError as e:
        raise ConfigError(source, e.where, e.message) from None


class _DumpResolver(yaml.resolver.BaseResolver):
    """Plain scalars that YAML 1.2 (this loader) *or* YAML 1.1 (``yaml.safe_load``) would read
    as something other than a string get quoted."""


for _tag, (_rx, _, _) in _IMPLICIT:
    _DumpResolver.add_implicit_resolver(_tag, re.compile(rf"^(?:{_rx.pattern})$"), list("~nNtTfF-+0123456789.") + [""])
for _ch, _lst in yaml.resolver.Resolver.yaml_implicit_resolvers.items():
    for _tag, _rx in _lst:
        _DumpResolver.add_implicit_resolver(_tag, _rx, [_ch])


class _Dumper(yaml.emitter.Emitter, yaml.serializer.Serializer, yaml.representer.SafeRepresenter, _DumpResolver):
    def __init__(self, stream, **kw):
        yaml.emitter.Emitter.__init__(self, stream, allow_unicode=True, width=kw.get("width"))
        yaml.serializer.Serializer.__init__(self)
        yaml.representer.SafeRepresenter.__init__(self, sort_keys=kw.get("sort_keys", False))
        _DumpResolver.__init__(self)

    def ignore_aliases(self, data):  # results files are read by people: no &id001 / *id001
        return True

    def represent_str(self, data):
        # non-printables, among them the line breaks NEL, LS and PS, only survive in double quotes
        if not data.replace("\n", "").isprintable():
            return self.represent_scalar(_CORE + "str", data, style='"')
        return super().represent_str(data)


_Dumper.add_representer(str, _Dumper.represent_str)


def yaml_dump(obj: Any) -> str:
    """YAML text of plain data (dict/list/str/int/float/bool/None) that :func:`yaml_load`
    and ``yaml.safe_load`` both read back as ``obj``: strings such as ``yes``, ``0o17`` or
    ``1e4`` are quoted, keys keep their order."""
    return yaml.dump(obj, Dumper=_Dumper, sort_keys=False)


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

    def unit_vector(self, v, where) -> np.ndarray:
        """A direction given as 3 numbers, normalized; only an exactly zero vector is rejected
        (tiny and huge components are scaled first, so neither underflows nor overflows)."""
        return _unit(self, self.vec3(v, where), where, "expected a non-zero vector (it is normalized)")

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
            a = np.array([self.number(x, f"{w}[{i}]") for i, x in enumerate(val)])
            axis = _unit(self, a[:3], w, "expected a non-zero rotation axis")
            check_radians(self, a[3], f"{w}[3]")
            # the angle modulo 360 degrees (exact): large angles keep their accuracy
            return np.asarray(exp_so3(axis * np.deg2rad(math.fmod(a[3], 360.0))))
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


def _unit(v: Validator, a: np.ndarray, where: str, msg: str) -> np.ndarray:
    """a / |a| computed without overflow or underflow (scaled by max |a_i| first)."""
    scale = float(np.max(np.abs(a)))
    if scale == 0.0:
        v.fail(where, msg)
    u = a / scale
    return u / np.linalg.norm(u)


def join_field(where, key):
    key = _short(str(key))
    if not key.isprintable() or not key or any(ch in key for ch in " .[]"):
        key = repr(key)  # keep messages on one line and unambiguous
    return f"{where}.{key}" if where else key


# ----------------------------------------------------------------- overrides
def apply_override(doc: dict, assignment: str, source: str = "--set") -> str:
    """Apply ``dotted.key=value`` (the value parsed as YAML, with the loader's limits) to
    ``doc`` in place; returns the dotted key.  Every problem is a one-line ConfigError whose
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
    return key


def blame_overrides(err: ConfigError, keys: Iterable[str], source: str = "--set") -> ConfigError:
    """``err`` re-attributed to ``source`` when its field is a key set by an override (or
    lies under one: ``initial.position[1]`` under ``initial.position``); else ``err``."""
    f = err.field or ""
    for k in keys:
        if f == k or f.startswith((k + ".", k + "[")):
            return ConfigError(source, f, err.detail)
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
