"""N and time needed to reach a continuous-time accuracy by uniform refinement (issue 26's closing note).

    .venv/bin/python scripts/accuracy_table.py                        # E3, E4; lgvi and first order; 1e-3, 1e-6, 1e-9
    .venv/bin/python scripts/accuracy_table.py --cases e3 --tols 1e-3 --schemes lgvi

For each case, scheme and tolerance: ``se3ocp.solve(man, accuracy=tol)`` from the file's N (wall time, one run,
in this process), printing the mesh history (N per level), the final N, the continuous miss reached and the
total time -- or the one-line answer given before solving when the tolerance is out of reach.  Thin over the
public API.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchkit  # noqa: E402

import se3ocp  # noqa: E402

CASES = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture"}


def one(case: str, scheme: str, tol: float) -> str:
    man = se3ocp.load(benchkit.ROOT / "configs" / f"{CASES[case]}.yaml", [f"discretization={scheme}"])
    t0 = time.perf_counter()
    try:
        sol = se3ocp.solve(man, accuracy=tol)
    except ValueError as e:
        return f"| {case} | {scheme} | {tol:g} | refused before solving ({time.perf_counter() - t0:.1f} s) | | | {e} |"
    wall = time.perf_counter() - t0
    Ns = " → ".join(str(r["N"]) for r in sol.mesh)
    met = "met" if sol.stats.get("accuracy_met") else "NOT met"
    return f"| {case} | {scheme} | {tol:g} | {Ns} | {sol.mesh[-1]['miss']:.2e} ({met}) | {wall:.1f} | {sol.result} |"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--schemes", nargs="+", default=["lgvi", "first_order"], choices=["lgvi", "first_order"])
    ap.add_argument("--tols", nargs="+", type=float, default=[1e-3, 1e-6, 1e-9])
    a = ap.parse_args(argv)
    print(f"# {benchkit.machine()}; load {benchkit.load()}")
    print("| case | scheme | accuracy | N per level | miss reached | time s | status / answer |")
    print("|---|---|---|---|---|---|---|")
    for case in a.cases:
        for scheme in a.schemes:
            for tol in a.tols:
                print(one(case, scheme, tol), flush=True)
    print(f"# load after {benchkit.load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
