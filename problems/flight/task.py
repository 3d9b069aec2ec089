"""The unit of work of a Monte Carlo flight: :func:`fly_runs`, a few runs flown from plain data to plain
data (so that it runs in another process or on a Dask worker), and the figures of merit of one flight."""
from __future__ import annotations

import json
import math
from dataclasses import replace
from functools import partial

import numpy as np

from ...transcription.dynamics.lgvi import two_point
from ...transcription.dynamics.flight import ClosedLoop, FlightError, OpenLoop, fly
from ...transcription.results.check import margin_keys
from ...transcription.closedloop.loop import TrackingLoop
from ...transcription.closedloop.actuated import fly_actuated
from ...transcription.geometry.state import X_POS, X_ROT
from ...transcription.geometry.so3 import log_so3, nearest_rotation
from ...transcription.closedloop.mpc import Replanner, Replanning
from ...transcription.dynamics.trajectory import Trajectory
from ...transcription.results.solution import rotation_angle
from ...transcription.closedloop.estimator import local_errors
from ...transcription.closedloop.tracking import saturate, sub_stepped, tracking_gains
from ..elements import ELEMENT_DIFFERENCES, element_differences
from ..elements import rtn
from .actuators import pulses_of, truth_axes, wheels_of
from .basilisk import fly_basilisk
from .forces import truth_forces
from .navigation import ESTIMATION_METRICS, estimation_metrics, navigated
from .plan import load_plan, run_seeds, sample_errors, truth_body, truth_model
from .schema import parse_flight

#: the figures of merit of a flight (flights.csv, after run, feedback, status), in this order
METRICS = ("position_miss", "miss_r", "miss_t", "miss_n", "velocity_miss", "attitude_miss_deg", "attitude_x_deg",
           "attitude_y_deg", "attitude_z_deg", "rate_miss", "delta_v", "delta_v_overhead", "delta_v_commanded",
           "delta_v_commanded_overhead", "angular_impulse", "peak_force", "peak_moment", "saturated_fraction",
           "max_position_deviation", "max_attitude_deviation_deg")
#: the terminal misses in osculating elements about the central body (flown minus plan; only with a central body):
#: a (length unit), e, i, Ω, u = ω + ν (deg; problems.elements.element_differences)
ELEMENT_METRICS = tuple(f"miss_{k}" for k, _, _ in ELEMENT_DIFFERENCES)
#: an MPC flight's re-plans (flights.csv; timings, so not among the statistics)
MPC_COLUMNS = ("replans", "replans_rejected", "replan_ms_median", "replan_ms_max", "prepare_ms_median")
#: the sampled errors reported with each flight (flights.csv)
ERROR_COLUMNS = ("force_scale", "moment_scale", "force_misalignment_deg", "moment_misalignment_deg",
                 "inertia_scale_1", "inertia_scale_2", "inertia_scale_3")

_GAINS: dict = {}


def gains_of(payload: dict, weights: dict, sub_steps: bool = False):
    """The plan's tracker (transcription.closedloop.tracking), built once per process and plan; ``sub_steps``: the LQR flight's,
    on the plan with the long steps of a non-uniform mesh split (transcription.closedloop.tracking.sub_stepped: the tracker
    corrects inside them; the plan's own on a uniform mesh), with the plan's local errors on its own body's continuous
    equations fed forward (transcription.closedloop.tracking.Gains.with_local_errors)."""
    key = (payload["key"], json.dumps(weights, sort_keys=True), bool(sub_steps))
    if key not in _GAINS:
        if len(_GAINS) >= 8:
            _GAINS.clear()
        _, sol = load_plan(payload)
        gains = tracking_gains(sub_stepped(sol) if sub_steps else sol, weights)
        problem = sol.problem
        _GAINS[key] = gains.with_local_errors(local_errors(gains, problem.model, problem.disc.force_frame))
    return _GAINS[key]


def miss_frame(X_N: np.ndarray, mass: float) -> str:
    """The frame the position miss is given in: the target orbit's RTN frame at the plan's final state
    (problems.elements.rtn: radial, along-track, normal), or the inertial axes where the body does
    not move about a centre (x x v = 0)."""
    x, v = X_N[X_POS], X_N[3:6] / mass
    n = np.linalg.norm(np.cross(x, v))
    return "RTN" if n > 1e-12 * np.linalg.norm(x) * np.linalg.norm(v) and n > 0 else "inertial"


def miss_components(X_N: np.ndarray, mass: float, dx: np.ndarray) -> np.ndarray:
    """The position miss dx (3,) in :func:`miss_frame`."""
    if miss_frame(X_N, mass) == "inertial":
        return np.asarray(dx, float)
    return rtn(X_N[None, X_POS], X_N[None, 3:6] / mass, np.asarray(dx, float)[None, :])[0]


