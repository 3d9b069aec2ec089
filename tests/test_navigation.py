"""Navigation (issue 43): noisy measurements and the multiplicative EKF between them and the tracker
(transcription/closedloop/estimator.py, docs/mathematics.md §12 *Navigation*).

Every claim with its tolerance:

* A static attitude measured with noise sigma (a scalar Kalman filter per axis, A = I): the covariance after k + 1
  measurements is 1 / (1/P0 + (k+1)/sigma^2) and, with a random walk q per step, tends to the Riccati root
  (-q + sqrt(q^2 + 4 q sigma^2)) / 2 -- both to 1e-12 relative; over 400 seeded runs the attitude errors' sum of
  squares over P lies within the chi-square(3 M) 99.9 % bounds.
* A body turning at a constant rate, its estimate started 0.5 rad off the plan and carried by the linearization
  with no measurement: the estimate equals R_0 Exp(delta) Exp(k h omega) at every node to 1e-13 (the multiplicative
  bookkeeping is exact for a map that is linear in the body-frame error).
* NEES: a linear-Gaussian truth with E3's own maps (A_k, Bu_k of a plan at N = 40), process noise and a persisting
  force as the filter assumes, 300 seeded runs: the mean NEES of the 12 state errors at 5 nodes within the
  chi-square(12 M) 99.9 % bounds; the estimator beats the raw measurement (RMS position error below 0.7 of it;
  measured 0.38; ~4 s).
* The measurement's noise has the stated 1-sigma per component (to 3 % over 8000 draws), the rate's through J.
* The plan's local errors (each continuous step from a plan node against the next node) carry the estimate along the
  continuous flight: E3 (LGVI, N = 40) open loop, to 2e-2 of the plan's own deviation from it (measured 1.0e-2).
* A constant rate bias is estimated from the attitude measurements of a body at rest: its posterior 1-sigma below 0.1
  of the prior, and the bias and state errors of 200 seeded runs within their chi-square 99.9 % bounds.
* Estimator none: the tracker reads the measurement itself, bit for bit.
* A flight with no noise and the ekf equals the flight without navigation to 1e-10 of the state's size (the state read
  is the flown one; only the law's evaluation path differs, as in test_flight's 1e-10).
* The navigation block's errors: one line naming the field; through the CLI exit 2, one line naming the file and
  field, nothing written; a CLI flight writes the estimation columns, their statistics and report rows.
* The navigated loop flown in one call (closedloop/navloop.py) equals the per-interval law to 1e-10 relative (states,
  commands, estimation errors; ekf, none, a measurement period).
* The bounded slew (per-interval law) with attitude noise: the EKF beats the raw measurement (see its test).
* Navigation flights on a Dask LocalCluster are the in-process flights, row for row (slow).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest
from scipy.stats import chi2

import se3ocp
from se3ocp.problems.flight import parse_flight
from se3ocp.problems.flight.plan import plan_payload, run_seeds, sample_errors, truth_body
from se3ocp.problems.flight.task import fly_one, gains_of
from se3ocp.problems.schema import ConfigError
from se3ocp.transcription.closedloop.estimator import (Estimator, measure, measurement_nodes, navigation_filter,
                                                       noise_factor)
from se3ocp.transcription.closedloop.tracking import retract, tangent_error, tracking_gains
from se3ocp.transcription.geometry.so3 import exp_so3, log_so3

from support import maneuver, perturbed_truth


def static_filter(N, sigma, q, P0, estimator="ekf", measured=None):
    """A body at rest at R0 (A = I, Bu = 0): the attitude measured with noise sigma (rad), the other blocks 1e-3."""
    R0 = exp_so3(np.array([0.3, -0.2, 0.5]))
    X = np.concatenate([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0], R0.ravel(order="F"), [0.0, 0.0, 0.0]])
    F = noise_factor((1e-3, 1e-3, sigma, 1e-3), 1.0, np.eye(3))
    Ry = F @ F.T
    Qz = np.zeros((12, 12))
    Qz[6:9, 6:9] = q * np.eye(3)
    prior = np.zeros((18, 18))
    prior[:12, :12] = P0 * np.eye(12)
    nav = navigation_filter(np.repeat(X[None], N + 1, axis=0), np.repeat(np.eye(12)[None], N, axis=0),
                            np.zeros((N, 12, 6)), np.ones(N), Ry, prior, Qz, np.zeros((6, 6)),
                            np.ones(N, bool) if measured is None else measured, estimator)
    return nav, X, F


def test_a_static_attitude_has_the_closed_form_kalman_covariance_and_errors():
    sigma, P0, N = 1e-3, 4e-6, 20
    nav, _, _ = static_filter(N, sigma, 0.0, P0)
    want = 1.0 / (1.0 / P0 + np.arange(1, N + 1) / sigma**2)
    got = nav.P[:, 6, 6]
    assert np.max(np.abs(got / want - 1)) <= 1e-12
    q = 1e-8
    nav_q, X, F = static_filter(400, sigma, q, P0)
    root = (-q + np.sqrt(q * q + 4 * q * sigma**2)) / 2
    assert abs(nav_q.P[-1, 6, 6] / root - 1) <= 1e-12
    # Monte Carlo: the attitude error after N measurements against sqrt(P_N)
    M, rng = 400, np.random.default_rng(7)
    s = 0.0
    for _ in range(M):
        truth = retract(X, np.r_[np.zeros(6), np.sqrt(P0) * rng.standard_normal(3), np.zeros(3)])
        est = Estimator(nav)
        for k in range(N):
            est.estimate(k, measure(truth, F, rng.standard_normal(12)))
            if k < N - 1:
                est.predict(np.zeros(6))
        e = est.error(truth)[6:9]
        s += e @ e / nav.P[-1, 6, 6]
    lo, hi = chi2.ppf([0.0005, 0.9995], 3 * M)
    print(f"sum e^2/P = {s:.1f}, bounds [{lo:.1f}, {hi:.1f}] (RMS ratio {np.sqrt(s / (3 * M)):.3f})")
    assert lo <= s <= hi


def test_a_constant_rate_body_is_propagated_exactly():
    """A spherical body turning at omega: the attitude error from the plan R_k = R0 Exp(k h omega) maps exactly by
    zeta_{k+1} = Exp(-h omega) zeta_k; started at R0 Exp(delta), |delta| = 0.5 rad, the estimate carried forward
    with no measurement is R0 Exp(delta) Exp(k h omega) at every node."""
    N, h, w = 50, 0.02, np.array([0.4, -1.1, 2.0])
    R0 = exp_so3(np.array([0.1, 0.2, -0.3]))
    Pi = w.copy()                                    # J = I
    Xref = np.array([np.concatenate([np.zeros(6), (R0 @ exp_so3(k * h * w)).ravel(order="F"), Pi])
                     for k in range(N + 1)])
    A = np.eye(12)
    A[6:9, 6:9] = exp_so3(-h * w)
    delta = np.array([0.3, -0.25, 0.3])
    measured = np.zeros(N, bool)
    measured[0] = True
    nav = navigation_filter(Xref, np.repeat(A[None], N, axis=0), np.zeros((N, 12, 6)), np.ones(N), np.zeros((12, 12)),
                            np.zeros((18, 18)), np.zeros((12, 12)), np.zeros((6, 6)), measured)
    est = Estimator(nav)
    worst = 0.0
    for k in range(N):
        truth = Xref[k].copy()
        truth[6:15] = (R0 @ exp_so3(delta) @ exp_so3(k * h * w)).ravel(order="F")
        Xh, _ = est.estimate(k, truth if k == 0 else None)
        worst = max(worst, np.abs(Xh - truth).max())
        est.predict(np.zeros(6))
    print(f"largest difference from the exact motion: {worst:.1e}")
    assert worst <= 1e-13


@lru_cache(maxsize=None)
def e3_gains(N=40):
    man = maneuver("e3", N, "lgvi")
    sol = se3ocp.solve(man, "direct")
    assert sol.converged
    return man, sol, tracking_gains(sol)


def test_nees_of_the_ekf_is_consistent_with_its_covariance():
    """The truth follows the filter's own model (E3's maps, process noise Qz, a random-walk force Qf) in tangent
    coordinates about the plan; the measurements are the module's (Y = X (+) F n)."""
    _, _, g = e3_gains()
    N = g.N
    F = noise_factor((1e-4, 1e-4, np.radians(0.01), 1e-4), 1.0, np.diag([1e-3, 2e-3, 3e-3]))
    Ry = F @ F.T
    Qz, Qf = 1e-2 * Ry, np.diag(np.r_[1e-4 * np.ones(3), 1e-8 * np.ones(3)])
    P0 = np.zeros((18, 18))
    P0[:12, :12], P0[12:, 12:] = 4 * Ry, 100 * Qf
    nav = navigation_filter(g.X, g.A, g.Bu, np.ones(N), Ry, P0, Qz, Qf, np.ones(N, bool))
    Lz, Lf, L0 = np.linalg.cholesky(Qz), np.linalg.cholesky(Qf), np.linalg.cholesky(P0)
    M, nodes, rng = 300, (5, 12, 20, 30, 39), np.random.default_rng(11)
    nees = {k: 0.0 for k in nodes}
    sq_est = sq_raw = 0.0
    for _ in range(M):
        s = L0 @ rng.standard_normal(18)
        z, f = s[:12], s[12:]
        est = Estimator(nav)
        for k in range(N):
            X = retract(g.X[k], z)
            Y = measure(X, F, rng.standard_normal(12))
            est.estimate(k, Y)
            e = est.error(X)
            if k in nees:
                nees[k] += e @ np.linalg.solve(nav.P[k, :12, :12], e)
            sq_est += e[0:3] @ e[0:3]
            sq_raw += np.sum((Y[0:3] - X[0:3]) ** 2)
            est.predict(np.zeros(6))
            z = g.A[k] @ z + g.Bu[k] @ f + Lz @ rng.standard_normal(12)
            f = f + Lf @ rng.standard_normal(6)
    lo, hi = chi2.ppf([0.0005, 0.9995], 12 * M)
    print({k: round(v / M, 2) for k, v in nees.items()}, f"bounds [{lo / M:.2f}, {hi / M:.2f}];",
          f"RMS position error over the raw measurement's {np.sqrt(sq_est / sq_raw):.3f}")
    assert all(lo <= v <= hi for v in nees.values())
    assert np.sqrt(sq_est / sq_raw) < 0.7


