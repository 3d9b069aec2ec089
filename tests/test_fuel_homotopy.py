"""The fuel objective by homotopy and its multistart (transcription/objectives/fuel/homotopy.py, issue 27).

On the coarsest grid the default plan of a fuel problem solves three starts: the homotopy (effort, then the
smoothed magnitude phi_eps(s) = (1 - eps) s + eps s^2 / (2 s_ref) down to eps = 1e-4, then the fuel NLP itself),
the free motion and the screw interpolation.  The fuel raise (configs/orbit_raise_fuel.yaml) on 25 steps: the
homotopy ends at the free motion's optimum or a lower one, the interpolation at a higher one.
"""
from __future__ import annotations

from dataclasses import replace as dc_replace

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.objectives.fuel.homotopy import Homotopy
from se3ocp.transcription.objectives.fuel.plan import FuelStrategy
from se3ocp.transcription.solve import solve_direct
from se3ocp.transcription.strategy.core import BestOf, CoarseToFine, FirstOf
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from se3ocp.transcription.ocp import fuel_cost, quadrature_weights
from support import maneuver, problem

N = 25


@pytest.fixture(scope="module")
def raise25():
    p = problem("orbit_raise_fuel", N)
    return p, solve_direct(p, se3ocp.DirectOptions())


def test_smoothing_levels_decrease_geometrically_to_the_last():
    h = Homotopy(None)
    eps = h.levels()
    assert eps[0] == h.first and eps[-1] == pytest.approx(h.last, rel=1e-12)
    assert np.allclose(np.array(eps[:-1]) / np.array(eps[1:]), h.factor, rtol=1e-12)
    other = Homotopy(None, first=0.5, factor=5.0, last=0.5 / 125)
    assert other.levels() == pytest.approx([0.5, 0.1, 0.02, 0.004], rel=1e-12)


def test_the_smoothed_cost_is_the_fuel_cost_at_eps_0_and_the_l2_form_at_eps():
    """The fuel block's cost at a point of the fuel raise: at eps = 0 the fuel objective (sum_j omega_j
    (w_f |u_f| + w_m |u_m|)) to round-off; at eps = 0.3 (1 - eps) s + eps s^2 / (2 s_ref) with the magnitude
    scales as s_ref, summed by the same weights."""
    p = problem("orbit_raise_fuel", 10)
    rng = np.random.default_rng(0)
    U = rng.normal(size=(6, 11)) * np.r_[np.full(3, 20.0), np.full(3, 0.5)][:, None]
    om = quadrature_weights(p.scheme, p.N, p.h)
    s = np.linalg.norm(U[:3], axis=0), np.linalg.norm(U[3:], axis=0)
    ref = SmoothTranscription.magnitude_scales(p)
    for eps in (0.0, 0.3):
        smoothed = p.replace(control=dc_replace(p.control, objective=p.control.objective.smoothed(eps, ref)))
        tr = SmoothTranscription(smoothed, se3ocp.DirectOptions(jit=False))
        X = np.repeat(p.X0[None, :], p.N + 1, axis=0)
        w = tr.layout.pack(X.T, U, np.zeros((3, p.N)), tr.objective.slack_values(tr, U)) / tr.w_scale
        blk = next(b for b in tr.nlp.blocks if b.name == "fuel")
        V = w[blk.idx]
        cost = float(np.sum(np.array(blk.fn.map(blk.M)(V, blk.data)[0]))) * tr.scales.objective
        phi = [(1 - eps) * si + eps * si**2 / (2 * r) for si, r in zip(s, ref)]
        want = float(om @ (p.control.W_f[0, 0] * phi[0] + p.control.W_m[0, 0] * phi[1]))
        assert cost == pytest.approx(want, rel=1e-13)
        if eps == 0.0:
            assert cost == pytest.approx(fuel_cost(U, p.control, om), rel=1e-13)


def test_the_homotopy_reaches_the_optimum_of_the_fuel_nlp(raise25):
    """The homotopy's last stage is the fuel NLP itself: its cost is the fuel cost of its controls (recomputed here
    with the quadrature weights, to 1e-12), not the smoothed one; it is no worse than today's start (the free
    motion, today's formulation) to 1e-8 -- on 25 steps the two ended at the same optimum or the homotopy's was
    lower (0.812941 against 0.813134), which of the two depends on the last bits of the coarse solves; the lowest
    start is kept."""
    p, sol = raise25
    hom, roll = sol.trace[0], sol.trace[1]
    assert hom.label == "the fuel homotopy from the effort optimum" and roll.label == "rollout"
    assert hom.result.successful and roll.result.successful
    assert hom.cost <= roll.cost * (1 + 1e-8)
    assert sol.cost == pytest.approx(min(a.cost for a in sol.trace), rel=1e-14)
    if sol.stats["initial_guess"] == hom.label:
        om = quadrature_weights(p.scheme, p.N, p.h)
        assert sol.cost == pytest.approx(fuel_cost(sol.controls, p.control, om), rel=1e-12)
        said = sol.stats.get("homotopy_levels", "")     # the jump to the fuel NLP, or the levels down to 1e-4
        assert "the fuel NLP from the effort optimum" in said or "eps = 1e-04" in said, said


