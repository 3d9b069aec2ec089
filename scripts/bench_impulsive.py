"""Benchmark of the impulsive examples: E1 (TPBVP) and E2 (relaxed) by both transcriptions.

    .venv/bin/python scripts/bench_impulsive.py                    # N = 800, 1 warm-up + 3 runs each
    .venv/bin/python scripts/bench_impulsive.py --runs 5 --N 400
    .venv/bin/python scripts/bench_impulsive.py --cases e1,e2-ss   # skip the ~45 s multiple-shooting runs
    .venv/bin/python scripts/bench_impulsive.py --json             # records on stdout, log on stderr

Cases: ``e1`` (configs/e1_impulsive_tpbvp.yaml, Newton-Armijo on six conditions), ``e2-ss``
(configs/e2_impulsive_relaxed.yaml, transcription single_shooting: the default) and ``e2-ms``
(the same, transcription multiple_shooting: IPOPT on all node states).

Timing protocol: every run is a fresh Python process (``--one``) that loads the YAML file, builds
and solves one case and reports the Solution's ``build_s`` and ``solve_s`` (time.perf_counter
inside the solve; E2's solve_s includes its feasible start, a TPBVP like E1) and the wall
time of the process.  Each case gets one discarded warm-up run (which also fills the code
generation cache; its build time is reported as ``cold_build_s``), then ``--runs`` runs; the
runs are interleaved round-robin over the cases so that a change of load on the shared machine
hits all of them alike.  Medians are reported, and the ratio of each case's median build + solve
to E1's from the same invocation.  Never imports tests/.
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

CASES = {
    "e1": ("configs/e1_impulsive_tpbvp.yaml", None),
    "e2-ss": ("configs/e2_impulsive_relaxed.yaml", "single_shooting"),
    "e2-ms": ("configs/e2_impulsive_relaxed.yaml", "multiple_shooting"),
}


def run_one(case: str, N: int) -> dict:
    """Load, build and solve one case in this process; returns one record."""
    t_wall = time.perf_counter()
    import se3ocp

    path, transcription = CASES[case]
    sets = [f"horizon.N={N}"] + ([f"solver.direct.transcription={transcription}"] if transcription else [])
    s = se3ocp.solve(se3ocp.load(ROOT / path, sets))
    return {"case": case, "N": N, "solver": s.solver, "status": str(s.result), "converged": bool(s.converged),
            "build_s": float(s.build_s), "solve_s": float(s.solve_s), "iterations": int(s.iterations),
            "cost": float(s.cost), "terminal_error": float(s.terminal_error),
            "wall_s": time.perf_counter() - t_wall}


def spawn_case(case: str, N: int, timeout: float) -> dict:
    return {"case": case, "N": N, **spawn(Path(__file__).resolve(), [case, str(N)], timeout)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--N", type=int, default=800)
    ap.add_argument("--runs", type=int, default=3, help="timed runs per case after one warm-up (default 3)")
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma separated, from {','.join(CASES)}")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run")
    ap.add_argument("--json", action="store_true", help="print the records as JSON on stdout")
    ap.add_argument("--one", nargs=2, metavar=("CASE", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(run_one(args.one[0], int(args.one[1]))))
        return 0
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown or args.runs < 1:
        ap.error(f"unknown case(s) {unknown}" if unknown else "--runs must be >= 1")
    log = sys.stderr if args.json else sys.stdout
    print(f"machine: {machine()}; load average before: {load()}", file=log)
    runs: dict[str, list[dict]] = {c: [] for c in cases}
    cold = {}
    for r in range(args.runs + 1):                      # run 0: warm-up (discarded)
        for c in cases:
            rec = spawn_case(c, args.N, args.timeout)
            print(f"  {'warm-up' if r == 0 else f'run {r}':8s} {c:6s} build {rec.get('build_s', float('nan')):7.3f} s"
                  f"  solve {rec.get('solve_s', float('nan')):7.3f} s  {rec.get('status')}", file=log, flush=True)
            if r == 0:
                cold[c] = rec.get("build_s", float("nan"))
            else:
                runs[c].append(rec)
    print(f"load average after: {load()}", file=log)
    records = []
    for c in cases:
        ok = [x for x in runs[c] if "build_s" in x]
        if not ok:
            records.append(dict(runs[c][-1], runs=0))
            continue
        rec = dict(ok[-1])
        rec.update(build_s=statistics.median(x["build_s"] for x in ok),
                   solve_s=statistics.median(x["solve_s"] for x in ok),
                   total_s=statistics.median(x["build_s"] + x["solve_s"] for x in ok),
                   wall_s=statistics.median(x["wall_s"] for x in ok), runs=len(ok), cold_build_s=cold.get(c),
                   converged=all(x["converged"] for x in ok), build_s_all=[x["build_s"] for x in ok],
                   solve_s_all=[x["solve_s"] for x in ok])
        records.append(rec)
    ref = next((r for r in records if r["case"] == "e1" and r.get("runs")), None)
    for r in records:
        if ref and r.get("runs"):
            r["ratio_to_e1"] = r["total_s"] / ref["total_s"]
    if args.json:
        print(json.dumps(records, indent=1))
        return 0
    print(f"\nN = {args.N}; medians of {args.runs} fresh-process runs after one warm-up; ratio = median(build + solve) "
          f"/ E1's")
    print("| case | solver | status | build s | solve s | build+solve s | ratio to E1 | iterations | cost |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in records:
        if not r.get("runs"):
            print(f"| {r['case']} | - | {r.get('status')} | | | | | | |")
            continue
        print(f"| {r['case']} | {r['solver']} | {r['status']} | {r['build_s']:.3f} | {r['solve_s']:.3f} | "
              f"{r['total_s']:.3f} | {r.get('ratio_to_e1', float('nan')):.2f} | {r['iterations']} | {r['cost']:.10f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
