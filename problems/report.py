"""``report.html``: one self-contained page per results directory, for reading rather than parsing.

The page holds the run's status per method (a failed run is red at the top), a table of figures
of merit per method (status, cost, terminal errors, iterations, times, Δv, ∫|u_m|, peaks, time at
a bound, minimum constraint margins: :func:`se3ocp.transcription.results.solution.figures_of_merit`, the
same numbers as summary.json), the comparison verdict, the figures (PNG embedded as base64 data
URIs), the convergence history and the resolved configuration.  It needs no network, no script
and no file beside it: it opens offline in any browser and can be mailed as it is.

The page is a Jinja2 template (``templates/report.html.j2``) rendered with autoescaping, since
names, messages and the configuration come from user files.
"""
from __future__ import annotations

import base64
import datetime as _dt
import io
import math
from pathlib import Path
from typing import Any

from ..transcription.outcome import Result
from ..transcription.results.solution import Solution
from .burns import burn_section
from .io import atomic_write_bytes
from .units import DIMENSIONS, MARGIN_DIMENSION, Units, units

TEMPLATES = Path(__file__).resolve().parent / "templates"

#: rows of the summary table: (key of Solution.summary(), label, unit, format); the unit is a
#: quantity of problems.units.DIMENSIONS (shown in the problem's units) or a literal ("s": wall clock)
ROWS = (
    ("cost", "cost J", "", "{:.10g}"),
    ("terminal_error", "terminal error (max-norm of the residual)", "", "{:.2e}"),
    ("terminal_attitude_error_deg", "terminal attitude error", "angle", "{:.2e}"),
    ("iterations", "iterations", "", "{:d}"),
    ("build_s", "build time", "s", "{:.2f}"),
    ("solve_s", "solve time", "s", "{:.2f}"),
    ("delta_v", "Δv = Σ ω |u_f| / m", "velocity", "{:.6g}"),
    ("angular_impulse", "∫ |u_m| dt", "angular_impulse", "{:.6g}"),
    ("peak_force", "peak |u_f|", "force", "{:.6g}"),
    ("peak_moment", "peak |u_m|", "moment", "{:.6g}"),
    ("force_time_at_bound", "time with the force at its bound", "time", "{:.4g}"),
    ("moment_time_at_bound", "time with the moment at its bound", "time", "{:.4g}"),
    ("max_orthogonality_error", "max |RᵀR − I|", "", "{:.1e}"),
    ("max_relative_energy_error", "max relative energy error", "", "{:.1e}"),
    ("max_cayley_residual", "max Cayley residual", "", "{:.1e}"),
    ("N", "steps N", "", "{:d}"),
    ("T", "final time T", "time", "{:.6g}"),
    ("solver", "solver", "", "{}"),
)


#: rows of the continuous check's table (issue 26; docs/mathematics.md §11), as ROWS: summary key, label, unit, format
CONTINUOUS_ROWS = (
    ("continuous_maneuver_fraction", "flown miss as a fraction of the maneuver: largest of the terminal misses "
                                     "below over what the maneuver changes (> 1 %: the plan does not fly as planned)",
     "", "{:.2%}"),
    ("continuous_change_position", "the maneuver's position change (smallest of: free motion to target, radius)",
     "length", "{:.4g}"),
    ("continuous_change_velocity", "the maneuver's velocity change (smallest of: free motion to target, delta-v)",
     "velocity", "{:.4g}"),
    ("continuous_change_attitude_rad", "the maneuver's attitude change (smallest of: free motion to target, slew)",
     "rad", "{:.4g}"),
    ("continuous_miss", "continuous miss: max(position / L, velocity / V, attitude, rate), as solver.accuracy "
                        "judges it (L, V: orbit radius and circular speed; 1 without a central body)", "", "{:.2e}"),
    ("continuous_terminal_error", "terminal miss (largest of the four below, each in its own unit)", "", "{:.2e}"),
    ("continuous_terminal_position", "terminal position miss |x(T) − x_N|", "length", "{:.2e}"),
    ("continuous_terminal_velocity", "terminal velocity miss |v(T) − v_N|", "velocity", "{:.2e}"),
    ("continuous_terminal_attitude_rad", "terminal attitude miss ∠(R_NᵀR(T))", "rad", "{:.2e}"),
    ("continuous_terminal_rate", "terminal rate miss |Ω(T) − Ω_N|", "angular_rate", "{:.2e}"),
    ("continuous_target_error", "terminal error of the flight (as the plan's)", "", "{:.2e}"),
    ("continuous_max_position_deviation", "largest position deviation at the nodes", "length", "{:.2e}"),
    ("continuous_max_attitude_deviation_rad", "largest attitude deviation at the nodes", "rad", "{:.2e}"),
    ("continuous_attitude_growth", "growth of an attitude error given at the start, flown open loop (measured when "
                                   "the plan misses by more than 1 %; > 100: unstable open loop)", "", "{:.3g}"),
    ("continuous_check_s", "time of the check", "s", "{:.3f}"),
)


