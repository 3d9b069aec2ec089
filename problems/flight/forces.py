"""A flight's truth forces besides gravity (the flight block's ``truth.drag`` and ``truth.srp``; issue 44), as one
CasADi Function X (18) -> f (3, inertial, the file's force unit) that the flight engine adds to the momentum
equation (transcription.dynamics.flight.equations_of_motion).  The plan knows neither: they are what a flight
shows the plan's sensitivity to.  Both need a maneuver in physical units; drag needs ``central_body: earth``.

**Drag** (``drag: {cd, area_m2}``): f = -1/2 rho(h) C_D A |v_r| v_r with v_r = v - omega_E e3 x x, the velocity
relative to an atmosphere turning with the Earth (omega_E = 7.292115e-5 rad/s, IERS Conventions (2010); e3 the
frame's pole), and rho the exponential atmosphere of Vallado, *Fundamentals of Astrodynamics and Applications*,
4th ed. (2013), Table 8-4 (:data:`EXPONENTIAL_ATMOSPHERE`, from the U.S. Standard Atmosphere 1976 and CIRA-72),
at the height h = |x| - R above the preset's sphere of equatorial radius R:

    rho(h) = rho_0,i exp(-(h - h_0,i) / H_i)   for h_0,i <= h < h_0,i+1   (the last band above 1000 km).

A static mean atmosphere: no solar or geomagnetic activity, no day-night bulge (real densities at 400 km vary by
a factor of ten over a solar cycle), no oblateness in h (up to 21 km at the poles).

**Solar radiation pressure** (``srp: {cr, area_m2}``), a cannonball: f = -P (1 AU / r_s)^2 C_R A s, with
P = S / c = 1361 W/m^2 / 299792458 m/s = 4.5398e-6 N/m^2 at 1 AU (the nominal total solar irradiance of IAU 2015
Resolution B3) and s, r_s the Sun's direction and distance from the Earth at the maneuver's epoch by the
low-precision solar coordinates of Vallado's algorithm SUN (Algorithm 29; 0.01 deg, mean equator and equinox of
date, within 0.4 deg of EME2000's axes before 2030), held fixed over the flight (the Sun moves 1 deg a day; the
parallax of a LEO orbit is 5e-5 rad).  Always sunlit: no shadow, so over an orbit that enters the Earth's shadow
this is an upper bound.
"""
from __future__ import annotations

import math
from functools import lru_cache

import casadi as ca
import numpy as np

from ...transcription.geometry.state import NX, split_state
from ..bodies import LENGTH_UNITS, PRESETS
from ..epochs import J2000_UTC, Epoch

#: Vallado (2013) Table 8-4: (base height h_0 (km), nominal density rho_0 (kg/m^3), scale height H (km))
EXPONENTIAL_ATMOSPHERE = (
    (0, 1.225, 7.249), (25, 3.899e-2, 6.349), (30, 1.774e-2, 6.682), (40, 3.972e-3, 7.554), (50, 1.057e-3, 8.382),
    (60, 3.206e-4, 7.714), (70, 8.770e-5, 6.549), (80, 1.905e-5, 5.799), (90, 3.396e-6, 5.382),
    (100, 5.297e-7, 5.877), (110, 9.661e-8, 7.263), (120, 2.438e-8, 9.473), (130, 8.484e-9, 12.636),
    (140, 3.845e-9, 16.149), (150, 2.070e-9, 22.523), (180, 5.464e-10, 29.740), (200, 2.789e-10, 37.105),
    (250, 7.248e-11, 45.546), (300, 2.418e-11, 53.628), (350, 9.518e-12, 53.298), (400, 3.725e-12, 58.515),
    (450, 1.585e-12, 60.828), (500, 6.967e-13, 63.822), (600, 1.454e-13, 71.835), (700, 3.614e-14, 88.667),
    (800, 1.170e-14, 124.64), (900, 5.245e-15, 181.05), (1000, 3.019e-15, 268.00),
)
#: the Earth's rotation rate (rad/s), IERS Conventions (2010) Table 1.1
OMEGA_EARTH = 7.292115e-5
#: solar radiation pressure at 1 AU (N/m^2): 1361 W/m^2 (IAU 2015 B3) over the speed of light
SOLAR_PRESSURE = 1361.0 / 299792458.0
#: the flight block's truth forces: name -> (its keys, what the maneuver needs)
FORCE_KEYS = {"drag": ("cd", "area_m2"), "srp": ("cr", "area_m2")}


