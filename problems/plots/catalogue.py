"""The catalogue of figures: their names (the files fig_<name>.png/.pdf), captions, which apply
to a run, and drawing them -- in memory (:func:`figures`) or into a results directory, from a
run held in memory (:func:`draw_run`) or read back from it (:func:`draw_all`)."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ...transcription.ocp import Problem
from ...transcription.results.solution import Solution
from ...transcription.solve import Comparison
from ..io import figure_files, write_figure
from .histories import (fig_angular_velocity, fig_attitude_error, fig_constraints, fig_control_norms, fig_convergence, fig_costates, fig_force, fig_moment, fig_orbital_elements, fig_thrust_rtn, fig_velocity)
from .continuous import fig_continuous, flown
from .engine import fig_thrust_direction
from .runs import Run, _runs
from .targets import removed
from .views3d import fig_attitude, fig_maneuver


FIGURES = {
    "maneuver": fig_maneuver,
    "attitude": fig_attitude,
    "attitude_error": fig_attitude_error,
    "control_norms": fig_control_norms,
    "force": fig_force,
    "moment": fig_moment,
    "thrust_rtn": fig_thrust_rtn,
    "thrust_direction": fig_thrust_direction,
    "orbital_elements": fig_orbital_elements,
    "constraints": fig_constraints,
    "velocity": fig_velocity,
    "angular_velocity": fig_angular_velocity,
    "costates": fig_costates,
    "convergence": fig_convergence,
    "continuous": fig_continuous,
}

#: one line per figure (the report's captions, the README's table)
CAPTIONS = {
    "maneuver": "3-D path of each method about the central body, initial and desired orbits, the body frame at a few nodes",
    "attitude": "the body axes' paths on the unit sphere (inertial), the final frame of each method against the target frame",
    "attitude_error": "angle of the attitude error R_dᵀR(t) (or the rotation from the start) and its quaternion",
    "control_norms": "|u_f| and |u_m| with their bounds; shaded where a bound is active (the switching structure)",
    "force": "control force u_f in its frame (inertial, or body with force_frame: body), with box limits ±b_i",
    "moment": "control moment, body components, with box limits ±b_i",
    "thrust_rtn": "applied force in the osculating orbit frame: radial, along-track, normal",
    "thrust_direction": "angle between the applied force and each body axis (and the engine's), |u_f| against its bound",
    "orbital_elements": "osculating radius, inclination and eccentricity against the target's",
    "constraints": "margin of each path constraint (≥ 0 where it holds), violations shaded",
    "velocity": "inertial velocity components (impulses as jumps)",
    "angular_velocity": "body angular velocity components and |Ω| (with a rate limit)",
    "costates": "discrete costates λ_k by block (direct: mapped from the NLP multipliers)",
    "convergence": "residual per iteration (Newton–Armijo: every line-search trial)",
    "continuous": "the plan flown through the continuous equations: position and attitude deviation from its nodes",
}


def caption(name: str, problem: Problem) -> str:
    """The caption of a figure for this problem (CAPTIONS, but the maneuver of a problem without a
    central body has no orbits)."""
    if name == "maneuver" and not problem.model.mu:
        return "no central body: the path and the body frame at a few nodes (a slew: the frame at a few times)"
    return CAPTIONS.get(name, name)


def applicable(runs: list[Run], problem: Problem) -> list[str]:
    """The names of the figures that apply to these runs (in FIGURES order)."""
    ctrl = any(r.sol.controls is not None for r in runs)
    central = bool(problem.model.mu)
    gone = removed(problem)
    skip = set(gone)  # a removed control: no component figure ("force", "moment")
    if not ctrl or gone == {"force", "moment"}:
        skip |= {"control_norms", "force", "moment", "thrust_rtn", "thrust_direction"}
    if "force" in gone or problem.disc.force_frame != "body":   # the direction in the body: a body-frame force's
        skip.add("thrust_direction")
    if "force" in gone:
        skip.add("thrust_rtn")
        if not central:  # no force and no gravity: the velocity is constant, a figure of flat lines
            skip.add("velocity")
    if not central:
        skip |= {"thrust_rtn", "orbital_elements"}
    if not problem.constraints:
        skip.add("constraints")
    if not any(r.sol.costates is not None for r in runs):
        skip.add("costates")
    if not any(r.sol.history for r in runs):
        skip.add("convergence")
    if not flown(runs):             # no continuous check (failed, impulsive, switched off)
        skip.add("continuous")
    return [n for n in FIGURES if n not in skip]


def draw(name: str, runs: list[Run], problem: Problem):
    """One figure by name (a failed run's non-finite states are drawn as gaps, without warnings)."""
    with np.errstate(all="ignore"):
        return FIGURES[name](runs, problem)



def figures(result: Solution | Comparison, which: tuple[str, ...] | None = None, *,
            constraint_tol: float | None = None) -> dict:
    """{name: Figure} of a Solution or a Comparison (both methods overlaid), drawn from memory;
    ``which`` limits the names (figures that do not apply are left out); ``constraint_tol``: margins
    of path constraints below -constraint_tol are drawn as violations (default
    store.DEFAULT_PATH_TOL; a results directory uses its maneuver's terminal_tol)."""
    runs = _runs(result, constraint_tol)
    problem = runs[0].sol.problem
    if which:
        unknown = set(which) - set(FIGURES)
        if unknown:
            raise ValueError(f"unknown figures {sorted(unknown)}; expected some of {', '.join(FIGURES)}")
    return {name: draw(name, runs, problem) for name in applicable(runs, problem) if not which or name in which}


def draw_all(results_dir: Path, which: tuple[str, ...] | None = None, *, stale_only: bool = False) -> list[Path]:
    """(Re)draw the figures of a results directory as PNG and PDF, from the run read back
    (:func:`problems.store.read_run`; :func:`draw_run` draws a run held in memory); returns the paths
    written.  ``which``, ``stale_only``: as :func:`draw_run`."""
    from ..store import read_run

    d = Path(results_dir)
    drawn = draw_run(d, read_run(d), which, stale_only=stale_only)
    return [d / f"fig_{name}.{ext}" for name in drawn for ext in ("png", "pdf")]


def draw_run(results_dir: Path, run, which: tuple[str, ...] | None = None, *,
             stale_only: bool = False) -> dict[str, bytes]:
    """Draw the figures of ``run`` (a :class:`problems.store.Run`: read back, or held by the command that has
    just written it) into the results directory as fig_<name>.png and .pdf; returns {name: the PNG's bytes,
    as written} of the figures drawn, in FIGURES order (report.html embeds them).  ``which`` limits the
    names; ``stale_only``: draw only the figures whose PNG is missing or older than the run's data.
    Redrawing every figure also deletes the files of figures that no longer apply (drawn by an
    earlier version: e.g. a force figure for a run whose force is removed)."""
    from ..store import path_tolerance

    d = Path(results_dir)
    runs = _runs(run.result, path_tolerance(run.maneuver))
    if not runs:                  # no method applies (its status says why): nothing to draw
        return {}
    problem = runs[0].sol.problem
    names = applicable(runs, problem)
    if stale_only:
        which = tuple(n for n in names if not is_fresh(d, n) and (not which or n in which))
        if not which:
            return {}
    if not which:
        for name in set(FIGURES) - set(names):
            for ext in (".png", ".pdf"):
                (d / f"fig_{name}{ext}").unlink(missing_ok=True)
    drawn = {}
    for name in names:  # one at a time: one figure in memory
        if which and name not in which:
            continue
        fig = draw(name, runs, problem)
        files = figure_files(fig)
        plt.close(fig)
        write_figure(files, d / f"fig_{name}")
        drawn[name] = files["png"]
    return drawn


def is_fresh(results_dir: Path, name: str) -> bool:
    """Whether fig_<name>.png exists and is newer than summary.json (the last file a run writes)."""
    d = Path(results_dir)
    png, summ = d / f"fig_{name}.png", d / "summary.json"
    return png.is_file() and summ.is_file() and png.stat().st_mtime_ns >= summ.stat().st_mtime_ns
