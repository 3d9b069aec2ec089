"""What a Monte Carlo flight writes, each file atomically: flights.csv, summary.json, flight.resolved.yaml,
config.resolved.yaml, plan.npz (the plan flown), gains.npz (its tracker; lqr_* the LQR flights' on the sub-stepped plan of a
non-uniform mesh, transcription.closedloop.tracking.sub_stepped), runs/NNNN.npz, the figures and
report.html (problems/flight/report.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import write_csv, write_json, write_npz, write_yaml
from .report import write_flight_report
from .run import FlightResult
from .task import ERROR_COLUMNS, MPC_COLUMNS


def columns(result: FlightResult) -> list[str]:
    """flights.csv's columns: run, feedback, status, the figures of merit, the re-plans (with MPC), the sampled
    errors, message (the figures include the actuators' with on/off thrusters or wheels: task.metric_keys)."""
    mpc = MPC_COLUMNS if "mpc" in result.spec.modes else ()
    return ["run", "feedback", "status", *result.metrics, *mpc, *ERROR_COLUMNS, "message"]


def write_flights(out: Path, result: FlightResult, plan_arrays: dict, figures: bool = True) -> list[Path]:
    """Every file of a flight into ``out``; summary.json last."""
    out = Path(out)
    cols = columns(result)
    write_csv(out / "flights.csv", cols, result.rows)
    write_yaml(out / "flight.resolved.yaml", {"flight": result.spec.resolved})
    write_yaml(out / "config.resolved.yaml", result.maneuver.resolved)
    write_npz(out / "plan.npz", plan_arrays)
    g, lqr = result.gains, result.lqr_gains
    sub = {} if lqr is None else {f"lqr_{k}": getattr(lqr, k) for k in ("K", "L", "t", "X", "U")}   # sub-stepped
    write_npz(out / "gains.npz", {"K": g.K, "L": g.L, "t": g.t, "X": g.X, "U": g.U, "Q": g.weights.Q,
                                  "R": g.weights.R, "Q_N": g.weights.Q_N, **sub})
    written = [out / n for n in ("flights.csv", "flight.resolved.yaml", "config.resolved.yaml", "plan.npz", "gains.npz")]
    for i, arrays in sorted(result.saved.items()):
        p = out / "runs" / f"{i:04d}.npz"
        p.parent.mkdir(exist_ok=True)
        write_npz(p, {k: np.asarray(v) for k, v in arrays.items()})
        written.append(p)
    if figures and any(r["status"] == "ok" for r in result.rows):
        from .figures import draw_flights

        written += draw_flights(out, result)
    summary = result.summary()
    written.append(write_flight_report(out, summary))
    write_json(out / "summary.json", summary)
    return written + [out / "summary.json"]
