"""The Kepler-split LGVI (docs/mathematics.md §2a; transcription/dynamics/kepler.py).  Claims and tolerances:

* The exact two-body drift: against DOP853 (rtol 1e-13) on elliptic and hyperbolic arcs, position and velocity to
  1e-11 relative; on a circular orbit against the closed form to 1e-14 relative per unit angle; Lagrange's
  f gd - fd g = 1 to 1e-13; a step past the Stumpff series' range (|z| > Z_MAX) reports a residual above 1.
* The series: C(z), S(z) against their closed forms (cos/cosh) for |z| <= Z_MAX to 2e-15 absolute.
* The scheme on a LEO orbit (configs/leo_body_engine.yaml's spacecraft, no thrust, N = 400, one orbit): its free motion
  against the continuous equations flown by scipy's DOP853 misses by <= 1 m and 1 mm/s where the second-order LGVI
  misses by >= 3 km (measured 3.51 km: the second-order phase error of the orbit) -- the error scales with the perturbation.
* Order: on the tumbling dumbbell the fitted slope is 2 (tests/test_lgvi.py::test_convergence_order, parametrized).
* The indirect method's conditions follow the step: direct = indirect on configs/eccentric_transfer.yaml with
  lgvi_kepler, cost to 1e-8 relative.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from se3ocp.problems.api import load, solve
from se3ocp.transcription.dynamics.kepler import Z_MAX, kepler_drift, stumpff
from se3ocp.transcription.geometry.so3 import hat
from se3ocp.transcription.geometry.state import unpack_states
from se3ocp.transcription.outcome import Result

MU = 398600.4418


def two_body(t, y):
    return np.r_[y[3:], -MU * y[:3] / np.linalg.norm(y[:3]) ** 3]


def drift(x, v, h):
    x1, v1, res = kepler_drift(MU)(x, v, h)
    return np.array(x1).ravel(), np.array(v1).ravel(), float(res)


@pytest.mark.parametrize("z", [-Z_MAX, -3.0, -1e-3, 0.0, 1e-8, 0.5, 4.0, Z_MAX])
def test_stumpff_series_match_closed_forms(z):
    """Closed forms (2 sin^2(s/2)/z, (s - sin s)/s^3 and the sinh forms) for |z| >= 1e-2, to 2e-15; below it the
    closed forms cancel, and the four-term Taylor polynomial (error < z^4/10! < 3e-19) is the reference, to 1e-16."""
    C, S = stumpff(z)
    if abs(z) < 1e-2:
        Cx = 0.5 - z / 24 + z**2 / 720 - z**3 / 40320
        Sx = 1 / 6 - z / 120 + z**2 / 5040 - z**3 / 362880
        tol = 1e-16
    elif z > 0:
        s = math.sqrt(z)
        Cx, Sx, tol = 2 * math.sin(s / 2) ** 2 / z, (s - math.sin(s)) / s**3, 2e-15
    else:
        s = math.sqrt(-z)
        Cx, Sx, tol = 2 * math.sinh(s / 2) ** 2 / -z, (math.sinh(s) - s) / s**3, 2e-15
    assert abs(C - Cx) <= tol, (z, C, Cx)
    assert abs(S - Sx) <= tol, (z, S, Sx)


def test_circular_orbit_exact():
    r = 6778.137
    n = math.sqrt(MU / r**3)
    for h in (1.0, 13.9, 600.0, 2000.0):
        x1, v1, res = drift(np.array([r, 0, 0.0]), np.array([0, math.sqrt(MU / r), 0.0]), h)
        ex = r * np.array([math.cos(n * h), math.sin(n * h), 0.0])
        ev = math.sqrt(MU / r) * np.array([-math.sin(n * h), math.cos(n * h), 0.0])
        assert np.linalg.norm(x1 - ex) <= 1e-14 * r * max(1.0, n * h), h
        assert np.linalg.norm(v1 - ev) <= 1e-14 * math.sqrt(MU / r) * max(1.0, n * h), h
        assert res <= 1e-14


@pytest.mark.parametrize("speed", [8.5, 10.0, 12.0])   # elliptic, near-parabolic, hyperbolic (escape 10.85 km/s)
@pytest.mark.parametrize("h", [20.0, 600.0])
def test_drift_matches_dop853(speed, h):
    x0, v0 = np.array([6778.137, 100.0, 50.0]), np.array([0.3, speed, 1.0])
    ref = solve_ivp(two_body, (0, h), np.r_[x0, v0], method="DOP853", rtol=1e-13, atol=1e-12)
    x1, v1, res = drift(x0, v0, h)
    assert np.linalg.norm(x1 - ref.y[:3, -1]) <= 1e-11 * np.linalg.norm(x1)
    assert np.linalg.norm(v1 - ref.y[3:, -1]) <= 1e-11 * np.linalg.norm(v1)
    assert res <= 1e-14
    # Lagrange's identity f gd - fd g = 1 (the flow is symplectic): the angular momentum x x v is kept
    assert np.linalg.norm(np.cross(x1, v1) - np.cross(x0, v0)) <= 1e-13 * np.linalg.norm(np.cross(x0, v0))


def test_step_past_series_range_is_reported():
    r = 6778.137
    period = 2 * math.pi * math.sqrt(r**3 / MU)
    _, _, ok = drift(np.array([r, 0, 0.0]), np.array([0, math.sqrt(MU / r), 0.0]), 0.4 * period)   # z = 6.3
    _, _, bad = drift(np.array([r, 0, 0.0]), np.array([0, math.sqrt(MU / r), 0.0]), 0.6 * period)  # z = 14.2
    assert ok <= 1e-13
    assert bad > 1.0


def fly_continuous(model, X0, T):
    """Eqs. (1)-(4), no control, by DOP853 (rtol 1e-13): the state at T as (x, v)."""
    Jinv = np.linalg.inv(model.inertia)

    def rhs(_t, y):
        x, gamma, R, Pi = y[0:3], y[3:6], y[6:15].reshape(3, 3), y[15:18]
        f, M = model.forces(x, R)
        omega = Jinv @ Pi
        return np.concatenate([gamma / model.mass, np.array(f).ravel(), (R @ hat(omega)).ravel(),
                               np.cross(Pi, omega) + np.array(M).ravel()])

    S = unpack_states(X0[None, :])
    y0 = np.concatenate([S.x[0], S.gamma[0], S.R[0].ravel(), S.Pi[0]])
    sol = solve_ivp(rhs, (0.0, T), y0, method="DOP853", rtol=1e-13, atol=1e-9)
    assert sol.success
    return sol.y[0:3, -1], sol.y[3:6, -1] / model.mass


def test_leo_free_motion_kepler_vs_lgvi():
    """One orbit of the LEO spacecraft at N = 400 (h = 13.9 s): lgvi misses by the note's 3.5 km, lgvi_kepler by
    less than a metre (measured 3.51 km / 3.97 m/s and 5 um / 6e-9 m/s: the point-mass gravity of a rigid body is
    the Kepler force, what is left is the gravity-gradient force, ~1e-12 of it)."""
    misses = {}
    for scheme in ("lgvi", "lgvi_kepler"):
        p = load("configs/leo_body_engine.yaml", [f"discretization={scheme}"]).problem
        X, res = p.disc.simulate(p.X0, None, p.h, p.N)
        assert res.max() <= 1e-12
        x_ref, v_ref = fly_continuous(p.model, p.X0, p.h * p.N)
        misses[scheme] = (np.linalg.norm(X[-1, 0:3] - x_ref), np.linalg.norm(X[-1, 3:6] / p.model.mass - v_ref))
    print(misses)
    assert misses["lgvi"][0] >= 3.0 and misses["lgvi"][1] >= 3e-3          # km, km/s
    assert misses["lgvi_kepler"][0] <= 1e-3 and misses["lgvi_kepler"][1] <= 1e-6


def test_direct_equals_indirect_on_the_kepler_scheme():
    m = load("configs/eccentric_transfer.yaml", ["discretization=lgvi_kepler"])
    out = solve(m, method="both")
    d, i = out.direct, out.indirect
    assert d.converged and i.converged
    assert abs(d.cost - i.cost) <= 1e-8 * abs(d.cost)
    assert np.abs(d.controls - i.controls).max() <= 1e-6 * np.abs(d.controls).max()


def fly_plan(sol):
    """The plan's node controls, linear between the nodes (the LGVI's control model; a body-frame force applied as
    R(t) u_f(t)), flown through eqs. (1)-(4) by DOP853 (rtol 1e-12): the final (x, v, R)."""
    p, tr = sol.problem, sol.trajectory
    model, t, U = p.model, tr.t, np.asarray(sol.controls, float)
    Jinv = np.linalg.inv(model.inertia)

    def rhs(s, y):
        x, gamma, R, Pi = y[0:3], y[3:6], y[6:15].reshape(3, 3), y[15:18]
        u = np.array([np.interp(s, t, U[i]) for i in range(6)])
        f, M = model.forces(x, R)
        omega = Jinv @ Pi
        thrust = R @ u[:3] if p.disc.force_frame == "body" else u[:3]      # a body-fixed engine turns with the body
        return np.concatenate([gamma / model.mass, np.array(f).ravel() + thrust, (R @ hat(omega)).ravel(),
                               np.cross(Pi, omega) + np.array(M).ravel() + u[3:]])

    y0 = np.concatenate([tr.x[0], tr.gamma[0], tr.R[0].ravel(), tr.Pi[0]])
    out = solve_ivp(rhs, (t[0], t[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-10, max_step=float(np.diff(t).min()))
    assert out.success
    return out.y[0:3, -1], out.y[3:6, -1] / model.mass, out.y[6:15, -1].reshape(3, 3)


def flown_miss(man, sol) -> tuple[float, float, float]:
    """The plan of ``sol`` flown by :func:`fly_plan`: its position and velocity miss of ``man``'s state target and
    the larger of each over the maneuver's change the continuous check measured (dx, dv, fraction)."""
    x, v, _ = fly_plan(sol)
    Xd = man.problem.terminal.X
    dx, dv = np.linalg.norm(x - Xd[0:3]), np.linalg.norm(v - Xd[3:6] / man.problem.model.mass)
    c = sol.continuous
    return dx, dv, max(dx / c.change_position, dv / c.change_velocity)


