"""Basilisk as a flight's truth (``flight.truth.integrator: basilisk``; issue 43): the plan flown in Basilisk's
spacecraft (AVS Lab, University of Colorado; PyPI ``bsk``, the optional extra ``se3ocp[basilisk]``), the simulation a
GNC team already trusts, instead of the project's own CVODES engine (transcription.dynamics.flight).

What is Basilisk's: the rigid hub (``spacecraft.Spacecraft``: mass, inertia about the centre of mass, translation and
rotation with MRP attitude and their shadow-set switching, its fixed-step RK4 integrator), the central body's gravity
at the centre of mass (``gravityEffector``: GM = the model's mu, and for a j2 truth its spherical harmonics to degree 2,
C20 = -J2 / sqrt(5) about the inertial e3, no planet rotation) and its gravity-gradient torque
(``GravityGradientEffector``, 3 mu / r^3 rhat x J rhat), all evaluated at every Runge-Kutta stage, and the external
force and torque (``extForceTorque``: an inertial force and a body torque held over each Basilisk step).

What is the project's, applied through ``extForceTorque``: the actuators' output (transcription.dynamics.flight.
actuator_output: the command through the run's scale factors and misalignments) and the rest of the truth model's
forces -- the body's exact gravity minus what Basilisk's two effectors apply (for the dumbbell, its finite size beyond
the second-order torque: ~(l / 2r)^2 of the gravity force), drag and solar radiation pressure.  These are held over
each Basilisk step at their value at the step's middle, predicted to second order from a flown state (x + s v +
s^2 a / 2, R exp(s Omega + s^2 Omega' / 2)), corrected in pairs of steps so that a pair applies the impulse and the
first moment of a load changing quadratically in time (docs/mathematics.md §11, *Basilisk as the truth*): the flight
converges at third order in the step dt = h / ``substeps``.

Units: any consistent system serves Newton's and Euler's laws, so the file's length and mass units are Basilisk's
metre and kilogram, and its time unit is scaled by tau so that one Basilisk step is exactly STEP_NS nanoseconds
(Basilisk's clock is an integer of nanoseconds): velocities and rates / tau, forces, torques and GM / tau^2.

The law of a closed-loop flight (the tracker, MPC) is asked for each node interval's command from the Basilisk state
at the node (an external loop stepping Basilisk between samples), as the project's engine asks it.  A plan on a
non-uniform mesh is not flown (its steps would need unequal Basilisk steps).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...transcription.dynamics.flight import (DEFAULT_SAMPLES, Actuators, Flight, FlightError, actuator_output,
                                              flight_record, law_sensing, node_grid, sensed)
from ...transcription.dynamics.model import BodyModel
from ...transcription.geometry.so3 import exp_so3
from ...transcription.geometry.state import NU, NX, join_state, split_state
from ..models import Gravity

#: one Basilisk step in Basilisk's nanoseconds (the time scale makes every step exactly this long)
STEP_NS = 1_000_000
#: Basilisk steps per node interval (an even multiple of the flight's samples); third order in the step
DEFAULT_SUBSTEPS = 16
_NAME = "central"


def available() -> bool:
    """True when Basilisk (``bsk``) can be imported."""
    from importlib.util import find_spec

    return find_spec("Basilisk") is not None


def basilisk_text(substeps: int) -> str:
    """One line naming the Basilisk truth: 'Basilisk 2.12.1 (bsk): spacecraft hub, RK4, 16 steps per node interval'."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        v = version("bsk")
    except PackageNotFoundError:
        v = "(version unknown)"
    return f"Basilisk {v} (bsk): spacecraft hub, RK4, {substeps} steps per node interval"


def central_field(model: BodyModel, j2: tuple[float, float] | None = None) -> Gravity | None:
    """The central body's field Basilisk applies at the centre of mass (problems.models.Gravity): the point mass of
    the model's mu, with the zonal J2 term when ``j2`` = (J2, R_e) is given; None without a central body."""
    if not model.mu:
        return None
    return Gravity("j2", float(model.mu), *map(float, j2)) if j2 else Gravity("point_mass", float(model.mu))


