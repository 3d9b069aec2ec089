"""The LEO fuel raises (configs/leo_body_engine.yaml, leo_raise_slew.yaml with control.objective=fuel; issue 27):
what the fuel plan does differently for maneuvers in physical units (docs/mathematics.md, "LEO fuel raises").

1. The smoothing references of the homotopy (:func:`~transcription.objectives.fuel.homotopy.smoothing_reference`):
   a bounded part keeps its bound, an unbounded part takes the effort optimum's largest magnitude (the LEO moments
   are ~1e-9 kN km against a scale of 1.5e-11).
2. The coarse grids of a fuel problem without a force bound (:func:`~transcription.objectives.fuel.plan.
   coarse_resolves`): used only when their free motion ends near the fine grid's compared with the displacement the
   maneuver needs (leo_raise_slew on 100 steps: a gap of 53 km against 47 km: not resolved).
3. The bundled LEO fuel raise with reaction wheels (configs/leo_engine_fuel.yaml): the homotopy's effort problem
   weighted as its first level (:meth:`~transcription.objectives.fuel.homotopy.Homotopy.effort_problem`); its solve,
   counted on the actuators' channels, is tests/test_channel_fuel.py's.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.nlp.transcription import SmoothTranscription
from se3ocp.transcription.objectives import Effort, Fuel
from se3ocp.transcription.objectives.fuel.homotopy import Homotopy, smoothing_reference
from se3ocp.transcription.objectives.fuel.plan import FuelStrategy, coarse_resolves
from se3ocp.transcription.ocp import BoxBound, quadrature_weights
from se3ocp.transcription.ocp.estimate import control_sizes
from support import maneuver, problem

FUEL = "control.objective=fuel"
#: the fuel strategy's coarse-grid reach (its default)
REACH = FuelStrategy().coarse_reach


def _controls(n: int, force: float, moment: float) -> np.ndarray:
    """Controls (6, n) whose force and moment norms rise linearly to ``force`` and ``moment`` (physical units)."""
    ramp = np.linspace(0.0, 1.0, n)
    U = np.zeros((6, n))
    U[0], U[1], U[3], U[5] = 0.6 * force * ramp, 0.8 * force * ramp, 0.8 * moment * ramp, -0.6 * moment * ramp
    return U


@pytest.mark.parametrize("name, bounded_force", [("leo_body_engine", True), ("leo_raise_slew", False)])
def test_the_smoothing_reference_is_the_bound_or_the_effort_magnitude(name, bounded_force):
    """r_f is the engine's maximum (1 N = 1e-3 kN, the slack scale) when the force is bounded, else the largest
    force magnitude of the given controls (to 1e-15); r_m (no moment bound in either file) the largest moment
    magnitude; a part that vanishes keeps its slack scale."""
    p = problem(name, 10, None, FUEL)
    tr = SmoothTranscription(p, se3ocp.DirectOptions(jit=False))
    U = _controls(p.disc.n_controls(p.N), 7.2e-4, 8.3e-9)
    r = smoothing_reference(tr.problem, U)
    assert r[0] == (tr.magnitudes[0] if bounded_force else pytest.approx(7.2e-4, rel=1e-15))
    assert r[1] == pytest.approx(8.3e-9, rel=1e-15) and tr.magnitudes[1] < 1e-10
    if bounded_force:
        assert r[0] == 1e-3
    U[3:] = 0.0
    assert smoothing_reference(tr.problem, U)[1] == tr.magnitudes[1]


def test_the_references_of_bounded_parts_are_unchanged():
    """The fuel raise (configs/orbit_raise_fuel.yaml: force and moment norm bounds 40 and 1): the references are the
    bounds whatever the controls, as before the references existed."""
    p = problem("orbit_raise_fuel", 10)
    tr = SmoothTranscription(p, se3ocp.DirectOptions(jit=False))
    r = smoothing_reference(tr.problem, _controls(p.disc.n_controls(p.N), 13.0, 0.2))
    assert np.array_equal(r, tr.magnitudes) and np.array_equal(r, [40.0, 1.0])


def test_the_smoothed_cost_uses_the_given_references():
    """The fuel block's cost at eps = 0.3 with references r = (7e-4, 5e-9) (not the slack scales): sum_j
    omega_j (w_f phi(s_f) + w_m phi(s_m)), phi(s) = (1 - eps) s + eps s^2 / (2 r), to 1e-13 relative; at eps = 0 the
    same NLP point gives the fuel cost whatever r."""
    p = problem("leo_raise_slew", 10, None, FUEL)
    U = _controls(p.disc.n_controls(p.N), 6e-4, 2e-10)
    om = quadrature_weights(p.scheme, p.N, p.h)
    s = np.linalg.norm(U[:3], axis=0), np.linalg.norm(U[3:], axis=0)
    ref = np.array([7e-4, 5e-9])
    for eps in (0.0, 0.3):
        level = p.replace(control=replace(p.control, objective=Fuel().smoothed(eps, ref)))
        tr = SmoothTranscription(level, se3ocp.DirectOptions(jit=False))
        X = np.repeat(p.X0[None, :], p.N + 1, axis=0)
        w = tr.layout.pack(X.T, U, np.zeros((3, p.N)), tr.objective.slack_values(tr, U)) / tr.w_scale
        assert np.allclose(w[tr.layout.iS[:2]] * tr.magnitudes[:, None], np.vstack(s), rtol=1e-15, atol=0.0)
        blk = next(b for b in tr.nlp.blocks if b.name == "fuel")
        cost = float(np.sum(np.array(blk.fn.map(blk.M)(w[blk.idx], blk.data)[0]))) * tr.scales.objective
        phi = [(1 - eps) * si + eps * si**2 / (2 * r) for si, r in zip(s, ref)]
        want = float(om @ (p.control.W_f[0, 0] * phi[0] + p.control.W_m[0, 0] * phi[1]))
        assert cost == pytest.approx(want, rel=1e-13)


def test_a_coarse_grid_without_a_force_bound_must_be_the_same_maneuver():
    """leo_raise_slew (no bound) on 400 steps of the LGVI: the 100-step free motion ends 53 km from the 400-step one,
    the maneuver needs 47 km (the 400-step free motion's miss): not resolved, so its fuel plan runs on 400 steps
    (before: always resolved without a bound, and its 25-step problem needed 20 kN of thrust).  On its own scheme,
    lgvi_kepler, the orbit is flown exactly on either grid: resolved.  The fuel raise's coarse grids still resolve
    (bounded: gap 0.0044 against a reach of 9.8), and so does an unbounded fuel raise (its force bound lifted: gap
    0.0044 against a miss of 1.4)."""
    assert not coarse_resolves(problem("leo_raise_slew", 400, "lgvi", FUEL), 100, REACH)
    assert coarse_resolves(problem("leo_raise_slew", 400, None, FUEL), 100, REACH)
    assert coarse_resolves(problem("orbit_raise_fuel", 400), 100, REACH)
    assert coarse_resolves(problem("orbit_raise_fuel", 400, None, "control.bounds={moment: {norm: 1.0}}"), 100, REACH)


# ------------------------------------------------------------------- the bundled LEO fuel raise (leo_engine_fuel)
def test_the_leo_fuel_raise_is_the_engine_raise_with_wheels():
    """configs/leo_engine_fuel.yaml is configs/leo_body_engine.yaml's spacecraft and maneuver (every resolved key
    but the name and the control equal), with the fuel objective, the same engine (body +x, 0 <= T <= 1e-3 kN), three
    reaction wheels on the body axes, |u_m,i| <= 1e-8 kN km (0.01 N m), and the weights w_f = 1, w_m = 1e5 /km (the
    solve: tests/test_channel_fuel.py)."""
    fuel, effort = maneuver("leo_engine_fuel"), maneuver("leo_body_engine")
    assert {k for k in fuel.resolved if fuel.resolved[k] != effort.resolved[k]} == {"name", "control"}
    c = fuel.problem.control
    assert isinstance(c.objective, Fuel)
    assert fuel.resolved["control"]["bounds"]["force"] == effort.resolved["control"]["bounds"]["force"]
    assert isinstance(c.moment_bound, BoxBound) and np.array_equal(c.moment_bound.b, np.full(3, 1e-8))
    assert c.W_f[0, 0] == 1.0 and c.W_m[0, 0] == 1e5 and fuel.problem.N == 400


def test_the_homotopys_effort_problem_is_its_first_level():
    """Homotopy.effort_problem: with every counted part bounded its weights are w_i / r_i (r_i the bounds), the
    first level's phi_1(s) = s^2 / (2 r), where the bounds differ by more than effort_level_ratio -- leo_engine_fuel:
    1e3 and 1e13 (the moment's weight 1e10 times the force's, as in leo_body_engine's effort problem) -- and the
    file's weights otherwise (the fuel raise, bounds 40 and 1).  With an unbounded counted part and a central body,
    the effort in the actuators' terms, I / s_i^2 (control_sizes: leo_body_engine's engine 1e-3 kN and its torque
    4 pi lambda_max(J) n^2 = 7.238e-9 kN km; leo/raise_engine's 3e-3 and 1.078e-8), whatever the fuel weights
    (1 and 1e10; 1 / 3e-3 and 1 / 1.078e-8)."""
    for name, sets, want in (("leo_engine_fuel", (), (1e3, 1e13)), ("orbit_raise_fuel", (), (1.0, 1.0))):
        e = Homotopy(None).effort_problem(problem(name, 10, None, *sets)).control
        assert isinstance(e.objective, Effort)
        assert np.allclose(e.W_f, want[0] * np.eye(3), rtol=1e-15, atol=0.0)
        assert np.allclose(e.W_m, want[1] * np.eye(3), rtol=1e-15, atol=0.0)
    for p in (problem("leo_body_engine", 10, None, FUEL), se3ocp.load("configs/leo/raise_engine.yaml", [FUEL]).problem):
        F, M = control_sizes(p)
        e = Homotopy(None).effort_problem(p).control
        assert isinstance(e.objective, Effort)
        assert np.allclose(e.W_f, np.eye(3) / F**2, rtol=1e-15, atol=0.0)
        assert np.allclose(e.W_m, np.eye(3) / M**2, rtol=1e-15, atol=0.0)
    assert control_sizes(problem("leo_body_engine", 10, None, FUEL))[1] == pytest.approx(7.238e-9, rel=1e-3)


@dataclass(frozen=True)
class _CutLevel:
    """A Context whose homotopy level eps = 0.1 gets 5 iterations (the rest of its solves as the Context's)."""

    ctx: object

    def solve(self, problem, start, label, ipopt=None, **options):
        return self.ctx.solve(problem, start, label, ipopt, **({**options, "max_iter": 5} if label == "eps 1e-01"
                                                                else options))

    def under(self, phase):
        return _CutLevel(self.ctx.under(phase))

    def using(self, **options):
        return _CutLevel(self.ctx.using(**options))

    @property
    def options(self):
        return self.ctx.options

    @property
    def method(self):
        return self.ctx.method


def test_a_level_at_its_budget_starts_the_structured_finish():
    """Homotopy.structure_from_budget: the fuel raise on 25 steps by the levels (jump=False) with the level eps = 0.1
    cut to 5 iterations: the homotopy ends there, and its point starts the structured finish.  That point is far from
    sparse (every node burns), and the finish's rough solve does not converge (500 iterations, as from the effort
    optimum, docs §24); the epigraph NLP from the same point, within the homotopy's level_budget, reaches the levels'
    own optimum (to 1e-8; measured 0.812941492) with the guard passed.  With structure_from_budget=False the homotopy
    gives no start.  (configs/leo_engine_fuel.yaml, where the level's point is near bang-off-bang, takes the finish
    itself: test_the_bundled_leo_fuel_raise_converges_bang_off_bang.)"""
    from se3ocp.transcription.methods.direct import Direct
    from se3ocp.transcription.strategy.core import Context

    p, ctx = problem("orbit_raise_fuel", 25), Context(Direct(se3ocp.DirectOptions()))

    def run(ctx, **fields):
        fuel = FuelStrategy(homotopy=Homotopy(None, jump=False, **fields))
        return replace(fuel.guard, inner=fuel.homotopy_start()).run(p, None, ctx)

    full, cut = run(ctx), run(_CutLevel(ctx))
    said = cut.stats["homotopy_levels"]
    assert "eps = 1e-01: 5, Maximum_Iterations_Exceeded: its point starts the structured finish" in said, said
    assert cut.converged and cut.stats["fuel_guard"] == "passed", cut.message
    structure = cut.stats["fuel_structure"]
    assert structure[0].startswith("solve 1: burn nodes force 26, moment 26 of 26; rough"), structure
    assert structure[-1] == "not kept: the fuel NLP finished from the same start"
    assert cut.trace[-1].iterations <= Homotopy(None).level_budget
    assert full.converged and cut.cost == pytest.approx(full.cost, rel=1e-8), (cut.cost, full.cost)
    none = run(_CutLevel(ctx), structure_from_budget=False)
    assert not none.converged and "not available" in none.trace[0].note, none.message
