"""The indirect method (transcription/methods/indirect/, docs/mathematics.md §6): necessary conditions, Psi_12,
Newton-Armijo, agreement with the direct method.

Default run: N = 100 (h = 5e-3) and smaller; the N = 500 versions of the
acceptance figures are marked slow (``pytest -m slow tests/test_indirect.py``).
Numbers measured are printed (run with -s to see them).
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NU, NX, U_FORCE, U_MOMENT, Z_ANG, Z_MOM
from se3ocp.transcription.solve import solve_direct
from se3ocp.transcription.methods.indirect.conditions import terminal_residual_function
from se3ocp.transcription.methods.indirect.control import bound_data, control_cost, weight_inverse
from se3ocp.transcription.methods.indirect.shooting import shooting_functions
from se3ocp.transcription.methods.indirect.solve import (lam0_from_costates, outer_errors, quadratic_constant, solve_indirect)
from se3ocp.transcription.options import IndirectOptions, OptionError
from se3ocp.transcription.outcome import Result
from se3ocp.transcription.results.solution import Solution
from se3ocp.transcription.results.start import Start
import support

EXAMPLES = {"E3": "e3", "E4": "e4"}


def problem(name: str, N: int, scheme: str = "first_order"):
    return support.problem(EXAMPLES[name], N, scheme)


def lam0_warm(p, lam0) -> Start:
    """A warm start that carries a shooting unknown lambda_0 (its primal part: the free motion)."""
    X, _ = p.disc.simulate(p.X0, None, p.h, p.N)
    return Start(t=p.h * np.arange(p.N + 1), X=X, U=np.zeros((NU, p.disc.n_controls(p.N))), scheme=p.scheme,
                     source="indirect", lam0=np.asarray(lam0, dtype=float))


def indirect(p, lam0=None, progress=None, **options):
    """solve_indirect from ``lam0``: 12 numbers, or a Solution whose warm start it takes."""
    warm = lam0.warm if isinstance(lam0, Solution) else None if lam0 is None else lam0_warm(p, lam0)
    return solve_indirect(p, IndirectOptions(**options), progress, warm)


def _args(p):
    return (p.X0, p.Xd, p.h, weight_inverse(p), bound_data(p))


@pytest.fixture(scope="module")
def solved():
    """Indirect solutions of E3 and E4 at N = 100 from lambda_0 = 0, eps_S = 0 (run to the floor)."""
    return {name: indirect(problem(name, 100), eps_S=0.0) for name in EXAMPLES}


# ------------------------------------------------------------- necessary conditions
def test_forward_map_is_the_stated_recursion(solved):
    """On a rollout from a perturbed lambda_0 (the E3 solution's, 10 % random): lambda_{k-1} = A_k^T lambda_k
    (28) with A_k from disc.variation evaluated independently, and u_{k+1} = -W^-1 [lambda^2_k; lambda^4_k]
    (26)-(27).  (Arbitrary lambda_0 of this size make the body spin faster than the Cayley solve allows.)"""
    p = problem("E3", 100)
    rng = np.random.default_rng(0)
    lam0 = solved["E3"].warm.lam0 * (1 + 0.1 * rng.standard_normal(12))
    _, X, lam, U, res, lres = (np.array(a) for a in shooting_functions(p.disc, p.N).shoot(lam0, *_args(p)))
    Xall = np.hstack([p.X0[:, None], X])
    Wf, Wm = p.control.W_f, p.control.W_m
    for k in range(p.N):
        lk = lam[:, k]
        np.testing.assert_allclose(U[U_FORCE, k], -np.linalg.solve(Wf, lk[Z_MOM]), rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(U[U_MOMENT, k], -np.linalg.solve(Wm, lk[Z_ANG]), rtol=1e-13, atol=1e-15)
        if k >= 1:
            A = np.array(p.disc.variation(Xall[:, k], np.zeros(NU), p.h)[0])
            np.testing.assert_allclose(A.T @ lk, lam[:, k - 1], rtol=0, atol=1e-12 * np.abs(lam[:, k - 1]).max())
    assert np.max(res) < 1e-12 and np.max(lres) < 1e-13


def test_A_and_B_do_not_depend_on_the_stage_control():
    """The forward recursion needs A_k independent of u_{k+1} (first-order scheme): check numerically."""
    p = problem("E4", 10)
    rng = np.random.default_rng(1)
    A0, B0 = (np.array(a) for a in p.disc.variation(p.X0, np.zeros(NU), p.h))
    A1, B1 = (np.array(a) for a in p.disc.variation(p.X0, rng.standard_normal(NU), p.h))
    np.testing.assert_allclose(A1, A0, atol=1e-14)
    np.testing.assert_allclose(B1, B0, atol=1e-14)
    Bblock = np.zeros((12, NU))
    Bblock[Z_MOM, U_FORCE] = p.h * np.eye(3)
    Bblock[Z_ANG, U_MOMENT] = p.h * np.eye(3)
    np.testing.assert_allclose(B0, Bblock, atol=1e-15)


def _reduced_gradient_check(name, p, sol):
    """|grad J + (dz_N/dU)^T lambda_{N-1}| / |grad J| at a solution, dz_N/dU by reverse AD of the
    plain state rollout (disc.step only, no costates) and the terminal residual."""
    # X_{k+1} only: the Cayley-residual output of disc.step has a norm whose derivative at 0 is
    # NaN, which a reverse sweep would spread
    Xsym, wsym = ca.SX.sym("X", NX), ca.SX.sym("w", p.disc.nw)
    step_x = ca.Function("step_x", [Xsym, wsym], [p.disc.step(Xsym, wsym, p.h)[0]])
    U = ca.MX.sym("U", NU, p.disc.n_controls(p.N))
    Xs = step_x.mapaccum("acc", p.N)(p.X0, p.disc.stage_controls(U))
    zN = terminal_residual_function()(Xs[:, -1], p.Xd)
    dz = np.array(ca.Function("dz", [U], [ca.jacobian(zN, ca.vec(U))])(sol.controls))  # 12 x 6n, column-major vec
    W = p.control.W
    omega = np.full(sol.controls.shape[1], p.h)
    if p.disc.scheme == "lgvi":
        omega[[0, -1]] *= 0.5
    gradJ = (omega * (W @ sol.controls)).T.ravel()  # same column-major order
    lamN1 = sol.costates[-1]
    rel = np.abs(gradJ + dz.T @ lamN1).max() / np.abs(gradJ).max()
    wrong_sign = np.abs(gradJ - dz.T @ lamN1).max() / np.abs(gradJ).max()
    print(f"{name} {p.disc.scheme}: |grad J + dz_N/dU^T lambda_(N-1)| / |grad J| = {rel:.2e} (opposite sign: {wrong_sign:.1e})")
    assert rel < 1e-9
    assert wrong_sign > 1.0


def test_sign_convention_by_the_reduced_gradient(solved):
    """Independent of the costate recursion: at the solution the gradient of the cost equals
    -(dz_N/dU)^T lambda_{N-1}.  This fixes the sign of L = J + sum lambda_k^T (step - X_{k+1})."""
    for name, sol in solved.items():
        _reduced_gradient_check(name, problem(name, 100), sol)


def test_sign_convention_lgvi():
    p = problem("E4", 50, "lgvi")
    sol = indirect(p, eps_S=0.0)
    assert sol.converged, sol.message
    _reduced_gradient_check("E4", p, sol)


# ------------------------------------------------------------------------ Psi_12
@pytest.mark.parametrize("name,scheme,N", [("E3", "first_order", 100), ("E4", "first_order", 100), ("E4", "lgvi", 100),
                                           pytest.param("E3", "first_order", 500, marks=pytest.mark.slow),
                                           pytest.param("E4", "first_order", 500, marks=pytest.mark.slow)])
def test_psi_against_finite_differences(name, scheme, N, solved):
    """Psi_12 (forward AD through the rollout) vs finite differences of z_N(lambda_0):
    max column-wise relative error <= 1e-6, at lambda_0 = 0 and at a point near the solution
    (the N = 100 solution's lambda_0, perturbed by 5 %)."""
    p = problem(name, N, scheme)
    fns = shooting_functions(p.disc, p.N)
    rng = np.random.default_rng(2)
    near = solved[name].warm.lam0
    if scheme == "lgvi":  # the unknown is lambda_{-1}; the first-order lambda_0 is close enough
        near = np.array(p.disc.variation(p.X0, np.r_[solved[name].controls[:, 0], np.zeros(NU)], p.h)[0]).T @ near
    for lam0 in (np.zeros(12), near * (1 + 0.05 * rng.standard_normal(12))):
        _, Psi, _ = (np.array(a) for a in fns.shoot_jac(lam0, *_args(p)))
        fd = np.zeros_like(Psi)

        def z(l):
            return np.array(fns.residual(l, *_args(p))[0]).ravel()

        for j in range(12):  # five-point central differences (4th order): truncation and round-off both ~1e-8
            d = 1e-4 * max(1.0, abs(lam0[j]))
            e = np.zeros(12)
            e[j] = d
            fd[:, j] = (8 * (z(lam0 + e) - z(lam0 - e)) - (z(lam0 + 2 * e) - z(lam0 - 2 * e))) / (12 * d)
        err = max(np.linalg.norm(fd[:, j] - Psi[:, j]) / np.linalg.norm(Psi[:, j]) for j in range(12))
        print(f"{name} {scheme} N={N}: Psi_12 vs finite differences, max column relative error {err:.2e}")
        assert err <= 1e-6


# ------------------------------------------------------------------ Newton-Armijo
def _check_run(name, sol, max_outer=50, tol=1e-11):
    e = outer_errors(sol.history)
    C = quadratic_constant(sol.history, floor=10 * sol.stats["noise_level"])
    print(f"{name} N={sol.N}: {sol.result}, {sol.iterations} outer iterations, terminal error {sol.terminal_error:.2e}, "
          f"cost {sol.cost:.10g}, C = {C}, solve {sol.solve_s:.2f} s\n  |z_N| per outer iteration: "
          + " ".join(f"{v:.1e}" for v in e))
    assert sol.converged, sol.message
    assert sol.iterations <= max_outer
    assert sol.terminal_error <= tol
    # quadratic convergence before the floor: e_{i+1} <= C e_i^2 over the full Newton steps of the
    # local phase (e_i <= 0.1) that end above 10x the measured round-off level; at least two of them
    acc = [r for r in sol.history if r.accepted]
    pairs = [(a.residual, b.residual) for a, b in zip(acc[:-1], acc[1:])
             if b.step == 1.0 and a.residual <= 0.1 and b.residual > 10 * sol.stats["noise_level"]]
    assert len(pairs) >= 2, pairs
    assert C is not None and C <= 2e3
    assert all(b <= (1 + 1e-9) * C * a * a for a, b in pairs)
    # the floor: reached, reported, and left after exactly one failed trial
    assert sol.result is Result.round_off_floor and "round-off floor" in sol.message
    assert sol.stats["roundoff_floor"] == pytest.approx(e[-1])
    last = [r for r in sol.history if r.iteration == sol.iterations + 1]
    assert len(last) == 1 and not last[0].accepted
    # every outer iteration and trial recorded
    assert len(e) == sol.iterations + 1
    assert sum(1 for r in sol.history if r.trial > 0) == sum(1 for r in sol.history if r.iteration >= 1)


@pytest.mark.parametrize("name", ["E3", "E4"])
def test_newton_armijo_from_zero(name, solved):
    _check_run(name, solved[name])


def test_solution_is_consistent(solved):
    """controls u_1..u_N from lambda_k; trajectory re-simulated; cost = sum (h/2) u^T W u."""
    sol = solved["E3"]
    p = sol.problem
    assert sol.controls.shape == (6, 100) and sol.costates.shape == (100, 12)
    X, _ = p.disc.simulate(p.X0, sol.controls, p.h, p.N)
    np.testing.assert_array_equal(X, sol.trajectory.X)
    assert sol.cost == pytest.approx(control_cost(p, sol.controls), rel=1e-14)
    assert sol.trajectory.orthogonality()["max_orthogonality_error"] < 1e-13
    assert sol.method == "indirect" and sol.solver == "newton-armijo"


def test_progress_called_once_per_outer_iteration():
    calls = []
    sol = indirect(problem("E3", 30), progress=calls.append)
    assert len(calls) == sol.iterations >= 1
    assert [c.iteration for c in calls] == list(range(1, sol.iterations + 1))


# ------------------------------------------------------------------- failure is data
def test_failures_are_data():
    sol = indirect(problem("E4", 30), max_iter=1, eps_S=0.0)
    assert not sol.converged and sol.result is Result.max_iterations and "no convergence in 1 iterations" in sol.message
    sol = indirect(problem("E4", 30), lam0=np.full(12, np.nan))
    assert not sol.converged and sol.result is Result.non_finite and "non-finite" in sol.message
    with pytest.raises(OptionError, match="initial_costate"):
        IndirectOptions(initial_costate=[1.0, 2.0])


def test_line_search_failure_is_reported():
    """E4 from lambda_0 = 0: the first full Newton step does not satisfy Armijo; with no halvings
    allowed the line search fails, and that is reported (not raised)."""
    sol = indirect(problem("E4", 100), max_halvings=0, eps_S=0.0)
    assert not sol.converged and sol.result is Result.line_search_failed
    assert "line search failed" in sol.message and sol.iterations == 0
    assert [r.accepted for r in sol.history] == [True, False]


def test_rollouts_that_break_the_cayley_solve_are_rejected():
    """A lambda_0 whose controls spin the body faster than the step's Cayley solve allows is not a
    rollout of the discrete equations: rejected at the start (and as a line-search trial)."""
    sol = indirect(problem("E4", 30), lam0=np.r_[np.zeros(9), 1e4, 1e4, 1e4])
    assert not sol.converged and sol.result is Result.invalid_option and "Cayley" in sol.message


def test_explicit_initial_costate_and_eps_S():
    """initial_costate as 12 numbers; the eps_S stop (before the floor)."""
    ref = indirect(problem("E3", 30), eps_S=0.0)
    sol = indirect(problem("E3", 30), eps_S=1e-6, initial_costate=list(ref.warm.lam0 * 1.001))
    assert sol.converged and sol.result is Result.converged and sol.stats["initial_costate"] == "explicit"
    assert outer_errors(sol.history)[-1] <= 1e-6


# ------------------------------------------------- agreement with the direct method
def _agreement(name, N, dsol, isol, rsol):
    cost_rel = abs(dsol.cost - isol.cost) / dsol.cost
    u_rel = np.abs(dsol.controls - isol.controls).max() / np.abs(dsol.controls).max()
    lam_rel = np.abs(dsol.costates - isol.costates).max() / np.abs(isol.costates).max()
    print(f"{name} N={N}: direct cost {dsol.cost:.12g}, indirect cost {isol.cost:.12g}: rel {cost_rel:.1e}; "
          f"controls rel {u_rel:.1e}; mapped multipliers vs lambda_k rel {lam_rel:.1e}; restart from the direct "
          f"multipliers: {rsol.iterations} outer iterations, {rsol.result}, terminal error {rsol.terminal_error:.1e}")
    assert dsol.converged and isol.converged and rsol.converged
    assert cost_rel <= 1e-8
    assert u_rel <= 1e-6
    assert lam_rel <= 1e-6
    assert rsol.iterations <= 3
    assert rsol.terminal_error <= 1e-11


def _direct(p):
    return solve_direct(p)


@pytest.mark.parametrize("name", ["E3", "E4"])
def test_agrees_with_direct(name, solved):
    """E3 and E4 (first-order scheme, N = 100): indirect from lambda_0 = 0 and direct agree; the direct
    multipliers mapped to tangent coordinates are the lambda_k; restarted from them (the
    initial_costate: from_direct path) the indirect method converges in <= 3 outer iterations."""
    dsol = _direct(problem(name, 100))
    rsol = se3ocp.solve(problem(name, 100), "indirect", indirect=IndirectOptions(eps_S=0.0, initial_costate="from_direct"))
    assert rsol.stats["initial_costate"] == "from_direct" and rsol.stats["direct_status"] == "converged"
    _agreement(name, 100, dsol, solved[name], rsol)


# ------------------------------------------------------------------ full size (slow)
@pytest.mark.slow
@pytest.mark.parametrize("name", ["E3", "E4"])
def test_full_size_from_zero_and_agreement(name):
    """Acceptance at N = 500: from lambda_0 = 0 to <= 1e-11 in <= 50 outer iterations, quadratic,
    stops at the floor; agreement with the direct method and the from_direct restart."""
    isol = indirect(problem(name, 500), eps_S=0.0)
    _check_run(name, isol)
    dsol = _direct(problem(name, 500))
    rsol = indirect(problem(name, 500), lam0=dsol, eps_S=0.0)
    _agreement(name, 500, dsol, isol, rsol)


# ------------------------------------------------ second-order LGVI (stretch, beyond the paper)
def test_lgvi_control_enters_as_a_momentum_kick():
    """The identity behind the explicit LGVI conditions: B^a_k = dX_{k+1}/du_k = A_k(X_k, u_k) B^b,
    with B^b = dX_{k+1}/du_{k+1} constant, and A_k independent of u_{k+1} (eqs. 7-11, on the graph)."""
    p = problem("E4", 10, "lgvi")
    rng = np.random.default_rng(3)
    for _ in range(3):
        w = rng.standard_normal(2 * NU) * np.r_[np.ones(3), 1e-2 * np.ones(3), np.ones(3), 1e-2 * np.ones(3)]
        A, B = (np.array(a) for a in p.disc.variation(p.X0, w, p.h))
        A2, B2 = (np.array(a) for a in p.disc.variation(p.X0, np.r_[w[:NU], rng.standard_normal(NU)], p.h))
        Bb = B[:, NU:]
        np.testing.assert_allclose(A2, A, atol=1e-14)
        np.testing.assert_allclose(B2[:, NU:], Bb, atol=1e-15)
        np.testing.assert_allclose(B[:, :NU], A @ Bb, rtol=0, atol=1e-13 * np.abs(B[:, :NU]).max())


@pytest.mark.parametrize("name", ["E3", "E4"])
def test_lgvi_indirect_agrees_with_direct(name):
    """Second-order LGVI, N = 50: shooting on lambda_{-1} from 0 reaches the floor and agrees with the
    direct LGVI solution (trapezoidal cost) in cost, controls u_0..u_N and mapped multipliers."""
    p = problem(name, 50, "lgvi")
    isol = indirect(p, eps_S=0.0)
    _check_run(f"{name} lgvi", isol)
    assert isol.controls.shape == (6, 51) and isol.costates.shape == (50, 12)
    dsol = _direct(p)
    lam_init = lam0_from_costates(p, dsol.costates[0], dsol.controls[:, 0])  # lambda_{-1} = A_0(X_0, u_0)^T lambda_0
    A0 = np.array(p.disc.variation(p.X0, np.r_[dsol.controls[:, 0], np.zeros(NU)], p.h)[0])
    np.testing.assert_array_equal(lam_init, A0.T @ dsol.costates[0])
    rsol = indirect(p, lam0=lam_init, eps_S=0.0)
    _agreement(f"{name} lgvi", 50, dsol, isol, rsol)


def test_lgvi_stage_control_is_a_momentum_kick():
    """The linearized LGVI recursion (indirect.linearized_map) uses step(X, [u_k; u]) = step(chart(X, B^b u_k), [0; u]):
    u_k enters as the kick B^b u_k of (gamma, Pi), B^b = dX_{k+1}/du_{k+1} (control_matrix)."""
    from se3ocp.transcription.methods.indirect.control import control_matrix
    from se3ocp.transcription.geometry.state import chart

    p = problem("E4", 50, "lgvi")
    d = p.disc
    Bb = np.array(control_matrix(d)(p.h))
    rng = np.random.default_rng(5)
    for _ in range(3):
        uk, u1 = rng.standard_normal(6) * [1, 1, 1, 1e-2, 1e-2, 1e-2], rng.standard_normal(6)
        a = np.array(d.step(p.X0, np.r_[uk, u1], p.h)[0]).ravel()
        b = np.array(d.step(np.array(chart(ca.DM(p.X0), ca.DM(Bb @ uk))).ravel(), np.r_[np.zeros(6), u1], p.h)[0]).ravel()
        assert np.abs(a - b).max() <= 1e-14 * np.abs(a).max()


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_psi_equals_forward_ad_through_the_rollout(scheme):
    """Psi by the linearized coupled recursion = forward AD through the rollout, to 1e-10 relative."""
    p = problem("E3", 30, scheme)
    fns = shooting_functions(p.disc, 30)
    args = _args(p)
    lam = np.random.default_rng(0).standard_normal(12) * 0.01
    assert float(fns.residual(lam, *args)[2]) <= 1e-10  # a valid rollout (the Cayley equation solved)
    l = ca.MX.sym("l", 12)
    P_ad = np.array(ca.Function("ad", [l], [ca.jacobian(fns.residual(l, *args)[0], l)])(lam))
    P = np.array(fns.shoot_jac(lam, *args)[1])
    assert np.abs(P - P_ad).max() <= 1e-10 * np.abs(P_ad).max()


@pytest.mark.parametrize("name,scheme,sets", [("e3", "first_order", ()), ("e4", "lgvi", ()),
                                              ("e3_bounded", "lgvi", ()), ("e3", "lgvi", ("control.force_frame=body",))])
def test_the_jacobian_from_the_residuals_rollout_is_shoot_jac(name, scheme, sets):
    """RolloutCache: the residual and, at the same point, the Jacobian from that residual's rollout (rollout +
    jac_given) equal residual and shoot_jac bit for bit -- both schemes, bounds, a body-fixed force; at another point
    it falls back to shoot_jac."""
    from se3ocp.transcription.methods.indirect.shooting import RolloutCache

    p = support.problem(name, 20, scheme, *sets)
    fns = shooting_functions(p.disc, p.N)
    args = (np.array(p.X0), np.array(p.terminal.X), p.h, weight_inverse(p), bound_data(p))
    rc = RolloutCache(fns, args)
    for lam in 1e-2 * np.random.default_rng(1).normal(size=(2, 12)):
        got = [np.array(x) for x in (*rc.residual(lam), *rc.jacobian(lam))]
        want = [np.array(x) for x in (*fns.residual(lam, *args), *fns.shoot_jac(lam, *args))]
        assert all(np.array_equal(a, b) for a, b in zip(got, want))
    other = [np.array(x) for x in rc.jacobian(lam + 1e-3)]
    assert all(np.array_equal(a, np.array(b)) for a, b in zip(other, fns.shoot_jac(lam + 1e-3, *args)))
    # seeded with the start's rollout (the Cayley check's): its outputs at that point, the same Jacobian from them
    seeded = RolloutCache(fns, args, (lam, [ca.DM(np.array(o)) * 0 + 7.0 for o in fns.rollout(lam, *args)]))
    assert float(seeded.residual(lam)[2]) == 7.0                      # the seed's values, no rollout
    rs = RolloutCache(fns, args, (lam, fns.rollout(lam, *args)))
    rs.residual(lam)
    assert all(np.array_equal(np.array(a), np.array(b)) for a, b in zip(rs.jacobian(lam), fns.shoot_jac(lam, *args)))