def density(h_km):
    """rho (kg/m^3) of :data:`EXPONENTIAL_ATMOSPHERE` at the height h (km; CasADi SX, MX or DM)."""
    h0, rho0, H = EXPONENTIAL_ATMOSPHERE[0]
    rho = rho0 * ca.exp(-(h_km - h0) / H)
    for h0, rho0, H in EXPONENTIAL_ATMOSPHERE[1:]:                # each band from its base up
        rho = ca.if_else(h_km >= h0, rho0 * ca.exp(-(h_km - h0) / H), rho)
    return rho


def sun(epoch: Epoch) -> tuple[np.ndarray, float]:
    """(unit direction (3,), distance in AU) of the Sun from the Earth at ``epoch`` (module docstring: Vallado's
    algorithm SUN, mean equator and equinox of date)."""
    T = float(epoch.minus(Epoch.parse(J2000_UTC))) / 86400.0 / 36525.0     # Julian centuries from J2000
    lam_m = 280.460 + 36000.771 * T
    M = math.radians(357.5291092 + 35999.05034 * T)
    lam = math.radians(lam_m + 1.914666471 * math.sin(M) + 0.019994643 * math.sin(2 * M))
    r = 1.000140612 - 0.016708617 * math.cos(M) - 0.000139589 * math.cos(2 * M)
    eps = math.radians(23.439291 - 0.0130042 * T)
    return np.array([math.cos(lam), math.cos(eps) * math.sin(lam), math.sin(eps) * math.sin(lam)]), r


def check_forces(maneuver, truth: dict) -> tuple[str, str] | None:
    """None when the maneuver can carry the truth forces of ``truth`` (the resolved truth block), else (the field
    under the flight block, why not)."""
    phys = maneuver.physical
    for name in FORCE_KEYS:
        if name not in truth:
            continue
        if phys is None or phys.units is None:
            return f"truth.{name}", "needs a maneuver in physical units (central_body: earth or units:)"
        if name == "drag" and phys.preset != "earth":
            return "truth.drag", "the exponential atmosphere is the Earth's: the maneuver needs central_body: earth"
    return None


def plane_turn(mu: float, x: np.ndarray, v: np.ndarray, c2: float, T: float) -> tuple[float, float]:
    """(secular, periodic): the angle (rad) by which a J2 term c2 = J2 R^2 turns the plane of the orbit through (x, v)
    over T by its nodal regression, (3/2) n c2 / p^2 |cos i| T sin i, and the amplitude of the plane's short-periodic
    wobble about it, (3/2) c2 / p^2 |sin i cos i| (the flown turn is within it of the secular one: measured within
    0.99 of it from 0.1 to 1.3 orbits at 45-97.6 deg); (0, 0) for an orbit that is not an ellipse."""
    from ..elements import elements_of

    el = elements_of(mu, x, v)
    p = el["a"] * (1.0 - el["e"] ** 2)
    if not (el["a"] > 0.0 and p > 0.0):
        return 0.0, 0.0
    i = math.radians(el["i_deg"])
    k = 1.5 * c2 / p**2 * abs(math.cos(i)) * math.sin(i)
    return math.sqrt(mu / el["a"] ** 3) * T * k, k


