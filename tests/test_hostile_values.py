"""Values from 1e-300 to 1e300 (and inf, NaN) where a file gives directions, bounds and inertias,
and summary.json tampered with field by field (issue 28).

Properties (hypothesis, derandomized and bounded: the same examples every run, a few seconds):

* a direction, a bound or an inertia is either refused -- one line naming --set and the field -- or
  read as written, and a short solve of the maneuver then never raises, and when it reports
  convergence its bounds and path constraints hold on the re-simulated path;
* ``report`` on a results directory whose summary.json has one field replaced by a value of another
  type, or deleted, either refuses with one line naming summary.json and the field, or writes a
  report whose statuses and verdict are those of the untouched run.

The real CLI runs each class once in tests/failure_cases.py (the catalogue); here the loader and
the solver are called in-process, so that many values fit in the time of the default suite.
"""
from __future__ import annotations

import json
import math
import re
import shutil
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import se3ocp
from se3ocp.problems.schema import ConfigError

from support import config

PROPERTY = settings(max_examples=14, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
#: a short solve: the keep-out slew at N = 8, few iterations (what is checked is never the optimum)
SHORT = ("horizon.N=8", "solver.direct.jit=false", "solver.direct.max_iter=60")
TOL = 1e-6
#: the statuses the short solves ended with (what the properties reached)
OUTCOMES: list[str] = []

#: numbers of every magnitude, both signs, zero, and the non-finite ones
MAGNITUDE = st.builds(lambda m, e: m * 10.0**e, st.floats(1.0, 9.99), st.integers(-300, 300))
NUMBER = st.one_of(MAGNITUDE, MAGNITUDE.map(lambda x: -x), st.just(0.0), st.sampled_from([math.inf, -math.inf, math.nan]))
#: a scale of any magnitude times factors near 1: limits and moments that are often valid together
SCALE = st.integers(-300, 300).map(lambda e: 10.0**e)
NEAR = st.floats(0.5, 2.0)


def _limits(scale, factors):
    return [scale * f for f in factors]


def _yaml(x) -> str:
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_yaml(a) for a in x) + "]"
    if math.isnan(x):
        return ".nan"
    if math.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    return repr(float(x))


def _load_or_refusal(*sets):
    """The maneuver, or None after checking that the refusal is one line naming --set."""
    try:
        return se3ocp.load(config("slew_keep_out"), SHORT + sets)
    except ConfigError as e:
        text = str(e)
        assert "\n" not in text and text.startswith("--set: "), text
        return None


def _solve_and_check(man):
    """A short solve: no exception; converged means bounds and path constraints hold on the re-simulation."""
    with np.errstate(all="ignore"):
        sol = se3ocp.solve(man)
    assert sol.message
    OUTCOMES.append(sol.result.value)
    if not sol.converged:
        return sol
    assert sol.terminal_error <= man.direct.terminal_tol
    ctrl = man.problem.control
    for u, b in ((sol.u_f, ctrl.force_bound), (sol.u_m, ctrl.moment_bound)):
        if b is None:
            continue
        limit = np.broadcast_to(np.asarray(b.b, float), (3,))
        if hasattr(b, "margin") and np.ndim(b.b) == 0:
            assert np.all(np.linalg.norm(u, axis=1) <= b.b * (1 + TOL)), "norm bound violated"
        else:
            assert np.all(np.abs(u) <= limit * (1 + TOL)), "box bound violated"
    for c in man.problem.constraints:
        assert c.margin(sol.trajectory).min() >= -TOL, f"{c.kind} violated on the re-simulated path"
    return sol


def _parallel(u: np.ndarray, v) -> bool:
    """u is the unit vector along v: checked in exact rational arithmetic (no overflow, no underflow)."""
    U = [Fraction(float(a)) for a in u]
    V = [Fraction(float(a)) for a in v]
    cross = [U[1] * V[2] - U[2] * V[1], U[2] * V[0] - U[0] * V[2], U[0] * V[1] - U[1] * V[0]]
    scale = max(abs(a) for a in V)
    return (max(abs(c) for c in cross) <= Fraction(1, 10**14) * scale and sum(a * b for a, b in zip(U, V)) > 0
            and abs(sum(a * a for a in U) - 1) <= Fraction(1, 10**14))


