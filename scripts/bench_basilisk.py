"""Issue 43's Basilisk figures: the project's CVODES truth against Basilisk's spacecraft (problems/flight/basilisk.py),
through the public API.  Needs the optional extra (pip install 'se3ocp[basilisk]').

    .venv/bin/python scripts/bench_basilisk.py [--case open|table|all] [--runs K] [--substeps N ...] [--workers K]

* ``open``: E3 with the LGVI at N = 400 flown open loop without errors, in both truths: the final differences
  (position and velocity relative to their magnitudes, attitude angle in rad, rate relative) at each ``--substeps``
  (default 8 16 32; issue 43 asks <= 1e-8) and the wall time of one flight in each;
* ``table``: the closed-loop Monte Carlo of configs/flights/e3_j2_thrust.yaml (J2, 2 % thrust, 0.5 deg misalignment,
  initial dispersions; open loop and LQR; ``--runs``, default 100, seed 1) in both truths: p95 (mean) of the terminal
  misses and the delta-v overhead, the largest per-run relative difference (the same runs are flown: the same
  seeds), and the p95's 95 % bootstrap interval over the CVODES runs (its Monte Carlo noise).

Timings are wall times (the plan is solved once, before).  Run on a quiet machine.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import se3ocp
from se3ocp.problems.flight import basilisk as bsk_truth, load_flight
from se3ocp.transcription.dynamics.flight import OpenLoop, fly
from se3ocp.transcription.results.solution import rotation_angle

ROOT = Path(__file__).resolve().parents[1]
E3 = (ROOT / "configs" / "e3_inclination_change.yaml", ["horizon.N=400", "discretization=lgvi"])
E3_FLIGHT = ROOT / "configs" / "flights" / "e3_j2_thrust.yaml"
KEYS = ("position_miss", "velocity_miss", "attitude_miss_deg", "rate_miss", "delta_v_overhead")


def plan():
    man = se3ocp.load(*E3)
    sol = se3ocp.solve(man, "direct")
    assert sol.converged, sol.message
    return man, sol


def open_loop(man, sol, substeps) -> None:
    law = OpenLoop.of_controls(man.problem.scheme, sol.controls)
    X0, t, model = sol.trajectory.X[0], sol.trajectory.t, man.problem.model
    t0 = time.perf_counter()
    ref = fly(model, X0, t, law).trajectory()
    print(f"CVODES: {time.perf_counter() - t0:.3f} s")
    for n in substeps:
        t0 = time.perf_counter()
        a = bsk_truth.fly_basilisk(model, X0, t, law, substeps=n).trajectory()
        el = time.perf_counter() - t0
        d = (np.linalg.norm(a.x[-1] - ref.x[-1]) / np.linalg.norm(ref.x[-1]),
             np.linalg.norm(a.v[-1] - ref.v[-1]) / np.linalg.norm(ref.v[-1]),
             float(rotation_angle(ref.R[-1].T @ a.R[-1])),
             np.linalg.norm(a.Omega[-1] - ref.Omega[-1]) / np.linalg.norm(ref.Omega[-1]))
        print(f"Basilisk, {n:3d} steps per interval: {el:6.2f} s; position {d[0]:.2e}, velocity {d[1]:.2e}, "
              f"attitude {d[2]:.2e} rad, rate {d[3]:.2e}")


def table(man, sol, runs: int, substeps: int, workers: int) -> None:
    spec = load_flight(E3_FLIGHT, man)
    doc = {**spec.resolved, "runs": runs}
    res = {}
    for engine in ("cvodes", "basilisk"):
        truth = {**doc["truth"], "integrator": engine, **({"substeps": substeps} if engine == "basilisk" else {})}
        t0 = time.perf_counter()
        res[engine] = se3ocp.fly(sol, {**doc, "truth": truth}, maneuver=man, workers=workers)
        print(f"{engine}: {runs} runs x {len(res[engine].spec.modes)} modes, {time.perf_counter() - t0:.1f} s wall on "
              f"{workers} workers, {res[engine].failed} failed")
    rng = np.random.default_rng(0)
    for mode in res["cvodes"].spec.modes:
        rows = {e: {r["run"]: r for r in res[e].rows if r["feedback"] == mode and r["status"] == "ok"} for e in res}
        stats = {e: res[e].statistics()[mode] for e in res}
        print(f"--- {mode}: p95 (mean): CVODES | Basilisk | largest per-run relative difference | CVODES p95's 95 % "
              f"bootstrap interval")
        for k in KEYS:
            a = np.array([rows["cvodes"][i][k] for i in sorted(rows["cvodes"])])
            d = max(abs(rows["basilisk"][i][k] - rows["cvodes"][i][k]) / abs(rows["cvodes"][i][k]) for i in rows["cvodes"])
            lo, hi = np.percentile(np.percentile(rng.choice(a, size=(2000, a.size)), 95, axis=1), [2.5, 97.5])
            c, b = stats["cvodes"][k], stats["basilisk"][k]
            print(f"{k:18s} {c['p95']:.5e} ({c['mean']:.3e}) | {b['p95']:.5e} ({b['mean']:.3e}) | {d:.1e} | "
                  f"[{lo:.3e}, {hi:.3e}]")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("open", "table", "all"), default="all")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--substeps", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    man, sol = plan()
    if args.case in ("open", "all"):
        open_loop(man, sol, args.substeps)
    if args.case in ("table", "all"):
        table(man, sol, args.runs, bsk_truth.DEFAULT_SUBSTEPS, args.workers)


if __name__ == "__main__":
    main()
