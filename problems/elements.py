"""Classical orbital elements <-> inertial position and velocity about a point mass GM = mu.

The elements are (a, e, i, Ω, ω, ν): semi-major axis a (the file's length unit; a < 0 for a
hyperbola), eccentricity e >= 0 (e != 1), and in **degrees** the inclination i of the orbit normal
to the inertial e3 axis, the right ascension of the ascending node Ω (from e1 about e3), the argument
of periapsis ω (from the node in the orbit plane) and the true anomaly ν (from periapsis).  In a file:

    initial:
      elements: {a: 6778.137, e: 0.0, i_deg: 51.6, raan_deg: 0.0, argp_deg: 0.0, nu_deg: 0.0}

replaces ``position`` and ``velocity`` (the attitude and angular velocity are given as usual).

The conversion (e.g. Vallado, *Fundamentals of Astrodynamics and Applications*, algorithm COE2RV):
p = a (1 - e²), r = p / (1 + e cos ν), in the perifocal frame
    r_pf = r (cos ν, sin ν, 0),   v_pf = sqrt(mu / p) (-sin ν, e + cos ν, 0),
and x = Q r_pf, v = Q v_pf with Q = Rz(Ω) Rx(i) Rz(ω).  :func:`elements_of` is the inverse (for
non-circular, non-equatorial orbits; circular or equatorial orbits get ω = 0 or Ω = 0 and the angle
measured from the node or from e1 instead).
"""
from __future__ import annotations

import math

import numpy as np

from ..transcription.geometry.so3 import rot_x, rot_z

#: the keys of an ``elements`` block: (file key, meaning)
ELEMENT_KEYS = (("a", "semi-major axis (length unit; < 0 for a hyperbola)"), ("e", "eccentricity"),
                ("i_deg", "inclination (deg)"), ("raan_deg", "right ascension of the ascending node (deg)"),
                ("argp_deg", "argument of periapsis (deg)"), ("nu_deg", "true anomaly (deg)"))


class ElementsError(ValueError):
    """Elements that describe no orbit: ``key`` names the offending element, ``str(e)`` says why."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


def check_elements(a: float, e: float, nu_deg: float) -> None:
    """ElementsError unless (a, e, ν) is a point of a conic: e >= 0, e != 1, p = a (1 - e²) > 0 and,
    on a hyperbola, 1 + e cos ν > 0 (ν within the asymptotes)."""
    if e < 0:
        raise ElementsError("e", f"expected an eccentricity >= 0, got {e:g}")
    if e == 1.0:
        raise ElementsError("e", "a parabola (e = 1) has no semi-major axis; give e < 1 or e > 1")
    if not a * (1.0 - e * e) > 0:
        raise ElementsError("a", f"expected a > 0 for e < 1 and a < 0 for e > 1 (a hyperbola), got a = {a:g}, e = {e:g}")
    if not 1.0 + e * math.cos(math.radians(nu_deg)) > 0:
        limit = math.degrees(math.acos(-1.0 / e))
        raise ElementsError("nu_deg", f"a hyperbola with e = {e:g} has |true anomaly| < {limit:.6g} deg, "
                                      f"got {nu_deg:g}")


def state_of(mu: float, a: float, e: float, i_deg: float, raan_deg: float, argp_deg: float,
             nu_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(position, velocity) in the inertial frame of the elements (see the module docstring)."""
    check_elements(a, e, nu_deg)
    p = a * (1.0 - e * e)
    nu = math.radians(nu_deg)
    c, s = math.cos(nu), math.sin(nu)
    r = p / (1.0 + e * c)
    Q = rot_z(raan_deg) @ rot_x(i_deg) @ rot_z(argp_deg)
    k = math.sqrt(mu / p)
    return Q @ np.array([r * c, r * s, 0.0]), Q @ np.array([-k * s, k * (e + c), 0.0])