def j2_plane_drift(maneuver, plan, gravity: dict | None) -> str:
    """'' or one line: the truth's J2 differs from the plan's (``gravity``: the truth's block, None: the plan's own)
    and undoing the orbit plane's turn it adds over T needs more delta-v than the force bound leaves beyond the plan.

    The nodal regression of J2 (Vallado 2013, ch. 9), dOmega/dt = -(3/2) n J2 (R/p)^2 cos i, differs between the
    truth and the plan by (3/2) n |J2_t R_t^2 - J2_p R_p^2| / p^2 |cos i|; over T the plane turns by that drift times
    sin i, less twice its short-periodic wobble (:func:`plane_turn`) at the least, and undoing a turn theta at speed v
    needs at least v theta (a plane change at its best node: spread over the orbit it costs more).  The engine leaves
    F_max T / m less the plan's own delta-v (``plan.delta_v``, sum_j omega_j |u_f,j| / m).
    A lower bound on what feedback needs, so the line is said only when it cannot be met.  Why: a point-mass plan
    flown on a J2 truth by a 1-2 N engine lands kilometres off in closed loop as in open loop (the pull of J2 is
    several times the engine's), and the cure is in the plan, not in the tracker's weights (issue 43)."""
    from ...transcription.geometry.state import X_MOM, X_POS
    from ..units import units

    problem = plan.problem if plan.problem is not None else maneuver.problem
    plan_g, truth_g = maneuver.resolved.get("gravity") or {}, gravity or maneuver.resolved.get("gravity") or {}
    c2 = [g.get("J2", 0.0) * g.get("radius", 0.0) ** 2 if g.get("kind") == "j2" else 0.0 for g in (plan_g, truth_g)]
    bound, mu = problem.control.force_bound, problem.model.mu
    if c2[0] == c2[1] or bound is None or not mu or plan.controls is None:
        return ""
    X0, T, m = np.asarray(problem.X0, float), float(problem.T), float(problem.model.mass)
    x, v = X0[X_POS], X0[X_MOM] / m
    secular, periodic = plane_turn(mu, x, v, abs(c2[1] - c2[0]), T)
    turn = max(secular - 2.0 * periodic, 0.0)
    need = float(np.linalg.norm(v)) * turn
    used = float(plan.delta_v)
    spare = bound.largest_norm() * T / m - used
    if need <= spare:
        return ""
    which = "the truth's J2 is not in the plan" if c2[0] == 0.0 else (
        "the plan's J2 is not in the truth" if c2[1] == 0.0 else "the truth's J2 differs from the plan's")
    unit, k = units(problem).shown("velocity")
    return (f"{which}: over T it turns the orbit's plane by at least {math.degrees(turn):.3g} deg against the plan; "
            f"undoing that needs at least {need * k:.3g} {unit}, and the force bound leaves {max(spare, 0.0) * k:.3g} "
            f"{unit} beyond the plan's {used * k:.3g}: no feedback can bring this plan to its target -- plan with "
            f"the truth's gravity (the maneuver's gravity block)")


def truth_forces(maneuver, truth: dict) -> ca.Function | None:
    """The Function X (18) -> f (3) of the truth forces ``truth`` for ``maneuver`` (module docstring), or None
    without any; one Function per set of numbers and process (the flight engine builds its integrator per
    Function)."""
    if not any(k in truth for k in FORCE_KEYS):
        return None
    phys = maneuver.physical
    drag = truth.get("drag")
    srp = truth.get("srp")
    radius = PRESETS[phys.preset].radius if drag else 0.0
    return _forces(float(maneuver.problem.model.mass), LENGTH_UNITS[phys.units.length], radius,
                   (drag["cd"], drag["area_m2"]) if drag else None,
                   (srp["cr"], srp["area_m2"], phys.epoch.iso(6)) if srp else None)


@lru_cache(maxsize=16)
def _forces(mass: float, L: float, radius_m: float, drag: tuple | None, srp: tuple | None) -> ca.Function:
    """The Function of :func:`truth_forces`: L metres per length unit, the body's mass (kg), the central body's
    radius (m), drag (C_D, A) and srp (C_R, A, epoch) or None.  Forces in kg L/s^2."""
    X = ca.SX.sym("X", NX)
    x, gamma, _, _ = split_state(X)
    f = ca.SX.zeros(3)
    if drag is not None:
        cd, area = drag
        v_r = gamma / mass - ca.cross(ca.DM([0.0, 0.0, OMEGA_EARTH]), x)
        h_km = (ca.norm_2(x) * L - radius_m) / 1000.0
        rho = density(h_km) * L**3                                  # kg per (length unit)^3
        f -= 0.5 * rho * cd * area / L**2 * ca.norm_2(v_r) * v_r
    if srp is not None:
        cr, area, epoch = srp
        s, r_au = sun(Epoch.parse(epoch))
        f -= ca.DM(SOLAR_PRESSURE / r_au**2 * cr * area / L * s)     # N -> kg L/s^2
    return ca.Function("truth_forces", [X], [f], ["X"], ["f"])


__all__ = ["EXPONENTIAL_ATMOSPHERE", "FORCE_KEYS", "OMEGA_EARTH", "SOLAR_PRESSURE", "check_forces", "density",
           "j2_plane_drift", "plane_turn", "sun", "truth_forces"]
