"""Control bounds in a maneuver file: ``control.bounds.{force,moment}`` as {box}, {norm} or (force only) one
body-fixed engine {thruster: {axis, max, min, isp}}, and ``control.bounds_margin`` (docs/mathematics.md §10, §14)."""
from __future__ import annotations

import numpy as np

from .bodies import UnitSystem
from .schema import Validator, describe
from ..transcription.ocp import BoxBound, NormBound, ThrusterBound

#: standard gravity g0 (m/s^2, exact by definition, 3rd CGPM 1901): an engine's exhaust velocity is Isp g0
G0 = 9.80665

#: positive limits whose squares enter the equations (control bounds, a rate limit, principal moments
#: of inertia) must lie in [MIN_MAGNITUDE, MAX_MAGNITUDE], so that their squares and inverse squares are
#: finite, normal double-precision numbers (a denormal bound is bad input, not a solver failure)
MIN_MAGNITUDE, MAX_MAGNITUDE = 1e-150, 1e150


def bounds_margin(v: Validator, c, bounds: dict) -> float:
    """control.bounds_margin m in [0, 1) (default 0): the bounds in ``bounds`` (the actuators') are
    replaced, in place, by the (1 - m) fraction the plan respects (SmoothControl.bounds_margin)."""
    if "bounds_margin" not in c:
        return 0.0
    m = v.number(c["bounds_margin"], "control.bounds_margin", nonneg=True, hi=1.0)
    if not bounds:
        v.fail("control.bounds_margin", "applies to bounded controls only (give control.bounds)")
    for k, b in bounds.items():
        lo, hi = b.engine_range or (-np.inf, np.inf)
        if not lo < hi * (1.0 - m):
            v.fail("control.bounds_margin", f"leaves the thruster no range: min {lo:g} >= (1 - margin) max "
                                            f"{hi * (1.0 - m):g}", also=(f"control.bounds.{k}",))
        bounds[k] = b.scaled(1.0 - m)
    return m


def control_bound(v: Validator, d, where, thruster: bool = False, units: UnitSystem | None = None):
    """{box: [3 positive]} or {norm: b >= 0} (or, ``thruster``, {thruster: {axis, max, min, isp}}) -> (BoxBound |
    NormBound | ThrusterBound, resolved); ``units``: the file's (None: normalized or unnamed), for an isp."""
    forms = ("box", "norm") + (("thruster",) if thruster else ())
    if not thruster and isinstance(d, dict) and "thruster" in d:
        v.fail(where, "a thruster is an engine: it bounds the force (control.bounds.force); the moment takes "
                      "{box: [b1, b2, b3]} or {norm: b}")
    if not isinstance(d, dict) or len(d) != 1 or next(iter(d)) not in forms:
        engine = " or {thruster: {axis: [3], max: F, min: 0}}" if thruster else ""
        v.fail(where, f"expected {{box: [b1, b2, b3]}}, {{norm: b}}{engine}, got {describe(d)}")
    (form, val), = d.items()
    w = f"{where}.{form}"
    if form == "thruster":
        return engine_bound(v, val, w, units)
    if form == "box":
        b = v.vec3(val, w)
        for i, x in enumerate(b):
            if not x > 0:
                v.fail(f"{w}[{i}]", f"expected a positive limit, got {float(x)!r}")
            magnitude(v, float(x), f"{w}[{i}]", "a limit")
        return BoxBound(b), {"box": b.tolist()}
    b = v.number(val, w, nonneg=True)
    if b != 0:
        magnitude(v, b, w, "a limit (or 0, which removes the control)")
    return NormBound(b), {"norm": b}


