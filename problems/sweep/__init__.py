"""Trade studies: parameter sweeps over a maneuver, with continuation, on a local
process pool or a Dask cluster (issue 8).

Sweep file (unknown keys rejected; every error is a one-line
``FILE: FIELD: expected ...`` :class:`~problems.schema.ConfigError`)::

    name: e3_T_sweep                      # optional (default: the file's stem)
    base: ../e3_inclination_change.yaml   # the maneuver file, relative to this file
    set: {horizon.N: 100}                 # optional overrides applied to every point
    axes:                                 # one or more; the grid is their product
      horizon.T: [0.45, 0.5, 0.55]        # a dotted key -> a list of values
      solver.direct.tol: {geomspace: [1.0e-8, 1.0e-12, 3]}
      model.length: {linspace: [0.05, 0.15, 5]}        # [start, stop, num], ends included
      inclination_deg:                    # a linked axis: each value sets several keys
        values: [10, 30]
        set:
          terminal.velocity: [[0, -6.1876, -1.0911], [0, -5.4414, -3.1416]]
          terminal.attitude: [{rotations: [[x, 10], [z, 180]]}, {rotations: [[x, 30], [z, 180]]}]
    methods: [direct, indirect]           # default [direct]; impulsive maneuvers: [direct]
    continuation: true                    # default false
    continuation_axis: horizon.T          # default: the first axis

Every grid point's overrides are validated through
:func:`~problems.maneuvers.load_maneuver` (and the raw IPOPT options are checked)
before any solve starts, so a bad axis value is bad input, not a failed point.

Execution.  A *task* is :func:`solve_point` applied to a plain dict (the base file
name and text, the override strings, the method, an optional warm start: a
transcription.results.start.Start, plain arrays); it returns a plain dict (the result row and
the warm start for the next point).  Tasks run in-process (``workers=1``), on a local
:class:`~concurrent.futures.ProcessPoolExecutor` (forkserver/spawn context: CasADi
is not fork-safe once threads exist) or, with ``scheduler=ADDRESS``, on an existing
``dask.distributed`` cluster (its workers need this package installed).

Continuation.  Along one axis the points form chains (one per value of the other
axes and per method); the chains are independent and run in parallel, the points of
a chain in order.  Each point starts from the last converged point(s) of its chain:
with one, its solution's warm start (``Solution.warm``: ``start = neighbour``); with
two, a secant predictor, the extrapolation in the axis value of both on SE(3)
(transcription.results.start.secant: attitudes along geodesics, the rest linearly; ``start =
secant``).  The direct method starts from its trajectory, controls and NLP
multipliers (primal and dual), the indirect method from its lambda_0.  A warm start that does not converge is followed by
a cold solve (``start = cold_after_failed_warm``; ``iterations_total`` counts both).

Modules: ``schema`` (the sweep file and its grid), ``task`` (:func:`solve_point`),
``executors`` (in-process, local pool, Dask), ``run`` (:func:`run_sweep`), ``output``
(:func:`write_results`), ``figures`` (:func:`draw_sweep`); the command is ``se3ocp sweep``
(problems/cli).
"""
from __future__ import annotations

from .executors import DaskExecutor, Executor, PoolExecutor, SerialExecutor, default_workers, make_executor
from .figures import draw_sweep
from .output import columns, write_results
from .run import MAX_SECANT_RATIO, SweepResult, run_sweep
from .schema import (MAX_AXIS_VALUES, MAX_GRID_POINTS, METHODS, RESULT_COLUMNS, Axis, Point, Sweep, load_sweep, parse_sweep, sweep_from_doc)
from .task import solve_point

__all__ = ["DaskExecutor", "Executor", "PoolExecutor", "SerialExecutor", "default_workers", "make_executor",
           "draw_sweep", "columns", "write_results", "MAX_SECANT_RATIO", "SweepResult", "run_sweep", "MAX_AXIS_VALUES",
           "MAX_GRID_POINTS", "METHODS", "RESULT_COLUMNS", "Axis", "Point", "Sweep", "load_sweep", "parse_sweep",
           "sweep_from_doc", "solve_point"]