@pytest.mark.slow
def test_bang_off_bang_at_the_end():
    """On 100 steps (the 25-step multistart resampled and finished): the thrust is near 0 or near its bound
    (within 1e-3 of the bound) at >= 95 % of the nodes (on 25 steps 3 of the 26 nodes are switching nodes)."""
    p = problem("orbit_raise_fuel", 100)
    sol = solve_direct(p, se3ocp.DirectOptions())
    assert sol.stats["multistart_grid"] == N and sol.trace[0].label == f"the best start on {N} steps, resampled"
    b = p.control.force_bound.b
    thrust = np.linalg.norm(sol.u_f, axis=1)
    assert sol.converged and thrust.max() <= b * (1 + 1e-7)
    assert np.mean((thrust >= b * (1 - 1e-3)) | (thrust <= b * 1e-3)) >= 0.95


def test_the_multistart_spread_is_reported(raise25):
    """Three starts on 25 steps, at least two optima (the interpolation's is higher): the count of distinct ones
    (costs more than BestOf.same_optimum_rtol apart), the spread in the stats and the message, and the lowest kept;
    the costlier ones fail the fuel KKT guard (docs §22: measured, the interpolation's 0.816954 with sigma up to
    +1.3e-2 on coast nodes, and with another rounding of the coarse solves the free motion's 0.813134 too) and the
    sentence says they are false minima."""
    p, sol = raise25
    st = sol.stats
    rtol = BestOf(()).same_optimum_rtol
    costs = sorted(a.cost for a in sol.trace if a.result is not None and a.result.successful)
    assert st["multistart_starts"] == len(costs) == 3 and st["multistart_grid"] == N
    distinct = 1 + sum(b - a > rtol * abs(a) for a, b in zip(costs[:-1], costs[1:]))
    assert st["multistart_optima"] == distinct >= 2
    assert st["multistart_spread"] == pytest.approx((costs[-1] - costs[0]) / costs[0], rel=1e-12)
    assert "different optima" in sol.message and sol.cost == costs[0]
    # the costlier starts are false minima of the NLP (the fuel KKT guard, docs §22): named as such
    false = sorted(c for c in costs if c > costs[0] * (1 + rtol))
    assert st["multistart_false_minima"] == len(false) >= 1 and sol.stats["fuel_guard"] == "passed"
    assert f"of these, {len(false)} ({', '.join(f'{c:.6g}' for c in false)}) fail the fuel KKT guard" in sol.message


def _finish_on(p, coarse, warm_primal: bool):
    """The epigraph NLP's finish on ``p``'s grid from ``coarse`` (a solution on a coarser grid) resampled, with or
    without the structured finish's fallback options (a barrier of 1e-6, no push off the bounds): the structured
    finish's own fallback alone (tests/test_fuel_structure.py tests the finish).  Its Solution and iterations."""
    from se3ocp.transcription.methods.direct import Direct
    from se3ocp.transcription.objectives.fuel.structure import StructuredFinish
    from se3ocp.transcription.objectives.fuel.guard import Guarded

    start = coarse.warm.fit(p.N, p.scheme)[0].primal()
    ipopt = StructuredFinish(Guarded(None)).fallback if warm_primal else {}
    sol = Direct(se3ocp.DirectOptions(), ipopt).solve(p, start)
    return sol, sol.iterations


def test_fatrop_does_not_converge_on_the_fuel_nlp_even_from_its_optimum(raise25):
    """Why fatrop does not solve the fuel objective (fatrop.FUEL_NOT_COVERED; docs/mathematics.md §20): its
    stage-ordered fuel NLP (tests/test_fatrop_stage.py) started at IPOPT's own optimum on 25 steps, with
    WARM_PRIMAL's barrier and pushes, does not converge in 300 iterations: the coast nodes' indefinite (s, d)
    blocks get a Hessian regularization of 10-100 at every iteration and the dual infeasibility crawls near 1e-6
    (measured: status 1 after 129-493 iterations, 1.2e-7 to 2.7e-7 above IPOPT's cost).  If this fails, fatrop
    has learned to solve it: measure the 400-step finish and extend fatrop.covers."""
    from se3ocp.transcription.methods.direct.fatrop import solve_fatrop
    from se3ocp.transcription.objectives.fuel.guard import Guarded
    from se3ocp.transcription.objectives.fuel.structure import StructuredFinish

    p, sol = raise25
    assert sol.converged
    primal = StructuredFinish(Guarded(None)).fallback
    opts = se3ocp.DirectOptions(fatrop_expand=True, fatrop_options={"max_iter": 300, **{
        k: primal[k] for k in ("mu_init", "bound_push", "bound_frac")}})
    covered = p.replace(control=dc_replace(p.control, objective=_Covered()))     # fatrop's own NLP, not refused
    fsol = solve_fatrop(covered, opts, sol.warm, "fatrop")
    assert not fsol.converged and fsol.stats.get("solver_status") not in ("Solve_Succeeded",), fsol.message


