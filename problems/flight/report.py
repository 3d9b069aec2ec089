"""``report.html`` of a Monte Carlo flight directory (``se3ocp fly`` writes it; ``se3ocp report DIR`` redraws
it): one self-contained page, the flight section of the project's report -- what was flown (the plan, the
truth, the errors, the feedback modes, where and how long), the statistics of every figure of merit with
the feedback modes side by side (mean, p95, p99.7) and closed over open loop, the re-plans' solve times
(MPC), the figures (terminal-miss scatter with 3-sigma ellipses, histograms, truth tracks, control usage
against the bounds; embedded PNG) and the resolved flight block and maneuver.

Everything comes from the directory's own files (summary.json, config.resolved.yaml, flight.resolved.yaml,
flight_*.png), so the page is the same whether written by ``fly`` or redrawn later.  The page's style is the
solve report's (templates/report.html.j2), one stylesheet for both."""
from __future__ import annotations

import base64
import datetime as _dt
import json
import math
import re
from pathlib import Path

from ..elements import ELEMENT_DIFFERENCES
from ..io import atomic_write_bytes
from ..units import DIMENSIONS, MARGIN_DIMENSION, Units, units
from .schema import preset_text

#: the page templates (the solve report's and this one)
TEMPLATES = Path(__file__).resolve().parents[1] / "templates"
#: the table's rows: (metric, label, quantity of problems.units.DIMENSIONS or a literal unit, format)
ROWS = (
    ("position_miss", "terminal position miss", "length", "{:.3e}"),
    ("velocity_miss", "terminal velocity miss", "velocity", "{:.3e}"),
    ("attitude_miss_deg", "terminal attitude miss", "angle", "{:.3e}"),
    ("rate_miss", "terminal rate miss |ΔΩ|", "angular_rate", "{:.3e}"),
    ("estimation_position", "navigation: RMS position estimate error", "length", "{:.3e}"),
    ("estimation_velocity", "navigation: RMS velocity estimate error", "velocity", "{:.3e}"),
    ("estimation_attitude_deg", "navigation: RMS attitude estimate error", "angle", "{:.3e}"),
    ("estimation_rate", "navigation: RMS rate estimate error", "angular_rate", "{:.3e}"),
    ("estimation_nees", "navigation: mean NEES per measured component (1: consistent)", "none", "{:.3g}"),
    ("delta_v", "Δv delivered", "velocity", "{:.6g}"),
    ("delta_v_overhead", "Δv overhead over the plan's (delivered)", "%", "{:.3f}"),
    ("delta_v_commanded_overhead", "Δv overhead over the plan's (commanded)", "%", "{:.3f}"),
    ("angular_impulse", "∫ |u_m| dt", "angular_impulse", "{:.6g}"),
    ("peak_force", "peak |u_f| applied", "force", "{:.6g}"),
    ("peak_moment", "peak |u_m| applied", "moment", "{:.6g}"),
    ("saturated_fraction", "steps whose correction the bounds limited", "%", "{:.2f}"),
    ("max_position_deviation", "largest position deviation from the plan", "length", "{:.3e}"),
    ("max_attitude_deviation_deg", "largest attitude deviation from the plan", "angle", "{:.3e}"),
    *((f"miss_{k}", f"terminal miss in osculating {name}", q, "{:.3e}") for k, name, q in ELEMENT_DIFFERENCES),
    ("pulses", "thruster pulses fired", "", "{:.1f}"),
    ("pulses_skipped", "periods under the minimum impulse (carried)", "", "{:.1f}"),
    ("pulses_saturated", "periods at full thrust throughout (excess cut)", "", "{:.1f}"),
    ("narrowest_pulse", "narrowest pulse", "time", "{:.4g}"),
    ("carried_delta_v", "Δv left carried at the end", "velocity", "{:.3e}"),
    ("wheel_torque_used", "peak wheel torque over its limit (the most used wheel)", "%", "{:.2f}"),
    ("wheel_momentum_used", "peak wheel momentum over its limit (the most used wheel)", "%", "{:.2f}"),
)
#: the columns of each feedback mode
STATS = (("mean", "mean"), ("p95", "p95"), ("p99_7", "p99.7"))
MODE_LABELS = {"none": "open loop", "lqr": "LQR", "mpc": "MPC"}
#: the figures of problems/flight/figures.py, in page order, with their captions
FIGURES = (
    ("flight_miss", "terminal misses of every run, one row per feedback mode: the position in the target orbit's "
                    "RTN frame (inertial axes without a central motion) and the attitude error, with 3σ ellipses"),
    ("flight_histograms", "histograms of the terminal misses and the Δv overhead, feedback modes overlaid"),
    ("flight_tracks", "the first runs' deviation from the plan's nodes (position, attitude angle)"),
    ("flight_controls", "the first runs' applied controls against the actuators' bounds (solid) and the plan's "
                        "(dashed, with a bounds margin)"),
    ("flight_navigation", "with navigation: the LQR flights' terminal misses beside their RMS estimation errors "
                          "(the estimate the tracker read)"),
)


