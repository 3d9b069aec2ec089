"""Compilation of hot Functions to C (transcription/codegen.py): fallback, cache, equality."""
from __future__ import annotations

import json
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.problems.models import GM_NORMALIZED, Dumbbell, Gravity, RigidBody
from se3ocp.transcription.compile import codegen
from se3ocp.transcription.dynamics.lgvi import Discretization
from se3ocp.transcription.methods.indirect.conditions import costate_functions
from se3ocp.transcription.methods.indirect.control import bound_data
from se3ocp.transcription.methods.indirect.shooting import shooting_functions
from se3ocp.transcription.methods.indirect.solve import weight_inverse
from se3ocp.transcription.nlp.blocks import dynamics
from se3ocp.transcription.geometry.so3 import exp_so3
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
    b = se3ocp.solve(man, "indirect", eps_S=0.0)      # on a cold cache: interpreted first, then compiled
    libs, deadline = shooting_functions(man.problem.disc, 40, True).libraries, time.monotonic() + 600.0
    while not codegen.ready(libs, codegen.QUICK_CFLAGS) and time.monotonic() < deadline:
        time.sleep(0.2)                                # its maps' builds (a cold suite's queue: other builds too)
    c = se3ocp.solve(man.problem.replace(disc=Discretization(man.problem.model, scheme)), "indirect", eps_S=0.0)
    assert not a.stats["jit"] and b.stats["jit"] and c.stats["jit"] and a.converged
    assert not shooting_functions(c.problem.disc, 40, True).switches
    for s in (b, c):
        assert [r.residual for r in a.history] == [r.residual for r in s.history]
        assert np.array_equal(a.controls, s.controls) and np.array_equal(a.warm.lam0, s.warm.lam0)


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


def _policy(monkeypatch, tmp_path) -> list[str]:
    """An empty compile cache of its own, the interpreted-first policy on, codegen's notices (one per build started)
    collected."""
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    monkeypatch.delenv("SE3OCP_JIT_BACKGROUND", raising=False)
    said: list[str] = []
    monkeypatch.setattr(codegen, "notify", said.append)
    return said


def test_new_numbers_in_a_known_structure_compile_nothing(monkeypatch, tmp_path):
    """Mass, inertia, mu, J2 and its radius (the model's numbers) and the bounds are data of the compiled Functions:
    a second problem that differs from a first only in those numbers compiles nothing (codegen's notice is the
    count: one per background build started) and runs on the first one's compiled code, equal to the interpreted
    solve to round-off."""
    if not codegen.available():
        pytest.skip("no C compiler")
    said = _policy(monkeypatch, tmp_path)
    j2 = ("gravity.kind=j2", "gravity.J2=1.0e-3", "gravity.radius=0.9")
    a = problem("e3_bounded", 20, "first_order", *j2, "control.bounds.force.norm=15.5")
    sa = se3ocp.solve(a.replace(disc=Discretization(a.model, a.scheme)))   # interpreted first
    ra = se3ocp.solve(a.replace(disc=Discretization(a.model, a.scheme)), jit=False)
    assert sa.converged and sa.stats["jit"] and len(said) == 2          # the dynamics block's jac and hess
    assert sa.iterations == ra.iterations and abs(sa.cost - ra.cost) <= 1e-12 * ra.cost
    assert np.max(np.abs(sa.controls - ra.controls)) <= 1e-12 * np.max(np.abs(ra.controls))
    libs = dynamics(a.disc, True, True).derivatives(True)._libraries
    deadline = time.monotonic() + 300.0                                 # their -O0 builds (the -O1 ones follow)
    while None in codegen.arrived(codegen.candidates(libs, quick=codegen.QUICK_CFLAGS))[0] and \
            time.monotonic() < deadline:
        time.sleep(0.2)
    body = Dumbbell(mass=1.02, length=0.11, sphere_radius=0.025, mu=1.01 * GM_NORMALIZED, gravity="j2", J2=2e-3,
                    J2_radius=0.85).body_model()
    b = problem("e3_bounded", 20, "first_order", *j2, "control.bounds.force.norm=16")
    b = b.replace(disc=Discretization(body, b.scheme))
    sb, ref = se3ocp.solve(b), se3ocp.solve(b, jit=False)
    d = dynamics(b.disc, True, True).derivatives(True)
    stopped = codegen.stop(tmp_path)                                    # the -O1 builds: not waited for here
    deadline = time.monotonic() + 60.0      # under load a stopped build's files go a little later, or the second
    while (codegen.building(tmp_path) or list(tmp_path.glob("*.building"))) and time.monotonic() < deadline:
        stopped += codegen.stop(tmp_path)   # -O1 build starts (one slot) after the first is stopped: stop it too
        time.sleep(0.2)
    assert len(said) == 2 and d.compiled and d.hess.class_name() == "External"
    assert sb.stats["jit"] and not ref.stats["jit"]
    assert sb.converged and sb.iterations == ref.iterations and abs(sb.cost - sa.cost) > 1e-3 * sa.cost
    assert abs(sb.cost - ref.cost) <= 1e-12 * ref.cost
    assert np.max(np.abs(sb.controls - ref.controls)) <= 1e-12 * np.max(np.abs(ref.controls))
    assert not codegen.building(tmp_path) and not list(tmp_path.glob("*.building")) and stopped <= 2
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]      # the stopped jobs' files are gone