def continuous_section(sols: dict[str, Solution]) -> dict[str, Any] | None:
    """The report's continuous-check section: a table (CONTINUOUS_ROWS, then every path constraint's smallest
    margin between the nodes) with a cell per method that was flown, and each method's mesh history when it was
    refined to ``solver.accuracy``; None when no method was flown (failed runs, impulsive plans, the check off)."""
    flown = {m: s for m, s in sols.items() if s.continuous is not None}
    if not flown:
        return None
    un = units(next(iter(flown.values())).problem)
    summ = {m: {**s.continuous.summary(), "continuous_miss": s.continuous_miss} for m, s in flown.items()}
    extra = sorted({k for d in summ.values() for k in d if k.startswith("continuous_min_margin_")})
    rows = []
    for key, label, unit, fmt in CONTINUOUS_ROWS + tuple((k, f"smallest margin between the nodes: "
                                                             f"{k[len('continuous_min_margin_'):].replace('_', ' ')}",
                                                          MARGIN_DIMENSION.get(k[len('continuous_min_margin_'):]
                                                                               .rstrip('_0123456789'), "none"), "{:.4g}")
                                                         for k in extra):
        f = un.shown(unit)[1] if unit in DIMENSIONS else 1.0
        cells = [_fmt(d.get(key) * f if isinstance(d.get(key), float) else d.get(key), fmt) for d in summ.values()]
        rows.append({"label": label, "unit": _unit(un, unit), "cells": cells})
    meshes = [{"method": m, "rows": [[_cell(r.get(c)) for c in MESH_COLUMNS] for r in s.mesh]}
              for m, s in flown.items() if s.mesh]
    return {"methods": list(flown), "rows": rows, "meshes": meshes, "mesh_cols": list(MESH_COLUMNS),
            "messages": [f"{m}: {s.continuous.message}" for m, s in flown.items() if s.continuous.message]}


#: the columns of a mesh history (transcription.strategy.refine: one record per refinement level)
MESH_COLUMNS = ("level", "N", "mesh", "h_min", "h_max", "miss", "predicted", "path_violation", "iterations", "solve_s",
                "check_s", "status")


def _unit(un: Units, u: str) -> str:
    """The unit a table shows a quantity in (:meth:`Units.shown`: a km file's velocities in m/s), or the literal u."""
    return un.shown(u)[0] if u in DIMENSIONS else u


def _fmt(value: Any, fmt: str) -> str:
    if value is None:
        return "—"
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    try:
        return fmt.format(int(value) if fmt == "{:d}" else value)
    except (ValueError, TypeError):
        return str(value)


def merit_rows(sols: dict[str, Solution], tol: float | None = None) -> list[dict[str, Any]]:
    """The summary table: one row per quantity that some method has, a cell per method; the
    margins of path constraints violated by more than ``tol`` (store.path_tolerance; default
    store.DEFAULT_PATH_TOL) flagged ``bad`` -- a margin of -1e-11 is round-off, not a violation."""
    import numpy as np

    from .store import DEFAULT_PATH_TOL

    tol = DEFAULT_PATH_TOL if tol is None else tol
    with np.errstate(all="ignore"):  # a failed run's non-finite states: reported as nan, not warned about
        summ = {m: s.summary() for m, s in sols.items()}
    un = units(next(iter(sols.values())).problem) if sols else Units(normalized=True)
    rows = []
    keys = [r[0] for r in ROWS]
    extra = sorted({k for s in summ.values() for k in s if k.startswith("min_margin_")})
    for key in keys[:12] + extra + keys[12:]:
        if key.startswith("min_margin_"):
            kind = key[len("min_margin_"):].rstrip("_0123456789")
            label, fmt = f"minimum margin: {key[len('min_margin_'):].replace('_', ' ')}", "{:.4g}"
            unit_key = MARGIN_DIMENSION.get(kind, "none")
            unit = _unit(un, unit_key)
        else:
            _, label, unit_key, fmt = next(r for r in ROWS if r[0] == key)
            unit = _unit(un, unit_key)
        if not any(key in s for s in summ.values()):
            continue
        cells = []
        factor = un.shown(unit_key)[1] if unit_key in DIMENSIONS else 1.0  # a km file's kN in N, km/s in m/s
        for s in summ.values():
            v = s.get(key)
            bad = key.startswith("min_margin_") and isinstance(v, (int, float)) and v < -tol
            v = v * factor if isinstance(v, float) and factor != 1.0 else v
            cells.append({"text": _fmt(v, fmt), "bad": bad})
        rows.append({"label": label, "unit": unit, "cells": cells, "margin": key.startswith("min_margin_")})
    return rows