def is_flight_dir(d: Path) -> bool:
    """Whether ``d`` holds a Monte Carlo flight (what ``se3ocp fly`` writes)."""
    d = Path(d)
    return all((d / n).is_file() for n in ("flights.csv", "flight.resolved.yaml", "summary.json"))


def stylesheet() -> str:
    """The solve report's stylesheet (the <style> element of templates/report.html.j2): one for both pages."""
    m = re.search(r"<style>(.*?)</style>", (TEMPLATES / "report.html.j2").read_text(), re.S)
    return m.group(1) if m else ""


def shown(un: Units, q: str) -> tuple[str, float]:
    """(unit, factor) a flight's tables show a quantity ``q`` in (shown value = factor * value): '%' for a fraction,
    a physical file's velocities in m/s, forces and moments in N and N·m (problems.units), the others in the file's
    units (:class:`~problems.units.Units`); ``q`` outside DIMENSIONS is itself the unit."""
    if q == "%":
        return "%", 100.0
    if q not in DIMENSIONS:
        return q, 1.0
    if q == "velocity" and un.system is not None:
        return "m/s", un.system.si("velocity")
    return un.unit(q), un.factor(q)


def table(summary: dict, un: Units, tol: float = 0.0) -> list[dict]:
    """The statistics table: a row per figure of merit any mode has, cells (mean, p95, p99.7) per mode;
    units by :func:`shown`; each wheel's headroom used (peak torque and momentum over its limits); a margin row ``bad``
    where one of
    its statistics is below -tol (a path constraint violated by more than round-off)."""
    stats = summary["statistics"]
    rows = list(ROWS)
    margins = sorted({k for s in stats.values() for k in s if k.startswith("min_margin_")})
    rows += [(k, f"minimum margin: {k[len('min_margin_'):].replace('_', ' ')}",
              MARGIN_DIMENSION.get(k[len("min_margin_"):].rstrip("_0123456789"), "none"), "{:.4g}") for k in margins]
    wheels = sorted(((int(m.group(1)), m.group(2)) for s in stats.values() for k in s
                     if (m := re.fullmatch(r"wheel(\d+)_(torque|momentum)_used", k))), key=lambda w: (w[0], w[1] != "torque"))
    rows += [(f"wheel{i}_{what}_used", f"wheel {i}: peak {what} over its limit", "%", "{:.2f}")
             for i, what in dict.fromkeys(wheels)]
    out = []
    for key, label, q, fmt in rows:
        if not any(stats[m].get(key, {}).get("n") for m in stats):
            continue
        unit, factor = shown(un, q)
        cells = []
        for m in stats:
            d = stats[m].get(key, {})
            for s, _ in STATS:
                v = d.get(s)
                cells.append("—" if v is None or not math.isfinite(v) else fmt.format(factor * v))
        values = [stats[m].get(key, {}).get(st) for m in stats for st, _ in STATS]
        out.append({"label": label, "unit": unit, "cells": cells,
                    "bad": key.startswith("min_margin_") and any(v is not None and v < -tol for v in values)})
    return out


def render(summary: dict, un: Units, images: list[tuple[str, str, bytes]], flight_text: str, config_text: str,
           tol: float = 0.0) -> str:
    """The HTML of a flight's report."""
    import jinja2

    from ... import __version__

    modes = list(summary["statistics"])
    ratios = [{"mode": MODE_LABELS[m], **{k: ("—" if v is None else f"{v:.2e}") for k, v in summary[key].items()}}
              for m, key in (("lqr", "closed_over_open"), ("mpc", "mpc_over_open")) if key in summary]
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                             autoescape=jinja2.select_autoescape(["html", "j2"], default=True),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    return env.get_template("flight.html.j2").render(
        style=stylesheet(), s=summary, version=__version__, units=un, modes=[MODE_LABELS[m] for m in modes],
        stats=[label for _, label in STATS], rows=table(summary, un, tol), ratios=ratios, mpc=summary.get("mpc"),
        generated=_dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
        figures=[{"name": n, "caption": c, "data": base64.b64encode(b).decode("ascii")} for n, c, b in images],
        flight=flight_text, config=config_text, preset=preset_text(summary.get("truth_from_preset", {}), un.unit("length")))


def write_flight_report(d: Path, summary: dict | None = None) -> Path:
    """Write ``report.html`` into a flight directory (atomically) from its files; ``summary``: summary.json's
    content when it is not written yet (``se3ocp fly`` writes summary.json last)."""
    from ..maneuvers import parse_maneuver
    from ..schema import read_yaml_file
    from ..store import path_tolerance

    d = Path(d)
    summary = summary if summary is not None else json.loads((d / "summary.json").read_text())
    config_text = (d / "config.resolved.yaml").read_text()
    man = parse_maneuver(read_yaml_file(d / "config.resolved.yaml"), str(summary.get("config", "")))
    images = [(n, c, (d / f"{n}.png").read_bytes()) for n, c in FIGURES if (d / f"{n}.png").is_file()]
    html = render(summary, units(man.problem), images, (d / "flight.resolved.yaml").read_text(), config_text,
                  path_tolerance(man))
    out = d / "report.html"
    atomic_write_bytes(out, html.encode("utf-8"))
    return out
