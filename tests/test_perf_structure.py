"""Speed work of issue 6 keeps the mathematics: stage-wise derivatives, linearized Psi, codegen.

* the stage-assembled Jacobian and Hessian of the direct NLP equal CasADi's AD of the
  SX-expanded NLP (the pre-issue-6 construction) at random points;
* Psi from the linearized recursion equals forward AD through the rollout;
* the seeded variation equals the Newton-solved one;
* code generation falls back cleanly without a compiler; (slow) compiled runs give the same
  iterates as interpreted ones.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import examples as ex
from se3ocp.transcription import codegen, direct
from se3ocp.transcription.indirect import shooting_functions, weight_inverse

SCHEMES = ("first_order", "lgvi")


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("with_c", [True, False])
def test_stage_assembled_derivatives_equal_expanded_ad(scheme, with_c):
    p = ex.e4(N=12, scheme=scheme, cayley_variables=with_c)
    opts = direct._options(p)
    new = direct.DirectNLP(p, opts, structured=True)
    old = direct.DirectNLP(p, opts, structured=False)
    rng = np.random.default_rng(3)
    ng = len(new.lbg)
    guess = direct.make_guess("interpolate", p.disc, p.X0, p.Xd, p.N, p.T)
    x = new.initial_point(guess) * (1.0 + 0.01 * rng.standard_normal(new.layout.n))
    lam = rng.standard_normal(ng)
    for name, args in (("nlp_jac_g", [x, []]), ("nlp_grad_f", [x, []]), ("nlp_hess_l", [x, [], 0.7, lam])):
        a = new.solver.get_function(name)(*args)
        b = old.solver.get_function(name)(*args)
        a, b = (a if isinstance(a, (list, tuple)) else [a]), (b if isinstance(b, (list, tuple)) else [b])
        for A, B in zip(a, b):
            A, B = ca.densify(ca.DM(A)).full(), ca.densify(ca.DM(B)).full()
            if name == "nlp_hess_l":  # both upper triangles
                A, B = np.triu(A), np.triu(B)
            assert np.allclose(A, B, rtol=1e-10, atol=1e-10 * max(1.0, np.abs(B).max())), name


@pytest.mark.parametrize("scheme", SCHEMES)
def test_psi_equals_forward_ad_through_the_rollout(scheme):
    p = ex.e3(N=30, scheme=scheme)
    fns = shooting_functions(p.disc, 30)
    args = (p.X0, p.Xd, p.h, weight_inverse(p))
    lam = np.random.default_rng(0).standard_normal(12) * 0.01
    assert float(fns.residual(lam, *args)[1]) <= 1e-10  # a valid rollout (the Cayley equation solved)
    l = ca.MX.sym("l", 12)
    ad = ca.Function("ad", [l], [ca.jacobian(fns.residual(l, *args)[0], l)])
    P_ad = np.array(ad(lam))
    P = np.array(fns.shoot_jac(lam, *args)[1])
    assert np.abs(P - P_ad).max() <= 1e-10 * np.abs(P_ad).max()


def test_lgvi_stage_control_is_a_momentum_kick():
    """The linearized LGVI recursion (indirect.linearized_map) uses step(X, [u_k; u]) = step(chart(X, B^b u_k), [0; u]):
    u_k enters as the kick B^b u_k of (gamma, Pi), B^b = dX_{k+1}/du_{k+1} (control_matrix)."""
    from se3ocp.transcription.indirect import control_matrix
    from se3ocp.transcription.lgvi import chart

    d = ex.disc("lgvi")
    p = ex.e4(N=50, scheme="lgvi")
    Bb = np.array(control_matrix(d)(p.h))
    rng = np.random.default_rng(5)
    for _ in range(3):
        uk, u1 = rng.standard_normal(6) * [1, 1, 1, 1e-2, 1e-2, 1e-2], rng.standard_normal(6)
        a = np.array(d.step(p.X0, np.r_[uk, u1], p.h)[0]).ravel()
        b = np.array(d.step(np.array(chart(ca.DM(p.X0), ca.DM(Bb @ uk))).ravel(), np.r_[np.zeros(6), u1], p.h)[0]).ravel()
        assert np.abs(a - b).max() <= 1e-14 * np.abs(a).max()


@pytest.mark.parametrize("scheme", SCHEMES)
def test_seeded_variation_equals_solved(scheme):
    d = ex.disc(scheme)
    rng = np.random.default_rng(1)
    p = ex.e4(N=50, scheme=scheme)
    w = rng.standard_normal(d.nw)
    c0 = d.cayley_solve(d.cayley_rhs(p.X0, w, p.h))[0]
    A, B = (np.array(a) for a in d.variation(p.X0, w, p.h))
    A2, B2 = (np.array(a) for a in d.variation_seeded(p.X0, w, p.h, c0))
    assert np.abs(A - A2).max() <= 1e-12 * np.abs(A).max() and np.abs(B - B2).max() <= 1e-12 * np.abs(B).max()


def test_codegen_falls_back_without_compiler(monkeypatch):
    monkeypatch.setenv("SE3OCP_NO_JIT", "1")
    x = ca.SX.sym("x", 2)
    f = ca.Function("fallback_probe", [x], [ca.sin(x)])
    assert codegen.compiled(f) is f and "no C compiler" in codegen.last_error
    direct._stage_functions.cache_clear()
    try:
        s = direct.solve_direct(ex.e3(N=10, scheme="first_order", jit=True))
    finally:
        direct._stage_functions.cache_clear()
    assert s.converged and s.extra["jit"] is False
    # the indirect method (jit on by default) falls back the same way
    from se3ocp.transcription.indirect import DEFAULT_OPTIONS, solve_indirect

    assert DEFAULT_OPTIONS["jit"] is True
    shooting_functions.cache_clear()
    try:
        s = solve_indirect(ex.e3(N=30, scheme="first_order"))
    finally:
        shooting_functions.cache_clear()
    assert s.converged and s.extra["jit"] is False


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
    from se3ocp.transcription.indirect import solve_indirect

    a = solve_indirect(ex.e4(N=40, scheme=scheme, jit=False, eps_S=0.0))
    b = solve_indirect(ex.e4(N=40, scheme=scheme, eps_S=0.0))
    assert not a.extra["jit"] and b.extra["jit"] and a.converged
    assert [r["error"] for r in a.history] == [r["error"] for r in b.history]
    assert np.array_equal(a.controls, b.controls) and np.array_equal(a.extra["lam0"], b.extra["lam0"])


@pytest.mark.slow
@pytest.mark.parametrize("scheme", SCHEMES)
def test_compiled_runs_equal_interpreted(scheme):
    if not codegen.available():
        pytest.skip("no C compiler")
    a = direct.solve_direct(ex.e4(N=60, scheme=scheme))
    b = direct.solve_direct(ex.e4(N=60, scheme=scheme, jit=True))
    assert b.extra["jit"] and a.iterations == b.iterations
    assert abs(a.cost - b.cost) <= 1e-12 * a.cost
    from se3ocp.transcription.indirect import solve_indirect

    c = solve_indirect(ex.e4(N=60, scheme=scheme, jit=False))
    d = solve_indirect(ex.e4(N=60, scheme=scheme))              # jit is the indirect default
    assert d.extra["jit"] and not c.extra["jit"] and c.converged and d.converged
    assert c.cost == d.cost and c.iterations == d.iterations


@pytest.mark.parametrize("solver", ["ipopt", "fatrop"])
def test_solve_time_split_accounts_for_the_solve(solver):
    """extra['evaluations_s'] + extra['solver_internal_s'] = solve_s, split over the NLP Functions."""
    s = direct.solve_direct(ex.e3(N=20, scheme="first_order", solver=solver))
    assert s.converged and s.solver == solver
    by = s.extra["evaluations_by_function"]
    assert {"nlp_jac_g", "nlp_hess_l", "nlp_g"} <= set(by) and all(v >= 0.0 for v in by.values())
    assert by["nlp_hess_l"] > 0.0 and by["nlp_jac_g"] > 0.0
    assert s.extra["evaluations_s"] == pytest.approx(sum(by.values()), rel=1e-12)
    assert 0.0 < s.extra["evaluations_s"] <= s.solve_s
    assert s.extra["evaluations_s"] + s.extra["solver_internal_s"] == pytest.approx(s.solve_s, rel=1e-9)


def test_solve_time_split_without_stats():
    """A failed solver call (no stats) gives zeros, never a negative solver share."""
    out = direct.solve_time_split({}, 0.5)
    assert out == {"evaluations_s": 0.0, "solver_internal_s": 0.5, "evaluations_by_function": {}}
    assert direct.solve_time_split({"t_wall_nlp_f": 2.0}, 1.0)["solver_internal_s"] == 0.0


def test_fatrop_own_time_is_part_of_the_solver_share():
    s = direct.solve_direct(ex.e3(N=20, scheme="first_order", solver="fatrop"))
    assert s.solver == "fatrop" and 0.0 < s.extra["fatrop_own_s"] <= s.extra["solver_internal_s"]


def test_direct_default_compiles_when_it_can():
    """jit is on by default for the direct method (and off with SE3OCP_NO_JIT, see the fallback test)."""
    if not codegen.available():
        pytest.skip("no C compiler")
    assert direct.DIRECT_OPTION_DEFAULTS["jit"] is True
    s = direct.solve_direct(ex.e3(N=10, scheme="first_order"))
    assert s.converged and s.extra["jit"] is True


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
