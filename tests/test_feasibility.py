"""The necessary conditions checked before solving (transcription/feasibility.py, docs/mathematics.md §13).

For each condition: a problem at 0.9 of its continuous bound is not refused and solves (converged,
bounds and path constraints held on the re-simulated path); one at 1.1 is refused as infeasible with
its reason and without an iteration.  The bounds used here are the continuous ones, written
independently of the module: the bang-bang distance F T^2 / 4m and angle M T^2 / 4 lambda_min (both
attained: rest to rest along a line / about the minor principal axis), T F and T M for the momenta,
Omega_max T for the rate limit.  The body is the keep-out slew's (inertia [1, 1.5, 2], no gravity).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.ocp.feasibility import necessary_conditions, step_failure
from se3ocp.transcription.outcome import Result

from support import config

N = 40
T = 10.0
BASE = (f"horizon.N={N}", f"horizon.T={T}", "constraints=[]", "solver.direct.jit=false",
        "initial={position: [0, 0, 0], velocity: [0, 0, 0], attitude: identity, angular_velocity: [0, 0, 0]}")
LAMBDA_MIN = 1.0  # the minor principal moment, about body x


def _load(*sets):
    return se3ocp.load(config("slew_keep_out"), BASE + sets)


def _cases(f: float):
    """(name, maneuver) at the fraction f of each condition's bound."""
    F, M, W = 0.02, 0.01, 0.05
    angle_M = math.degrees(f * M * T**2 / (4 * LAMBDA_MIN))
    angle_W = math.degrees(f * W * T)
    return [
        ("distance", _load("control.bounds={force: {norm: 0.02}, moment: {norm: 0}}",
                           f"terminal={{position: [{f * F * T**2 / 4}, 0, 0], velocity: [0, 0, 0], attitude: identity, "
                           "angular_velocity: [0, 0, 0]}")),
        ("linear momentum", _load("control.bounds={force: {norm: 0.02}, moment: {norm: 0}}",
                                  f"terminal={{velocity: [0, {f * F * T}, 0], attitude: identity, "
                                  "angular_velocity: [0, 0, 0]}")),
        ("angular momentum", _load("control.bounds={force: {norm: 0}, moment: {norm: 0.01}}",
                                   f"terminal={{angular_velocity: [0, 0, {f * M * T / 2.0}]}}")),  # J_z = 2
        ("moment bound", _load("control.bounds={force: {norm: 0}, moment: {norm: 0.01}}",
                               f"terminal={{attitude: {{axis_angle: [1, 0, 0, {angle_M}]}}, angular_velocity: [0, 0, 0]}}")),
        ("rate limit", _load("control.bounds={force: {norm: 0}}", "discretization=first_order",
                             f"constraints=[{{kind: max_angular_rate, value: {W}}}]",
                             f"terminal={{attitude: {{axis_angle: [1, 0, 0, {angle_W}]}}, angular_velocity: [0, 0, 0]}}")),
    ]


@pytest.mark.parametrize("name", ["distance", "linear momentum", "angular momentum", "moment bound", "rate limit"])
def test_just_inside_each_bound_is_solved(name):
    man = dict(_cases(0.9))[name]
    assert necessary_conditions(man.problem) is None
    sol = se3ocp.solve(man, direct={"max_iter": 500})
    assert sol.converged, sol.message
    assert sol.terminal_error <= 1e-6
    ctrl = man.problem.control
    for u, bound in ((sol.u_f, ctrl.force_bound), (sol.u_m, ctrl.moment_bound)):
        if bound is not None:
            assert np.all(np.linalg.norm(u, axis=1) <= bound.b * (1 + 1e-6) + 1e-12)
    for c in man.problem.constraints:
        assert c.margin(sol.trajectory).min() >= -1e-6
    # near the bound the bound is active: the case tests the boundary, not the interior
    if name == "distance":
        assert np.linalg.norm(sol.u_f, axis=1).max() >= 0.999 * ctrl.force_bound.b
    elif name == "moment bound":
        assert np.linalg.norm(sol.u_m, axis=1).max() >= 0.999 * ctrl.moment_bound.b
    elif name == "rate limit":
        assert np.linalg.norm(sol.trajectory.Omega, axis=1).max() >= 0.999 * man.problem.constraints[0].value


