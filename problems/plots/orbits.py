"""Orbital mechanics for the figures, in NumPy only (no matplotlib): osculating elements and points of orbit
ellipses and circles (the radial / along-track / normal frame: problems.elements.rtn)."""
from __future__ import annotations

import numpy as np


def osculating_elements(x: np.ndarray, v: np.ndarray, mu: float) -> dict[str, np.ndarray]:
    """Radius, inclination (deg, of the orbit normal to e3), eccentricity and semi-major axis of the
    osculating orbits of positions and velocities x, v (n, 3) about a point mass mu."""
    x, v = np.atleast_2d(np.asarray(x, float)), np.atleast_2d(np.asarray(v, float))
    r = np.linalg.norm(x, axis=1)
    h = np.cross(x, v)
    hn = np.linalg.norm(h, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        inc = np.degrees(np.arccos(np.clip(h[:, 2] / hn, -1.0, 1.0)))
        e = np.linalg.norm(np.cross(v, h) / mu - x / r[:, None], axis=1)
        a = 1.0 / (2.0 / r - np.einsum("ij,ij->i", v, v) / mu)
    return {"radius": r, "inclination": inc, "eccentricity": e, "semi_major_axis": a}


def _orbit_ellipse(x, v, mu, n=200):
    """The osculating orbit of (x, v) about a point mass mu, as points (n, 3) (None if unbound)."""
    x, v = np.asarray(x, float), np.asarray(v, float)
    r = np.linalg.norm(x)
    hvec = np.cross(x, v)
    if not mu or np.linalg.norm(hvec) < 1e-12:
        return None
    evec = np.cross(v, hvec) / mu - x / r
    e = np.linalg.norm(evec)
    a = 1.0 / (2.0 / r - v @ v / mu)
    if e >= 1 or a <= 0:
        return None
    p_hat = evec / e if e > 1e-10 else x / r
    w_hat = hvec / np.linalg.norm(hvec)
    q_hat = np.cross(w_hat, p_hat)
    nu = np.linspace(0, 2 * np.pi, n)
    rad = a * (1 - e**2) / (1 + e * np.cos(nu))
    return (rad * np.cos(nu))[:, None] * p_hat + (rad * np.sin(nu))[:, None] * q_hat


def _circle(radius, normal, n=200):
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    t = np.linspace(0, 2 * np.pi, n)
    return radius * (np.cos(t)[:, None] * a + np.sin(t)[:, None] * b)
