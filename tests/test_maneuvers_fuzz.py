"""Property test: the loader either returns a valid Maneuver or raises ConfigError.

Random documents and random mutations of the bundled configs (deleted keys,
replaced values of every type, inserted keys) must never escape as another
exception type.
"""
from __future__ import annotations

import copy
import os
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from se3ocp.problems.maneuvers import Maneuver, parse_maneuver
from se3ocp.problems.schema import ConfigError, yaml_load

CONFIGS = sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.yaml"))
BASES = [yaml_load(p.read_text()) for p in CONFIGS]

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-10**6, 10**6),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.sampled_from(["identity", "lgvi", "first_order", "smooth", "impulsive", "dumbbell", "x", "z", "zero", "from_direct"]),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12,
)


def _paths(node, prefix=()):
    """All key paths into nested dicts/lists."""
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


def _check(doc):
    try:
        man = parse_maneuver(doc, "fuzz.yaml")
    except ConfigError as e:
        assert str(e).startswith("fuzz.yaml: ") and "\n" not in str(e)
        return
    assert isinstance(man, Maneuver)
    assert np.all(np.isfinite(man.problem.X0)) and man.N > 0 and man.T > 0


@settings(max_examples=300, deadline=None, derandomize=bool(os.environ.get("CI")), suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(values, st.dictionaries(st.sampled_from(["name", "horizon", "initial", "model", "terminal",
                                                          "control", "solver", "discretization"]), values)))
def test_random_documents(doc):
    _check(doc)


@settings(max_examples=500, deadline=None, derandomize=bool(os.environ.get("CI")), suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_mutated_configs(data):
    doc = copy.deepcopy(data.draw(st.sampled_from(BASES)))
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        if not paths:
            break
        path = data.draw(st.sampled_from(paths))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        action = data.draw(st.sampled_from(["replace", "delete", "insert"]))
        if action == "replace":
            parent[path[-1]] = data.draw(values)
        elif action == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[data.draw(st.text(max_size=6))] = data.draw(values)
        else:
            parent.append(data.draw(values))
    _check(doc)
