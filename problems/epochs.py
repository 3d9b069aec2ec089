"""Epochs (UTC, ISO-8601) and the names of inertial reference frames, for the exports.

A maneuver's ``epoch:`` is the UTC instant of t = 0, written ``YYYY-MM-DDThh:mm:ss[.fff...][Z]``
(any number of decimal places); without it, J2000.0.  J2000.0 is 2000-01-01T12:00:00 TT; with
TT - TAI = 32.184 s and TAI - UTC = 32 s in 2000 (:data:`LEAP_SECONDS`) that is
2000-01-01T11:58:55.816 UTC (:data:`J2000_UTC`; :func:`j2000_utc` derives it from the table).

An epoch is kept exactly: the calendar day and the seconds of that day as a Decimal, so that adding
the node times t_k (binary floats, converted exactly) and printing them loses nothing but the
last printed digit.  UTC here counts 86400 s a day: a span that contains a leap second (the last
second of a day before a date in :data:`LEAP_SECONDS`) cannot be labelled that way, and
:func:`check_no_leap_second` refuses it rather than shift every later epoch by one second.

Time systems (:data:`TIME_SYSTEMS`): an export may label its epochs in TAI, TT or GPS instead of UTC.  The
elapsed times t are physical seconds, so every label is the start's label + t; the start's is UTC + (TAI - UTC
on its date) for TAI, TAI + 32.184 s for TT, TAI - 19 s for GPS (:func:`offset_from_utc`).  Those three count
no leap seconds, so a span over one is refused only in UTC.

Frames: ``frame:`` names the inertial frame of the file's positions and velocities, as CCSDS writes
it (:data:`FRAMES`; default EME2000).  The dynamics do not depend on it: it is a label for
downstream tools, which must agree with how the initial state was obtained.
"""
from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass
from decimal import ROUND_HALF_EVEN, Decimal

#: CCSDS reference-frame names a maneuver may give as ``frame:`` (SANA registry spelling)
FRAMES = ("EME2000", "ICRF", "GCRF")
DEFAULT_FRAME = "EME2000"

#: UTC dates at whose start TAI - UTC stepped to the value given (IERS Bulletin C; the 1972-01-01
#: entry is the start of the leap-second era, not a leap second).  No leap second has been
#: announced after 2017-01-01 at the time of writing: for later dates the table assumes none.
LEAP_SECONDS = (
    ("1972-01-01", 10), ("1972-07-01", 11), ("1973-01-01", 12), ("1974-01-01", 13), ("1975-01-01", 14),
    ("1976-01-01", 15), ("1977-01-01", 16), ("1978-01-01", 17), ("1979-01-01", 18), ("1980-01-01", 19),
    ("1981-07-01", 20), ("1982-07-01", 21), ("1983-07-01", 22), ("1985-07-01", 23), ("1988-01-01", 24),
    ("1990-01-01", 25), ("1991-01-01", 26), ("1992-07-01", 27), ("1993-07-01", 28), ("1994-07-01", 29),
    ("1996-01-01", 30), ("1997-07-01", 31), ("1999-01-01", 32), ("2006-01-01", 33), ("2009-01-01", 34),
    ("2012-07-01", 35), ("2015-07-01", 36), ("2017-01-01", 37),
)
#: TT - TAI in seconds (exact by definition)
TT_MINUS_TAI = Decimal("32.184")
#: GPS - TAI in seconds (GPS time was UTC at 1980-01-06, when TAI - UTC was 19 s; it counts no leap seconds)
GPS_MINUS_TAI = Decimal(-19)
#: the time systems an export may label its epochs in (CCSDS TIME_SYSTEM names)
TIME_SYSTEMS = ("UTC", "TAI", "TT", "GPS")
#: J2000.0 (2000-01-01T12:00:00 TT) in UTC; tests check it against :func:`j2000_utc`
J2000_UTC = "2000-01-01T11:58:55.816"

_DAY = Decimal(86400)
_ISO = re.compile(r"(\d{4})-(\d{2})-(\d{2})(?:[T ](\d{2}):(\d{2}):(\d{2})(\.\d+)?)?(Z|[+-]00:?00)?")


class EpochError(ValueError):
    """An epoch that is not a UTC ISO-8601 date-time; ``str(e)`` says what was expected."""