def test_new_numbers_compile_nothing_in_the_indirect_method(monkeypatch, tmp_path):
    """The indirect method's per-step maps take the model's numbers theta as data too: a model that differs in mass,
    size and mu starts no build once the first model's maps are compiled, runs on them (no Switch left), and equals
    its interpreted solve (the maps with the numbers as constants) to round-off."""
    if not codegen.available():
        pytest.skip("no C compiler")
    said = _policy(monkeypatch, tmp_path)
    a = fresh("e3", 30)
    sa = se3ocp.solve(a, "indirect")
    assert sa.converged and sa.stats["jit"] and len(said) == 3          # costate map, its Hessian, linearized map
    codegen.settle(300.0)
    body = Dumbbell(mass=1.05, length=0.11, sphere_radius=0.025, mu=1.02 * GM_NORMALIZED).body_model()
    b = a.replace(disc=Discretization(body, a.scheme))
    sb, ref = se3ocp.solve(b, "indirect"), se3ocp.solve(b, "indirect", jit=False)
    fns = shooting_functions(b.disc, b.N, True)
    assert len(said) == 3 and fns.compiled and not fns.switches
    assert sb.converged and ref.converged and abs(sb.cost - sa.cost) > 1e-3 * sa.cost
    assert abs(sb.cost - ref.cost) <= 1e-12 * ref.cost
    assert np.max(np.abs(sb.controls - ref.controls)) <= 1e-10 * np.max(np.abs(ref.controls))


def _probe(name: str, expr) -> tuple[ca.Function, codegen.Library]:
    """A small Function of one 3-vector, x -> expr(x), and its one-Function library (with CSE)."""
    x = ca.SX.sym("x", 3)
    f = ca.Function(name, [x], [expr(x)])
    return f, codegen.Library(f.name(), (f,), cse=True)


def test_a_first_use_runs_interpreted_and_the_build_follows_in_the_background(monkeypatch, tmp_path):
    """Interpreted first: a cache miss is not waited for -- the Function comes back interpreted while a detached
    process compiles it at -O0 and then at its own flags into the cache (no lock, no job files left); the next
    build loads the library.  Same values either way, bit for bit."""
    if not codegen.available():
        pytest.skip("no C compiler")
    said = _policy(monkeypatch, tmp_path)
    f, lib = _probe("background_probe", lambda x: ca.sin(x) * x[0] + ca.exp(x[1]))
    (g,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)
    assert g is f and codegen.last_provisional and len(said) == 1
    (g2,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)   # under way: no second build
    assert len(said) == 1
    codegen.settle(120.0)
    assert codegen.ready([lib]) and not list(tmp_path.glob("*.building"))
    assert all(p.exists() for p in codegen.candidates([lib], quick=codegen.QUICK_CFLAGS)[0])   # -O1 and -O0
    (k,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)
    assert k.class_name() == "External" and not codegen.last_provisional
    assert not [p for p in tmp_path.iterdir() if p.is_dir()]      # the job's files are gone
    v = [0.3, -1.2, 2.0]
    assert np.array_equal(np.array(k(v)), np.array(f(v)))


