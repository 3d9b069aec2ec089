"""Running a Monte Carlo flight on any executor of the sweep machinery, and its statistics."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ...transcription.closedloop.mpc import checked_constraints, polished
from ..maneuvers import Maneuver
from ..sweep.executors import Executor, make_executor
from .actuators import actuator_keys
from .basilisk import basilisk_text
from .forces import j2_plane_drift
from .plan import plan_payload
from .schema import FlightSpec, truth_from_preset
from .task import fly_runs, gains_of, metric_keys, miss_frame, plan_usage

#: the percentiles of summary.json (p99.7: the 3-sigma level of a Gaussian)
PERCENTILES = {"p50": 50.0, "p95": 95.0, "p99_7": 99.7}
#: runs whose node deviations and controls are kept for the figures
TRACKS = 20
#: the most runs in one task (fewer when there are few runs per worker: every worker gets several tasks)
MAX_CHUNK = 25


@dataclass
class FlightResult:
    """A Monte Carlo flight: rows (one per run and feedback mode, sorted), tracks and saved flights of
    the first runs, the plan's figures, the tracker, where and how long it ran."""

    maneuver: Maneuver
    spec: FlightSpec
    plan: dict
    gains: object
    rows: list
    tracks: dict = field(default_factory=dict)
    saved: dict = field(default_factory=dict)
    replan_s: dict = field(default_factory=dict)
    executor: str = "serial"
    workers: int | None = 1
    lqr_gains: object = None      # the LQR flights' tracker when it is not ``gains`` (a non-uniform plan's sub-steps)
    mpc_warm_start: str = ""      # which costates the re-plans start from (transcription.closedloop.mpc.polished)
    wall_s: float = 0.0
    interrupted: bool = False
    #: said before flying (problems.flight.forces.j2_plane_drift: no feedback can hold the plan), '' when nothing
    plane_drift: str = ""

    @property
    def metrics(self) -> tuple:
        return metric_keys(self.maneuver.problem, self.spec.navigation is not None) + actuator_keys(self.spec.actuators)

    @property
    def finished_runs(self) -> int:
        return len({r["run"] for r in self.rows})

    @property
    def failed(self) -> int:
        return sum(r["status"] != "ok" for r in self.rows)

    def statistics(self) -> dict:
        """{mode: {metric: {mean, p50, p95, p99_7, max, n}}} over the flights that finished (rows in
        run order: the same numbers whatever the workers)."""
        out = {}
        for mode in self.spec.modes:
            ok = [r for r in self.rows if r["feedback"] == mode and r["status"] == "ok"]
            out[mode] = {m: describe(np.array([r[m] for r in ok], dtype=float)) for m in self.metrics}
        return out

    def summary(self) -> dict:
        stats = self.statistics()
        out = {"name": self.maneuver.name, "config": self.maneuver.source, "plan": self.plan,
               "flight": self.spec.resolved, "runs": self.spec.runs, "finished_runs": self.finished_runs,
               "failed_flights": self.failed, "interrupted": self.interrupted, "executor": self.executor,
               "workers": self.workers, "wall_s": self.wall_s,
               "tracking": {"scales": self.gains.weights.scales, "removed": list(self.gains.removed)},
               "statistics": stats}
        for mode, key in (("lqr", "closed_over_open"), ("mpc", "mpc_over_open")):
            if {"none", mode} <= set(stats):
                out[key] = p95_ratios(stats["none"], stats[mode])
        out["worse_than_open"] = worse_than_open(out)
        if self.plane_drift:
            out["plane_drift"] = self.plane_drift
        if "mpc" in stats:
            out["mpc"] = self.replan_summary()
        taken = truth_from_preset(self.spec.gravity, self.maneuver.physical)
        if taken:
            out["truth_from_preset"] = taken
        if self.spec.integrator == "basilisk":
            out["truth_engine"] = basilisk_text(self.spec.substeps)
        return out

    def replan_summary(self) -> dict:
        """The re-planning options and every re-plan's times (ms) pooled over the finished runs -- from the flown
        state to the new plan (``solve_ms``) and the preparation before it (``prepare_ms``): median, p95, max --
        and how many (summary.json ``mpc``; timings, so not among the statistics); the path constraints the re-plans
        check on their predicted nodes (transcription.closedloop.mpc.checked_constraints)."""
        ms = 1e3 * np.array([t for run in sorted(self.replan_s) for t in self.replan_s[run]], float).reshape(-1, 2)
        rejected = sum(int(r.get("replans_rejected", 0)) for r in self.rows if r["feedback"] == "mpc")
        checked = [f"{c.kind} {c.limit:.6g}" for c in checked_constraints(self.maneuver.problem)]
        return {**self.spec.mpc, "replans": int(ms.shape[0]), "rejected": rejected, "solve_ms": timing(ms[:, 0]),
                "prepare_ms": timing(ms[:, 1]), "checked_constraints": checked, "warm_start": self.mpc_warm_start}


def timing(ms: np.ndarray) -> dict:
    """median, p95 and max of some times (None where there are none)."""
    if ms.size == 0:
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(ms)), "p95": float(np.percentile(ms, 95)), "max": float(ms.max())}


def p95_ratios(open_loop: dict, closed: dict) -> dict:
    """closed p95 / open-loop p95 of the terminal misses (None where undefined)."""
    ratio = {}
    for m in ("position_miss", "velocity_miss", "attitude_miss_deg", "rate_miss"):
        a, b = open_loop[m]["p95"], closed[m]["p95"]
        ratio[f"{m}_p95"] = b / a if a and math.isfinite(a) and b is not None and math.isfinite(b) else None
    return ratio


