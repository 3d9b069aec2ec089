"""The translational relaxation of the LEO engine fuel raise by successive convexification (scripts/scvx_relaxation.py,
optional extra ``scvx``: cvxpy and Clarabel) against our direct method's optimum of the same relaxed problem and against
Hohmann's delta-v (issue 41's speed anchor).  Skipped cleanly where cvxpy or Clarabel is not installed.

configs/leo_body_engine.yaml with the fuel objective at N = 100 (the file's 400 takes SCvx ~1.2 s but IPOPT ~8 s; on
the Kepler-split scheme the discrete orbit is exact at any N, so 100 steps are the same maneuver).

Why the costs agree to 1e-6 and the controls need not: the relaxed optimum is degenerate.  For a raise of 10 km on a
6778 km orbit every spread of along-track burns that keeps the orbit circular and the phase meets the target at the
same first-order cost, v da / (2 a) -- Hohmann's -- and the burns' placement changes the cost only at second order, (da /
a)^2 ~ 2e-6 of it.  Two solvers end at different points of that near-flat face (SCvx's subproblem, linear in it, needs
its proximal term to stop moving), at costs that differ by their tolerances only: IPOPT's KKT tolerance 1e-8 (scaled),
Clarabel's 1e-10 and SCvx's step 1e-5 (a cost error of the order of the face's curvature times the step squared).
Measured: 3.1e-9 at N = 100 (6.5e-10 at N = 400, 6.6e-9 at N = 50); 1e-6 is the brief's aim and leaves a margin of
300.  The relaxed delta-v is 8.3e-8 above Hohmann's (the discrete problem is exactly a sequence of impulses at the
nodes between exact Kepler arcs, so it cannot beat Hohmann; a continuous spread of small along-track burns on a small
raise is as efficient to first order)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.ocp.feasibility import orbit_capacity
from support import config

pytest.importorskip("cvxpy", reason="the optional extra 'scvx' (cvxpy + Clarabel)")
pytest.importorskip("clarabel", reason="the optional extra 'scvx' (cvxpy + Clarabel)")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import scvx_relaxation  # noqa: E402

N = 100
#: the relative agreement of the two optima (module docstring)
COST_RTOL = 1e-6
#: the relaxed delta-v may fall below Hohmann's by at most this fraction: the plans' terminal velocity misses (below
#: 1e-11 km/s for SCvx's, IPOPT's within its 1e-8 KKT tolerance) move the delta-v by less than 1e-9 of it
HOHMANN_SLACK = 1e-9


@pytest.fixture(scope="module")
def solved():
    problem = se3ocp.load(config("leo_body_engine"), ["control.objective=fuel", f"horizon.N={N}"]).problem
    return problem, scvx_relaxation.solve(problem), scvx_relaxation.solve_relaxed(problem)


def test_scvx_optimum_equals_ipopt_optimum_of_the_same_relaxed_problem(solved):
    problem, scvx, ipopt = solved
    assert scvx.converged, scvx.history[-3:]
    assert scvx.iterations <= 20
    assert ipopt.converged, ipopt.message
    assert abs(ipopt.cost - scvx.cost) <= COST_RTOL * scvx.cost, (scvx.cost, ipopt.cost)


def test_relaxed_delta_v_is_hohmanns_within_ten_percent_and_not_below(solved):
    problem, scvx, ipopt = solved
    r0, r1, hohmann, _ = orbit_capacity(problem)
    assert (r0, r1) == pytest.approx((6778.137, 6788.137))
    m = problem.model.mass
    for cost in (scvx.cost, ipopt.cost):
        dv = cost / m                      # kN s / kg = km/s (w_f = 1)
        assert hohmann * (1 - HOHMANN_SLACK) <= dv <= 1.10 * hohmann, (dv, hohmann)


def test_scvx_plan_is_a_plan_of_our_discretization(solved):
    """SCvx's own translation (kick, the project's exact two-body drift, kick) is our lgvi_kepler step: its controls,
    flown by ``se3ocp.simulate`` through the relaxed Problem's 18-state step, meet the target (the residual's
    position rows in km, momentum rows in kg km/s), within the bound and at the cost SCvx reports."""
    problem, scvx, _ = solved
    rel = scvx_relaxation.relaxed_problem(problem)
    F = problem.control.force_bound.largest_norm()
    assert np.linalg.norm(scvx.U, axis=0).max() <= F * (1 + 1e-8)
    U6 = np.vstack([scvx.U, np.zeros_like(scvx.U)])
    flown = se3ocp.simulate(rel, U6)
    assert flown.terminal_error <= 1e-6, flown.terminal_error
    assert rel.control.objective.value(rel, U6, rel.h) == pytest.approx(scvx.cost, rel=1e-12)
