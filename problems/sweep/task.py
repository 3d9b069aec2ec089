"""The unit of work of a sweep: :func:`solve_point`, one grid point by one method, from plain
data to plain data (so that it can run in another process or on a Dask worker), with the
warm-start payload it hands to the next point of its chain."""
from __future__ import annotations

import copy
import time


from ..maneuvers import parse_maneuver
from ..schema import apply_override, yaml_load


def _maneuver_from_text(source: str, text: str, overrides):
    """load_maneuver on a file's text (workers of a remote cluster need not see the file)."""
    doc = yaml_load(text) or {}
    doc = copy.deepcopy(doc)
    for a in overrides:
        apply_override(doc, a)
    return parse_maneuver(doc, source)


def _payload(sol):
    """What a point hands to the next point of its chain: its Solution's warm start if it converged (a
    transcription.results.start.Start: plain arrays, so it travels to another process), else None."""
    return sol.warm if sol.converged else None


def _solve(man, method: str, warm: dict | None):
    """(final Solution, warm_started, start, iterations_total): a warm solve from the payload, and a
    cold one if there is none or it fails (through the one dispatcher, transcription.solve)."""
    from ...transcription.solve import solve
    from ..api import check_clearance

    problem = man.problem

    def run(ws=None):
        return check_clearance(man, solve(problem, method, direct=man.direct, indirect=man.indirect, warm_start=ws,
                                          accuracy=man.accuracy))

    ws = warm["start"] if warm and man.control_kind == "smooth" else None
    if ws is None:
        sol = run()
        return sol, False, "cold" if not warm else "cold_warm_start_does_not_fit", sol.iterations
    try:
        sol = run(ws)
    except Exception:  # noqa: BLE001 - a warm start that breaks the solver is a failed warm start
        sol = None
    if sol is not None and sol.converged:
        return sol, True, warm.get("kind", "neighbour"), sol.iterations
    first = sol.iterations if sol is not None else 0
    sol = run()
    return sol, False, "cold_after_failed_warm", first + sol.iterations


def solve_point(task: dict) -> dict:
    """One grid point by one method: the unit of work sent to a pool or a Dask cluster.

    task: {'source': base file name, 'text': its YAML text, 'overrides': [KEY=VALUE, ...],
    'method': 'direct' | 'indirect', 'warm': None | {'start': Start, 'kind': 'neighbour' | 'secant'}}.
    Returns {'row': result fields (RESULT_COLUMNS), 'payload': warm start for the next
    point or None}.  Never raises for a failing solve: the error is the row's status.
    """
    t0 = time.perf_counter()
    try:
        man = _maneuver_from_text(task["source"], task["text"], task["overrides"])
        sol, warm_started, start, total = _solve(man, task["method"], task.get("warm"))
    except Exception as exc:  # a failing point is data; the sweep goes on
        start = "cold" if not task.get("warm") else task["warm"].get("kind", "neighbour")
        return {"row": failed_row("error", start, exc, solve_s=time.perf_counter() - t0), "payload": None}
    row = dict(status=sol.result.value, converged=bool(sol.converged), cost=float(sol.cost),
               terminal_error=float(sol.terminal_error), iterations=int(sol.iterations), iterations_total=int(total),
               build_s=float(sol.build_s), solve_s=float(sol.solve_s), warm_started=bool(warm_started), start=start,
               message=" ".join(str(sol.message).split()))
    return {"row": row, "payload": _payload(sol)}


def failed_row(status: str, start: str, exc: BaseException, solve_s: float = 0.0) -> dict:
    """The result row (RESULT_COLUMNS) of a task that raised (``status`` "error") or whose worker
    died ("worker_failed"): no numbers, the exception in one line of at most 500 characters."""
    return dict(status=status, converged=False, cost=float("nan"), terminal_error=float("nan"), iterations=0,
                iterations_total=0, build_s=0.0, solve_s=solve_s, warm_started=False, start=start,
                message=f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500])
