"""Impulsive maneuvers (SPEC §5) and the sensitivity Phi (SPEC §4 eq. 19).

Default run: Phi checks at N = 100, E1 and E2 at N = 100.  ``pytest -m slow``: N = 800.
"""
from __future__ import annotations

import numpy as np
import pytest

import examples as ex
from se3ocp.transcription.direct import DIRECT_OPTION_DEFAULTS
from se3ocp.transcription.impulsive import (P_COLS, orbit_plane_basis, relaxed_jacobian, relaxed_terminal, right_jacobian_inv, sensitivity,
                                     sensitivity_ad, solve_impulsive, tpbvp_jacobian, tpbvp_residual, with_momenta)
from se3ocp.transcription.layout import pack_state, unpack_states
from se3ocp.transcription.lie import exp_so3, hat, log_so3

SCHEMES = ("lgvi", "first_order")
SEEDS = (0, 1, 2)


def random_start(seed: int) -> np.ndarray:
    """A state near the reference orbit with a random attitude and tumbling rate."""
    rng = np.random.default_rng(seed)
    s = unpack_states(ex.x0_reference_orbit())
    return pack_state(s.x[0] + 0.1 * rng.normal(size=3), s.gamma[0] * (1 + 0.1 * rng.normal()),
                      exp_so3(rng.normal(size=3)), ex.BODY.inertia @ (3.0 * rng.normal(size=3)))


def manifold_difference(Xa: np.ndarray, Xb: np.ndarray) -> np.ndarray:
    """z with Xa = Xb (+) z: additive blocks and log(R_b^T R_a)."""
    a, b = unpack_states(Xa), unpack_states(Xb)
    return np.concatenate([a.x[0] - b.x[0], a.gamma[0] - b.gamma[0], log_so3(b.R[0].T @ a.R[0]), a.Pi[0] - b.Pi[0]])


def perturb(X: np.ndarray, z: np.ndarray) -> np.ndarray:
    """X (+) z: additive on x, gamma, Pi; R exp(S(zeta))."""
    s = unpack_states(X)
    return pack_state(s.x[0] + z[:3], s.gamma[0] + z[3:6], s.R[0] @ exp_so3(z[6:9]), s.Pi[0] + z[9:])


def colwise_rel(A: np.ndarray, B: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(A - B, axis=0) / np.linalg.norm(B, axis=0)))


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("seed", SEEDS)
def test_phi_against_manifold_finite_differences(scheme, seed):
    """Phi vs central differences on the manifold (exp perturbation, log comparison): rel <= 1e-6."""
    d, N, h, eps = ex.disc(scheme), 100, 0.8 / 100, 1e-6
    X0 = random_start(seed)
    X, res = d.simulate(X0, None, h, N)
    assert res.max() < 1e-12
    Phi = sensitivity(d, X, h)
    Pfd = np.zeros((12, 12))
    for i in range(12):
        e = np.zeros(12)
        e[i] = eps
        Xp = d.simulate(perturb(X0, e), None, h, N)[0][-1]
        Xm = d.simulate(perturb(X0, -e), None, h, N)[0][-1]
        Pfd[:, i] = (manifold_difference(Xp, X[-1]) - manifold_difference(Xm, X[-1])) / (2 * eps)
    err = colwise_rel(Phi, Pfd)
    assert err <= 1e-6, f"seed {seed}: column-wise relative error {err:.2e}"


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("seed", SEEDS)
def test_phi_against_second_ad_route(scheme, seed):
    """Chain of A_k (eq. 19) vs AD of the whole rollout through the chart: rel <= 1e-12."""
    d, N, h = ex.disc(scheme), 100, 0.8 / 100
    X0 = random_start(seed)
    X, _ = d.simulate(X0, None, h, N)
    Phi = sensitivity(d, X, h)
    Pad = sensitivity_ad(d, X0, h, N)
    err = float(np.abs(Phi - Pad).max() / np.abs(Pad).max())
    assert err <= 1e-12, f"seed {seed}: relative error {err:.2e}"


