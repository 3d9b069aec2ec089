"""Benchmarks of issue 8 (sweeps): parallel speedup and continuation savings.

1. Speedup: a 12-point sweep (E3, T x inclination = 3 x 4, direct and indirect,
   cold starts so that only the execution differs) run serially (in-process) and on
   the local process pool; wall times, median of --runs runs each (pool start-up
   included).  Issue target: >= 1.7x on 2 cores.
2. Continuation: the 10-point T sweep of E3 (configs/sweeps/e3_T.yaml) with and
   without continuation; total Newton/IPOPT iterations per method (including the
   iterations of warm starts that failed and were redone cold).  Issue target: >= 40%
   fewer.

    python scripts/bench_sweep.py [--runs 3] [--N 100] [--workers 2] [--json out.json]

Both figures depend on the machine being otherwise idle; the load average at
the start of each part is printed with the results.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from se3ocp.problems import sweep as sw  # noqa: E402
from se3ocp.problems.schema import yaml_load  # noqa: E402
from se3ocp.problems.io import write_yaml  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from benchkit import load  # noqa: E402


def grid12(tmp: Path, N: int) -> Path:
    """The T x inclination example cut to 3 x 4 = 12 points, N overridden."""
    doc = yaml_load((ROOT / "configs/sweeps/e3_T_inclination.yaml").read_text())
    doc["base"] = str(ROOT / "configs/e3_inclination_change.yaml")
    doc["name"] = "bench_grid12"
    doc["set"] = {"horizon.N": N}
    doc["axes"]["horizon.T"] = {"linspace": [0.45, 0.55, 3]}
    doc["continuation"] = False
    p = tmp / "grid12.yaml"
    write_yaml(p, doc)
    return p


def t_sweep(tmp: Path, N: int | None) -> Path:
    doc = yaml_load((ROOT / "configs/sweeps/e3_T.yaml").read_text())
    doc["base"] = str(ROOT / "configs/e3_inclination_change.yaml")
    if N is not None:
        doc["set"] = {"horizon.N": N}
    p = tmp / "e3_T.yaml"
    write_yaml(p, doc)
    return p


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="runs per configuration for the speedup (median)")
    ap.add_argument("--N", type=int, default=100, help="horizon.N of the 12-point sweep (default 100)")
    ap.add_argument("--N-continuation", type=int, default=None,
                    help="horizon.N of the T sweep (default: the file's, 200)")
    ap.add_argument("--workers", type=int, default=sw.default_workers())
    ap.add_argument("--skip-speedup", action="store_true")
    ap.add_argument("--skip-continuation", action="store_true")
    ap.add_argument("--json", default=None, help="also write the numbers to this JSON file")
    a = ap.parse_args(argv)
    out: dict = {"cores": sw.default_workers(), "workers": a.workers}
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        if not a.skip_speedup:
            s = sw.load_sweep(grid12(tmp, a.N))
            print(f"[speedup] 12 points x {len(s.methods)} methods, N = {a.N}, cold starts; load average {load()}", flush=True)
            times = {"serial": [], "pool": []}
            costs = {}
            for i in range(a.runs):
                for kind, workers in (("serial", 1), ("pool", a.workers)):
                    t0 = time.perf_counter()
                    res = sw.run_sweep(s, workers=workers)
                    dt = time.perf_counter() - t0
                    times[kind].append(dt)
                    c = [r["cost"] for r in res.rows]
                    costs.setdefault(kind, c)
                    print(f"  run {i + 1}: {kind:<6} {dt:6.2f} s  ({sum(r['converged'] for r in res.rows)}/"
                          f"{len(res.rows)} converged)", flush=True)
            med = {k: statistics.median(v) for k, v in times.items()}
            same = all(abs(x - y) <= 1e-10 * abs(x) for x, y in zip(costs["serial"], costs["pool"]))
            out["speedup"] = {"N": a.N, "tasks": len(costs["serial"]), "runs": a.runs, "times_s": times,
                              "median_s": med, "speedup": med["serial"] / med["pool"], "same_costs": same}
            print(f"  median serial {med['serial']:.2f} s, pool ({a.workers} workers) {med['pool']:.2f} s: "
                  f"speedup {med['serial'] / med['pool']:.2f}x (target >= 1.7x); identical costs: {same}; load average {load()}",
                  flush=True)
        if not a.skip_continuation:
            s = sw.load_sweep(t_sweep(tmp, a.N_continuation))
            n = a.N_continuation or yaml_load((ROOT / "configs/sweeps/e3_T.yaml").read_text())["set"]["horizon.N"]
            print(f"[continuation] E3 T sweep, {len(s.points())} points, N = {n}; load average {load()}", flush=True)
            runs = {}
            for label, cont in (("cold", False), ("continuation", True)):
                t0 = time.perf_counter()
                res = sw.run_sweep(s, workers=a.workers, continuation=cont)
                runs[label] = (res, time.perf_counter() - t0)
            out["continuation"] = {"N": n, "points": len(s.points()), "by_method": {}}
            for m in s.methods:
                rc = [r for r in runs["cold"][0].rows if r["method"] == m]
                rw = [r for r in runs["continuation"][0].rows if r["method"] == m]
                ic, iw = sum(r["iterations_total"] for r in rc), sum(r["iterations_total"] for r in rw)
                dc = max(abs(x["cost"] - y["cost"]) / abs(x["cost"]) for x, y in zip(rc, rw))
                starts = {k: sum(r["start"] == k for r in rw) for k in sorted({r["start"] for r in rw})}
                out["continuation"]["by_method"][m] = {
                    "iterations_cold": ic, "iterations_continuation": iw, "saving": 1 - iw / ic,
                    "per_point_cold": [r["iterations"] for r in rc], "per_point_continuation": [r["iterations_total"] for r in rw],
                    "starts": starts, "max_relative_cost_difference": dc,
                    "converged": [sum(r["converged"] for r in rc), sum(r["converged"] for r in rw)]}
                print(f"  {m:<9} iterations cold {ic:3d} {[r['iterations'] for r in rc]}", flush=True)
                print(f"  {'':<9} continuation {iw:3d} {[r['iterations_total'] for r in rw]}  starts {starts}", flush=True)
                print(f"  {'':<9} saving {100 * (1 - iw / ic):.0f}% (target >= 40%); max rel. cost difference "
                      f"{dc:.1e}", flush=True)
            tot_c = sum(b["iterations_cold"] for b in out["continuation"]["by_method"].values())
            tot_w = sum(b["iterations_continuation"] for b in out["continuation"]["by_method"].values())
            out["continuation"]["saving_all_methods"] = 1 - tot_w / tot_c
            out["continuation"]["wall_s"] = {k: v[1] for k, v in runs.items()}
            print(f"  all methods: {tot_c} -> {tot_w} iterations, saving {100 * (1 - tot_w / tot_c):.0f}%; "
                  f"wall {runs['cold'][1]:.1f} s cold, {runs['continuation'][1]:.1f} s continuation; load average {load()}",
                  flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=2, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