def predicted_loads(model: BodyModel, disturbance: ca.Function | None = None,
                    j2: tuple[float, float] | None = None) -> ca.Function:
    """``basilisk_loads(X[18], u_cmd[6], q[21], J[3x3], s) -> (f[3] inertial, M[3] body)``: the load extForceTorque is
    to apply at the time s (the file's time unit) after the state X of the truth body of inertia J: the actuators'
    output for the command u_cmd (the command at that time) plus the truth's forces (``model.forces`` and the
    ``disturbance``) minus Basilisk's gravity at the centre of mass, -m grad V(x) of :func:`central_field` (``j2``:
    (J2, R_e) of a j2 truth), and its gravity-gradient torque 3 mu / r^3 rhat_B x J rhat_B (none without a central
    body), all at the state predicted to second order in s: x + s v + s^2 a / 2, R exp(s Omega + s^2 Omega' / 2), the
    momenta advanced by their rates at X (module docstring)."""
    X, uc, q, J, dt = ca.SX.sym("X", NX), ca.SX.sym("u_cmd", NU), ca.SX.sym("q", 21), ca.SX.sym("J", 3, 3), ca.SX.sym("s")
    act = actuator_output()

    def loads(Y):
        y, _, R, _ = split_state(Y)
        f, M = model.forces(y, R)
        if disturbance is not None:
            f = f + disturbance(Y)
        u = act(Y, uc, q)
        return f + u[0:3], M + u[3:6]

    x, gamma, R, Pi = split_state(X)
    Om = ca.solve(J, Pi)
    f0, M0 = loads(X)
    dPi = ca.cross(Pi, Om) + M0
    Xm = join_state(x + dt * gamma / model.mass + 0.5 * dt**2 * f0 / model.mass, gamma + dt * f0,
                    ca.mtimes(R, exp_so3(dt * Om + 0.5 * dt**2 * ca.solve(J, dPi))), Pi + dt * dPi)
    f, M = loads(Xm)
    field = central_field(model, j2)
    if field is not None:
        xm, _, Rm, _ = split_state(Xm)
        y = ca.SX.sym("y", 3)
        grad = ca.Function("grad_V", [y], [ca.gradient(field.per_unit_mass(y), y)])
        r = ca.norm_2(xm)
        rb = ca.mtimes(Rm.T, xm) / r
        f = f + model.mass * grad(xm)
        M = M - 3.0 * model.mu / r**3 * ca.cross(rb, ca.mtimes(J, rb))
    return ca.Function("basilisk_loads", [X, uc, q, J, dt], [f, M], ["X", "u_cmd", "q", "J", "s"], ["f", "M"])


