"""The YAML layer (problems/yamlfile.py, problems/schema.py) against hostile input: every bad file or --set value is
one ConfigError line, bounded by the loader's limits; YAML 1.2 core schema; Validator edge cases."""
from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from se3ocp.problems import yamlfile
from se3ocp.problems.schema import (MAX_DEPTH, MAX_INTEGER, ConfigError, Validator, apply_override, blame_overrides, describe, load_with_overrides, read_yaml_file, yaml_dump, yaml_load)
from se3ocp.transcription.geometry.so3 import exp_so3

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
E3 = CONFIGS / "e3_inclination_change.yaml"

#: the event sources the loader can use: libyaml's C parser (if PyYAML has it) and PyYAML's own
PARSERS = [p for p in (yamlfile._CParser, yamlfile._PyParser) if p is not None]


@pytest.fixture(params=PARSERS, ids=lambda p: p.__name__)
def parser(request, monkeypatch):
    """Run the test with each event source: the checks must not depend on which one is used."""
    monkeypatch.setattr(yamlfile, "_Parser", request.param)
    return request.param


def one_line(err: ConfigError, source: str) -> str:
    msg = str(err)
    assert "\n" not in msg and "\r" not in msg, msg
    assert msg.startswith(f"{source}: "), msg
    assert len(msg) < 400, msg
    return msg


def load_file(tmp_path, data: bytes, name="f.yaml"):
    p = tmp_path / name
    p.write_bytes(data)
    return read_yaml_file(p), str(p)


def file_error(tmp_path, data: bytes, name="f.yaml") -> str:
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(ConfigError) as ei:
        read_yaml_file(p)
    return one_line(ei.value, str(p))


# ----------------------------------------------------------------------------- encoding
def test_non_utf8_names_line_column_byte_and_offset(tmp_path, parser):
    msg = file_error(tmp_path, b"name: x\nmodel: {kind: \xc3\xa9\xff}\n")
    # line 2: 'model: {kind: ' is 14 characters, 'é' one more (two bytes), then the bad byte
    assert msg.endswith(": line 2, column 16: not UTF-8 text (byte 0xff at offset 24)"), msg


def test_binary_file_is_one_line(tmp_path, parser):
    msg = file_error(tmp_path, bytes(range(256)) * 4)
    # bytes 0-127 decode (byte 10 is a newline); byte 128 = 0x80 is the first that is not UTF-8
    assert msg.endswith(": line 2, column 118: not UTF-8 text (byte 0x80 at offset 128)"), msg


def test_nul_byte_is_one_line_with_position(tmp_path, parser):
    msg = file_error(tmp_path, b"name: x\nhorizon: {T: 1,\x00 N: 2}\n")
    assert msg.endswith(": line 2, column 16: not YAML text: the character U+0000 is not allowed in YAML "
                        "(control characters such as NUL are not)"), msg


def test_utf16_is_refused_with_advice_and_utf8_bom_is_accepted(tmp_path, parser):
    msg = file_error(tmp_path, "a: 1\n".encode("utf-16"))
    assert "byte-order mark" in msg and "save the file as UTF-8" in msg
    doc, _ = load_file(tmp_path, "a: 1\n".encode("utf-8-sig"))
    assert doc == {"a": 1}


# ----------------------------------------------------------------------------- limits
def test_size_limit_refuses_before_reading(tmp_path):
    p = tmp_path / "big.yaml"
    with open(p, "wb") as f:  # 50 MB of NUL bytes: reading it would report the NUL, not the size
        f.truncate(50_000_000)
    with pytest.raises(ConfigError) as ei:
        read_yaml_file(p)
    msg = one_line(ei.value, str(p))
    assert msg == f"{p}: <document>: file too large (50000000 bytes; the limit is 1000000 bytes = 1 MB, yamlfile.MAX_FILE_BYTES)"


def test_size_limit_bounds_reading_files_without_a_size():
    with pytest.raises(ConfigError) as ei:
        read_yaml_file("/dev/zero")  # endless: only MAX_FILE_BYTES + 1 bytes are read
    assert one_line(ei.value, "/dev/zero").endswith("file too large (the limit is 1000000 bytes = 1 MB, "
                                                    "yamlfile.MAX_FILE_BYTES)")


