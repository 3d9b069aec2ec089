"""The physical side of a maneuver file: ``epoch``, ``frame``, ``units``, ``central_body``, orbital
``elements``, and the checks that catch numbers given in inconsistent units before anything is solved.

:func:`expand` is the hook :func:`problems.maneuvers.parse_maneuver` calls first: it validates the
four top-level keys and returns the document with the preset's values filled in (``model.mu``,
``model.central_body_radius``, ``gravity.J2``/``gravity.radius`` for j2) and every ``elements`` block
replaced by the ``position`` and ``velocity`` it states, plus a :class:`Physical` record for the
exports.  :func:`check_units` runs once the body and the initial state are known.

The unit checks (each one line naming the field and the likely mistake; exit 2):

* **GM against the initial state.**  With q = |v| / sqrt(GM/|x|) (the speed in circular speeds) and
  the free-fall time t_ff = (π/2) sqrt(|x|³ / (2 GM)): q > 1e4, or q < 1e-4 with T > 100 t_ff, is
  refused.  A slip between km³ and m³ changes GM by 1e9 and q by 3.2e4, so any orbit-like state
  (q from 0.3 to 3) lands beyond the limits.  What passes: every bound orbit and hyperbola up to
  10⁴ circular speeds (beyond it gravity bends the path by less than 2/q² = 2e-8 rad: the file
  would mean ``gravity: {kind: none}``), and a body nearly at rest (a hovering lander) for less than
  100 free-fall times.
* **Angles in radians** (:func:`radians_hint`, called by the attitude validator): an
  ``axis_angle`` or ``rotations`` angle within 1e-4 (relative) of kπ/n (n = 1, 2, 3, 4, 6, 8, 12;
  0 < kπ/n <= 2π) is refused as radians: angles are degrees, and "silently degrees" turned π/2 into
  a 1.57° rotation.  A rotation of exactly such a number of degrees is written as a matrix.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .bodies import DEFAULT_PRESET_LENGTH, LENGTH_UNITS, MASS_UNITS, PRESETS, TIME_UNITS, UnitSystem, preset_values
from .elements import ELEMENT_KEYS, ElementsError, state_of
from .epochs import DEFAULT_FRAME, FRAMES, Epoch, EpochError, default_epoch

#: the top-level keys this module reads
KEYS = ("epoch", "frame", "units", "central_body")
#: limits of the GM check (module docstring)
SPEED_RATIO_MAX = 1e4
FALL_TIMES_MAX = 100.0
#: relative tolerance of the radians check and the fractions of π it knows
RADIANS_TOL = 1e-4
_PI_FRACTIONS = sorted({(k / n, (f"{k}" if k > 1 else "") + "π" + (f"/{n}" if n > 1 else ""))
                        for n in (1, 2, 3, 4, 6, 8, 12) for k in range(1, 2 * n + 1) if math.gcd(k, n) == 1})


@dataclass(frozen=True)
class Physical:
    """What a file says about the physical world: the epoch of t = 0 (UTC), the inertial frame's CCSDS
    name, the units (None: normalized or unnamed) and the preset central body (its name and CCSDS name)."""

    epoch: Epoch
    frame: str
    units: UnitSystem | None
    preset: str | None
    center: str | None


def expand(v, doc: dict) -> tuple[dict, Physical]:
    """(the document with presets and elements expanded, :class:`Physical`).  ``doc`` is not changed;
    ``v`` is the file's :class:`~problems.schema.Validator`."""
    epoch = default_epoch()
    if "epoch" in doc:
        try:
            epoch = Epoch.parse(doc["epoch"])
        except EpochError as e:
            v.fail("epoch", str(e))
    frame = v.choice(doc.get("frame", DEFAULT_FRAME), "frame", FRAMES)
    units = _units(v, doc.get("units")) if "units" in doc else None
    out = dict(doc)
    preset = None
    if "central_body" in doc:
        preset, length = _central_body(v, doc["central_body"])
        if units is not None and units.length != length:
            v.fail("units.length", f"{units.length} disagrees with central_body units {length}")
        units = units or UnitSystem(length=length)
        _fill_preset(v, out, preset, length)
    mu = _mu(v, out)
    for where in ("initial", "terminal"):
        if isinstance(out.get(where), dict) and "elements" in out[where]:
            out[where] = _expand_elements(v, out[where], where, mu)
    return out, Physical(epoch, frame, units, preset, PRESETS[preset].name if preset else None)