@pytest.mark.parametrize("name", ["distance", "linear momentum", "angular momentum", "moment bound", "rate limit"])
def test_just_outside_each_bound_is_refused_at_once(name):
    man = dict(_cases(1.1))[name]
    reason = necessary_conditions(man.problem)
    assert reason is not None and name in reason, reason
    for method in ("direct", "both"):
        out = se3ocp.solve(man, method)
        for s in (out.solutions.values() if method == "both" else [out]):
            assert s.result is Result.infeasible and s.iterations == 0 and s.history == ()
            assert s.message.startswith("provably infeasible") and name in s.message
            assert s.trajectory.X.shape == (N + 1, 18) and np.all(np.isfinite(s.trajectory.X))


def test_external_forces_and_moments_switch_the_checks_off():
    """Under gravity nothing is refused: the force check does not apply to E3 with a small thrust bound."""
    e3 = se3ocp.load(config("e3"), ["horizon.N=20", "control.bounds={force: {norm: 1}}"])
    assert necessary_conditions(e3.problem) is None
    e3_free = se3ocp.load(config("e3"), ["horizon.N=20", "control.bounds={force: {norm: 1}}", "gravity={kind: none}"])
    assert "linear momentum" in necessary_conditions(e3_free.problem)


def test_lgvi_rate_limit_without_a_moment_bound_is_not_checked():
    """The LGVI's node moments act within a step: without a moment bound the node rates bound nothing."""
    man = _load("control.bounds={force: {norm: 0}}", "constraints=[{kind: max_angular_rate, value: 0.001}]",
                "terminal={attitude: {axis_angle: [1, 0, 0, 90]}, angular_velocity: [0, 0, 0]}")
    assert necessary_conditions(man.problem) is None


def test_step_failure_tells_non_finite_from_a_fold_from_hopeless_data():
    man = _load("control.bounds={force: {norm: 0}}")
    p = man.problem
    X = np.tile(p.X0, (N + 1, 1))
    res = np.zeros(N)
    X[3, 0] = np.nan
    assert step_failure(p, X, res, 0.25)[0] is Result.non_finite
    X = np.tile(p.X0, (N + 1, 1))
    X[5, 15] = 8.0  # h |Pi| / lambda_min = 2 at step 5: N = 40 * 2 * 2 = 160 brings it to 1/2
    res[5] = 1.0
    result, text = step_failure(p, X, res, 0.25)
    assert result is Result.cayley_failed and "smaller step" in text and "about 160" in text
    X[5, 15] = 1e300  # no horizon.N fixes that
    result, text = step_failure(p, X, res, 0.25)
    assert result is Result.cayley_failed and "no step size can fix it" in text and "smaller step h" not in text


@pytest.mark.parametrize("name, published", [("slew_time_optimal_symmetric", 3.2431), ("slew_time_optimal", 28.6304077)])
def test_published_minimum_times_are_never_refused(name, published):
    """The time-optimal slews of test_constrained (published minima [BW93], [Bet10]): with the final time
    free up to just below the published minimum nothing is refused (the conditions are necessary),
    and the refusal threshold of the symmetric body is the bang-bang eigenaxis bound of the torque's
    norm, T^2 >= 4 pi lambda / |b| = 4 pi / sqrt(3) (to the discrete scheme's 0.1 %)."""
    p = se3ocp.load(config(name)).problem

    def refused(t_max):
        return necessary_conditions(p.replace(time_bounds=(0.25 * t_max, t_max), T=0.5 * t_max)) is not None

    assert not refused(published * 0.999)
    lo, hi = 0.01, published
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if refused(mid) else (lo, mid)
    assert hi < published
    if name == "slew_time_optimal_symmetric":
        assert hi == pytest.approx(math.sqrt(4 * math.pi / math.sqrt(3)), rel=1e-3)


