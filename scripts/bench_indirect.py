"""Benchmark of the indirect method's default path (issue 16): warm and cold code-generation cache,
compiled and interpreted, against the direct method's default; optionally a second source tree
(``--before``) measured in the same run.

    .venv/bin/python scripts/bench_indirect.py                       # E3/E4, both schemes, N = 250, 1000, 4000
    .venv/bin/python scripts/bench_indirect.py --N 1000 --runs 5 --schemes first_order
    .venv/bin/python scripts/bench_indirect.py --before /tmp/se3ocp-base   # an exported older tree, e.g.
        # mkdir /tmp/se3ocp-base && git archive c88f297 | tar -x -C /tmp/se3ocp-base

Every run is a fresh Python process (``--one``) that loads the maneuver file (configs/e3_*, e4_*;
``--set horizon.N=... discretization=...``), builds and solves it, and reports

* ``total_s``: problem construction (incl. the Discretization) + build (incl. code generation and the
  C compiler on a cache miss) + solve, i.e. the whole solve as a library user pays it;
* ``build_s``, ``solve_s``: the Solution's own split;
* ``wall_s``: the process from the parent's view (interpreter start, imports, exit).

Variants (``--variants``):

    direct          solve_direct with default options (its own default jit; warm cache)
    indirect        solve_indirect with default options, warm cache
    indirect-cold   the same, every run with a fresh empty SE3OCP_CACHE directory (first use on a machine)
    indirect-interp the same with SE3OCP_NO_JIT=1: what users without a C compiler get

With ``--before DIR`` (a source tree whose root is the package, as this repository): the same maneuvers
solved by that tree's indirect method, interpreted (``before-interp``, its default then), compiled warm
(``before-jit``) and compiled from an empty cache (``before-jit-cold``, only at the N of
``--before-cold-N``: its compile takes 20-50 s).

Per configuration: one discarded warm-up run per warm variant (it also fills the cache), then ``--runs``
rounds, each running every variant once (cold variants with a new empty cache directory each time), so
that a change of the machine's load hits all variants alike.  Medians.  Runs are sequential.  The
machine is shared: the load average is printed before and after; compare ratios from one run.
Table: medians of total_s; ratios indirect/direct and cold/warm (total_s, and process wall time).
The script is thin over the library (it imports nothing from tests/).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = {"e3": "configs/e3_inclination_change.yaml", "e4": "configs/e4_orbital_capture.yaml"}
VARIANTS = ("direct", "indirect", "indirect-cold", "indirect-interp")
BEFORE_VARIANTS = ("before-interp", "before-jit", "before-jit-cold")


# ----------------------------------------------------------------------------- one run (child)
def run_one(case: str, scheme: str, N: int, method: str, overrides: list[str]) -> dict:
    t_start = time.perf_counter()
    import se3ocp

    t_import = time.perf_counter() - t_start
    t0 = time.perf_counter()
    sets = [f"horizon.N={N}", f"discretization={scheme}", *overrides]
    if hasattr(se3ocp, "solve"):                     # the public API (0.2 and later)
        sol = se3ocp.solve(se3ocp.load(ROOT / CONFIGS[case], sets), method)
        status, stats = sol.result.value, sol.stats
    else:                                            # a 'before' tree of 0.1: the method modules
        from se3ocp.problems.maneuvers import load_maneuver

        man = load_maneuver(ROOT / CONFIGS[case], sets)
        if method == "direct":
            from se3ocp.transcription.direct import solve_direct

            sol = solve_direct(man.smooth_problem("direct"))
        else:
            from se3ocp.transcription.indirect import solve_indirect

            sol = solve_indirect(man.smooth_problem("indirect"))
        status, stats = str(sol.status), (sol.extra or {})
    total = time.perf_counter() - t0
    return {"total_s": total, "build_s": float(sol.build_s), "solve_s": float(sol.solve_s), "import_s": t_import,
            "iterations": int(sol.iterations), "converged": bool(sol.converged), "status": status,
            "cost": float(sol.cost), "terminal_error": float(sol.terminal_error),
            "jit": bool(stats.get("jit", False)), "package": str(Path(se3ocp.__file__).parent)}


# ---------------------------------------------------------------------------- runner (parent)
def spawn(case, scheme, N, method, overrides, env_extra, pythonpath, timeout) -> dict:
    env = dict(os.environ)
    env.pop("SE3OCP_NO_JIT", None)
    env.update(env_extra)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--one", case, scheme, str(N), method, *overrides]
    t = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd="/")
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {timeout:.0f} s"}
    wall = time.perf_counter() - t
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        tail = (out.stderr or out.stdout).strip().splitlines()[-1:] or ["no output"]
        return {"error": tail[0][:200]}
    rec = json.loads(lines[-1])
    rec["wall_s"] = wall
    return rec


def package_path(tree: Path, tmp: Path) -> str:
    """A directory to put first on PYTHONPATH so that ``import se3ocp`` is ``tree``."""
    d = tmp / "before-path"
    d.mkdir(exist_ok=True)
    link = d / "se3ocp"
    if not link.exists():
        link.symlink_to(tree.resolve(), target_is_directory=True)
    return str(d)


def _setup(variant: str, tmp: Path, before_path):
    """(method, overrides, env, pythonpath, cold) of a variant."""
    method = "direct" if variant == "direct" else "indirect"
    overrides: list[str] = []
    env: dict[str, str] = {}
    pythonpath = None
    if variant.startswith("before"):
        pythonpath = before_path
        overrides = ["solver.indirect.jit=" + ("false" if variant == "before-interp" else "true")]
        env["SE3OCP_CACHE"] = str(tmp / "cache-before")
    else:
        env["SE3OCP_CACHE"] = str(tmp / "cache-after")
    if variant == "indirect-interp":
        env["SE3OCP_NO_JIT"] = "1"
    return method, overrides, env, pythonpath, variant.endswith("-cold")


def measure(variants, case, scheme, N, runs, tmp: Path, before_path, timeout) -> dict:
    """All variants of one configuration: warm-ups first, then ``runs`` rounds, each running every variant once
    (so that a change of the machine's load hits all variants alike); medians per variant."""
    setups = {v: _setup(v, tmp, before_path) for v in variants}
    recs: dict[str, list] = {v: [] for v in variants}
    errors: dict[str, str] = {}
    for v, (method, overrides, env, pythonpath, cold) in setups.items():
        if not cold:                                       # warm-up, discarded (fills the cache)
            r = spawn(case, scheme, N, method, overrides, env, pythonpath, timeout)
            if "error" in r:
                errors[v] = r["error"]
    for _ in range(runs):
        for v, (method, overrides, env, pythonpath, cold) in setups.items():
            if v in errors:
                continue
            if cold:
                env = dict(env, SE3OCP_CACHE=tempfile.mkdtemp(prefix="cold-", dir=tmp))
            r = spawn(case, scheme, N, method, overrides, env, pythonpath, timeout)
            if "error" in r:
                errors[v] = r["error"]
            else:
                recs[v].append(r)
    out = {}
    for v in variants:
        rs = recs[v]
        if v in errors or not rs:
            out[v] = {"error": errors.get(v, "no run"), "runs": rs}
            continue
        med = {k: statistics.median(r[k] for r in rs) for k in ("total_s", "build_s", "solve_s", "wall_s")}
        out[v] = {**med, "runs": rs, "iterations": rs[-1]["iterations"], "converged": all(r["converged"] for r in rs),
                  "status": rs[-1]["status"], "jit": rs[-1]["jit"], "cost": rs[-1]["cost"],
                  "package": rs[-1]["package"]}
    return out


def _f(v, spec=".2f"):
    return "-" if v is None else format(v, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="e3,e4")
    ap.add_argument("--schemes", default="first_order,lgvi")
    ap.add_argument("--N", default="250,1000,4000")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--before", default=None, help="source tree measured as before-* variants")
    ap.add_argument("--before-cold-N", default="1000", help="N at which before-jit-cold is measured")
    ap.add_argument("--before-interp-max-N", type=int, default=4000)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--json", default=None, help="write all records to this file")
    ap.add_argument("--one", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one:
        case, scheme, N, method, *overrides = a.one
        print(json.dumps(run_one(case, scheme, int(N), method, overrides)))
        return 0

    variants = [v for v in a.variants.split(",") if v]
    if a.before:
        variants += list(BEFORE_VARIANTS)
    before_cold_N = {int(n) for n in a.before_cold_N.split(",") if n}
    Ns = [int(n) for n in a.N.split(",")]
    log = sys.stderr
    import casadi

    print(f"# {os.cpu_count()} cores, casadi {casadi.__version__}, load average {os.getloadavg()}; fresh process per "
          f"run, warm: 1 warm-up + {a.runs} runs, cold: {a.runs} runs with an empty cache each; medians", file=log)
    records = []
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="bench-indirect-") as tmpname:
        tmp = Path(tmpname)
        before_path = package_path(Path(a.before), tmp) if a.before else None
        for case in a.cases.split(","):
            for scheme in a.schemes.split(","):
                for N in Ns:
                    vs = [v for v in variants if not (v == "before-jit-cold" and N not in before_cold_N)
                          and not (v == "before-interp" and N > a.before_interp_max_N)]
                    res = measure(vs, case, scheme, N, a.runs, tmp, before_path, a.timeout)
                    for v, rec in res.items():
                        rec.update(case=case, scheme=scheme, N=N, variant=v)
                        records.append(rec)
                        print(f"  {case} {scheme:11s} N={N:5d} {v:16s} total {_f(rec.get('total_s'))} s (build "
                              f"{_f(rec.get('build_s'))}, solve {_f(rec.get('solve_s'))}, process {_f(rec.get('wall_s'))})"
                              f"  it {rec.get('iterations')} jit {rec.get('jit')} "
                              f"{'ok' if rec.get('converged') else 'NOT converged: ' + str(rec.get('status', rec.get('error')))}",
                              file=log, flush=True)
    print(f"# elapsed {time.perf_counter() - t_start:.0f} s, load average {os.getloadavg()}", file=log)
    print(table(records, variants))
    if a.json:
        Path(a.json).write_text(json.dumps(records, indent=1))
    return 0


def table(records: list[dict], variants: list[str]) -> str:
    """Medians of total_s (build + solve incl. problem construction) per variant; ratios."""
    by = {(r["case"], r["scheme"], r["N"], r["variant"]): r for r in records}
    cols = list(variants)
    head = ("| case | scheme | N | " + " | ".join(cols) +
            " | indirect / direct | cold / warm | cold / warm (process) | it |")
    lines = [head, "|" + "---|" * (len(cols) + 7)]
    for key in sorted({k[:3] for k in by}, key=lambda k: (k[0], k[1], k[2])):
        row = [by.get((*key, v)) for v in cols]
        cells = [_f(r.get("total_s")) if r and "total_s" in r and r.get("converged") else
                 ("-" if not r else "fail") for r in row]
        d, w, c = (by.get((*key, v), {}) for v in ("direct", "indirect", "indirect-cold"))
        ratio = _f(w["total_s"] / d["total_s"]) if "total_s" in w and "total_s" in d else "-"
        cw = _f(c["total_s"] / w["total_s"]) if "total_s" in c and "total_s" in w else "-"
        cwp = _f(c["wall_s"] / w["wall_s"]) if "wall_s" in c and "wall_s" in w else "-"
        it = "/".join(str(by[(*key, v)].get("iterations")) for v in cols if (*key, v) in by)
        lines.append(f"| {key[0]} | {key[1]} | {key[2]} | " + " | ".join(cells) + f" | {ratio} | {cw} | {cwp} | {it} |")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
