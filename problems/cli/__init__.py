"""``se3ocp``: the command-line tool.

Exit codes: 0 success / converged; 1 a solver or integrator did not converge
(results are still written and flagged); 2 bad input (config, options, results
directory); 3 an internal error (a defect: one line naming the file that holds the
traceback; ``crash``); 130 interrupted.

Modules: ``signals`` (Ctrl-C and stderr plumbing), ``parser`` (the arguments), ``commands``
(one function per command), ``progress`` (what a run prints), ``crash`` (a defect: exit 3).  This module and ``signals``
import nothing heavy, so that the program installs its Ctrl-C handler before NumPy and CasADi
load (:func:`signals.start_as_program`); the others load when a command runs.
"""
from __future__ import annotations

import os
import sys
import warnings

from . import signals

# The console script `se3ocp` imports this package to call main() (python -m se3ocp.problems.cli
# runs __main__.py, which starts the same way); merely importing it installs nothing.
if os.path.basename(sys.argv[0] if sys.argv else "") == "se3ocp":
    signals.start_as_program()


def main(argv: list[str] | None = None) -> int:
    """Run ``se3ocp`` with the arguments ``argv`` (default: the command line); returns the exit status."""
    rc = signals.run_guarded(_main, argv)
    if rc == 130 and signals.AS_PROGRAM:
        signals.exit_interrupted()
    return rc


def _main(argv: list[str] | None) -> int:
    """Parse the arguments, run the command, and map what it raises to an exit status and one line."""
    from ...transcription.compile import codegen
    from ..io import ResultsDirError
    from ..schema import ConfigError
    from .parser import build_parser
    from .progress import say, stdout_gone
    from .signals import Interrupt, interrupted

    args = build_parser().parse_args(argv)
    # a failed run's non-finite numbers are reported by its status, not by NumPy's warnings on stderr
    warnings.simplefilter("ignore", RuntimeWarning)
    before, codegen.notify = codegen.notify, (lambda msg: say(args, f"  [jit] {msg}"))
    try:
        return args.func(args)
    except (ConfigError, ResultsDirError) as e:
        if Interrupt.flag:
            return interrupted()
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return interrupted()
    except MemoryError:  # e.g. a horizon.N the schema allows but this machine cannot hold; nothing was committed
        if Interrupt.flag:
            return interrupted()
        print("se3ocp: error: out of memory (nothing was written); try a smaller horizon.N", file=sys.stderr)
        return 1
    except BrokenPipeError:  # stdout's reader went away while the result was printed (--json ... | head)
        stdout_gone()
        return 141  # 128 + SIGPIPE, as a shell reports a process killed by it
    except Exception as e:  # a defect: one line, the traceback in a file, its own exit status
        if Interrupt.flag:  # an error caused by the interrupt inside a library
            return interrupted()
        from .crash import report_crash

        return report_crash(e)
    finally:  # a command run in-process (tests, notebooks) leaves no notifier bound to its arguments behind
        codegen.notify = before
