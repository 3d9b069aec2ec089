"""fatrop's stage form of the bounded and fuel NLPs (transcription/methods/direct/fatrop.py, issue 27).

The stage-ordered transcription takes the control-node rows (norm bounds, the fuel epigraph u = s d, |d|^2 <= 1)
as path rows of the stage whose stage control holds the node's copy of u_j and its slacks, the fuel magnitudes'
s >= 0 as variable bounds, and an orbit target's rows at stage N.  Effort problems to an orbit target are covered
(fatrop reaches IPOPT's optimum); on the fuel NLP fatrop does not converge (tests/test_fuel_homotopy.py), so the
fuel objective is not covered and a fuel solve with ``solver: fatrop`` is IPOPT's.
"""
from __future__ import annotations

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.methods.direct import fatrop
from se3ocp.transcription.objectives import Fuel
from se3ocp.transcription.objectives.effort import relaxation
from se3ocp.transcription.solve import solve_direct
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from se3ocp.transcription.nlp.layouts import StageLayout
from se3ocp.transcription.ocp import TargetOrbit
from support import problem

SCHEMES = ["first_order", "lgvi"]


@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_control_node_is_a_path_row_block_of_one_stage(scheme):
    """The fuel raise's stage-ordered NLP (N = 6): the rows in fatrop's order are a permutation of all rows; each
    control node j's rows (norm bounds, |d|^2 <= 1, u - s d) sit in stage max(j - 1, 0) beside the variables they
    use; the gaps are the negated defects (and lifting rows); fatrop accepts the structure (CasADi checks the
    Jacobian's block pattern when the solver is built)."""
    p = problem("orbit_raise_fuel", 6, scheme)
    opts = se3ocp.DirectOptions(jit=False)
    tr = SmoothTranscription(p, opts, stage_order=True)
    lay, nlp = tr.layout, tr.nlp
    assert isinstance(lay, StageLayout) and lay.iS.shape == (8, len(lay.control_nodes))
    perm, sign, ng = fatrop.stage_rows(tr)
    assert np.array_equal(np.sort(perm), np.arange(nlp.ng)) and len(ng) == p.N + 1
    ngap = 18 + (6 if scheme == "lgvi" else 0)           # the state s_k: X_k (and v_k = u_k, LGVI)
    assert ngap * p.N + sum(ng) == nlp.ng
    stage_of_row, pos = np.empty(nlp.ng, dtype=int), 0
    for k in range(p.N + 1):
        gap = ngap if k < p.N else 0
        assert np.all(sign[pos:pos + min(gap, 18)] == -1.0) and np.all(sign[pos + min(gap, 18):pos + gap + ng[k]] == 1.0)
        stage_of_row[perm[pos:pos + gap + ng[k]]] = k
        pos += gap + ng[k]
    for name in ("controls", "fuel"):          # the norm bounds; the fuel epigraph
        ctrl, rows = next(b for b in nlp.blocks if b.name == name), nlp.rows(name)
        for m, j in enumerate(lay.control_nodes):
            assert np.all(stage_of_row[rows[:, m]] == max(j - 1, 0))
            assert np.all(lay.stage_of[ctrl.idx[:, m]] == max(j - 1, 0))
    solver, _, _ = fatrop._fatrop_solver(tr, opts)
    assert solver.name() == "direct_fatrop"


def test_fatrop_reaches_ipopts_optimum_to_the_orbit_target():
    """The effort raise to the orbit target without its bounds (first order, N = 40; newly covered): fatrop's
    optimum, the orbit target's rows at stage N, is IPOPT's, cost to 1e-8 and controls to 1e-6 relative
    (measured: 24 iterations against 54, cost to 5e-15, controls to 3e-15)."""
    p = relaxation(problem("orbit_raise_fuel", 40, "first_order", "control.objective=effort"))
    assert isinstance(p.terminal, TargetOrbit) and not p.control.bounded and fatrop.covers(p)
    ip, fa = solve_direct(p, se3ocp.DirectOptions()), solve_direct(p, se3ocp.DirectOptions(solver="fatrop"))
    assert ip.converged and fa.converged and fa.solver == "fatrop", (ip.message, fa.message)
    assert abs(fa.cost - ip.cost) <= 1e-8 * ip.cost
    assert np.abs(fa.controls - ip.controls).max() <= 1e-6 * np.abs(ip.controls).max()


def test_the_fuel_objective_is_not_covered_and_says_why():
    """A fuel problem with ``solver: fatrop`` goes to IPOPT at once (no fatrop iteration): fatrop's status
    not_applicable, the fuel objective's reason (``Fuel.fatrop``) in the fallback's message; effort problems without
    bounds stay covered."""
    sol = solve_direct(problem("orbit_raise_fuel", 10), se3ocp.DirectOptions(solver="fatrop"))
    assert sol.stats["fatrop_status"] == "not_applicable" and sol.solver == "ipopt"
    assert sol.stats["fatrop_message"] == Fuel.fatrop and "fuel NLP" in sol.stats["fatrop_message"]
    assert sol.message.startswith(Fuel.fatrop + "; IPOPT fallback: ")
    assert fatrop.covers(problem("e3", 10)) and not fatrop.covers(problem("e3_bounded", 10))
    assert fatrop.not_covered(problem("e3_bounded", 10)) == fatrop.NOT_COVERED