def test_right_jacobian_inverse():
    rng = np.random.default_rng(3)
    for angle in (1.0, 1e-5, 2.8):          # inside the injectivity radius pi of log
        v = rng.normal(size=3)
        phi = angle * v / np.linalg.norm(v)
        d = 1e-7 * rng.normal(size=3)
        lhs = log_so3(exp_so3(phi) @ exp_so3(d)) - log_so3(exp_so3(phi))
        assert np.allclose(lhs, right_jacobian_inv(phi) @ d, rtol=1e-5, atol=1e-13)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_tpbvp_jacobian_against_finite_differences(scheme):
    p = ex.e1(N=100, scheme=scheme)
    s0 = unpack_states(p.X0)
    q = np.r_[s0.gamma[0] + 0.3, s0.Pi[0] + 0.01]
    sim = lambda q: p.disc.simulate(with_momenta(p.X0, q), None, p.h, p.N)[0]
    X = sim(q)
    Jac = tpbvp_jacobian(X[-1], p.terminal, sensitivity(p.disc, X, p.h))
    eps = 1e-6 * np.r_[np.ones(3), 1e-2 * np.ones(3)]
    Jfd = np.column_stack([(tpbvp_residual(sim(q + e)[-1], p.terminal) - tpbvp_residual(sim(q - e)[-1], p.terminal))
                           / (2 * e[i]) for i, e in enumerate(np.diag(eps))])
    assert colwise_rel(Jac, Jfd) <= 1e-6


def test_relaxed_jacobian_against_finite_differences():
    p = ex.e2(N=100)
    s0 = unpack_states(p.X0)
    q = np.r_[s0.gamma[0], s0.Pi[0]]
    sim = lambda q: p.disc.simulate(with_momenta(p.X0, q), None, p.h, p.N)[0]
    C = lambda q: relaxed_terminal(sim(q)[-1], p.terminal, ex.BODY.mass, p.mu)[0]
    X = sim(q)
    Jac = relaxed_jacobian(X[-1], p.terminal, sensitivity(p.disc, X, p.h))
    eps = 1e-6 * np.r_[np.ones(3), 1e-2 * np.ones(3)]
    Jfd = np.column_stack([(C(q + e) - C(q - e)) / (2 * e[i]) for i, e in enumerate(np.diag(eps))])
    assert np.abs(Jac - Jfd).max() <= 1e-6 * np.abs(Jfd).max()


# --------------------------------------------------------------------------- E1
def _check_impulsive(s, problem):
    assert s.trajectory.orthogonality()["max_orthogonality_error"] <= 1e-12
    X = s.trajectory.X
    s0 = unpack_states(problem.X0)
    assert np.allclose(unpack_states(X[0]).gamma[0], s0.gamma[0] + s.impulses["dgamma0"], atol=1e-14)
    assert np.allclose(unpack_states(X[0]).Pi[0], s0.Pi[0] + s.impulses["dPi0"], atol=1e-14)
    assert s.cost == pytest.approx(sum(np.linalg.norm(v) for v in s.impulses.values()), rel=1e-14)
    Xs, _ = problem.disc.simulate(X[0], None, problem.h, problem.N)
    assert np.array_equal(Xs, X)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_e1_tpbvp_small(scheme):
    p = ex.e1(N=100, scheme=scheme)
    s = solve_impulsive(p)
    assert s.converged, s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], p.terminal)).max() <= 1e-12
    assert s.terminal_error <= 1e-12
    _check_impulsive(s, p)
    # the terminal impulse lands exactly on the desired momenta
    XNp = s.extra["XN_plus"]
    assert np.abs(XNp[3:6] - p.terminal[3:6]).max() <= 1e-14 and np.abs(XNp[15:] - p.terminal[15:]).max() <= 1e-14
    # quadratic convergence at the end: the last residuals fall fast
    r = [h["residual_inf"] for h in s.history]
    assert r[-1] <= 1e-12 and r[-2] <= 1e-4


