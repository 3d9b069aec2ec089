"""Results on disk: atomic writes and results-directory policy.

Every file is written to a temporary name in the same directory and renamed
into place, so an interrupted run (Ctrl-C, crash) never leaves a half-written
file under its final name.
"""
from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..transcription.results import to_jsonable


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_json(path: Path, obj: Any) -> None:
    atomic_write_bytes(path, (json.dumps(to_jsonable(obj), indent=2, allow_nan=True) + "\n").encode())


def write_yaml(path: Path, obj: Any) -> None:
    atomic_write_bytes(path, yaml.safe_dump(to_jsonable(obj), sort_keys=False).encode())


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    buf = io.BytesIO()
    np.savez(buf, **{k: np.asarray(v) for k, v in arrays.items()})
    atomic_write_bytes(path, buf.getvalue())


def save_figure(fig, path_stem: Path) -> list[Path]:
    """Save a matplotlib figure as PNG and PDF (atomically); returns the paths."""
    out = []
    for ext in ("png", "pdf"):
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, dpi=130 if ext == "png" else None, bbox_inches="tight")
        p = Path(f"{path_stem}.{ext}")
        atomic_write_bytes(p, buf.getvalue())
        out.append(p)
    return out


class ResultsDirError(Exception):
    pass


def prepare_results_dir(out: str | None, default: Path, force: bool) -> Path:
    """Choose the results directory.

    * ``--out DIR`` given: DIR is used; if it already holds files, only with --force
      (otherwise :class:`ResultsDirError`).
    * no ``--out``: ``default``; if that already holds files and --force is not given,
      a fresh numbered sibling ``default.1``, ``default.2``, ... is used instead, so
      runs are never silently mixed.
    """
    if out is not None:
        d = Path(out)
        if d.exists() and not d.is_dir():
            raise ResultsDirError(f"{d}: exists and is not a directory")
        if d.is_dir() and any(d.iterdir()) and not force:
            raise ResultsDirError(f"{d}: results directory already holds files; pass --force to overwrite, or choose another --out")
    else:
        d = default
        if d.is_dir() and any(d.iterdir()) and not force:
            i = 1
            while Path(f"{default}.{i}").exists():
                i += 1
            d = Path(f"{default}.{i}")
    d.mkdir(parents=True, exist_ok=True)
    return d