def test_size_limit_applies_to_text_and_is_exact(monkeypatch):
    monkeypatch.setattr(yamlfile, "MAX_FILE_BYTES", 20)
    assert yaml_load("a: '" + "x" * 14 + "'") == {"a": "x" * 14}  # 20 bytes
    with pytest.raises(ConfigError, match="too large \\(21 bytes; the limit is 20 bytes"):
        yaml_load("a: '" + "é" * 8 + "'")  # 13 characters, 21 bytes


def nested(depth: int, flow: bool) -> str:
    if flow:
        return "a: " + "[" * depth + "]" * depth
    return "".join("  " * i + "- \n" for i in range(depth - 1)) + "  " * (depth - 1) + "- 1\n"


@pytest.mark.parametrize("flow", [True, False], ids=["flow", "block"])
def test_depth_limit_is_exact(flow, parser):
    doc = yaml_load(nested(MAX_DEPTH - (1 if flow else 0), flow))  # the mapping is one level
    assert doc is not None
    with pytest.raises(ConfigError) as ei:
        yaml_load(nested(MAX_DEPTH + 1, flow), "deep.yaml")
    msg = one_line(ei.value, "deep.yaml")
    assert f"nested more than {MAX_DEPTH} levels deep" in msg, msg


def test_3000_levels_is_one_line_not_a_recursion_error(tmp_path, parser):
    for text in ("[" * 3000 + "]" * 3000, "{a: " * 3000 + "1" + "}" * 3000, "- " * 3000 + "1\n",
                 "".join(" " * i + "a:\n" for i in range(1000))):  # 1000 levels: 0.5 MB of indentation
        msg = file_error(tmp_path, text.encode())
        assert "nest" in msg, msg  # ours, or libyaml's own limit of 1000 flow levels


BILLION_LAUGHS = (
    'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
    + "".join(f"{chr(98 + i)}: &{chr(98 + i)} [" + ",".join(["*" + chr(97 + i)] * 9) + "]\n" for i in range(8))
)


def test_alias_bomb_is_rejected_at_the_alias_that_crosses_the_limit(tmp_path, parser):
    assert len(BILLION_LAUGHS) < 2048  # expands to 9**9 = 387 million strings
    msg = file_error(tmp_path, BILLION_LAUGHS.encode())
    # rejected while reading line 6 (9**6 * ... > MAX_NODES): nothing was expanded, only counted
    assert ": line 6, column " in msg and "more than 200000 values" in msg and "yamlfile.MAX_NODES" in msg, msg


def test_node_limit_counts_aliases_as_copies(monkeypatch, parser):
    monkeypatch.setattr(yamlfile, "MAX_NODES", 10)
    assert yaml_load("[" + ",".join("1" * 9) + "]") == [1] * 9  # 10 values with the list
    with pytest.raises(ConfigError, match="more than 10 values"):
        yaml_load("[" + ",".join("1" * 10) + "]")
    # a: 4 values; b: 1 + 4 copied; c: 1 = 10 in all, and the mapping makes 11
    assert yaml_load("[&a [1, 2, 3], *a, 7]") == [[1, 2, 3], [1, 2, 3], 7]
    with pytest.raises(ConfigError, match="more than 10 values"):
        yaml_load("{a: &a [1, 2, 3], b: *a, c: 7}")


def test_recursive_alias_is_rejected(parser):
    with pytest.raises(ConfigError) as ei:
        yaml_load("a: &x {b: [1, *x]}\n", "r.yaml")
    assert one_line(ei.value, "r.yaml") == ("r.yaml: line 1, column 15: alias *x is inside its own anchored node "
                                            "(a recursive structure)")


def test_aliases_follow_yaml12(parser):
    assert yaml_load("a: &x 1\nb: &x 2\nc: *x\n") == {"a": 1, "b": 2, "c": 2}  # the latest anchor
    assert yaml_load("a: &x [&x 1, *x]\n") == {"a": [1, 1]}
    with pytest.raises(ConfigError, match="alias \\*y has no anchor &y before it"):
        yaml_load("a: *y\nb: &y 1\n")