def test_the_plans_local_errors_carry_the_estimate_along_the_continuous_flight():
    """E3 (LGVI, N = 40) flown open loop from its first node on the plan's own body (transcription.dynamics.flight):
    the estimate carried from that node by the plan's maps alone follows the plan's nodes, 4.0e-2 off the flight at
    worst; with each step's local error (local_errors: the continuous step from the plan's node against the next node)
    it follows the flight to 2e-2 of that (measured 1.0e-2: what is left is second order in the deviation)."""
    from se3ocp.transcription.closedloop.estimator import local_errors
    from se3ocp.transcription.dynamics.flight import OpenLoop, fly

    man, sol, g = e3_gains()
    body = sol.problem.model
    flown = fly(body, g.X[0], g.t, OpenLoop.of_controls(g.scheme, g.U)).nodes
    worst = []
    for eps in (None, local_errors(g, body, sol.problem.disc.force_frame)):
        measured = np.zeros(g.N, bool)
        measured[0] = True
        nav = navigation_filter(g.X, g.A, g.Bu, np.ones(g.N), np.zeros((12, 12)), np.zeros((18, 18)), np.zeros((12, 12)),
                                np.zeros((6, 6)), measured, "ekf", eps)
        est, w = Estimator(nav), 0.0
        for k in range(g.N):
            Xh, _ = est.estimate(k, flown[k] if k == 0 else None)
            w = max(w, np.abs(tangent_error(flown[k], Xh)).max())
            est.predict(np.zeros(6))
        worst.append(w)
    print(f"largest error from the flight: {worst[0]:.2e} without, {worst[1]:.2e} with the local errors")
    assert worst[0] >= 1e-2 and worst[1] <= 2e-2 * worst[0]


