"""Acceptance figures of the discrete schemes (issue 2; docs/mathematics.md §1-§4, §8).

Every numerical claim has a test that can fail, with its tolerance stated here:

* Cayley solve (eq. 9/23): |G(c)|/|g| <= 1e-12 within 8 Newton iterations for
  h|Pi|/lambda_min(J) up to 0.999 (at exactly 1 the equation has a double root along
  the minor axis; see S_MAX); the solved F satisfies F J_d - J_d F^T = S(g).
* Orthogonality: 1e5 steps of a tumbling dumbbell on the reference orbit, h = 1e-3:
  max |R^T R - I| <= 1e-12 and |det R - 1| <= 1e-12.
* Energy: same run (100 orbits): max relative energy error over the last 10 orbits
  <= 2 x the max over the first 10.
* Order: global error against DOP853 (rtol 1e-13) of eqs. (1)-(4) as h halves:
  fitted slope in [1.9, 2.1] (lgvi) and [0.9, 1.1] (first_order).
* GM = 0: linear momentum exactly conserved, spatial angular momentum x x gamma + R Pi
  to 1e-13 relative over 1e4 steps, both schemes.
* Moment formulas (docs/mathematics.md §1 eq. 6 by AD vs sum rho x R^T f): agree to 1e-14.
* variation (A, B) vs manifold central differences of step: relative error <= 1e-6.

All randomness is seeded.
"""
from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from se3ocp.problems.models import Dumbbell
from se3ocp.transcription.geometry.state import NZ, pack_state, unpack_states
from se3ocp.transcription.dynamics.lgvi import Discretization
from se3ocp.transcription.geometry.so3 import cayley, exp_so3, hat, log_so3, orthogonality_error

SCHEMES = ("lgvi", "first_order")
TWO_PI = 2.0 * np.pi


