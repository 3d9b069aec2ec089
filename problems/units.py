"""The units a problem's numbers are in, as labels: one function, :func:`units`, for every figure,
the animation's clock and report.html.

Three cases (problems/bodies.py):

* **physical units** named by the maneuver file (``units:`` or ``central_body:``): labels in km, s,
  rad/s, and forces and moments *shown* in N and N·m whatever the length unit (``Units.factor``
  converts: a km-kg-s file's kN are drawn times 1000, its kN·km times 1e6);
* **normalized orbit units** (a central body of GM = 4π², no ``units:``; docs/mathematics.md §1):
  length in radii of the reference circular orbit, time in its periods;
* **unnamed units**: no central body (``gravity: {kind: none}``) or another GM, and no ``units:`` --
  the numbers are in whatever units the file used, and the labels name only the dimension
  ("mass·length²/time²") or nothing at all -- never "orbital periods".

A loaded maneuver's Problem carries its unit system (``Problem.units``: problems.physical.in_units,
called by problems.maneuvers), and every Problem derived from it by ``replace`` -- a refined level's, a
strategy's -- keeps it, so everything drawn from a Solution finds it; a Problem built in Python has none
unless given ``units=`` (normalized or unnamed, by its GM).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..transcription.ocp import MARGIN_DIMENSION
from .bodies import UnitSystem
from .models import GM_NORMALIZED

#: the dimension of each quantity the figures and the report label, in base dimensions
DIMENSIONS = {
    "time": "time", "length": "length", "velocity": "length/time", "force": "mass·length/time²",
    "moment": "mass·length²/time²", "angular_impulse": "mass·length²/time", "angular_rate": "rad/time",
    "angle": "deg", "mass": "mass", "none": "",
}
#: the normalized spelling of each base dimension (mass stays "mass": the body's mass as given)
_NORMALIZED = {"length": "radii", "time": "period"}


@dataclass(frozen=True)
class Units:
    """Unit labels of one problem.  ``normalized``: the orbit units of a central body with GM = 4π²;
    ``system``: the physical units the file names (then not normalized); ``mu``: GM (None: no central
    body), for the summary.

    ``unit(q)`` is the unit of a quantity q (a key of DIMENSIONS) as shown; ``factor(q)`` converts a
    value in the file's units to it (1 but for forces and moments of a non-SI file);
    ``label(text, q)`` is an axis label "text (unit)" -- without the parenthesis when the unit would
    only repeat the dimension's name ("time t", not "time t (time)"); ``duration(x)`` a length of time
    with its unit ("2.5 periods", "30 s" or "2.5 time units")."""

    normalized: bool
    system: UnitSystem | None = None
    mu: float | None = None

    def unit(self, quantity: str) -> str:
        if self.system is not None:
            return self.system.display(quantity)[0]
        dim = DIMENSIONS[quantity]
        if not self.normalized:
            return dim
        out = dim
        for base, name in _NORMALIZED.items():
            out = out.replace(base, name)
        return "periods" if out == "period" else out  # plural alone, singular in a quotient

    def factor(self, quantity: str) -> float:
        return self.system.display(quantity)[1] if self.system is not None else 1.0

    def shown(self, quantity: str) -> tuple[str, float]:
        """(unit, factor) of a quantity in a table (the CLI's, report.html's): a physical file's velocities in m/s and
        masses in kg, its forces and moments in N and N·m (as the figures draw them), the rest in the file's units;
        normalized and unnamed units as :meth:`unit`.  Shown value = factor * file value."""
        if self.system is None:
            return self.unit(quantity), 1.0
        if quantity in ("velocity", "mass"):
            return {"velocity": "m/s", "mass": "kg"}[quantity], self.system.si(quantity)
        return self.system.display(quantity)

    def amount(self, x: float, quantity: str) -> str:
        """A length, velocity or angle (rad) as a person reads it, three digits: physical lengths in m below 1 km,
        else km; physical velocities in m/s; angles in deg; otherwise the number with its :meth:`unit` (none when
        the unit would only name the dimension)."""
        if not math.isfinite(x):
            return "-"
        if quantity == "angle":
            return f"{math.degrees(x):.3g} deg"
        if self.system is not None and quantity in ("length", "velocity"):
            si = x * self.system.si(quantity)
            if quantity == "velocity":
                return f"{si:.3g} m/s"
            return f"{si / 1000:.3g} km" if abs(si) >= 1000 else f"{si:.3g} m"
        u = self.unit(quantity)
        return f"{x:.3g}" + (f" {u}" if u and u != DIMENSIONS[quantity] else "")

    def label(self, text: str, quantity: str) -> str:
        u = self.unit(quantity)
        return text if not u or u == quantity else f"{text} ({u})"

    @property
    def time_label(self) -> str:
        """The label of a time axis: "time t (orbital periods)", "time t (s)" or "time t"."""
        if self.system is not None:
            return f"time t ({self.system.time})"
        return "time t (orbital periods)" if self.normalized else "time t"

    def duration(self, x: float, fmt: str = "{:.3g}") -> str:
        if self.system is not None:
            return fmt.format(x) + f" {self.system.time}"
        return fmt.format(x) + (" periods" if self.normalized else " time units")

    @property
    def summary(self) -> str:
        """One line for a report's header."""
        if self.system is not None:
            s = self.system
            return (f"physical, as the configuration file names them: lengths in {s.length}, masses in {s.mass}, "
                    f"times in {s.time}; forces shown in N and moments in N·m, and in tables velocities in m/s")
        if self.normalized:
            return ("normalized orbit units: length in radii of the reference orbit, time in its periods "
                    "(GM = 4π²), mass as in the file")
        body = "no central body" if self.mu is None else f"a central body of GM = {self.mu:.10g}, not the normalized 4π²"
        return (f"those of the configuration file, which does not name them ({body}; units: or central_body: would); "
                f"composite units are shown by dimension")


def units_for(mu: float | None, system: UnitSystem | None = None) -> Units:
    """Physical units if ``system`` is given; else normalized orbit units iff there is a central body
    (GM ``mu``; None without gravity) with GM = 4π²."""
    if system is not None:
        return Units(normalized=False, system=system, mu=mu)
    return Units(normalized=mu is not None and math.isclose(mu, GM_NORMALIZED, rel_tol=1e-9), mu=mu)


def declared(problem) -> UnitSystem | None:
    """The UnitSystem a Problem carries (its ``units``: a loaded maneuver's ``units:`` or preset,
    :func:`problems.physical.in_units`), or None."""
    system = getattr(problem, "units", None)
    return system if isinstance(system, UnitSystem) else None


def units(problem) -> Units:
    """The units of a Problem: those its maneuver declared, else by its ``model.mu`` (:func:`units_for`)."""
    return units_for(getattr(getattr(problem, "model", None), "mu", None), declared(problem))


__all__ = ["DIMENSIONS", "MARGIN_DIMENSION", "Units", "declared", "units", "units_for"]