def test_a_rate_bias_is_estimated_from_the_attitude_measurements():
    """A body near rest (A: the attitude integrates the rate, zeta_{k+1} = zeta_k + h J^-1 dPi_k, the truth's too),
    attitude and rate measured with noise 1e-3 and the rate with a constant bias of 1-sigma 1e-2 rad per time unit: the
    rate bias is observable through the attitude, its posterior 1-sigma after 100 steps below 0.1 of the prior, and
    over 200 seeded runs its errors' sum of squares over the posterior covariance, and the state errors' NEES, within
    their chi-square 99.9 % bounds."""
    N, h, J = 100, 0.05, np.diag([1.0, 2.0, 3.0])
    R0 = exp_so3(np.array([0.3, -0.2, 0.5]))
    X = np.concatenate([np.zeros(6), R0.ravel(order="F"), np.zeros(3)])
    A = np.eye(12)
    A[6:9, 9:12] = h * np.linalg.inv(J)
    F = noise_factor((1e-3, 1e-3, 1e-3, 1e-3), 1.0, J)
    Fb = noise_factor((0.0, 0.0, 0.0, 1e-2), 1.0, J)
    P0 = np.zeros((18, 18))
    P0[:12, :12] = F @ F.T
    nav = navigation_filter(np.repeat(X[None], N + 1, axis=0), np.repeat(A[None], N, axis=0), np.zeros((N, 12, 6)),
                            np.ones(N), F @ F.T, P0, 1e-12 * np.eye(12), np.zeros((6, 6)), np.ones(N, bool), "ekf",
                            Pc=Fb @ Fb.T)
    Pb = nav.P[-1, 27:30, 27:30]
    assert np.sqrt(np.diag(Pb)).max() <= 0.1 * 1e-2 * np.diag(J).min()
    M, rng = 200, np.random.default_rng(9)
    sb = se = 0.0
    for _ in range(M):
        z, c = F @ rng.standard_normal(12), Fb @ rng.standard_normal(12)
        est = Estimator(nav)
        for k in range(N):
            truth = retract(X, z)
            est.estimate(k, measure(truth, F, rng.standard_normal(12), c))
            if k < N - 1:
                est.predict(np.zeros(6))
                z = A @ z
        db = est.c[9:12] - c[9:12]
        sb += db @ np.linalg.solve(Pb, db)
        e = est.error(truth)
        se += e @ np.linalg.solve(nav.P[-1, :12, :12], e)
    lo3, hi3 = chi2.ppf([0.0005, 0.9995], 3 * M)
    lo12, hi12 = chi2.ppf([0.0005, 0.9995], 12 * M)
    print(f"rate bias: {sb / M:.2f} (3), state NEES {se / M:.2f} (12); posterior bias sigma {np.sqrt(np.diag(Pb))}")
    assert lo3 <= sb <= hi3 and lo12 <= se <= hi12