# ----------------------------------------------------------------------------- duplicate keys
@pytest.mark.parametrize("text,field,key,first", [
    ("name: a\nhorizon: {T: 1}\nname: b\n", "line 3, column 1", "'name'", 1),
    ("horizon:\n  T: 1\n  N: 2\n  T: 3\n", "line 4, column 3", "'T'", 2),
    ("{1: a, 1.0: b}", "line 1, column 8", "1.0", 1),
])
def test_duplicate_keys_name_key_and_both_lines(text, field, key, first, parser):
    with pytest.raises(ConfigError) as ei:
        yaml_load(text, "d.yaml")
    assert one_line(ei.value, "d.yaml") == f"d.yaml: {field}: duplicate key {key} (first given on line {first})"


# ----------------------------------------------------------------------------- YAML 1.2 core schema
CORE = [
    ("1:40", "1:40"), ("1_000", "1_000"), ("0o17", 15), ("0x1F", 31), ("0x1f", 31), ("017", 17),
    ("-0x1F", "-0x1F"), ("0b101", "0b101"), ("+12", 12), ("-3", -3),
    ("yes", "yes"), ("no", "no"), ("on", "on"), ("off", "off"), ("Y", "Y"), ("n", "n"),
    ("true", True), ("False", False), ("TRUE", True), ("tRUE", "tRUE"),
    ("null", None), ("~", None), ("", None), ("NULL", None), ("nil", "nil"),
    ("1e4", 1e4), ("1.0e4", 1e4), ("-1E-3", -1e-3), ("1.", 1.0), (".5", 0.5), ("+.5", 0.5),
    ("1.5e+3", 1500.0), ("1e400", math.inf), (".inf", math.inf), ("-.Inf", -math.inf), (".NaN", math.nan),
    ("2001-12-14", "2001-12-14"), ("1,000", "1,000"), ("=", "="), ("<<", "<<"),
    ("'12'", "12"), ('"true"', "true"), ("!!str 12", "12"), ("!!int '12'", 12), ("!!float 3", 3.0),
    ("!!bool true", True), ("!!null ''", None), ("! 12", "12"),
]


def same(a, b) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("text,value", CORE, ids=[c[0] or "empty" for c in CORE])
def test_yaml12_core_schema(text, value, parser):
    got = yaml_load(f"a: {text}\n")["a"]
    assert same(got, value), (text, got)


@pytest.mark.parametrize("text", ["!!binary aGVsbG8=", "!!timestamp 2001-12-14", "!!set {a}", "!!omap [a: 1]",
                                  "!!python/object:os.system x", "!foo bar", "!!merge <<", "!!int 1.5",
                                  "!!bool yes", "!!float x", "!!null 0"])
def test_other_tags_are_rejected(text, parser):
    with pytest.raises(ConfigError) as ei:
        yaml_load(f"a: {text}\n", "t.yaml")
    msg = one_line(ei.value, "t.yaml")
    assert msg.startswith("t.yaml: line 1, column 4: ") and ("unsupported tag" in msg or "for the tag" in msg), msg


def test_merge_key_is_an_ordinary_key_in_yaml12(parser):
    assert yaml_load("a: &a {x: 1}\nb: {<<: *a, y: 2}\n") == {"a": {"x": 1}, "b": {"<<": {"x": 1}, "y": 2}}


def test_integer_beyond_python_digit_limit_is_one_line(parser):
    assert yaml_load("a: " + "9" * 4000)["a"] == int("9" * 4000)
    with pytest.raises(ConfigError, match="integer too long \\(5000 digits\\)"):
        yaml_load("a: " + "9" * 5000)


def test_ipopt_yes_no_options_stay_strings_ipopt_accepts():
    """YAML 1.2 reads ``mehrotra_algorithm: yes`` as the string IPOPT expects; true/false still work."""
    from se3ocp.problems.maneuvers import load_maneuver
    from se3ocp.transcription.options import check_raw_options

    man = load_maneuver(E3, ["solver.direct.options.mehrotra_algorithm=yes",
                             "solver.direct.options.warm_start_init_point=false"])
    opts = man.direct.options
    assert opts == {"mehrotra_algorithm": "yes", "warm_start_init_point": False}
    check_raw_options("ipopt", opts, "options")  # raises if IPOPT rejects a value (it was checked at load too)


