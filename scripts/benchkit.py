"""Small shared pieces of the benchmark scripts: the machine line, the load average, and running one
case in a fresh Python process that prints its record as a JSON line."""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_model() -> str:
    """The CPU model string (/proc/cpuinfo, else platform.processor())."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or ""


def machine() -> str:
    """CPU model, cores, Python and CasADi versions."""
    import casadi

    return f"{cpu_model()}, {os.cpu_count()} cores, Python {platform.python_version()}, CasADi {casadi.__version__}"


def load(avg=None) -> str:
    """The 1, 5 and 15 minute load averages, now or as stored (``avg``), to two decimals (the machine is
    shared: say how busy it was)."""
    try:
        return " ".join(f"{x:.2f}" for x in (os.getloadavg() if avg is None else avg))
    except (OSError, AttributeError):   # no load average on this system
        return "n/a"


def spawn(script: Path, args: list[str], timeout: float, env: dict | None = None) -> dict:
    """Run ``python script --one ARGS`` in a fresh process; its last stdout line starting with '{' is the
    record (JSON).  A timeout or a crash becomes a record with 'status' saying so and converged False."""
    cmd = [sys.executable, str(script), "--one", *args]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                             env=None if env is None else {**os.environ, **env})
    except subprocess.TimeoutExpired:
        return {"status": f"timeout {timeout:.0f} s", "converged": False}
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    if out.returncode != 0 or not lines:
        tail = (out.stderr or out.stdout).strip().splitlines()[-1:] or ["no output"]
        return {"status": f"error: {tail[0][:200]}", "converged": False}
    return json.loads(lines[-1])


def round_robin(script: Path, cases: list[str], Ns: list[int], runs: int, timeout: float,
                keep: tuple[str, ...], line: "callable") -> list[dict]:
    """Ours and a peer, each (case, N, who) run ``runs`` times in a fresh process (:func:`spawn` with the
    arguments ``case N who``), round-robin over the configurations so that a change of the machine's load
    hits them alike.  ``line(run, key, rec)`` prints one progress line.  Returns per (case, N) the medians
    of build, solve and build+solve time of each side, the last run's ``keep`` fields, the loads, and the
    ratios peer / ours -- None where either side did not converge (a time to no solution is not a speed)."""
    import statistics

    print(f"machine: {machine()}; load average before: {load()}", flush=True)
    keys = [(c, N, who) for c in cases for N in Ns for who in ("ours", "peer")]
    got: dict = {k: [] for k in keys}
    for r in range(runs):
        for k in keys:
            rec = spawn(script, [k[0], str(k[1]), k[2]], timeout)
            got[k].append(rec)
            line(r, k, rec)
    print(f"load average after: {load()}")
    med = statistics.median
    out = []
    for c in cases:
        for N in Ns:
            o = [x for x in got[(c, N, "ours")] if "solve_s" in x]
            p = [x for x in got[(c, N, "peer")] if "solve_s" in x]
            if not o or not p:
                out.append({"case": c, "N": N, "status": "missing runs"})
                continue
            rec = {"case": c, "N": N, "runs": min(len(o), len(p))}
            for who, xs in (("ours", o), ("peer", p)):
                rec[who] = {"build_s": med(x["build_s"] for x in xs), "solve_s": med(x["solve_s"] for x in xs),
                            "total_s": med(x["build_s"] + x["solve_s"] for x in xs),
                            "loads": [x.get("load") for x in xs],
                            **{f: xs[-1][f] for f in ("iterations", "converged", "status", *keep) if f in xs[-1]}}
            both = rec["ours"].get("converged") and rec["peer"].get("converged")
            rec["solve_ratio"] = rec["peer"]["solve_s"] / rec["ours"]["solve_s"] if both else None
            rec["total_ratio"] = rec["peer"]["total_s"] / rec["ours"]["total_s"] if both else None
            out.append(rec)
    return out
