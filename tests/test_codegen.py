"""Compilation of hot Functions to C (transcription/codegen.py): fallback, cache, equality."""
from __future__ import annotations

import time

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.problems.models import GM_NORMALIZED, Dumbbell, Gravity, RigidBody
from se3ocp.transcription import codegen
from se3ocp.transcription.lgvi import Discretization
from se3ocp.transcription.lie import exp_so3
from se3ocp.transcription.options import DirectOptions, IndirectOptions
from support import maneuver, problem

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


@pytest.mark.parametrize("model", ["dumbbell", "rigid_body"])
@pytest.mark.parametrize("gravity", ["none", "point_mass", "gravity_gradient", "j2"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_parametric_step_equals_the_numeric_step(model, gravity, scheme):
    """The step Functions with the model's numbers as data (Discretization.parametric, what the NLP's dynamics block
    is built from), given theta = model.parameters, equal the Functions with the numbers as constants: the states
    bit for bit (the same expression: the numbers enter as data instead of constants), the Cayley equation's
    relative residual after the Newton iterations (~1e-17, round-off) to 1e-15; and the two potentials agree."""
    body = (Dumbbell(mass=1.3, length=0.12, sphere_radius=0.03, gravity=gravity, J2=1.1e-3, J2_radius=0.9)
            if model == "dumbbell" else RigidBody(1.3, np.array([[0.02, 0.001, 0.0], [0.001, 0.03, 0.002], [0.0, 0.002, 0.04]]),
                                                   Gravity(gravity, 39.0, 1.1e-3 if gravity == "j2" else 0.0,
                                                           0.9 if gravity == "j2" else 0.0))).body_model()
    disc, rng = Discretization(body, scheme), np.random.default_rng(3)
    P, th = disc.parametric(), body.parameters
    for _ in range(5):
        R = np.asarray(exp_so3(rng.normal(size=3)), dtype=float)
        X = np.r_[rng.normal(size=3) + [1.0, 0.0, 0.0], rng.normal(size=3), R.ravel(order="F"), 0.01 * rng.normal(size=3)]
        w, c, h = rng.normal(size=disc.nw), 0.01 * rng.normal(size=3), 1e-2
        got = [np.array(a) for a in (*P.step_given_c(X, c, w, h, th), *P.step(X, w, h, th))]
        want = [np.array(a) for a in (*disc.step_given_c(X, c, w, h), *disc.step(X, w, h))]
        assert all(np.array_equal(a, b) for a, b in zip(got[:3], want[:3]))
        assert abs(got[3] - want[3]).max() <= 1e-15
        assert float(body.parametric_potential(X[:3], R, body.potential_data)) == float(body.potential(X[:3], R))


def test_new_numbers_in_a_known_structure_compile_nothing(monkeypatch, tmp_path):
    """Mass, inertia, mu, J2 and its radius (the model's numbers) and the bounds are data of the compiled Functions:
    a second problem that differs from a first only in those numbers compiles nothing (codegen's notice is the
    count), and its compiled solve equals the interpreted one to round-off."""
    if not codegen.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "_spawn", lambda *args: None)    # the -O0 build only: no background process
    said: list[str] = []
    monkeypatch.setattr(codegen, "notify", said.append)
    j2 = ("gravity.kind=j2", "gravity.J2=1.0e-3", "gravity.radius=0.9")
    a = problem("e3_bounded", 20, "first_order", *j2, "control.bounds.force.norm=15.5")
    sa = se3ocp.solve(a.replace(disc=Discretization(a.model, a.scheme)))
    assert sa.converged and sa.stats["jit"] and len(said) == 1
    body = Dumbbell(mass=1.02, length=0.11, sphere_radius=0.025, mu=1.01 * GM_NORMALIZED, gravity="j2", J2=2e-3,
                    J2_radius=0.85).body_model()
    b = problem("e3_bounded", 20, "first_order", *j2, "control.bounds.force.norm=16")
    b = b.replace(disc=Discretization(body, b.scheme))
    sb, ref = se3ocp.solve(b), se3ocp.solve(b, jit=False)
    assert len(said) == 1 and sb.stats["jit"] and not ref.stats["jit"]
    assert sb.converged and sb.iterations == ref.iterations and abs(sb.cost - sa.cost) > 1e-3 * sa.cost
    assert abs(sb.cost - ref.cost) <= 1e-12 * ref.cost
    assert np.max(np.abs(sb.controls - ref.controls)) <= 1e-12 * np.max(np.abs(ref.controls))


def test_a_first_use_compiles_quickly_and_the_full_build_follows_in_the_background(monkeypatch, tmp_path):
    """With ``quick`` flags a cache miss is compiled now at -O0 (usable at once) while a detached process compiles
    the library at its own flags into the cache; the next build loads that one.  Same values either way."""
    if not codegen.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    monkeypatch.delenv("SE3OCP_JIT_BACKGROUND", raising=False)
    x = ca.SX.sym("x", 3)
    f = ca.Function("background_probe", [x], [ca.sin(x) * x[0] + ca.exp(x[1])])
    lib = codegen.Library(f.name(), (f,), cse=True)
    (g,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)
    assert g.class_name() == "External" and codegen.last_provisional
    deadline = time.monotonic() + 120.0
    while (not codegen.ready([lib]) or list(tmp_path.glob("*.building"))) and time.monotonic() < deadline:
        time.sleep(0.2)                                              # the lock goes last, after the job's files
    assert codegen.ready([lib]) and not list(tmp_path.glob("*.building"))
    (k,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)
    assert k.class_name() == "External" and not codegen.last_provisional
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]      # the job's files are gone
    v = [0.3, -1.2, 2.0]
    assert np.array_equal(np.array(g(v)), np.array(f(v))) and np.allclose(np.array(k(v)), np.array(f(v)), rtol=1e-15)