def _units(v, d) -> UnitSystem:
    d = v.mapping(d, "units", ("length", "mass", "time"))
    return UnitSystem(length=v.choice(d.get("length", "m"), "units.length", tuple(LENGTH_UNITS)),
                      mass=v.choice(d.get("mass", "kg"), "units.mass", tuple(MASS_UNITS)),
                      time=v.choice(d.get("time", "s"), "units.time", tuple(TIME_UNITS)))


def _central_body(v, d) -> tuple[str, str]:
    """(preset name, length unit) of ``central_body: NAME`` or ``{name: NAME, units: km | m}``."""
    if isinstance(d, str):
        return v.choice(d, "central_body", tuple(PRESETS)), DEFAULT_PRESET_LENGTH
    d = v.mapping(d, "central_body", ("name", "units"), required=("name",))
    name = v.choice(d["name"], "central_body.name", tuple(PRESETS))
    return name, v.choice(d.get("units", DEFAULT_PRESET_LENGTH), "central_body.units", tuple(LENGTH_UNITS))


def _fill_preset(v, out: dict, name: str, length: str) -> None:
    """model.mu, model.central_body_radius and the j2 gravity's J2 and radius from the preset where not given."""
    p = preset_values(name, length)
    model = dict(out.get("model", {"kind": "dumbbell"})) if isinstance(out.get("model", {}), dict) else out["model"]
    gravity = out.get("gravity", {"kind": "point_mass"})
    if isinstance(gravity, dict) and gravity.get("kind") == "none":
        v.fail("gravity.kind", f"none contradicts central_body: {name} (remove one of them)")
    if isinstance(model, dict):
        if "mu" in model:
            mu = v.number(model["mu"], "model.mu", positive=True)
            if not math.isclose(mu, p["mu"], rel_tol=1e-9):
                v.fail("model.mu", f"GM = {mu:.10g} disagrees with central_body {name}'s {p['mu']:.10g} {length}^3/s^2"
                                   f"{_gm_hint(mu / p['mu'], length)}; remove model.mu (the preset gives it)")
        model.setdefault("mu", p["mu"])
        model.setdefault("central_body_radius", p["radius"])
        out["model"] = model
    if isinstance(gravity, dict) and gravity.get("kind") == "j2":
        out["gravity"] = {**gravity, "J2": gravity.get("J2", p["J2"]), "radius": gravity.get("radius", p["radius"])}


def _gm_hint(ratio: float, length: str) -> str:
    """' (GM in m^3/s^2? ...)' when ``ratio`` (given / expected) is a km-m slip (1e9 or 1e-9, to 1 %)."""
    for factor, text in ((1e9, "in m^3/s^2 while the lengths are in km"), (1e-9, "in km^3/s^2 while the lengths are in m")):
        if abs(ratio / factor - 1.0) < 1e-2:
            return f" (GM {text}? 1 km^3 = 1e9 m^3)"
    return ""


def _mu(v, doc) -> float | None:
    """GM the elements are converted with: model.mu (the preset's if filled), else 4π²; None without gravity."""
    from .models import GM_NORMALIZED

    g = doc.get("gravity", {})
    if isinstance(g, dict) and g.get("kind") == "none":
        return None
    m = doc.get("model", {})
    if isinstance(m, dict) and "mu" in m:
        return v.number(m["mu"], "model.mu", positive=True)
    return GM_NORMALIZED


def _expand_elements(v, d: dict, where: str, mu: float | None) -> dict:
    """A state block with ``elements`` -> the same block with ``position`` and ``velocity``."""
    w = f"{where}.elements"
    for k in ("position", "velocity"):
        if k in d:
            v.fail(f"{where}.{k}", "give either elements or position and velocity, not both")
    if mu is None:
        v.fail(w, "orbital elements need a central body (a gravity kind other than none)")
    keys = tuple(k for k, _ in ELEMENT_KEYS)
    el = v.mapping(d["elements"], w, keys, required=keys)
    vals = {k: v.number(el[k], f"{w}.{k}") for k in keys}
    try:
        with np.errstate(all="ignore"):
            x, vel = state_of(mu, **vals)
    except ElementsError as e:
        v.fail(f"{w}.{e.key}", str(e))
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(vel))):
        v.fail(w, "the elements give a non-finite position or velocity (values too large)")
    out = {k: val for k, val in d.items() if k != "elements"}
    out["position"], out["velocity"] = x.tolist(), vel.tolist()
    return out


