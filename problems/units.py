"""The units a problem's numbers are in, as labels: one function, :func:`units`, for every figure,
the animation's clock and report.html.

With a central body of GM = 4π² the numbers are in the project's normalized orbit units
(docs/mathematics.md §1): length in radii of the reference circular orbit, time in its periods.
Without one (``gravity: {kind: none}``), or with another GM, nothing is normalized: the numbers
are in whatever units the configuration file used (the time-optimal slews give J in kg m², torques
in N m and T in s, but the file does not say so), and the labels name only the dimension
("mass·length²/time²") or nothing at all -- never "orbital periods".
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..transcription.problem import MARGIN_DIMENSION
from .models import GM_NORMALIZED

#: the dimension of each quantity the figures and the report label, in base dimensions
DIMENSIONS = {
    "time": "time", "length": "length", "velocity": "length/time", "force": "mass·length/time²",
    "moment": "mass·length²/time²", "angular_impulse": "mass·length²/time", "angular_rate": "rad/time",
    "angle": "deg", "none": "",
}
#: the normalized spelling of each base dimension (mass stays "mass": the body's mass as given)
_NORMALIZED = {"length": "radii", "time": "period"}


@dataclass(frozen=True)
class Units:
    """Unit labels of one problem.  ``normalized``: the orbit units of a central body with GM = 4π².

    ``unit(q)`` is the unit of a quantity q (a key of DIMENSIONS) for a table's unit column;
    ``label(text, q)`` is an axis label "text (unit)" -- without the parenthesis when the unit
    would only repeat the dimension's name ("time t", not "time t (time)");
    ``duration(x)`` a length of time with its unit ("2.5 periods" or "2.5 time units")."""

    normalized: bool

    def unit(self, quantity: str) -> str:
        dim = DIMENSIONS[quantity]
        if not self.normalized:
            return dim
        out = dim
        for base, name in _NORMALIZED.items():
            out = out.replace(base, name)
        return "periods" if out == "period" else out  # plural alone, singular in a quotient

    def label(self, text: str, quantity: str) -> str:
        u = self.unit(quantity)
        return text if not u or u == quantity else f"{text} ({u})"

    @property
    def time_label(self) -> str:
        """The label of a time axis: "time t (orbital periods)" or "time t"."""
        return "time t (orbital periods)" if self.normalized else "time t"

    def duration(self, x: float, fmt: str = "{:.3g}") -> str:
        return fmt.format(x) + (" periods" if self.normalized else " time units")

    @property
    def summary(self) -> str:
        """One line for a report's header."""
        if self.normalized:
            return ("normalized orbit units: length in radii of the reference orbit, time in its periods "
                    "(GM = 4π²), mass as in the file")
        return ("those of the configuration file (no central body with GM = 4π², so nothing is normalized; "
                "composite units are shown by dimension)")


def units_for(mu: float | None) -> Units:
    """Normalized orbit units iff there is a central body (GM ``mu``; None without gravity) with GM = 4π²."""
    return Units(normalized=mu is not None and math.isclose(mu, GM_NORMALIZED, rel_tol=1e-9))


def units(problem) -> Units:
    """The units of a Problem (its ``model.mu``, :func:`units_for`)."""
    return units_for(getattr(getattr(problem, "model", None), "mu", None))


__all__ = ["DIMENSIONS", "MARGIN_DIMENSION", "Units", "units", "units_for"]
