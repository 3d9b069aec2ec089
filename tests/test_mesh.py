"""The direct method on a non-uniform mesh (issue 26, docs/mathematics.md §16): step k of size h_k = h r_k in
both schemes, the per-step quadrature, node times from the mesh, warm starts resampled onto it."""
from __future__ import annotations

import numpy as np
import pytest

from se3ocp.transcription.layout import U_FORCE, U_MOMENT, unpack_states
from se3ocp.transcription.lie import orthogonality_error
from se3ocp.transcription.problem import quadrature_weights
from se3ocp.transcription.solve import not_covered, solve
from support import problem

N = 60


def random_mesh(n: int, seed: int = 1) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.5, 2.0, n)


def independent_effort(U: np.ndarray, h: np.ndarray, scheme: str, Wf: np.ndarray, Wm: np.ndarray) -> float:
    """The effort written out step by step: lgvi sum_k h_k/4 (u_k'Wu_k + u_{k+1}'Wu_{k+1}), first order
    sum_k h_k/2 u_{k+1}'W u_{k+1} (U of first order holds u_1..u_N)."""
    def q(u):
        return u[U_FORCE] @ Wf @ u[U_FORCE] + u[U_MOMENT] @ Wm @ u[U_MOMENT]
    if scheme == "lgvi":
        return sum(0.25 * h[k] * (q(U[:, k]) + q(U[:, k + 1])) for k in range(len(h)))
    return sum(0.5 * h[k] * q(U[:, k]) for k in range(len(h)))


@pytest.mark.parametrize("name", ["e3", "e4"])
@pytest.mark.parametrize("scheme", ["lgvi", "first_order"])
def test_direct_on_a_random_mesh_solves_each_step_with_its_own_h(name, scheme):
    """r_k random in [0.5, 2]: converged; stepping the controls node by node with disc.step(X_k, w_k, h_k)
    reproduces every node to round-off (and with the mean step it does not); the cost equals the per-step
    quadrature written out here; node times are the mesh's."""
    base = problem(name, N, scheme)
    p = base.replace(mesh=random_mesh(N))
    sol = solve(p, "direct")
    assert sol.converged, sol.message
    assert sol.terminal_error <= 1e-10 and sol.stats["max_defect"] <= 1e-8
    np.testing.assert_allclose(sol.trajectory.t, p.times, rtol=0, atol=1e-14 * p.T)
    np.testing.assert_allclose(sol.steps, p.steps, rtol=1e-12)
    X, W, h = sol.trajectory.X, p.disc.stage_controls(sol.controls), p.steps
    scale = np.abs(X).max()
    own = max(np.abs(np.array(p.disc.step(X[k], W[:, k], h[k])[0]).ravel() - X[k + 1]).max() for k in range(N))
    mean = max(np.abs(np.array(p.disc.step(X[k], W[:, k], p.h)[0]).ravel() - X[k + 1]).max() for k in range(N))
    assert own <= 1e-12 * scale, own
    assert mean >= 1e-4 * scale, mean                     # the steps are really of different sizes
    c = p.control
    assert abs(sol.cost - independent_effort(sol.controls, h, scheme, c.W_f, c.W_m)) <= 1e-12 * sol.cost
    assert sol.summary()["h_min"] == pytest.approx(h.min()) and sol.summary()["h_max"] == pytest.approx(h.max())


def test_a_uniform_mesh_given_explicitly_is_bit_identical_to_none():
    """mesh = r with all r equal (whatever their value and the round-off of their mean) is the uniform problem:
    the same controls and cost to the bit."""
    base = problem("e3", 40)
    same = base.replace(mesh=np.full(40, 0.1))
    assert same.uniform
    a, b = solve(base, "direct"), solve(same, "direct")
    assert a.cost == b.cost
    np.testing.assert_array_equal(a.controls, b.controls)
    np.testing.assert_array_equal(a.trajectory.t, b.trajectory.t)


def test_quadrature_weights_per_step_sum_to_T_and_integrate_linear_functions_exactly():
    """omega_j on a mesh: both schemes sum to T; the trapezoid integrates u(t) = a + b t exactly."""
    h = random_mesh(30, seed=4) * 0.1
    t = np.r_[0.0, np.cumsum(h)]
    for scheme in ("lgvi", "first_order"):
        assert abs(quadrature_weights(scheme, 30, h).sum() - t[-1]) <= 1e-14
    om = quadrature_weights("lgvi", 30, h)
    assert abs(om @ (2.0 + 3.0 * t) - (2.0 * t[-1] + 1.5 * t[-1] ** 2)) <= 1e-13
    np.testing.assert_array_equal(quadrature_weights("lgvi", 30, np.full(30, 0.1)), quadrature_weights("lgvi", 30, 0.1))


def test_both_smooth_methods_take_a_mesh_and_the_impulsive_one_refuses_it():
    """The guard is per method and kind of control: the direct and the indirect method take a mesh for smooth
    control (tests/test_indirect_mesh.py for the indirect one); the impulsive transcription refuses one."""
    p = problem("e3", 20).replace(mesh=random_mesh(20))
    assert not_covered(p, "direct") == not_covered(p, "indirect") == not_covered(p, "both") == ""
    q = problem("e1", 20).replace(mesh=random_mesh(20))
    assert "non-uniform mesh" in not_covered(q, "direct")


def test_free_final_time_on_a_mesh_scales_every_step_together():
    """configs/e3_free_time.yaml on a mesh: T = sum h_k = N h, the relative steps kept."""
    p = problem("e3_free_time", 40).replace(mesh=random_mesh(40))
    sol = solve(p, "direct")
    assert sol.converged, sol.message
    assert abs(sol.T - sol.stats["T"]) <= 1e-12 * sol.T
    np.testing.assert_allclose(sol.steps / sol.h, p.mesh, rtol=1e-10)


def test_a_warm_start_is_resampled_onto_a_mesh_on_SO3():
    """A uniform solution warm-starts a mesh of other N: fitted onto the mesh's node times, attitudes on SO(3),
    the end nodes copied; the solve from it converges to the mesh's own optimum."""
    u = solve(problem("e4", 40), "direct")
    p = problem("e4", 50).replace(mesh=random_mesh(50, seed=2))
    fitted, notes = u.warm.fit(p.N, p.scheme, p.fractions)
    np.testing.assert_allclose(fitted.t, p.times, rtol=0, atol=1e-12 * p.T)
    assert "non-uniform mesh" in notes[0]
    R = unpack_states(fitted.X).R
    assert orthogonality_error(R)[0].max() <= 1e-13
    np.testing.assert_array_equal(fitted.X[[0, -1]], u.warm.X[[0, -1]])
    cold, warm = solve(p, "direct"), solve(p, "direct", warm_start=u)
    assert warm.converged and abs(warm.cost - cold.cost) <= 1e-8 * cold.cost
    assert warm.stats["warm_start_resampled"]
