"""``se3ocp``: the command-line tool.

Exit codes: 0 success / converged; 1 a solver or integrator did not converge
(results are still written and flagged); 2 bad input (config, options, results
directory); 130 interrupted.
"""
from __future__ import annotations

import os
import signal
import sys


def _interrupted_at_startup(signum, frame):  # pragma: no cover - timing dependent
    # Ctrl-C while the heavy modules load: nothing has been written yet.
    os.write(2, b"se3ocp: interrupted during start-up, before anything was written; nothing half-written was left\n")
    os._exit(130)


# Only when running as the program (python -m se3ocp.problems.cli, or the se3ocp script), never when
# merely imported: main() replaces it once the modules are loaded.  The package's __init__ imports
# nothing heavy, so this runs before NumPy and CasADi load.  A Ctrl-C that arrived while SIGINT was
# blocked (a test starts the program that way) is delivered here, once the handler is in place.
_AS_PROGRAM = __name__ == "__main__" or os.path.basename(sys.argv[0] if sys.argv else "") == "se3ocp"
if _AS_PROGRAM:
    signal.signal(signal.SIGINT, _interrupted_at_startup)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402


from .io import ResultsDirError, results_transaction, results_update  # noqa: E402
from .maneuvers import Maneuver, load_maneuver  # noqa: E402
from .schema import ConfigError  # noqa: E402

EPILOG = """examples:
  se3ocp validate configs/e3_inclination_change.yaml
  se3ocp simulate configs/free_tumble.yaml --set horizon.N=2000
  se3ocp solve configs/e3_inclination_change.yaml --method both
  se3ocp compare configs/e4_orbital_capture.yaml --set solver.indirect.initial_costate=from_direct
  se3ocp plot results/e3_inclination_change
  se3ocp plot results/e3_inclination_change --animate --frames 150 --fps 25
  se3ocp report results/e3_inclination_change
  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T
"""


def _common(p: argparse.ArgumentParser, out=True):
    p.add_argument("config", help="maneuver YAML file")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config value by dotted key, e.g. --set horizon.N=1000 (repeatable)")
    if out:
        p.add_argument("--out", default=None, metavar="DIR",
                       help="results directory (default results/<name>/; a fresh numbered sibling if that is not empty)")
        p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")


def _animation_options(p: argparse.ArgumentParser):
    p.add_argument("--animate", action="store_true",
                   help="also write maneuver.gif (every method, named; body frame, thrust arrow, target)")
    p.add_argument("--frames", type=_frames, default=100, metavar="K", help="frames of the animation (default 100)")
    p.add_argument("--fps", type=_positive_int, default=20, metavar="F", help="frames per second (default 20)")