@pytest.mark.slow
def test_the_raise_on_200_steps_is_an_extremal_of_the_indirect_method():
    """The fuel raise on 200 steps (25 -> 50 -> 200, each finish with WARM_PRIMAL) and the indirect method from it
    (its exact switching structure, docs/mathematics.md §19) agree: compare says agree, costs to 1e-7 relative
    (measured 1.1e-8, the direct method at its default tol).  The optimum is below the one the finish with IPOPT's
    defaults reached, 0.82195290 (measured 0.81883915): the cold finish wandered out of the coarse optimum's basin."""
    c = se3ocp.solve(maneuver("orbit_raise_fuel", 200), "both")
    assert c.direct.converged and c.indirect.converged, (c.direct.message, c.indirect.message)
    assert c.verdict.startswith("agree"), c.verdict
    assert abs(c.indirect.cost - c.direct.cost) <= 1e-7 * c.direct.cost
    assert c.indirect.stats["fuel_structured"]["consistent"]
    assert c.direct.cost <= 0.82195290


def test_a_coarse_grid_whose_orbit_the_force_cannot_reach_is_skipped():
    """The LEO body-engine raise with the fuel objective (configs/leo_body_engine.yaml on the LGVI, N = 400): the free
    motion on 100 steps ends 53 km from that on 400 steps, beyond half of what the 1 N engine moves 500 kg in T (31 km), so the
    strategy starts with the homotopy on the 400 steps themselves ('first'; its moment unbounded, the continuation
    where it applies); the fuel raise keeps its coarse grid (gap 0.0044 against a reach of 9.8).  A 10 N engine
    (reach 309 km) brings the coarse grid back, and so does the file's own scheme, lgvi_kepler, which flies the orbit
    exactly on either grid (there the continuation through channels is tried on the 400 steps before it, docs §25).
    Composing solves nothing."""
    from se3ocp.transcription.objectives.fuel.plan import coarse_resolves

    assert coarse_resolves(problem("leo_body_engine", 400, None, "control.objective=fuel"), 100,
                           FuelStrategy().coarse_reach)
    leo = problem("leo_body_engine", 400, "lgvi", "control.objective=fuel")
    plan = FuelStrategy().compose(leo, se3ocp.DirectOptions()).inner
    assert isinstance(plan, FirstOf) and [e.label for e in plan.strategies] == [
        "the fuel homotopy from the effort optimum (or its continuation from channels)", "rollout",
        "interpolate"]
    assert not plan.strategies[0].continued
    assert not coarse_resolves(leo, 100, FuelStrategy().coarse_reach)
    # on lgvi_kepler, where the coarse grid resolves, the continuation through channels runs on the 400 steps first
    kepler = problem("leo_body_engine", 400, None, "control.objective=fuel")
    first, grids = FuelStrategy().compose(kepler, se3ocp.DirectOptions()).inner.strategies
    assert first.continued and isinstance(grids.strategies[0], CoarseToFine)
    strong = problem("leo_body_engine", 400, "lgvi", "control.objective=fuel",
                     "control.bounds={force: {thruster: {axis: [1, 0, 0], max: 1.0e-2, min: 0.0}}}")
    assert coarse_resolves(strong, 100, FuelStrategy().coarse_reach)
    plan = FuelStrategy().compose(problem("orbit_raise_fuel", 400), se3ocp.DirectOptions()).inner
    assert isinstance(plan.strategies[0], CoarseToFine) and plan.strategies[0].grid(problem("orbit_raise_fuel", 400)) == 100


def _homotopy_solve(p, homotopy):
    """The fuel strategy's homotopy start alone on ``p``'s grid (no rollout, no interpolation), guarded as the
    strategy guards it."""
    from se3ocp.transcription.objectives.fuel.plan import FuelStart

    class Only(FuelStrategy):
        def _plan(self, problem):
            return FuelStart(self.homotopy_start(), self._continuation())

    sol = solve_direct(p, se3ocp.DirectOptions(), strategy=Only(homotopy=homotopy))
    assert sol.converged, sol.message
    return sol