def test_estimator_none_reads_the_raw_measurement():
    nav, X, F = static_filter(20, 1e-3, 0.0, 1e-6, estimator="none")
    est, rng = Estimator(nav), np.random.default_rng(3)
    for k in range(20):
        Y = measure(X, F, rng.standard_normal(12))
        Xh, r = est.estimate(k, Y)
        assert np.array_equal(Xh, Y) and r is None
        est.predict(np.zeros(6))
    assert np.allclose(nav.P[:, :12, :12], F @ F.T, rtol=1e-14, atol=0)       # the covariance of the measurement


def test_measurement_nodes_of_a_period():
    t = np.linspace(0.0, 1.0, 11)                 # h = 0.1
    assert measurement_nodes(t, None).all() and measurement_nodes(t, None).size == 10
    assert np.flatnonzero(measurement_nodes(t, 0.3)).tolist() == [0, 3, 6, 9]
    assert np.flatnonzero(measurement_nodes(t, 0.1)).tolist() == list(range(10))
    assert np.flatnonzero(measurement_nodes(t, 0.25)).tolist() == [0, 3, 5, 8]


def test_measurement_noise_has_the_stated_sigmas():
    """Y (-) X over 8000 draws: sample 1-sigma of each component within 3 % of the stated (the rate's through J; the
    sampling error of a 1-sigma is 0.8 %)."""
    J = np.diag([2.0, 3.0, 4.0])
    F = noise_factor((1e-4, 2e-4, np.radians(0.01), 3e-4), 5.0, J)
    X = retract(np.r_[np.zeros(6), np.eye(3).ravel(), np.ones(3)], np.r_[np.zeros(6), 0.4, 0.2, 0.1, np.zeros(3)])
    rng = np.random.default_rng(5)
    e = np.array([tangent_error(measure(X, F, rng.standard_normal(12)), X) for _ in range(8000)])
    e[:, 3:6] /= 5.0
    e[:, 9:12] = np.linalg.solve(J, e[:, 9:12].T).T
    want = np.repeat([1e-4, 2e-4, np.radians(0.01), 3e-4], 3)
    assert np.max(np.abs(e.std(axis=0) / want - 1)) < 0.03
    assert np.abs(log_so3(X[6:15].reshape(3, 3, order="F"))).max() > 0.1        # away from the identity


