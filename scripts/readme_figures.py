"""Regenerate the README's figures and its direct-vs-indirect comparison table.

Runs the bundled examples through the CLI (``se3ocp solve``/``compare``), copies the figures the
README shows to ``docs/figures/`` (``<stem>_<figure>.png``) and rewrites the block between the
``<!-- comparison:start -->`` / ``<!-- comparison:end -->`` markers of README.md: the paper's four
examples (docs/mathematics.md §9) and the bounded and free-time E3 (§10), by both methods.  Figures
only (not in the table; the indirect method does not cover them): the two slews without a central
body, the minimum-radius E3 and the fuel-optimal orbit raise.  Drawn through the public API:
``failed_*`` (E4 stopped after two IPOPT iterations, to show how a failed run is marked) and
``e3_animation.png``, a frame of the animation of E3.

    .venv/bin/python scripts/readme_figures.py            # the configs' N, a few minutes
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
    # (label, config, command, extra --set overrides, stem of the figure files)
    ("E1", "e1_impulsive_tpbvp", "solve", [], "e1"),
    ("E2", "e2_impulsive_relaxed", "solve", [], "e2"),
    ("E3", "e3_inclination_change", "compare", [], "e3"),
    ("E4 (λ₀ = 0)", "e4_orbital_capture", "compare", [], "e4"),
    ("E4 (from direct)", "e4_orbital_capture", "compare", ["solver.indirect.initial_costate=from_direct"], "e4_from_direct"),
    ("E3 bounded", "e3_bounded", "compare", [], "e3_bounded"),
    ("E3 free T", "e3_free_time", "compare", [], "e3_free_time"),
]
#: runs for figures only (not in the comparison table; their own N): (stem, config, command)
FIGURE_RUNS = [("slew_keep_out", "slew_keep_out", "solve"), ("slew_time_optimal", "slew_time_optimal", "solve"),
               ("e3_min_radius", "e3_min_radius", "solve"), ("orbit_raise_fuel", "orbit_raise_fuel", "solve")]
#: the figures the README shows, per stem
FIGS = {
    "e1": ("maneuver",),
    "e2": ("maneuver",),
    "e3": ("maneuver", "attitude", "attitude_error", "control_norms", "thrust_rtn", "orbital_elements", "costates"),
    "e4": ("convergence",),
    "e3_bounded": ("control_norms", "moment"),
    "slew_keep_out": ("maneuver", "attitude", "constraints"),
    "slew_time_optimal": ("moment",),
    "e3_min_radius": ("orbital_elements",),
    "orbit_raise_fuel": ("control_norms", "thrust_rtn"),
}


def run(label, config, command, sets, N, work: Path):
    out = work / label.replace(" ", "_").replace("(", "").replace(")", "").replace("λ₀_=_0", "zero")
    args = [sys.executable, "-m", "se3ocp.problems.cli", command, str(ROOT / "configs" / f"{config}.yaml"),
            "--out", str(out), "--force", "--json"]
    for s in sets + ([f"horizon.N={N}"] if N else []):
        args += ["--set", s]
    print(f"{label}: {' '.join(args[3:])}", flush=True)
    r = subprocess.run(args, cwd=ROOT, capture_output=True, text=True)
    if r.returncode not in (0, 1):
        raise SystemExit(f"{label} failed (exit {r.returncode}):\n{r.stderr}")
    return out, json.loads(r.stdout)


def _save(fig, path: Path):
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)


def demonstrations(figdir: Path, N: int | None):
    """failed_*: E4 stopped by max_iter (public API, figures as the CLI draws them)."""
    import matplotlib

    matplotlib.use("Agg")
    import se3ocp

    man = se3ocp.load(ROOT / "configs" / "e4_orbital_capture.yaml", [f"horizon.N={N or 200}", "solver.direct.max_iter=2"])
    for name, fig in se3ocp.plot(se3ocp.solve(man), ("maneuver",)).items():
        _save(fig, figdir / f"failed_{name}.png")
    print("failed_* drawn", flush=True)


def animation_frame(results: Path, path: Path):
    """A frame of the animation (mid-maneuver) as a PNG."""
    from PIL import Image

    from se3ocp.problems.plots import Animation
    from se3ocp.problems.store import read_run

    res = read_run(results).result
    anim = Animation(res)
    Image.fromarray(anim.frame(0.4 * (anim.t0 + anim.t1))).save(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--N", type=int, default=None, help="override horizon.N for every example (default: the configs')")
    ap.add_argument("--no-readme", action="store_true", help="do not rewrite README.md")
    a = ap.parse_args()
    figdir = ROOT / "docs" / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    rows = []
    demonstrations(figdir, a.N)
    with tempfile.TemporaryDirectory() as tmp:
        for label, config, command, sets, stem in RUNS:
            out, summary = run(label, config, command, sets, a.N, Path(tmp))
            for f in FIGS.get(stem, ()):
                src = out / f"fig_{f}.png"
                if src.exists():
                    shutil.copyfile(src, figdir / f"{stem}_{f}.png")
            if stem == "e3":
                animation_frame(out, figdir / "e3_animation.png")
            verdict = summary.get("comparison", {}).get("verdict", "")
            for m, s in summary["methods"].items():
                rows.append((label, m, s, verdict if m == "indirect" else ""))
        for stem, config, command in FIGURE_RUNS:  # their own N: the slews are not scaled with --N
            out, _ = run(stem, config, command, [], None, Path(tmp))
            for f in FIGS[stem]:
                shutil.copyfile(out / f"fig_{f}.png", figdir / f"{stem}_{f}.png")
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