def test_the_jump_ends_where_the_levels_end():
    """The homotopy's jump (the fuel NLP straight from the effort optimum, Homotopy.jump) against the smoothed
    levels (the path it replaces; taken here because a jump of 3 iterations does not converge): on the raise's 25
    steps both reach the same optimum, to 1e-10, which passes the fuel KKT guard and is the fuel cost of its
    controls; the jump takes fewer iterations (measured 77 against 350 with the effort problem from the free
    motion, 21 + 3 + 321 + 5 of them), and ``homotopy_levels`` says which path was taken (costs 0.8129414920420919
    and 0.8129414920420461).  Also against the strategy's other start: the free motion ends at the same cost (or
    escapes a false minimum to it, docs §22, 0.8129414920)."""
    p = problem("orbit_raise_fuel", N)
    jump = _homotopy_solve(p, Homotopy(None))
    said = jump.stats["homotopy_levels"]
    assert "the fuel NLP from the effort optimum: " in said and "so the levels" not in said and "eps =" not in said
    assert jump.stats["fuel_guard"] == "passed"
    levels = _homotopy_solve(p, Homotopy(None, jump_budget=3))
    said = levels.stats["homotopy_levels"]
    assert "the fuel NLP from the effort optimum: 3, Maximum_Iterations_Exceeded, so the levels" in said, said
    assert "eps = 1e+00" in said and "eps = 1e-04" in said
    assert jump.cost == pytest.approx(levels.cost, rel=1e-10) and levels.stats["fuel_guard"] == "passed"
    assert jump.iterations < levels.iterations
    above = _homotopy_solve(p, Homotopy(None, jump_max_n=N - 1))  # a grid above jump_max_n: the levels, no jump
    said = above.stats["homotopy_levels"]
    assert "the fuel NLP from the effort optimum" not in said and "eps = 1e-04" in said, said
    assert above.cost == pytest.approx(levels.cost, rel=1e-10) and above.iterations == levels.iterations - 3
    om = quadrature_weights(p.scheme, p.N, p.h)
    assert jump.cost == pytest.approx(fuel_cost(jump.controls, p.control, om), rel=1e-12)
    roll = solve_direct(p, se3ocp.DirectOptions(initial_guess="rollout"))
    assert roll.converged and roll.stats["fuel_guard"] == "passed"
    assert roll.cost == pytest.approx(jump.cost, rel=1e-9), (roll.cost, jump.cost)


def test_the_effort_optimum_from_the_free_motion_is_the_effort_plans():
    """Homotopy.effort: the raise's effort problem (a force and a moment bound, so its strategy starts from the
    relaxed problem) from the free motion reaches the optimum the effort strategy reaches (to 1e-10; measured 21
    iterations against 92, the relaxed problem ending at another local minimum, 1.376); with a budget the free
    motion cannot meet, the strategy's; and a body-fixed engine (issue 24: the aimed relaxed start) goes to the
    strategy directly."""
    from se3ocp.transcription.methods.direct import Direct
    from se3ocp.transcription.strategy.core import Context

    p = problem("orbit_raise_fuel", N)
    effort = p.replace(control=dc_replace(p.control, objective=se3ocp.Effort()))
    ctx = Context(Direct(se3ocp.DirectOptions()))
    planned = solve_direct(effort, se3ocp.DirectOptions())
    assert planned.converged and planned.trace[0].label == "the solution without bounds and path constraints"
    sol, said = Homotopy(None).effort(effort, ctx)
    assert said.endswith("(from the free motion)") and sol.iterations < planned.iterations
    assert sol.cost == pytest.approx(planned.cost, rel=1e-10)
    sol, said = Homotopy(None, effort_rollout_budget=2).effort(effort, ctx)
    assert [a.label for a in sol.trace][0] == "rollout" and said.endswith("by the effort plan"), said
    assert said.startswith("2 from the free motion") and sol.iterations == planned.iterations + 2, said
    assert sol.cost == pytest.approx(planned.cost, rel=1e-10)
    from test_body_force import ENGINE_SLEW

    engine = problem("slew_keep_out", None, None, *ENGINE_SLEW[:-1], "horizon.N=6")
    assert engine.control.objective == se3ocp.Effort()
    sol, said = Homotopy(None).effort(engine, ctx)
    assert sol.trace[0].label != "rollout" and said == str(sol.iterations)
    sol, said = Homotopy(None, effort_rollout=False).effort(effort, ctx)    # switched off: the effort strategy
    assert said == str(planned.iterations) and sol.cost == planned.cost


class _Covered(se3ocp.Fuel):
    """The fuel objective whose NLP fatrop is given (not refused): fatrop's own attempt at it."""

    fatrop = ""
