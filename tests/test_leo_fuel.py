"""The LEO fuel raises (configs/leo_body_engine.yaml, leo_raise_slew.yaml with control.objective=fuel; issue 27):
what the fuel plan does differently for maneuvers in physical units (docs/mathematics.md, "LEO fuel raises").

1. The smoothing references of the homotopy (:func:`~transcription.methods.direct.homotopy.smoothing_reference`):
   a bounded part keeps its bound, an unbounded part takes the effort optimum's largest magnitude (the LEO moments
   are ~1e-9 kN km against a scale of 1.5e-11).
2. The coarse grids of a fuel problem without a force bound (:func:`~transcription.methods.direct.plan.
   coarse_resolves`): used only when their free motion ends near the fine grid's compared with the displacement the
   maneuver needs (leo_raise_slew on 100 steps: a gap of 53 km against 47 km: not resolved).
"""
from __future__ import annotations

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.methods.direct import homotopy
from se3ocp.transcription.methods.direct.plan import coarse_resolves
from se3ocp.transcription.methods.direct.transcription import SmoothTranscription
from se3ocp.transcription.problem import quadrature_weights
from support import problem

FUEL = "control.objective=fuel"


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
    r = homotopy.smoothing_reference(tr.problem, U)
    assert r[0] == (tr.slack_scales[0] if bounded_force else pytest.approx(7.2e-4, rel=1e-15))
    assert r[1] == pytest.approx(8.3e-9, rel=1e-15) and tr.slack_scales[1] < 1e-10
    if bounded_force:
        assert r[0] == 1e-3
    U[3:] = 0.0
    assert homotopy.smoothing_reference(tr.problem, U)[1] == tr.slack_scales[1]


def test_the_references_of_bounded_parts_are_unchanged():
    """The fuel raise (configs/orbit_raise_fuel.yaml: force and moment norm bounds 40 and 1): the references are the
    bounds whatever the controls, as before the references existed."""
    p = problem("orbit_raise_fuel", 10)
    tr = SmoothTranscription(p, se3ocp.DirectOptions(jit=False))
    r = homotopy.smoothing_reference(tr.problem, _controls(p.disc.n_controls(p.N), 13.0, 0.2))
    assert np.array_equal(r, tr.slack_scales) and np.array_equal(r, [40.0, 1.0])


def test_the_smoothed_cost_uses_the_given_references():
    """The control-node block's cost at eps = 0.3 with references r = (7e-4, 5e-9) (not the slack scales): sum_j
    omega_j (w_f phi(s_f) + w_m phi(s_m)), phi(s) = (1 - eps) s + eps s^2 / (2 r), to 1e-13 relative; at eps = 0 the
    same NLP point gives the fuel cost whatever r."""
    p = problem("leo_raise_slew", 10, None, FUEL)
    U = _controls(p.disc.n_controls(p.N), 6e-4, 2e-10)
    om = quadrature_weights(p.scheme, p.N, p.h)
    s = np.linalg.norm(U[:3], axis=0), np.linalg.norm(U[3:], axis=0)
    ref = np.array([7e-4, 5e-9])
    for eps in (0.0, 0.3):
        tr = SmoothTranscription(p, se3ocp.DirectOptions(jit=False), smoothing=eps, smoothing_ref=ref)
        X = np.repeat(p.X0[None, :], p.N + 1, axis=0)
        w = tr.layout.pack(X.T, U, np.zeros((3, p.N))) / tr.w_scale
        w[tr.layout.iS[:2]] = np.vstack(s) / tr.slack_scales[:, None]      # the magnitudes s = |u| of the optimum
        blk = next(b for b in tr.nlp.blocks if b.name == "controls")
        cost = float(np.sum(np.array(blk.fn.map(blk.M)(w[blk.idx], blk.data)[0]))) * tr.scales.objective
        phi = [(1 - eps) * si + eps * si**2 / (2 * r) for si, r in zip(s, ref)]
        want = float(om @ (p.control.W_f[0, 0] * phi[0] + p.control.W_m[0, 0] * phi[1]))
        assert cost == pytest.approx(want, rel=1e-13)


def test_a_coarse_grid_without_a_force_bound_must_be_the_same_maneuver():
    """leo_raise_slew (no bound) on 400 steps: the 100-step free motion ends 53 km from the 400-step one, the
    maneuver needs 47 km (the 400-step free motion's miss): not resolved, so its fuel plan runs on 400 steps (before:
    always resolved without a bound, and its 25-step problem needed 20 kN of thrust).  The fuel raise's coarse grids
    still resolve (bounded: gap 0.0044 against a reach of 9.8), and so does an unbounded fuel raise (its force bound
    lifted: gap 0.0044 against a miss of 1.4)."""
    assert not coarse_resolves(problem("leo_raise_slew", 400, None, FUEL), 100)
    assert coarse_resolves(problem("orbit_raise_fuel", 400), 100)
    assert coarse_resolves(problem("orbit_raise_fuel", 400, None, "control.bounds={moment: {norm: 1.0}}"), 100)