#: 3 components of any magnitudes, or of one magnitude (a direction at the scale of 1e200 or 1e-200)
VECTOR = st.one_of(st.lists(NUMBER, min_size=3, max_size=3),
                   st.builds(_limits, SCALE, st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3)))


@settings(PROPERTY, max_examples=20)
@given(axis=VECTOR, direction=VECTOR)
def test_a_cone_axis_of_any_magnitude_is_refused_or_read_as_written(axis, direction):
    man = _load_or_refusal(f"constraints=[{{kind: keep_out, body_axis: {_yaml(axis)}, direction: {_yaml(direction)}, "
                           "min_angle_deg: 20}]")
    finite = all(map(math.isfinite, axis + direction))
    if man is None:
        return
    assert finite and any(axis) and any(direction), "a non-finite or zero direction was accepted"
    cone = man.problem.constraints[0]
    assert _parallel(cone.body_axis, axis) and _parallel(cone.direction, direction), "the direction was misread"
    _solve_and_check(man)


LIMIT = st.one_of(NUMBER, st.lists(NUMBER, min_size=3, max_size=3), st.builds(lambda s, f: s * f, SCALE, NEAR),
                  st.builds(_limits, SCALE, st.lists(NEAR, min_size=3, max_size=3)))


#: force, moment and rate limits of one scale (the bounds fit together), or each of any value
BOUNDS = st.one_of(
    st.tuples(st.one_of(st.just(0.0), LIMIT), LIMIT, st.one_of(NUMBER, st.builds(lambda s, f: s * f, SCALE, NEAR))),
    st.builds(lambda e, ff, fm, fw, box: (0.0 if ff < 0.7 else 10.0**e * ff,
                                          [10.0**e * fm] * 3 if box else 10.0**e * fm, 10.0**e * fw),
              st.integers(-200, 200), NEAR, NEAR, NEAR, st.booleans()))


@settings(PROPERTY, max_examples=20)
@given(limits=BOUNDS)
def test_bounds_of_any_magnitude_are_refused_or_held(limits):
    force, moment, rate = limits
    form = {True: "box", False: "norm"}
    bounds = (f"control.bounds={{force: {{{form[isinstance(force, list)]}: {_yaml(force)}}}, "
              f"moment: {{{form[isinstance(moment, list)]}: {_yaml(moment)}}}}}")
    man = _load_or_refusal(bounds, f"constraints=[{{kind: max_angular_rate, value: {_yaml(rate)}}}]")
    if man is None:
        return
    for b in (force, moment, rate):
        for x in (b if isinstance(b, list) else [b]):
            assert math.isfinite(x) and (x == 0 or 1e-150 <= x <= 1e150), f"limit {x!r} accepted"
    _solve_and_check(man)


@settings(PROPERTY, max_examples=20)
@given(moments=st.one_of(st.lists(st.one_of(MAGNITUDE, st.sampled_from([0.0, -1.0, math.inf, math.nan])), min_size=3,
                                   max_size=3),
                         st.builds(_limits, st.integers(-170, 170).map(lambda e: 10.0**e),
                                   st.lists(st.floats(0.6, 1.0), min_size=3, max_size=3))))
def test_inertias_of_any_magnitude_are_refused_or_solved(moments):
    man = _load_or_refusal(f"model={{kind: rigid_body, mass: 1.0, inertia: {_yaml(moments)}}}")
    if man is None:
        return
    lo, mid, hi = sorted(moments)
    assert 1e-150 <= lo and hi <= 1e150 and lo + mid >= hi * (1 - 1e-12), f"inertia {moments} accepted"
    assert np.allclose(np.linalg.eigvalsh(man.problem.model.inertia), sorted(moments), rtol=1e-12, atol=0)
    _solve_and_check(man)


# ---------------------------------------------------------------------------- summary.json tampered
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory):
    """A compare run of E3 at N = 10 (the direct method converges, the indirect one does not) and the
    statuses and verdict its report shows."""
    from se3ocp.problems.cli import main

    d = tmp_path_factory.mktemp("run") / "out"
    assert main(["compare", str(config("e3")), "--set", "horizon.N=10", "--out", str(d), "--quiet",
                 "--no-figures"]) in (0, 1)
    return d, _verdicts(d / "report.html")


