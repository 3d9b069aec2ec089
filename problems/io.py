"""Results on disk, file by file: every file is written atomically, complete or absent.

:func:`atomic_write_bytes` (and ``write_json``/``write_yaml``/``write_npz``/``save_figure`` on top
of it) writes a temporary file beside the target and renames it into place, so a file is
complete or absent, never half written; :func:`atomic_output` does the same for writers that
want a path (matplotlib animations).  Files get the mode of an ordinary new file (0666 minus the
umask, e.g. 0644), not mkstemp's 0600.  A file-system fault is a one-line
:class:`ResultsDirError` naming the file, never a traceback.

Whole results directories, written as one transaction, are :mod:`problems.results_dir`.  This
module needs nothing POSIX-only (no file locks), so that drawing and writing figures works
wherever Python and matplotlib do.
"""
from __future__ import annotations

import contextlib
import csv
import errno
import io
import json
import os
import secrets
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ..transcription.results.solution import to_jsonable
from .schema import yaml_dump


class ResultsDirError(Exception):
    """A results directory or file that cannot be used or written: one line, naming the path."""


def safe_name(name: str) -> str:
    """A file or directory name from a user's name (a maneuver, a sweep, an axis): every character
    other than a letter, a digit, '-', '_' or '.' becomes '_'."""
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name)


def _fs_error(path, e: OSError | ValueError, doing: str) -> ResultsDirError:
    """One line for a file-system fault: ``PATH: cannot DOING (reason)``."""
    if isinstance(e, ValueError):  # a NUL byte in the path
        return ResultsDirError(f"{_show(path)}: cannot {doing} ({e})")
    reason = e.strerror or str(e)
    if e.errno == errno.ENOTDIR:
        reason += "; a part of the path is a file"
    elif e.errno == errno.ENAMETOOLONG:
        reason += "; use a shorter name"
    return ResultsDirError(f"{_show(path)}: cannot {doing} ({reason})")


def _show(path) -> str:
    s = str(path)
    return s if s.isprintable() else repr(s)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file in the same directory, fsync,
    rename): ``path`` is the old file or the complete new one.  The directory must exist.
    Mode 0666 minus the umask.  OSError -> :class:`ResultsDirError` naming ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    fd = -1
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        _write_all(fd, data)
        os.fsync(fd)
        os.close(fd)
        fd = -1
        os.replace(tmp, path)
    except BaseException as e:
        if fd >= 0:
            os.close(fd)
        with contextlib.suppress(OSError, ValueError):
            os.unlink(tmp)
        if isinstance(e, (OSError, ValueError)):
            raise _fs_error(path, e, "write") from None
        raise


@contextlib.contextmanager
def atomic_output(path: Path) -> Iterator[Path]:
    """For writers that need a file name: yields a temporary path beside ``path`` with the
    same suffix (``.maneuver.gif.XXXXXXXX.tmp.gif``), renamed to ``path`` when the block ends
    normally and deleted otherwise (an interrupted animation leaves no temporary GIF)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY | os.O_CLOEXEC)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError, ValueError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise _fs_error(path, e, "write") from None
        raise


def write_json(path: Path, obj: Any) -> None:
    atomic_write_bytes(path, (json.dumps(to_jsonable(obj), indent=2, allow_nan=True) + "\n").encode())


def write_yaml(path: Path, obj: Any) -> None:
    """:func:`yaml_text` of ``obj`` into ``path`` (atomically)."""
    atomic_write_bytes(path, yaml_text(obj).encode())


def yaml_text(obj: Any) -> str:
    """YAML that reads back as written with the project's YAML 1.2 loader and with YAML 1.1."""
    return yaml_dump(to_jsonable(obj))


def _csv_cell(v):
    """One CSV cell: booleans as true/false, floats by repr (round-trips), lists and mappings as JSON, None empty."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return "" if v is None else v


def write_csv(path: Path, columns: list[str], rows: list[dict]) -> None:
    """A CSV file (atomically) of ``rows`` (mappings) with the header ``columns``; absent cells empty."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([_csv_cell(r.get(c)) for c in columns])
    atomic_write_bytes(path, buf.getvalue().encode())


def write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    buf = io.BytesIO()
    np.savez(buf, **{k: np.asarray(v) for k, v in arrays.items()})
    atomic_write_bytes(path, buf.getvalue())


def save_figure(fig, path_stem: Path) -> list[Path]:
    """Save a matplotlib figure as PNG and PDF (atomically); returns the paths."""
    return write_figure(figure_files(fig), path_stem)


def figure_files(fig) -> dict[str, bytes]:
    """The files of a matplotlib figure as :func:`save_figure` writes them: {"png": PNG at 130 dpi, "pdf": PDF}."""
    out = {}
    for ext in ("png", "pdf"):
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, dpi=130 if ext == "png" else None, bbox_inches="tight")
        out[ext] = buf.getvalue()
    return out


def write_figure(files: dict[str, bytes], path_stem: Path) -> list[Path]:
    """Write :func:`figure_files` as ``path_stem.png`` and ``path_stem.pdf`` (atomically); returns the paths."""
    out = []
    for ext, data in files.items():
        p = Path(f"{path_stem}.{ext}")
        atomic_write_bytes(p, data)
        out.append(p)
    return out