def _bounds(problem) -> list[str]:
    out = []
    ctrl, un = problem.control, units(problem)
    for name, b in (("force", getattr(ctrl, "force_bound", None)), ("moment", getattr(ctrl, "moment_bound", None))):
        f, u = un.factor(name), (f" {un.unit(name)}" if un.system is not None else "")  # shown as the figures show it
        if b is not None:
            out.append(f"{name}: {b.describe('u', f, u)}")
    if getattr(getattr(problem, "disc", None), "force_frame", "inertial") == "body":
        out.append("force: in the body frame (applied inertial force R u_f)")
    return out


def _horizon(problem) -> str:
    """The final time for the header: "T = 10 orbital periods", or free with its range and guess."""
    un = units(problem)
    unit = " orbital periods" if un.normalized else f" {un.system.time}" if un.system is not None else ""
    if problem.free_time:
        lo, hi = problem.time_bounds
        return f"T free in [{lo:g}, {hi:g}]{unit} (guess {problem.T:g})"
    return f"T = {problem.T:g}{unit}"


def _width(png: bytes) -> int:
    """The width in pixels of a PNG (from its IHDR chunk; 0 if it is not one)."""
    if png[:8] != b"\x89PNG\r\n\x1a\n" or len(png) < 24:
        return 0
    return int.from_bytes(png[16:20], "big")


