"""Compilation of hot Functions to C (transcription/codegen.py): fallback, cache, equality."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription import codegen
from se3ocp.transcription.lgvi import Discretization
from se3ocp.transcription.options import DirectOptions, IndirectOptions
from support import maneuver

SCHEMES = ("first_order", "lgvi")


def fresh(name: str, N: int):
    """The first-order problem ``name`` on a Discretization of its own: nothing built or compiled for it yet
    (what a Discretization builds is cached on it)."""
    p = maneuver(name, N, "first_order").problem
    return p.replace(disc=Discretization(p.model, p.scheme))


def test_codegen_falls_back_without_compiler(monkeypatch):
    monkeypatch.setenv("SE3OCP_NO_JIT", "1")
    x = ca.SX.sym("x", 2)
    f = ca.Function("fallback_probe", [x], [ca.sin(x)])
    assert codegen.compiled(f) is f and "no C compiler" in codegen.last_error
    s = se3ocp.solve(fresh("e3", 10), jit=True)
    assert s.converged and s.stats["jit"] is False
    # the indirect method (jit on by default) falls back the same way
    assert IndirectOptions().jit is True
    s = se3ocp.solve(fresh("e3", 30), "indirect")
    assert s.converged and s.stats["jit"] is False


def test_codegen_all_or_nothing(monkeypatch, tmp_path):
    """A failing compiler leaves every Function of every library interpreted, with the reason kept."""
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "compiler", lambda: "false")   # exits 1 without output
    monkeypatch.setattr(codegen, "available", lambda: True)
    x = ca.SX.sym("x", 2)
    f, g = ca.Function("aon_f", [x], [ca.sin(x)]), ca.Function("aon_g", [x], [ca.cos(x)])
    out = codegen.compiled_libraries([codegen.Library("aon_f", (f,)), codegen.Library("aon_g", (g,))],
                                     cflags=codegen.QUICK_CFLAGS)
    assert out == [[f], [g]] and "CalledProcessError" in codegen.last_error
    assert not list(tmp_path.glob("*.so")) and not [p for p in tmp_path.iterdir() if p.is_dir()]


def test_lean_io_keeps_values_with_absent_inputs_and_outputs(monkeypatch, tmp_path):
    """codegen.lean_io (one null test per input/output pointer instead of one per element) changes no value,
    also when CasADi passes no buffer for a structurally zero input or an unused output."""
    if not codegen.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    x, y = ca.SX.sym("x", 3), ca.SX.sym("y", 2, 2)
    f = ca.Function("lean_probe", [x, y], [ca.sin(x) * y[0, 1] + 1, ca.mtimes(y, x[:2]) + x[2], ca.vertcat(x, y[:])])
    src = codegen.lean_io(codegen._generate(codegen.Library("lean_probe", (f,)), str(tmp_path)).read_text())
    assert "arg[0]? arg[0]" not in src and "if (res[" not in src and "ci1[3]" in src
    g = codegen.compiled(f, cse=False, cflags=codegen.QUICK_CFLAGS)
    assert g.class_name() == "External"
    X = ca.MX.sym("X", 3)
    vals = []
    for fn in (f, g):
        F = ca.Function("F", [X], [fn(X, ca.MX(2, 2))[1], fn(X, ca.reshape(X[:2], 2, 1) @ X[1:].T)[0]])
        vals.append([np.array(o) for o in F([0.3, -1.2, 2.0])])
    assert all(np.array_equal(a, b) for a, b in zip(*vals))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_indirect_compiled_equals_interpreted_bit_for_bit(scheme):
    """The compiled per-step maps (gcc -O0 -ffp-contract=off) do the interpreter's arithmetic: a whole solve gives
    the same history, controls and lambda_0, bit for bit.  And the default compiles when it can."""
    if not codegen.available():
        pytest.skip("no C compiler")
    man = maneuver("e4", 40, scheme)
    a = se3ocp.solve(man, "indirect", jit=False, eps_S=0.0)
    b = se3ocp.solve(man, "indirect", eps_S=0.0)
    assert not a.stats["jit"] and b.stats["jit"] and a.converged
    assert [r.residual for r in a.history] == [r.residual for r in b.history]
    assert np.array_equal(a.controls, b.controls) and np.array_equal(a.warm.lam0, b.warm.lam0)


def test_direct_default_compiles_when_it_can():
    """jit is on by default for the direct method (and off with SE3OCP_NO_JIT, see the fallback test)."""
    if not codegen.available():
        pytest.skip("no C compiler")
    assert DirectOptions().jit is True
    s = se3ocp.solve(maneuver("e3", 10, "first_order"))
    assert s.converged and s.stats["jit"] is True


def test_codegen_notifies_on_a_cache_miss_only(monkeypatch, tmp_path):
    if not codegen.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    said: list[str] = []
    monkeypatch.setattr(codegen, "notify", said.append)
    x = ca.SX.sym("x", 2)
    f = ca.Function("notify_probe", [x], [ca.sin(x) * x[0]])
    g = codegen.compiled(f)
    assert g.class_name() == "External" and len(said) == 1 and "notify_probe" in said[0]
    h = codegen.compiled(f)                       # cache hit: loaded, nothing said
    assert h.class_name() == "External" and len(said) == 1
    assert np.allclose(np.array(h([0.3, -1.2])), np.array(f([0.3, -1.2])), rtol=0, atol=1e-15)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", SCHEMES)
def test_compiled_runs_equal_interpreted(scheme):
    if not codegen.available():
        pytest.skip("no C compiler")
    man = maneuver("e4", 60, scheme)
    a, b = se3ocp.solve(man, jit=False), se3ocp.solve(man, jit=True)
    assert b.stats["jit"] and a.iterations == b.iterations and abs(a.cost - b.cost) <= 1e-12 * a.cost
    c, d = se3ocp.solve(man, "indirect", jit=False), se3ocp.solve(man, "indirect")   # jit: the indirect default
    assert d.stats["jit"] and not c.stats["jit"] and c.converged and d.converged
    assert c.cost == d.cost and c.iterations == d.iterations