def check_units(v, phys: Physical, mu: float | None, x: np.ndarray, vel: np.ndarray, T: float) -> None:
    """The GM check of the module docstring at the initial state (``mu`` None: no central body)."""
    with np.errstate(all="ignore"):
        r, s = float(np.linalg.norm(x)), float(np.linalg.norm(vel))
        if mu is None or not (0 < r < math.inf and 0 <= s < math.inf):
            return
        vc = math.sqrt(mu / r)
        t_ff = 0.5 * math.pi * r * math.sqrt(r / (2.0 * mu))  # no overflow of r^3
    if not (0 < vc < math.inf and 0 < t_ff < math.inf):
        return
    q = s / vc
    if q > SPEED_RATIO_MAX:
        what = f"{q:.3g} times the circular speed sqrt(GM/|position|) = {vc:.4g} at |position| = {r:.6g}"
        likely = "GM in km^3/s^2 with positions in m?" if 0.01 < q / math.sqrt(1e9) < 100 else \
            "GM, lengths and times in different units?"
    elif q < 1.0 / SPEED_RATIO_MAX and T > FALL_TIMES_MAX * t_ff:
        what = (f"{q:.3g} times the circular speed sqrt(GM/|position|) = {vc:.4g} at |position| = {r:.6g}, and "
                f"the body would fall to the centre in {t_ff:.3g}, {T / t_ff:.3g} times less than the horizon T = {T:.6g}")
        likely = "GM in m^3/s^2 with positions in km?" if 0.01 < q * math.sqrt(1e9) < 100 else \
            "GM, lengths and times in different units?"
    else:
        return
    if phys.preset is not None:
        field, fix = "initial.velocity", (f"central_body {phys.preset} gives GM in {phys.units.length}^3/s^2: positions "
                                          f"in {phys.units.length}, velocities in {phys.units.length}/s")
    else:
        field, fix = "model.mu", "GM, positions, velocities and T must share one set of units (1 km^3 = 1e9 m^3)"
    v.fail(field, f"GM = {mu:.6g} does not fit the initial state: its speed {s:.4g} is {what} ({likely} {fix})")


def radians_hint(angle: float) -> str | None:
    """'π/2' etc. when ``angle`` is within RADIANS_TOL (relative) of kπ/n in (0, 2π] (module
    docstring), else None."""
    a = abs(float(angle))
    for frac, name in _PI_FRACTIONS:
        if abs(a - frac * math.pi) <= RADIANS_TOL * frac * math.pi:
            return ("-" if angle < 0 else "") + name
    return None


def check_radians(v, angle: float, where: str) -> None:
    """ConfigError naming ``where`` when ``angle`` (given in degrees) looks like radians (:func:`radians_hint`)."""
    angle = float(angle)
    name = radians_hint(angle)
    if name is not None:
        deg = math.degrees(angle)
        v.fail(where, f"{angle!r} is {name} in radians, but angles here are in degrees: write {deg:.6g} for {name} "
                      f"(a rotation of exactly {angle!r} degrees: give the attitude as a matrix)")


def in_units(problem, phys: Physical | None):
    """The file's Problem carrying the file's units (Problem.units, problems.units.declared), so figures and
    reports of its solutions -- and of every Problem derived from it -- label them."""
    if phys is None or phys.units is None:
        return problem
    return problem.replace(units=phys.units)


def unit_system(man) -> UnitSystem | None:
    """The units a loaded maneuver names (None: normalized or unnamed)."""
    phys = getattr(man, "physical", None)
    return phys.units if phys is not None else None


#: the force bound is suspected of a N-for-kN slip when the engine could give this many times the delta-v its orbit
#: change needs: the factor of the slip itself (1 kN = 1000 N)
THRUST_SLIP_RATIO = 1e3


def thrust_warning(man) -> str:
    """'' or one line: in a file whose lengths are km (forces in kN), the force bound gives at least
    THRUST_SLIP_RATIO times the least delta-v the orbit change needs (transcription.ocp.feasibility.orbit_capacity)
    -- a bound in newtons written as kN passes every check but plans with a thousand times the engine."""
    from ..transcription.ocp.feasibility import orbit_capacity

    phys = man.physical
    if phys is None or phys.units is None or phys.units.length != "km" or man.problem.kind != "smooth":
        return ""
    cap = orbit_capacity(man.problem)
    if cap is None or not cap[2] > 0 or cap[3] < THRUST_SLIP_RATIO * cap[2]:
        return ""
    _, _, need, can = cap
    return (f"control.bounds.force lets the engine give {can * 1e3:.4g} m/s in T, {can / need:.3g} times the "
            f"{need * 1e3:.4g} m/s this orbit change needs at least (Hohmann): forces in this km file are kN "
            f"(1 N = 1e-3 kN) -- a bound meant in newtons?")


__all__ = ["KEYS", "THRUST_SLIP_RATIO", "Physical", "check_radians", "check_units", "expand", "in_units",
           "radians_hint", "thrust_warning", "unit_system"]

