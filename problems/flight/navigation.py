"""Navigation in a Monte Carlo flight (the ``navigation:`` block): the plan's estimator (transcription.closedloop.
estimator, built once per process and plan), each run's measurement draws from its own seed, and the estimation
errors reported beside the misses (flights.csv)."""
from __future__ import annotations

import json

import numpy as np

from ...transcription.closedloop.estimator import Navigated, local_errors, measurement_nodes, noise_factor, plan_filter
from ...transcription.closedloop.loop import TrackingLoop
from ...transcription.closedloop.navloop import NavigatedLoop

#: the estimation errors of a flight with navigation (flights.csv, the statistics): RMS over the nodes the tracker
#: read of |x - x^|, |v - v^|, the attitude angle of R^T R^ (deg), |Omega - Omega^|, and the mean NEES per noisy
#: component (1 when the estimator's covariance is consistent with its errors)
ESTIMATION_METRICS = ("estimation_position", "estimation_velocity", "estimation_attitude_deg", "estimation_rate",
                      "estimation_nees")
#: the spawn key appended to a run's SeedSequence for its measurement noise (the other errors keep their draws)
NOISE_STREAM = 0

_FILTERS: dict = {}


def sigmas(block: dict) -> tuple:
    """(position, velocity, attitude (rad), rate) of a block of INITIAL_KEYS (problems.flight.schema)."""
    return block["position"], block["velocity"], np.radians(block["attitude_deg"]), block["angular_velocity"]


def filter_of(payload: dict, gains, spec, problem):
    """The estimator of the plan of ``gains`` (the tracker it feeds; ``problem`` the plan's Problem) for the flight
    ``spec``: the navigation noise, the prior of the initial errors (spec.errors.initial), the measurement nodes of
    ``period``, the plan's local errors on its body's continuous equations (those of ``gains``, which its tracker
    feeds forward), the bias's prior: (NavigationFilter, the
    noise factor F, the bias factor F_b) (transcription.closedloop.estimator.noise_factor); built once per process,
    plan and block."""
    nav = spec.navigation
    key = (payload["key"], id(gains), json.dumps(nav, sort_keys=True), json.dumps(spec.errors["initial"], sort_keys=True))
    if key not in _FILTERS:
        if len(_FILTERS) >= 8:
            _FILTERS.clear()
        model = problem.model
        mass, inertia = model.mass, model.inertia
        F0 = noise_factor(sigmas(spec.errors["initial"]), mass, inertia)
        F = noise_factor(sigmas(nav["noise"]), mass, inertia)
        Fb = noise_factor(sigmas(nav["bias"]), mass, inertia)
        eps = gains.eps if gains.eps is not None else local_errors(gains, model, problem.disc.force_frame)
        _FILTERS[key] = (plan_filter(gains, F, F0 @ F0.T, measurement_nodes(gains.t, nav.get("period")),
                                     nav["estimator"], eps=eps, Pc=Fb @ Fb.T), F, Fb, gains)   # gains: its id is in the key
    return _FILTERS[key][:3]


def navigated(payload: dict, gains, tracker, spec, err, problem, one_call: bool = True):
    """The tracker fed by the estimator for the run of ``err`` (problems.flight.plan.RunErrors), its measurement
    draws and then its constant bias from SeedSequence(entropy, spawn_key + (NOISE_STREAM,)) of the run's seed: flown
    in one call
    (transcription.closedloop.navloop.NavigatedLoop) with ``one_call``, else the per-interval law
    (transcription.closedloop.estimator.Navigated, the correction of a ClosedLoop: a tracker that limits its
    corrections, actuators, Basilisk)."""
    nav, F, Fb = filter_of(payload, gains, spec, problem)
    entropy, spawn_key = err.seed
    rng = np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(*spawn_key, NOISE_STREAM)))
    draws = rng.standard_normal((gains.N, 12))
    bias = Fb @ rng.standard_normal(12)
    if not one_call:
        return Navigated(nav, tracker, F, draws, bias)
    return NavigatedLoop(TrackingLoop.of_gains(gains, tracker.disturbance), nav, F, draws, bias)


def estimation_metrics(law, mass: float, inertia: np.ndarray) -> dict:
    """ESTIMATION_METRICS of a flight flown by ``law`` (:func:`navigated`'s; {} without navigation)."""
    if law is None:
        return {}
    e = np.array(law.errors, float)
    rms = lambda a: float(np.sqrt(np.mean(np.sum(a * a, axis=1))))          # noqa: E731
    noisy = int(np.count_nonzero(~law.nav.exact))
    return {"estimation_position": rms(e[:, 0:3]), "estimation_velocity": rms(e[:, 3:6]) / mass,
            "estimation_attitude_deg": float(np.degrees(rms(e[:, 6:9]))),
            "estimation_rate": rms(np.linalg.solve(np.asarray(inertia, float), e[:, 9:12].T).T),
            "estimation_nees": float(np.mean(law.nav.nees(e))) / noisy if noisy else float("nan")}