class Hub:
    """One Basilisk simulation of a truth body: the spacecraft hub (mass, inertia), the central body's point-mass
    gravity and gravity-gradient torque (when the model has a mu) and extForceTorque, stepped STEP_NS at a time.
    ``tau``: Basilisk seconds per time unit of the file; ``j2``: (J2, R_e) of the central body's zonal term (None:
    a point mass).  :meth:`state` reads the hub as the project's state (18,)."""

    def __init__(self, model: BodyModel, X0: np.ndarray, tau: float, j2: tuple[float, float] | None = None):
        from Basilisk.simulation import GravityGradientEffector, extForceTorque, gravityEffector, spacecraft
        from Basilisk.utilities import RigidBodyKinematics, SimulationBaseClass, simIncludeGravBody

        self.mass, self.J, self.tau, self.mrp = float(model.mass), np.asarray(model.inertia, float), tau, RigidBodyKinematics
        self.sim = SimulationBaseClass.SimBaseClass()
        self.sim.CreateNewProcess("truth").addTask(self.sim.CreateNewTask("dynamics", STEP_NS))
        sc = self.sc = spacecraft.Spacecraft()
        sc.ModelTag = "se3ocp"
        x, gamma, R, Pi = split_state(X0)
        sc.hub.mHub, sc.hub.IHubPntBc_B, sc.hub.r_BcB_B = self.mass, self.J.tolist(), [[0.0]] * 3
        sc.hub.r_CN_NInit = [[float(c)] for c in x]
        sc.hub.v_CN_NInit = [[float(c)] for c in gamma / self.mass / tau]
        sc.hub.sigma_BNInit = [[float(c)] for c in RigidBodyKinematics.C2MRP(R.T)]
        sc.hub.omega_BN_BInit = [[float(c)] for c in np.linalg.solve(self.J, Pi) / tau]
        self.sim.AddModelToTask("dynamics", sc)
        self.effectors = []           # Basilisk's objects referenced here live as long as the simulation
        if model.mu:
            self.gravity = simIncludeGravBody.gravBodyFactory()
            body = self.gravity.createCustomGravObject(_NAME, float(model.mu) / tau**2)
            body.isCentralBody = True
            if j2:
                sh = gravityEffector.SphericalHarmonicsGravityModel()
                sh.muBody, sh.radEquator, sh.maxDeg = body.mu, float(j2[1]), 2
                sh.cBar = [[1.0], [0.0, 0.0], [-float(j2[0]) / np.sqrt(5.0), 0.0, 0.0]]   # fully normalized C20
                sh.sBar = [[0.0], [0.0, 0.0], [0.0, 0.0, 0.0]]
                body.radEquator, body.gravityModel = float(j2[1]), sh
                self.effectors.append(sh)
            self.gravity.addBodiesTo(sc)
            gg = GravityGradientEffector.GravityGradientEffector()
            gg.ModelTag = "gravity_gradient"
            gg.addPlanetName(body.planetName)
            sc.addDynamicEffector(gg)
            self.sim.AddModelToTask("dynamics", gg)
            self.effectors.append(gg)
        self.ext = extForceTorque.ExtForceTorque()
        self.ext.ModelTag = "loads"
        sc.addDynamicEffector(self.ext)
        self.sim.AddModelToTask("dynamics", self.ext)
        self.sim.InitializeSimulation()
        self.steps = 0

    def step(self, f: np.ndarray, M: np.ndarray) -> None:
        """One Basilisk step with the inertial force f and body torque M (the file's units) held over it."""
        s = self.tau**-2
        self.ext.extForce_N = [float(c) * s for c in f]
        self.ext.extTorquePntB_B = [float(c) * s for c in M]
        self.steps += 1
        self.sim.ConfigureStopTime(self.steps * STEP_NS)
        self.sim.ExecuteSimulation()

    def state(self) -> np.ndarray:
        """The hub's state as the project's X (18,): x, m v, R = [BN]^T from the MRP, J Omega (the file's units)."""
        out = self.sc.scStateOutMsg.read()
        R = np.asarray(self.mrp.MRP2C(np.asarray(out.sigma_BN, float))).T
        return join_state(np.asarray(out.r_BN_N, float), self.mass * self.tau * np.asarray(out.v_BN_N, float), R,
                          self.J @ (self.tau * np.asarray(out.omega_BN_B, float)))


