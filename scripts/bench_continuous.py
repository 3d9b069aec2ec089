"""Cost of the continuous check (issue 26: at most 20 % of the solve at N = 1000).

    .venv/bin/python scripts/bench_continuous.py                       # E3, both schemes, N = 1000, 5 runs
    .venv/bin/python scripts/bench_continuous.py --N 400 1000 --runs 7 --schemes lgvi

For each scheme and N, in this process: one warm-up (the solve's Functions and compiled code, the
check's CVODES integrator: the first check's time is printed as ``check cold``), then ``--runs``
rounds of: the direct solve of configs/e3_inclination_change.yaml with the check switched off
(``se3ocp.solve(..., continuous_check=False)``, wall time: build + solve as a library user pays it; the
Solution's own solve_s beside it), the continuous check of that Solution (``continuous_check``, wall time,
default samples), and the default solve, which runs the check itself (``with check``).  Medians; the ratio
is median check over median solve.  The machine is shared: the load average is printed before and after, and the two
medians come from interleaved runs so that a change of load hits both.  Thin over the public API.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import benchkit  # noqa: E402

import se3ocp  # noqa: E402
from se3ocp.transcription.results.check import continuous_check  # noqa: E402

CONFIG = benchkit.ROOT / "configs" / "e3_inclination_change.yaml"


def measure(scheme: str, N: int, runs: int) -> dict:
    man = se3ocp.load(CONFIG, [f"horizon.N={N}", f"discretization={scheme}"])
    sol = se3ocp.solve(man, "direct", continuous_check=False)
    t0 = time.perf_counter()
    check = continuous_check(sol)
    cold = time.perf_counter() - t0
    solve_wall, solve_s, check_s, with_check = [], [], [], []
    for _ in range(runs):
        t0 = time.perf_counter()
        sol = se3ocp.solve(man, "direct", continuous_check=False)
        solve_wall.append(time.perf_counter() - t0)
        solve_s.append(sol.solve_s)
        t0 = time.perf_counter()
        check = continuous_check(sol)
        check_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        se3ocp.solve(man, "direct", continuous_check=True)
        with_check.append(time.perf_counter() - t0)
    med = {k: statistics.median(v) for k, v in (("solve", solve_wall), ("solve_s", solve_s), ("check", check_s),
                                                ("with_check", with_check))}
    return {"scheme": scheme, "N": N, "status": sol.result.value, **med, "check_cold": cold,
            "ratio": med["check"] / med["solve"], "miss": check.terminal_error, "samples": check.samples}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, nargs="+", default=[1000])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--schemes", nargs="+", default=["first_order", "lgvi"], choices=["first_order", "lgvi"])
    a = ap.parse_args(argv)
    print(f"# {benchkit.machine()}; load {benchkit.load()}")
    print("| scheme | N | status | solve s (wall, median, check off) | solve_s | check s (median) | check cold s | "
          "check/solve | solve s with check (default) | continuous miss |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for scheme in a.schemes:
        for N in a.N:
            r = measure(scheme, N, a.runs)
            print(f"| {r['scheme']} | {r['N']} | {r['status']} | {r['solve']:.3f} | {r['solve_s']:.3f} | {r['check']:.3f} | "
                  f"{r['check_cold']:.3f} | {100 * r['ratio']:.1f} % | {r['with_check']:.3f} | {r['miss']:.2e} |", flush=True)
    print(f"# medians of {a.runs} interleaved runs, {r['samples']} samples per interval; load after {benchkit.load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