def test_e1_failure_is_data():
    s = solve_impulsive(ex.e1(N=100, newton_max_iter=1))
    assert not s.converged and s.status == "max_iter" and "max_iter" in s.message
    s = solve_impulsive(ex.e1(N=100, initial_guess="nonsense"))
    assert not s.converged and s.status == "invalid_option"


@pytest.mark.parametrize("guess", ["rollout", "interpolate"])
def test_e1_with_the_direct_option_block(guess):
    """The CLI passes the YAML solver.direct block (tol 1e-10, max_iter 3000, ...) to impulsive problems."""
    opts = dict(DIRECT_OPTION_DEFAULTS, initial_guess=guess)
    p = ex.e1(N=100, **opts)
    s = solve_impulsive(p)
    assert s.converged, s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], p.terminal)).max() <= 1e-12


@pytest.mark.slow
def test_e1_tpbvp_full():
    p = ex.e1()
    s = solve_impulsive(p)
    assert s.converged, s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], p.terminal)).max() <= 1e-12
    _check_impulsive(s, p)


# --------------------------------------------------------------------------- E2
def reduced_kkt_residual(s, problem) -> float:
    """|dJ/dp + mu^T dC/dp| / |dJ/dp| minimized over mu, all gradients from Phi (SPEC §5).

    J(p) = |gamma_0^+ - gamma_0| + |Pi_0^+ - Pi_0| + |gamma_N^+(x_N) - gamma_N| + |Pi_N|.
    """
    X = s.trajectory.X
    Phi = sensitivity(problem.disc, X, problem.h)[:, P_COLS]          # dz_N/dp (12 x 6)
    imp = s.impulses
    unit = {k: v / np.linalg.norm(v) for k, v in imp.items()}
    n, _, _ = orbit_plane_basis(problem.terminal.normal)
    rd = problem.terminal.radius
    dgp_dx = ex.BODY.mass * np.sqrt(problem.mu / rd) / rd * hat(n)     # d gamma_N^+ / d x_N
    dJ = np.r_[unit["dgamma0"], unit["dPi0"]]
    dJ = dJ + unit["dgammaN"] @ (dgp_dx @ Phi[0:3] - Phi[3:6]) - unit["dPiN"] @ Phi[9:12]
    dC = relaxed_jacobian(X[-1], problem.terminal, sensitivity(problem.disc, X, problem.h))
    mu = np.linalg.lstsq(dC.T, -dJ, rcond=None)[0]
    return float(np.linalg.norm(dJ + dC.T @ mu) / np.linalg.norm(dJ))


def _check_relaxed(s, p):
    assert s.status == "Solve_Succeeded" and s.converged, s.message
    assert s.extra["kkt_tol"] <= 1e-10
    assert s.terminal_error <= 1e-10                                   # max |C| on the re-simulation
    C = relaxed_terminal(s.trajectory.X[-1], p.terminal, ex.BODY.mass, p.mu)[0]
    assert np.abs(C).max() <= 1e-10
    assert s.extra["min_impulse_norm"] > 1e-6                          # smooth optimum (no kink)
    _check_impulsive(s, p)
    # the terminal impulse puts the body on the circular orbit, not spinning
    XNp = s.extra["XN_plus"]
    _, gp, Pp = relaxed_terminal(XNp, p.terminal, ex.BODY.mass, p.mu)
    assert np.allclose(XNp[3:6], gp, atol=1e-14) and np.abs(XNp[15:]).max() == 0.0
    assert reduced_kkt_residual(s, p) <= 1e-6


def test_e2_relaxed_small():
    p = ex.e2(N=100)
    _check_relaxed(solve_impulsive(p), p)


@pytest.mark.slow
def test_e2_relaxed_full():
    p = ex.e2()
    _check_relaxed(solve_impulsive(p), p)
