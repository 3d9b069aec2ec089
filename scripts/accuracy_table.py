"""N and time needed to reach a continuous-time accuracy by uniform and by adaptive refinement (issues 26, 41).

    .venv/bin/python scripts/accuracy_table.py          # E3, E4, slew, eccentric, fuel; lgvi, first order; 1e-3,
                                                        # 1e-6, 1e-9; uniform and adaptive
    .venv/bin/python scripts/accuracy_table.py --cases e3 --tols 1e-3 --schemes lgvi --refinements adaptive
    .venv/bin/python scripts/accuracy_table.py --maneuver --cases leo_raise_slew leo_body_engine raise_engine \\
        phasing_engine one_engine_raise --schemes lgvi lgvi_kepler --tols 0 1e-2 1e-3 1e-6 --refinements adaptive

For each case, scheme, tolerance and refinement: ``se3ocp.solve(man, accuracy=tol, refinement=...)`` -- with
``--maneuver``, ``maneuver_accuracy=tol``: the flown miss as a fraction of what the maneuver changes -- from the
file's N (wall time, one run, in a fresh process cut at ``--timeout`` seconds), printing the mesh history (N per
level), the final N, the largest step over the smallest, the miss reached (and the flown fraction of the maneuver)
and the total time -- or the one-line answer given before solving when the tolerance is out of reach.  Tolerance
0: the file's N, no refinement (the flown miss the plan has as it is).  Thin over the public API.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchkit  # noqa: E402

import se3ocp  # noqa: E402

CASES = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture", "slew": "slew_time_optimal",
         "eccentric": "eccentric_transfer", "fuel": "orbit_raise_fuel", "leo_raise_slew": "leo_raise_slew",
         "leo_body_engine": "leo_body_engine", "raise_engine": "leo/raise_engine",
         "phasing_engine": "leo/phasing_engine", "one_engine_raise": "one_engine_raise"}
SCHEMES = ["lgvi", "first_order", "lgvi_kepler"]


def one(case: str, scheme: str, tol: float, refinement: str, maneuver: bool) -> dict:
    """One row's record (in this process)."""
    man = se3ocp.load(benchkit.ROOT / "configs" / f"{CASES[case]}.yaml", [f"discretization={scheme}"])
    key = "maneuver_accuracy" if maneuver else "accuracy"
    rec = {"case": case, "scheme": scheme, "tol": tol, "refinement": refinement, "of": key}
    t0 = time.perf_counter()
    try:
        sol = se3ocp.solve(man, **({key: tol, "refinement": refinement} if tol else {}))
    except ValueError as e:
        return {**rec, "answer": str(e), "wall_s": time.perf_counter() - t0}
    rec["wall_s"] = time.perf_counter() - t0
    c = sol.continuous
    levels = sol.mesh or ({"N": sol.problem.N, "h_max": 1.0, "h_min": 1.0, "miss": float("nan")},)
    rec.update(Ns=[r["N"] for r in levels], N=sol.problem.N, ratio=levels[-1]["h_max"] / levels[-1]["h_min"],
               miss=levels[-1]["miss"], met=bool(sol.stats.get("accuracy_met")), status=str(sol.result),
               iterations=sol.iterations, fraction=None if c is None else c.maneuver_fraction)
    return rec


def row(r: dict) -> str:
    head = f"| {r['case']} | {r['scheme']} | {r['tol'] or 'file N'} | {r['refinement'] if r['tol'] else ''} |"
    if "answer" in r:
        return f"{head} refused before solving ({r['wall_s']:.1f} s) | | | | | {r['answer']} |"
    if "timeout" in r:
        return f"{head} | | | | {r['timeout']:.0f}+ | no answer within the timeout |"
    met = "" if not r["tol"] else (" (met)" if r["met"] else " (NOT met)")
    frac = "" if r["fraction"] is None else f"{100 * r['fraction']:.3g} %"
    return (f"{head} {' → '.join(map(str, r['Ns']))} | {r['ratio']:.1f} | {r['miss']:.2e}{met} | {frac} | "
            f"{r['wall_s']:.1f} | {r['status']}, {r['iterations']} it |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["e3", "e4", "slew", "eccentric", "fuel"], choices=list(CASES))
    ap.add_argument("--schemes", nargs="+", default=["lgvi", "first_order"], choices=SCHEMES)
    ap.add_argument("--tols", nargs="+", type=float, default=[1e-3, 1e-6, 1e-9])
    ap.add_argument("--refinements", nargs="+", default=["uniform", "adaptive"], choices=["uniform", "adaptive"])
    ap.add_argument("--maneuver", action="store_true", help="tolerances as fractions of the maneuver")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per row (its own process)")
    ap.add_argument("--json", help="write the records here")
    ap.add_argument("--one", nargs=4, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        case, scheme, tol, refinement = a.one
        print(json.dumps(one(case, scheme, float(tol), refinement, a.maneuver), default=str))
        return 0
    print(f"# {benchkit.machine()}; load {benchkit.load()}")
    print("| case | scheme | accuracy | refinement | N per level | h_max / h_min | miss reached | flown, of the "
          "maneuver | time s | status |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    out = []
    for case in a.cases:
        for scheme in a.schemes:
            for tol in a.tols:
                for refinement in (a.refinements if tol else a.refinements[:1]):
                    cmd = [sys.executable, __file__, "--one", case, scheme, repr(tol), refinement] + \
                        (["--maneuver"] if a.maneuver else [])
                    try:
                        p = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout, cwd=benchkit.ROOT)
                        r = json.loads(p.stdout.strip().splitlines()[-1])
                    except subprocess.TimeoutExpired:
                        r = {"case": case, "scheme": scheme, "tol": tol, "refinement": refinement,
                             "timeout": a.timeout}
                    out.append(r)
                    print(row(r), flush=True)
    print(f"# load after {benchkit.load()}")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