def test_leo_raise_flies_within_one_percent_of_the_maneuver():
    """configs/leo_raise_slew.yaml (+10 km, 90 deg slew, N = 400, inertial force): flown by the test's own DOP853,
    the lgvi plan misses by 3.5 km and 4 m/s (70 % of its 5.66 m/s delta-v: its message and the check say so), the
    lgvi_kepler plan by <= 1 % of the raise (<= 100 m, <= 1 % of delta-v; measured 1 m, 1.2 mm/s); the check's
    fraction agrees with the independent flight to 10 %."""
    for scheme in ("lgvi", "lgvi_kepler"):
        man = load("configs/leo_raise_slew.yaml", [f"discretization={scheme}"])
        sol = solve(man)
        assert sol.converged
        dx, dv, frac = flown_miss(man, sol)
        c = sol.continuous
        assert c.change_position == pytest.approx(10.0, rel=1e-9)                          # the raise, km
        assert c.change_attitude == pytest.approx(np.pi / 2, rel=1e-9)                     # the slew
        print(scheme, dx, dv, c.change_velocity, frac, c.maneuver_fraction)
        assert c.maneuver_fraction == pytest.approx(frac, rel=0.1)
        if scheme == "lgvi":
            assert frac > 0.3 and "of the maneuver" in sol.message
        else:   # reached from the LGVI's optimum (strategy.core.from_scheme)
            assert sol.trace[0].label == "from the lgvi optimum" and sol.trace[0].parts
            assert dx <= 0.1 and dv <= 0.01 * c.change_velocity and frac <= 0.01
            assert "of the maneuver" not in sol.message


