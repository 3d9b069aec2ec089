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
    miss (position / L, velocity / V, rad, rad per time unit; the number solver.accuracy bounds).  ``flown
    miss``: the same flight's terminal miss as a percentage of what the maneuver changes
    (ContinuousCheck.maneuver_fraction), with '!' above :data:`FLOWN_MISS_TOL`; then a line per flown
    method in the file's units (:func:`miss_lines`), and the burns of each plan with a force
    (:func:`problems.burns.burn_lines`)."""
    from ...transcription.outcome import Result
    from ..burns import burn_lines

    sols = list(sols)
    mw = max([len("method")] + [len(s.method) for s in sols])
    sw = max([len("status")] + [len(str(s.result.value)) for s in sols])
    head = (f"{'method':<{mw}} {'status':<{sw}} {'cost':>14} {'term. err':>10} {'cont. miss':>10} {'flown miss':>10} "
            f"{'orth. err':>10} {'iters':>6} {'build s':>8} {'solve s':>8}")
    rows = [head, "-" * len(head)]
    for s in sols:
        if s.result is Result.not_applicable:
            rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {'-':>14} {'-':>10} {'-':>10} {'-':>10} {'-':>10} "
                        f"{'-':>6} {'-':>8} {'-':>8}")
            continue
        o = s.trajectory.orthogonality()["max_orthogonality_error"]
        miss = getattr(s, "continuous_miss", None)   # the scaled miss solver.accuracy judges; "-" if not flown
        miss = f"{miss:>10.2e}" if miss is not None else f"{'-':>10}"
        rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {s.cost:>14.8g} {s.terminal_error:>10.2e} {miss} "
                    f"{_percent(s):>10} {o:>10.2e} {s.iterations:>6d} {s.build_s:>8.2f} {s.solve_s:>8.2f}")
    return rows + miss_lines(sols) + burn_lines(sols) + engine_lines(sols)


def engine_lines(sols) -> list[str]:
    """A line per method found infeasible because its engine is too weak (``stats['least_peak_force']``, the least peak
    force of the maneuver with the thrust pointing anywhere): that force and the engine's, in N for a physical file."""
    from ..units import units

    out = []
    for s in sols:
        need = (getattr(s, "stats", None) or {}).get("least_peak_force")
        if need is None:
            continue
        bound = s.problem.control.force_bound       # an engine's: the stat is only made for one
        unit, f = units(s.problem).shown("force")
        unit = f" {unit}" if unit else ""
        out.append(f"{s.method}: the engine would need a thrust above {f * need:.4g}{unit} at its peak, the least the "
                   f"maneuver needs with the thrust pointing anywhere; it gives {f * bound.engine_range[1]:.4g}{unit}")
    return out


def _percent(sol) -> str:
    from ...transcription.results.check import FLOWN_MISS_TOL
    c = getattr(sol, "continuous", None)
    f = math.nan if c is None else c.maneuver_fraction
    if not math.isfinite(f):
        return "-"
    return f"{100 * f:.2g} %" + ("!" if f > FLOWN_MISS_TOL else "")


def miss_lines(sols) -> list[str]:
    """One line per flown method: its terminal miss flown in continuous time, in the file's units, against what
    the maneuver changes; a 'warning:' line naming the miss and the cure when it exceeds
    :data:`FLOWN_MISS_TOL` of the maneuver."""
    from ...transcription.results.check import FLOWN_MISS_TOL
    from ..units import units

    out = []
    for s in sols:
        c = getattr(s, "continuous", None)
        if c is None or not c.ok or not math.isfinite(c.maneuver_fraction):
            continue
        u, parts = units(s.problem), c.maneuver_parts()
        if parts:
            quantity = {"position": "length", "velocity": "velocity", "attitude": "angle"}
            miss = ", ".join(u.amount(m, quantity[n]) for n, m, _ in parts)
            of = ", ".join(u.amount(ch, quantity[n]) for n, _, ch in parts)
        else:
            miss, of = f"terminal error {c.target_error:.3g}", f"{c.change_target:.3g} from the free motion"
        pct = f"{100 * c.maneuver_fraction:.2g} %"
        out.append(f"{s.method}: flown in continuous time it ends {miss} off its target: {pct} of the maneuver "
                   f"({of})")
        if c.maneuver_fraction > FLOWN_MISS_TOL:
            out.append(f"warning: {s.method}'s plan misses by {pct} of its maneuver, above "
                       f"{100 * FLOWN_MISS_TOL:g} %: " + (c.unstable_note() or f"the {s.scheme} scheme's error at N = "
                                                           f"{s.N}; " + _cure(s)))
    return out + path_lines(sols)


def path_lines(sols) -> list[str]:
    """One line per flown method with path constraints: each constraint's smallest margin along the continuous
    flight (ContinuousCheck.min_margins) in the file's units, with its tolerance; a 'warning:' line naming the
    constraints violated beyond it and the cure (ContinuousCheck.path_violations)."""
    from ...transcription.results.check import PATH_CURE, margin_kind

    out = []
    for s in sols:
        c = getattr(s, "continuous", None)
        if c is None or not c.ok or not c.margin_tolerances:
            continue
        amount = _margin_amount(s)
        margins = ", ".join(f"{margin_kind(k)} {amount(k, m)} (allowed down to {amount(k, -c.margin_tolerances[k])})"
                            for k, m in c.min_margins.items() if k in c.margin_tolerances)
        out.append(f"{s.method}: flown in continuous time its smallest path margin: {margins}")
        bad = c.path_violations()
        if bad:
            out.append(f"warning: {s.method}'s path leaves its constraints between the nodes: "
                       + ", ".join(f"{margin_kind(k)} by {amount(k, v)}" for k, v, _ in bad)
                       + f", beyond the tolerance: the {s.scheme} scheme's error at N = {s.N}; {PATH_CURE}")
    return out


def _margin_amount(sol):
    """(margin key, value in the margin's own unit) -> the value as text in the file's units (deg for a cone)."""
    from ...transcription.ocp import MARGIN_DIMENSION
    from ...transcription.results.check import margin_kind
    from ..units import units

    u = units(sol.problem)

    def amount(key: str, x: float) -> str:
        dim = MARGIN_DIMENSION.get(margin_kind(key), "none")
        return f"{x:.3g} deg" if dim == "angle" else u.amount(x, dim)
    return amount


def _cure(sol) -> str:
    if sol.scheme == "lgvi" and sol.problem is not None and sol.problem.model.mu:
        return "discretization: lgvi_kepler flies the orbit exactly, or raise horizon.N or set solver.accuracy"
    return "raise horizon.N or set solver.accuracy"


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
