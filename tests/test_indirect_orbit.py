"""The indirect method to an orbit target (docs/mathematics.md §19): the free motions K span the null space of the
conditions' Jacobian, the transversality conditions hold at the solution, and the indirect optimum is the direct
one on the effort version of the bundled fuel raise (configs/orbit_raise_fuel.yaml)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NX, NZ, chart, pack_state
from se3ocp.transcription.geometry.so3 import exp_so3
from se3ocp.transcription.methods.indirect.orbit import null_basis, orbit_shooting_function
from se3ocp.transcription.ocp import orbit_residual

from support import maneuver

EFFORT = "control.objective=effort"


def conditions_jacobian(problem, XN):
    """G = d g(chart(X_N, z))/dz at z = 0 (10 x 12) by CasADi, independently of K."""
    z = ca.SX.sym("z", NZ)
    g = orbit_residual(chart(ca.DM(XN), z), problem.terminal, problem.model.mass, problem.model.mu)
    return np.array(ca.Function("G", [z], [ca.jacobian(g, z)])(np.zeros(NZ)))


def random_state(rng):
    return pack_state(rng.normal(size=3), rng.normal(size=3), np.array(exp_so3(rng.normal(size=3))),
                      rng.normal(size=3))


def test_free_motions_span_the_null_space_of_the_conditions():
    p = maneuver("orbit_raise_fuel", 20, None, EFFORT).problem
    K = ca.Function("K", [X := ca.SX.sym("X", NX)], [null_basis(X, p.terminal, p.model.mass, p.model.mu)])
    rng = np.random.default_rng(3)
    for _ in range(5):
        XN = random_state(rng)
        G, Kx = conditions_jacobian(p, XN), np.array(K(XN))
        assert np.abs(G @ Kx).max() <= 1e-13 * np.abs(G).max() * np.abs(Kx).max()
        assert np.linalg.matrix_rank(G, tol=1e-10) == 10 and np.linalg.matrix_rank(Kx) == 2
        # the residual's Jacobian in z: the conditions' rows are G
        _, JX, Jl = orbit_shooting_function(p.terminal, p.model.mass, p.model.mu)(XN, rng.normal(size=NZ))
        assert np.allclose(np.array(JX)[:10], G, rtol=0, atol=1e-13 * np.abs(G).max())
        assert np.array_equal(np.array(Jl)[10:], Kx.T)


@pytest.fixture(scope="module")
def effort_raise():
    """The effort raise at N = 60 by both methods (the indirect start from lambda_0 = 0 fails; the fallback
    starts it from the direct solution).  The force bound is active at N = 60: at the default tol the direct
    solution sits inside it and costs 4.8e-7 relative more, so the direct method runs at tol 1e-12."""
    return se3ocp.solve(maneuver("orbit_raise_fuel", 60, None, EFFORT), "both", direct={"tol": 1e-12})


def test_indirect_equals_direct_on_an_orbit_target(effort_raise):
    c = effort_raise
    d, i = c.direct, c.indirect
    assert d.converged and i.converged, i.message
    assert c.verdict.startswith("agree"), c.verdict
    assert i.stats["fallback"] == "from_direct"
    assert abs(i.cost - d.cost) <= 1e-8 * d.cost
    assert i.terminal_error <= 1e-12
    assert np.abs(i.controls - d.controls).max() <= 1e-4 * np.abs(d.controls).max()


def test_transversality_at_the_solution(effort_raise):
    """lambda_{N-1} = G^T nu for some nu (least squares) to round-off, G from CasADi independently of K; and
    lambda_{N-1} is not trivially 0 on the free motions' complement."""
    sol = effort_raise.indirect
    p = sol.problem
    G = conditions_jacobian(p, sol.trajectory.X[-1])
    lamN = sol.costates[-1]
    nu = np.linalg.lstsq(G.T, lamN, rcond=None)[0]
    assert np.linalg.norm(G.T @ nu - lamN) <= 1e-12 * np.linalg.norm(lamN)
    assert np.linalg.norm(lamN) > 1e-2


def test_mpc_refuses_what_only_the_solve_covers():
    """The re-planner's shooting is the state target's with the effort law: an orbit target and the fuel objective,
    which the indirect solve now covers, are refused with their names (before: the solve's coverage was the
    re-planner's)."""
    from se3ocp.transcription.closedloop.mpc import Replanner, replan_not_covered

    p = maneuver("orbit_raise_fuel", 20).problem
    assert replan_not_covered(p) == "the fuel objective, an orbit target in a re-plan"
    with pytest.raises(ValueError, match="does not cover the fuel objective, an orbit target in a re-plan"):
        Replanner(p, p.h, jit=False)
    assert replan_not_covered(maneuver("e3", 20).problem) == ""
