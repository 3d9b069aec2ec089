"""Running a sweep: every grid point by every method, in chains along the continuation axis (each
point warm-started from the last converged ones of its chain), on any executor."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable


from ...transcription.results.start import secant
from .executors import Executor, make_executor
from .schema import Sweep
from .task import failed_row, solve_point


#: a secant step larger than this multiple of the last spacing falls back to the neighbour
MAX_SECANT_RATIO = 3.0


def _predict(history: list, value, numeric: bool) -> dict | None:
    """The warm start of the point at axis ``value`` from the last converged (value, Start) pairs of its
    chain, as {'start': Start, 'kind': 'neighbour' | 'secant'}: the neighbour's, or the secant
    extrapolation of the last two (transcription.results.start.secant, on SE(3))."""
    if not history:
        return None
    v1, w1 = history[-1]
    out = {"start": w1, "kind": "neighbour"}
    if len(history) >= 2 and numeric:
        v0, w0 = history[-2]
        r = (value - v1) / (v1 - v0) if v1 != v0 else math.inf
        predicted = secant(w0, w1, r) if math.isfinite(r) and abs(r) <= MAX_SECANT_RATIO else None
        if predicted is not None:
            out = {"start": predicted, "kind": "secant"}
    return out


@dataclass
class SweepResult:
    sweep: Sweep
    rows: list            # dicts: point, method, axis values, RESULT_COLUMNS
    continuation: bool
    executor: str
    workers: int | None
    wall_s: float
    interrupted: bool = False

    @property
    def n_tasks(self) -> int:
        return len(self.sweep.points()) * len(self.sweep.row_methods())

    def summary(self) -> dict:
        rows = self.rows
        by = {}
        for m in self.sweep.row_methods():
            r = [x for x in rows if x["method"] == m]
            by[m] = {"points": len(r), "converged": sum(x["converged"] for x in r),
                     "iterations": sum(x["iterations"] for x in r),
                     "iterations_total": sum(x["iterations_total"] for x in r),
                     "warm_started": sum(x["warm_started"] for x in r),
                     "fallbacks_to_cold": sum(x["start"] == "cold_after_failed_warm" for x in r)}
        return {"name": self.sweep.name, "sweep": self.sweep.source, "base": str(self.sweep.base),
                "axes": {a.name: list(a.values) for a in self.sweep.axes}, "methods": list(self.sweep.row_methods()),
                "continuation": self.continuation,
                "continuation_axis": self.sweep.axes[self.sweep.continuation_axis].name if self.continuation else None,
                "executor": self.executor, "workers": self.workers, "tasks": self.n_tasks, "finished": len(rows),
                "converged": sum(x["converged"] for x in rows), "all_converged": self.all_converged,
                "interrupted": self.interrupted, "wall_s": self.wall_s, "by_method": by}

    @property
    def all_converged(self) -> bool:
        return len(self.rows) == self.n_tasks and all(r["converged"] for r in self.rows)


def run_sweep(sweep: Sweep, *, workers: int | None = None, scheduler: str | None = None,
              continuation: bool | None = None, progress: Callable[[dict, int, int], None] | None = None,
              check_interrupt: Callable[[], None] | None = None, executor: Executor | None = None) -> SweepResult:
    """Run every grid point by every method; failures are rows, never exceptions.

    continuation: None -> the sweep file's setting.  progress(row, done, total) after each task.
    On KeyboardInterrupt the workers are stopped and the exception carries the rows
    finished so far as ``exc.partial`` (a SweepResult).
    """
    cont = sweep.continuation if continuation is None else bool(continuation)
    pts = sweep.points()
    methods = sweep.row_methods()
    text = sweep.base.read_text()
    chains = sweep.chains(cont)
    ax = sweep.axes[sweep.continuation_axis]
    ex = executor or make_executor(workers, scheduler)
    n_workers = ex.workers
    total = len(pts) * len(methods)
    rows: list[dict] = []
    t0 = time.perf_counter()
    # chain state per (chain id, method): next position, converged history [(axis value, payload)]
    state = {(c, m): {"pos": 0, "hist": []} for c in range(len(chains)) for m in methods}
    pending: dict = {}

    def submit(key):
        c, m = key
        st = state[key]
        p = pts[chains[c][st["pos"]]]
        warm = _predict(st["hist"], p.values[ax.name], ax.numeric) if cont else None
        task = {"source": str(sweep.base), "text": text, "overrides": list(p.overrides), "method": m, "warm": warm}
        pending[ex.submit(solve_point, task)] = (key, p, warm)

    def finish(fut):
        key, p, warm = pending.pop(fut)
        try:
            out = fut.result()
        except Exception as exc:  # the worker itself died (not a solver failure: those are rows)
            out = {"row": failed_row("worker_failed", "cold" if not warm else warm["kind"], exc), "payload": None}
        row = {"point": p.index, "method": key[1], **p.values, **out["row"]}
        rows.append(row)
        st = state[key]
        if out["payload"] is not None:
            st["hist"] = (st["hist"] + [(p.values[ax.name], out["payload"])])[-2:]
        st["pos"] += 1
        if progress:
            progress(row, len(rows), total)
        if st["pos"] < len(chains[key[0]]):
            submit(key)

    interrupted = False
    try:
        for key in state:
            submit(key)
            if check_interrupt:
                check_interrupt()
        while pending:
            for f in ex.wait_first(pending):
                finish(f)
            if check_interrupt:
                check_interrupt()
    except KeyboardInterrupt as exc:
        interrupted = True
        ex.shutdown(cancel=True)
        exc.partial = SweepResult(sweep, _sorted(rows, methods), cont, ex.kind, n_workers,
                                  time.perf_counter() - t0, interrupted=True)
        raise
    finally:
        if not interrupted and executor is None:
            ex.shutdown()
    return SweepResult(sweep, _sorted(rows, methods), cont, ex.kind, n_workers, time.perf_counter() - t0)


def _sorted(rows, methods):
    order = {m: i for i, m in enumerate(methods)}
    return sorted(rows, key=lambda r: (r["point"], order[r["method"]]))
