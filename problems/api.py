"""The Python API: ``load``, ``solve``, ``simulate``, ``plot`` (re-exported as ``se3ocp.*``).

    import se3ocp
    man = se3ocp.load("configs/e3_inclination_change.yaml", ["horizon.N=200"])
    sol = se3ocp.solve(man, method="direct")          # a Solution (failure is data: sol.result)
    both = se3ocp.solve(man, method="both")           # a Comparison: both.direct, both.indirect, both.verdict
    figs = se3ocp.plot(both)                          # matplotlib Figures, drawn from memory

``solve`` and ``simulate`` take a :class:`~se3ocp.problems.maneuvers.Maneuver` (a loaded file: its
Problem and its ``solver`` blocks as default options) or a
:class:`~se3ocp.transcription.ocp.Problem` built in Python (default options).
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..transcription.strategy.refine import AccuracyOptions, each
from ..transcription.options import DirectOptions, IndirectOptions, Options
from ..transcription.ocp import Problem
from ..transcription import solve as _solve
from ..transcription.outcome import Iterate, Result
from ..transcription.results.solution import Solution
from ..transcription.solve import Comparison, compare
from ..transcription.results.start import Start
from .maneuvers import Maneuver, load_maneuver
from .store import path_tolerance


def load(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Maneuver:
    """Read and validate a maneuver file; ``overrides`` are ``dotted.key=value`` strings (the CLI's
    ``--set``).  Bad input raises ConfigError with one line ``FILE: FIELD: what was expected``."""
    return load_maneuver(path, tuple(overrides))


def _merge(base: Options, given: Options | Mapping[str, Any] | None) -> Options:
    if given is None:
        return base
    if isinstance(given, Options):
        return given
    return base.replace(**dict(given))


def _printer(rec: Iterate) -> None:
    print(f"  {rec.progress_line()}", file=sys.stderr, flush=True)


def resolve(problem: Maneuver | Problem, method: str = "direct", direct=None, indirect=None,
            options: Mapping[str, Any] | None = None) -> tuple[Problem, DirectOptions, IndirectOptions]:
    """The Problem and the options of each method for a solve: a Maneuver's solver blocks (or the
    defaults), replaced by ``direct``/``indirect`` (options objects or mappings of changes) and
    by ``options`` (changes for the single method chosen)."""
    if isinstance(problem, Maneuver):
        prob, d, i = problem.problem, problem.direct, problem.indirect
    elif isinstance(problem, Problem):
        prob, d, i = problem, DirectOptions(), IndirectOptions()
    else:
        raise TypeError(f"expected a Maneuver (se3ocp.load) or a Problem, got {type(problem).__name__}")
    d, i = _merge(d, direct), _merge(i, indirect)
    if options:
        if method == "direct":
            d = d.replace(**options)
        elif method == "indirect":
            i = i.replace(**options)
        else:
            raise TypeError("with method='both' give the options of each method as direct={...} and indirect={...}")
    return prob, d, i


def accuracy_options(problem: Maneuver | Problem, options: dict[str, Any]) -> AccuracyOptions:
    """The continuous check and accuracy options of a solve (transcription.strategy.refine.AccuracyOptions): a
    Maneuver's ``solver`` block (or the defaults), changed by the keywords among ``options`` that name them
    (``continuous_check=False``, ``accuracy=1e-6`` or ``maneuver_accuracy=0.01``, ...), which are removed from
    ``options``.  ``accuracy`` and ``maneuver_accuracy`` exclude each other (OptionError, a ValueError): to change
    a file's one for the other, give the file's as None."""
    base = problem.accuracy if isinstance(problem, Maneuver) else AccuracyOptions.default()
    names = [f.name for f in dataclasses.fields(AccuracyOptions)]
    changes = {k: options.pop(k) for k in list(options) if k in names}
    return base.replace(**changes) if changes else base


def check_clearance(maneuver: Maneuver, result: Solution | Comparison) -> Solution | Comparison:
    """Check every solution's whole re-simulated path against the central body: a path whose
    centre of mass comes closer to the centre than ``maneuver.clearance`` (central_body_radius
    + the body's bounding radius), by more than the path tolerance (solver.direct.terminal_tol,
    so that an enforced ``min_radius`` met to round-off passes), is not a solution.  A solution
    that had converged becomes ``Result.inside_central_body`` with a message giving the closest
    approach; a failed one keeps its status and has the fact added to its message.  Returns the
    result (a Comparison is re-made, so its verdict follows).  Methods that do not apply and
    non-finite paths are left alone."""
    need = maneuver.clearance
    if need is None:
        return result
    tol = path_tolerance(maneuver)

    def checked(s: Solution) -> Solution:
        if s.result in (Result.not_applicable, Result.inside_central_body):
            return s
        r = np.linalg.norm(np.asarray(s.trajectory.x, float), axis=1)
        if r.size == 0 or not np.all(np.isfinite(r)) or r.min() >= need - tol:
            return s
        k = int(np.argmin(r))
        what = (f"the re-simulated path enters the central body: |x| = {r[k]:.4g} at node {k} (t = "
                f"{s.trajectory.t[k]:.4g}), below the clearance {need:.4g} (model.central_body_radius "
                f"{maneuver.central_body_radius:g} + the body's bounding radius {need - maneuver.central_body_radius:g})")
        if not s.result.successful:
            return s.with_notes(f"also, {what}")
        hint = ("; give model.central_body_radius (> 0) or a min_radius constraint so that the direct method "
                "keeps the path outside" if not maneuver.central_body_radius > 0 else "")
        return dataclasses.replace(s, result=Result.inside_central_body, verdict=f"{what}; the solver reported: "
                                                                              f"{s.verdict}").with_notes(hint[2:])

    out = each(result, checked)
    return compare(out.direct, out.indirect) if isinstance(out, Comparison) else out


def with_physical(maneuver: Maneuver, result: Solution | Comparison) -> Solution | Comparison:
    """Every Solution of ``result`` carrying the maneuver file's epoch, frame, units and central body
    (``Solution.physical``), so that ``se3ocp.export(sol, "oem")`` finds them without ``maneuver=``."""
    if maneuver.physical is None:
        return result
    return each(result, lambda s: dataclasses.replace(s, physical=maneuver.physical))


def solve(problem: Maneuver | Problem, method: str = "direct", *, direct: DirectOptions | Mapping | None = None,
          indirect: IndirectOptions | Mapping | None = None,
          progress: bool | Callable[[Iterate], None] | None = None, warm_start: Solution | Start | None = None,
          throw: bool = False, strategy=None, **options) -> Solution | Comparison:
    """Solve a maneuver (or a Problem) by ``method``: 'direct', 'indirect' or 'both'.

    Options: a Maneuver's ``solver`` blocks are the defaults; ``direct=`` / ``indirect=`` replace
    them (a DirectOptions/IndirectOptions, or a mapping of changes, e.g. ``direct={"tol": 1e-8}``);
    keyword ``**options`` change the chosen method's options (``solve(man, "indirect",
    initial_costate="from_direct")``), except the solver block's own keys (``continuous_check=False``,
    ``accuracy=1e-6``, ``maneuver_accuracy=0.01`` -- the flown miss at most 1 % of what the maneuver changes --,
    ``constraints_tolerance=1e-5`` -- the path constraints' violation between the nodes (rad for a cone) --,
    ``max_N``, ...: :class:`~se3ocp.transcription.strategy.refine.AccuracyOptions`).  ``progress``: True prints one line per iteration on stderr,
    or a callable(Iterate) (``Iterate.method`` names the method, ``phase`` the solve within it, ``elapsed_s``
    the seconds since the call).  ``warm_start``: a previous Solution (or
    its ``warm``, a Start) of either method and any N or scheme: it is resampled onto this problem's grid
    and the Solution's message and ``stats['warm_start*']`` say what was reused.  ``strategy``: how the direct method
    composes its solves (default: the objective's, e.g. ``EffortStrategy(first_budget=100)``:
    :mod:`se3ocp.transcription.strategy`, :mod:`se3ocp.transcription.objectives`).

    Returns a :class:`~se3ocp.transcription.results.solution.Solution` (for 'both' a
    :class:`~se3ocp.transcription.solve.Comparison` of the two).  A solver that fails returns a
    Solution saying why (``sol.result``, ``sol.message``); ``throw=True`` raises SolveError instead.
    """
    acc = accuracy_options(problem, options)
    prob, d, i = resolve(problem, method, direct, indirect, options)
    cb = _printer if progress is True else (progress or None)
    out = _solve.solve(prob, method, direct=d, indirect=i, progress=cb, warm_start=warm_start, accuracy=acc,
                       strategy=strategy)
    if isinstance(problem, Maneuver):
        out = with_physical(problem, check_clearance(problem, out))
    return _solve.raise_unconverged(out) if throw else out


def simulate(problem: Maneuver | Problem, controls=None) -> Solution:
    """The motion of a maneuver's discretization from its initial state (free motion, or under
    ``controls`` (6 x n_controls)) over its horizon, with orthogonality and energy diagnostics and
    the miss distance to its terminal target (``terminal_error``)."""
    prob = problem.problem if isinstance(problem, Maneuver) else problem
    sol = _solve.simulate(prob, controls)
    return with_physical(problem, check_clearance(problem, sol)) if isinstance(problem, Maneuver) else sol


def plot(result: Solution | Comparison, which: tuple[str, ...] | None = None) -> dict:
    """The figures of a Solution or a Comparison, drawn from memory: {name: matplotlib Figure}.
    Does not change the matplotlib backend."""
    from .plots import figures

    return figures(result, which)
