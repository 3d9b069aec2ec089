"""Impulsive maneuvers (transcription/methods/impulsive/, docs/mathematics.md §5) and the sensitivity Phi (§4, eq. 19).

E2 by single shooting (the default) and by multiple shooting, the two compared.

Default run: Phi checks at N = 100, E1 at N = 100, E2 at N = 60.  ``pytest -m slow``: N = 800.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import pack_state, tangent_readback, unpack_states
from se3ocp.transcription.methods.impulsive.reduced import ReducedRelaxed, _null_space
from se3ocp.transcription.methods.impulsive.relaxed import relaxed_jacobian
from se3ocp.transcription.methods.impulsive.sensitivity import P_COLS, sensitivity, sensitivity_ad, with_momenta
from se3ocp.transcription.methods.impulsive.tpbvp import (ImpulsiveSettings, initial_momenta, solve_tpbvp,
                                                          tpbvp_jacobian, tpbvp_residual)
from se3ocp.transcription.geometry.so3 import exp_so3, hat, log_so3
from se3ocp.transcription.ocp import orbit_conditions
from se3ocp.transcription.outcome import Result
from support import maneuver, problem


def disc(scheme):
    return problem("e1", 100, scheme).disc

SCHEMES = ("lgvi", "first_order")
SEEDS = (0, 1, 2)


def random_start(seed: int) -> np.ndarray:
    """A state near the reference orbit with a random attitude and tumbling rate."""
    rng = np.random.default_rng(seed)
    p = problem("e1", 100)
    s = unpack_states(p.X0)
    return pack_state(s.x[0] + 0.1 * rng.normal(size=3), s.gamma[0] * (1 + 0.1 * rng.normal()),
                      exp_so3(rng.normal(size=3)), p.model.inertia @ (3.0 * rng.normal(size=3)))


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
    d, N, h, eps = disc(scheme), 100, 0.8 / 100, 1e-6
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
    d, N, h = disc(scheme), 100, 0.8 / 100
    X0 = random_start(seed)
    X, _ = d.simulate(X0, None, h, N)
    Phi = sensitivity(d, X, h)
    Pad = sensitivity_ad(d, X0, h, N)
    err = float(np.abs(Phi - Pad).max() / np.abs(Pad).max())
    assert err <= 1e-12, f"seed {seed}: relative error {err:.2e}"


@pytest.mark.parametrize("scheme", SCHEMES)
def test_tpbvp_jacobian_against_finite_differences(scheme):
    p = problem("e1", 100, scheme)
    Xd = p.terminal.X
    s0 = unpack_states(p.X0)
    q = np.r_[s0.gamma[0] + 0.3, s0.Pi[0] + 0.01]
    sim = lambda q: p.disc.simulate(with_momenta(p.X0, q), None, p.h, p.N)[0]
    X = sim(q)
    Jac = tpbvp_jacobian(X[-1], Xd, sensitivity(p.disc, X, p.h))
    eps = 1e-6 * np.r_[np.ones(3), 1e-2 * np.ones(3)]
    Jfd = np.column_stack([(tpbvp_residual(sim(q + e)[-1], Xd) - tpbvp_residual(sim(q - e)[-1], Xd))
                           / (2 * e[i]) for i, e in enumerate(np.diag(eps))])
    assert colwise_rel(Jac, Jfd) <= 1e-6


def test_relaxed_jacobian_against_finite_differences():
    p = problem("e2", 100)
    s0 = unpack_states(p.X0)
    q = np.r_[s0.gamma[0], s0.Pi[0]]
    sim = lambda q: p.disc.simulate(with_momenta(p.X0, q), None, p.h, p.N)[0]
    C = lambda q: orbit_conditions(sim(q)[-1], p.terminal, p.model.mass, p.model.mu)[0]
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
    s = se3ocp.solve(maneuver("e1", 100, scheme))
    p = s.problem
    assert s.converged and s.method == "direct" and s.solver == "newton-armijo", s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], p.terminal.X)).max() <= 1e-12
    assert s.terminal_error <= 1e-12
    _check_impulsive(s, p)
    # the terminal impulse lands exactly on the desired momenta
    XNp = s.stats["XN_plus"]
    Xd = p.terminal.X
    assert np.abs(XNp[3:6] - Xd[3:6]).max() <= 1e-14 and np.abs(XNp[15:] - Xd[15:]).max() <= 1e-14
    # quadratic convergence at the end: the last residuals fall fast
    r = [h.residual_inf for h in s.history if h.accepted]
    assert r[-1] <= 1e-12 and r[-2] <= 1e-4


def test_e1_failure_is_data():
    p = problem("e1", 100)
    nr, X = solve_tpbvp(p, initial_momenta(p, "rollout"), ImpulsiveSettings(newton_max_iter=1))
    assert nr.result is Result.max_iterations and nr.iterations == 1 and X.shape == (101, 18)
    with pytest.raises(ValueError, match="indirect method applies to smooth maneuvers"):
        se3ocp.solve(maneuver("e1", 100), "indirect")


@pytest.mark.parametrize("guess", ["rollout", "interpolate"])
def test_e1_from_either_guess(guess):
    """initial_guess of the direct block: rollout (no impulse) or interpolate (Pi_0^+ from the attitude change)."""
    s = se3ocp.solve(maneuver("e1", 100), initial_guess=guess)
    assert s.converged and s.stats["start"] in ("rollout", "interpolate"), s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], s.problem.terminal.X)).max() <= 1e-12


@pytest.mark.slow
def test_e1_tpbvp_full():
    s = se3ocp.solve(maneuver("e1"))
    p = s.problem
    assert s.converged, s.message
    assert np.abs(tpbvp_residual(s.trajectory.X[-1], p.terminal.X)).max() <= 1e-12
    _check_impulsive(s, p)


# --------------------------------------------------------------------------- E2
def phi_gradients(X: np.ndarray, impulses: dict, problem) -> tuple[np.ndarray, np.ndarray]:
    """(dJ/dp (6,), dC/dp (4 x 6)) along the rollout X, both from Phi = A_{N-1} ... A_0 (docs/mathematics.md §5).

    J(p) = |gamma_0^+ - gamma_0| + |Pi_0^+ - Pi_0| + |gamma_N^+(x_N) - gamma_N| + |Pi_N|.
    """
    Phi_full = sensitivity(problem.disc, X, problem.h)
    Phi = Phi_full[:, P_COLS]                                            # dz_N/dp (12 x 6)
    unit = {k: v / np.linalg.norm(v) for k, v in impulses.items()}
    n, _, _ = problem.terminal.plane_basis()
    rd = problem.terminal.radius
    dgp_dx = problem.model.mass * np.sqrt(problem.model.mu / rd) / rd * hat(n)     # d gamma_N^+ / d x_N
    dJ = np.r_[unit["dgamma0"], unit["dPi0"]]
    dJ = dJ + unit["dgammaN"] @ (dgp_dx @ Phi[0:3] - Phi[3:6]) - unit["dPiN"] @ Phi[9:12]
    return dJ, relaxed_jacobian(X[-1], problem.terminal, Phi_full)


def reduced_kkt_residual(s, problem, mu=None) -> float:
    """|dJ/dp + mu^T dC/dp| / |dJ/dp| with the Phi-based gradients; mu: the given multipliers of
    J + mu^T C, or None for the least-squares ones (the residual is then the reduced gradient)."""
    dJ, dC = phi_gradients(s.trajectory.X, s.impulses, problem)
    if mu is None:
        mu = np.linalg.lstsq(dC.T, -dJ, rcond=None)[0]
    return float(np.linalg.norm(dJ + dC.T @ np.asarray(mu)) / np.linalg.norm(dJ))


#: relative KKT residual (Phi-based, least-squares multipliers) the relaxed solutions must reach:
#: single shooting stops at a scaled reduced gradient of 1e-10 (measured 6.4e-14 at N = 100,
#: 4.7e-11 at N = 800); IPOPT's tol 1e-10 is on its scaled multiple-shooting KKT system
#: (measured 4.8e-10 at N = 100, 1.5e-7 at N = 800)
KKT_RTOL = {"single_shooting": 1e-9, "multiple_shooting": 1e-6}
#: max |C| on the re-simulation: single shooting projects onto C = 0 to 1e-12 in C / (r_d, r_d, 1, 1)
#: (measured 6e-15 .. 1.8e-14); IPOPT's node states satisfy the scaled constraints and defects to
#: its tol only, and the re-simulation accumulates the defects (measured 5e-13 .. 1.2e-10)
TERMINAL_TOL = {"single_shooting": 2e-12, "multiple_shooting": 1e-9}


def _check_relaxed(s, p):
    assert s.converged and s.result is Result.converged, s.message
    assert s.stats["kkt_tol"] <= 1e-10
    C = orbit_conditions(s.trajectory.X[-1], p.terminal, p.model.mass, p.model.mu)[0]
    assert s.terminal_error == np.abs(C).max() <= TERMINAL_TOL[s.stats["transcription"]]   # on the re-simulation
    assert s.stats["min_impulse_norm"] > 1e-6                          # smooth optimum (no kink)
    _check_impulsive(s, p)
    # the terminal impulse puts the body on the circular orbit, not spinning
    XNp = s.stats["XN_plus"]
    _, gp, Pp = orbit_conditions(XNp, p.terminal, p.model.mass, p.model.mu)
    assert np.allclose(XNp[3:6], gp, atol=1e-14) and np.abs(XNp[15:]).max() == 0.0
    assert reduced_kkt_residual(s, p) <= KKT_RTOL[s.stats["transcription"]]


@pytest.fixture(scope="module")
def e2_both_small():
    """E2 at N = 60 by the default transcription (single shooting) and by multiple shooting, both
    from the same feasible start.  (Multiple shooting is fragile on this problem: at N = 40 it runs
    to max_iter along the flat spin direction, at N = 100 it ends in another, lower local minimum.)"""
    man = maneuver("e2", 60)
    return {"single_shooting": se3ocp.solve(man),
            "multiple_shooting": se3ocp.solve(man, transcription="multiple_shooting")}


def test_e2_relaxed_small(e2_both_small):
    s = e2_both_small["single_shooting"]
    assert s.solver == "sqp" and s.stats["transcription"] == "single_shooting"      # the default
    _check_relaxed(s, s.problem)


def test_e2_relaxed_small_multiple_shooting(e2_both_small):
    s = e2_both_small["multiple_shooting"]
    assert s.solver == "ipopt" and s.stats["transcription"] == "multiple_shooting"
    _check_relaxed(s, s.problem)


def test_e2_single_shooting_equals_multiple_shooting(e2_both_small):
    """Two formulations of one problem (6 unknowns vs all node states) reach the same optimum:
    cost to 1e-8 relative, each impulse to 1e-6 relative (IPOPT's tolerance along the flat
    direction of the spin about the dumbbell's axis)."""
    ss, ms = e2_both_small["single_shooting"], e2_both_small["multiple_shooting"]
    assert ss.converged and ms.converged, (ss.message, ms.message)
    assert abs(ss.cost - ms.cost) <= 1e-8 * ms.cost
    for k in ss.impulses:
        assert np.linalg.norm(ss.impulses[k] - ms.impulses[k]) <= 1e-6 * np.linalg.norm(ms.impulses[k]), k


def test_e2_single_shooting_kkt(e2_both_small):
    """First- and second-order optimality of the single-shooting result, all derivatives from Phi
    except the Hessian: the reported multipliers make the Phi-based Lagrangian gradient vanish
    (relative 1e-8: the solver stops at 1e-10 in the max-norm of the *scaled* reduced gradient, and
    the unknowns' scales differ by ~1e2; measured 1.2e-9 at N = 60), and the Hessian of the Lagrangian (checked against finite differences in
    test_reduced_derivatives) is positive definite on the tangent space of C = 0."""
    s = e2_both_small["single_shooting"]
    p = s.problem
    assert reduced_kkt_residual(s, p, mu=s.stats["multipliers"]) <= 1e-8
    red = ReducedRelaxed(p)
    y = np.r_[s.trajectory.X[0, 3:6], s.trajectory.X[0, 15:]] / red.sy
    X = red.rollout(y)
    d1 = red.first(X, y)
    lam = np.asarray(s.stats["multipliers"]) * red.sc / red.sf               # scaled multipliers
    Z = _null_space(d1["Jc"])
    assert np.linalg.eigvalsh(Z.T @ red.hessian(X, y, lam, d1) @ Z).min() > 0.0


@pytest.mark.parametrize("scheme", SCHEMES)
def test_reduced_derivatives(scheme):
    """ReducedRelaxed at a non-optimal point (N = 100): S_N read back to tangent coordinates equals
    Phi (1e-12), its constraint Jacobian equals relaxed_jacobian's (1e-12) and its cost gradient
    the Phi-based one (1e-12); its Hessian of the Lagrangian equals central differences of its
    gradient with step 1e-6 (1e-7 relative; measured 1.3e-9 and 1.4e-9, falling as the step
    squared from 1e-5 at step 1e-4, i.e. the differences' truncation error, not a wrong term)."""
    p = problem("e2", 100, scheme)
    red = ReducedRelaxed(p)
    s0 = unpack_states(p.X0)
    y = np.r_[s0.gamma[0] * 1.05, s0.Pi[0] + 0.3 * np.diag(p.model.inertia)] / red.sy
    X = red.rollout(y)
    d1 = red.first(X, y)
    Phi = sensitivity(p.disc, X, p.h)
    SN = np.array(tangent_readback(ca.DM(X[-1]), ca.DM(d1["SN"])))
    assert np.abs(SN - Phi[:, P_COLS] * red.sy).max() <= 1e-12 * np.abs(SN).max()
    Jc = relaxed_jacobian(X[-1], p.terminal, Phi) * red.sy / red.sc[:, None]
    assert np.abs(d1["Jc"] - Jc).max() <= 1e-12 * np.abs(Jc).max()
    _, gp, Pp = orbit_conditions(X[-1], p.terminal, p.model.mass, p.model.mu)
    aN = unpack_states(X[-1])
    imp = {"dgamma0": red.p(y)[:3] - s0.gamma[0], "dPi0": red.p(y)[3:] - s0.Pi[0], "dgammaN": gp - aN.gamma[0],
           "dPiN": Pp - aN.Pi[0]}
    dJ, _ = phi_gradients(X, imp, p)
    assert np.abs(d1["g"] - dJ * red.sy / red.sf).max() <= 1e-12 * np.abs(d1["g"]).max()
    lam = np.array([0.3, -0.2, 0.5, 0.1])
    H = red.hessian(X, y, lam, d1)

    def grad_l(yy):
        Xy = red.rollout(yy)
        d = red.first(Xy, yy)
        return d["g"] + d["Jc"].T @ lam

    eps = 1e-6
    Hfd = np.column_stack([(grad_l(y + eps * e) - grad_l(y - eps * e)) / (2 * eps) for e in np.eye(6)])
    assert np.abs(H - Hfd).max() <= 1e-7 * np.abs(H).max()
    assert np.array_equal(H, H.T)


def test_transcription_option():
    """solver.direct.transcription from a file reaches the solve; a bad value is rejected by name."""
    assert maneuver("e2", 60).direct.transcription == "single_shooting"
    assert maneuver("e2", 60, None, "solver.direct.transcription=multiple_shooting").direct.transcription == \
        "multiple_shooting"
    with pytest.raises(se3ocp.ConfigError, match="solver.direct.transcription"):
        maneuver("e2", 60, None, "solver.direct.transcription=reduced")


@pytest.mark.slow
def test_e2_relaxed_full():
    """N = 800 by single shooting: the multiple-shooting optimum 2.4740483077 (IPOPT) or lower."""
    s = se3ocp.solve(maneuver("e2"))
    _check_relaxed(s, s.problem)
    assert s.cost <= 2.4740483077


@pytest.mark.slow
def test_e2_relaxed_full_multiple_shooting():
    s = se3ocp.solve(maneuver("e2"), transcription="multiple_shooting")
    _check_relaxed(s, s.problem)