def test_a_noiseless_ekf_flight_is_the_flight_without_navigation():
    man, sol, _ = e3_gains()
    flight = {"truth": {"gravity": {"kind": "j2", "J2": 1.08e-3, "radius": 0.9}},
              "errors": {"initial": {"position": 1e-4, "velocity": 1e-4, "attitude_deg": 0.5, "angular_velocity": 1e-3},
                         "force_scale": 0.02, "force_misalignment_deg": 0.5, "inertia_scale": 0.01},
              "feedback": "lqr", "runs": 2, "seed": 2}
    plain = parse_flight(flight)
    nav = parse_flight({**flight, "navigation": {"noise": {}, "estimator": "ekf"}})
    zero = {"position": 0.0, "velocity": 0.0, "attitude_deg": 0.0, "angular_velocity": 0.0}
    assert nav.navigation == {"noise": zero, "bias": zero, "estimator": "ekf"}
    payload = plan_payload(man, sol)
    gains = gains_of(payload, plain.weights)
    base = truth_body(man, plain)
    from se3ocp.problems.flight.plan import load_plan
    _, plan = load_plan(payload)
    for i, seed in enumerate(run_seeds(plain)):
        err = sample_errors(plain, i, seed, plan.trajectory.X[0], man.problem.model.mass, man.problem.model.inertia,
                            man.problem.disc.force_frame)
        a, _, _, none, _ = fly_one(plan, gains, plain, err, base, "lqr", payload=payload)
        b, _, _, law, _ = fly_one(plan, gains, nav, err, base, "lqr", payload=payload)
        d = np.abs(a.X - b.X).max() / np.abs(a.X).max()
        print(f"run {i}: largest difference {d:.1e} of the state's size")
        assert none is None and law is not None and len(law.errors) == gains.N
        assert d <= 1e-10
        assert np.abs(np.array(law.errors)).max() <= 1e-12         # the estimate is the flown state


def test_the_navigation_block_and_its_one_line_errors():
    spec = parse_flight({"navigation": {"noise": {"position": 1e-4, "attitude_deg": 0.01}, "period": 0.005}})
    zero = {"position": 0.0, "velocity": 0.0, "attitude_deg": 0.0, "angular_velocity": 0.0}
    assert spec.navigation == {"noise": {**zero, "position": 1e-4, "attitude_deg": 0.01}, "bias": zero,
                               "period": 0.005, "estimator": "ekf"}
    assert parse_flight(spec.resolved).resolved == spec.resolved
    assert "navigation" not in parse_flight({}).resolved and parse_flight({}).navigation is None
    for doc, message in (({"noise": {"position": -1}}, "flight.navigation.noise.position: expected a non-negative"),
                         ({"noise": {"rate": 1e-4}}, "flight.navigation.noise.rate: unknown key"),
                         ({"period": 0}, "flight.navigation.period: expected a positive number"),
                         ({"estimator": "ukf"}, "flight.navigation.estimator: expected one of ekf, none"),
                         ({"bias": {"angular_velocity": -1}}, "flight.navigation.bias.angular_velocity: expected a non"),
                         ({"drift": 1}, "flight.navigation.drift: unknown key"),
                         ("ekf", "flight.navigation: expected a mapping")):
        with pytest.raises(ConfigError, match=message) as info:
            parse_flight({"navigation": doc}, "f.yaml")
        assert "\n" not in str(info.value) and "f.yaml" in str(info.value)
    with pytest.raises(ConfigError, match="flight.navigation: not flown with feedback 'all'"):
        parse_flight({"navigation": {}, "feedback": "all"}, "f.yaml")


