"""Central-body presets and physical unit systems (the ``central_body:`` and ``units:`` keys).

A maneuver file's numbers are in one of three kinds of units:

* **normalized orbit units** (the default, the paper's examples): GM = 4π², length in radii of the
  reference circular orbit, time in its periods, mass as in the file -- no physical unit;
* **physical units** named by ``units: {length: km | m, mass: kg, time: s}`` or by a preset
  ``central_body: {name: earth, units: km | m}`` (``central_body: earth`` means km): every number
  of the file is then in those units (inertia in kg·km² with km, torque in kg·km²/s² = kN·km, force
  in kg·km/s² = kN);
* unnamed units: a file with another GM (or no gravity) and no ``units:`` -- labels name only the
  dimension.

A preset gives the central body's GM, equatorial radius and J2 in the chosen units
(:data:`PRESETS`); it fills ``model.mu``, ``model.central_body_radius`` and, for ``gravity: {kind: j2}``,
``gravity.J2`` and ``gravity.radius`` where the file does not give them.  A ``model.mu`` given
together with a preset must equal the preset's GM (to 1e-9): anything else is a unit mistake or
two bodies at once.

:class:`UnitSystem` names the unit of each quantity, composed from the length, mass and time units
(:meth:`UnitSystem.unit`: "km/s", "kN", "kN·km"), and gives the factor to the unit a figure shows
(:meth:`UnitSystem.display`: force in N, moment in N·m, whatever the length unit).

:class:`Scale` reads normalized orbit units physically: a reference circular orbit of radius
``radius`` (in km) about a preset body fixes the length unit (that radius) and the time unit (its
period 2π sqrt(a³/GM)); only the exports use it (``se3ocp export --reference-radius``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class CentralBody:
    """A central body in SI units: CCSDS name, GM (m³/s²), equatorial radius (m), J2, and the source."""

    name: str
    gm: float
    radius: float
    J2: float
    source: str

    def in_units(self, length: str) -> dict[str, float]:
        """GM, radius and J2 in ``length`` units (km or m) and seconds."""
        L = LENGTH_UNITS[length]
        return {"mu": self.gm / L**3, "radius": self.radius / L, "J2": self.J2}


#: the presets by the name a file gives; the IERS Conventions (2010) numerical standards
PRESETS = {
    "earth": CentralBody("EARTH", 3.986004418e14, 6378136.6, 1.0826359e-3, "IERS Conventions (2010), Table 1.1"),
}
#: metres per length unit
LENGTH_UNITS = {"m": 1.0, "km": 1000.0}
MASS_UNITS = {"kg": 1.0}
TIME_UNITS = {"s": 1.0}
#: the default length unit of ``central_body: NAME``
DEFAULT_PRESET_LENGTH = "km"

#: SI prefixes by power of ten, for composite unit names
_PREFIX = {-9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}


@dataclass(frozen=True)
class UnitSystem:
    """Length, mass and time units of a file's numbers (names from LENGTH_UNITS, MASS_UNITS, TIME_UNITS)."""

    length: str = "m"
    mass: str = "kg"
    time: str = "s"

    def si(self, quantity: str) -> float:
        """SI value of one unit of ``quantity`` (a key of :data:`POWERS`)."""
        pl, pm, pt = POWERS[quantity]
        return LENGTH_UNITS[self.length] ** pl * MASS_UNITS[self.mass] ** pm * TIME_UNITS[self.time] ** pt

    def unit(self, quantity: str) -> str:
        """The name of the unit the file's numbers of ``quantity`` are in: 'km', 'km/s', 'kN', 'kN·km'."""
        L, M, T = self.length, self.mass, self.time
        if quantity in ("force", "moment", "impulse", "angular_impulse") and M == "kg" and T == "s":
            f = _prefixed("N", round(math.log10(LENGTH_UNITS[L])))
            return {"force": f, "moment": f"{f}·{L}", "impulse": f"{f}·s", "angular_impulse": f"{f}·{L}·s"}[quantity]
        return {"time": T, "length": L, "velocity": f"{L}/{T}", "acceleration": f"{L}/{T}²",
                "mass": M, "inertia": f"{M}·{L}²", "gm": f"{L}³/{T}²", "angular_rate": f"rad/{T}",
                "force": f"{M}·{L}/{T}²", "moment": f"{M}·{L}²/{T}²", "impulse": f"{M}·{L}/{T}",
                "angular_impulse": f"{M}·{L}²/{T}", "angle": "deg", "none": ""}[quantity]

    def display(self, quantity: str) -> tuple[str, float]:
        """(unit name, factor) for a figure: force in N, moment in N·m, impulses in N·s and N·m·s,
        everything else in the file's units (factor 1).  Shown value = factor * file value."""
        if quantity in ("force", "moment", "impulse", "angular_impulse"):
            return {"force": "N", "moment": "N·m", "impulse": "N·s", "angular_impulse": "N·m·s"}[quantity], self.si(quantity)
        return self.unit(quantity), 1.0


