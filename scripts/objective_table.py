"""Iterations and times of the time and fuel objectives at N = 100, 200, 400 (issue 27's closing note).

    .venv/bin/python scripts/objective_table.py                      # every time and fuel config, N = 100 200 400
    .venv/bin/python scripts/objective_table.py --Ns 100 --cases orbit_raise_fuel

The cases: every file of configs/ and configs/everyday/ whose objective is time or fuel, and the fuel versions of
the LEO raises (``--set control.objective=fuel``; configs/leo_body_engine.yaml, configs/leo_raise_slew.yaml).  Each
fuel case is also solved with the effort objective (the same maneuver otherwise), and the ratio of the wall times
is printed (issue 27: fuel <= 10x effort).  Each solve is ``se3ocp.solve(man)`` with the file's settings, in a fresh
process (:func:`benchkit.spawn`: the first solve of a process compiles what the disk cache lacks, as a user's
would), one run, wall time of the solve call; the load average is printed before and after (the machine may be
shared).  Thin over the public API.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchkit  # noqa: E402

#: the fuel versions of maneuvers whose files have another objective: (case name, file, --set overrides)
FUEL_VERSIONS = [("leo_body_engine (fuel)", "leo_body_engine.yaml", ["control.objective=fuel"]),
                 ("leo_raise_slew (fuel)", "leo_raise_slew.yaml", ["control.objective=fuel"])]


def cases() -> list[tuple[str, str, list[str]]]:
    """(name, file relative to configs/, overrides) of every time and fuel case."""
    out = []
    for path in sorted((benchkit.ROOT / "configs").glob("*.yaml")) + \
            sorted((benchkit.ROOT / "configs" / "everyday").glob("*.yaml")):
        data = yaml.safe_load(path.read_text()) or {}
        if isinstance(data, dict) and (data.get("control") or {}).get("objective") in ("time", "fuel"):
            out.append((path.stem, str(path.relative_to(benchkit.ROOT / "configs")), []))
    return out + [(n, f, list(s)) for n, f, s in FUEL_VERSIONS]


def one(file: str, N: int, sets: list[str]) -> dict:
    """One solve in this process (``--one``): the record benchkit.spawn reads."""
    import se3ocp

    man = se3ocp.load(benchkit.ROOT / "configs" / file, [f"horizon.N={N}", *sets])
    t0 = time.perf_counter()
    sol = se3ocp.solve(man)
    wall = time.perf_counter() - t0
    return {"converged": bool(sol.converged), "status": str(sol.result), "iterations": int(sol.iterations),
            "cost": float(sol.cost), "build_s": float(sol.build_s), "solve_s": float(sol.solve_s), "wall_s": wall,
            "objective": str(man.problem.control.objective), "spread": sol.stats.get("multistart_spread"),
            "optima": sol.stats.get("multistart_optima"), "load": benchkit.load()}


def row(name: str, N: int, rec: dict) -> str:
    if "wall_s" not in rec:
        return f"| {name} | {N} | {rec['status']} | | | | | |"
    spread = "" if rec.get("spread") is None else f"{rec['optima']} optima, spread {rec['spread']:.1e}"
    return (f"| {name} | {N} | {rec['status']} | {rec['iterations']} | {rec['cost']:.10g} | {rec['wall_s']:.1f} | "
            f"{spread} | {rec['load']} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", nargs=3, metavar=("FILE", "N", "SETS_JSON"), help=argparse.SUPPRESS)
    ap.add_argument("--Ns", nargs="+", type=int, default=[100, 200, 400])
    ap.add_argument("--cases", nargs="+", default=None, help="case names (default: all)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per solve")
    a = ap.parse_args(argv)
    if a.one:
        print(json.dumps(one(a.one[0], int(a.one[1]), json.loads(a.one[2]))))
        return 0
    script = Path(__file__).resolve()
    print(f"# {benchkit.machine()}; load {benchkit.load()}")
    print("| case | N | result | iterations | cost | wall s | multistart | load (1, 5, 15 min) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, file, sets in cases():
        if a.cases and name not in a.cases and name.split(" ")[0] not in a.cases:
            continue
        for N in a.Ns:
            rec = benchkit.spawn(script, [file, str(N), json.dumps(sets)], a.timeout)
            print(row(name, N, rec), flush=True)
            if rec.get("objective") == "fuel":
                eff = benchkit.spawn(script, [file, str(N), json.dumps([*sets, "control.objective=effort"])],
                                     a.timeout)
                ratio = f"; fuel / effort {rec['wall_s'] / eff['wall_s']:.1f}x" if "wall_s" in eff else ""
                print(row(f"{name} with effort{ratio}", N, eff), flush=True)
    print(f"# load after {benchkit.load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
