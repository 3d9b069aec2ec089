"""A defect, told apart from bad input and from a failed solve: the exit status :data:`EXIT_CRASH`.

An exception nobody expected (a bug, not a ConfigError and not a solver's failure, which is data)
ends the run with one line on stderr -- what it was and the file that holds the traceback, in the
system's temporary directory -- and the exit status 3, so that scripts and sweeps can tell a defect
from a hard problem (1) and from bad input (2).  The results directory is left as the contract says:
a run is written aside and swapped in only when complete, so a crash leaves the previous run (or
nothing) in place.
"""
from __future__ import annotations

import datetime
import os
import sys
import tempfile
import traceback

#: the exit status of an unexpected exception (a defect)
EXIT_CRASH = 3


def report_crash(exc: BaseException) -> int:
    """Save the traceback of ``exc`` to a file, print one line naming it, return :data:`EXIT_CRASH`.
    If no file can be written, the traceback goes to stderr after the line."""
    details = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    what = f"{type(exc).__name__}: {' '.join(str(exc).split())}" if str(exc).strip() else type(exc).__name__
    what = what if len(what) <= 200 else what[:200] + "..."
    try:
        fd, path = tempfile.mkstemp(prefix="se3ocp-crash-", suffix=".txt")
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(f"se3ocp crashed at {datetime.datetime.now().astimezone():%Y-%m-%d %H:%M:%S %Z}\n"
                    f"command: {' '.join(sys.argv)}\npython: {sys.version.split()[0]}\n\n{details}")
    except OSError:
        path = None
    tail = (f"the details (traceback) are in {path} -- a defect of se3ocp, please report it with that file; "
            f"the results directory was left as it was" if path else "the traceback follows")
    print(f"se3ocp: internal error ({what}); {tail}", file=sys.stderr)
    if path is None:
        print(details, file=sys.stderr, end="")
    return EXIT_CRASH