#: (length, mass, time) powers of each quantity
POWERS = {"time": (0, 0, 1), "length": (1, 0, 0), "velocity": (1, 0, -1), "acceleration": (1, 0, -2),
          "mass": (0, 1, 0), "inertia": (2, 1, 0), "gm": (3, 0, -2), "angular_rate": (0, 0, -1),
          "force": (1, 1, -2), "moment": (2, 1, -2), "impulse": (1, 1, -1), "angular_impulse": (2, 1, -1),
          "angle": (0, 0, 0), "none": (0, 0, 0)}


def _prefixed(base: str, power: int) -> str:
    return f"{_PREFIX[power]}{base}" if power in _PREFIX else f"1e{power} {base}"


@dataclass(frozen=True)
class Scale:
    """A physical reading of a file's numbers for the exports: metres, kilograms and seconds per file
    unit of length, mass and time (mass None: not known, the exports that need it say so), the CCSDS
    name of the central body (None: not known) and one line saying where the scale comes from."""

    length_m: float
    time_s: float
    mass_kg: float | None
    center: str | None
    origin: str

    @classmethod
    def of_units(cls, units: UnitSystem, center: str | None) -> "Scale":
        return cls(LENGTH_UNITS[units.length], TIME_UNITS[units.time], MASS_UNITS[units.mass], center,
                   f"the file's units ({units.length}, {units.mass}, {units.time})")

    @classmethod
    def reference_orbit(cls, body: str, radius_km: float, mu_file: float) -> "Scale":
        """Normalized orbit units (GM = ``mu_file`` = 4π² in radii³/periods²) read as a circular orbit of
        radius ``radius_km`` about the preset ``body``: 1 length unit = radius, 1 time unit = period."""
        cb = PRESETS[body]
        a = radius_km * 1000.0
        # mu_file [L^3/T^2] = GM [m^3/s^2] * T^2 / L^3  ->  T = sqrt(mu_file * L^3 / GM)
        T = math.sqrt(mu_file * a**3 / cb.gm)
        return cls(a, T, None, cb.name, f"normalized units read as a circular orbit of radius {radius_km:.10g} km "
                                        f"about {cb.name} (GM {cb.gm:.10g} m^3/s^2): 1 length unit = {radius_km:.10g} km,"
                                        f" 1 time unit = {T:.10g} s")


def preset_values(name: str, length: str) -> dict[str, Any]:
    """{mu, radius, J2, center} of a preset in ``length`` units (km or m) and seconds."""
    cb = PRESETS[name]
    return {**cb.in_units(length), "center": cb.name}


__all__ = ["CentralBody", "DEFAULT_PRESET_LENGTH", "LENGTH_UNITS", "POWERS", "PRESETS", "Scale", "UnitSystem",
           "preset_values"]