def metric_keys(problem, navigation: bool = False) -> tuple:
    """The figures of merit of a flight of ``problem``'s plan: METRICS, the estimation errors with ``navigation``
    (problems.flight.navigation.ESTIMATION_METRICS), the element misses (ELEMENT_METRICS) with a central body, and
    the margins of its path constraints."""
    orbit = ELEMENT_METRICS if problem.model.mu else ()
    return METRICS + (ESTIMATION_METRICS if navigation else ()) + orbit + tuple(margin_keys(problem.constraints))


def element_misses(mu: float | None, X_N: np.ndarray, mass: float, x: np.ndarray, v: np.ndarray) -> dict:
    """ELEMENT_METRICS of a flown terminal position x and velocity v (inertial) against the plan's last state X_N (18)
    of a body of ``mass``, about GM ``mu``: {} without a central body, NaN where the plan does not move about it
    (:func:`miss_frame` inertial: no orbit plane)."""
    if not mu:
        return {}
    if miss_frame(X_N, mass) == "inertial":
        return dict.fromkeys(ELEMENT_METRICS, math.nan)
    d = element_differences(mu, x, v, X_N[X_POS], X_N[3:6] / mass)
    return {f"miss_{k}": float(d[k]) for k, _, _ in ELEMENT_DIFFERENCES}


def impulse(control_t: np.ndarray, u: np.ndarray) -> float:
    """sum over intervals of the trapezoidal integral of |u| over the samples: control_t (N, M+1), u (N, M+1, 3)."""
    n = np.linalg.norm(u, axis=-1)
    return float(np.sum(0.5 * (n[:, 1:] + n[:, :-1]) * np.diff(control_t, axis=1)))


def plan_usage(gains, samples: int) -> tuple[float, float]:
    """(delta-v, angular impulse) of the plan's commands with exact actuators, by the quadrature of :func:`impulse`
    on ``samples`` samples per interval (so that a flight's overhead compares like with like)."""
    a, b = gains.U[:, :-1].T, gains.U[:, 1:].T
    if not two_point(gains.scheme):
        a = b = gains.U.T
    s = np.arange(samples + 1) / samples
    u = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
    t = gains.t[:-1, None] + s[None, :] * np.diff(gains.t)[:, None]
    return impulse(t, u[:, :, :3]), impulse(t, u[:, :, 3:])


def flight_metrics(flight, plan, tracker, usage: tuple, constraints) -> tuple[dict, dict]:
    """The figures of merit (:func:`metric_keys`) of one flight against the plan's nodes, and its track (the
    position and attitude deviation at the nodes).  Misses are against the plan's last node: position and
    velocity (inertial; the position's components in :func:`miss_frame`), the attitude angle and rotation vector
    vee log(R_N^T R(T)) (body, deg), the rate |Omega(T) - Omega_N| (the truth's inertia), the osculating
    elements (:func:`element_misses`).  delta_v: the integral of |u_f|/m applied by the actuators,
    delta_v_commanded: of the commands (both by :func:`impulse` over the samples), their overheads over the
    plan's (``usage``)."""
    X = flight.X.copy()
    R = nearest_rotation(flight.trajectory().R)
    X[:, X_ROT] = np.swapaxes(R, -1, -2).reshape(-1, 9)
    flown = Trajectory(t=flight.t, X=X, mass=flight.mass, inertia=flight.inertia)
    tr = plan.trajectory
    k = np.searchsorted(flight.t, tr.t)      # the plan's nodes among the samples (an LQR flight may have more nodes)
    dx = flown.x[k] - tr.x
    dR = np.degrees(rotation_angle(np.einsum("kji,kjl->kil", tr.R, flown.R[k])))
    att = np.degrees(log_so3(tr.R[-1].T @ flown.R[-1]))
    m = flight.mass
    dv, ang = impulse(flight.control_t, flight.control[..., :3]) / m, impulse(flight.control_t, flight.control[..., 3:])
    s = (flight.control_t - flight.control_t[:, :1]) / np.diff(flight.control_t[:, [0, -1]], axis=1)
    cmd = flight.command_start[:, None, :3] + s[..., None] * (flight.command_end - flight.command_start)[:, None, :3]
    dvc = impulse(flight.control_t, cmd) / m
    comp = miss_components(tr.X[-1], tr.mass, dx[-1])
    out = dict(position_miss=float(np.linalg.norm(dx[-1])), **dict(zip(("miss_r", "miss_t", "miss_n"), comp)),
               velocity_miss=float(np.linalg.norm(flown.v[-1] - tr.v[-1])), attitude_miss_deg=float(dR[-1]),
               **dict(zip(("attitude_x_deg", "attitude_y_deg", "attitude_z_deg"), att)),
               rate_miss=float(np.linalg.norm(flown.Omega[-1] - tr.Omega[-1])), delta_v=dv,
               delta_v_overhead=dv / usage[0] * m - 1.0 if usage[0] > 0 else math.nan, delta_v_commanded=dvc,
               delta_v_commanded_overhead=dvc / usage[0] * m - 1.0 if usage[0] > 0 else math.nan, angular_impulse=ang,
               peak_force=float(np.linalg.norm(flight.control[..., :3], axis=-1).max()),
               peak_moment=float(np.linalg.norm(flight.control[..., 3:], axis=-1).max()),
               saturated_fraction=tracker.saturated_fraction if tracker is not None else 0.0,
               max_position_deviation=float(np.linalg.norm(dx, axis=1).max()), max_attitude_deviation_deg=float(dR.max()))
    out.update(element_misses(plan.problem.model.mu, tr.X[-1], tr.mass, flown.x[-1], flown.v[-1]))
    out.update({key: float(np.min(c.margin(flown))) for key, c in zip(margin_keys(constraints), constraints)})
    out = {key: float(v) for key, v in out.items()}
    return out, {"dx": np.linalg.norm(dx, axis=1), "dR_deg": dR}


