"""Benchmark: the first solve of a model never seen before against a warm solve of it (issue 27, "compile little,
once").

    .venv/bin/python scripts/bench_first_solve.py                  # every case, both methods, 3 repetitions
    .venv/bin/python scripts/bench_first_solve.py --cases e3,j2_body --methods direct --runs 1
    .venv/bin/python scripts/bench_first_solve.py --json           # the records on stdout (the table on stderr)

Per (case, method) and repetition, each solve a fresh Python process (``se3ocp.load`` + ``se3ocp.solve``, timed
together: what a user waits for):

    first        an empty compile cache of its own (``SE3OCP_CACHE`` = a new directory): the structure was never
                 compiled on this machine;
    warm         the same cache once the background builds the first solve started have arrived (the script waits
                 for them: no ``*.building`` left), so nothing is compiled;
    new numbers  the same cache and structure with other numbers (mass, inertia, gravity data, bounds: the case's
                 ``NEW_NUMBERS``), which must compile nothing (``compiles`` = codegen's notices, 0);
    interpreted  ``SE3OCP_NO_JIT=1``: nothing compiled, CasADi's interpreter.

Printed: the medians over the repetitions and the medians of the back-to-back ratios first / warm, new numbers /
warm, interpreted / warm (each repetition's solves run one after the other), with the load average before and
after and the median of the loads the solves saw (the machine may be shared: the ratios within one run are what
count), and first / warm in the solving process's CPU time (what the solve itself did: the background compilers
are other processes: a view of the foreground's work that the load changes little).  ``compiles`` counts codegen's notices, one per background build started: the first solve of a structure
starts them and runs interpreted (the interpreted-first policy, transcription/codegen.py); new numbers start none.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import benchkit  # noqa: E402

J2 = ["gravity.kind=j2", "gravity.J2=1.08e-3", "gravity.radius=0.9"]
#: name -> (maneuver file, overrides, methods it applies to)
CASES = {
    "e3": ("configs/e3_inclination_change.yaml", [], ("direct", "indirect")),
    "e3_bounded": ("configs/e3_bounded.yaml", [], ("direct", "indirect")),
    "j2_body": ("configs/everyday/raise_and_incline.yaml", J2 + ["control.bounds.force.norm=14.0"], ("direct",)),
    "slew": ("configs/slew_time_optimal.yaml", [], ("direct",)),
}
#: the same structures with other numbers
NEW_NUMBERS = {
    "e3": ["model.mass=1.05", "model.length=0.11", "model.sphere_radius=0.025"],
    # a lighter body and a looser bound (a larger body needs more torque than e3_bounded's moment box allows)
    "e3_bounded": ["model.mass=0.98", "control.bounds.force.norm=12.5"],
    "j2_body": ["model.mass=1.1", "model.inertia=[0.025, 0.03, 0.045]", "gravity.J2=1.5e-3", "gravity.radius=0.85",
                "control.bounds.force.norm=15.0"],
    "slew": ["model.inertia=[6000.0, 4500.0, 2500.0]", "control.bounds.moment.box=[45.0, 50.0, 55.0]"],
}


def one(cfg: str, method: str, sets: list[str]) -> None:
    """Load and solve in this process; print the record (JSON)."""
    import se3ocp
    from se3ocp.transcription.compile import codegen

    said: list[str] = []
    codegen.notify = said.append
    t, c = time.perf_counter(), time.process_time()
    sol = se3ocp.solve(se3ocp.load(ROOT / cfg, sets), method)
    sec, cpu = time.perf_counter() - t, time.process_time() - c
    print(json.dumps({"s": sec, "cpu_s": cpu, "compiles": len(said), "status": str(sol.result), "converged": bool(sol.converged),
                      "cost": float(sol.cost) if sol.cost is not None else None, "iterations": sol.iterations,
                      "load": os.getloadavg()[0]}))


def settle(cache: Path, timeout: float = 1800.0) -> float:
    """Wait until no background build is under way in ``cache``; the seconds waited."""
    from se3ocp.transcription.compile import codegen

    return codegen.settle(timeout, cache)


def measure(case: str, method: str, runs: int, timeout: float, log) -> dict:
    """The four kinds of solve (module docstring), ``runs`` repetitions; medians and ratios."""
    cfg, sets, _ = CASES[case]
    script = Path(__file__)
    got: dict[str, list[dict]] = {k: [] for k in ("first", "warm", "new_numbers", "interpreted")}
    waited = []
    for r in range(runs):
        with tempfile.TemporaryDirectory(prefix="se3ocp_first_solve_") as cache:
            env = {"SE3OCP_CACHE": cache}
            got["first"].append(benchkit.spawn(script, [cfg, method, *sets], timeout, env))
            waited.append(settle(Path(cache)))
            got["warm"].append(benchkit.spawn(script, [cfg, method, *sets], timeout, env))
            got["new_numbers"].append(benchkit.spawn(script, [cfg, method, *sets, *NEW_NUMBERS[case]], timeout, env))
            got["interpreted"].append(benchkit.spawn(script, [cfg, method, *sets], timeout,
                                                     {**env, "SE3OCP_NO_JIT": "1"}))
        for k, recs in got.items():
            rec = recs[-1]
            log(f"  {case:10s} {method:8s} run {r + 1} {k:11s} {rec.get('s', float('nan')):7.2f} s  "
                f"compiles {rec.get('compiles', '-')}  {rec.get('status')}  load {rec.get('load', float('nan')):.2f}")
    out = {"case": case, "method": method, "runs": runs, "background_wait_s": waited}
    for k, recs in got.items():
        ok = [x["s"] for x in recs if "s" in x]
        out[f"{k}_s"] = statistics.median(ok) if ok else None
        out[f"{k}_compiles"] = [x.get("compiles") for x in recs]
        out[f"{k}_status"] = sorted({x.get("status") for x in recs})
        out[f"{k}_loads"] = [round(x.get("load", float("nan")), 2) for x in recs]
    for k in ("first", "new_numbers", "interpreted"):
        out[f"{k}_ratio"] = out[f"{k}_s"] / out["warm_s"] if out[f"{k}_s"] and out["warm_s"] else None
        # back to back: each repetition's ratio to the warm solve right after it (what a shared machine's load
        # changes least), and their median
        pairs = [a["s"] / w["s"] for a, w in zip(got[k], got["warm"]) if "s" in a and "s" in w]
        out[f"{k}_ratios"] = [round(r, 3) for r in pairs]
        out[f"{k}_ratio_median"] = statistics.median(pairs) if pairs else None
    for k in ("first", "warm"):   # this process's CPU time: what the solve itself did, whatever the load
        ok = [x["cpu_s"] for x in got[k] if "cpu_s" in x]
        out[f"{k}_cpu_s"] = statistics.median(ok) if ok else None
    fc, wc = out["first_cpu_s"], out["warm_cpu_s"]
    out["first_cpu_ratio"] = fc / wc if fc and wc else None
    out["load_median"] = statistics.median(x.get("load", float("nan")) for recs in got.values() for x in recs)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--one", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--methods", default="direct,indirect")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if a.one is not None:
        one(a.one[0], a.one[1], a.one[2:])
        return
    log = (lambda s: print(s, file=sys.stderr, flush=True)) if a.json else (lambda s: print(s, flush=True))
    log(f"machine: {benchkit.machine()}; load average before: {benchkit.load()}")
    recs = [measure(c, m, a.runs, a.timeout, log) for c in a.cases.split(",") for m in a.methods.split(",")
            if m in CASES[c][2]]
    log(f"load average after: {benchkit.load()}")
    log(f"medians of {a.runs} run(s); ratios: medians of the back-to-back ratios of each run")
    log(f"{'case':10s} {'method':8s} {'first':>7s} {'warm':>7s} {'new':>7s} {'interp':>7s}   first/warm  new/warm  "
        f"interp/warm  new compiles  load  first/warm CPU")

    def f(x, fmt):
        return format(x, fmt) if x is not None else "-"

    for r in recs:
        log(f"{r['case']:10s} {r['method']:8s} {f(r['first_s'], '7.2f')} {f(r['warm_s'], '7.2f')} "
            f"{f(r['new_numbers_s'], '7.2f')} {f(r['interpreted_s'], '7.2f')}   {f(r['first_ratio_median'], '10.2f')} "
            f"{f(r['new_numbers_ratio_median'], '9.2f')} {f(r['interpreted_ratio_median'], '12.2f')}  "
            f"{str(r['new_numbers_compiles']):12s} {r['load_median']:.1f}  {f(r['first_cpu_ratio'], '.2f')}")
    if a.json:
        print(json.dumps(recs, indent=1))


if __name__ == "__main__":
    main()