def test_boolean_field_names_yaml12():
    with pytest.raises(ConfigError) as ei:
        Validator("b.yaml").boolean(yaml_load("a: on")["a"], "continuation")
    assert str(ei.value) == ("b.yaml: continuation: expected true or false, got the string 'on' "
                             "(YAML 1.2 reads yes/no/on/off as strings)")
    assert Validator("b.yaml").boolean(True, "x") is True


def test_syntax_error_names_line_column_and_context(parser):
    with pytest.raises(ConfigError) as ei:
        yaml_load("name: x\nhorizon: {T: 'unterminated, N: 2}\n", "s.yaml")
    assert one_line(ei.value, "s.yaml") == ("s.yaml: line 3, column 1: not valid YAML (found unexpected end of stream "
                                            "while scanning a quoted scalar that starts on line 2, column 14)")


def test_second_document_is_rejected(parser):
    with pytest.raises(ConfigError, match="s.yaml: line 3, column 1: expected one YAML document"):
        yaml_load("a: 1\n...\n--- {b: 2}\n", "s.yaml")


def test_bundled_configs_parse_as_before():
    """For the bundled files YAML 1.2 differs from PyYAML's YAML 1.1 reading only where the
    project always read numbers: exponents without a dot (1e4) and 1.0e4 are floats."""
    exp_float = __import__("re").compile(r"[-+]?[0-9.]+[eE][-+]?[0-9]+")

    def as_before(x):
        if isinstance(x, dict):
            return {k: as_before(v) for k, v in x.items()}
        if isinstance(x, list):
            return [as_before(v) for v in x]
        return float(x) if isinstance(x, str) and exp_float.fullmatch(x) else x

    files = sorted(CONFIGS.rglob("*.yaml"))
    assert len(files) >= 6
    for p in files:
        assert read_yaml_file(p) == as_before(yaml.safe_load(p.read_text())), p


# ----------------------------------------------------------------------------- yaml_dump
def test_yaml_dump_quotes_what_either_yaml_version_would_misread():
    obj = {"s": ["yes", "on", "0o17", "1e4", "1:40", "1_000", "2001-12-14", "null", "", "=", ".5", "0x1F", "~"],
           "v": [1, -2.5, 1e-8, True, None, math.inf], "name": "e3",
           "breaks": ["a\x85b", "a\u2028b", "\u2029", "tab\there", "\ufeffbom", "two\nlines", "bell\x07"]}
    text = yaml_dump(obj)
    assert yaml_load(text) == obj and yaml.safe_load(text) == obj
    assert text.startswith("s:\n- 'yes'\n")  # keys in order, one per line


# ----------------------------------------------------------------------------- --set
@pytest.mark.parametrize("assignment,expected", [
    ("horizon.N=[1, {", "--set: horizon.N: invalid value (line "),
    ("horizon.N=1\x00", "--set: horizon.N: invalid value (line 1, column 2 of the value): not YAML text: the "
                        "character U+0000"),
    ("horizon.N={a: 1, a: 2}", "--set: horizon.N: invalid value (line 1, column 8 of the value): duplicate key 'a' "
                               "(first given on line 1)"),
    ("horizon.N=!!binary eA==", "--set: horizon.N: invalid value (line 1, column 1 of the value): unsupported tag"),
    ("horizon.N=" + "[" * 100, "--set: horizon.N: invalid value (line 1, column 65 of the value): nested more than"),
    ("horizon.N=" + "x" * 1_000_001, "--set: horizon.N: invalid value: too large (1000001 bytes; the limit is 1000000 bytes"),
    ("horizon..N=1", "--set: horizon..N: expected a dotted key such as horizon.N"),
    ("=1", "--set: =1: expected a dotted key before '='"),
    ("horizon.N", "--set: horizon.N: expected KEY=VALUE"),
])
def test_bad_set_is_one_line_naming_set(assignment, expected, parser):
    with pytest.raises(ConfigError) as ei:
        apply_override({"horizon": {"N": 1}}, assignment)
    assert one_line(ei.value, "--set").startswith(expected), str(ei.value)


