"""One engine fixed in the body on a LEO orbit in km, s, kg: the relaxation that starts its solve, the default
weights in the actuators' terms, and a maneuver written with them (configs/leo/phasing_engine.yaml) flown by the
test's own integrator."""
from __future__ import annotations

import numpy as np
import pytest

from se3ocp.problems.api import load, solve
from se3ocp.transcription.nlp.scaling import characteristic_scales
from se3ocp.transcription.objectives.effort import relaxation

from test_kepler import fly_plan

PHASING = "configs/leo/phasing_engine.yaml"


def test_an_engines_relaxation_frees_the_thrust_in_the_inertial_frame_at_the_engines_scale():
    """leo_body_engine's relaxed problem: no bounds, the force inertial (the translation apart from the attitude), and
    its force scale the engine's 1 N (1e-3 kN), not the orbit's m L / T^2 (0.6 kN); the moment's scale unchanged."""
    p = load("configs/leo_body_engine.yaml").problem
    r = relaxation(p)
    assert r.control.force_bound is None and r.disc.force_frame == "inertial" and p.disc.force_frame == "body"
    free = characteristic_scales(r.replace(control_scales=None)).U
    sU = characteristic_scales(r).U
    assert free[0] > 100 * 1e-3
    assert sU[0] == pytest.approx(1e-3, rel=1e-12)
    assert sU[3] == pytest.approx(characteristic_scales(p).U[3], rel=1e-12)


def test_a_file_without_weights_measures_each_control_in_its_size():
    """configs/leo/phasing_engine.yaml gives no weights: W_f = I / F^2 (F the engine's 1e-3 kN), W_m = I / M^2 with
    M = 4 pi lambda_max(J) n^2 (half a turn rest to rest in 1/n); the fuel objective's are I / F, I / M (and a moment
    bound is M); weights given in the file, or a file without a force bound, keep theirs."""
    man = load(PHASING)
    c, p = man.problem.control, man.problem
    n2 = p.model.mu / np.linalg.norm(man.problem.X0[0:3]) ** 3
    M = 4 * np.pi * 1.8e-4 * n2
    assert np.allclose(c.W_f, np.eye(3) / 1e-3**2, rtol=1e-12, atol=0)
    assert np.allclose(c.W_m, np.eye(3) / M**2, rtol=1e-12, atol=0)
    assert man.resolved["control"]["weights"] == {"force": pytest.approx(1e6, rel=1e-12),
                                                  "moment": pytest.approx(1 / M**2, rel=1e-12)}
    fuel = load(PHASING, ["control.objective=fuel", "control.bounds.moment.norm=2e-8"]).problem.control
    assert fuel.W_f[0, 0] == pytest.approx(1e3, rel=1e-12) and fuel.W_m[0, 0] == pytest.approx(5e7, rel=1e-12)
    given = load(PHASING, ["control.weights.force=2.0"]).problem.control
    assert given.W_f[0, 0] == 2.0 and given.W_m[0, 0] == 1e4
    assert load("configs/leo_raise_slew.yaml").problem.control.W_m[0, 0] == 1e13      # the file's own


@pytest.mark.slow
def test_the_phasing_written_with_default_weights_converges_and_flies_within_one_percent():
    """configs/leo/phasing_engine.yaml by default (0.5 deg ahead in two orbits with a 1 N forward-only engine):
    converged; flown by the test's own DOP853 it ends within 1 % of the maneuver (the check's change: 60.6 km, 6.68 m/s
    of delta-v), and the check's fraction agrees with that flight to 10 % (measured: 24 m, 0.018 m/s, 0.27 %)."""
    man = load(PHASING)
    sol = solve(man)
    assert sol.converged, sol.message
    x, v, _ = fly_plan(sol)
    Xd = man.problem.terminal.X
    dx, dv = np.linalg.norm(x - Xd[0:3]), np.linalg.norm(v - Xd[3:6] / man.problem.model.mass)
    c = sol.continuous
    frac = max(dx / c.change_position, dv / c.change_velocity)
    print(dx, dv, c.change_position, c.change_velocity, frac, c.maneuver_fraction)
    assert frac <= 0.01
    assert c.maneuver_fraction == pytest.approx(frac, rel=0.1)
