"""Benchmark: the LEO engine fuel raise's translational relaxation by SCvx beside our own fuel solves (issue 41, "the
anchor for speed": the engine's fuel solve converged in <= 10x the relaxation's SCvx time, measured side by side).

    .venv/bin/python -m pip install -e '.[scvx]'                    # cvxpy + Clarabel
    .venv/bin/python scripts/bench_fuel_scvx.py --json bench_fuel_scvx.json
    .venv/bin/python scripts/bench_fuel_scvx.py --cases leo_engine_fuel --repeat 5 --full-timeout 600

Per case (a maneuver file and its overrides, loaded by ``se3ocp.load``), in one run:

    (a) scvx       the translational relaxation (the thrust free to point anywhere, |u| <= the engine's max) by
                   successive convexification, Clarabel through cvxpy (scripts/scvx_relaxation.py), in this process:
                   wall time (linearizations, cvxpy's compilation, Clarabel), Clarabel's own time, iterations;
    (b) ipopt      the same relaxed problem as a Problem solved by our direct method (IPOPT; the fuel objective's
                   strategy on the file's scheme, KKT tolerance 1e-8, no continuous check:
                   scvx_relaxation.solve_relaxed), in this process: wall time, iterations, cost;
    (b0) default   optional (``--relaxed-default``): the relaxed Problem through ``se3ocp.solve`` with every default
                   (for lgvi_kepler: first the lgvi optimum; tol 1e-10), once, in a subprocess capped at
                   ``--full-timeout``;
    (c) full       our default solve of the engine problem itself (``se3ocp.solve(se3ocp.load(file, full_sets))``,
                   the body turned to aim its engine: the fuel objective, or the propellant objective, whose
                   relaxation is the fuel one's), once, in a fresh subprocess capped at ``--full-timeout`` seconds.

(a) and (b) are repeated ``--repeat`` times, interleaved, each from a fresh ``se3ocp.load``; medians are printed
(the first run of (b) may include compiling; the load average before and after says how busy the shared machine
was).  Printed: a table with the wall times, iterations and costs, the agreement |cost_b - cost_a| / cost_a, the
delta-v against Hohmann's (transcription.ocp.feasibility.orbit_capacity), and the ratio full / SCvx (a lower bound
when the full solve hit its cap); ``--json PATH`` writes every record.  Thin over the public API.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import benchkit  # noqa: E402

#: name -> (maneuver file, overrides of the relaxation (a, b), overrides of the full solve (c)): the propellant
#: objective's relaxation is the fuel objective's (the same engine impulse, the thrust free to point anywhere)
CASES = {
    "leo_body_engine_fuel": ("configs/leo_body_engine.yaml", ["control.objective=fuel"], ["control.objective=fuel"]),
    "leo_body_engine_propellant": ("configs/leo_body_engine.yaml", ["control.objective=fuel"],
                                   ["control.objective=propellant", "control.weights=auto"]),
    "raise_engine_fuel": ("configs/leo/raise_engine_fuel.yaml", ["control.objective=fuel"], []),
    "leo_engine_fuel": ("configs/leo_engine_fuel.yaml", [], []),
}


def _load(cfg: str, sets: list[str]):
    import se3ocp

    return se3ocp.load(benchkit.ROOT / cfg, sets)


def run_scvx(cfg: str, sets: list[str]) -> dict:
    """(a): SCvx on the translational relaxation, timed from the loaded Problem."""
    import scvx_relaxation

    problem = _load(cfg, sets).problem
    r = scvx_relaxation.solve(problem)
    return {"wall_s": r.wall_s, "solver_s": r.solver_s, "iterations": r.iterations, "accepted": r.accepted,
            "converged": r.converged, "cost": r.cost, "defect": list(r.defect), "miss": list(r.miss),
            "load": os.getloadavg()[0]}


def run_ipopt(cfg: str, sets: list[str]) -> dict:
    """(b): our direct method on the same relaxed problem, timed from the loaded Problem (build + solve)."""
    import scvx_relaxation

    problem = _load(cfg, sets).problem
    t = time.perf_counter()
    sol = scvx_relaxation.solve_relaxed(problem)
    wall = time.perf_counter() - t
    return {"wall_s": wall, "iterations": sol.iterations, "status": str(sol.result.value), "converged": bool(sol.converged),
            "cost": float(sol.cost) if sol.converged else None, "tol": scvx_relaxation.IPOPT_TOL,
            "load": os.getloadavg()[0]}


def one(kind: str, cfg: str, sets: list[str]) -> None:
    """In a fresh process (``--one``): (c) the default fuel solve of the file, or (b0) the relaxed Problem's default
    solve; prints the record (JSON)."""
    import se3ocp
    import scvx_relaxation

    t = time.perf_counter()
    man = _load(cfg, sets)
    if kind == "full":
        sol = se3ocp.solve(man)
    else:
        sol = se3ocp.solve(scvx_relaxation.relaxed_problem(man.problem), continuous_check=False)
    wall = time.perf_counter() - t
    dv = sol.delta_v if kind == "full" and sol.converged else None
    print(json.dumps({"wall_s": wall, "status": str(sol.result.value), "converged": bool(sol.converged),
                      "cost": float(sol.cost) if sol.converged else None, "iterations": sol.iterations,
                      "delta_v": None if dv is None else float(dv), "load": os.getloadavg()[0]}))


def _spawned(kind: str, cfg: str, sets: list[str], timeout: float) -> dict:
    t = time.perf_counter()
    rec = benchkit.spawn(Path(__file__), [kind, cfg, *sets], timeout)
    rec.setdefault("wall_s", time.perf_counter() - t)
    rec["timed_out"] = str(rec.get("status", "")).startswith("timeout")
    return rec


def _median(runs: list[dict], key: str):
    xs = [r[key] for r in runs if r.get(key) is not None]
    return statistics.median(xs) if xs else None


def measure(name: str, repeat: int, full_timeout: float, relaxed_default: bool) -> dict:
    from se3ocp.transcription.ocp.feasibility import orbit_capacity

    cfg, sets, full_sets = CASES[name]
    problem = _load(cfg, sets).problem
    cap = orbit_capacity(problem)
    a, b = [], []
    for r in range(repeat):
        a.append(run_scvx(cfg, sets))
        b.append(run_ipopt(cfg, sets))
        print(f"  {name} run {r + 1}: scvx {a[-1]['wall_s']:.2f} s ({a[-1]['iterations']} it), "
              f"ipopt {b[-1]['wall_s']:.2f} s ({b[-1]['iterations']} it, {b[-1]['status']})", flush=True)
    rec = {"case": name, "config": cfg, "sets": sets, "full_sets": full_sets, "N": problem.N, "mass": problem.model.mass,
           "w_f": float(problem.control.W_f[0, 0]),
           "hohmann_dv": cap[2] if cap else None,
           "scvx": {"runs": a, **{k: _median(a, k) for k in ("wall_s", "solver_s", "iterations", "cost")},
                    "converged": all(x["converged"] for x in a)},
           "ipopt_relaxed": {"runs": b, **{k: _median(b, k) for k in ("wall_s", "iterations", "cost")},
                             "converged": all(x["converged"] for x in b)}}
    if relaxed_default:
        rec["relaxed_default"] = _spawned("relaxed", cfg, sets, full_timeout)
        print(f"  {name} relaxed, default solve: {rec['relaxed_default']}", flush=True)
    rec["full"] = full = _spawned("full", cfg, full_sets, full_timeout)
    print(f"  {name} full: {full}", flush=True)
    ca_, cb = rec["scvx"]["cost"], rec["ipopt_relaxed"]["cost"]
    rec["agreement"] = abs(cb - ca_) / abs(ca_) if ca_ and cb else None
    rec["ratio_full_scvx"] = full["wall_s"] / rec["scvx"]["wall_s"]
    rec["ratio_is_lower_bound"] = not full.get("converged", False)
    return rec


def table(recs: list[dict]) -> str:
    def f(x, spec):
        return "—" if x is None else format(x, spec)

    lines = ["| case | what | wall s | solver s | iterations | status | cost | Δv m/s | Δv / Hohmann |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        m, hv, w = r["mass"], r["hohmann_dv"], r["w_f"]
        def dv(cost, delta_v=None):           # the relaxation's cost is w_f x the impulse; the full solve says its own
            v = delta_v if delta_v is not None else (cost / w / m if cost else None)
            return (f(v * 1e3, ".6f"), f(v / hv, ".9f") if hv else "—") if v else ("—", "—")
        s, b, full = r["scvx"], r["ipopt_relaxed"], r["full"]
        lines.append(f"| {r['case']} (N = {r['N']}) | (a) SCvx relaxation | {f(s['wall_s'], '.2f')} | "
                     f"{f(s['solver_s'], '.2f')} | {f(s['iterations'], '.0f')} | "
                     f"{'converged' if s['converged'] else 'NOT converged'} | {f(s['cost'], '.10f')} | "
                     + " | ".join(dv(s["cost"])) + " |")
        lines.append(f"| | (b) IPOPT relaxed (tol {b['runs'][0]['tol']:g}) | {f(b['wall_s'], '.2f')} | | "
                     f"{f(b['iterations'], '.0f')} | {b['runs'][-1]['status']} | {f(b['cost'], '.10f')} | "
                     + " | ".join(dv(b["cost"])) + " |")
        if "relaxed_default" in r:
            d = r["relaxed_default"]
            lines.append(f"| | (b0) relaxed, se3ocp.solve defaults | {f(d['wall_s'], '.1f')} | | "
                         f"{d.get('iterations', '—')} | {d.get('status')} | {f(d.get('cost'), '.10f')} | "
                         + " | ".join(dv(d.get("cost"))) + " |")
        lines.append(f"| | (c) full engine solve (default{', ' + ' '.join(r['full_sets']) if r['full_sets'] else ''}) | "
                     f"{f(full['wall_s'], '.1f')} | | {full.get('iterations', '—')} | {full.get('status')} | "
                     f"{f(full.get('cost'), '.10f')} | " + " | ".join(dv(None, full.get("delta_v"))) + " |")
        lines.append(f"| | agreement (b)/(a) {f(r['agreement'], '.2e')}; full / SCvx "
                     f"{'≥ ' if r['ratio_is_lower_bound'] else ''}{r['ratio_full_scvx']:.0f}× | | | | | | | |")
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", nargs="+", help=argparse.SUPPRESS)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated, of: " + ", ".join(CASES))
    ap.add_argument("--repeat", type=int, default=3, help="runs of (a) and (b) per case (medians)")
    ap.add_argument("--full-timeout", type=float, default=120.0, help="seconds the full fuel solve may take")
    ap.add_argument("--relaxed-default", action="store_true",
                    help="also the relaxed Problem through se3ocp.solve's defaults (once, capped like the full solve)")
    ap.add_argument("--json", type=Path, help="write the records here")
    a = ap.parse_args(argv)
    if a.one:
        kind, cfg, *sets = a.one
        one(kind, cfg, sets)
        return
    print(f"machine: {benchkit.machine()}; load average before: {benchkit.load()}", flush=True)
    recs = [measure(name, a.repeat, a.full_timeout, a.relaxed_default) for name in a.cases.split(",")]
    after = benchkit.load()
    print(f"load average after: {after}")
    print(table(recs))
    if a.json:
        a.json.write_text(json.dumps({"machine": benchkit.machine(), "load_after": after, "repeat": a.repeat,
                                      "full_timeout": a.full_timeout, "cases": recs}, indent=1))
        print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
