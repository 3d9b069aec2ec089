"""Properties of the Lie group helpers in transcription/lie.py (docs/mathematics.md §1-§4).

Grouped by property: hat/vee, Cayley map and its inverse, exp/log (uniform and near-identity
samples, rotations by exactly pi), the inverse right Jacobian, CasADi derivatives at the
identity, elementary rotations, the charts of the state space.
All randomness is seeded; tolerances are stated next to each check.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from se3ocp.transcription.layout import pack_state, tangent_basis, unpack_states
from se3ocp.transcription.lie import (
    cayley,
    cayley_inv,
    exp_so3,
    hat,
    log_so3,
    log_so3_any,
    right_jacobian_inv,
    orthogonality_error,
    rot_x,
    rot_y,
    rot_z,
    vee,
)

SEEDS = range(5)
N_SAMPLES = 200
EPS = np.finfo(float).eps
#: orthogonality in the project's metric (Frobenius ||R^T R - I||, 9 entries):
#: 1e-15 is below the round-off of a 3x3 product (measured max 1.7e-15), so 10 eps.
ORTH_TOL = 10 * EPS


#: absolute accuracy of the NumPy log_so3 at every angle: atan2 for the angle and, near pi, the
#: axis from the symmetric part keep it at round-off (measured max 8.9e-16 over 20,000 samples,
#: half of them within 1e-1..1e-9 of pi)
LOG_TOL = 4e-15


def uniform_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """n rotations uniform (Haar) on SO(3) from normalized Gaussian quaternions, shape (n,3,3)."""
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def random_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    u = rng.standard_normal((n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


# ------------------------------------------------------------------ hat / vee
@pytest.mark.parametrize("seed", SEEDS)
def test_hat_vee_inverse_and_cross(seed):
    rng = np.random.default_rng(seed)
    for a, b in rng.standard_normal((N_SAMPLES, 2, 3)):
        A = hat(a)
        assert np.array_equal(A, -A.T)                       # skew, exactly
        assert np.array_equal(vee(A), a)                     # vee(hat(a)) = a, exactly
        assert np.array_equal(hat(vee(A)), A)                # hat(vee(A)) = A on skew A
        # hat(a) b = a x b: same products, same rounding up to summation order
        np.testing.assert_allclose(A @ b, np.cross(a, b), rtol=0, atol=1e-15 * np.linalg.norm(a) * np.linalg.norm(b))


def test_hat_vee_casadi_matches_numpy():
    rng = np.random.default_rng(0)
    a = rng.standard_normal(3)
    s = ca.SX.sym("a", 3)
    f = ca.Function("hv", [s], [hat(s), vee(hat(s))])
    A, v = f(a)
    np.testing.assert_array_equal(np.array(A), hat(a))
    np.testing.assert_array_equal(np.array(v).ravel(), a)


# --------------------------------------------------------------------- Cayley
@pytest.mark.parametrize("seed", SEEDS)
def test_cayley_orthogonal_and_inverse(seed):
    rng = np.random.default_rng(seed)
    # |c| from 1e-8 to 1e2: rotation angles 2 atan|c| from ~0 to ~pi - 0.02
    mags = 10.0 ** rng.uniform(-8, 2, N_SAMPLES)
    C = random_unit(rng, N_SAMPLES) * mags[:, None]
    for c in C:
        F = cayley(c)
        orth, det = orthogonality_error(F)
        assert orth <= ORTH_TOL and det <= ORTH_TOL, (seed, c, orth, det)
        # cay^-1(cay(c)) = c, relative 1e-12 (conditioning grows like |c| near angle pi)
        np.testing.assert_allclose(cayley_inv(F), c, rtol=1e-12 * max(1.0, np.linalg.norm(c)), atol=0)
        # matches the defining product (I + S)(I - S)^-1
        S = hat(c)
        np.testing.assert_allclose(F, (np.eye(3) + S) @ np.linalg.inv(np.eye(3) - S), rtol=0, atol=1e-14)


def test_cayley_angle():
    c = np.array([0.0, 0.0, 0.3])
    np.testing.assert_allclose(cayley(c), rot_z(np.rad2deg(2 * np.arctan(0.3))), atol=1e-15)


# -------------------------------------------------------------------- exp/log
@pytest.mark.parametrize("seed", SEEDS)
def test_exp_log_roundtrip_random(seed):
    rng = np.random.default_rng(seed)
    # log(exp(w)) = w for angles in [0, pi - 1e-3]
    W = random_unit(rng, N_SAMPLES) * rng.uniform(0.0, np.pi - 1e-3, N_SAMPLES)[:, None]
    for w in W:
        R = exp_so3(w)
        orth, det = orthogonality_error(R)
        assert orth <= ORTH_TOL and det <= ORTH_TOL
        theta = np.linalg.norm(w)
        np.testing.assert_allclose(log_so3(R), w, rtol=0, atol=LOG_TOL, err_msg=f"seed {seed} theta {theta}")


@pytest.mark.parametrize("seed", SEEDS)
def test_exp_log_roundtrip_uniform_rotations(seed):
    rng = np.random.default_rng(seed)
    for R in uniform_rotations(rng, N_SAMPLES):
        w = log_so3(R)
        theta = np.linalg.norm(w)
        assert theta <= np.pi + 1e-12
        # exp(log(R)) = R, with the accuracy of log at that angle
        np.testing.assert_allclose(exp_so3(w), R, rtol=0, atol=LOG_TOL, err_msg=f"seed {seed}")


@pytest.mark.parametrize("seed", SEEDS)
def test_log_near_pi(seed):
    """Angles pi - 1e-1 ... pi - 1e-9: log(exp(w)) = w to round-off (axis from the symmetric part)."""
    rng = np.random.default_rng(seed)
    W = random_unit(rng, N_SAMPLES) * (np.pi - 10.0 ** rng.uniform(-9, -1, N_SAMPLES))[:, None]
    for w in W:
        np.testing.assert_allclose(log_so3(exp_so3(w)), w, rtol=0, atol=LOG_TOL, err_msg=f"seed {seed}")


@pytest.mark.parametrize("theta", [1e-12, 1e-9, 1e-6, 1e-4, 9.99e-4, 1.001e-3, 1e-2])
def test_exp_log_near_identity(theta):
    """Small angles, both sides of the Taylor switch (theta^2 = 1e-6): relative 1e-13."""
    rng = np.random.default_rng(int(-np.log10(theta) * 1000))
    for u in random_unit(rng, 50):
        w = theta * u
        R = exp_so3(w)
        np.testing.assert_allclose(vee(R - R.T) / 2, w * np.sin(theta) / theta, rtol=1e-14, atol=0)
        np.testing.assert_allclose(log_so3(R), w, rtol=1e-13, atol=0)


def test_log_identity_is_zero():
    assert np.array_equal(log_so3(np.eye(3)), np.zeros(3))
    assert np.array_equal(exp_so3(np.zeros(3)), np.eye(3))


def test_exp_log_casadi_matches_numpy():
    rng = np.random.default_rng(1)
    w = ca.SX.sym("w", 3)
    R = ca.SX.sym("R", 3, 3)
    fexp = ca.Function("e", [w], [exp_so3(w)])
    flog = ca.Function("l", [R], [log_so3(R)])
    for v in np.vstack([random_unit(rng, 20) * rng.uniform(0, 3, (20, 1)), 1e-5 * random_unit(rng, 5)]):
        np.testing.assert_allclose(np.array(fexp(v)), exp_so3(v), rtol=0, atol=1e-15)
        # both logs against the true vector: NumPy (atan2 form) and CasADi (acos form,
        # angles <= 3 rad here) are accurate to round-off; 1e-14 is ~50 eps
        np.testing.assert_allclose(np.array(flog(exp_so3(v))).ravel(), v, rtol=0, atol=1e-14)
        np.testing.assert_allclose(log_so3(exp_so3(v)), v, rtol=0, atol=LOG_TOL)


# ------------------------------------------------- CasADi derivatives near I
@pytest.mark.parametrize("w0", [np.zeros(3), np.array([1e-9, -2e-9, 0.5e-9]), np.array([1e-4, 3e-5, -2e-4]), np.array([6e-4, -7e-4, 2e-4])])
def test_casadi_derivatives_near_identity(w0):
    """CasADi derivatives of exp/log at and near w = 0 (both sides of the Taylor switch):
    finite; d log(exp(w))/dw = I (log o exp is the identity map) to 1e-10; d exp/dw
    equals central differences (step 1e-6) to 1e-9 and at w = 0 the generators hat(e_i)."""
    w = ca.SX.sym("w", 3)
    R = ca.SX.sym("R", 3, 3)
    fexp = ca.Function("exp", [w], [ca.vec(exp_so3(w))])
    Jexp = ca.Function("Jexp", [w], [ca.jacobian(ca.vec(exp_so3(w)), w)])
    Jlogexp = ca.Function("Jlogexp", [w], [ca.jacobian(log_so3(exp_so3(w)), w)])
    Jlog = ca.Function("Jlog", [R], [ca.jacobian(log_so3(R), ca.vec(R))])

    je = np.array(Jexp(w0))
    jle = np.array(Jlogexp(w0))
    jl = np.array(Jlog(exp_so3(w0)))
    for J in (je, jle, jl):
        assert np.all(np.isfinite(J))
    np.testing.assert_allclose(jle, np.eye(3), rtol=0, atol=1e-10)
    d = 1e-6
    fd = np.stack([(np.array(fexp(w0 + d * e)) - np.array(fexp(w0 - d * e))).ravel() / (2 * d) for e in np.eye(3)], 1)
    np.testing.assert_allclose(je, fd, rtol=0, atol=1e-9)
    if not np.any(w0):
        gens = np.stack([hat(e).T.reshape(9) for e in np.eye(3)], axis=1)  # column-major vec(hat(e_i))
        np.testing.assert_allclose(je, gens, rtol=0, atol=1e-15)
        np.testing.assert_allclose(jl @ gens, np.eye(3), rtol=0, atol=1e-15)


def test_casadi_derivatives_exact_at_zero():
    """At exactly w = 0 the Jacobians are the exact identity values (to round-off)."""
    w = ca.SX.sym("w", 3)
    Jlogexp = ca.Function("Jlogexp", [w], [ca.jacobian(log_so3(exp_so3(w)), w)])
    np.testing.assert_allclose(np.array(Jlogexp(np.zeros(3))), np.eye(3), rtol=0, atol=1e-15)


# ----------------------------------------------------- elementary rotations
@pytest.mark.parametrize("rot, axis", [(rot_x, 0), (rot_y, 1), (rot_z, 2)])
def test_elementary_rotations(rot, axis):
    rng = np.random.default_rng(axis)
    for deg in np.concatenate([[0.0, 90.0, 180.0, -150.0], rng.uniform(-360, 360, 50)]):
        R = rot(deg)
        orth, det = orthogonality_error(R)
        assert orth <= ORTH_TOL and det <= ORTH_TOL
        e = np.eye(3)[axis]
        np.testing.assert_allclose(R @ e, e, atol=0)                              # fixes its axis
        np.testing.assert_allclose(R, exp_so3(np.deg2rad(deg) * e), rtol=0, atol=1e-14)  # right-handed


# ------------------------------------------------------- rotations by pi, Jacobians
def test_cayley_inverse_batch_equals_single():
    rng = np.random.default_rng(7)
    C = rng.normal(size=(20, 3))
    F = np.array([cayley(c) for c in C])
    np.testing.assert_allclose(cayley_inv(F), C, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(cayley_inv(F)[3], cayley_inv(F[3]))


def test_log_any_handles_pi_rotations():
    """At exactly pi the skew part carries no sign: log_so3_any picks the one along ``prefer``."""
    R = rot_x(30) @ rot_z(180)
    for prefer in (np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0])):
        w = log_so3_any(R, prefer=prefer)
        assert abs(np.linalg.norm(w) - np.pi) <= 4 * EPS
        assert np.abs(exp_so3(w) - R).max() <= 1e-15 and w @ prefer > 0
    np.testing.assert_array_equal(log_so3_any(rot_z(40)), log_so3(rot_z(40)))


def test_right_jacobian_inverse_against_differences():
    """Log(Exp(phi) Exp(d)) - phi = Jr^-1(phi) d + O(|d|^2): with |d| = 1e-7 the remainder is
    below 1e-13 (and the relative error of the linear term below 1e-5), for angles from 1e-5 to 2.8."""
    rng = np.random.default_rng(3)
    for angle in (1.0, 1e-5, 2.8):          # inside the injectivity radius pi of log
        v = rng.normal(size=3)
        phi = angle * v / np.linalg.norm(v)
        d = 1e-7 * rng.normal(size=3)
        lhs = log_so3(exp_so3(phi) @ exp_so3(d)) - log_so3(exp_so3(phi))
        np.testing.assert_allclose(lhs, right_jacobian_inv(phi) @ d, rtol=1e-5, atol=1e-13)


# ------------------------------------------------------- charts of the state space
def test_tangent_basis_matches_left_perturbation():
    """dX = D(X) z for dR = R S(zeta): a perturbation of size 1e-7 matches to 1e-13 (O(|z|^2))."""
    rng = np.random.default_rng(1)
    R = exp_so3(rng.normal(size=3))
    X = pack_state(rng.normal(size=3), rng.normal(size=3), R, rng.normal(size=3))
    z = rng.normal(size=12) * 1e-7
    s = unpack_states(X)
    Xp = pack_state(s.x[0] + z[:3], s.gamma[0] + z[3:6], R @ exp_so3(z[6:9]), s.Pi[0] + z[9:])
    np.testing.assert_allclose(Xp - X, tangent_basis(X) @ z, rtol=0, atol=1e-13)