def _output_options(p: argparse.ArgumentParser):
    p.add_argument("--no-figures", action="store_true", help="skip the PNG/PDF figures (report.html is still written)")
    _animation_options(p)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="se3ocp", description="Geometrically exact optimal control of a rigid body on SE(3).",
                                 epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"se3ocp {_version()}",
                    help="print the installed version and exit")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("validate", help="check a maneuver file against the schema",
                       epilog="example:\n  se3ocp validate configs/e1_impulsive_tpbvp.yaml",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p, out=False)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("simulate", help="uncontrolled motion from the initial state over the horizon",
                       epilog="example:\n  se3ocp simulate configs/free_tumble.yaml --out results/tumble",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p)
    _output_options(p)
    p.set_defaults(func=cmd_simulate)

    for name, helptext, ex in (
        ("solve", "solve the optimal control problem (direct, indirect or both)",
         "examples:\n  se3ocp solve configs/e3_inclination_change.yaml --method direct\n"
         "  se3ocp solve configs/e1_impulsive_tpbvp.yaml --set horizon.N=200\n"
         "  se3ocp solve configs/e4_orbital_capture.yaml --method indirect --set solver.indirect.initial_costate=from_direct"),
        ("compare", "solve by both methods and compare them side by side",
         "example:\n  se3ocp compare configs/e3_inclination_change.yaml --set horizon.N=200"),
    ):
        p = sub.add_parser(name, help=helptext, epilog=ex, formatter_class=argparse.RawDescriptionHelpFormatter)
        _common(p)
        if name == "solve":
            p.add_argument("--method", choices=("direct", "indirect", "both"), default="direct",
                           help="direct (multiple shooting + NLP solver), indirect (Newton-Armijo shooting), "
                                "or both (default: direct)")
        _output_options(p)
        p.set_defaults(func=cmd_solve)
        if name == "compare":
            p.set_defaults(method="both")

    p = sub.add_parser("plot", help="(re)draw the figures, report.html and the animation of a results directory",
                       description="Without --animate: redraw every figure and report.html.  With --animate: write "
                                   "maneuver.gif, and draw only the figures that are missing or older than the run's "
                                   "summary.json (so a new animation does not redraw up-to-date figures).",
                       epilog="examples:\n  se3ocp plot results/e3_inclination_change\n"
                              "  se3ocp plot results/e3_inclination_change --animate --frames 150 --fps 25",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    _animation_options(p)
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the list of files written as JSON")
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser("report", help="write report.html: a self-contained page (summary table, figures, history, config)",
                       epilog="example:\n  se3ocp report results/e3_inclination_change",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    p.add_argument("--no-figures", action="store_true", help="leave the figures out (no drawing)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the path written as JSON")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("sweep", help="trade study: solve a grid of parameter values (local pool or Dask cluster)",
                       epilog="examples:\n  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T\n"
                              "  se3ocp sweep configs/sweeps/e3_T_inclination.yaml --scheduler tcp://127.0.0.1:8786",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", help="sweep YAML file (base maneuver, axes, methods; see problems/sweep.py)")
    p.add_argument("--out", default=None, metavar="DIR", help="results directory (default results/sweeps/<name>/)")
    p.add_argument("--workers", type=_positive_int, default=None, metavar="K",
                   help="local worker processes (default: one per core; 1 = in-process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the tasks on an existing dask.distributed cluster, e.g. tcp://host:8786")
    p.add_argument("--no-continuation", action="store_true", help="cold-start every point (ignore 'continuation')")
    p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=cmd_sweep)
    return ap


def _version() -> str:
    """The installed distribution's version (package metadata), so it cannot drift from pyproject.toml."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("se3ocp")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def _positive_int(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return int(text)


def _frames(text: str) -> int:
    if not text.isdigit() or int(text) < 2:
        raise argparse.ArgumentTypeError(f"expected an integer >= 2, got {text!r}")
    return int(text)


class _Interrupt:
    """Ctrl-C policy.  The first SIGINT sets a flag and raises KeyboardInterrupt.
    Solvers may swallow that exception inside their own callbacks (IPOPT then stops
    with User_Requested_Stop, CasADi may turn it into another error), and Python
    swallows it where it cannot propagate (a weakref callback or __del__ during garbage
    collection: it is "unraisable"), so the flag is what counts: it is checked after each
    solve and before every commit of a results directory, and any exception raised while
    it is set means "interrupted" (exit 130), never a traceback."""

    flag = False

    @classmethod
    def unraisable(cls, u, default=sys.unraisablehook):
        """sys.unraisablehook: our own KeyboardInterrupt, swallowed where it could not propagate,
        is not printed (the flag carries it); anything else is reported as usual."""
        if cls.flag and isinstance(u.exc_value, KeyboardInterrupt):
            return
        default(u)

    @classmethod
    def handler(cls, signum, frame):
        cls.flag = True
        raise KeyboardInterrupt

    @classmethod
    def check(cls):
        if cls.flag:
            raise KeyboardInterrupt


class _DropInterruptWarnings:
    """sys.stderr during a CLI run, minus CasADi's ``WARNING("KeyboardInterruptException")`` lines.

    CasADi checks for Ctrl-C inside its evaluations and solver callbacks; when our SIGINT handler
    raises there, CasADi stops the solver and logs that warning through ``sys.stderr`` (its Python
    build writes with PySys_WriteStderr).  The interrupt itself is recorded by :class:`_Interrupt`
    and reported in one line of our own, so the warning is noise.  Text is passed through at once,
    except a line that starts like a CasADi log line, which is held until it is complete."""

    MARK = 'WARNING("KeyboardInterruptException")'

    def __init__(self, stream):
        self.stream, self.held = stream, ""

    def write(self, text: str) -> int:
        n = len(text)
        text = self.held + text
        self.held = ""
        while text:
            line, nl, rest = text.partition("\n")
            if not nl:  # an incomplete line: hold it only if it may be a CasADi warning
                if text.startswith("CasADi"[:len(text)]):
                    self.held = text
                else:
                    self.stream.write(text)
                break
            if self.MARK not in line:
                self.stream.write(line + nl)
            text = rest
        return n

    def flush(self) -> None:
        if self.held:
            if self.MARK not in self.held:
                self.stream.write(self.held)
            self.held = ""
        self.stream.flush()

    def __getattr__(self, name):  # fileno, isatty, encoding, ...
        return getattr(self.stream, name)


def main(argv: list[str] | None = None) -> int:
    rc = _run(argv)
    if rc == 130 and _AS_PROGRAM:
        # An interrupted run ends here, with status 130 and nothing more to do.  Leaving through the
        # interpreter's normal exit could still turn it into death by SIGINT (-2, no message): CPython
        # does so whenever a KeyboardInterrupt once escaped code that a C extension ran while importing
        # (its flag _Py_UnhandledKeyboardInterrupt stays set even though we caught the interrupt).
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(130)
    return rc


def _run(argv: list[str] | None) -> int:
    old_handler = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, _Interrupt.handler)
    except ValueError:  # not the main thread
        pass
    old_hook, sys.unraisablehook = sys.unraisablehook, _Interrupt.unraisable
    real_stderr = sys.stderr
    sys.stderr = _DropInterruptWarnings(real_stderr)
    try:
        return _main(argv)
    except KeyboardInterrupt:  # while the arguments are parsed or the modules load
        return _interrupted()
    finally:
        # The run is over (its results committed or not).  As the program, a late Ctrl-C changes
        # nothing and must not raise a KeyboardInterrupt traceback on the way out; called from
        # Python (tests), the caller's handler and hook come back.
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN if _AS_PROGRAM else old_handler)
        except (ValueError, TypeError):
            pass
        sys.unraisablehook = old_hook
        sys.stderr.flush()
        sys.stderr = real_stderr


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    from ..transcription import codegen

    codegen.notify = lambda msg: _say(args, f"  [jit] {msg}")
    try:
        return args.func(args)
    except (ConfigError, ResultsDirError) as e:
        if _Interrupt.flag:
            return _interrupted()
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except MemoryError:  # e.g. a horizon.N the schema allows but this machine cannot hold; nothing was committed
        if _Interrupt.flag:
            return _interrupted()
        print("se3ocp: error: out of memory (nothing was written); try a smaller horizon.N", file=sys.stderr)
        return 1
    except BrokenPipeError:  # stdout's reader went away while the result was printed (--json ... | head)
        _stdout_gone()
        return 141  # 128 + SIGPIPE, as a shell reports a process killed by it
    except Exception:
        if _Interrupt.flag:  # an error caused by the interrupt inside a library
            return _interrupted()
        raise


def _interrupted() -> int:
    from .io import ResultsTransaction

    if ResultsTransaction.committed:  # Ctrl-C after a commit: say what is in place
        where, incomplete = ResultsTransaction.committed[-1]
        what = ("the part finished before the interrupt, marked INCOMPLETE" if incomplete is not None
                else "this run, complete (the interrupt came after the results were in place)")
        print(f"se3ocp: interrupted; {where}/ holds {what} (nothing half-written)", file=sys.stderr)
    else:
        print("se3ocp: interrupted; the results directory was left as it was (nothing half-written)", file=sys.stderr)
    return 130


# ------------------------------------------------------------------ helpers
def _say(args, *msg):
    """Print a progress or result line (not with --quiet or --json).  If stdout's reader went away
    (``se3ocp solve ... | head``), printing stops and the run goes on to write its results."""
    if not args.quiet and not args.json:
        try:
            print(*msg, flush=True)
        except BrokenPipeError:
            _stdout_gone()
            args.quiet = True


def _stdout_gone() -> None:
    """Point stdout at /dev/null, so that neither later prints nor the flush at exit fail."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def _load(args) -> Maneuver:
    return load_maneuver(args.config, args.overrides)


def _results(args, man: Maneuver):
    """The results directory of a run, as a transaction: written aside, swapped in whole when the
    block ends normally, absent (or the previous run, untouched) if it does not."""
    safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in man.name)
    return results_transaction(args.out, Path("results") / safe, args.force)


def _emit_summary(args, summary: dict):
    if args.json:
        print(json.dumps(summary, indent=2, default=float))


# ----------------------------------------------------------------- commands
def cmd_validate(args) -> int:
    man = _load(args)
    summary = {"config": man.source, "name": man.name, "valid": True, "control": man.control_kind,
               "discretization": man.discretization, "N": man.N, "T": man.T}
    _say(args, f"{man.source}: valid ({man.name}: {man.control_kind or 'no control'}, "
               f"{man.discretization}, N = {man.N}, T = {man.T:g})")
    _emit_summary(args, summary)
    return 0


def cmd_simulate(args) -> int:
    from . import api, store

    man = _load(args)
    with _results(args, man) as tx:
        sol = api.simulate(man)
        _Interrupt.check()
        store.write_run(tx.path, man, sol)
        _figures_and_report(args, tx.path)
        _Interrupt.check()  # a Ctrl-C that a library swallowed (see _Interrupt): do not commit
    out = tx.target
    st = sol.stats
    _say(args, f"{man.name}: {man.discretization} free motion, N = {man.N}, h = {man.h:.3g}, {sol.solve_s:.2f} s")
    _say(args, f"  max |R^T R - I|          {st['max_orthogonality_error']:.2e}")
    _say(args, f"  max |det R - 1|          {st['max_determinant_error']:.2e}")
    _say(args, f"  max relative energy err  {st['max_relative_energy_error']:.2e}")
    if sol.problem.terminal is not None:
        _say(args, f"  miss at the target       {sol.terminal_error:.3e} (terminal error of the free motion)")
    _say(args, f"  status                   {sol.result}: {sol.message}")
    _say(args, f"  results in {out}/")
    _emit_summary(args, store.summary(man, sol))
    return 0 if sol.converged else 1


class Progress:
    """One line per iteration of any method (at most one a second after the first ten, and every
    Newton step), so long solves show life without flooding; Ctrl-C is honoured here."""

    def __init__(self, args):
        self.args = args
        self.last = 0.0
        self.count = 0

    def __call__(self, rec):
        _Interrupt.check()
        self.count += 1
        now = time.perf_counter()
        if self.count > 10 and now - self.last < 1.0 and rec.trial == 0 and math.isnan(rec.step):
            return
        self.last = now
        _say(self.args, f"  [{rec.method}] {rec.line()}")


def _table(sols) -> list[str]:
    """The side-by-side table; the text columns are as wide as their widest entry (a status is
    never cut, however long)."""
    from ..transcription.results import Result

    sols = list(sols)
    mw = max([len("method")] + [len(s.method) for s in sols])
    sw = max([len("status")] + [len(str(s.result.value)) for s in sols])
    head = (f"{'method':<{mw}} {'status':<{sw}} {'cost':>14} {'term. err':>10} {'orth. err':>10} {'iters':>6} "
            f"{'build s':>8} {'solve s':>8}")
    rows = [head, "-" * len(head)]
    for s in sols:
        if s.result is Result.not_applicable:
            rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {'-':>14} {'-':>10} {'-':>10} {'-':>6} {'-':>8} {'-':>8}")
            continue
        o = s.trajectory.orthogonality()["max_orthogonality_error"]
        rows.append(f"{s.method:<{mw}} {s.result.value:<{sw}} {s.cost:>14.8g} {s.terminal_error:>10.2e} {o:>10.2e} "
                    f"{s.iterations:>6d} {s.build_s:>8.2f} {s.solve_s:>8.2f}")
    return rows


def cmd_solve(args) -> int:
    from ..transcription.results import Result
    from . import api, store

    man = _load(args)
    if man.control_kind is None:
        raise ConfigError(man.source, "control/terminal",
                          "solving needs a 'control' block (kind smooth or impulsive) and a 'terminal' block")
    method = args.method
    if man.control_kind == "impulsive":
        if method == "indirect":
            raise ConfigError(man.source, "control.kind", "the indirect method applies to smooth maneuvers; "
                                                          "impulsive maneuvers are solved by --method direct")
        method = "direct"
    with _results(args, man) as tx:
        _say(args, f"{man.name}: {man.control_kind} maneuver, {man.discretization}, N = {man.N}, T = {man.T:g} "
                   f"-> {tx.target}/")
        _say(args, f"solving by the {method} method{'s' if method == 'both' else ''} ...")
        result = api.solve(man, method, progress=Progress(args))  # with the central-body check of the path
        _Interrupt.check()  # a solver may have swallowed Ctrl-C and returned
        sols = store.solutions_of(result)
        for m, sol in sols.items():
            if sol.result is Result.not_applicable:
                _say(args, f"  {m}: {sol.result} ({sol.message})")
                continue
            _say(args, f"  {m}: {sol.result} ({sol.message}); cost {sol.cost:.10g}, terminal error "
                       f"{sol.terminal_error:.2e}, {sol.iterations} iterations, build {sol.build_s:.2f} s, "
                       f"solve {sol.solve_s:.2f} s")
        store.write_run(tx.path, man, result)
        _figures_and_report(args, tx.path)
        _Interrupt.check()  # a Ctrl-C that a library swallowed (see _Interrupt): do not commit
    out = tx.target
    for line in _table(sols.values()):
        _say(args, line)
    if hasattr(result, "verdict"):
        _say(args, f"comparison: {result.verdict}")
    _say(args, f"results in {out}/")
    _emit_summary(args, store.summary(man, result, with_history=False))
    if store.all_converged(result):
        return 0
    if args.quiet:  # quiet is not silent: a failure is still said, in one line
        failed = [f"{m}: {s.result} ({s.message})" for m, s in sols.items()
                  if not s.converged and s.result is not Result.not_applicable]
        print(" ".join(f"se3ocp: {man.name}: not converged: {' | '.join(failed) or 'no method applies'}; results in {out}/".split()),
              file=sys.stderr)
    return 1


def _figures_and_report(args, out: Path) -> list[Path]:
    """After simulate/solve/compare: the figures (unless --no-figures), the animation (--animate)
    and report.html (always; with the figures just drawn embedded)."""
    from .plots import animate, draw_all
    from .report import write_report

    written = []
    if not args.no_figures:
        written += draw_all(out)
        if args.animate:
            written.append(animate(out, frames=args.frames, fps=args.fps))
    written.append(write_report(out, draw=False))
    return written


def _results_dir(d: Path) -> int:
    """0 if d is a results directory, else the error printed and 2."""
    if not (d / "summary.json").exists() or not (d / "config.resolved.yaml").exists():
        print(f"se3ocp: error: {d}: not a results directory (needs summary.json and config.resolved.yaml)", file=sys.stderr)
        return 2
    if not any((d / n).is_file() for n in ("direct.npz", "indirect.npz", "trajectory.npz")):
        print(f"se3ocp: error: {d}: not a results directory (no direct.npz, indirect.npz or trajectory.npz)",
              file=sys.stderr)
        return 2
    return 0


def _update_results(args, write, said) -> int:
    """``plot`` and ``report``: ``write(path)`` adds files to a copy of the complete results directory
    ``args.results`` (results_update: the copy is swapped in when it returns) and returns their names;
    ``said(d, written)`` is the line printed.  2 if the directory is not a results directory."""
    d = Path(args.results)
    if _results_dir(d):
        return 2
    with results_update(d) as tx:
        written = [str(d / name) for name in write(tx.path)]
        _Interrupt.check()
    _say(args, said(d, written))
    if args.json:
        print(json.dumps(written))
    return 0


def cmd_plot(args) -> int:
    from .plots import animate, draw_all
    from .report import write_report

    def write(path: Path) -> list[str]:
        # --animate: the animation, and only the static figures that are missing or stale
        names = [p.name for p in draw_all(path, stale_only=args.animate)]
        if names or not (path / "report.html").exists():
            names.append(write_report(path, draw=False).name)
        if args.animate:
            names.append(animate(path, frames=args.frames, fps=args.fps).name)
        return names

    return _update_results(args, write, lambda d, written: f"wrote {len(written)} files in {d}/")


def cmd_report(args) -> int:
    from .report import write_report

    return _update_results(args, lambda path: [write_report(path, draw=not args.no_figures).name],
                           lambda d, written: f"wrote {written[0]}")


def cmd_sweep(args) -> int:
    from .sweep import cli_sweep

    return cli_sweep(args, check_interrupt=_Interrupt.check)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