def error_columns(err, plan_inertia: np.ndarray) -> dict:
    """The sampled errors of a run as ERROR_COLUMNS: scale factors, misalignment angles (deg), and the
    relative change of each diagonal inertia entry."""
    a = err.actuators
    out = {"force_scale": a.force_scale, "moment_scale": a.moment_scale,
           "force_misalignment_deg": float(np.degrees(rotation_angle(a.force_misalignment))),
           "moment_misalignment_deg": float(np.degrees(rotation_angle(a.moment_misalignment)))}
    scale = np.diag(err.inertia) / np.diag(np.asarray(plan_inertia, float)) - 1.0
    out.update({f"inertia_scale_{i + 1}": float(s) for i, s in enumerate(scale)})
    return out


def truth_engine(spec, gravity: dict | None):
    """The continuous engine that flies a run: transcription.dynamics.flight.fly (CVODES), or Basilisk's spacecraft
    (problems.flight.basilisk.fly_basilisk) for ``spec.integrator`` basilisk, given the truth's gravity block
    ``gravity`` ({kind, J2, radius}: Basilisk's own gravity; None: point mass)."""
    if spec.integrator != "basilisk":
        return fly
    g = gravity or {"kind": "point_mass"}
    return partial(fly_basilisk, substeps=spec.substeps, j2=(g["J2"], g["radius"]) if g["kind"] == "j2" else None)


def fly_one(plan, gains, spec, err, base, mode: str, lqr=None, forces=None, payload=None, wheel_axes=None,
            engine=fly):
    """One flight of a run's errors ``err`` in feedback ``mode`` -> (Flight, what reports the saturated fraction
    (the tracker, the re-planning law) or None, the re-planning law or None, the navigated law or None, the
    actuators' figures (PULSE_COLUMNS; {} without on/off thrusters or wheels: spec.actuators,
    transcription.closedloop.actuated)).  ``lqr``: the LQR flight's tracker (:func:`gains_of` with sub_steps;
    default ``gains``), flown over its own node times.  ``forces``: the truth's forces besides gravity
    (problems.flight.forces.truth_forces; None: none).  With ``spec.navigation`` the LQR reads the estimate of the
    measured state (problems.flight.navigation; ``payload``: the plan's, problems.flight.plan.plan_payload);
    ``wheel_axes``: the run's truth wheel axes (3, n; problems.flight.actuators.truth_axes); ``engine``: the
    continuous engine (:func:`truth_engine`; the actuators' flights are CVODES's)."""
    if mode == "lqr" and lqr is not None:
        gains = lqr
    law = OpenLoop.of_controls(gains.scheme, gains.U)
    tracker = nav = None
    if mode == "mpc":
        o = spec.mpc
        law = tracker = Replanning(Replanner(plan.problem, gains.h, o["iterations"]), plan.warm, o["replan_every"],
                                   o["min_horizon"], gains if o["between"] == "lqr" else None)
    pulses, wheels = pulses_of(spec.actuators, plan.problem), wheels_of(spec.actuators)
    one_call = engine is fly and pulses is None and wheels is None   # a law the CVODES flight evaluates in one call
    if mode == "lqr":
        if wheels is not None:       # the wheels' limits are their own (their controller clips; the tracker told)
            gains = replace(gains, moment_bound=None)
        tracker = gains.tracker()
        clip = (lambda u: saturate(u, gains.force_bound, gains.moment_bound)[0]) if tracker.bounded else None
        one_call = one_call and not tracker.bounded           # nothing to limit: the law inside the flight, one call
        if spec.navigation is not None:
            nav = navigated(payload, gains, tracker, spec, err, plan.problem, one_call)
        if one_call:
            law = TrackingLoop.of_gains(gains) if nav is None else nav
        else:                                                  # clip: a plan's round-off only
            law = ClosedLoop(law, nav if nav is not None else lambda k, t, X: tracker.correction(k, X), clip)
    truth, J_law = truth_model(base, err.inertia), plan.problem.model.inertia   # the rate measured, the plan's J
    if pulses is not None or wheels is not None:
        run = fly_actuated(truth, err.X0, gains.t, law, pulses, wheels, err.actuators, spec.samples, forces, J_law,
                           tracker if mode == "lqr" else None, wheel_axes)
        return run.flight, tracker, law if mode == "mpc" else None, nav, run.summary()
    flight = engine(truth, err.X0, gains.t, law, err.actuators, samples=spec.samples, disturbance=forces,
                    law_inertia=J_law)
    return flight, tracker, law if mode == "mpc" else None, nav, {}


