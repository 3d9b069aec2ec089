"""The tracker of docs/mathematics.md §12 measured on a *discrete* truth (issue 25's two cases).

The truth here is the plan's own scheme on a different body model, with actuator errors; the
continuous-time truth of the flight engine (transcription/flight/) is the acceptance case.  This
script measures what the feedback design can do before that:

* E3 (LGVI, N = 400), truth with J2 (1.08e-3, radius 0.9), thrust scale 2 % and misalignment 0.5 deg
  (1-sigma, about each axis), the issue's initial dispersions: p95 terminal position miss open and
  closed loop, and the delta-v overhead (commands' delta-v over the plan's);
* the time-optimal slew planned with bounds_margin 0.1 (and 0), truth with torque scale 2 % and inertia
  scale 1 % per axis: p95 terminal attitude and rate misses, the saturated fraction.

    .venv/bin/python scripts/tracking_discrete.py [--runs 100] [--seed 7] [--no-disturbance]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import se3ocp
from se3ocp.problems.models import Dumbbell, Gravity, RigidBody
from se3ocp.transcription.dynamics.lgvi import discretization
from se3ocp.transcription.geometry.so3 import exp_so3
from se3ocp.transcription.closedloop.tracking import fly_discrete, retract

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def scaled(columns: slice, scale, rotation=None):
    """The actuator: commands (rows, 6) -> delivered, the ``columns`` block scaled (and rotated)."""
    def actuator(u):
        v = u.copy()
        blk = u[:, columns] if rotation is None else u[:, columns] @ rotation.T
        v[:, columns] = (1.0 + scale) * blk
        return v
    return actuator


def e3(runs: int, seed: int, disturbance: bool) -> None:
    sol = se3ocp.solve(se3ocp.load(CONFIGS / "e3_inclination_change.yaml", ["horizon.N=400", "discretization=lgvi"]))
    G = se3ocp.tracking_gains(sol)
    truth = discretization(Dumbbell(gravity="j2", J2=1.08e-3, J2_radius=0.9).body_model(), "lgvi")
    J = sol.problem.model.inertia
    rng = np.random.default_rng(seed)
    rows = {False: [], True: []}
    for _ in range(runs):
        act = scaled(slice(0, 3), 0.02 * rng.standard_normal(), exp_so3(np.radians(0.5) * rng.standard_normal(3)))
        z0 = np.r_[1e-4 * rng.standard_normal(6), np.radians(0.5) * rng.standard_normal(3),
                   J @ (1e-3 * rng.standard_normal(3))]
        for fb in (False, True):
            f = fly_discrete(G, truth, retract(G.X[0], z0), feedback=fb, disturbance=disturbance, actuator=act)
            dv = G.h * np.linalg.norm(f.commands[:, :, :3], axis=2).mean(axis=1).sum()
            rows[fb].append((np.linalg.norm(f.z[-1][:3]), np.linalg.norm(f.z[-1][3:6]), dv))
    o, c = np.array(rows[False]), np.array(rows[True])
    p = lambda a: np.percentile(a, 95)  # noqa: E731
    print(f"E3 LGVI N=400, {runs} runs: p95 position miss open {p(o[:, 0]):.3e}, closed {p(c[:, 0]):.3e} "
          f"(ratio {p(c[:, 0]) / p(o[:, 0]):.2e}); momentum miss open {p(o[:, 1]):.3e}, closed {p(c[:, 1]):.3e}; "
          f"delta-v overhead p95 {100 * p(c[:, 2] / o[:, 2] - 1):.2f} %")


def slew(runs: int, seed: int, margin: float, disturbance: bool) -> None:
    man = se3ocp.load(CONFIGS / "slew_time_optimal.yaml", [f"control.bounds_margin={margin}"] if margin else [])
    sol = se3ocp.solve(man)
    G = se3ocp.tracking_gains(sol)
    J = sol.problem.model.inertia
    rng = np.random.default_rng(seed)
    rows = {False: [], True: []}
    for _ in range(runs):
        act = scaled(slice(3, 6), 0.02 * rng.standard_normal(3))
        Jt = J * (1.0 + 0.01 * rng.standard_normal(3))[:, None] * np.eye(3)
        truth = discretization(RigidBody(1.0, Jt, Gravity("none")).body_model(), "lgvi")
        for fb in (False, True):
            f = fly_discrete(G, truth, G.X[0], feedback=fb, disturbance=disturbance, actuator=act)
            rate = np.linalg.solve(Jt, f.X[-1, 15:]) - np.linalg.solve(J, G.X[-1, 15:])
            rows[fb].append((np.degrees(np.linalg.norm(f.z[-1][6:9])), np.linalg.norm(rate), f.saturated_fraction))
    o, c = np.array(rows[False]), np.array(rows[True])
    p = lambda a: np.percentile(a, 95)  # noqa: E731
    print(f"slew T = {sol.T:.3f} s, bounds_margin {margin}, {runs} runs: p95 attitude miss open {p(o[:, 0]):.3e} deg, "
          f"closed {p(c[:, 0]):.3e} deg; rate open {p(o[:, 1]):.3e}, closed {p(c[:, 1]):.3e} rad/s; "
          f"saturated fraction p95 {p(c[:, 2]):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--no-disturbance", action="store_true", help="feedback -K z only (no disturbance feedforward)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    e3(a.runs, a.seed, not a.no_disturbance)
    for margin in (0.1, 0.0):
        slew(a.runs, a.seed, margin, not a.no_disturbance)
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
