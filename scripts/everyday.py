"""The everyday-maneuver suite (configs/everyday/): solve every maneuver with the default settings and
report the result, the re-simulated terminal error, IPOPT iterations, times and the initial guesses tried.

    .venv/bin/python scripts/everyday.py                      # all cases -> docs/everyday_<tag>.json
    .venv/bin/python scripts/everyday.py --tag before         # e.g. on the code before a change
    .venv/bin/python scripts/everyday.py --table              # docs/everyday.md from before/after JSON
    .venv/bin/python scripts/everyday.py --one FILE           # one case, its record as a JSON line

Each case runs in a fresh Python process (benchkit.spawn), so one case's compiled code or memory does
not colour the next one's time.  Thin over the public API: ``se3ocp.load`` and ``se3ocp.solve``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import benchkit  # noqa: E402

ROOT = benchkit.ROOT
SUITE = ROOT / "configs" / "everyday"
DOCS = ROOT / "docs"


def one(path: str) -> dict:
    """Solve one maneuver file with the defaults; its record."""
    import se3ocp

    man = se3ocp.load(path)
    t0 = time.perf_counter()
    sol = se3ocp.solve(man)
    wall = time.perf_counter() - t0
    return {"case": Path(path).stem, "scheme": man.discretization, "model": man.resolved["model"]["kind"],
            "N": man.N, "T": man.T, "result": str(sol.result), "converged": bool(sol.converged),
            "terminal_error": float(sol.terminal_error), "cost": float(sol.cost), "iterations": int(sol.iterations),
            "build_s": float(sol.build_s), "solve_s": float(sol.solve_s), "wall_s": wall,
            "guesses_tried": [a.line() for a in sol.trace], "message": sol.message}


def run(tag: str, cases: list[Path], timeout: float) -> Path:
    rows = []
    for path in cases:
        rec = benchkit.spawn(Path(__file__), [str(path)], timeout=timeout)
        rec.setdefault("case", path.stem)
        rows.append(rec)
        print(f"{rec['case']:<24} {rec.get('result', rec.get('status')):<16} its {rec.get('iterations', '-'):>5} "
              f"solve {rec.get('solve_s', float('nan')):7.2f} s  err {rec.get('terminal_error', float('nan')):.1e}  "
              f"{' | '.join(rec.get('guesses_tried', []))}", flush=True)
    out = DOCS / f"everyday_{tag}.json"
    out.write_text(json.dumps({"machine": benchkit.machine(), "load_after": benchkit.load(), "cases": rows},
                              indent=1) + "\n")
    print(f"wrote {out} (load average {benchkit.load()})")
    return out


def _cell(rec: dict | None) -> str:
    """result | iterations | solve s | cost | terminal error of one record."""
    if rec is None or "iterations" not in rec:
        return f"{(rec or {}).get('status', '-')} | - | - | - | -"
    return (f"{rec['result']} | {rec['iterations']} | {rec['solve_s']:.1f} | {rec['cost']:.7g} | "
            f"{rec['terminal_error']:.1e}")


def table() -> str:
    """The before/after Markdown table of docs/everyday_before.json and docs/everyday_after.json."""
    data = {t: json.loads((DOCS / f"everyday_{t}.json").read_text()) for t in ("before", "after")
            if (DOCS / f"everyday_{t}.json").exists()}
    by = {t: {r["case"]: r for r in d["cases"]} for t, d in data.items()}
    cases = list(dict.fromkeys([c for d in by.values() for c in d]))
    lines = ["| case | scheme, model, N, T | before: result | its | solve s | cost | term. err | after: result | its | "
             "solve s | cost | term. err | guesses tried before → after |", "|" + "---|" * 13]
    for c in cases:
        a, b = by.get("before", {}).get(c), by.get("after", {}).get(c)
        r = b or a
        desc = f"{r.get('scheme', '?')}, {r.get('model', '?')}, {r.get('N', '?')}, {r.get('T', '?')}"
        tried = " → ".join("; ".join((x or {}).get("guesses_tried", [])) or "-" for x in (a, b))
        lines.append(f"| {c} | {desc} | {_cell(a)} | {_cell(b)} | {tried} |")
    foot = [f"* {t}: {d['machine']}; load average (1, 5, 15 min) after the run {d['load_after']}"
            for t, d in data.items()]
    return "\n".join(lines + [""] + foot) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--one", help="solve one file and print its record")
    ap.add_argument("--tag", default="after", help="the JSON written is docs/everyday_<tag>.json")
    ap.add_argument("--table", action="store_true", help="print the before/after table")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per case")
    ap.add_argument("cases", nargs="*", help="maneuver files (default: configs/everyday/*.yaml)")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.one)))
        return
    if args.table:
        print(table(), end="")
        return
    run(args.tag, [Path(c) for c in args.cases] or sorted(SUITE.glob("*.yaml")), args.timeout)


if __name__ == "__main__":
    main()
