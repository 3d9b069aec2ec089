"""On/off thrusters in a flight: the commanded force of each control period delivered as one full-thrust pulse of the
right width, with a minimum impulse bit (docs/mathematics.md §11, *On/off thrusters*).

Over node interval k (the control period, length h_k) the law commands the affine force a_f -> b_f (the command's
frame: inertial, or the body's for a body-fixed engine).  Its impulse, with what earlier periods left over,

    I_k = h_k (a_f + b_f) / 2 + c_k,

is delivered as one pulse of the force F d (d = I_k / |I_k|, F the thrusters' on level) and width tau_k = |I_k| / F,
placed on the command's centroid in the period (s_c = (alpha + 2 beta) / (3 (alpha + beta)), alpha = a_f.d, beta = b_f.d,
the pulse shifted to fit in the period): then the period's delivered impulse is I_k to round-off and its first moment
the command's where the pulse fits.  Pulse-width modulation, one pulse per period:

* |I_k| < the minimum impulse bit: nothing fires and the impulse is **carried** to the next period, c_{k+1} = I_k
  (accumulated, never dropped: the sum of the delivered impulses stays within one bit of the commanded sum);
* tau_k > h_k (more than full thrust for the whole period): the period fires throughout and the excess is cut
  (c_{k+1} = 0; a saturated period, counted);
* otherwise c_{k+1} = 0.

The moment command is not pulsed (it stays the law's affine command).
:func:`transcription.closedloop.actuated.fly_actuated` flies any control law so, each period split at the pulse's
edges into at most three intervals of the flight engine (CVODES restarted at each edge, never integrated across the
switch).  A tracker told what was delivered (:meth:`Tracker.delivered`) does not
mistake a carried or cut impulse for a disturbance.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Pulses:
    """On/off thrusters: ``thrust`` F > 0, the force while a pulse is on (force units), and ``minimum_impulse`` >= 0,
    the smallest impulse one pulse can give (force x time, the file's units)."""

    thrust: float
    minimum_impulse: float = 0.0

    def __post_init__(self):
        if not (np.isfinite(self.thrust) and self.thrust > 0):
            raise ValueError(f"pulses: the thrust must be a positive number, got {self.thrust!r}")
        if not (np.isfinite(self.minimum_impulse) and self.minimum_impulse >= 0):
            raise ValueError(f"pulses: the minimum impulse must be a non-negative number, got {self.minimum_impulse!r}")


@dataclass(frozen=True)
class Pulse:
    """One period's pulse: ``start`` and ``width`` as fractions of the period (s in [0, 1]), ``force`` (3,) while on,
    ``commanded`` (3,) the period's own command's impulse h (a + b) / 2, ``delivered`` (3,) = width h force."""

    start: float
    width: float
    force: np.ndarray
    commanded: np.ndarray
    delivered: np.ndarray


@dataclass
class Modulator:
    """Pulse-width modulation of one flight (module docstring): call :meth:`period` for k = 0, 1, ... in order.
    ``carry`` (3,): the impulse carried to the next period; ``fired``, ``skipped``, ``saturated``: periods with a
    pulse, with a commanded impulse below the bit (carried), with more than full thrust (cut); ``narrowest``: the
    narrowest pulse's width (time units)."""

    pulses: Pulses
    carry: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fired: int = 0
    skipped: int = 0
    saturated: int = 0
    narrowest: float = np.inf

    def period(self, a: np.ndarray, b: np.ndarray, h: float) -> Pulse:
        """The pulse of a period of length h whose force command goes from a (3,) to b (3,) (affine)."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        own = 0.5 * h * (a + b)
        total = own + self.carry
        n = float(np.linalg.norm(total))
        F = self.pulses.thrust
        if n == 0.0 or n < self.pulses.minimum_impulse:
            self.skipped += n > 0.0
            self.carry = total
            return Pulse(0.0, 0.0, np.zeros(3), own, np.zeros(3))
        d = total / n
        width = n / (F * h)
        if width > 1.0:
            self.saturated += 1
            width = 1.0
        self.carry = np.zeros(3)
        alpha, beta = float(a @ d), float(b @ d)
        centre = (alpha + 2.0 * beta) / (3.0 * (alpha + beta)) if alpha + beta > 0 else 0.5
        start = min(max(centre - 0.5 * width, 0.0), 1.0 - width)
        self.fired += 1
        self.narrowest = min(self.narrowest, width * h)
        delivered = total if width < 1.0 else F * h * d
        return Pulse(start, width, F * d, own, delivered)

    def summary(self, mass: float) -> dict:
        """The flight's pulse figures (:data:`PULSE_COLUMNS`): pulses fired, periods skipped (carried) and saturated,
        the narrowest pulse (time units; NaN without one), the impulse left carried at the end as a velocity."""
        return {"pulses": self.fired, "pulses_skipped": self.skipped, "pulses_saturated": self.saturated,
                "narrowest_pulse": float(self.narrowest) if self.fired else float("nan"),
                "carried_delta_v": float(np.linalg.norm(self.carry)) / mass}


#: flights.csv's columns of a pulsed flight (:meth:`Modulator.summary`)
PULSE_COLUMNS = ("pulses", "pulses_skipped", "pulses_saturated", "narrowest_pulse", "carried_delta_v")


#: a gap between a pulse and its period's edge below this fraction of the period is closed by moving the pulse
#: (never integrated: CVODES on an interval of round-off length)
EDGE = 1e-9


def segments(pulse: Pulse) -> list[tuple[float, float, np.ndarray]]:
    """The period split at the pulse's edges: (s_lo, s_hi, force (3,)) for the off, on, off parts of positive length."""
    s0 = pulse.start if pulse.start > EDGE else 0.0
    s1 = s0 + pulse.width
    if 1.0 - s1 <= EDGE:              # a gap of round-off at either end: the pulse moved onto the edge, its width kept
        s0, s1 = 1.0 - pulse.width, 1.0
    parts = [(0.0, s0, np.zeros(3)), (s0, s1, pulse.force), (s1, 1.0, np.zeros(3))]
    return [(lo, min(hi, 1.0), f) for lo, hi, f in parts if hi - lo > 0.0 and lo < 1.0]
