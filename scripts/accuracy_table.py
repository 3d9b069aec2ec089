"""N and time needed to reach a continuous-time accuracy by uniform and by adaptive refinement (issue 26).

    .venv/bin/python scripts/accuracy_table.py          # E3, E4, slew, eccentric; lgvi, first order; 1e-3, 1e-6, 1e-9;
                                                        # uniform and adaptive
    .venv/bin/python scripts/accuracy_table.py --cases e3 --tols 1e-3 --schemes lgvi --refinements adaptive

For each case, scheme, tolerance and refinement: ``se3ocp.solve(man, accuracy=tol, refinement=...)`` from the
file's N (wall time, one run, in this process), printing the mesh history (N per level), the final N, the largest
step over the smallest, the continuous miss reached and the total time -- or the one-line answer given before
solving when the tolerance is out of reach.  Thin over the public API.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchkit  # noqa: E402

import se3ocp  # noqa: E402

CASES = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture", "slew": "slew_time_optimal",
         "eccentric": "eccentric_transfer", "fuel": "orbit_raise_fuel"}


def one(case: str, scheme: str, tol: float, refinement: str) -> str:
    man = se3ocp.load(benchkit.ROOT / "configs" / f"{CASES[case]}.yaml", [f"discretization={scheme}"])
    head = f"| {case} | {scheme} | {tol:g} | {refinement} |"
    t0 = time.perf_counter()
    try:
        sol = se3ocp.solve(man, accuracy=tol, refinement=refinement)
    except ValueError as e:
        return f"{head} refused before solving ({time.perf_counter() - t0:.1f} s) | | | | {e} |"
    wall = time.perf_counter() - t0
    Ns = " → ".join(str(r["N"]) for r in sol.mesh)
    last = sol.mesh[-1]
    met = "met" if sol.stats.get("accuracy_met") else "NOT met"
    return (f"{head} {Ns} | {last['h_max'] / last['h_min']:.1f} | {last['miss']:.2e} ({met}) | {wall:.1f} | "
            f"{sol.result} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--schemes", nargs="+", default=["lgvi", "first_order"], choices=["lgvi", "first_order"])
    ap.add_argument("--tols", nargs="+", type=float, default=[1e-3, 1e-6, 1e-9])
    ap.add_argument("--refinements", nargs="+", default=["uniform", "adaptive"], choices=["uniform", "adaptive"])
    a = ap.parse_args(argv)
    print(f"# {benchkit.machine()}; load {benchkit.load()}")
    print("| case | scheme | accuracy | refinement | N per level | h_max / h_min | miss reached | time s | "
          "status / answer |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in a.cases:
        for scheme in a.schemes:
            for tol in a.tols:
                for refinement in a.refinements:
                    print(one(case, scheme, tol, refinement), flush=True)
    print(f"# load after {benchkit.load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
