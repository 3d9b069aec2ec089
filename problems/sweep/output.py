"""What a sweep writes: results.csv, results.jsonl, summary.json, sweep.resolved.yaml and the
figures, each file atomically."""
from __future__ import annotations

import json
import math
from pathlib import Path

from ..io import atomic_write_bytes, write_csv, write_json, write_yaml
from .figures import draw_sweep
from .run import SweepResult
from .schema import RESULT_COLUMNS, Sweep


def _finite_or_none(v):
    """JSON lines stay strict JSON: NaN/inf (a failed point's cost) become null."""
    return None if isinstance(v, float) and not math.isfinite(v) else v


def columns(sweep: Sweep) -> list[str]:
    return ["point", "method", *(a.name for a in sweep.axes), *RESULT_COLUMNS]


def write_results(out: Path, result: SweepResult, figures: bool = True) -> list[Path]:
    """results.csv, results.jsonl, summary.json, sweep.resolved.yaml and the figures (atomic writes)."""
    out = Path(out)
    cols = columns(result.sweep)
    write_csv(out / "results.csv", cols, result.rows)
    pts = result.sweep.points()
    lines = [json.dumps({**{c: _finite_or_none(r.get(c)) for c in cols}, "overrides": list(pts[r["point"]].overrides)},
                        allow_nan=False) for r in result.rows]
    atomic_write_bytes(out / "results.jsonl", ("\n".join(lines) + "\n" if lines else "").encode())
    write_json(out / "summary.json", result.summary())
    write_yaml(out / "sweep.resolved.yaml", {**result.sweep.doc, "base": str(result.sweep.base)})
    written = [out / n for n in ("results.csv", "results.jsonl", "summary.json", "sweep.resolved.yaml")]
    if figures and result.rows:
        written += draw_sweep(out, result)
    return written
