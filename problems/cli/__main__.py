"""``python -m se3ocp.problems.cli``: the program, as the console script ``se3ocp``."""
import sys

from . import signals

signals.start_as_program()  # before NumPy and CasADi load

from . import main  # noqa: E402

sys.exit(main())
