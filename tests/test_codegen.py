"""Compilation of hot Functions to C (transcription/codegen.py): fallback, cache, equality."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription import codegen, nlp
from se3ocp.transcription.options import DirectOptions
from support import maneuver

SCHEMES = ("first_order", "lgvi")


def test_codegen_falls_back_without_compiler(monkeypatch):
    monkeypatch.setenv("SE3OCP_NO_JIT", "1")
    x = ca.SX.sym("x", 2)
    f = ca.Function("fallback_probe", [x], [ca.sin(x)])
    assert codegen.compiled(f) is f and "no C compiler" in codegen.last_error
    saved = dict(nlp._DERIVATIVES)
    nlp._DERIVATIVES.clear()
    try:
        s = se3ocp.solve(maneuver("e3", 10, "first_order"), jit=True)
    finally:
        nlp._DERIVATIVES.clear()
        nlp._DERIVATIVES.update(saved)
    assert s.converged and s.stats["jit"] is False


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
    c, d = se3ocp.solve(man, "indirect", jit=False), se3ocp.solve(man, "indirect", jit=True)
    assert d.stats["jit"] and c.converged and d.converged and abs(c.cost - d.cost) <= 1e-10 * c.cost