def worse_than_open(summary: dict) -> list[str]:
    """The sentences saying where a closed loop ends farther from the plan than open loop (its p95 terminal miss over
    open loop's > 1, from ``closed_over_open`` / ``mpc_over_open`` of :meth:`Flights.summary`): one per mode, naming
    the misses and their ratios; [] when feedback helps (or only one mode was flown)."""
    out = []
    for mode, key in (("LQR", "closed_over_open"), ("MPC", "mpc_over_open")):
        worse = {m[:-len("_p95")]: r for m, r in summary.get(key, {}).items() if r is not None and r > 1.0}
        if worse:
            said = ", ".join(f"{m} x{r:.3g}" for m, r in worse.items())
            out.append(f"{mode} ends farther from the plan than open loop (p95 over open loop's: {said}): the feedback "
                       f"makes these flights worse; check the tracking weights, the actuators' saturation and whether "
                       f"the truth's forces (J2, drag) are in the plan")
    return out


def describe(a: np.ndarray) -> dict:
    """mean, the PERCENTILES, max and n of the finite values of ``a`` (None where there are none)."""
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"mean": None, **{k: None for k in PERCENTILES}, "max": None, "n": 0}
    return {"mean": float(a.mean()), **{k: float(np.percentile(a, q)) for k, q in PERCENTILES.items()},
            "max": float(a.max()), "n": int(a.size)}


def plan_figures(sol, gains, spec: FlightSpec) -> dict:
    """The plan's own numbers in summary.json: method, scheme, N, T and its delta-v and angular impulse
    (the quadrature the flights use); on a non-uniform mesh its shortest and longest steps (h_min, h_max)."""
    dv, ang = plan_usage(gains, spec.samples)
    mesh = {} if gains.steps is None else {"h_min": float(gains.steps.min()), "h_max": float(gains.steps.max())}
    return {"method": sol.method, "discretization": gains.scheme, "N": int(gains.N), "T": float(gains.t[-1]),
            **mesh, "delta_v": dv / sol.trajectory.mass, "angular_impulse": ang,
            "bounds_margin": float(sol.problem.control.bounds_margin),
            "miss_frame": miss_frame(sol.trajectory.X[-1], sol.trajectory.mass)}


def run_flights(man: Maneuver, sol, spec: FlightSpec, *, workers: int | None = None, scheduler: str | None = None,
                executor: Executor | None = None, save_runs: int = 0,
                progress: Callable[[int, int], None] | None = None,
                check_interrupt: Callable[[], None] | None = None) -> FlightResult:
    """Fly ``spec.runs`` runs of the plan ``sol`` (a converged smooth-control Solution of ``man``) in each
    feedback mode, in tasks of a few runs on the executor (in-process, local pool, Dask).

    save_runs: the first runs whose whole flights are kept (runs/NNNN.npz).  progress(done, total) after
    each task (runs).  With MPC the re-plans start from the plan's costates polished by the indirect method
    (transcription.closedloop.mpc.polished).  On KeyboardInterrupt the workers are stopped and the exception carries the runs
    finished so far as ``exc.partial`` (a FlightResult with ``interrupted``)."""
    sol, warm = polished(sol) if "mpc" in spec.modes else (sol, "")
    payload = plan_payload(man, sol)
    gains = gains_of(payload, spec.weights)
    res = FlightResult(man, spec, plan_figures(sol, gains, spec), gains, [], mpc_warm_start=warm,
                       plane_drift=j2_plane_drift(man, sol, spec.gravity))
    if "lqr" in spec.modes and gains.steps is not None:
        res.lqr_gains = gains_of(payload, spec.weights, sub_steps=True)
    ex = executor or make_executor(workers, scheduler)
    res.executor, res.workers = ex.kind, ex.workers
    per = max(1, min(MAX_CHUNK, math.ceil(spec.runs / (4 * (ex.workers or 8)))))
    chunks = [list(range(i, min(i + per, spec.runs))) for i in range(0, spec.runs, per)]
    base = {"plan": payload, "flight": spec.resolved, "source": man.source, "tracks": TRACKS, "save": save_runs}
    t0, done = time.perf_counter(), 0
    pending = {}
    try:
        for c in chunks:
            pending[ex.submit(fly_runs, {**base, "runs": c})] = c
            if check_interrupt:
                check_interrupt()
        while pending:
            for f in ex.wait_first(pending):
                c = pending.pop(f)
                _collect(res, c, f, spec)
                done += len(c)
                if progress:
                    progress(done, spec.runs)
            if check_interrupt:
                check_interrupt()
    except KeyboardInterrupt as exc:
        ex.shutdown(cancel=True)
        res.interrupted, res.wall_s = True, time.perf_counter() - t0
        res.rows.sort(key=lambda r: (r["run"], spec.modes.index(r["feedback"])))
        exc.partial = res
        raise
    if executor is None:
        ex.shutdown()
    res.wall_s = time.perf_counter() - t0
    res.rows.sort(key=lambda r: (r["run"], spec.modes.index(r["feedback"])))
    return res


def _collect(res: FlightResult, runs: list, fut, spec: FlightSpec) -> None:
    """A finished task's rows, tracks and saved flights into ``res`` (a task whose worker died: failed rows)."""
    try:
        out = fut.result()
    except Exception as exc:  # noqa: BLE001 - the worker itself died (a failing flight is a row)
        msg = f"worker failed: {type(exc).__name__}: {' '.join(str(exc).split())}"[:500]
        res.rows += [{"run": i, "feedback": m, "status": "failed", "message": msg} for i in runs for m in spec.modes]
        return
    res.rows += out["rows"]
    res.tracks.update(out["tracks"])
    res.saved.update(out["saved"])
    res.replan_s.update(out.get("replan_s", {}))
