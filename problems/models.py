"""The bodies and the gravity fields of the maneuver files (docs/mathematics.md §1).

Bodies:

* :class:`Dumbbell` -- two equal spheres of mass m/2 and radius r_s at body-fixed
  rho_1 = +(l/2) e1, rho_2 = -(l/2) e1, joined by a massless rod (the paper's body);
* :class:`RigidBody` -- a body given by its mass and inertia tensor only (principal moments or a
  symmetric positive definite 3x3 matrix, body frame).

Gravity of a fixed central body at the origin with GM = mu (``gravity.kind``):

* ``none`` -- U = 0 (a free rigid body: attitude-only maneuvers when the force is removed);
* ``point_mass`` (default) -- the central body is a point mass.  The dumbbell's potential is
  exact, the sum over its spheres of -mu (m/2) / |x + R rho_q|.  A rigid body known only by its
  inertia gets the second-order (MacCullagh) expansion in its size over the distance,
      U(x, R) = -mu m / r - mu / (2 r^3) (tr J - 3 rhat^T R J R^T rhat),   r = |x|, rhat = x / r,
  whose R-dependent part is the gravity-gradient torque;
* ``gravity_gradient`` -- the MacCullagh expansion for every body (for the dumbbell: a model of
  its exact potential, to compare against);
* ``j2`` -- the point mass plus the oblateness of the central body about the inertial e3 axis,
  V(y) = -mu/|y| [1 - J2 (R_e/|y|)^2 (3 (y_3/|y|)^2 - 1) / 2] per unit mass at y, applied to each
  sphere of the dumbbell, and to the centre of mass of a rigid body with its MacCullagh term
  (the coupling of J2 with the body's size is of higher order and left out).

Normalized units (the project's convention with a central body): mass by the body's mass, length
by the radius of the reference circular orbit, time by its period, so GM = 4 pi^2.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..transcription.dynamics.model import BodyModel

GM_NORMALIZED = 4.0 * np.pi**2
GRAVITY_KINDS = ("none", "point_mass", "gravity_gradient", "j2")


def parse_gravity(v, g, where: str) -> dict:
    """A gravity block {kind, J2, radius} checked with the Validator ``v`` (errors name ``where``):
    the resolved block, with J2 and radius for (and only for) kind j2."""
    g = v.mapping(g, where, ("kind", "J2", "radius"), required=("kind",))
    kind = v.choice(g["kind"], f"{where}.kind", GRAVITY_KINDS)
    rg = {"kind": kind}
    if kind == "j2":
        for k in ("J2", "radius"):
            if k not in g:
                v.fail(f"{where}.{k}", "missing required key (the j2 model needs J2 and the central body's radius)")
        rg["J2"] = v.number(g["J2"], f"{where}.J2")
        rg["radius"] = v.number(g["radius"], f"{where}.radius", positive=True)
    else:
        for k in ("J2", "radius"):
            if k in g:
                v.fail(f"{where}.{k}", f"applies to gravity kind j2 only (kind is {kind})")
    return rg


@dataclass(frozen=True)
class Gravity:
    """The central body's field: kind (GRAVITY_KINDS), mu = GM, and for 'j2' the coefficient J2 and
    the equatorial radius R_e."""

    kind: str = "point_mass"
    mu: float = GM_NORMALIZED
    J2: float = 0.0
    radius: float = 0.0

    def data(self) -> np.ndarray:
        """[mu, J2, R_e]: the numbers of :meth:`per_unit_mass` (a model's parametric potential takes them as data)."""
        return np.array([self.mu, self.J2, self.radius])

    def per_unit_mass(self, y, d=None):
        """V(y) of a point of unit mass at y (CasADi): -mu/|y| (with the J2 term for 'j2'); ``d``: symbolic
        [mu, J2, R_e] in place of this field's numbers (the same expression with the numbers as data)."""
        mu, J2, Re = (self.mu, self.J2, self.radius) if d is None else (d[0], d[1], d[2])
        r = ca.norm_2(y)
        V = -mu / r
        if self.kind == "j2":
            V = V * (1.0 - J2 * (Re / r) ** 2 * (3.0 * (y[2] / r) ** 2 - 1.0) / 2.0)
        return V

    def maccullagh(self, x, R, J, mu=None, trJ=None):
        """The second-order term -mu/(2 r^3) (tr J - 3 rhat^T R J R^T rhat) (CasADi); J (3x3) numbers or symbols,
        ``mu``, ``trJ``: symbols in place of the numbers."""
        mu = self.mu if mu is None else mu
        trJ = float(np.trace(J)) if trJ is None else trJ
        r = ca.norm_2(x)
        rhat = x / r
        Ir = ca.mtimes([rhat.T, R, ca.DM(J) if isinstance(J, np.ndarray) else J, R.T, rhat])
        return -mu / (2.0 * r**3) * (trJ - 3.0 * Ir)

    @property
    def key(self) -> tuple:
        return (self.kind, self.mu, self.J2, self.radius)


#: BodyModels by key: validating a file (a sweep validates every grid point) builds each model's
#: CasADi Functions once per process, not once per parse
_BODY_MODELS: dict = {}
_MAX_BODY_MODELS = 4096


def _cached_model(key, build) -> BodyModel:
    model = _BODY_MODELS.get(key)
    if model is None:
        if len(_BODY_MODELS) >= _MAX_BODY_MODELS:
            _BODY_MODELS.clear()
        model = _BODY_MODELS[key] = build()
    return model


def _potential_function(name: str, U_of) -> ca.Function:
    x = ca.SX.sym("x", 3)
    R = ca.SX.sym("R", 3, 3)
    return ca.Function(name, [x, R], [U_of(x, R)], ["x", "R"], ["U"])


def _parametric_potential(name: str, U_of, nq: int) -> ca.Function:
    """U(x, R, q) from U_of(x, R, q) (the model's potential with its numbers q as data)."""
    x, R, q = ca.SX.sym("x", 3), ca.SX.sym("R", 3, 3), ca.SX.sym("q", nq)
    return ca.Function(name, [x, R, q], [U_of(x, R, q)], ["x", "R", "q"], ["U"])


#: the data q of the parametric potentials: [m, mu, J2, R_e, tr J, vec J (9), l/2 (dumbbell)]
_NQ_RIGID = 14


def _maccullagh_q(g: Gravity, x, R, q):
    return g.maccullagh(x, R, ca.reshape(q[5:14], 3, 3), mu=q[1], trJ=q[4])


@dataclass(frozen=True)
class Dumbbell:
    """Dumbbell parameters: mass m, rod length l, sphere radius r_s, central body mu = GM, and the
    gravity model (its ``mu`` is this ``mu``)."""

    mass: float = 1.0
    length: float = 0.1
    sphere_radius: float = 0.02
    mu: float = GM_NORMALIZED
    gravity: str = "point_mass"
    J2: float = 0.0
    J2_radius: float = 0.0

    @property
    def rho(self) -> np.ndarray:
        """Body-fixed sphere centres, shape (2, 3)."""
        e1 = np.array([1.0, 0.0, 0.0])
        return np.array([0.5 * self.length * e1, -0.5 * self.length * e1])

    @property
    def inertia(self) -> np.ndarray:
        """J = sum_q (m/2)(|rho_q|^2 I - rho_q rho_q^T) + 2 (2/5)(m/2) r_s^2 I (body frame)."""
        m2 = 0.5 * self.mass
        J = sum(m2 * (q @ q * np.eye(3) - np.outer(q, q)) for q in self.rho)
        return J + 2 * 0.4 * m2 * self.sphere_radius**2 * np.eye(3)

    @property
    def field(self) -> Gravity:
        return Gravity(self.gravity, self.mu, self.J2, self.J2_radius)

    @property
    def extent(self) -> float:
        """The radius of the body's bounding sphere about its centre of mass."""
        return 0.5 * self.length + self.sphere_radius

    @property
    def central_mu(self) -> float | None:
        """GM of the central body (None without gravity)."""
        return None if self.gravity == "none" else self.mu

    def potential(self) -> ca.Function:
        """U(x, R): exact over the two spheres (point_mass, j2), MacCullagh (gravity_gradient), 0 (none)."""
        g = self.field
        if g.kind == "none":
            return _potential_function("dumbbell_potential", lambda x, R: ca.SX(0))
        if g.kind == "gravity_gradient":
            return _potential_function("dumbbell_potential",
                                       lambda x, R: -g.mu * self.mass / ca.norm_2(x) + g.maccullagh(x, R, self.inertia))
        return _potential_function("dumbbell_potential", lambda x, R: sum(
            0.5 * self.mass * g.per_unit_mass(x + ca.mtimes(R, ca.DM(q))) for q in self.rho))

    def potential_data(self) -> np.ndarray:
        """q of :meth:`parametric_potential`: [m, mu, J2, R_e, tr J, vec J (9), l/2]."""
        J = self.inertia
        return np.concatenate([[self.mass], self.field.data(), [np.trace(J)], J.ravel(order="F"), [0.5 * self.length]])

    def parametric_potential(self) -> ca.Function:
        """:meth:`potential` with its numbers as data q (:meth:`potential_data`); the same expression."""
        g = self.field
        if g.kind == "none":
            return _parametric_potential("dumbbell_potential_q", lambda x, R, q: ca.SX(0), _NQ_RIGID + 1)
        if g.kind == "gravity_gradient":
            return _parametric_potential("dumbbell_potential_q", lambda x, R, q: -q[1] * q[0] / ca.norm_2(x)
                                         + _maccullagh_q(g, x, R, q), _NQ_RIGID + 1)
        return _parametric_potential("dumbbell_potential_q", lambda x, R, q: sum(
            0.5 * q[0] * g.per_unit_mass(x + R[:, 0] * (s * q[14]), q[1:4]) for s in (1.0, -1.0)), _NQ_RIGID + 1)

    def moment_point_masses(self) -> ca.Function:
        """The alternative moment formula M = sum_q rho_q x (R^T f_q) (point-mass gravity), for checks."""
        x = ca.SX.sym("x", 3)
        R = ca.SX.sym("R", 3, 3)
        M = ca.SX.zeros(3, 1)
        for q in self.rho:
            y = x + ca.mtimes(R, ca.DM(q))
            fq = -self.mu * 0.5 * self.mass * y / ca.norm_2(y) ** 3
            M += ca.cross(ca.DM(q), ca.mtimes(R.T, fq))
        return ca.Function("dumbbell_moment_pm", [x, R], [M], ["x", "R"], ["M"])

    def body_model(self) -> BodyModel:
        """The BodyModel: U by this potential, mu for orbit targets (None without gravity), the sphere
        centres as markers for the figures, and a key so that equal dumbbells share their Functions."""
        g = self.field
        key = ("dumbbell", self.mass, self.length, self.sphere_radius, g.key)
        return _cached_model(key, lambda: BodyModel(mass=self.mass, inertia=self.inertia, potential=self.potential(),
                                                    mu=self.central_mu, markers=self.rho, key=key, name="dumbbell",
                                                    parametric_potential=self.parametric_potential(),
                                                    potential_data=self.potential_data()))


@dataclass(frozen=True)
class RigidBody:
    """A rigid body known by its mass and inertia tensor (body frame, symmetric positive definite)."""

    mass: float
    inertia: np.ndarray
    gravity: Gravity = Gravity()

    @property
    def extent(self) -> float:
        """No geometry: the body is a point for the central-body clearance."""
        return 0.0

    @property
    def central_mu(self) -> float | None:
        """GM of the central body (None without gravity)."""
        return None if self.gravity.kind == "none" else self.gravity.mu

    def potential(self) -> ca.Function:
        g, m, J = self.gravity, self.mass, np.asarray(self.inertia, float)
        if g.kind == "none":
            return _potential_function("rigid_body_potential", lambda x, R: ca.SX(0))
        return _potential_function("rigid_body_potential",
                                   lambda x, R: m * g.per_unit_mass(x) + g.maccullagh(x, R, J))

    def potential_data(self) -> np.ndarray:
        """q of :meth:`parametric_potential`: [m, mu, J2, R_e, tr J, vec J (9)]."""
        J = np.asarray(self.inertia, float)
        return np.concatenate([[self.mass], self.gravity.data(), [np.trace(J)], J.ravel(order="F")])

    def parametric_potential(self) -> ca.Function:
        """:meth:`potential` with its numbers as data q (:meth:`potential_data`); the same expression."""
        g = self.gravity
        if g.kind == "none":
            return _parametric_potential("rigid_body_potential_q", lambda x, R, q: ca.SX(0), _NQ_RIGID)
        return _parametric_potential("rigid_body_potential_q", lambda x, R, q: q[0] * g.per_unit_mass(x, q[1:4])
                                     + _maccullagh_q(g, x, R, q), _NQ_RIGID)

    def body_model(self) -> BodyModel:
        g = self.gravity
        J = np.asarray(self.inertia, float)
        key = ("rigid_body", self.mass, tuple(J.ravel()), g.key)
        return _cached_model(key, lambda: BodyModel(mass=self.mass, inertia=J, potential=self.potential(),
                                                    mu=self.central_mu, key=key, name="rigid body",
                                                    parametric_potential=self.parametric_potential(),
                                                    potential_data=self.potential_data()))
