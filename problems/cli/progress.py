"""What a run prints on stdout: progress and result lines (none with --quiet or --json), the
side-by-side table of the methods, the JSON summary; and the progress of a sweep on stderr."""
from __future__ import annotations

import json
import math
import os
import sys
import time

from ..sweep.schema import RESULT_COLUMNS, _label
from .signals import Interrupt


def say(args, *msg):
    """Print a progress or result line (not with --quiet or --json).  If stdout's reader went away
    (``se3ocp solve ... | head``), printing stops and the run goes on to write its results."""
    if not getattr(args, "quiet", False) and not getattr(args, "json", False):   # not every command has --json
        try:
            print(*msg, flush=True)
        except BrokenPipeError:
            stdout_gone()
            args.quiet = True


def stdout_gone() -> None:
    """Point stdout at /dev/null, so that neither later prints nor the flush at exit fail."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def emit_summary(args, summary: dict):
    """The summary as JSON on stdout (with --json)."""
    if args.json:
        print(json.dumps(summary, indent=2, default=float))


class Progress:
    """One line per iteration of any method (at most one a second after the first ten, and every
    Newton step and the first record of every new phase), so long solves show life without flooding;
    each line names the method, the seconds since the solve started and the phase
    (:meth:`~transcription.results.solution.Iterate.progress_line`).  Ctrl-C is honoured here."""

    def __init__(self, args):
        self.args = args
        self.last = 0.0
        self.count = 0
        self.phase = ""

    def __call__(self, rec):
        Interrupt.check()
        self.count += 1
        now = time.perf_counter()
        if (self.count > 10 and now - self.last < 1.0 and rec.trial == 0 and math.isnan(rec.step)
                and rec.phase == self.phase):
            return
        self.last, self.phase = now, rec.phase
        say(self.args, f"  {rec.progress_line()}")


def table(sols) -> list[str]:
    """The side-by-side table; the text columns are as wide as their widest entry (a status is
    never cut, however long).  ``cont. miss``: Solution.continuous_miss, the continuous check's scaled terminal
    miss (position / L, velocity / V, rad, rad per time unit; the number solver.accuracy bounds)."""
    from ...transcription.outcome import Result

    sols = list(sols)
    mw = max([len("method")] + [len(s.method) for s in sols])
    sw = max([len("status")] + [len(str(s.result.value)) for s in sols])
    head = (f"{'method':<{mw}} {'status':<{sw}} {'cost':>14} {'term. err':>10} {'cont. miss':>10} {'orth. err':>10} "
            f"{'iters':>6} {'build s':>8} {'solve s':>8}")
    rows = [head, "-" * len(head)]
    for s in sols:
        if s.result is Result.not_applicable:
            rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {'-':>14} {'-':>10} {'-':>10} {'-':>10} {'-':>6} "
                        f"{'-':>8} {'-':>8}")
            continue
        o = s.trajectory.orthogonality()["max_orthogonality_error"]
        miss = getattr(s, "continuous_miss", None)   # the scaled miss solver.accuracy judges; "-" if not flown
        miss = f"{miss:>10.2e}" if miss is not None else f"{'-':>10}"
        rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {s.cost:>14.8g} {s.terminal_error:>10.2e} {miss} {o:>10.2e} "
                    f"{s.iterations:>6d} {s.build_s:>8.2f} {s.solve_s:>8.2f}")
    return rows


class ProgressBar:
    """One line redrawn in place on a terminal; one line per finished task otherwise."""

    def __init__(self, stream=None, quiet: bool = False, width: int = 30):
        self.stream = stream or sys.stderr
        self.quiet, self.width = quiet, width
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self.bad = 0
        self.ended = False

    def __call__(self, row: dict, done: int, total: int):
        if self.quiet:
            return
        self.bad += not row["converged"]
        el = time.perf_counter() - self.t0
        if self.tty:
            k = int(self.width * done / max(total, 1))
            line = (f"\r[{'#' * k}{'.' * (self.width - k)}] {done}/{total} tasks, {self.bad} not converged, "
                    f"{el:.0f} s")
            self.ended = done == total
            self.stream.write(line + ("\n" if self.ended else ""))
        else:
            vals = {k: v for k, v in row.items() if k not in ("point", "method", *RESULT_COLUMNS)}
            self.stream.write(f"[{done:>{len(str(total))}}/{total}] {row['method']:<9} {_label(vals)}: "
                              f"{row['status']}, cost {row['cost']:.10g}, {row['iterations']} it ({row['start']}), "
                              f"{row['build_s'] + row['solve_s']:.2f} s\n")
        self.stream.flush()

    def close(self):
        if self.tty and not self.quiet and not self.ended:
            self.stream.write("\n")
            self.stream.flush()
