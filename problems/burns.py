"""The burn table of a plan with a force, in the units a person reads (the CLI after its results table,
report.html): the burns of :mod:`se3ocp.transcription.results.burns` (``Solution.burns``), converted by
:meth:`problems.units.Units.shown` -- a km-kg-s file's delta-v in m/s, thrust in N, propellant in kg; a normalized
or unnamed file keeps its units.

With an engine's ``isp`` the propellant is the plan's impulse over the exhaust velocity Isp g0; the dynamics keep the
mass constant, so the table says so and gives the propellant as a fraction f of the mass.  Above
:data:`PROPELLANT_FRACTION_WARN` it warns: the same thrust on a body losing mass gives c ln(1/(1 - f)) instead of the
plan's c f, a delta-v larger by f/2 of the plan's (to first order); at f = 1 % that is 0.5 %, half of the 1 % of the
maneuver by which the flown miss is flagged (transcription.results.check.FLOWN_MISS_TOL), so below it the
constant-mass model's error stays inside what the results already accept.
"""
from __future__ import annotations

import math
from typing import Any

from ..transcription.ocp import ENGINE_ON_RTOL, engine_reference
from .units import units

#: the propellant fraction of the mass above which the table warns that the constant-mass dynamics are in error
#: (module docstring: a delta-v error of f/2, 0.5 % at 1 %)
PROPELLANT_FRACTION_WARN = 0.01

#: the table's columns: (header, Burn field, quantity of problems.units.DIMENSIONS)
COLUMNS = (("start", "start", "time"), ("stop", "stop", "time"), ("duration", "duration", "time"),
           ("Δv", "delta_v", "velocity"), ("mean thrust", "mean_thrust", "force"),
           ("peak thrust", "peak_thrust", "force"), ("propellant", "propellant", "mass"))


def burn_section(sol) -> dict[str, Any] | None:
    """The burn table of a converged Solution with smooth controls and a force (None otherwise: a failed plan's
    burns are in its summary.json only): {columns: [header (unit)], rows: [[text]], total: [text] (the plan's
    delta-v and propellant), notes: [sentences], warning: '' or a sentence}.  The propellant column only for an
    engine with an isp."""
    if getattr(sol, "controls", None) is None or not len(sol.u_f) or sol.problem is None or not sol.converged:
        return None
    un = units(sol.problem)
    bound = getattr(sol.problem.control, "force_bound", None)
    if bound is not None and bound.removed:
        return None
    c = None if bound is None else bound.exhaust_velocity
    cols = [col for col in COLUMNS if c is not None or col[1] != "propellant"]

    def shown(x: float, quantity: str) -> str:
        unit, f = un.shown(quantity)
        return "-" if not math.isfinite(x) else f"{f * x:.4g}"

    header = [f"{h} ({un.shown(q)[0]})" if un.shown(q)[0] else h for h, _, q in cols]
    rows = [[str(i + 1)] + [shown(getattr(b, key), q) for _, key, q in cols] for i, b in enumerate(sol.burns)]
    total = {"delta_v": sol.delta_v, "propellant": sol.propellant}
    ref = engine_reference(bound, sol.u_f)
    fu, ff = un.shown("force")
    what = "the force bound" if bound is not None else "the peak |u_f|"
    notes = [f"a burn: |u_f| above {ENGINE_ON_RTOL:g} of {what} ({ff * ref:.4g}{' ' + fu if fu else ''}); start and "
             f"stop are the edges of its first and last controls' quadrature cells"]
    rest = sol.delta_v - sum(b.delta_v for b in sol.burns)
    if sol.burns and abs(rest) > 0:
        notes.append(f"Δv outside the burns (|u_f| at or below the threshold): {shown(rest, 'velocity')} "
                     f"{un.shown('velocity')[0]}".rstrip())
    warning = ""
    if c is not None:
        m, mu, mf = sol.trajectory.mass, *un.shown("mass")
        frac = sol.propellant / m
        vu, vf = un.shown("velocity")
        notes.append(f"propellant = impulse / c, the exhaust velocity c = Isp g0 = {vf * c:.5g}"
                     f"{' ' + vu if vu else ''}; the dynamics keep the mass constant: the propellant is "
                     f"{100 * frac:.3g} % of the {mf * m:.4g}{' ' + mu if mu else ''} spacecraft")
        if frac > PROPELLANT_FRACTION_WARN:
            warning = (f"the propellant is {100 * frac:.3g} % of the mass, above {100 * PROPELLANT_FRACTION_WARN:g} %: "
                       f"the constant-mass dynamics under-state what the thrust gives by about {50 * frac:.2g} % of "
                       f"the Δv")
    return {"columns": ["burn"] + header, "rows": rows,
            "total": ["total"] + ["" if key not in total else shown(total[key], q) for _, key, q in cols],
            "notes": notes, "warning": warning}


def burn_lines(sols) -> list[str]:
    """The burn table of each Solution with a force, as text lines (the CLI, after its results table)."""
    out = []
    for s in sols:
        sec = burn_section(s)
        if sec is None:
            continue
        table = [sec["columns"]] + sec["rows"] + [sec["total"]]
        widths = [max(len(r[i]) for r in table) for i in range(len(sec["columns"]))]
        out.append(f"{s.method}: {len(sec['rows'])} burn{'s' if len(sec['rows']) != 1 else ''}")
        out += [("  " + "  ".join(f"{x:>{w}}" for x, w in zip(r, widths))).rstrip() for r in table]
        out += [f"  {n}" for n in sec["notes"]]
        if sec["warning"]:
            out.append(f"warning: {s.method}: {sec['warning']}")
    return out


__all__ = ["COLUMNS", "PROPELLANT_FRACTION_WARN", "burn_lines", "burn_section"]
