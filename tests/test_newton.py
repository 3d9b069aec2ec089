"""The one Newton-Armijo loop (transcription/newton.py), on small systems with known answers."""
from __future__ import annotations

import numpy as np

from se3ocp.transcription.methods.newton import newton_armijo, noise_level
from se3ocp.transcription.outcome import Result


def _system(x):
    """F(x) = [x0^2 + x1^2 - 4; x0 - x1]: root (sqrt 2, sqrt 2) from the first quadrant."""
    return np.array([x[0] ** 2 + x[1] ** 2 - 4.0, x[0] - x[1]]), 0.0


def _jac(x):
    return np.array([[2 * x[0], 2 * x[1]], [1.0, -1.0]])


def test_quadratic_convergence_to_the_root():
    r = newton_armijo(np.array([3.0, 1.0]), _system, _jac, tol=1e-14, norm=np.inf)
    assert r.result is Result.converged and np.abs(r.x - np.sqrt(2)).max() <= 1e-15
    e = [h.residual for h in r.history if h.accepted]
    tail = [(a, b) for a, b in zip(e[:-1], e[1:]) if a < 1e-2 and b > 1e-15]
    assert tail and all(b <= 10 * a * a for a, b in tail)                # e_{k+1} <= C e_k^2, C = 10


def test_line_search_halves_and_records_every_trial():
    """From far away the full step overshoots F = atan(x) and must be halved; every trial is recorded."""
    F = lambda x: (np.arctan(x), 0.0)                                     # noqa: E731
    J = lambda x: np.array([[1.0 / (1.0 + x[0] ** 2)]])                   # noqa: E731
    r = newton_armijo(np.array([10.0]), F, J, tol=1e-14)
    assert r.result is Result.converged and abs(r.x[0]) <= 1e-14
    assert any(h.trial > 1 for h in r.history)                            # a halving happened
    assert sum(h.accepted for h in r.history if h.trial > 0) == r.iterations


def test_rejected_trials_by_the_aux_bound():
    """A trial whose aux exceeds aux_tol counts as no decrease, even if F decreased: from 0 the full
    step to 1 is rejected, the half step to 0.5 accepted; from 0.5 every trial (1, 0.75, 0.625,
    0.5625) lies where aux = 1: the line search fails with x = 0.5 after one iteration."""
    def F(x):
        return np.array([x[0] - 1.0]), (1.0 if x[0] > 0.5 else 0.0)
    r = newton_armijo(np.array([0.0]), F, lambda x: np.eye(1), tol=1e-12, max_halvings=3, aux_tol=0.5)
    assert r.result is Result.line_search_failed and r.rejected_aux == [1.0] * 5
    assert r.x[0] == 0.5 and r.iterations == 1


def test_round_off_floor_is_detected_and_reported():
    """F with evaluation noise at ~1e-9 (relative 2^-30 in x): the iteration stops at the floor,
    converged, with the measured level reported; above floor_accept it is floor_too_high."""
    def F(x):
        return np.array([np.round((x[0] - 1.0) * 2**30) / 2**30 + 1e-9 * np.sin(1e9 * x[0])]), 0.0
    J = lambda x: np.eye(1)                                               # noqa: E731
    r = newton_armijo(np.array([3.0]), F, J, tol=0.0, floor_factor=10.0, floor_accept=1e-6)
    assert r.result is Result.round_off_floor and r.floor is not None and r.floor <= 10 * r.noise
    assert abs(r.x[0] - 1.0) <= 1e-8
    r = newton_armijo(np.array([3.0]), F, J, tol=0.0, floor_factor=10.0, floor_accept=1e-12)
    assert r.result is Result.floor_too_high and "floor_accept" in r.message


def test_singular_and_non_finite_are_data():
    r = newton_armijo(np.array([1.0, 1.0]), _system, lambda x: np.zeros((2, 2)), tol=1e-12)
    assert r.result is Result.singular_jacobian and r.iterations == 0
    r = newton_armijo(np.array([np.nan, 1.0]), _system, _jac, tol=1e-12)
    assert r.result is Result.non_finite


def test_step_cap_and_stagnation():
    """With |D / scale| capped at 1 a far root takes many short steps; stagnation_steps stops a run
    of steps shorter than 1e-2."""
    F = lambda x: (np.array([x[0] - 100.0]), 0.0)                         # noqa: E731
    r = newton_armijo(np.array([0.0]), F, lambda x: np.eye(1), tol=1e-12, step_scale=np.array([1.0]), max_iter=200)
    assert r.result is Result.converged and r.iterations == 100
    G = lambda x: (np.array([np.arctan(x[0] - 1e6) + 1e-3 * x[0]]), 0.0)  # noqa: E731
    r = newton_armijo(np.array([0.0]), G, lambda x: np.array([[1 / (1 + (x[0] - 1e6) ** 2) + 1e-3]]), tol=1e-12,
                      stagnation_steps=3, max_halvings=40)
    assert r.result in (Result.stagnated, Result.converged)


def test_noise_level_measures_the_nonlinear_remainder():
    """For an exactly linear F evaluated in floating point the measured level is round-off (<= 1e-14)."""
    A = np.array([[2.0, 1.0], [1.0, 3.0]])
    x = np.array([0.3, -0.7])
    assert noise_level(lambda y: A @ y, x, A @ x, A) <= 1e-14


def test_a_step_below_the_resolution_of_x_is_the_floor():
    """|F| = max(|x - 1|, 1e-12) at x = 1: a residual floor that ulp perturbations of x do not see (the measured
    noise is ~1e-16).  The line search halves until x + c D == x; with floor detection that is the round-off floor
    (accepted below floor_accept), without it the iteration stagnated."""
    F = lambda x: (np.array([max(abs(x[0] - 1.0), 1e-12)]), 0.0)          # noqa: E731
    J = lambda x: np.array([[1.0]])                                         # noqa: E731
    r = newton_armijo(np.array([1.0]), F, J, tol=0.0, floor_factor=10.0)
    assert r.result is Result.round_off_floor and r.floor == 1e-12 and r.x[0] == 1.0
    assert newton_armijo(np.array([1.0]), F, J, tol=0.0).result is Result.stagnated
    assert newton_armijo(np.array([1.0]), F, J, tol=0.0, floor_factor=10.0, floor_accept=1e-13).result is \
        Result.floor_too_high