def _verdicts(html: Path) -> tuple:
    text = html.read_text()
    heads = re.findall(r'<div class="head">(.*?)</div>', text)
    verdict = re.search(r'id="verdict">\s*<b>(.*?)</b>', text, re.S)
    return tuple(heads), verdict.group(1) if verdict else None


def _leaves(doc, prefix=()):
    """Dotted paths of every field (history: its first record only)."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield prefix + (k,)
            yield from _leaves(v, prefix + (k,))
    elif isinstance(doc, list) and doc and isinstance(doc[0], dict):
        yield prefix + (0,)
        yield from _leaves(doc[0], prefix + (0,))


_DELETE = object()
REPLACEMENTS = [_DELETE, None, True, False, 0, -1, 2.5, math.nan, "converged", "agree: same extremal", [], [1], {}]


def _tamper(doc, path, value):
    node = doc
    for p in path[:-1]:
        node = node[p]
    if value is _DELETE:
        del node[path[-1]]
    else:
        node[path[-1]] = value


def _same_kind(a, b) -> bool:
    """A replacement of the same JSON kind (a number for a number): not a type change, left out."""
    def kind(x):
        return "number" if isinstance(x, (int, float)) and not isinstance(x, bool) else type(x).__name__
    return kind(a) == kind(b) and not (isinstance(a, str) or isinstance(a, (list, dict)))


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_tampered_summary_is_refused_or_reported_as_it_was(finished_run, tmp_path_factory, data):
    from se3ocp.problems.cli import main

    src, truth = finished_run
    doc = json.loads((src / "summary.json").read_text())
    paths = sorted(_leaves(doc), key=str)
    path = data.draw(st.sampled_from(paths), label="field")
    node = doc
    for p in path:
        node = node[p]
    value = data.draw(st.sampled_from([r for r in REPLACEMENTS if r is _DELETE or not _same_kind(r, node)]),
                      label="value")
    d = tmp_path_factory.mktemp("tampered") / "out"
    shutil.copytree(src, d)
    (d / "report.html").unlink()
    _tamper(doc, path, value)
    (d / "summary.json").write_text(json.dumps(doc))
    import io
    from contextlib import redirect_stderr, redirect_stdout

    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        rc = main(["report", str(d), "--no-figures", "--quiet"])
    lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
    if rc == 2:
        assert len(lines) == 1 and f"{d / 'summary.json'}: " in lines[0], lines
        assert "Traceback" not in err.getvalue()
        return
    assert rc == 0 and not lines, (rc, lines)
    assert _verdicts(d / "report.html") == truth, f"{'.'.join(map(str, path))} = {value!r} changed the report"


def test_orbit_target_and_axis_angle_directions_of_any_magnitude():
    """The orbit target's normal and body axis and an axis-angle axis go through the same reader as the
    cones (transcription.geometry.so3.unit_direction): huge and tiny vectors keep their direction."""
    from se3ocp.transcription.geometry.so3 import exp_so3
    from se3ocp.transcription.ocp import ProblemError, TargetOrbit

    m = se3ocp.load(config("e2"), ["terminal.orbit.body_axis=[1e200, 0, 0]", "terminal.orbit.normal=[0, 1e-200, 1e-200]"])
    assert m.terminal.body_axis.tolist() == [1.0, 0.0, 0.0]
    assert np.allclose(m.terminal.normal, [0, 2**-0.5, 2**-0.5], rtol=0, atol=4e-16)
    t = TargetOrbit(2.0, [0.0, 0.0, 5e-324], [3e250, 4e250, 0.0])
    assert t.normal.tolist() == [0.0, 0.0, 1.0] and np.allclose(t.body_axis, [0.6, 0.8, 0.0], rtol=0, atol=4e-16)
    with pytest.raises(ProblemError):
        TargetOrbit(2.0, [0.0, 0.0, 0.0])
    m = se3ocp.load(config("e3"), ["initial.attitude={axis_angle: [0, 0, 1e300, 90]}"])
    assert np.allclose(m.initial.R, exp_so3(np.array([0.0, 0.0, np.pi / 2])), rtol=0, atol=1e-15)
