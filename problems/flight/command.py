"""``se3ocp fly CONFIG|RESULTS_DIR``: plan (or read the plan), fly it ``runs`` times, write the results.

Exit 0 when every flight finished, 1 when the plan did not converge (nothing written) or some flight
failed (the results are still written, the failures are rows), 2 for bad input; on Ctrl-C the runs
finished so far are written and marked INCOMPLETE, as sweeps do."""
from __future__ import annotations

import sys
import time
from pathlib import Path

from ..io import safe_name
from ..results_dir import results_transaction
from ..schema import ConfigError
from . import (_spec, check_feedback, check_plan, check_replanned_plan, check_truth, check_truth_plan, load_flight,
               spec_source, with_changes)
from .navigation import ESTIMATION_METRICS
from .task import ELEMENT_METRICS


def _flight_spec(args, man):
    """The flight block flown: --flight FILE, else the maneuver's own, with --runs and --feedback; ConfigError
    when it cannot be flown (MPC for a plan the re-planner does not cover)."""
    flight = args.flight
    spec = load_flight(flight, man) if flight else _spec(None, man)
    spec = with_changes(spec, spec_source(flight, man), runs=args.runs, feedback=args.feedback)
    check_feedback(man, spec, spec_source(flight, man))
    check_truth(man, spec, spec_source(flight, man))
    return spec


def _plan(args):
    """(Maneuver, its plan, the flight spec): a maneuver file solved by the direct method (after the flight
    block is checked), or a results directory's direct solution (else its indirect one)."""
    from .. import api
    from ..maneuvers import load_maneuver
    from ..store import read_run

    src = Path(args.plan)
    if src.is_dir():
        if args.overrides:
            raise ConfigError("--set", "", "applies to a maneuver file, not to a results directory")
        run = read_run(src)
        sols = run.solutions
        sol = sols.get("direct") or sols.get("indirect") or next(iter(sols.values()))
        return run.maneuver, sol, _flight_spec(args, run.maneuver)
    man = load_maneuver(src, args.overrides)
    if man.control_kind != "smooth":
        raise ConfigError(man.source, "control.kind", "only smooth-control plans are flown (give kind: smooth)")
    spec = _flight_spec(args, man)
    _say(args, f"{man.name}: planning by the direct method ({man.discretization}, N = {man.N}) ...")
    t0 = time.perf_counter()
    sol = api.solve(man, "direct")
    _say(args, f"  {sol.result} ({sol.message}); cost {sol.cost:.10g}, {time.perf_counter() - t0:.1f} s")
    return man, sol, spec


def _say(args, *msg):
    if not args.quiet:
        print(*msg, flush=True)


class FlightProgress:
    """One line per finished task: runs done, elapsed time, estimated time left (redrawn on a terminal)."""

    def __init__(self, quiet: bool = False, stream=None):
        self.quiet, self.stream = quiet, stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()

    def __call__(self, done: int, total: int):
        if self.quiet:
            return
        el = time.perf_counter() - self.t0
        eta = el / done * (total - done) if done else float("nan")
        line = f"{done}/{total} runs, {el:.0f} s elapsed, ETA {eta:.0f} s"
        self.stream.write(("\r" + line + ("\n" if done == total else "")) if self.tty else line + "\n")
        self.stream.flush()

    def close(self):
        pass


def cmd_fly(args) -> int:
    from ..cli.signals import Interrupt
    from ..sweep.executors import make_executor
    from ..units import units
    from .output import write_flights
    from .run import run_flights
    from .actuators import actuator_lines
    from .basilisk import basilisk_text
    from .forces import j2_plane_drift
    from .schema import preset_text, truth_from_preset

    man, sol, spec = _plan(args)
    try:
        check_plan(sol)
    except ValueError as e:
        print(f"se3ocp: {man.name}: {e}", file=sys.stderr)
        return 1
    check_replanned_plan(man, sol, spec, spec_source(args.flight, man))
    check_truth_plan(sol, spec, spec_source(args.flight, man))
    ex = make_executor(args.workers, args.scheduler)  # a bad --scheduler fails before anything is written
    try:
        with results_transaction(args.out, Path("results") / "flights" / safe_name(man.name), args.force) as tx:
            where = {"serial": "in-process", "local": f"a local pool of {ex.workers} workers",
                     "dask": f"the Dask cluster at {args.scheduler}"}[ex.kind]
            _say(args, f"{man.name}: {spec.runs} runs x {' and '.join(spec.modes)} on {where} -> {tx.target}/")
            if spec.integrator == "basilisk":
                _say(args, f"  the truth: {basilisk_text(spec.substeps)}")
            taken = truth_from_preset(spec.gravity, man.physical)
            if taken:
                _say(args, f"  {preset_text(taken, units(man.problem).unit('length'))}")
            drift = j2_plane_drift(man, sol, spec.gravity)
            if drift:
                _say(args, f"  warning: {drift}")
            for line in actuator_lines(spec.actuators, man.problem, units(man.problem)):
                _say(args, f"  {line}")
            bar = FlightProgress(quiet=args.quiet)
            try:
                res = run_flights(man, sol, spec, executor=ex, save_runs=args.save_runs, progress=bar,
                                  check_interrupt=Interrupt.check)
            except KeyboardInterrupt as exc:
                part = getattr(exc, "partial", None)
                if part is not None and part.rows:   # the finished runs, clearly marked incomplete
                    write_flights(tx.path, part, sol.arrays(), figures=False)
                    tx.commit(incomplete=f"interrupted (Ctrl-C) after {part.finished_runs} of {spec.runs} runs")
                raise
            write_flights(tx.path, res, sol.arrays(), figures=not args.no_figures)
            Interrupt.check()
        out = tx.target
    finally:
        ex.shutdown()
    for line in table(res):
        _say(args, line)
    _say(args, f"  {res.wall_s:.1f} s wall; results in {out}/ (flights.csv, summary.json, figures, report.html)")
    if res.failed:
        print(f"se3ocp: {man.name}: {res.failed} flights failed (see flights.csv); results in {out}/", file=sys.stderr)
    return 1 if res.failed else 0


#: the figures of the command's table, in its order (those the flight has; report.ROWS gives their quantities)
TABLE_KEYS = ("position_miss", "velocity_miss", "attitude_miss_deg", "rate_miss", *ESTIMATION_METRICS, *ELEMENT_METRICS,
              "delta_v_overhead", "saturated_fraction", "pulses_skipped", "wheel_torque_used", "wheel_momentum_used")


def table(res) -> list[str]:
    """p95 (and mean) of the headline figures with their units (problems.flight.report.shown: m/s and deg for a km
    file), one column per feedback mode."""
    from ..units import units
    from .report import ROWS, shown

    stats = res.statistics()
    un, quantity = units(res.maneuver.problem), {k: q for k, _, q, _ in ROWS}
    modes = list(stats)
    rows = [f"{'p95 (mean)':<24}{'unit':<9}" + "".join(f"{m:>26}" for m in modes)]
    for key in TABLE_KEYS:
        if key not in res.metrics:
            continue
        unit, factor = shown(un, quantity[key])
        cells = []
        for m in modes:
            d = stats[m][key]
            cells.append(f"{'-':>26}" if d["n"] == 0 else f"{factor * d['p95']:>13.3e} ({factor * d['mean']:.2e})")
        rows.append(f"{key:<24}{unit:<9}" + "".join(cells))
    return rows + [f"warning: {w}" for w in res.summary()["worse_than_open"]]