@dataclass(frozen=True)
class Epoch:
    """A UTC instant: a calendar ``day`` and ``seconds`` of that day (0 <= seconds < 86400, exact)."""

    day: _dt.date
    seconds: Decimal

    @classmethod
    def parse(cls, text: str) -> "Epoch":
        """``YYYY-MM-DD[Thh:mm:ss[.f...]][Z|+00:00]``, UTC; EpochError otherwise."""
        if not isinstance(text, str):
            raise EpochError(f"expected a UTC date-time string such as {J2000_UTC}, got {type(text).__name__}")
        m = _ISO.fullmatch(text.strip())
        if not m:
            raise EpochError(f"expected a UTC ISO-8601 date-time such as {J2000_UTC} (or ...Z), got {text!r}")
        y, mo, d, hh, mm, ss, frac, _zone = m.groups()
        try:
            day = _dt.date(int(y), int(mo), int(d))
        except ValueError as e:
            raise EpochError(f"not a calendar date ({e}): {text!r}") from None
        hh, mm, ss = int(hh or 0), int(mm or 0), int(ss or 0)
        if hh > 23 or mm > 59 or ss > 59:
            raise EpochError(f"expected hh <= 23, mm <= 59, ss <= 59 (leap seconds 23:59:60 cannot start a "
                             f"maneuver), got {text!r}")
        return cls(day, Decimal(hh * 3600 + mm * 60 + ss) + Decimal(frac or 0))

    def plus(self, seconds: float | Decimal) -> "Epoch":
        """This epoch + ``seconds`` (a float is converted exactly), days of 86400 s."""
        s = self.seconds + Decimal(seconds)
        days = int(s // _DAY)
        return Epoch(self.day + _dt.timedelta(days=days), s - days * _DAY)

    def minus(self, other: "Epoch") -> Decimal:
        """Seconds from ``other`` to this epoch (exact, days of 86400 s)."""
        return (self.day - other.day).days * _DAY + self.seconds - other.seconds

    def iso(self, digits: int = 3) -> str:
        """``YYYY-MM-DDThh:mm:ss.fff`` with ``digits`` decimals of the second (rounded half-even)."""
        q = Decimal(1).scaleb(-digits)
        s = self.seconds.quantize(q, rounding=ROUND_HALF_EVEN)
        day = self.day
        if s >= _DAY:  # rounded up into the next day
            s -= _DAY
            day += _dt.timedelta(days=1)
        whole = int(s)
        hh, rem = divmod(whole, 3600)
        mm, ss = divmod(rem, 60)
        frac = f"{s - whole:f}"[1:] if digits > 0 else ""
        return f"{day.isoformat()}T{hh:02d}:{mm:02d}:{ss:02d}{frac}"


def default_epoch() -> Epoch:
    """J2000.0 in UTC."""
    return Epoch.parse(J2000_UTC)


def tai_minus_utc(day: _dt.date) -> int:
    """TAI - UTC in seconds on a UTC date from 1972 on (:data:`LEAP_SECONDS`)."""
    out = None
    for start, n in LEAP_SECONDS:
        if day >= _dt.date.fromisoformat(start):
            out = n
    if out is None:
        raise EpochError(f"no leap-second table before 1972 (got {day.isoformat()})")
    return out


def offset_from_utc(system: str, start: Epoch) -> Decimal:
    """Seconds to add to the UTC instant ``start`` to label it in ``system`` (:data:`TIME_SYSTEMS`): 0 (UTC),
    TAI - UTC on its date (TAI), that + 32.184 (TT), that - 19 (GPS).  Later instants start + t take the same
    offset in TAI, TT and GPS, which count no leap seconds."""
    if system not in TIME_SYSTEMS:
        raise EpochError(f"expected a time system among {', '.join(TIME_SYSTEMS)}, got {system!r}")
    if system == "UTC":
        return Decimal(0)
    tai = Decimal(tai_minus_utc(start.day))
    return tai + {"TAI": Decimal(0), "TT": TT_MINUS_TAI, "GPS": GPS_MINUS_TAI}[system]


def j2000_utc() -> Epoch:
    """J2000.0 = 2000-01-01T12:00:00 TT in UTC, from TT - TAI and the leap-second table."""
    day = _dt.date(2000, 1, 1)
    return Epoch(day, Decimal(12 * 3600) - TT_MINUS_TAI - tai_minus_utc(day))


def check_no_leap_second(start: Epoch, duration_s: float) -> None:
    """EpochError if [start, start + duration] contains a leap second (the second before the start of a
    date in :data:`LEAP_SECONDS`): epochs after it, counted in days of 86400 s, would be 1 s late."""
    stop = start.plus(duration_s)
    for date, _n in LEAP_SECONDS[1:]:
        d = _dt.date.fromisoformat(date)
        if start.day < d <= stop.day:
            raise EpochError(f"the maneuver from {start.iso()} to {stop.iso()} UTC spans the leap second at the end "
                             f"of {(d - _dt.timedelta(days=1)).isoformat()}; UTC epochs after it would be 1 s off: "
                             f"choose an epoch that does not span it")


def second_digits(duration_s: float) -> int:
    """Decimals of the second to print so that each epoch is within 1e-13 of the duration of its exact
    value (half a unit of the last digit), from 3 to 15."""
    if not duration_s > 0:
        return 3
    d = 3
    while d < 15 and Decimal(5).scaleb(-d - 1) > Decimal(duration_s) * Decimal("1e-13"):
        d += 1
    return d


__all__ = ["DEFAULT_FRAME", "Epoch", "EpochError", "FRAMES", "GPS_MINUS_TAI", "J2000_UTC", "LEAP_SECONDS", "TIME_SYSTEMS",
           "TT_MINUS_TAI", "check_no_leap_second", "default_epoch", "j2000_utc", "offset_from_utc", "second_digits",
           "tai_minus_utc"]
