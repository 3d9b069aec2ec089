"""Ctrl-C and stderr plumbing of the command-line tool.  Imports nothing heavy: the program
installs its start-up handler from here before NumPy and CasADi load.

* Start-up (:func:`start_as_program`): a Ctrl-C while the modules load ends the program at once
  with one line; nothing has been written yet.
* During a run (:func:`run_guarded`): :class:`Interrupt` turns the first SIGINT into a flag and a
  KeyboardInterrupt, so that however a library swallows the exception, the run ends with exit 130
  and one line (:func:`interrupted`) saying what the results directory holds; CasADi's own
  warning about the interrupt is dropped from stderr (:class:`DropInterruptWarnings`).
* The end (:func:`exit_interrupted`): an interrupted program leaves with status 130, never by
  death from SIGINT.
"""
from __future__ import annotations

import importlib
import os
import signal
import sys

#: True when this process is the se3ocp program (the console script, or ``python -m
#: se3ocp.problems.cli``), not a Python caller of main() (tests, notebooks)
AS_PROGRAM = False


def _interrupted_at_startup(signum, frame):  # pragma: no cover - timing dependent
    # Ctrl-C while the heavy modules load: nothing has been written yet.
    os.write(2, b"se3ocp: interrupted during start-up, before anything was written; nothing half-written was left\n")
    os._exit(130)


def start_as_program() -> None:
    """The program's first step, before NumPy and CasADi load (only when running as the program,
    never when merely imported: :func:`run_guarded` replaces the handler once the modules are
    loaded).  A Ctrl-C that arrived while SIGINT was blocked (a test starts the program that way)
    is delivered here, once the handler is in place; then the modules of the commands load."""
    global AS_PROGRAM
    AS_PROGRAM = True
    signal.signal(signal.SIGINT, _interrupted_at_startup)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    importlib.import_module(".commands", __package__)


class Interrupt:
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


class DropInterruptWarnings:
    """sys.stderr during a CLI run, minus CasADi's ``WARNING("KeyboardInterruptException")`` lines.

    CasADi checks for Ctrl-C inside its evaluations and solver callbacks; when our SIGINT handler
    raises there, CasADi stops the solver and logs that warning through ``sys.stderr`` (its Python
    build writes with PySys_WriteStderr).  The interrupt itself is recorded by :class:`Interrupt`
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


def run_guarded(run, argv: list[str] | None) -> int:
    """``run(argv)`` with the Ctrl-C policy (:class:`Interrupt`) and the stderr filter in place;
    a KeyboardInterrupt that escapes it (while the arguments are parsed or the modules load) is
    exit 130.  Afterwards the caller's handler, hook and stderr come back (as the program, a late
    Ctrl-C is ignored instead)."""
    old_handler = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, Interrupt.handler)
    except ValueError:  # not the main thread
        pass
    old_hook, sys.unraisablehook = sys.unraisablehook, Interrupt.unraisable
    real_stderr = sys.stderr
    sys.stderr = DropInterruptWarnings(real_stderr)
    try:
        return run(argv)
    except KeyboardInterrupt:  # while the arguments are parsed or the modules load
        return interrupted()
    finally:
        # The run is over (its results committed or not).  As the program, a late Ctrl-C changes
        # nothing and must not raise a KeyboardInterrupt traceback on the way out; called from
        # Python (tests), the caller's handler and hook come back.
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN if AS_PROGRAM else old_handler)
        except (ValueError, TypeError):
            pass
        sys.unraisablehook = old_hook
        sys.stderr.flush()
        sys.stderr = real_stderr


def interrupted() -> int:
    """Say in one line what an interrupted run left, and return its exit status, 130."""
    from ..results_dir import ResultsTransaction

    if ResultsTransaction.committed:  # Ctrl-C after a commit: say what is in place
        where, incomplete = ResultsTransaction.committed[-1]
        what = ("the part finished before the interrupt, marked INCOMPLETE" if incomplete is not None
                else "this run, complete (the interrupt came after the results were in place)")
        print(f"se3ocp: interrupted; {where}/ holds {what} (nothing half-written)", file=sys.stderr)
    else:
        print("se3ocp: interrupted; the results directory was left as it was (nothing half-written)", file=sys.stderr)
    return 130


def exit_interrupted() -> None:
    """End the interrupted program here, with status 130 and nothing more to do.  Leaving through
    the interpreter's normal exit could still turn it into death by SIGINT (-2, no message): CPython
    does so whenever a KeyboardInterrupt once escaped code that a C extension ran while importing
    (its flag _Py_UnhandledKeyboardInterrupt stays set even though we caught the interrupt).
    os._exit skips the atexit handlers, among them multiprocessing's, which unlink the semaphores of a local pool's
    queues: left registered, multiprocessing's resource tracker warns of "leaked semaphore objects" on stderr after
    the last line (seen once in a full suite run of test_cli_ctrl_c_writes_finished_rows), so its finalizers run
    first when it was loaded."""
    mp_util = sys.modules.get("multiprocessing.util")
    if mp_util is not None:
        try:
            mp_util._run_finalizers(0)      # what its atexit handler runs first: the semaphores' unlinking among them
        except Exception:  # noqa: BLE001 - leaving must not fail; the worst left is the tracker's warning
            pass
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(130)