@pytest.mark.parametrize("estimator, period", [("ekf", None), ("none", None), ("ekf", 0.04)])
def test_the_navigated_loop_in_one_call_flies_as_the_law_asked_per_interval(estimator, period):
    """transcription/closedloop/navloop.py (measurement, estimator and tracker inside one mapaccum) against the
    per-interval law (estimator.Navigated in a ClosedLoop): E3 at N = 40, a truth inertia 1 % off, 2 % thrust scale,
    a misalignment, an initial offset and navigation noise; every sample, command and estimation error agrees to 1e-10
    relative."""
    from se3ocp.transcription.closedloop.estimator import Navigated, local_errors, plan_filter
    from se3ocp.transcription.closedloop.loop import TrackingLoop
    from se3ocp.transcription.closedloop.navloop import NavigatedLoop
    from se3ocp.transcription.dynamics.flight import ClosedLoop, OpenLoop, fly

    _, sol, g = e3_gains()
    body = sol.problem.model
    truth, act, X0 = perturbed_truth(sol)
    F = noise_factor((1e-4, 1e-4, np.radians(0.01), 1e-4), body.mass, body.inertia)
    F0 = noise_factor((1e-4, 1e-4, np.radians(0.5), 1e-3), body.mass, body.inertia)
    eps = local_errors(g, body, sol.problem.disc.force_frame)
    g = g.with_local_errors(eps)                         # the tracker feeds the same local errors forward
    nav = plan_filter(g, F, F0 @ F0.T, measurement_nodes(g.t, period), estimator, eps=eps)
    draws = np.random.default_rng(4).standard_normal((g.N, 12))
    per = Navigated(nav, g.tracker(), F, draws)
    old = fly(truth, X0, g.t, ClosedLoop(OpenLoop.of_controls(g.scheme, g.U), per), act, law_inertia=body.inertia)
    one = NavigatedLoop(TrackingLoop.of_gains(g), nav, F, draws)
    new = fly(truth, X0, g.t, one, act, law_inertia=body.inertia)
    dX = np.max(np.abs(new.X - old.X) / np.abs(old.X).max(axis=0))
    dc = max(np.abs(new.command_start - old.command_start).max(), np.abs(new.command_end - old.command_end).max())
    dc /= np.abs(old.command_start).max()
    de = np.abs(one.errors - np.array(per.errors)).max() / np.abs(np.array(per.errors)).max()
    print(f"{estimator}, period {period}: states {dX:.1e}, commands {dc:.1e}, estimation errors {de:.1e} relative")
    assert dX <= 1e-10 and dc <= 1e-10 and de <= 1e-10
    assert np.abs(np.array(per.errors)).max() > 1e-6                      # the noise was there


def test_the_bounded_slew_with_attitude_noise():
    """The time-optimal slew (bounds margin 0.1: the tracker limits its corrections, so the per-interval law flies),
    2 % torque and 1 % inertia errors, attitude measured with 0.005 deg noise (rates exact), 4 runs: the EKF's RMS
    attitude error below 0.4 of the raw measurement's (sqrt(3) 0.005 deg; measured 0.18), its mean NEES per
    component between 0.3 and 2 (measured 0.56), and the LQR fed by it ends within 0.003 deg (measured 9.2e-4 deg) and
    every run's rate miss below the median run's fed by the raw measurement (measured 8.7e-6 vs 1.8e-4 rad/s)."""
    from se3ocp.problems.flight import fly

    man = maneuver("slew_time_optimal", None, None, "control.bounds_margin=0.1")
    block = {"errors": {"moment_scale": 0.02, "inertia_scale": 0.01}, "runs": 4, "seed": 2, "feedback": "lqr"}
    ekf = fly(man, {**block, "navigation": {"noise": {"attitude_deg": 0.005}}}).statistics()["lqr"]
    raw = fly(man, {**block, "navigation": {"noise": {"attitude_deg": 0.005}, "estimator": "none"}}).statistics()["lqr"]
    assert ekf["estimation_attitude_deg"]["max"] <= 0.4 * np.sqrt(3) * 0.005
    assert 0.3 <= ekf["estimation_nees"]["mean"] <= 2.0
    assert ekf["attitude_miss_deg"]["max"] <= 0.003 and ekf["rate_miss"]["max"] < raw["rate_miss"]["p50"]
    assert ekf["estimation_position"]["max"] == 0.0 and ekf["estimation_rate"]["max"] == 0.0      # measured exactly


