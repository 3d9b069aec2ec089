"""The one NLP builder (transcription/nlp/structured.py): block-assembled derivatives are exact, and the
NLP it builds is the discrete problem.

The Jacobian, gradient and Lagrangian Hessian assembled block by block (each block's derivatives
mapped over its instances and scattered) are compared with CasADi's AD of the same NLP written
as one expression (nlp.f, nlp.g), at random points, for every transcription that uses the
builder: smooth control (both schemes, with and without Cayley unknowns) and the relaxed
impulsive problem.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.dynamics.lgvi import Discretization
from se3ocp.transcription.nlp import blocks
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from se3ocp.transcription.strategy import starts
from se3ocp.transcription.nlp import Block, NLPLayout, StructuredNLP, assemble, solve_time_split
from se3ocp.transcription.options import DirectOptions
from support import maneuver, problem

SCHEMES = ("first_order", "lgvi")


def _dense(a) -> np.ndarray:
    return ca.densify(ca.DM(a)).full()


def _compare_with_ad(n: StructuredNLP, x: np.ndarray, lam: np.ndarray, sigma: float = 0.7):
    """Assembled derivatives at (x, lam) against AD of the expression graph: to 1e-10 relative."""
    d = n.derivative_functions()
    w = n.w
    lf, lg = ca.MX.sym("lf"), ca.MX.sym("lg", n.ng)
    ref_J = ca.Function("J", [w], [ca.jacobian(n.g, w)])(x)
    ref_g = ca.Function("g", [w], [ca.gradient(n.f, w)])(x)
    ref_H = ca.Function("H", [w, lf, lg], [ca.hessian(lf * n.f + ca.dot(lg, n.g), w)[0]])(x, sigma, lam)
    J = d["jac_g"](x, [])[1]
    g = d["grad_f"](x, [])[1]
    H = d["hess_lag"](x, [], sigma, lam)
    for name, A, B in (("jac_g", J, ref_J), ("grad_f", g, ref_g), ("hess_lag", H, ref_H)):
        A, B = _dense(A), _dense(B)
        if name == "hess_lag":                       # the solver takes the upper triangle
            A, B = np.triu(A), np.triu(B)
        scale = max(1.0, np.abs(B).max())
        assert np.abs(A - B).max() <= 1e-10 * scale, f"{name}: {np.abs(A - B).max():.2e}"


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("with_c", [True, False])
def test_smooth_blocks_equal_ad_of_the_whole_nlp(scheme, with_c):
    p = problem("e4", 12, scheme)
    tr = SmoothTranscription(p, DirectOptions(cayley_variables=with_c, jit=False))
    rng = np.random.default_rng(3)
    x = tr.initial_point(starts.interpolation(p))
    x = x * (1.0 + 0.01 * rng.standard_normal(x.size))
    _compare_with_ad(tr.nlp, x, rng.standard_normal(tr.nlp.ng))


def test_relaxed_impulsive_blocks_equal_ad():
    """The relaxed NLP's blocks (dynamics without controls, the impulse costs, the orbit rows)."""
    from se3ocp.transcription.methods.impulsive.relaxed import relaxed_blocks

    p = problem("e2", 10)
    N, h = p.N, p.h
    lay = NLPLayout(N, [], True)
    rng = np.random.default_rng(5)
    sX = np.concatenate([np.full(3, 2.0), np.full(3, 6.0), np.ones(9), np.full(3, 0.01)])
    sC, sG = np.full(3, 0.05), np.full(3, h * 0.01)
    initial, terminal, _, _ = relaxed_blocks(p, sX, 6.0)
    iV = np.vstack([lay.iX[:, :-1], lay.iC, lay.iX[:, 1:]])
    n = StructuredNLP(lay.n, [Block("dynamics", blocks.dynamics(p.disc, True, False, False), iV,
                                    blocks.dynamics_data(p.disc, h, sX, sC, None, sG)),
                              Block("initial", initial, lay.iX[:, 0], np.zeros(0)),
                              Block("terminal", terminal, lay.iX[:, -1], np.zeros(0))])
    x = 1.0 + 0.1 * rng.standard_normal(lay.n)
    _compare_with_ad(n, x, rng.standard_normal(n.ng))


def test_dynamics_rows_vanish_on_a_rollout():
    """The NLP's dynamics rows are the discrete equations: zero (to 1e-13) on the scheme's own rollout."""
    p = problem("e3", 30, "lgvi")
    tr = SmoothTranscription(p, DirectOptions(jit=False))
    x = tr.initial_point(starts.rollout(p))
    g = np.array(ca.Function("g", [tr.nlp.w], [tr.nlp.g])(x)).ravel()
    assert np.abs(g[tr.nlp.rows("dynamics").ravel()]).max() <= 1e-13
    assert np.abs(g[tr.nlp.rows("terminal").ravel()]).max() > 0.1      # the rollout misses the target