@pytest.mark.slow   # 32 s: slow since the default suite passed 15 min on slower instances
def test_the_kepler_scheme_falls_back_on_its_own_starts_when_the_lgvi_route_wanders():
    """The default strategy on lgvi_kepler: the LGVI's optimum finished on the exact scheme within the route's finish
    budget (200 iterations; 7-27 on the six bundled lgvi_kepler files), then the objective's own starts on the exact
    scheme.  leo_engine_fuel.yaml's effort problem with its wheels as one torque of any direction (the propellant
    strategy's first solve: the thrust priced at w_f / T_max, the torque bounded at |u_m| <= 0.01 N m) is one whose LGVI optimum was no start with IPOPT's default
    barrier start (the finish wandered for 3000 iterations, 6 min, at a residual of 0.18; with the budget it stopped at
    200 and the own starts converged, 30 s in all); from the barrier at 1e-4 (strategy.core.Warm) the route's finish
    converges (measured 48 iterations, 9 s in all), to the own starts' optimum (1e-9 relative), and the plan flown by
    the test's own DOP853 lands within 1 % of the raise.  A route that cannot finish within its budget (here 3) hands
    over to the own starts."""
    from se3ocp.transcription.options import DirectOptions
    from se3ocp.transcription.strategy.core import FirstOf, FromRelated, default_strategy

    man = load("configs/leo_engine_fuel.yaml", ["control.objective=effort", "control.weights.force=1e6",
                                                "control.weights.moment=1e16", "control.bounds.moment={norm: 1.0e-8}"])
    p = man.problem
    plan = default_strategy(p, DirectOptions())
    assert isinstance(plan, FirstOf) and isinstance(plan.strategies[0], FromRelated)
    assert plan.strategies[0].finish_budget == 200 and plan.strategies[1] == p.control.objective.strategy(p, None)
    lgvi = p.replace(disc=load("configs/leo_engine_fuel.yaml", ["discretization=lgvi"]).problem.disc)
    assert default_strategy(lgvi, DirectOptions()) == lgvi.control.objective.strategy(lgvi, None)  # no route on lgvi
    sol = solve(man)
    assert sol.converged, sol.message
    (route,) = sol.trace
    assert route.label == "from the lgvi optimum" and route.result is Result.converged and route.iterations < 200
    dx, dv, frac = flown_miss(man, sol)
    assert frac <= 0.01, (dx, dv, frac)
    short = FirstOf((replace(plan.strategies[0], finish_budget=3), plan.strategies[1]))
    fell = solve(man, strategy=short)
    route, own = fell.trace
    assert route.label == "from the lgvi optimum" and route.result is Result.max_iterations and route.iterations == 3
    assert own.result is Result.converged and fell.cost == pytest.approx(sol.cost, rel=1e-9)


