"""The project's YAML reader and writer, shared by every file the project reads and writes.

* :func:`read_yaml_file` / :func:`yaml_load`: the project's YAML loader.  It reads YAML 1.2
  with the core schema (``yes``/``on`` are strings, ``1:40`` and ``1_000`` are strings, ``0o17``
  and ``0x1F`` are integers, ``1e4`` is a number; no timestamps, merge keys or other tags),
  rejects duplicate keys, and bounds the input (:data:`MAX_FILE_BYTES`, :data:`MAX_DEPTH`,
  :data:`MAX_NODES`), so that any file, even a hostile one, yields a document or one
  :class:`ConfigError` in bounded time and memory.
* :func:`yaml_dump` writes YAML that this loader and YAML 1.1 readers (``yaml.safe_load``) both
  read back as written.
* :class:`ConfigError`: every problem with an input file, as one line ``FILE: FIELD: what was expected``.

The values in a document are checked by :mod:`problems.schema` (the Validator).
"""
from __future__ import annotations

import collections.abc
import math
import os
import re
from pathlib import Path
from typing import Any

import yaml

from ..transcription.options import shorten as _short, show as _show

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
                            f"copy of its node); the limit is yamlfile.MAX_NODES", mark)

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
                raise _Rejected(f"nested more than {MAX_DEPTH} levels deep (the limit is yamlfile.MAX_DEPTH)",
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

    def __init__(self, source: str, fieldname: str, message: str, also: tuple[str, ...] = ()):
        #: also: the other fields the check involved (a --set on any of them is named as the cause)
        self.source, self.field, self.detail, self.also = source, fieldname, message, tuple(also)
        super().__init__(f"{_one_line(source)}: {_one_line(fieldname) or '<document>'}: {_one_line(message)}")


def _one_line(text) -> str:
    text = str(text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


def _size_limit() -> str:
    return f"the limit is {MAX_FILE_BYTES} bytes = {MAX_FILE_BYTES / 1e6:g} MB, yamlfile.MAX_FILE_BYTES"


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