def replan_columns(law) -> dict:
    """An MPC flight's re-plans (MPC_COLUMNS): how many, how many rejected, median and largest solve time (ms)."""
    if law is None:
        return {}
    ms, prep = 1e3 * law.solve_times, 1e3 * law.prepare_times
    return {"replans": len(ms), "replans_rejected": law.rejected,
            "replan_ms_median": float(np.median(ms)) if ms.size else math.nan,
            "replan_ms_max": float(ms.max()) if ms.size else math.nan,
            "prepare_ms_median": float(np.median(prep)) if prep.size else math.nan}


def fly_runs(task: dict) -> dict:
    """Some runs of a Monte Carlo flight: the unit of work sent to a pool or a Dask cluster.

    task: {'plan': problems.flight.plan.plan_payload, 'flight': the resolved flight block, 'source': its
    name, 'runs': [run indices], 'tracks': runs below this index return their node deviations and
    controls (figures), 'save': runs below this index return their whole flights (runs/NNNN.npz)}.
    Returns {'rows': [one dict per run and feedback mode], 'tracks': {run: {mode: arrays}},
    'saved': {run: arrays}, 'replan_s': {run: the MPC flight's re-plan times (s): [solve, prepare] each}}.  A flight that fails is
    a row (status 'failed'), never an exception."""
    man, plan = load_plan(task["plan"])
    spec = parse_flight(task["flight"], task["source"])
    gains = gains_of(task["plan"], spec.weights)
    lqr = gains_of(task["plan"], spec.weights, sub_steps=True) if "lqr" in spec.modes else None
    base, forces = truth_body(man, spec), truth_forces(man, spec.resolved["truth"])
    engine = truth_engine(spec, spec.gravity or man.resolved.get("gravity"))
    seeds = run_seeds(spec)
    usage = plan_usage(gains, spec.samples)
    rows, tracks, saved, replan_s = [], {}, {}, {}
    for i in task["runs"]:
        err = sample_errors(spec, i, seeds[i], plan.trajectory.X[0], man.problem.model.mass, man.problem.model.inertia,
                            man.problem.disc.force_frame)
        cols = error_columns(err, man.problem.model.inertia)
        axes = truth_axes(spec.actuators, seeds[i])
        if i < task.get("save", 0):
            saved[i] = err.arrays()
        for mode in spec.modes:
            row = {"run": i, "feedback": mode, "status": "ok", "message": ""}
            try:
                flight, tracker, mpc, nav, pulsed = fly_one(plan, gains, spec, err, base, mode, lqr, forces,
                                                            task["plan"], axes, engine)
                metrics, track = flight_metrics(flight, plan, tracker, usage, man.problem.constraints)
                metrics.update(pulsed)
                metrics.update(replan_columns(mpc))
                if spec.navigation is not None:
                    metrics.update(estimation_metrics(nav, man.problem.model.mass, man.problem.model.inertia)
                                   or dict.fromkeys(ESTIMATION_METRICS, math.nan))
                if mpc is not None:
                    replan_s[i] = np.column_stack([mpc.solve_times, mpc.prepare_times]).tolist()
            except (FlightError, ValueError, np.linalg.LinAlgError) as e:
                rows.append({**row, "status": "failed", "message": " ".join(str(e).split())[:500], **cols})
                continue
            rows.append({**row, **metrics, **cols})
            if i < task.get("tracks", 0):
                tracks.setdefault(i, {})[mode] = {**track, "control_t": flight.control_t, "control": flight.control}
            if i in saved:
                saved[i].update({f"{mode}_{k}": v for k, v in (
                    ("t", flight.t), ("X", flight.X), ("command_start", flight.command_start),
                    ("command_end", flight.command_end), ("control_t", flight.control_t), ("control", flight.control))})
    return {"rows": rows, "tracks": tracks, "saved": saved, "replan_s": replan_s}