@pytest.mark.slow
def test_cli_flies_navigation_and_refuses_a_bad_block(tmp_path):
    """Slow (~6 s: a flight with its figures and a CLI subprocess)."""
    import json
    import subprocess
    import sys

    from support import ROOT, config

    f = tmp_path / "flight.yaml"
    f.write_text(json.dumps({"flight": {"errors": {"initial": {"position": 1e-4}}, "runs": 2, "seed": 1,
                                        "navigation": {"noise": {"position": 1e-4, "attitude_deg": 0.01},
                                                       "period": 0.0125}}}))
    out = tmp_path / "o"
    from se3ocp.problems.cli import main
    assert main(["fly", str(config("e3")), "--set", "horizon.N=40", "--set", "discretization=lgvi", "--flight", str(f),
                 "--workers", "1", "--out", str(out), "--quiet"]) == 0
    header = (out / "flights.csv").read_text().splitlines()[0].split(",")
    assert header.index("rate_miss") < header.index("estimation_position") < header.index("estimation_nees")
    s = json.loads((out / "summary.json").read_text())
    assert s["statistics"]["lqr"]["estimation_position"]["n"] == 2 and s["statistics"]["none"]["estimation_position"]["n"] == 0
    assert s["flight"]["navigation"]["period"] == 0.0125
    html = (out / "report.html").read_text()
    assert "navigation: RMS attitude estimate error" in html and 'id="fig-flight_navigation"' in html
    assert (out / "flight_navigation.png").is_file()
    f.write_text(json.dumps({"flight": {"navigation": {"noise": {"attitude": 0.01}}}}))
    r = subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", "fly", str(config("e3")), "--flight", str(f),
                        "--out", str(tmp_path / "bad")], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and not (tmp_path / "bad").exists()
    assert r.stderr.strip().count("\n") == 0 and str(f) in r.stderr and "flight.navigation.noise.attitude: unknown key" in r.stderr


@pytest.mark.slow
def test_navigation_flights_on_dask_are_the_serial_flights():
    """Slow (~15 s: a Dask LocalCluster of 2 processes).  E3 at N = 40 with navigation noise, 4 runs, open loop and
    LQR: the rows (misses, estimation errors) flown on Dask equal the in-process ones exactly (each run's noise from
    its own seed, the estimator built in the worker)."""
    distributed = pytest.importorskip("distributed")
    from se3ocp.problems.flight.run import run_flights
    from se3ocp.problems.sweep.executors import DaskExecutor, SerialExecutor

    man, sol, _ = e3_gains()
    spec = parse_flight({"truth": {"gravity": {"kind": "j2", "J2": 1.08e-3, "radius": 0.9}},
                         "errors": {"initial": {"position": 1e-4}, "force_scale": 0.02}, "runs": 4, "seed": 5,
                         "navigation": {"noise": {"position": 1e-4, "velocity": 1e-4, "attitude_deg": 0.01,
                                                  "angular_velocity": 1e-4}}})
    serial = run_flights(man, sol, spec, executor=SerialExecutor())
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, protocol="tcp") as cluster:
        ex = DaskExecutor(cluster.scheduler_address)
        try:
            dask = run_flights(man, sol, spec, executor=ex)
        finally:
            ex.shutdown()
    import json

    assert dask.executor == "dask" and not dask.failed
    assert json.dumps(serial.rows) == json.dumps(dask.rows)           # NaN (open loop's estimation errors) as NaN
    assert all(r["estimation_position"] > 0 for r in serial.rows if r["feedback"] == "lqr")