def test_assemble_sums_duplicates_and_keeps_order():
    vals = ca.MX.sym("v", 4)
    M = assemble(3, 2, [0, 2, 0, 1], [1, 0, 1, 1], vals)
    out = _dense(ca.Function("M", [vals], [M])([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_array_equal(out, [[0, 4], [0, 4], [2, 0]])


def _rows_block(name: str, nr: int, M: int) -> Block:
    """A block of nr rows v[0] * (1..nr) per instance over M variables (one per instance)."""
    v, p = ca.SX.sym("v", 1), ca.SX.sym("p", 0)
    fn = ca.Function(f"rows_{nr}", [v, p], [ca.SX(0), v * ca.DM(np.arange(1.0, nr + 1))], ["v", "p"], ["cost", "rows"])
    return Block(name, fn, np.arange(M)[None, :], np.zeros(0))


def test_shared_rows_copy_the_blocks_two_nlps_share_and_zero_the_rest():
    """StructuredNLP.shared_rows: per-row values of one NLP (by its key) on another's rows -- a block with the same
    name, rows and instances copied row for row, a block of another shape or absent there 0; exact (a copy)."""
    M = 4
    theirs = StructuredNLP(M, [_rows_block("dynamics", 3, M), _rows_block("fuel", 12, M), _rows_block("path", 2, M),
                               _rows_block("terminal", 5, 1)])
    mine = StructuredNLP(M, [_rows_block("dynamics", 3, M), _rows_block("fuel", 2, M), _rows_block("extra", 1, M),
                             _rows_block("terminal", 5, 1)])
    values = np.arange(1.0, theirs.ng + 1)
    out = mine.shared_rows(theirs.key, values)
    assert out.shape == (mine.ng,)
    for name in ("dynamics", "terminal"):
        np.testing.assert_array_equal(out[mine.rows(name)], values[theirs.rows(name)])
    for name in ("fuel", "extra"):
        assert not out[mine.rows(name)].any()
    np.testing.assert_array_equal(mine.shared_rows(mine.key, np.arange(mine.ng)), np.arange(mine.ng))


def test_block_shapes_are_checked():
    fn = blocks.state_target(problem("e3", 10).disc, ("position",)).function
    with pytest.raises(ValueError, match="do not match"):
        Block("bad", fn, np.zeros((17, 1), dtype=int), np.zeros(2 * 18 + 3))


# ---------------------------------------------------------------- where the time goes
@pytest.mark.parametrize("solver", ["ipopt", "fatrop"])
def test_solve_time_split_accounts_for_the_solve(solver):
    """stats['evaluations_s'] + stats['solver_internal_s'] = solve_s, split over the NLP Functions."""
    s = se3ocp.solve(maneuver("e3", 20, "first_order"), solver=solver)
    assert s.converged and s.solver == solver
    by = s.stats["evaluations_by_function"]
    assert by and all(v >= 0.0 for v in by.values())
    assert s.stats["evaluations_s"] == pytest.approx(sum(by.values()), rel=1e-12)
    assert 0.0 < s.stats["evaluations_s"] <= s.solve_s
    assert s.stats["evaluations_s"] + s.stats["solver_internal_s"] == pytest.approx(s.solve_s, rel=1e-9)
    if solver == "ipopt":
        assert by["nlp_hess_l"] > 0.0 and by["nlp_jac_g"] > 0.0
    else:
        assert 0.0 < s.stats["fatrop_own_s"] <= s.stats["solver_internal_s"]


def test_solve_time_split_without_stats():
    """A failed solver call (no stats) gives zeros, never a negative solver share."""
    assert solve_time_split({}, 0.5) == {"evaluations_s": 0.0, "solver_internal_s": 0.5, "evaluations_by_function": {}}
    assert solve_time_split({"t_wall_nlp_f": 2.0}, 1.0)["solver_internal_s"] == 0.0


def test_blocks_and_their_derivatives_are_built_once_per_discretization():
    """A block built for a Discretization is kept on it, with its derivatives: the same objects on a second
    call; another Discretization of the same model and scheme builds its own."""
    disc = problem("e3", 10, "first_order").disc
    fn = blocks.dynamics(disc, True, True, True)
    assert blocks.dynamics(disc, True, True, True) is fn and fn.derivatives(False) is fn.derivatives(False)
    assert blocks.state_target(disc, ("position",)) is blocks.state_target(disc, ("position",))
    other = Discretization(disc.model, disc.scheme)
    assert blocks.dynamics(other, True, True, True) is not fn
