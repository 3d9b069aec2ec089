"""Regenerate the README's figures and its direct-vs-indirect comparison table.

Runs the four bundled examples (docs/mathematics.md §9) through the CLI (``se3ocp solve``/``compare``),
copies the figures to ``docs/figures/`` and rewrites the block between the
``<!-- comparison:start -->`` / ``<!-- comparison:end -->`` markers of README.md.

    .venv/bin/python scripts/readme_figures.py            # full size (N = 500/800), a few minutes
    .venv/bin/python scripts/readme_figures.py --N 100    # quick look
"""
from __future__ import annotations

import argparse
import json
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

RUNS = [
    # (label, config, command, extra --set overrides)
    ("E1", "e1_impulsive_tpbvp", "solve", []),
    ("E2", "e2_impulsive_relaxed", "solve", []),
    ("E3", "e3_inclination_change", "compare", []),
    ("E4 (λ₀ = 0)", "e4_orbital_capture", "compare", []),
    ("E4 (from direct)", "e4_orbital_capture", "compare", ["solver.indirect.initial_costate=from_direct"]),
]
FIGS = ("maneuver", "convergence", "velocity", "angular_velocity", "force", "moment")


def run(label, config, command, sets, N, work: Path):
    out = work / config / ("from_direct" if sets else "default")
    args = [sys.executable, "-m", "se3ocp.problems.cli", command, str(ROOT / "configs" / f"{config}.yaml"),
            "--out", str(out), "--force", "--json"]
    for s in sets + ([f"horizon.N={N}"] if N else []):
        args += ["--set", s]
    print(f"{label}: {' '.join(args[3:])}", flush=True)
    r = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
    if r.returncode not in (0, 1):
        raise SystemExit(f"{label} failed (exit {r.returncode}):\n{r.stderr}")
    return out, json.loads(r.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--N", type=int, default=None, help="override horizon.N for every example (default: the configs')")
    ap.add_argument("--no-readme", action="store_true", help="do not rewrite README.md")
    a = ap.parse_args()
    figdir = ROOT / "docs" / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, config, command, sets in RUNS:
            out, summary = run(label, config, command, sets, a.N, Path(tmp))
            stem = config.split("_")[0] + ("_from_direct" if sets else "")
            for f in FIGS:
                src = out / f"fig_{f}.png"
                if src.exists():
                    shutil.copyfile(src, figdir / f"{stem}_{f}.png")
            verdict = summary.get("comparison", {}).get("verdict", "")
            for m, s in summary["methods"].items():
                rows.append((label, m, s, verdict if m == "indirect" else ""))
    lines = [
        f"Produced by `.venv/bin/python scripts/readme_figures.py{' --N ' + str(a.N) if a.N else ''}` on "
        f"{platform.processor() or platform.machine()} ({platform.python_version()}); times in seconds, one run each.",
        "",
        "| example | method | status | cost | terminal error | max ‖RᵀR−I‖ | iterations | build s | solve s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, m, s, _ in rows:
        lines.append(f"| {label} | {m} | {s['status']} | {s['cost']:.10g} | {s['terminal_error']:.1e} | "
                     f"{s['max_orthogonality_error']:.1e} | {s['iterations']} | {s['build_s']:.2f} | {s['solve_s']:.2f} |")
    verdicts = [(label, v) for label, _, _, v in rows if v]
    if verdicts:
        lines.append("")
        lines += [f"* {label}: {v}" for label, v in verdicts]
    table = "\n".join(lines)
    (ROOT / "docs" / "comparison.md").write_text(table + "\n")
    print(table)
    if not a.no_readme:
        readme = ROOT / "README.md"
        text = readme.read_text()
        start, end = "<!-- comparison:start -->", "<!-- comparison:end -->"
        if start in text and end in text:
            head, rest = text.split(start, 1)
            _, tail = rest.split(end, 1)
            readme.write_text(f"{head}{start}\n{table}\n{end}{tail}")
            print("README.md updated")


if __name__ == "__main__":
    main()
