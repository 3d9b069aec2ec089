"""The Problem (transcription/problem/): validation, terminal conditions, costs."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from se3ocp.transcription.geometry.state import pack_state
from se3ocp.transcription.geometry.so3 import exp_so3
from se3ocp.transcription.ocp import (ImpulsiveControl, Problem, ProblemError, SmoothControl, TargetOrbit, TargetState, effort_cost, orbit_conditions, quadrature_weights, state_residual, terminal_error)
from se3ocp.transcription.objectives import Effort
from support import problem


def _random_state(rng):
    return pack_state(rng.normal(size=3), rng.normal(size=3), exp_so3(rng.normal(size=3)), rng.normal(size=3))


@pytest.mark.parametrize("fixed", [("position", "velocity", "attitude", "angular_velocity"), ("attitude",),
                                   ("position", "angular_velocity")])
def test_state_residual_symbolic_equals_numeric(fixed):
    """One definition serves CasADi and NumPy: the same numbers to 1e-14 (away from pi)."""
    rng = np.random.default_rng(0)
    X, Xd = _random_state(rng), _random_state(rng)
    Xd[6:15] = (X[6:15].reshape(3, 3, order="F") @ exp_so3(0.3 * rng.normal(size=3))).ravel(order="F")
    S = ca.SX.sym("X", 18)
    sym = np.array(ca.Function("r", [S], [state_residual(S, Xd, fixed)])(X)).ravel()
    num = state_residual(X, Xd, fixed)
    assert sym.shape == (3 * len(fixed),) and np.abs(sym - num).max() <= 1e-14


def test_terminal_error_is_the_max_norm_of_the_residual():
    rng = np.random.default_rng(1)
    p = problem("e3", 20)
    X = _random_state(rng)
    assert terminal_error(X, p) == np.abs(state_residual(X, p.terminal.X)).max()
    assert terminal_error(p.terminal.X, p) == 0.0


def test_orbit_conditions_vanish_on_the_target_orbit():
    """A point of the target orbit with the body axis along the normal satisfies C = 0 to 1e-15;
    the post-impulse momentum is the circular one (|gamma+| = m sqrt(mu/r))."""
    p = problem("e2", 20)
    t: TargetOrbit = p.terminal
    n, a, b = t.plane_basis()
    x = t.radius * (np.cos(0.7) * a + np.sin(0.7) * b)
    R = np.column_stack([n, x / np.linalg.norm(x), np.cross(n, x / np.linalg.norm(x))])
    C, gp, Pp = orbit_conditions(pack_state(x, np.zeros(3), R, np.zeros(3)), t, p.model.mass, p.model.mu)
    assert np.abs(C).max() <= 1e-15 and abs(np.linalg.norm(gp) - np.sqrt(p.model.mu / t.radius)) <= 1e-14
    assert abs(gp @ x) <= 1e-14 and np.all(Pp == 0)


def test_quadrature_weights_and_effort_cost():
    om = quadrature_weights("lgvi", 10, 0.1)
    assert om[0] == om[-1] == pytest.approx(0.05) and np.allclose(om[1:-1], 0.1)
    assert np.allclose(quadrature_weights("first_order", 10, 0.1), 0.1)
    c = SmoothControl(W_f=2.0, W_m=[1.0, 2.0, 3.0], objective=Effort())
    U = np.ones((6, 11))
    # constant unit controls over T = 1: (1/2) sum_i W_ii = (1/2)(3 * 2 + 6)
    assert effort_cost(U, c, om) == pytest.approx(6.0, rel=1e-14)
    full = SmoothControl(W_f=[[2, 0.5, 0], [0.5, 1, 0], [0, 0, 1]], objective=Effort())
    u = np.array([1.0, -1.0, 0, 0, 0, 0])[:, None]
    assert effort_cost(u, full, np.array([2.0])) == pytest.approx(u[:3, 0] @ full.W_f @ u[:3, 0], rel=1e-15)


@pytest.mark.parametrize("kw, field", [({"N": 0}, "N"), ({"N": 2.5}, "N"), ({"T": -1.0}, "T"), ({"T": np.inf}, "T"),
                                       ({"X0": np.zeros(17)}, "X0"), ({"terminal": None}, "terminal"),
                                       ({"control": ImpulsiveControl(), "terminal": TargetState(np.zeros(18), frozenset({"attitude"}))}, "terminal.free")])
def test_problem_validation_names_the_field(kw, field):
    p = problem("e3", 10)
    base = dict(disc=p.disc, N=p.N, T=p.T, X0=p.X0, terminal=p.terminal, control=p.control)
    base.update(kw)
    with pytest.raises(ProblemError) as e:
        Problem(**base)
    assert e.value.field == field


@pytest.mark.parametrize("W", [0.0, [1, -1, 1], [[1, 2, 0], [2, 1, 0], [0, 0, 1]], [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]])
def test_weights_must_be_symmetric_positive_definite(W):
    with pytest.raises(ProblemError, match="control.W_f"):
        SmoothControl(W_f=W, objective=Effort())


def test_targets_validate_and_normalize():
    t = TargetOrbit(2.0, [0, 0, 5.0])
    np.testing.assert_array_equal(t.normal, [0, 0, 1.0])
    with pytest.raises(ProblemError, match="terminal.normal"):
        TargetOrbit(2.0, [0, 0, 0])
    with pytest.raises(ProblemError, match="terminal.free"):
        TargetState(np.zeros(18), frozenset({"spin"}))


def test_mesh_steps_sum_to_T_and_bad_meshes_name_the_field():
    """Problem.mesh: relative step sizes normalized to mean 1, h_k = h r_k summing to T; uniform -> None."""
    base = problem("e3")
    r = np.linspace(1.0, 3.0, base.N)
    p = base.replace(mesh=r)
    assert not p.uniform and abs(p.mesh.mean() - 1.0) < 1e-15
    assert abs(p.steps.sum() - p.T) <= 1e-12 * p.T and p.times[0] == 0.0 and abs(p.times[-1] - p.T) <= 1e-12 * p.T
    np.testing.assert_allclose(p.steps / p.steps[0], r / r[0], rtol=1e-14)
    assert base.replace(mesh=np.full(base.N, 2.0)).uniform
    for bad in (np.ones(base.N - 1), -np.ones(base.N), np.full(base.N, np.nan)):
        with pytest.raises(ProblemError, match="mesh"):
            base.replace(mesh=bad)
