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