def elements_of(mu: float, x, v) -> dict[str, float]:
    """The elements {a, e, i_deg, raan_deg, argp_deg, nu_deg} of a position and velocity (angles in
    [0, 360) deg, i in [0, 180]).  Circular orbits (e < 1e-12) have ω = 0 (ν from the node); equatorial
    ones (sin i < 1e-12) have Ω = 0 (ω from e1)."""
    x, v = np.asarray(x, float), np.asarray(v, float)
    r = np.linalg.norm(x)
    h = np.cross(x, v)
    hn = np.linalg.norm(h)
    ev = np.cross(v, h) / mu - x / r
    e = float(np.linalg.norm(ev))
    a = 1.0 / (2.0 / r - v @ v / mu)
    i = math.degrees(math.atan2(math.hypot(h[0], h[1]), h[2]))
    node = np.array([-h[1], h[0], 0.0])
    equatorial = np.linalg.norm(node) < 1e-12 * hn
    if equatorial:
        node = np.array([1.0, 0.0, 0.0])
    node = node / np.linalg.norm(node)
    raan = 0.0 if equatorial else math.degrees(math.atan2(node[1], node[0]))
    hhat = h / hn
    m = np.cross(hhat, node)          # in-plane, 90 deg ahead of the node

    def angle_from_node(u):
        return math.degrees(math.atan2(u @ m, u @ node))

    circular = e < 1e-12
    argp = 0.0 if circular else angle_from_node(ev)
    nu = angle_from_node(x) - argp
    return {"a": float(a), "e": e, "i_deg": i, "raan_deg": raan % 360.0, "argp_deg": argp % 360.0,
            "nu_deg": nu % 360.0}


#: the element differences of :func:`element_differences`: (key, element, quantity of problems.units.DIMENSIONS)
ELEMENT_DIFFERENCES = (("a", "semi-major axis a", "length"), ("e", "eccentricity e", "none"),
                       ("i_deg", "inclination i", "angle"), ("raan_deg", "right ascension of the node Ω", "angle"),
                       ("u_deg", "argument of latitude u = ω + ν", "angle"))


def element_differences(mu: float, x, v, x_ref, v_ref) -> dict[str, float]:
    """Osculating elements of (x, v) minus those of (x_ref, v_ref) about GM = mu (positions (3,) and velocities (3,)
    inertial, in one set of units): {a (length unit), e, i_deg, raan_deg, u_deg}, the angles wrapped to
    [-180, 180) deg.  The argument of latitude u = ω + ν (the angle from the node to the position in the orbit
    plane) stays defined as e -> 0, where ω and ν do not; on an equatorial orbit Ω = 0 and u is the true longitude
    (from e1), so near i = 0 ΔΩ and Δu trade against each other and only their sum means anything."""
    el, ref = elements_of(mu, x, v), elements_of(mu, x_ref, v_ref)

    def wrap(d):
        return (d + 180.0) % 360.0 - 180.0

    def u(e):
        return e["argp_deg"] + e["nu_deg"]

    return {"a": el["a"] - ref["a"], "e": el["e"] - ref["e"], "i_deg": el["i_deg"] - ref["i_deg"],
            "raan_deg": wrap(el["raan_deg"] - ref["raan_deg"]), "u_deg": wrap(u(el) - u(ref))}


def rtn(x: np.ndarray, v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Components (n, 3) of inertial vectors u in the osculating orbit's radial, along-track
    (transverse: n x r) and normal (h/|h|) directions at positions and velocities x, v (n, 3)."""
    r_hat = x / np.linalg.norm(x, axis=1)[:, None]
    h = np.cross(x, v)
    n_hat = h / np.linalg.norm(h, axis=1)[:, None]
    t_hat = np.cross(n_hat, r_hat)
    return np.stack([np.einsum("ij,ij->i", u, e) for e in (r_hat, t_hat, n_hat)], axis=1)


__all__ = ["ELEMENT_DIFFERENCES", "ELEMENT_KEYS", "ElementsError", "check_elements", "element_differences", "elements_of",
           "rtn", "state_of"]