@pytest.mark.parametrize("N, route", [pytest.param(400, True, marks=pytest.mark.slow), (100, False), (40, False)])
def test_the_lgvi_route_is_taken_only_where_its_orbit_resolves_the_maneuver(N, route):
    """default_strategy on lgvi_kepler goes through the LGVI only where the LGVI's free motion ends within half of what
    the engine can move the body in T (leo_body_engine: 1 N on 500 kg, 31 km; the LGVI's orbit 3.5 km off at N = 400,
    56 km at 100): at N = 100 and 40 the LGVI problem failed after 94 and 49 s where the own starts converge in about
    a second; by default the plan converges at every N and is flown by the test's own DOP853 within 1 % at N = 400."""
    from se3ocp.transcription.options import DirectOptions
    from se3ocp.transcription.strategy.core import FirstOf, default_strategy

    man = load("configs/leo_body_engine.yaml", [f"horizon.N={N}"])
    plan = default_strategy(man.problem, DirectOptions())
    assert isinstance(plan, FirstOf) is route
    sol = solve(man)
    assert sol.converged, sol.message
    assert (sol.trace[0].label == "from the lgvi optimum") is route
    if N == 400:
        assert flown_miss(man, sol)[2] <= 0.01


def test_an_orbit_targets_miss_is_measured_in_the_maneuvers_terms():
    """configs/orbit_raise_time.yaml (r = 1 -> the circular orbit r = 1.2, any point of it): what the maneuver changes
    is measured against the target orbit's point nearest the free motion's end -- the raise 0.2 and a velocity change --
    so its flown miss is a fraction of the maneuver, not a bare terminal-error number.  Flown by the test's own
    DOP853, the plan ends at most the check's terminal position miss from the target circle (the check measures
    against the plan's last node, which lies on the circle: an upper bound; measured 1.3e-4 against 2.4e-4), and the
    fraction of the maneuver it misses by (distance to the circle, velocity off the circular one there) is within the
    check's (measured 6.4e-4 against 1.3e-3)."""
    man = load("configs/orbit_raise_time.yaml")
    sol = solve(man)
    assert sol.converged, sol.message
    c = sol.continuous
    assert [n for n, _, _ in c.maneuver_parts()] == ["position", "velocity"]
    assert c.change_position == pytest.approx(0.2, rel=1e-9)
    x, v, _ = fly_plan(sol)
    target, mu = man.problem.terminal, man.problem.model.mu
    n = target.normal
    e = (x - (x @ n) * n) / np.linalg.norm(x - (x @ n) * n)
    dx = np.linalg.norm(x - target.radius * e)
    dv = np.linalg.norm(v - np.sqrt(mu / target.radius) * np.cross(n, e))
    print(dx, dv, c.terminal_position, c.terminal_velocity, c.maneuver_fraction)
    assert dx <= c.terminal_position * (1 + 1e-6)
    assert max(dx / c.change_position, dv / c.change_velocity) <= c.maneuver_fraction * 1.1
    assert c.maneuver_fraction < 0.01
