"""Schema entries for what moves with the state or with time: the direction of a keep-in / keep-out cone
(``nadir``, ``velocity`` or a fixed inertial vector such as the Sun's) and the rendezvous target (a point of a
circular orbit moving at its circular rate).  Kept apart from problems/maneuvers.py, which calls these::

    constraints:
      - {kind: keep_in,  body_axis: [3], direction: nadir | velocity | [3], max_angle_deg: deg}
      - {kind: keep_out, body_axis: [3], direction: nadir | velocity | [3], min_angle_deg: deg}
    terminal:
      rendezvous:
        radius: r                           # the target's circular orbit (length unit of the file)
        normal: [3]                         # its plane: the normal (the target turns positively about it),
        # or inclination_deg: i, raan_deg: Omega (normal Rz(Omega) Rx(i) e3, node (cos Omega, sin Omega, 0))
        phase_deg: u0                       # the target's argument of latitude at t = 0, from the ascending node
        attitude: ATT                       # optional: the attitude at arrival (else free)
        angular_velocity: [3]               # optional: body frame (else free)

The target moves at omega = sqrt(mu / r^3) (the model's mu); position and velocity at t = T are asked for
(transcription.ocp.TargetRendezvous, docs/mathematics.md §10).  Every error is the file's one-line
ConfigError.
"""
from __future__ import annotations

import numpy as np

from ..transcription.geometry.so3 import rot_x, rot_z
from ..transcription.ocp import MOVING_DIRECTIONS, ProblemError, TargetRendezvous
from .physical import check_radians
from .schema import describe

RENDEZVOUS_KEYS = ("radius", "normal", "inclination_deg", "raan_deg", "phase_deg", "attitude", "angular_velocity")


def cone_direction(v, val, where: str):
    """A cone's direction: 'nadir', 'velocity' (the direction follows the state) or a non-zero 3-vector (a fixed
    inertial direction, normalized)."""
    if isinstance(val, str):
        if val not in MOVING_DIRECTIONS:
            v.fail(where, f"expected {' or '.join(MOVING_DIRECTIONS)} or a fixed inertial direction [x, y, z], "
                          f"got {describe(val)}")
        return val
    if not isinstance(val, (list, tuple)):
        v.fail(where, f"expected {' or '.join(MOVING_DIRECTIONS)} or a fixed inertial direction [x, y, z], "
                      f"got {describe(val)}")
    return v.unit_vector(val, where)


def is_rendezvous(t) -> bool:
    """True if the terminal block is a rendezvous target."""
    return isinstance(t, dict) and "rendezvous" in t


def rendezvous(v, t, body, extent) -> TargetRendezvous:
    """terminal: {rendezvous: {...}} (module docstring) -> TargetRendezvous; ``extent``: the clearance from the
    central body's centre (None without a central body)."""
    v.mapping(t, "terminal", ("rendezvous",))
    w = "terminal.rendezvous"
    o = v.mapping(t["rendezvous"], w, RENDEZVOUS_KEYS, required=("radius", "phase_deg"))
    if body.body_model().mu is None:
        v.fail(w, "a rendezvous target needs a central body (gravity kind other than none)")
    r = v.number(o["radius"], f"{w}.radius", positive=True)
    if extent is not None and not r > extent:
        v.fail(f"{w}.radius", "expected an orbit outside the central body",
               also=("model.central_body_radius", "model.length", "model.sphere_radius"))
    normal, node = _plane(v, o, w)
    phase = v.number(o["phase_deg"], f"{w}.phase_deg")
    check_radians(v, phase, f"{w}.phase_deg")
    R = v.attitude(o["attitude"], f"{w}.attitude") if "attitude" in o else None
    Pi = body.inertia @ v.vec3(o["angular_velocity"], f"{w}.angular_velocity") if "angular_velocity" in o else None
    try:
        return TargetRendezvous(r, normal, np.radians(phase), node, R, Pi)
    except ProblemError as e:
        v.fail(w, str(e).split(": ", 1)[1])


def _plane(v, o, w):
    """(unit normal, node or None) from ``normal`` or from ``inclination_deg`` and ``raan_deg`` (not both)."""
    angles = [k for k in ("inclination_deg", "raan_deg") if k in o]
    if "normal" in o and angles:
        v.fail(f"{w}.{angles[0]}", "give the plane by normal or by inclination_deg and raan_deg, not both")
    if "normal" in o:
        return v.unit_vector(o["normal"], f"{w}.normal"), None
    if len(angles) < 2:
        missing = "inclination_deg" if "inclination_deg" not in o else "raan_deg"
        v.fail(f"{w}.{missing}" if angles else w,
               "missing the orbit plane: give normal: [x, y, z], or inclination_deg and raan_deg")
    i = v.number(o["inclination_deg"], f"{w}.inclination_deg", nonneg=True)
    if i > 180.0:
        v.fail(f"{w}.inclination_deg", f"expected an inclination from 0 to 180 degrees, got {i:g}")
    raan = v.number(o["raan_deg"], f"{w}.raan_deg")
    for k, a in (("inclination_deg", i), ("raan_deg", raan)):
        check_radians(v, a, f"{w}.{k}")
    Q = rot_z(raan) @ rot_x(i)
    return Q[:, 2], Q[:, 0]


__all__ = ["RENDEZVOUS_KEYS", "cone_direction", "is_rendezvous", "rendezvous"]