def test_set_value_errors_after_parsing_name_set_not_the_file():
    from se3ocp.problems.maneuvers import parse_maneuver

    with pytest.raises(ConfigError) as ei:
        load_with_overrides(E3, ["horizon.N=oops"], parse_maneuver)
    assert str(ei.value) == "--set: horizon.N: expected an integer, got the string 'oops'"
    with pytest.raises(ConfigError) as ei:  # under the key set: --set
        load_with_overrides(E3, ["initial.position=[1, x, 0]"], parse_maneuver)
    assert str(ei.value) == "--set: initial.position[1]: expected a number, got the string 'x'"
    with pytest.raises(ConfigError) as ei:  # a problem the override did not cause: the file
        load_with_overrides(E3, ["horizon.N=7", "colour=red"], parse_maneuver)
    assert str(ei.value).startswith("--set: colour: unknown key")
    man = load_with_overrides(E3, ["horizon.N=7"], parse_maneuver)
    assert man.N == 7
    err = ConfigError(str(E3), "horizon.T", "expected a positive number, got -1.0")
    assert blame_overrides(err, ["horizon.N", "horizon.Tx"]) is err


def test_long_set_value_message_is_bounded():
    from se3ocp.problems.maneuvers import parse_maneuver

    with pytest.raises(ConfigError) as ei:
        load_with_overrides(E3, ["horizon.N=" + "x" * 100_000], parse_maneuver)
    msg = one_line(ei.value, "--set")
    assert msg == "--set: horizon.N: expected an integer, got the string '" + "x" * 60 + "... (100000 characters)'"


def test_override_through_an_alias_changes_only_its_path(parser):
    doc = yaml_load("base: &b {x: 1, y: 2}\nother: *b\n")
    assert doc["base"] is doc["other"]  # shared, as YAML says
    apply_override(doc, "other.x=5")
    assert doc == {"base": {"x": 1, "y": 2}, "other": {"x": 5, "y": 2}}


# ----------------------------------------------------------------------------- Validator
V = Validator("v.yaml")


def fails(fn, *args, **kw) -> str:
    with pytest.raises(ConfigError) as ei:
        fn(*args, **kw)
    return one_line(ei.value, "v.yaml")


def test_axis_angle_overflowing_norm_is_normalized_not_identity():
    R = V.attitude({"axis_angle": [1e308, 1e308, 0, 30]}, "a")
    expected = np.asarray(exp_so3(np.array([1.0, 1.0, 0.0]) / math.sqrt(2) * math.radians(30)))
    np.testing.assert_allclose(R, expected, atol=1e-15)
    assert abs(R[2, 2] - math.cos(math.radians(30))) <= 1e-15  # not the identity


@pytest.mark.parametrize("scale", [1e-200, 5e-324, 1.0, 1e200])
def test_axis_angle_tiny_and_huge_axes_are_directions(scale):
    R = V.attitude({"axis_angle": [0, 0, scale, 90]}, "a")
    np.testing.assert_allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)


def test_axis_angle_zero_axis_and_large_angle():
    assert fails(V.attitude, {"axis_angle": [0, 0, 0.0, 10]}, "a") == \
        "v.yaml: a.axis_angle: expected a non-zero rotation axis"
    np.testing.assert_allclose(V.attitude({"axis_angle": [1, 0, 0, 360 * 10**12 + 30]}, "a"),
                               V.attitude({"axis_angle": [1, 0, 0, 30]}, "a"), atol=1e-15)


def test_unit_vector():
    np.testing.assert_allclose(V.unit_vector([0, 0, 1e-300], "n"), [0, 0, 1])
    np.testing.assert_allclose(V.unit_vector([1e308, -1e308, 0], "n"), [2**-0.5, -(2**-0.5), 0])
    assert fails(V.unit_vector, [0, 0, 0], "n") == "v.yaml: n: expected a non-zero vector (it is normalized)"


def test_matrix_with_huge_entries_is_a_message_not_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        msg = fails(V.attitude, {"matrix": [[1e200, 0, 0], [0, 1, 0], [0, 0, 1]]}, "a")
    assert msg.startswith("v.yaml: a.matrix: expected a rotation matrix") and "|R^T R - I| = inf" in msg


