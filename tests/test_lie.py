"""Properties of the Lie group helpers in transcription/lie.py (docs/mathematics.md §1-§4).

Grouped by property: hat/vee, Cayley map and its inverse, exp/log (uniform and near-identity
samples, rotations by exactly pi), the inverse right Jacobian, CasADi derivatives at the
identity, elementary rotations, the charts of the state space, rotation angles, quaternions (their
convention), geodesic interpolation, orthonormalization, the one NumPy-or-CasADi check.
All randomness is seeded; tolerances are stated next to each check.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from se3ocp.transcription.geometry.state import pack_state, tangent_basis, unpack_states
from se3ocp.transcription.geometry.so3 import (cayley, cayley_inv, exp_so3, geodesic_interpolation, hat, is_symbolic, log_so3, log_so3_any, mtimes, orthogonality_error, orthonormalize, quaternion_product, quaternions, right_jacobian_inv, rot_x, rot_y, rot_z, rotation_angle, rotation_of_quaternion, step_cayley_vectors, vee)

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


# ------------------------------------------------------------- angles and quaternions
def test_rotation_angle_and_quaternions_are_accurate_at_every_angle():
    """The angle to 1e-12 and the quaternion (cos theta/2, sin theta/2 n) to 1e-12 in w, 1e-8 in the axis
    part (the axis is ill-determined at theta = 0), from 0 to pi."""
    rng = np.random.default_rng(1)
    for theta in (0.0, 1e-9, 0.3, np.pi / 2, np.pi - 1e-9, np.pi):
        n = random_unit(rng, 1)[0]
        R = np.asarray(exp_so3(theta * n), float)
        q = quaternions(R[None])[0]
        assert abs(rotation_angle(R) - theta) <= 1e-12
        np.testing.assert_allclose(abs(q[0]), np.cos(theta / 2), atol=1e-12)
        np.testing.assert_allclose(np.abs(q[1:]), np.abs(np.sin(theta / 2) * n), atol=1e-8)


@pytest.mark.parametrize("seed", SEEDS)
def test_quaternion_convention(seed):
    """Scalar first, Hamilton, R body -> inertial (lie's docstring): the inverse of the textbook quaternion
    -> matrix map of uniform_rotations (to 1e-15, up to the sign), (0, R v) = q (0, v) q*, and
    R(p q) = R(p) R(q); unit norm to 1e-15."""
    rng = np.random.default_rng(seed)
    Rs = uniform_rotations(rng, 50)
    qs = quaternions(Rs)
    assert np.abs(np.linalg.norm(qs, axis=1) - 1.0).max() <= 4 * EPS
    for R, q, v in zip(Rs, qs, rng.standard_normal((50, 3))):
        assert np.abs(rotation_of_quaternion(q) - R).max() <= 4 * EPS
        assert np.abs(rotation_of_quaternion(-q) - R).max() <= 4 * EPS
        rotated = quaternion_product(quaternion_product(q, np.r_[0.0, v]), q * np.r_[1.0, -1.0, -1.0, -1.0])
        assert abs(rotated[0]) <= 10 * EPS * np.linalg.norm(v)
        assert np.abs(rotated[1:] - R @ v).max() <= 10 * EPS * np.linalg.norm(v)
    for p, q in zip(qs[:-1], qs[1:]):
        assert np.abs(rotation_of_quaternion(quaternion_product(p, q)) - rotation_of_quaternion(p)
                      @ rotation_of_quaternion(q)).max() <= 10 * EPS


def test_quaternion_of_a_quarter_turn_about_z():
    """Rz(90 deg) takes the body e1 to the inertial e2; its quaternion is (cos 45, 0, 0, sin 45)."""
    R = rot_z(90.0)
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(quaternions(R[None])[0], [np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)], atol=1e-15)


def test_quaternion_signs_are_continuous_along_a_path():
    """Two full turns about an axis: q(theta) = (cos theta/2, sin theta/2 n) changes sign after one turn, the
    matrices do not; the returned signs follow the continuous branch from w >= 0 at the start."""
    n = np.array([1.0, 2.0, 2.0]) / 3.0
    theta = np.linspace(0.0, 4 * np.pi, 401)
    q = quaternions(np.array([exp_so3(t * n) for t in theta]))
    assert q[0, 0] >= 0 and np.all(np.einsum("ki,ki->k", q[1:], q[:-1]) >= 0)
    ref = np.column_stack([np.cos(theta / 2), np.outer(np.sin(theta / 2), n)])
    assert np.abs(q - ref).max() <= 1e-14


# ------------------------------------------------------------- geodesics, orthonormalization
def test_geodesic_interpolation_follows_a_constant_rate_rotation():
    """Nodes of R(t) = R_0 exp(t w) interpolated anywhere in between give R(t) to 1e-14, on SO(3); held outside."""
    rng = np.random.default_rng(2)
    R0, w = uniform_rotations(rng, 1)[0], np.array([0.4, -1.1, 0.7])
    t = np.linspace(0.0, 2.0, 9)
    R = np.array([R0 @ exp_so3(tk * w) for tk in t])
    tq = np.r_[-0.5, rng.uniform(0.0, 2.0, 30), 2.5]
    out = geodesic_interpolation(R, t, tq)
    ref = np.array([R0 @ exp_so3(np.clip(tk, 0.0, 2.0) * w) for tk in tq])
    assert np.abs(out - ref).max() <= 1e-14
    # each interpolated rotation is a product of a node rotation and an exponential, each orthonormal to a few ulps:
    # their product to about twice that (measured 2.3e-15 = 10.4 eps on one x86_64 machine, below 10 eps on another)
    assert orthogonality_error(out)[0].max() <= 2 * ORTH_TOL


def test_orthonormalize_is_second_order_and_the_identity_on_so3():
    """R (3 I - R^T R) / 2: the identity on SO(3) (to round-off), an error E = R^T R - I of size d goes to O(d^2);
    NumPy and CasADi alike."""
    rng = np.random.default_rng(3)
    R = uniform_rotations(rng, 1)[0]
    assert np.abs(orthonormalize(R) - R).max() <= 4 * EPS
    for d in (1e-3, 1e-5):
        P = R @ (np.eye(3) + d * rng.standard_normal((3, 3)))
        e0 = np.linalg.norm(P.T @ P - np.eye(3))
        Q = orthonormalize(P)
        assert np.linalg.norm(Q.T @ Q - np.eye(3)) <= 3 * e0 ** 2
    S = ca.SX.sym("R", 3, 3)
    f = ca.Function("o", [S], [orthonormalize(S)])
    assert np.abs(np.array(f(P)) - orthonormalize(P)).max() <= 4 * EPS


def test_step_cayley_vectors_rebuild_the_steps():
    """R_{k+1} = R_k cay(c_k) to 1e-15 along uniform random attitudes."""
    R = uniform_rotations(np.random.default_rng(4), 20)
    c = step_cayley_vectors(R)
    assert c.shape == (19, 3)
    assert max(np.abs(R[k] @ cayley(c[k]) - R[k + 1]).max() for k in range(19)) <= 1e-14


def test_the_one_backend_check():
    """is_symbolic is True for SX, MX and DM, False for NumPy and numbers; mtimes follows it."""
    assert all(is_symbolic(a) for a in (ca.SX.sym("a"), ca.MX.sym("b"), ca.DM(1.0)))
    assert not any(is_symbolic(a) for a in (np.eye(3), 1.0, [1.0]))
    A, B = np.arange(9.0).reshape(3, 3), np.eye(3) * 2
    assert isinstance(mtimes(A, B), np.ndarray) and np.array_equal(mtimes(A, B), A @ B)
    S = ca.SX.sym("S", 3, 3)
    assert isinstance(mtimes(A, S), ca.SX)
    assert np.array_equal(np.array(ca.Function("m", [S], [mtimes(A, S)])(B)), A @ B)



def test_log_so3_small_symbolic_equals_numpy():
    """log_so3_small in CasADi (the flight loop's tracking error) equals the NumPy logarithm to round-off for
    angles from 1e-9 to 2.5 rad (measured <= 4e-16 relative), where log_so3's acos branch loses eps/theta^2."""
    import casadi as ca

    from se3ocp.transcription.geometry.so3 import exp_so3, log_so3, log_so3_small

    R = ca.SX.sym("R", 3, 3)
    f = ca.Function("log_small", [R], [log_so3_small(R)])
    rng = np.random.default_rng(0)
    worst = 0.0
    for theta in (1e-9, 1e-6, 1e-4, 1e-3, 0.3, 1.0, 2.5):
        n = rng.standard_normal(3)
        w = theta * n / np.linalg.norm(n)
        Rn = exp_so3(w)
        worst = max(worst, np.abs(np.array(f(Rn)).ravel() - log_so3(Rn)).max() / theta)
    assert worst <= 1e-14, worst