# ------------------------------------------------------------------------------ the orbit's delta-v
def _hohmann_vis_viva(mu, r1, r2):
    """Hohmann's delta-v written from the vis-viva equation v^2 = mu (2/r - 1/a), independently of the module."""
    a = 0.5 * (r1 + r2)
    dv1 = abs(math.sqrt(mu * (2 / r1 - 1 / a)) - math.sqrt(mu / r1))
    dv2 = abs(math.sqrt(mu / r2) - math.sqrt(mu * (2 / r2 - 1 / a)))
    return dv1 + dv2


def test_orbit_delta_v_is_hohmann_or_the_bielliptic_limit():
    from se3ocp.transcription.ocp.feasibility import orbit_delta_v
    mu = 398600.4418
    for r1, r2 in ((6778.137, 6788.137), (6788.137, 6778.137), (7000.0, 42164.0)):
        assert orbit_delta_v(mu, r1, r2) == pytest.approx(_hohmann_vis_viva(mu, r1, r2), rel=1e-12)
    # beyond r2/r1 = 11.94 the bi-elliptic limit (sqrt 2 - 1)(v1 + v2) is smaller: at 15 it is the bound
    v1, v2 = math.sqrt(mu / 7000.0), math.sqrt(mu / 105000.0)
    assert orbit_delta_v(mu, 7000.0, 105000.0) == pytest.approx((math.sqrt(2) - 1) * (v1 + v2), rel=1e-12)
    assert orbit_delta_v(mu, 7000.0, 105000.0) < _hohmann_vis_viva(mu, 7000.0, 105000.0)


@pytest.mark.parametrize("fraction, refused", [(0.02, True), (0.95, True), (1.02, False), (2.0, False)])
def test_an_engine_too_weak_for_the_raise_is_refused_before_solving(fraction, refused):
    """configs/leo_body_engine.yaml (+10 km in one orbit, 500 kg) with an engine that can give ``fraction`` of the
    Hohmann delta-v in T: below it (a 0.01 N engine: 2 %), infeasible at once with the numbers, no iteration; at or
    above it (1 %: the perturbations' allowance) the check lets it through (it is necessary, not sufficient)."""
    from se3ocp.transcription.ocp.feasibility import orbit_delta_v
    mu, T, m = 398600.4418, 5560.0, 500.0
    F = fraction * orbit_delta_v(mu, 6778.137, 6788.137) * m / T
    man = se3ocp.load(config("leo_body_engine"), [f"control.bounds.force.thruster.max={F!r}"])
    reason = necessary_conditions(man.problem)
    assert (reason is not None) == refused, reason
    if refused:
        assert "needs a delta-v of at least 0.005651" in reason and "Hohmann" in reason
        sol = se3ocp.solve(man)
        assert sol.result is Result.infeasible and sol.iterations == 0


def test_a_thrust_bound_in_newtons_in_a_km_file_is_named():
    """leo_body_engine's 1 N engine written as 1.0 (1 kN in a km file): 1.97e3 times the Hohmann delta-v, above the
    slip factor 1e3 -> a warning naming the unit, on validate's 'but' line; the file's own 1e-3 kN (2x) and a
    normalized file (no km) get none."""
    import io
    from contextlib import redirect_stdout

    from se3ocp.problems.cli import main
    from se3ocp.problems.physical import thrust_warning

    slip = se3ocp.load(config("leo_body_engine"), ["control.bounds.force.thruster.max=1.0"])
    said = thrust_warning(slip)
    assert "1.97e+03 times the 5.651 m/s" in said and "1 N = 1e-3 kN" in said, said
    assert thrust_warning(se3ocp.load(config("leo_body_engine"))) == ""
    assert thrust_warning(se3ocp.load(config("orbit_raise_fuel"))) == ""
    out = io.StringIO()
    with redirect_stdout(out):
        rc = main(["validate", str(config("leo_body_engine")), "--set", "control.bounds.force.thruster.max=1.0"])
    assert rc == 0 and "  but control.bounds.force lets the engine give" in out.getvalue()
