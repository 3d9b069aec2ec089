"""Iterations and times of the bounded, time-optimal, fuel-optimal and path-constrained maneuvers
(configs/ of docs/mathematics.md §10) at several N, by the direct method and, where it applies, the
indirect one, each with its default settings.

    .venv/bin/python scripts/bench_constrained.py                      # N = 100, 200, 400; 1 run each
    .venv/bin/python scripts/bench_constrained.py --N 200 --runs 3     # medians of 3
    .venv/bin/python scripts/bench_constrained.py --cases e3_bounded,e3_free_time --json

Every run is a fresh Python process (``--one``) that loads the maneuver with ``horizon.N`` set,
solves it and reports the Solution's iterations, build_s and solve_s (time.perf_counter inside the
solve; the direct method's includes every initial guess it tried) and result.  Runs are interleaved
round-robin over the cases, so that a change of the machine's load hits them alike; medians when
``--runs`` > 1.  Thin over the public API; never imports tests/.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from benchkit import ROOT, load, machine, spawn  # noqa: E402

CASES = ("slew_time_optimal", "slew_time_optimal_symmetric", "e3_bounded", "e3_free_time", "slew_keep_out",
         "e3_min_radius", "orbit_raise_fuel")
METHODS = ("direct", "indirect")


def run_one(case: str, N: int, method: str) -> dict:
    t = time.perf_counter()
    import se3ocp

    s = se3ocp.solve(se3ocp.load(ROOT / "configs" / f"{case}.yaml", [f"horizon.N={N}"]), method)
    return {"case": case, "N": N, "method": method, "status": s.result.value, "converged": bool(s.converged),
            "applicable": s.result.value != "not_applicable", "iterations": int(s.iterations),
            "build_s": float(s.build_s), "solve_s": float(s.solve_s), "cost": float(s.cost), "T": float(s.T),
            "terminal_error": float(s.terminal_error), "wall_s": time.perf_counter() - t}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--N", default="100,200,400", help="comma separated (default 100,200,400)")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma separated, from {','.join(CASES)}")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per run")
    ap.add_argument("--json", action="store_true", help="print the records as JSON on stdout")
    ap.add_argument("--one", nargs=3, metavar=("CASE", "N", "METHOD"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(run_one(args.one[0], int(args.one[1]), args.one[2])))
        return 0
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    Ns = [int(n) for n in args.N.split(",")]
    if set(cases) - set(CASES) or args.runs < 1:
        ap.error(f"unknown case(s) {sorted(set(cases) - set(CASES))}" if set(cases) - set(CASES) else "--runs >= 1")
    log = sys.stderr if args.json else sys.stdout
    print(f"machine: {machine()}; load average before: {load()}", file=log)
    keys = [(c, N, m) for c in cases for N in Ns for m in METHODS]
    runs: dict = {k: [] for k in keys}
    skip = set()
    for r in range(args.runs):
        for k in keys:
            if k in skip:
                continue
            rec = spawn(Path(__file__).resolve(), [k[0], str(k[1]), k[2]], args.timeout)
            rec.update(case=k[0], N=k[1], method=k[2])
            runs[k].append(rec)
            if rec.get("applicable") is False:
                skip.add(k)
            print(f"  run {r + 1} {k[0]:28s} N={k[1]:4d} {k[2]:8s} {rec.get('status'):16s} it {rec.get('iterations', '-')!s:>5}"
                  f"  build {rec.get('build_s', float('nan')):6.2f} s  solve {rec.get('solve_s', float('nan')):7.2f} s",
                  file=log, flush=True)
    print(f"load average after: {load()}", file=log)
    records = []
    for k in keys:
        ok = [x for x in runs[k] if "solve_s" in x]
        rec = dict(runs[k][-1])
        if ok:
            rec.update(build_s=statistics.median(x["build_s"] for x in ok),
                       solve_s=statistics.median(x["solve_s"] for x in ok), runs=len(ok))
        records.append(rec)
    if args.json:
        print(json.dumps(records, indent=1))
        return 0
    print(f"\nmedians of {args.runs} fresh-process run(s); '-': the method does not cover the problem")
    print("| maneuver | N | direct: result | iterations | build s | solve s | indirect: result | iterations | "
          "build s | solve s | cost (direct) | T |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    by = {(r["case"], r["N"], r["method"]): r for r in records}
    for c in cases:
        for N in Ns:
            d, i = by[(c, N, "direct")], by[(c, N, "indirect")]

            def cols(r):
                if r.get("applicable") is False:
                    return "-", "", "", ""
                if "solve_s" not in r:
                    return r.get("status", "?"), "", "", ""
                return r["status"], str(r["iterations"]), f"{r['build_s']:.2f}", f"{r['solve_s']:.2f}"

            print(f"| {c} | {N} | " + " | ".join(cols(d)) + " | " + " | ".join(cols(i)) +
                  f" | {d.get('cost', float('nan')):.10g} | {d.get('T', float('nan')):.8g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