def fly_basilisk(model: BodyModel, X0: np.ndarray, times: np.ndarray, law, actuators: Actuators | None = None,
                 samples: int = DEFAULT_SAMPLES, disturbance: ca.Function | None = None, law_inertia: np.ndarray | None = None,
                 substeps: int = DEFAULT_SUBSTEPS, j2: tuple[float, float] | None = None) -> Flight:
    """Fly ``law`` (transcription.dynamics.flight's OpenLoop, ClosedLoop or any law with ``commands(k, t, X)``, X as
    transcription.dynamics.flight.sensed makes it) from X0 over the node grid ``times`` (N+1, equal steps) in Basilisk
    (module docstring), ``substeps`` Basilisk steps per node interval (an even multiple of ``samples``), ``j2`` = (J2, R_e)
    when the truth's central body has the J2 term (``model``'s potential must be that field); the arguments and
    the returned :class:`Flight` as transcription.dynamics.flight.fly's.  ValueError for a non-uniform grid, a law
    without ``commands`` or substeps that are not an even multiple of samples; FlightError when the state leaves its
    domain."""
    (times, h), X0 = node_grid(times), np.asarray(X0, float).reshape(NX)
    if np.max(np.abs(h - h.mean())) > 1e-9 * h.mean():
        raise ValueError("the Basilisk truth flies plans of equal steps only (one Basilisk step length)")
    if not hasattr(law, "commands"):
        raise ValueError("the Basilisk truth asks its law for each interval's commands: give a law with commands()")
    if substeps < 2 or substeps % samples or substeps % 2:
        raise ValueError(f"substeps ({substeps}) must be an even multiple of samples ({samples})")
    N, n, every = h.size, int(substeps), int(substeps) // int(samples)
    dt = float(h.mean()) / n
    q = (actuators or Actuators()).vector()
    Jinv, J_law = law_sensing(model, law_inertia)
    loads = predicted_loads(model, disturbance, j2)
    hub = Hub(model, X0, STEP_NS * 1e-9 / dt, j2)
    A, B, Xs, X = np.zeros((NU, N)), np.zeros((NU, N)), [], X0
    for k in range(N):
        A[:, k], B[:, k] = law.commands(k, float(times[k]), sensed(X, J_law, Jinv))
        for j in range(0, n, 2):
            X = _pair(hub, loads, X, A[:, k], B[:, k], j / n, 1.0 / n, q, model.inertia, dt, Xs, every, k)
    return flight_record(model, times, X0, np.array(Xs), A, B, samples, q)


def _pair(hub: Hub, loads: ca.Function, X: np.ndarray, a: np.ndarray, b: np.ndarray, s: float, ds: float, q, J, dt,
          Xs: list, every: int, k: int) -> np.ndarray:
    """Two Basilisk steps from X at the normalized time s of interval k (command a + s (b - a), steps of ds = dt / h):
    the loads L1, L2 at the steps' middles (:func:`predicted_loads`) held as L1 - c + e and L2 + c + e with
    c = L' dt / 6 = (L2 - L1) / 6 and e = L'' dt^2 / 24 = (L- - 2 L1 + L2) / 24 (L- at the middle of the step before),
    so that the pair applies the impulse and the first moment of a load changing quadratically (midpoint values alone
    lag the position by L' dt^3 / 12 and the impulse by L'' dt^3 / 24 every step).  c and e come from loads predicted
    from X (the interval's affine command extended past its ends, so no node's kink enters); L2 held from the state
    after the first step.  Appends the states on the sample grid (``every`` steps) to Xs; returns the state after the
    pair."""
    def load(Y, at, ahead):
        f, M = loads(Y, a + at * (b - a), q, J, ahead)
        return np.concatenate([np.asarray(f).ravel(), np.asarray(M).ravel()])

    def step(held):
        hub.step(held[:3], held[3:])
        Y = hub.state()
        if not np.all(np.isfinite(Y)):
            raise FlightError(f"the Basilisk flight left the state's domain in node interval {k}")
        if hub.steps % every == 0:
            Xs.append(Y)
        return Y

    before, first, second = (load(X, s + f * ds, f * dt) for f in (-0.5, 0.5, 1.5))
    c, curve = (second - first) / 6.0, (before - 2.0 * first + second) / 24.0
    X = step(first - c + curve)
    return step(load(X, s + 1.5 * ds, 0.5 * dt) + c + curve)


__all__ = ["DEFAULT_SUBSTEPS", "Hub", "STEP_NS", "available", "basilisk_text", "central_field", "fly_basilisk", "predicted_loads"]