# ------------------------------------------------------------------ helpers
def uniform_rotation(rng: np.random.Generator) -> np.ndarray:
    """Haar-uniform rotation from a normalized Gaussian quaternion."""
    q = rng.standard_normal(4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def tumbling_state(db: Dumbbell) -> np.ndarray:
    """Reference orbit x0 = (1,0,0), v0 = (0, 2 pi, 0), R0 = I, tumbling with
    body angular velocity Omega0 = (1, -2, 3) + 2 pi e3 (docs/mathematics.md §9 start, E4's tumble)."""
    omega = np.array([1.0, -2.0, 3.0 + TWO_PI])
    return pack_state([1.0, 0.0, 0.0], [0.0, db.mass * TWO_PI, 0.0], np.eye(3), db.inertia @ omega)


def energies(model, X: np.ndarray) -> np.ndarray:
    """E(X_k) for X of shape (M, 18)."""
    return np.array(model.energy().map(X.shape[0])(X.T)).ravel()


@pytest.fixture(scope="module")
def db():
    return Dumbbell()


@pytest.fixture(scope="module")
def model(db):
    return db.body_model()


@pytest.fixture(scope="module")
def disc(model):
    return {s: Discretization(model, s) for s in SCHEMES + ("lgvi_kepler",)}


# ------------------------------------------------------------- Cayley solve
#: Largest s = h|Pi|/lambda_min(J) for which the claim "|G|/|g| <= 1e-12 within 8 Newton
#: iterations, every direction" holds.  At s = 1 exactly it fails near the minor
#: principal axis e1: there eq. (9) becomes g1 (1 + c1^2) = 2 J11 c1, whose two roots
#: merge at s = 1 (a fold; no real root beyond), Newton turns linear and needs up to 19
#: iterations (measured: s = 0.999 -> <= 7 iterations for directions within 0.05 rad of
#: e1; s = 0.9999 -> 9; s = 1 -> 19, failing for ~3e-4 of uniform directions).
S_MAX = 0.999


def random_cayley_rhs(rng, lam_min, n, s_max=S_MAX):
    """n right-hand sides g = h Pi (first-order scheme, eq. 23) with s = |g|/lambda_min(J)
    = h|Pi|/lambda_min in (0, s_max]: uniform directions with uniform s (60%), s = s_max
    (10%), tiny s down to 1e-8 (10%); and adversarial directions within 0.05 rad of +-e1
    (the minor axis, where the solve is hardest) with s in [0.9, s_max] (20%)."""
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    s = rng.uniform(0.0, s_max, n)
    a, b, c = n // 10, n // 5, (2 * n) // 5
    s[:a] = s_max
    s[a:b] = 10.0 ** rng.uniform(-8, -1, b - a)
    ang, phi = rng.uniform(0.0, 0.05, c - b), rng.uniform(0.0, 2 * np.pi, c - b)
    sign = rng.choice([-1.0, 1.0], c - b)
    u[b:c] = np.stack([sign * np.cos(ang), np.sin(ang) * np.cos(phi), np.sin(ang) * np.sin(phi)], axis=1)
    s[b:c] = rng.uniform(0.9, s_max, c - b)
    return (u * (s * lam_min)[:, None]).T, s


@pytest.mark.parametrize("seed", range(5))
def test_cayley_solve_converges(db, disc, seed):
    """|G(c_k)|/|g| <= 1e-12 for some k <= 8 (counted from res_hist), 4000 samples per seed,
    s = h|Pi|/lambda_min(J) <= S_MAX = 0.999 (see S_MAX for s = 1).

    Measured: at most 7 iterations (near e1 at s = 0.999); 2-3 for s < 0.5."""
    rng = np.random.default_rng(seed)
    lam_min = np.linalg.eigvalsh(db.inertia).min()
    G, s = random_cayley_rhs(rng, lam_min, 4000)
    for scheme in SCHEMES:  # the solve depends on J only; check both instances anyway
        d = disc[scheme]
        C, H = d.cayley_solve.map(G.shape[1])(G)
        H = np.array(H)
        assert H.shape == (d.newton_iters + 1, G.shape[1]) and d.newton_iters <= 8
        reached = H <= 1e-12
        bad = np.flatnonzero(~reached.any(axis=0))
        assert bad.size == 0, f"seed {seed}: no convergence for s = {s[bad][:5]}, final res {H[-1, bad][:5]}"
        iters = np.argmax(reached, axis=0)
        assert iters.max() <= 8, f"seed {seed}: {iters.max()} iterations"
        # and it stays converged (no divergence after reaching round-off)
        assert H[-1].max() <= 1e-12, f"seed {seed}"


def test_cayley_fold_at_s_equal_1_is_reported(db, disc):
    """Characterizes the limit of the claim: at s = 1 along e1 (double root of eq. 9) the
    8-iteration solve does NOT reach 1e-12, and both cayley_solve and step say so through
    their residual outputs (failure is data).  If the solver is improved this test fails:
    then raise S_MAX to 1."""
    J11 = db.inertia[0, 0]
    h = 1e-3
    _, H = disc["first_order"].cayley_solve(np.array([J11, 0.0, 0.0]))
    X0 = pack_state([1.0, 0.0, 0.0], [0.0, TWO_PI, 0.0], np.eye(3), [J11 / h, 0.0, 0.0])
    _, res = disc["first_order"].step(X0, np.zeros(6), h)
    assert float(H[-1]) > 1e-12
    assert float(res) == float(H[-1])


@pytest.mark.parametrize("seed", range(3))
def test_cayley_solution_satisfies_eq9(db, disc, seed):
    """F = cay(c) satisfies F J_d - J_d F^T = S(g) (eq. 9) to 1e-14 relative to |S(g)|
    (measured max 4.5e-15 over 20000 samples including |g| = 1e-8 lambda_min)."""
    rng = np.random.default_rng(100 + seed)
    J = db.inertia
    Jd = 0.5 * np.trace(J) * np.eye(3) - J
    G, _ = random_cayley_rhs(rng, np.linalg.eigvalsh(J).min(), 1000)
    C = np.array(disc["lgvi"].cayley_solve.map(G.shape[1])(G)[0])
    for c, g in zip(C.T, G.T):
        F = cayley(c)
        err = np.linalg.norm(F @ Jd - Jd @ F.T - hat(g)) / np.linalg.norm(hat(g))
        assert err <= 1e-14, (seed, g, err)


def test_cayley_no_solution_is_reported(db, disc):
    """Past the existence limit the residual output says so (failure is data).

    Along the minor principal axis e1, eq. (9) reduces to g1 (1 + c1^2) = 2 J11 c1,
    which has a real root iff |g1| <= J11 = lambda_min: s = 1 is exactly the limit."""
    J11 = db.inertia[0, 0]
    for s, ok in ((0.999, True), (1.05, False)):
        _, H = disc["first_order"].cayley_solve(np.array([s * J11, 0.0, 0.0]))
        assert (float(H[-1]) <= 1e-12) is ok, (s, np.array(H).ravel())
    # the same through a solved step: X with h Pi = 1.05 J11 e1
    X0 = pack_state([1.0, 0.0, 0.0], [0, TWO_PI, 0], np.eye(3), [1.05 * J11 / 1e-3, 0, 0])
    _, res = disc["first_order"].step(X0, np.zeros(6), 1e-3)
    assert float(res) > 1e-6


# -------------------------------------------- long run: orthogonality, energy
N_LONG = 100_000
H_LONG = 1e-3  # period 1: 1e5 steps = 100 orbits


@pytest.fixture(scope="module")
def long_run(db, disc):
    t0 = time.perf_counter()
    X, res = disc["lgvi"].simulate(tumbling_state(db), None, H_LONG, N_LONG)
    return X, res, time.perf_counter() - t0


def test_orthogonality_1e5_steps(long_run):
    """max_k |R_k^T R_k - I|_F <= 1e-12 and |det R_k - 1| <= 1e-12 over 1e5 steps
    (measured: 6.7e-14 and 3.4e-14; the run takes ~0.5 s)."""
    X, res, elapsed = long_run
    orth, det = orthogonality_error(unpack_states(X).R)
    print(f"1e5 lgvi steps in {elapsed:.2f} s: max orth {orth.max():.2e}, max |det-1| {det.max():.2e}")
    assert np.all(np.isfinite(X))
    assert orth.max() <= 1e-12
    assert det.max() <= 1e-12
    assert res.max() <= 1e-12  # every Cayley solve converged


def test_energy_bounded_100_orbits(model, long_run):
    """No secular drift: max |E/E0 - 1| over orbits 91-100 <= 2 x max over orbits 1-10
    (measured 1.61e-7 vs 1.66e-7: ratio 0.97)."""
    X, _, _ = long_run
    E = energies(model, X)
    rel = np.abs(E / E[0] - 1.0)
    per_orbit = int(round(1.0 / H_LONG))
    first, last = rel[: 10 * per_orbit + 1].max(), rel[-(10 * per_orbit + 1) :].max()
    print(f"energy error: first 10 orbits {first:.3e}, last 10 orbits {last:.3e}, ratio {last / first:.3f}")
    assert first > 0  # a genuinely nonzero error, so the ratio means something
    assert last <= 2.0 * first


# --------------------------------------------------------------------- order
def continuous_rhs(model):
    """Eqs. (1)-(4), u = 0, on y = [x, gamma, R (row-major 9), Pi]."""
    Jinv = np.linalg.inv(model.inertia)
    forces = model.forces

    def rhs(_t, y):
        x, gamma, R, Pi = y[0:3], y[3:6], y[6:15].reshape(3, 3), y[15:18]
        f, M = forces(x, R)
        omega = Jinv @ Pi
        return np.concatenate(
            [gamma / model.mass, np.array(f).ravel(), (R @ hat(omega)).ravel(), np.cross(Pi, omega) + np.array(M).ravel()]
        )

    return rhs


def state_errors(S, ref_y):
    """(max |dx|,|dgamma|,|dPi| entries, max |log(R_ref^T R)|) along the common nodes."""
    Rref = ref_y[6:15].T.reshape(-1, 3, 3)
    e_trans = max(np.abs(S.x - ref_y[0:3].T).max(), np.abs(S.gamma - ref_y[3:6].T).max())
    e_pi = np.abs(S.Pi - ref_y[15:18].T).max()
    e_rot = max(np.linalg.norm(log_so3(Rr.T @ Rk)) for Rr, Rk in zip(Rref, S.R))
    return e_trans, e_pi, e_rot


T_ORDER = 0.5
N_ORDER = (100, 200, 400, 800)


@pytest.fixture(scope="module")
def reference(db, model):
    """DOP853 at rtol 1e-13, atol 1e-15 at the nodes of the coarsest grid (measured
    agreement with an rtol 1e-11 run: 1.5e-11, far below the smallest discrete error 2e-5)."""
    X0 = tumbling_state(db)
    S0 = unpack_states(X0)
    y0 = np.concatenate([S0.x[0], S0.gamma[0], S0.R[0].ravel(), S0.Pi[0]])
    t_eval = np.linspace(0.0, T_ORDER, N_ORDER[0] + 1)
    sol = solve_ivp(continuous_rhs(model), (0.0, T_ORDER), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t_eval)
    assert sol.success, sol.message
    return X0, sol.y


@pytest.mark.parametrize("scheme, lo, hi", [("lgvi", 1.9, 2.1), ("lgvi_kepler", 1.9, 2.1), ("first_order", 0.9, 1.1)])
def test_convergence_order(disc, reference, scheme, lo, hi):
    """Global error over T = 0.5 (half an orbit, about 1.5 tumbles) at N = 100..800
    (h = 5e-3 .. 6.25e-4): fitted log-log slope of max(|dx|, |dgamma|, |dPi|, |log R_ref^T R|)
    in [lo, hi]; the attitude part (|dPi|, |log R_ref^T R|) alone must show the same order.
    Measured: lgvi 2.000 (errors 7.0e-3 .. 1.1e-4), first_order 1.027 (0.22 .. 0.026)."""
    X0, ref_y = reference
    d = disc[scheme]
    total, attitude = [], []
    for N in N_ORDER:
        X, res = d.simulate(X0, None, T_ORDER / N, N)
        assert res.max() <= 1e-12
        e_trans, e_pi, e_rot = state_errors(unpack_states(X[:: N // N_ORDER[0]]), ref_y)
        total.append(max(e_trans, e_pi, e_rot))
        attitude.append(max(e_pi, e_rot))
    hs = T_ORDER / np.array(N_ORDER)
    slope = np.polyfit(np.log(hs), np.log(total), 1)[0]
    slope_att = np.polyfit(np.log(hs), np.log(attitude), 1)[0]
    print(f"{scheme}: errors {np.array(total)}, slope {slope:.4f}; attitude {np.array(attitude)}, slope {slope_att:.4f}")
    assert lo <= slope <= hi, (scheme, slope, total)
    assert lo <= slope_att <= hi, (scheme, slope_att, attitude)
    assert min(total) > 1e3 * 1.5e-11  # errors well above the reference's own accuracy


# -------------------------------------------------------------- GM = 0
@pytest.mark.parametrize("scheme", SCHEMES)
def test_free_body_momenta(db, scheme):
    """mu = 0, 1e4 steps, h = 1e-3: gamma_k bitwise equal to gamma_0; spatial angular
    momentum L = x x gamma + R Pi, and its parts x x gamma and R Pi separately (each is
    conserved when f = 0 and M = 0), constant to 1e-13 relative."""
    free = Dumbbell(mass=db.mass, length=db.length, sphere_radius=db.sphere_radius, mu=0.0)
    d = Discretization(free.body_model(), scheme)
    X0 = tumbling_state(free)
    X, res = d.simulate(X0, None, 1e-3, 10_000)
    assert res.max() <= 1e-12
    S = unpack_states(X)
    assert np.array_equal(S.gamma, np.broadcast_to(S.gamma[0], S.gamma.shape))
    L_orb = np.cross(S.x, S.gamma)
    L_spin = np.einsum("kij,kj->ki", S.R, S.Pi)
    L = L_orb + L_spin

    def drift(V):
        return np.linalg.norm(V - V[0], axis=1).max() / np.linalg.norm(V[0])

    print(f"{scheme}: rel drift L {drift(L):.2e}, x x gamma {drift(L_orb):.2e}, R Pi {drift(L_spin):.2e}")
    assert drift(L) <= 1e-13
    assert drift(L_orb) <= 1e-13
    assert drift(L_spin) <= 1e-13


# ------------------------------------------------------- moment formulas
def test_moment_formulas_agree(db, model):
    """M from U by AD (eq. 6) vs sum_q rho_q x (R^T f_q) on 2000 random states
    (uniform rotations, |x| in [0.5, 3]): |M_ad - M_pm| <= 1e-14 relative to
    sum_q |rho_q x R^T f_q| (the size of the terms whose near-cancellation gives M;
    relative to |M| itself the bound would depend on how close R e1 is to x)."""
    rng = np.random.default_rng(7)
    n = 2000
    u = rng.standard_normal((n, 3))
    xs = u / np.linalg.norm(u, axis=1, keepdims=True) * rng.uniform(0.5, 3.0, (n, 1))
    Rs = np.stack([uniform_rotation(rng) for _ in range(n)])
    Rcols = np.hstack(list(Rs))  # 3 x 3n: the mapped R inputs side by side
    M_ad = np.array(model.forces.map(n)(xs.T, Rcols)[1])
    M_pm = np.array(db.moment_point_masses().map(n)(xs.T, Rcols))
    scale = np.zeros(n)
    for q in db.rho:
        y = xs + np.einsum("kij,j->ki", Rs, q)
        fq = -db.mu * 0.5 * db.mass * y / np.linalg.norm(y, axis=1, keepdims=True) ** 3
        scale += np.linalg.norm(np.cross(q, np.einsum("kji,kj->ki", Rs, fq)), axis=1)
    err = np.linalg.norm(M_ad - M_pm, axis=0) / scale
    print(f"moment formulas: max rel err {err.max():.2e}")
    assert err.max() <= 1e-14, (int(np.argmax(err)), err.max())


# ---------------------------------------------------- variation vs FD
def step_numeric(d):
    def f(X, w, h):
        return np.array(d.step(X, w, h)[0]).ravel()

    return f


def tangent_difference(Xp, Xm, eps):
    """[dx, dgamma, vee log(R^-^T R^+) ... ] central difference in the §4 coordinates,
    (X(+eps) - X(-eps)) / (2 eps), the rotation part read back at the minus point."""
    Sp, Sm = unpack_states(Xp), unpack_states(Xm)
    return np.concatenate(
        [
            (Sp.x[0] - Sm.x[0]),
            (Sp.gamma[0] - Sm.gamma[0]),
            log_so3(Sm.R[0].T @ Sp.R[0]),
            (Sp.Pi[0] - Sm.Pi[0]),
        ]
    ) / (2 * eps)


def perturb(X, z):
    """Chart for the FD: R -> R exp(S(zeta)), others additive."""
    S = unpack_states(X)
    return pack_state(S.x[0] + z[0:3], S.gamma[0] + z[3:6], S.R[0] @ exp_so3(z[6:9]), S.Pi[0] + z[9:12])


def random_stage(rng, db, nw):
    """Random state near the orbit (|x| ~ 1, uniform attitude, |Omega| ~ 5) and controls
    (forces ~ 1, moments ~ J * 10) with h = 4e-3 (h|Pi|/lambda_min ~ 0.3)."""
    x = rng.standard_normal(3)
    x *= rng.uniform(0.8, 1.5) / np.linalg.norm(x)
    gamma = TWO_PI * rng.standard_normal(3)
    Pi = db.inertia @ (3.0 * rng.standard_normal(3))
    X = pack_state(x, gamma, uniform_rotation(rng), Pi)
    w = np.concatenate([np.concatenate([rng.standard_normal(3), 0.03 * rng.standard_normal(3)]) for _ in range(nw // 6)])
    return X, w, 4e-3


@pytest.mark.parametrize("scheme", SCHEMES)
def test_variation_matches_manifold_fd(db, disc, scheme):
    """A, B of `variation` vs central differences of `step` (R perturbed by R exp(eps S(e_i)),
    read back by vee log): column-wise relative error <= 1e-6 (relative to the column
    norm), 5 seeds; the failing seed is printed.  eps = 1e-6 for A and 1e-4 for B (the
    B columns are O(h), so with 1e-6 round-off alone reaches 4e-7).  Measured worst:
    A 1.4e-9, B 4.5e-9."""
    d = disc[scheme]
    step = step_numeric(d)
    eps, eps_w = 1e-6, 1e-4
    worst = 0.0
    for seed in range(5):
        rng = np.random.default_rng(1000 + seed)
        X, w, h = random_stage(rng, db, d.nw)
        A, B = (np.array(M) for M in d.variation(X, w, h))
        X1 = step(X, w, h)
        A_fd = np.zeros((NZ, NZ))
        for i in range(NZ):
            e = np.zeros(NZ)
            e[i] = eps
            A_fd[:, i] = tangent_difference(step(perturb(X, e), w, h), step(perturb(X, -e), w, h), eps)
        B_fd = np.zeros((NZ, d.nw))
        for i in range(d.nw):
            e = np.zeros(d.nw)
            e[i] = eps_w
            B_fd[:, i] = tangent_difference(step(X, w + e, h), step(X, w - e, h), eps_w)
        for name, M, M_fd in (("A", A, A_fd), ("B", B, B_fd)):
            col_err = np.linalg.norm(M - M_fd, axis=0) / np.maximum(np.linalg.norm(M_fd, axis=0), 1e-300)
            worst = max(worst, col_err.max())
            assert col_err.max() <= 1e-6, (
                f"{scheme} seed {1000 + seed}: {name} column {int(np.argmax(col_err))} rel err {col_err.max():.2e}"
            )
        # the readback point is the step's own output
        np.testing.assert_allclose(X1, step(X, w, h), rtol=0, atol=0)
    print(f"{scheme}: worst column rel err {worst:.2e}")


@pytest.mark.parametrize("scheme", SCHEMES)
def test_variation_tends_to_identity(db, disc, scheme):
    """As h -> 0, A -> I_12 (the chart and the readback use the same coordinates):
    |A - I| <= 1e-6 at h = 1e-12 (the largest O(h) entry, h/J11, is 6e-9 there)."""
    X = tumbling_state(db)
    A, _ = disc[scheme].variation(X, np.zeros(disc[scheme].nw), 1e-12)
    np.testing.assert_allclose(np.array(A), np.eye(NZ), rtol=0, atol=1e-6)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_seeded_variation_equals_solved(db, disc, scheme):
    """Two Newton iterations from the solved Cayley root give the same (A, B) as the solved step, to 1e-12."""
    d = disc[scheme]
    rng = np.random.default_rng(1)
    X0, h = tumbling_state(db), 0.01
    w = rng.standard_normal(d.nw)
    c0 = d.cayley_solve(d.cayley_rhs(X0, w, h))[0]
    A, B = (np.array(a) for a in d.variation(X0, w, h))
    A2, B2 = (np.array(a) for a in d.variation_seeded(X0, w, h, c0))
    assert np.abs(A - A2).max() <= 1e-12 * np.abs(A).max() and np.abs(B - B2).max() <= 1e-12 * np.abs(B).max()


# ------------------------------------------------ the README's RK4 contrast
def test_energy_contrast_script_runs():
    """scripts/energy_contrast.py (20 orbits, ~1 s): the table it prints shows the LGVI's
    energy error bounded (last/first 10 orbits <= 2) and RK4's growing (ratio >= 1.5,
    measured 1.97 at 20 orbits, 9.9 at 100) with orthogonality lost (>= 1e-12, measured
    2e-10), the LGVI's kept (<= 1e-12)."""
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "scripts" / "energy_contrast.py"
    out = subprocess.run([sys.executable, str(script), "--orbits", "20"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    rows = {}
    for line in out.stdout.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0] in ("LGVI", "RK4"):
            rows[cells[0]] = [float(c) for c in cells[1:4]]
    first, last, orth = rows["LGVI"]
    assert last <= 2 * first and orth <= 1e-12, rows
    first, last, orth = rows["RK4"]
    assert last >= 1.5 * first and orth >= 1e-12, rows


@pytest.mark.parametrize("scheme", ["lgvi", "first_order"])
def test_body_force_frame_is_the_inertial_scheme_with_rotated_controls(model, db, scheme):
    """force_frame='body': a body-frame control u_f at node j applies R_j u_f (the node's attitude), so a
    body-frame rollout with u_b,j equals the inertial rollout with u_i,j = R_j u_b,j to round-off (the
    frame is a change of variables node by node)."""
    rng = np.random.default_rng(7)
    inertial = Discretization(model, scheme)
    body = Discretization(model, scheme, force_frame="body")
    N, h = 40, 1e-3
    X0 = tumbling_state(db)
    Ub = 1e-2 * rng.standard_normal((6, body.n_controls(N)))
    Xb, _ = body.simulate(X0, Ub, h, N)
    R = unpack_states(Xb).R
    nodes = np.arange(N + 1) if scheme == "lgvi" else np.arange(1, N + 1)
    Ui = Ub.copy()
    Ui[:3] = body.applied_force(R[nodes], Ub[:3].T).T
    Xi, _ = inertial.simulate(X0, Ui, h, N)
    assert np.max(np.abs(Xb - Xi)) <= 1e-12 * max(1.0, np.max(np.abs(Xi)))
    assert not np.allclose(Ub[:3], Ui[:3])


def test_unknown_force_frame_is_refused(model):
    with pytest.raises(ValueError, match="force_frame"):
        Discretization(model, "lgvi", force_frame="lvlh")