def test_a_library_with_a_quick_build_gets_only_its_later_stage_in_the_background(monkeypatch, tmp_path):
    """A library whose -O0 build is cached (its -O1 one not: a build stopped in between) is loaded from it at once,
    and the background build that follows compiles only the -O1 stage, as a later stage (niced): no solve waits."""
    if not codegen.available():
        pytest.skip("no C compiler")
    said = _policy(monkeypatch, tmp_path)
    f, lib = _probe("later_probe", lambda x: ca.cos(x) * x[2] + ca.exp(x[0]))
    monkeypatch.setenv("SE3OCP_JIT_BACKGROUND", "0")
    codegen.compiled_libraries([lib], cflags=codegen.QUICK_CFLAGS)          # the -O0 build only
    monkeypatch.delenv("SE3OCP_JIT_BACKGROUND")
    builds = []
    spawn = codegen.spawn
    monkeypatch.setattr(codegen, "spawn", lambda b, notify=None: (builds.extend(b), spawn(b, notify)))
    (g,), = codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)
    assert g.class_name() == "External" and codegen.last_provisional and len(said) == 2
    assert [(len(stages), waited) for _, stages, waited in builds] == [(1, False)]
    codegen.settle(120.0)
    assert codegen.ready([lib]) and not list(tmp_path.glob("*.building"))
    v = [0.3, -1.2, 2.0]
    assert np.array_equal(np.array(codegen.compiled_libraries([lib], quick=codegen.QUICK_CFLAGS)[0][0](v)),
                          np.array(f(v)))


def test_a_switch_moves_to_the_compiled_code_as_it_arrives(monkeypatch, tmp_path):
    """codegen.Switch evaluates its interpreted Function until the library arrives in the cache, then the compiled
    one (within the same NLP or Newton iteration: it checks at every evaluation), with the same values; it does not
    look again once at the library's own flags."""
    if not codegen.available():
        pytest.skip("no C compiler")
    monkeypatch.setenv("SE3OCP_CACHE", str(tmp_path))
    x, y = ca.SX.sym("x", 3), ca.SX.sym("y", 2)
    f = ca.Function("switch_probe", [x, y], [ca.sin(x) * y[0] + ca.cos(y[1]), ca.dot(x, x)])
    lib = codegen.Library(f.name(), (f,), cse=True)
    sw = codegen.Switch(f.map(4), [lib], lambda loaded, paths: loaded[0][0].map(4))
    X, Y = ca.MX.sym("X", 3, 4), ca.MX.sym("Y", 2, 4)
    F = ca.Function("F", [X, Y], sw(X, Y))            # inside an MX graph, as in the NLP's derivatives
    v = (np.arange(12.0).reshape(3, 4) / 7, np.arange(8.0).reshape(2, 4) / 5)
    before = [np.array(o) for o in F(*v)]
    assert not sw.final and sw.fn.class_name() != "External"
    monkeypatch.setenv("SE3OCP_JIT_BACKGROUND", "0")
    codegen.compiled_libraries([lib])                # the library arrives (here: compiled now)
    after = [np.array(o) for o in F(*v)]
    assert sw.final and sw.paths == (codegen.candidates([lib])[0][0],)     # the library at its own flags
    want = [np.array(o) for o in f.map(4)(*v)]
    assert all(np.array_equal(a, b) and np.array_equal(a, c) for a, b, c in zip(before, after, want))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_the_shooting_moves_to_each_library_as_it_lands(monkeypatch, tmp_path, scheme):
    """The indirect method's shooting Functions, built once on a cold cache, hold a codegen.Switch per N-step map
    (costate rollout, Hessians, linearized recursion): each moves to its own library as that lands -- the costate
    map first, before the Jacobian's two -- and the rollout, the Jacobian at it and the Jacobian from scratch equal
    the interpreted ones bit for bit at every stage.  (No background build here: the libraries are compiled in
    the test, one after the other, in the order the builder takes them.)"""
    if not codegen.available():
        pytest.skip("no C compiler")
    said = _policy(monkeypatch, tmp_path)
    spawned = []
    monkeypatch.setattr(codegen, "spawn", lambda builds, notify=None: spawned.append([b[0].name for b in builds]))
    p = problem("e3_bounded", 12, scheme)
    fns = shooting_functions(Discretization(p.model, scheme), 12, True)
    ref = shooting_functions(Discretization(p.model, scheme), 12, False)
    assert len(fns.switches) == 3 and spawned == [[lib.name for lib in fns.libraries]] and not said
    assert "costate_map" in fns.libraries[0].name
    args = (p.X0, p.terminal.X, p.h, weight_inverse(p), bound_data(p))
    lam = np.linspace(-3.0, 4.0, 12)                     # the controls saturate on some steps

    def values(f):
        out = f.rollout(lam, *args)
        return [np.array(o) for o in (*out, *f.jac_given(lam, *args, *out[3:]), *f.shoot_jac(lam, *args))]

    want = values(ref)
    monkeypatch.setenv("SE3OCP_JIT_BACKGROUND", "0")
    for k, lib in enumerate([None, *fns.libraries]):
        if lib is not None:
            codegen.compiled_libraries([lib], cflags=codegen.QUICK_CFLAGS)      # it lands
        got = values(fns)
        assert [sw.paths[0] is not None for sw in fns.switches] == [i < k for i in range(3)]
        assert all(np.array_equal(a, b) for a, b in zip(got, want))
    assert all(sw.final for sw in fns.switches)