def _wide(images: list[tuple[str, bytes]]) -> list[bool]:
    """Which figures are wider than the others (the maneuver with a zoom panel, a slew's frames
    side by side: 1.6 times the usual width) and get the page's full width, where their text is
    as large as the others' rather than shrunk into a column.  Short figures of the usual width
    stay in their column."""
    widths = [_width(b) for _, b in images]
    usual = sorted(widths)[len(widths) // 2] if widths else 0
    return [w > 1.3 * usual for w in widths]


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return buf.getvalue()


def figure_images(results_dir: Path | None, result, draw: bool = True, tol: float | None = None
                  ) -> list[tuple[str, bytes]]:
    """(name, PNG bytes) of every figure that applies to ``result``: the results directory's
    fig_<name>.png where it is up to date, otherwise drawn in memory (``draw``; ``tol`` the
    path-constraint tolerance) -- nothing is written."""
    import matplotlib.pyplot as plt

    from . import plots

    runs = plots._runs(result, tol)
    names = plots.applicable(runs, runs[0].sol.problem)
    out, missing = {}, []
    for n in names:
        if results_dir is not None and plots.is_fresh(results_dir, n):
            out[n] = (Path(results_dir) / f"fig_{n}.png").read_bytes()
        else:
            missing.append(n)
    if draw:
        for n in missing:  # one at a time: one figure in memory
            fig = plots.draw(n, runs, runs[0].sol.problem)
            out[n] = _png(fig)
            plt.close(fig)
    return [(n, out[n]) for n in names if n in out]


def render(run, images: list[tuple[str, bytes]], config_text: str = "") -> str:
    """The HTML of the report of a run (:class:`problems.store.Run`, read back or held in memory) with
    ``images`` ((name, PNG bytes)) embedded and ``config_text`` (the resolved configuration) shown."""
    import jinja2

    from .. import __version__
    from .plots import caption
    from .store import path_tolerance

    result = run.result
    sols = dict(run.solutions)
    problem = next(iter(sols.values())).problem if sols else run.maneuver.problem   # none: no method applies
    summ = run.summary
    methods = _status_cards(sols, summ)
    comparison = None
    if hasattr(result, "same_extremal"):
        comparison = {"verdict": result.verdict, "agree": bool(result.same_extremal),
                      "cost_rel": _fmt(result.cost_relative_difference, "{:.2e}"),
                      "control_rel": _fmt(result.control_max_difference_relative, "{:.2e}")}
    elif isinstance(summ.get("comparison"), dict):  # a method not applicable: its verdict says so
        c = summ["comparison"]
        comparison = {"verdict": str(c.get("verdict", "")), "agree": bool(c.get("same_extremal", False)),
                      "cost_rel": _fmt(c.get("cost_relative_difference"), "{:.2e}"),
                      "control_rel": _fmt(c.get("control_max_difference_relative"), "{:.2e}")}
    if comparison is not None:
        comparison["comparable"] = not comparison["verdict"].startswith("not comparable")
    history = []
    for m, s in sols.items():
        recs = [h.as_dict() for h in s.history]
        cols = [c for c in ("iteration", "trial", "residual", "dual", "cost", "step", "accepted", "phase", "elapsed_s")
                if any(_present(r.get(c)) for r in recs)]
        history.append({"method": m, "cols": cols,
                        "rows": [[_cell(r.get(c)) for c in cols] for r in recs]})
    command = summ.get("command") or ("compare" if comparison else "solve")
    tol = path_tolerance(run.maneuver)
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                             autoescape=jinja2.select_autoescape(["html", "j2"], default=True),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    return env.get_template("report.html.j2").render(
        name=run.maneuver.name, source=str(summ.get("config") or run.maneuver.source), command=command,
        version=__version__,
        generated=_dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        control=run.maneuver.control_kind or "none (free motion)", discretization=run.maneuver.discretization,
        N=run.maneuver.N, T=_horizon(problem), units=units(problem), methods=methods, method_names=list(sols),
        ok=all(m["converged"] for m in methods if m["applicable"]), rows=merit_rows(sols, tol), tol=tol, comparison=comparison,
        bounds=_bounds(problem), constraints=[_describe(c) for c in problem.constraints],
        figures=[{"name": n, "caption": caption(n, problem), "data": base64.b64encode(b).decode("ascii"),
                  "wide": w} for (n, b), w in zip(images, _wide(images))],
        history=history, config=config_text, continuous=continuous_section(sols),
        burns=[{"method": m, **sec} for m, sec in ((m, burn_section(s)) for m, s in sols.items()) if sec is not None])


def _status_cards(sols: dict[str, Solution], summ: dict) -> list[dict[str, Any]]:
    """One status card per method of the run, in summary.json's order: the Solutions read back, and
    the methods summary.json lists without a trajectory -- a method that does not apply to the
    problem (Result.not_applicable: status and message in its block) is a neutral card of its own."""
    blocks = summ.get("methods") if isinstance(summ.get("methods"), dict) else {}
    cards = []
    for m in list(blocks) + [m for m in sols if m not in blocks]:
        s = sols.get(m)
        if s is not None:
            cards.append({"name": m, "converged": s.converged, "status": s.result.value, "message": s.message,
                          "explain": s.result.message, "applicable": s.result is not Result.not_applicable,
                          "in_table": True})
            continue
        b = blocks[m] if isinstance(blocks[m], dict) else {}
        status = str(b.get("status", "unknown"))
        try:
            explain = Result(status).message
        except ValueError:
            explain = ""
        cards.append({"name": m, "converged": bool(b.get("converged", False)), "status": status,
                      "message": str(b.get("message", "")), "explain": explain,
                      "applicable": status != Result.not_applicable.value, "in_table": False})
    return cards


def _describe(c) -> str:
    from .plots import _describe as d

    return d(c)


def _present(v) -> bool:
    return v is not None and not (isinstance(v, float) and math.isnan(v)) and v != ""


def _cell(v) -> str:
    if not _present(v):
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def write_report(results_dir: Path, draw: bool = True) -> Path:
    """Write ``report.html`` into a results directory (atomically), from the run read back
    (:func:`problems.store.read_run`; :func:`write_run_report` writes the report of a run held in memory);
    figures are taken from the directory where up to date, else drawn in memory (``draw=False``: the page
    without them).  A flight directory (``se3ocp fly``) gets the flight report (problems/flight/report.py)."""
    from .flight.report import is_flight_dir, write_flight_report
    from .store import path_tolerance, read_run

    d = Path(results_dir)
    if is_flight_dir(d):
        return write_flight_report(d)
    run = read_run(d)
    images = figure_images(d, run.result, draw=draw, tol=path_tolerance(run.maneuver)) if run.solutions else []
    return write_run_report(d, run, images)


def write_run_report(results_dir: Path, run, images: list[tuple[str, bytes]]) -> Path:
    """Write ``report.html`` of ``run`` (a :class:`problems.store.Run`: read back, or held by the command
    that has just written it) into the results directory (atomically), with ``images`` ((name, PNG bytes),
    in FIGURES order: :func:`figure_images`, or the PNGs :func:`problems.plots.draw_run` has just written)
    embedded and the run's resolved configuration.  Returns the path written."""
    out = Path(results_dir) / "report.html"
    atomic_write_bytes(out, render(run, images, run.config_text).encode("utf-8"))
    return out


__all__ = ["CONTINUOUS_ROWS", "ROWS", "continuous_section", "figure_images", "merit_rows", "render", "write_report",
           "write_run_report"]
