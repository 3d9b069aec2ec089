"""Benchmark: build and solve times of every method on E3 and E4, both schemes, growing N.

    .venv/bin/python scripts/bench.py                 # N = 250..4000, 5 runs, writes docs/bench.{json,csv,png,md}
    .venv/bin/python scripts/bench.py --quick         # default methods only, N = 250, 1000, 3 runs (< 5 min), docs/bench_quick.*
    .venv/bin/python scripts/bench.py --quick --json  # the JSON list of records on stdout (log on stderr)
    .venv/bin/python scripts/bench.py --methods direct-ipopt,indirect-jit --N 1000 --runs 5

Methods (``--methods``, comma separated):

    direct-ipopt       the direct method, IPOPT (the default solver), interpreted stage Functions (jit: false)
    direct-ipopt-jit   the same with the stage derivative Functions compiled to C (jit: true, the
                       direct method's default)
    direct-fatrop      the direct method with solver 'fatrop' (IPOPT fallback is *reported*: solver field
                       'fatrop->ipopt', and such a run is not counted as a fatrop time)
    indirect           the indirect method from lambda_0 = 0 (Newton-Armijo), interpreted CasADi Functions
    indirect-jit       the same with the per-step maps compiled to C (options.jit)
    rockit             the rockit peer (scripts/peer_rockit.py: RK4 multiple shooting on eqs. (1)-(4)),
                       only if rockit-meco is installed; first_order scheme rows only (it has no scheme)

Timing protocol: every run is a **fresh Python process** (``--one``) that builds and solves one
configuration and reports ``build_s`` (construction of the NLP / shooting Functions: the
Solution's own build_s, time.perf_counter) and ``solve_s`` (the solver call: IPOPT/fatrop or
the whole Newton-Armijo loop incl. the final re-simulation) separately, plus ``wall_s`` of the
process.  One warm-up run per configuration is discarded (it also fills the code-generation
cache of the jit variants: their cold build is reported separately as ``cold_build_s``), then
the medians of ``--runs`` runs are reported.  Runs are sequential (never two at once); the
machine (cores, CPU model, load average before and after) is printed and stored, because on a
shared machine the ratios are what count.

Record keys (``--json``): case, scheme, method, solver, N, build_s, solve_s, iterations,
time_per_iter_s, converged, status, cost, terminal_error, runs, build_s_all, solve_s_all,
cold_build_s, wall_s, for the direct methods evaluations_s / solver_internal_s (solve_s split into
the NLP Function evaluations and the solver's own work, from CasADi's t_wall_nlp_* stats: how far
a faster linear algebra can go; fatrop_own_s: fatrop's own share of solver_internal_s, without
CasADi's interface), and for the peer orthogonality / unit-norm drift.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import benchkit  # noqa: E402

METHODS = ("direct-ipopt", "direct-ipopt-jit", "direct-fatrop", "indirect", "indirect-jit", "rockit")
DEFAULT_METHODS = ("direct-ipopt", "direct-fatrop", "indirect", "indirect-jit", "rockit")
FULL_N = (250, 500, 1000, 2000, 4000)
#: largest N per method in the full run (so that it ends within the hour on 2 shared cores): the
#: rockit peer's build grows to 75 s at N = 1000 (SX expansion of the whole RK4 NLP), fatrop's
#: build is quadratic in N inside CasADi's fatrop interface (12 s at N = 1000, first order) and the
#: interpreted indirect method takes 10 s per solve at N = 1000 (its jit variant covers 4000)
CAPS = {"rockit": 500, "direct-fatrop": 1000, "indirect": 2000}
QUICK_CAPS = {"rockit": 250}
QUICK_N = (250, 1000)
#: --quick runs each method as the library runs it by default (both compiled, warm cache), in under five
#: minutes on 2 cores with the same protocol; the interpreted variants, fatrop and the peer (scripts/
#: peer_rockit.py --compare) belong to the full run or an explicit --methods
QUICK_METHODS = ("direct-ipopt-jit", "indirect-jit")
#: the bundled maneuver file of each case
CASES = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture"}
#: the direct methods' split of solve_s (Solution.stats, see transcription.nlp.solvers.solve_time_split)
SPLIT_KEYS = ("evaluations_s", "solver_internal_s", "fatrop_own_s")
KEYS = ("case", "scheme", "method", "solver", "N", "build_s", "solve_s", "iterations", "time_per_iter_s", "converged",
        "status", "cost", "terminal_error")


# ----------------------------------------------------------------------------- one run
def run_one(case: str, scheme: str, method: str, N: int) -> dict:
    """Build and solve one configuration in this process; returns a record (no medians)."""
    t_wall = time.perf_counter()
    if method == "rockit":
        from scripts.peer_rockit import solve_peer

        rec = solve_peer(case, N)
        rec.update(case=case, scheme="rk4", method="rockit", N=N)   # the peer has no LGVI scheme
        rec["wall_s"] = time.perf_counter() - t_wall
        return rec
    import se3ocp

    man = se3ocp.load(ROOT / "configs" / f"{CASES[case]}.yaml", [f"horizon.N={N}", f"discretization={scheme}"])
    if method.startswith("direct"):
        solver = "fatrop" if method == "direct-fatrop" else "ipopt"
        sol = se3ocp.solve(man, "direct", solver=solver, jit=method.endswith("-jit"))
        name = sol.solver
        if method.endswith("-jit"):
            name += "+jit" if sol.stats.get("jit") else "(jit unavailable)"
        rec = {"method": "direct", "solver": name, **{k: sol.stats.get(k) for k in SPLIT_KEYS}}
    elif method.startswith("indirect"):
        sol = se3ocp.solve(man, "indirect", jit=method.endswith("-jit"))
        name = sol.solver + ("+jit" if sol.stats.get("jit") else "")
        rec = {"method": "indirect", "solver": name}
    else:
        raise ValueError(f"unknown method {method!r}")
    it = int(sol.iterations)
    rec.update(case=case, scheme=scheme, N=N, build_s=float(sol.build_s), solve_s=float(sol.solve_s), iterations=it,
               converged=bool(sol.converged), status=str(sol.result), cost=float(sol.cost),
               terminal_error=float(sol.terminal_error),
               message=str(sol.message)[:300])
    rec["wall_s"] = time.perf_counter() - t_wall
    return rec


def spawn(case: str, scheme: str, method: str, N: int, timeout: float) -> dict:
    """run_one in a fresh process (the timing unit; benchkit.spawn); a timeout or crash is a record saying so."""
    rec = benchkit.spawn(Path(__file__).resolve(), [case, scheme, method, str(N)], timeout)
    if "solve_s" not in rec:
        rec = {"case": case, "scheme": scheme, "method": method, "N": N, **rec}
    return rec


# ------------------------------------------------------------------------------ machine
def machine() -> dict:
    import casadi

    return {"cores": os.cpu_count(), "cpu": benchkit.cpu_model(), "platform": platform.platform(),
            "python": platform.python_version(), "casadi": casadi.__version__,
            "loadavg": os.getloadavg() if hasattr(os, "getloadavg") else None}


# ------------------------------------------------------------------------------ summary
def _median(vals):
    vals = [v for v in vals if v is not None]
    return float(statistics.median(vals)) if vals else None


def summarize(runs: list[dict], warm: dict | None) -> dict:
    ok = [r for r in runs if "build_s" in r]
    base = dict(ok[-1] if ok else runs[-1])
    base["runs"] = len(ok)
    base["build_s_all"] = [r["build_s"] for r in ok]
    base["solve_s_all"] = [r["solve_s"] for r in ok]
    base["build_s"] = _median(base["build_s_all"])
    base["solve_s"] = _median(base["solve_s_all"])
    base["wall_s"] = _median([r.get("wall_s") for r in ok])
    for key in SPLIT_KEYS:   # direct methods: where the solve time went
        base[key] = _median([r.get(key) for r in ok])
    it = base.get("iterations")
    base["time_per_iter_s"] = base["solve_s"] / it if (base["solve_s"] is not None and it) else None
    base["cold_build_s"] = warm.get("build_s") if warm else None
    for k in KEYS:
        base.setdefault(k, None)
    return base


def slope(Ns, ts):
    """Least-squares slope of log t against log N (None with fewer than two points)."""
    import numpy as np

    pts = [(n, t) for n, t in zip(Ns, ts) if t and t > 0]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def slopes(records: list[dict]) -> list[dict]:
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r["case"], r["scheme"], r["method"], r.get("solver")), []).append(r)
    out = []
    for (case, scheme, method, solver), rs in groups.items():
        rs = sorted(rs, key=lambda r: r["N"])
        Ns = [r["N"] for r in rs]
        out.append({"case": case, "scheme": scheme, "method": method, "solver": solver, "N": f"{Ns[0]}..{Ns[-1]}",
                    "slope_time_per_iter": slope(Ns, [r.get("time_per_iter_s") for r in rs]),
                    "slope_build": slope(Ns, [r.get("build_s") for r in rs]),
                    "slope_solve": slope(Ns, [r.get("solve_s") for r in rs])})
    return out


def _fmt(v, spec):
    return "-" if v is None else format(v, spec)


def table(records: list[dict]) -> str:
    head = ("| case | scheme | method | solver | N | build s | solve s | (evals s | solver s) | iter | s/iter | conv | "
            "cost | term. err |")
    lines = [head, "|" + "---|" * 14]
    for r in records:
        lines.append(
            f"| {r['case']} | {r['scheme']} | {r['method']} | {r.get('solver') or '-'} | {r['N']} | "
            f"{_fmt(r.get('build_s'), '.3f')} | {_fmt(r.get('solve_s'), '.3f')} | {_fmt(r.get('evaluations_s'), '.3f')} | "
            f"{_fmt(r.get('solver_internal_s'), '.3f')}"
            f"{'' if r.get('fatrop_own_s') is None else ' (fatrop ' + _fmt(r['fatrop_own_s'], '.3f') + ')'} | "
            f"{r.get('iterations') or '-'} | "
            f"{_fmt(r.get('time_per_iter_s'), '.4f')} | {'yes' if r.get('converged') else 'no: ' + str(r.get('status'))} | "
            f"{_fmt(r.get('cost'), '.10g')} | {_fmt(r.get('terminal_error'), '.1e')} |")
    return "\n".join(lines)


def plot(records: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = sorted({(r["case"], r["scheme"]) for r in records if r["scheme"] != "rk4"}) or \
        sorted({(r["case"], r["scheme"]) for r in records})
    fig, axes = plt.subplots(2, len(cases), figsize=(4.2 * len(cases), 7.5), squeeze=False)
    for j, (case, scheme) in enumerate(cases):
        # the peer (scheme 'rk4') is drawn in every panel of its case
        rs = [r for r in records if r["case"] == case and r["scheme"] in (scheme, "rk4")]
        for key, ax, label in (("solve_s", axes[0, j], "solve [s]"), ("build_s", axes[1, j], "build [s]")):
            for m in sorted({(r["method"], r.get("solver")) for r in rs}, key=str):
                pts = sorted((r["N"], r.get(key)) for r in rs if (r["method"], r.get("solver")) == m and r.get(key))
                if pts:
                    ax.loglog(*zip(*pts), "o-", ms=4, label=f"{m[0]} {m[1]}")
            Ns = sorted({r["N"] for r in rs})
            if len(Ns) > 1:
                ref = [p for p in (r.get(key) for r in rs if r["N"] == Ns[0]) if p]
                if ref:
                    y0 = min(ref)
                    ax.loglog(Ns, [y0 * n / Ns[0] for n in Ns], "k:", lw=1, label="slope 1")
            ax.set_title(f"{case.upper()} {scheme}", fontsize=9)
            ax.set_xlabel("N")
            ax.set_ylabel(label)
            ax.grid(alpha=0.3, which="both")
        axes[0, j].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# --------------------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the default methods (compiled), N in {250, 1000}, 3 runs")
    ap.add_argument("--json", action="store_true", help="print the JSON list of records on stdout")
    ap.add_argument("--cases", default="e3,e4")
    ap.add_argument("--schemes", default="first_order,lgvi")
    ap.add_argument("--methods", default=None,
                    help=f"default {','.join(DEFAULT_METHODS)}; with --quick {','.join(QUICK_METHODS)}")
    ap.add_argument("--N", default=None, help="comma-separated horizon lengths")
    ap.add_argument("--runs", type=int, default=None, help="timed runs per configuration (after one warm-up)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per run (process)")
    ap.add_argument("--out", default=None, help="output stem (default docs/bench or docs/bench_quick)")
    ap.add_argument("--cap", default=None,
                    help="largest N per method, e.g. 'rockit=500,direct-fatrop=1000' (default: see CAPS)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--replot", default=None, help="only redraw the plot of a written JSON (stem.json -> stem.png)")
    ap.add_argument("--one", nargs=4, metavar=("CASE", "SCHEME", "METHOD", "N"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.replot:
        plot(json.loads(Path(a.replot).read_text())["records"], Path(a.replot).with_suffix(".png"))
        return 0
    if a.one:
        case, scheme, method, N = a.one
        print(json.dumps(run_one(case, scheme, method, int(N))))
        return 0

    Ns = [int(n) for n in a.N.split(",")] if a.N else list(QUICK_N if a.quick else FULL_N)
    runs = a.runs or (3 if a.quick else 5)
    methods = [m for m in (a.methods or ",".join(QUICK_METHODS if a.quick else DEFAULT_METHODS)).split(",") if m]
    caps = dict(QUICK_CAPS if a.quick else CAPS)
    if a.cap:
        caps.update({k: int(v) for k, v in (kv.split("=") for kv in a.cap.split(",") if kv)})
    for m in methods:
        if m not in METHODS:
            ap.error(f"unknown method {m!r}; choose from {', '.join(METHODS)}")
    if "rockit" in methods:
        import importlib.util

        if importlib.util.find_spec("rockit") is None:
            print("rockit not installed (pip install rockit-meco): peer skipped", file=sys.stderr)
            methods.remove("rockit")
    log = sys.stderr
    mach = machine()
    print(f"machine: {mach['cores']} cores, {mach['cpu']}, {mach['platform']}, casadi {mach['casadi']}, "
          f"load average {benchkit.load()}", file=log)
    print(f"protocol: fresh process per run, 1 warm-up + {runs} timed runs, medians; N = {Ns}; N caps {caps}", file=log)
    records = []
    t_start = time.perf_counter()
    for case in a.cases.split(","):
        for scheme in a.schemes.split(","):
            for method in methods:
                if method == "rockit" and scheme != "first_order":
                    continue  # the peer has no discrete scheme: one row per case
                for N in Ns:
                    if N > caps.get(method, N):
                        continue
                    warm = spawn(case, scheme, method, N, a.timeout)
                    rs = [warm] if str(warm.get("status", "")).startswith(("timeout", "error")) else \
                        [spawn(case, scheme, method, N, a.timeout) for _ in range(runs)]
                    rec = summarize(rs, warm)
                    records.append(rec)
                    print(f"  {case} {scheme:11s} {method:16s} N={N:5d}  build {_fmt(rec['build_s'], '.3f')} s  "
                          f"solve {_fmt(rec['solve_s'], '.3f')} s  it {rec.get('iterations')}  "
                          f"{'ok' if rec.get('converged') else 'NOT converged: ' + str(rec.get('status'))}", file=log)
    mach["loadavg_end"] = os.getloadavg() if hasattr(os, "getloadavg") else None
    sl = slopes(records)
    summary = {"machine": mach, "protocol": {"runs": runs, "warmup": 1, "fresh_process_per_run": True, "N": Ns, "caps": caps,
                                             "elapsed_s": time.perf_counter() - t_start},
               "records": records, "slopes": sl}
    md = table(records)
    print(md, file=log)
    print("\nlog-log slopes (time per iteration, build, solve):", file=log)
    for s in sl:
        print(f"  {s['case']} {s['scheme']} {s['method']} {s['solver']}: per-iter {_fmt(s['slope_time_per_iter'], '.2f')}, "
              f"build {_fmt(s['slope_build'], '.2f')}, solve {_fmt(s['slope_solve'], '.2f')}", file=log)
    if not a.no_write:
        stem = ROOT / (a.out or ("docs/bench_quick" if a.quick else "docs/bench"))
        stem.parent.mkdir(parents=True, exist_ok=True)
        Path(f"{stem}.json").write_text(json.dumps(summary, indent=1))
        with open(f"{stem}.csv", "w", newline="") as fh:
            cols = list(KEYS) + ["time_per_iter_s", "runs", "cold_build_s", "wall_s", *SPLIT_KEYS]
            cols = list(dict.fromkeys(cols))
            w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
            w.writeheader()
            w.writerows(records)
        plot(records, Path(f"{stem}.png"))
        cmd = " ".join(["scripts/bench.py", *(sys.argv[1:] if argv is None else argv)])   # what was run
        Path(f"{stem}.md").write_text(
            f"# Benchmark\n\n`.venv/bin/python {cmd}` on {mach['cores']} cores, {mach['cpu']} "
            f"(load average {benchkit.load(mach['loadavg'])} -> {benchkit.load(mach['loadavg_end'])}; shared machine: compare ratios).\n"
            f"Fresh process per run, 1 warm-up + {runs} timed runs, medians.\n\n{md}\n\n"
            "| case | scheme | method | solver | N | slope s/iter | slope build | slope solve |\n|---|---|---|---|---|---|---|---|\n"
            + "\n".join(f"| {s['case']} | {s['scheme']} | {s['method']} | {s['solver']} | {s['N']} | "
                        f"{_fmt(s['slope_time_per_iter'], '.2f')} | {_fmt(s['slope_build'], '.2f')} | "
                        f"{_fmt(s['slope_solve'], '.2f')} |" for s in sl) + "\n")
        print(f"wrote {stem}.json/.csv/.png/.md", file=log)
    if a.json:
        print(json.dumps(records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