def engine_bound(v: Validator, d, w: str, units: UnitSystem | None = None):
    """{axis: [3] (body frame, non-zero; normalized), max: F > 0, min: 0 <= min < max (default 0), and optionally
    isp: seconds > 0 or exhaust_velocity: c > 0 in the file's velocity unit} -> (ThrusterBound, resolved): one engine
    fixed in the body, u_f = T axis with min <= T <= max, of exhaust velocity c = isp g0 converted to the file's
    velocity unit (``units``: a file without units cannot read seconds; it gives exhaust_velocity instead)."""
    v.mapping(d, w, ("axis", "max", "min", "isp", "exhaust_velocity"), required=("axis", "max"))
    axis = v.unit_vector(d["axis"], f"{w}.axis", "expected a non-zero engine axis (body frame; it is normalized)")
    hi = v.number(d["max"], f"{w}.max", positive=True)
    magnitude(v, hi, f"{w}.max", "a thrust limit")
    lo = v.number(d.get("min", 0.0), f"{w}.min", nonneg=True)
    if not lo < hi:
        v.fail(f"{w}.min", f"expected min < max (the engine's thrust range), got min {lo:g} >= max {hi:g}", also=(f"{w}.max",))
    resolved = {"axis": axis.tolist(), "max": hi, "min": lo}
    c = None
    if "isp" in d and "exhaust_velocity" in d:
        v.fail(f"{w}.isp", "expected isp or exhaust_velocity (c = isp g0), not both", also=(f"{w}.exhaust_velocity",))
    if "exhaust_velocity" in d:
        c = v.number(d["exhaust_velocity"], f"{w}.exhaust_velocity", positive=True)
        magnitude(v, c, f"{w}.exhaust_velocity", "an exhaust velocity")
        resolved["exhaust_velocity"] = c
    if "isp" in d:
        isp = v.number(d["isp"], f"{w}.isp", positive=True)
        magnitude(v, isp, f"{w}.isp", "a specific impulse in seconds")
        if units is None:
            v.fail(f"{w}.isp", "a specific impulse in seconds needs the file's units (units: or central_body:), "
                               "and this file names none: give exhaust_velocity in its velocity unit instead")
        c, resolved["isp"] = isp * G0 / units.si("velocity"), isp
    return ThrusterBound(axis, hi, lo, c), {"thruster": resolved}


def magnitude(v: Validator, x: float, where: str, what: str) -> None:
    """ConfigError unless MIN_MAGNITUDE <= x <= MAX_MAGNITUDE (a positive limit whose square is used)."""
    if not MIN_MAGNITUDE <= x <= MAX_MAGNITUDE:
        v.fail(where, f"expected {what} from {MIN_MAGNITUDE:g} to {MAX_MAGNITUDE:g} (its square enters the "
                      f"equations and must be a normal double-precision number), got {x:g}")


#: the most reaction wheels a file may give
MAX_WHEELS = 12


def wheel_axes(v: Validator, axes, where: str) -> np.ndarray:
    """A list of 3 to MAX_WHEELS wheel spin axes (body frame) -> (n, 3) unit rows spanning three dimensions (the
    wheels must give a moment about any axis); bad input names ``where``."""
    if not isinstance(axes, (list, tuple)) or not 3 <= len(axes) <= MAX_WHEELS:
        v.fail(where, f"expected a list of 3 to {MAX_WHEELS} axes (each a list of 3 numbers)")
    A = np.array([v.vec3(a, f"{where}[{i}]") for i, a in enumerate(axes)], float)
    n = np.linalg.norm(A, axis=1)
    if np.any(n == 0):
        v.fail(f"{where}[{int(np.argmin(n))}]", "expected a non-zero axis")
    A = A / n[:, None]
    if np.linalg.matrix_rank(A, tol=1e-6) < 3:
        v.fail(where, "expected axes spanning three dimensions (the wheels must give a moment about any axis)")
    return A


def per_wheel(v: Validator, val, n: int, where: str) -> list[float]:
    """One positive number for every wheel, or one per wheel (n) -> n positive floats; bad input names ``where``."""
    vals = val if isinstance(val, (list, tuple)) else [val] * n
    if len(vals) != n:
        v.fail(where, f"expected one positive number or {n} (one per wheel)")
    return [v.number(x, where + (f"[{i}]" if isinstance(val, (list, tuple)) else ""), positive=True)
            for i, x in enumerate(vals)]