@pytest.mark.parametrize("name,scheme", [("e3", "first_order"), ("e4", "lgvi"), ("e3_bounded", "lgvi")])
def test_the_parametric_costate_map_equals_the_numeric_one(name, scheme):
    """costate_functions(disc, parametric=True) -- the model's numbers theta the last input, what the shooting compiles
    once per structure -- given theta = model.parameters, equals the map with the numbers as constants: the states
    bit for bit, the costates and the variation A to round-off (1e-13 relative; (2J)^-1 and J enter as data instead
    of folded constants)."""
    p = problem(name, 10, scheme)
    num, par = costate_functions(p.disc)[0], costate_functions(p.disc, True)[0]
    rng = np.random.default_rng(5)
    X = np.array(p.X0, dtype=float)
    args = [X, 1e-2 * rng.normal(size=12), p.h, np.linalg.inv(p.control.W), np.r_[np.full(6, np.inf), 1e300, 1e300,
                                                                                  np.zeros(10)]]
    a, b = ([np.array(o) for o in f(*args, *extra)] for f, extra in ((num, ()), (par, (p.model.parameters,))))
    assert np.array_equal(a[0], b[0])
    for x, y in zip(a[1:], b[1:]):
        assert np.max(np.abs(x - y)) <= 1e-13 * max(1.0, np.max(np.abs(x)))


def test_stop_collects_an_ended_builder_and_its_lock(tmp_path):
    """A builder that ended without removing its lock (killed while still starting, before its SIGTERM handler) and
    is not yet collected is a zombie, which a signal 0 takes for a live build: stop() collects it and removes the
    lock and the job it left (the cache keeps no orphan), so building() is empty at once instead of until the parent
    happens to reap it (a CI run under load left two such locks for the 60 s of
    test_new_numbers_in_a_known_structure_compile_nothing, and a run on two workers its job)."""
    import subprocess
    import sys

    from se3ocp.transcription.compile import build

    if not Path("/proc").is_dir():
        pytest.skip("the process table is read from /proc (Linux)")
    proc = subprocess.Popen([sys.executable, "-c", "pass"], start_new_session=True)
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:        # ended, not collected: a zombie
        with open(f"/proc/{proc.pid}/stat") as f:
            if f.read().split(")")[-1].split()[0] == "Z":
                break
        time.sleep(0.05)
    lock = tmp_path / "lib.so.building"
    lock.write_text(str(proc.pid))
    job = tmp_path / "background_x"        # its job, which a builder ended by its SIGTERM handler removes first
    job.mkdir()
    (job / "job.json").write_text(json.dumps([{"lock": str(lock)}]))
    other = tmp_path / "other.so.building"  # a build whose lock is being written (no pid yet): under way, its job stays
    other.write_text("")
    live = tmp_path / "background_y"
    live.mkdir()
    (live / "job.json").write_text(json.dumps([{"lock": str(other)}]))
    assert sorted(build.building(tmp_path)) == sorted([lock, other])
    assert build.stop(tmp_path, timeout=1.0) == 1
    assert build.building(tmp_path) == [other] and not lock.exists()
    assert not job.exists() and live.is_dir()