@pytest.mark.parametrize("value,kw,expected", [
    (1e30, {}, "expected an integer <= 2147483647, got 1e+30"),
    (2**31, {}, "expected an integer <= 2147483647, got 2147483648"),
    (-(2**31), {}, "expected an integer >= -2147483647, got -2147483648"),
    (10**400, {}, "expected an integer <= 2147483647, got <an integer of 401 digits>"),
    (1001, {"at_most": 1000}, "expected an integer <= 1000, got 1001"),
    (2.5, {}, "expected an integer, got 2.5"),
    (math.inf, {}, "expected a finite number, got inf"),
    ("7", {}, "expected an integer, got the string '7'"),
    (True, {}, "expected an integer, got a boolean (True)"),
])
def test_integer_bounds(value, kw, expected):
    assert fails(V.number, value, "n", integer=True, **kw) == f"v.yaml: n: {expected}"


def test_integer_accepted_values():
    assert V.number(3.0, "n", integer=True) == 3 and type(V.number(3.0, "n", integer=True)) is int
    assert V.number(MAX_INTEGER, "n", integer=True) == MAX_INTEGER
    assert V.number(1000, "n", integer=True, at_most=1000) == 1000


def test_huge_integer_for_a_number_field():
    assert fails(V.number, 10**400, "T") == \
        "v.yaml: T: expected a finite number, got an integer too large for a float (<an integer of 401 digits>)"
    assert V.number(10**300, "T") == 1e300


def test_messages_stay_one_line_with_hostile_names():
    err = ConfigError("a\nb.yaml", "x\ry", "bad\x00value")
    assert str(err) == "a\\nb.yaml: x\\ry: bad\\x00value"
    assert describe("x" * 1000) == "the string '" + "x" * 60 + "... (1000 characters)'"
    assert fails(V.mapping, {"k\n" * 50: 1}, "", ("a",)).startswith("v.yaml: '")


# ----------------------------------------------------------------------------- properties
CORE_TYPES = (dict, list, str, int, float, bool, type(None))


def only_core_types(x, depth=0) -> bool:
    assert depth <= MAX_DEPTH + 1
    if isinstance(x, dict):
        return all(only_core_types(k, depth + 1) and only_core_types(v, depth + 1) for k, v in x.items())
    if isinstance(x, list):
        return all(only_core_types(v, depth + 1) for v in x)
    return isinstance(x, CORE_TYPES)


#: YAML-ish text: the indicators, some words, aliases, tags, a NUL, a BOM, a non-ASCII letter
YAMLISH = st.lists(st.sampled_from(list("ab01.-+eE:,[]{}&*!|>'\"#?~%@` \n\t\\") + [
    "yes", "null", ": ", "- ", "\n  ", "&a ", "*a", "!!", "!!int ", "\x00", "é", "\ufeff", "0x1F", "1:40"]),
    max_size=60).map("".join)

PROPERTY = settings(max_examples=300, deadline=None, derandomize=bool(os.environ.get("CI")),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("which", PARSERS, ids=lambda p: p.__name__)
@PROPERTY
@given(data=st.one_of(st.binary(max_size=300), YAMLISH.map(lambda s: s.encode("utf-8", "surrogatepass"))))
def test_any_bytes_give_a_document_or_one_config_error(which, data, tmp_path_factory):
    """Any file: a document of core types, or one ConfigError line naming the file.  Time is
    bounded by the limits (size, depth, values), not asserted."""
    p = tmp_path_factory.mktemp("fuzz") / "fuzz.yaml"
    p.write_bytes(data)
    old = yamlfile._Parser
    yamlfile._Parser = which
    try:
        doc = read_yaml_file(p)
    except ConfigError as e:
        one_line(e, str(p))
        return
    finally:
        yamlfile._Parser = old
    assert only_core_types(doc)


@PROPERTY
@given(doc=st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), st.floats(),
                                  st.text(max_size=12)),
                        lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                        max_leaves=20))
def test_yaml_dump_round_trips(doc):
    """What the project writes (config.resolved.yaml) reads back as written, by both YAML versions."""
    text = yaml_dump(doc)
    for back in (yaml_load(text), yaml.safe_load(text)):
        assert repr(back) == repr(doc)  # repr: NaN == NaN, 1 is not True
