"""The continuous-time flight engine: eqs. (1)-(4) under the controls a scheme defines between its nodes, integrated
by SUNDIALS CVODES (casadi.integrator) node interval by node interval (docs/mathematics.md §11).

* :func:`equations_of_motion` -- eqs. (1)-(4); :class:`Actuators`, :func:`actuator_output` -- commands -> applied
  controls; :func:`interval_commands` -- a scheme's controls as each node interval's affine command;
* :class:`OpenLoop`, :class:`ClosedLoop` -- control laws: interval k's command at its two ends from (k, t_k, X_k);
* :func:`interval_integrator` -- one interval in normalized time s = (t - t_k)/h_k, sampled at s = j/M;
* :func:`fly` -- a law flown from X0 over a time grid -> :class:`Flight` (dense samples of state and control).

The truth body is any :class:`~transcription.dynamics.model.BodyModel`; the integrator is built once per potential
and number of samples (inverse inertia and actuator errors are parameters).  R is integrated as nine entries; the
continuous check re-projects it onto SO(3) (transcription.results.check).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import casadi as ca
import numpy as np

from .lgvi import SCHEMES, two_point
from ..geometry.state import NU, NX, U_FORCE, U_MOMENT, join_state, split_state
from ..geometry.so3 import orthogonality_error
from .model import BodyModel
from .trajectory import Trajectory

#: CVODES (Adams, functional iteration: not stiff) tolerances; each restart at a node adds about RTOL relative, so
#: N intervals carry about N RTOL (docs/mathematics.md §11)
RTOL = 1e-14
ATOL = 1e-16
#: the smallest CVODES step, as a fraction of the node interval: below it the motion is singular (a body at a point
#: mass) and CVODES fails instead of creeping on
MIN_STEP = 1e-12
#: samples of the state per node interval (s = 1/M, ..., 1): path deviations and constraint margins between nodes
DEFAULT_SAMPLES = 4
#: actuator parameters: force scale, moment scale, vec(A_f), vec(A_m), the force command's frame (0 inertial, 1 body)
N_ACTUATOR = 21
#: interval parameters w = [a (6); b (6); h] and flight parameters p = [vec(J^-1) (9); actuators (21)]
N_W, N_P = 2 * NU + 1, 9 + N_ACTUATOR


class FlightError(RuntimeError):
    """The integrator failed (the state left its domain, e.g. into the central body's singularity)."""


# --------------------------------------------------------------------------- equations of motion
def equations_of_motion(model: BodyModel, disturbance: ca.Function | None = None) -> ca.Function:
    """``flight_eom(X[18], u[6], Jinv[3x3]) -> Xdot[18]``: eqs. (1)-(4) (docs/mathematics.md §1),

        x' = gamma/m,  gamma' = f(x, R) + f_d(X) + u_f,  R' = R S(Omega),  Pi' = Pi x Omega + M(x, R) + u_m,

    Omega = Jinv Pi (body), u_f inertial and u_m body as they act on the body, f and M from
    ``model.forces``, f_d the truth's other forces (``disturbance``: X[18] -> f[3] inertial, e.g. drag and solar
    radiation pressure, problems.flight.forces; none by default); Xdot in the layout of
    transcription.geometry.state (vec(R') column-major)."""
    X, u, Jinv = ca.SX.sym("X", NX), ca.SX.sym("u", NU), ca.SX.sym("Jinv", 3, 3)
    x, gamma, R, Pi = split_state(X)
    f, M = model.forces(x, R)
    if disturbance is not None:
        f = f + disturbance(X)
    Om = ca.mtimes(Jinv, Pi)
    Xdot = join_state(gamma / model.mass, f + u[0:3], ca.mtimes(R, ca.skew(Om)), ca.cross(Pi, Om) + M + u[3:6])
    return ca.Function("flight_eom", [X, u, Jinv], [Xdot], ["X", "u", "Jinv"], ["Xdot"])


@dataclass(frozen=True)
class Actuators:
    """How commands become the controls acting on the body (nominal: identity): scale factors s_f, s_m and body-fixed
    misalignment rotations A_f, A_m (3x3).  Applied force s_f R A_f R^T u_f for an inertial command (``force_frame``),
    s_f R A_f u_f for a body-frame one (§14); applied moment (body) s_m A_m u_m."""

    force_scale: float = 1.0
    moment_scale: float = 1.0
    force_misalignment: np.ndarray = field(default_factory=lambda: np.eye(3))
    moment_misalignment: np.ndarray = field(default_factory=lambda: np.eye(3))
    force_frame: str = "inertial"

    def __post_init__(self):
        for name in ("force_scale", "moment_scale"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number")
        for name in ("force_misalignment", "moment_misalignment"):
            A = np.asarray(getattr(self, name), dtype=float)
            if A.shape != (3, 3) or not np.all(np.isfinite(A)) or orthogonality_error(A)[0] > 1e-9 or np.linalg.det(A) < 0:
                raise ValueError(f"{name}: expected a rotation matrix (3x3, A^T A = I, det A = 1)")
            object.__setattr__(self, name, A)

    def vector(self) -> np.ndarray:
        """q (21,) = [s_f; s_m; vec(A_f); vec(A_m); 1 for a body-frame force command, else 0] (column-major),
        the parameters of :func:`actuator_output`."""
        return np.concatenate([[self.force_scale, self.moment_scale], self.force_misalignment.ravel(order="F"),
                               self.moment_misalignment.ravel(order="F"), [float(self.force_frame == "body")]])


def actuator_output() -> ca.Function:
    """``flight_actuators(X[18], u_cmd[6], q[21]) -> u[6]``: u_f = s_f R A_f u_b with u_b = R^T u_f,cmd (inertial
    command) or u_f,cmd (body-frame, q[20] = 1); u_m = s_m A_m u_m,cmd; q = :meth:`Actuators.vector`, R the flown
    attitude in X."""
    X, uc, q = ca.SX.sym("X", NX), ca.SX.sym("u_cmd", NU), ca.SX.sym("q", N_ACTUATOR)
    _, _, R, _ = split_state(X)
    Af, Am = ca.reshape(q[2:11], 3, 3), ca.reshape(q[11:20], 3, 3)
    body = q[20] * uc[U_FORCE] + (1 - q[20]) * ca.mtimes(R.T, uc[U_FORCE])
    u = ca.vertcat(q[0] * ca.mtimes([R, Af, body]), q[1] * ca.mtimes(Am, uc[U_MOMENT]))
    return ca.Function("flight_actuators", [X, uc, q], [u], ["X", "u_cmd", "q"], ["u"])


# ----------------------------------------------------------------------------- control laws
def interval_commands(scheme: str, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The controls U of a scheme as the affine command of each node interval k, ``start[:, k]`` at t_k to
    ``end[:, k]`` at t_{k+1} (§11): LGVI U (6, N+1), start = u_k, end = u_{k+1}; first order U (6, N) = u_1..u_N,
    start = end = u_{k+1}.  Returns (6, N) each."""
    U = np.asarray(U, dtype=float)
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    return (U[:, :-1], U[:, 1:]) if two_point(scheme) else (U, U)


class ControlLaw(Protocol):
    def commands(self, k: int, t: float, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The command (6,) at the start and at the end of interval k, from the flown state X (18,) at t_k."""


@dataclass(frozen=True, eq=False)
class OpenLoop:
    """Commands fixed in advance: ``start``, ``end`` (6, N) (:func:`interval_commands`)."""

    start: np.ndarray
    end: np.ndarray

    @classmethod
    def of_controls(cls, scheme: str, U: np.ndarray) -> "OpenLoop":
        """A plan's controls U (6, n_controls) applied as ``scheme`` defines them between the nodes."""
        return cls(*interval_commands(scheme, U))

    @classmethod
    def free(cls, N: int) -> "OpenLoop":
        """No control over N intervals (free motion)."""
        return cls(np.zeros((NU, N)), np.zeros((NU, N)))

    def commands(self, k, t, X):
        return self.start[:, k], self.end[:, k]


@dataclass(frozen=True, eq=False)
class ClosedLoop:
    """The plan's commands plus a correction held over each interval: start + d, end + d, d = correction(k, t_k, X_k)
    (6,); ``limit`` (optional) maps each end into the admissible set (convex: the affine command between stays in)."""

    plan: OpenLoop
    correction: Callable[[int, float, np.ndarray], np.ndarray]
    limit: Callable[[np.ndarray], np.ndarray] | None = None

    def commands(self, k, t, X):
        a, b = self.plan.commands(k, t, X)
        d = np.asarray(self.correction(k, t, X), dtype=float).reshape(NU)
        a, b = a + d, b + d
        return (a, b) if self.limit is None else (self.limit(a), self.limit(b))


# ------------------------------------------------------------------------------- integrator
class BoundedCache:
    """Functions built once per key, at most ``size`` kept (oldest evicted first).  ``keep``: objects whose ``id`` is
    part of the key, kept alive with the entry so the id stays unique."""

    def __init__(self, size: int = 32):
        self.size, self.entries = size, {}

    def get(self, key, make: Callable[[], ca.Function], keep=None) -> ca.Function:
        """The Function of ``key``, made by ``make()`` when it is not kept yet."""
        hit = self.entries.get(key)
        if hit is None:
            if len(self.entries) >= self.size:
                self.entries.pop(next(iter(self.entries)))
            hit = self.entries[key] = (keep, make())
        return hit[1]


_INTEGRATORS = BoundedCache()


def interval_integrator(model: BodyModel, samples: int = DEFAULT_SAMPLES, rtol: float = RTOL,
                        atol: float = ATOL, disturbance: ca.Function | None = None) -> ca.Function:
    """``flight_interval(X0[18], w[13], p[29]) -> (X1[18], Xs[18 x M])`` for M = ``samples``: one node
    interval of length h flown from X0, in normalized time s = (t - t_k)/h in [0, 1],

        dX/ds = h eom(X, actuators(X, a + s (b - a), q), Jinv),   w = [a (6); b (6); h],
        p = [vec(Jinv) (9, column-major); q (21, Actuators.vector())],

    by CVODES, restarted at every call so the command's kinks and jumps at the nodes are never integrated across.
    Xs holds the states at s = 1/M, ..., 1 (Xs[:, -1] = X1).  ``disturbance``: the truth's other forces
    (:func:`equations_of_motion`).  Built once per (potential, disturbance, mass, M, tolerances)."""
    key = (id(model.forces), id(disturbance), float(model.mass), int(samples), float(rtol), float(atol))
    return _INTEGRATORS.get(key, lambda: _interval_integrator(model, samples, rtol, atol, disturbance),
                            keep=(model.forces, disturbance))


def _interval_integrator(model: BodyModel, samples: int, rtol: float, atol: float,
                         disturbance: ca.Function | None = None) -> ca.Function:
    """The Function of :func:`interval_integrator`, built."""
    eom, act = equations_of_motion(model, disturbance), actuator_output()
    X, w, p, s = ca.SX.sym("X", NX), ca.SX.sym("w", N_W), ca.SX.sym("p", N_P), ca.SX.sym("s")
    a, b, h = w[0:NU], w[NU:2 * NU], w[2 * NU]
    u = act(X, a + s * (b - a), p[9:])
    ode = h * eom(X, u, ca.reshape(p[0:9], 3, 3))
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": 100000, "min_step_size": MIN_STEP,
            "linear_multistep_method": "adams", "nonlinear_solver_iteration": "functional"}
    grid = [j / samples for j in range(1, samples + 1)]
    cv = ca.integrator("flight_cvodes", "cvodes", {"x": X, "p": ca.vertcat(w, p), "t": s, "ode": ode}, 0.0, grid, opts)
    X0, wm, pm = ca.MX.sym("X0", NX), ca.MX.sym("w", N_W), ca.MX.sym("p", N_P)
    Xs = cv(x0=X0, p=ca.vertcat(wm, pm))["xf"]
    return ca.Function("flight_interval", [X0, wm, pm], [Xs[:, -1], Xs], ["X0", "w", "p"], ["X1", "Xs"])


_RUNS = BoundedCache()


def _open_loop_run(fn: ca.Function, N: int) -> ca.Function:
    """``flight_interval`` accumulated over N intervals (casadi mapaccum: one call, a C loop that restarts
    CVODES at every node), built once per (integrator, N)."""
    return _RUNS.get((id(fn), N), lambda: fn.mapaccum(f"flight_run{N}", N), keep=fn)


# ------------------------------------------------------------------------------------ flight
@dataclass(frozen=True, eq=False)
class Flight:
    """A flown motion, sampled M = ``samples`` times per node interval: t (N M + 1,) sample times, t[k M] = t_k;
    X (N M + 1, 18) the flown state (R as integrated); command_start, command_end (N, 6) the law's command at each
    interval's ends ([u_f inertial; u_m body], affine in between); control_t (N, M + 1), control (N, M + 1, 6) the
    applied control (the actuators' output) at s = 0, 1/M, ..., 1 of each interval; mass, inertia: the truth body's."""

    t: np.ndarray
    X: np.ndarray
    samples: int
    command_start: np.ndarray
    command_end: np.ndarray
    control_t: np.ndarray
    control: np.ndarray
    mass: float
    inertia: np.ndarray

    @property
    def nodes(self) -> np.ndarray:
        """The flown state at the nodes t_0..t_N (N+1, 18)."""
        return self.X[:: self.samples]

    @property
    def node_times(self) -> np.ndarray:
        return self.t[:: self.samples]

    def trajectory(self) -> Trajectory:
        """The samples as a :class:`~transcription.results.solution.Trajectory` (x, v, R, Omega, ... at every sample)."""
        return Trajectory(t=self.t, X=self.X, mass=self.mass, inertia=self.inertia)


def sensed(X: np.ndarray, J_law: np.ndarray, Jinv_truth: np.ndarray) -> np.ndarray:
    """The state (18,) a law that knows its body by the inertia ``J_law`` reads from the truth's state X (18,): the
    rate is measured, Omega = Jinv_truth Pi, and the law's angular momentum is J_law Omega (docs/mathematics.md §12,
    *The rate tracked*); the rest as flown.  X itself where J_law is the truth's."""
    out = np.array(X, dtype=float).reshape(NX)
    out[15:18] = np.asarray(J_law, float) @ (np.asarray(Jinv_truth, float) @ out[15:18])
    return out


def node_grid(times) -> tuple[np.ndarray, np.ndarray]:
    """(times (N+1,), steps h (N,)) of a flight's node grid; ValueError unless it has two or more increasing finite
    times."""
    times = np.asarray(times, dtype=float).ravel()
    h = np.diff(times)
    if times.size < 2 or not np.all(np.isfinite(times)) or not np.all(h > 0):
        raise ValueError("times: expected at least two increasing finite times")
    return times, h


def law_sensing(model: BodyModel, law_inertia: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(J_truth^-1, J_law) of a flight whose law believes the inertia ``law_inertia`` (3x3; None: the truth's): the
    two matrices of :func:`sensed`."""
    J_law = model.inertia if law_inertia is None else law_inertia
    return np.linalg.inv(model.inertia), np.asarray(J_law, dtype=float).reshape(3, 3)


def fly(model: BodyModel, X0: np.ndarray, times: np.ndarray, law: "OpenLoop | ControlLaw",
        actuators: Actuators | None = None, samples: int = DEFAULT_SAMPLES, rtol: float = RTOL,
        atol: float = ATOL, disturbance: ca.Function | None = None,
        law_inertia: np.ndarray | None = None) -> Flight:
    """Fly ``law`` from X0 (18,; the truth body's momenta) over the increasing node grid ``times`` (N+1,) through
    eqs. (1)-(4) of the truth body ``model`` with ``actuators`` (default nominal), one node interval at a time
    (:func:`interval_integrator`), ``samples`` per interval.  An :class:`OpenLoop`, or a law with a ``flown(fn, X0, h,
    p, law_inertia) -> (start, end, Xs)`` method, is flown in one call; any other law is asked for each interval's
    command from the flown state as the law senses it (:func:`sensed`: the measured rate times ``law_inertia``, the
    inertia the law believes, 3x3; default the truth's: the flown state itself).  ``disturbance``: the truth's forces
    besides gravity (:func:`equations_of_motion`).  Raises FlightError if the integrator fails."""
    (times, h), X0 = node_grid(times), np.asarray(X0, dtype=float).reshape(NX)
    if not np.all(np.isfinite(X0)):
        raise ValueError("X0: expected a finite state of 18 numbers")
    N, M = h.size, int(samples)
    fn = interval_integrator(model, M, rtol, atol, disturbance)
    Jinv, J_law = law_sensing(model, law_inertia)
    p = np.concatenate([Jinv.ravel(order="F"), (actuators or Actuators()).vector()])
    try:
        if isinstance(law, OpenLoop):
            A, B = np.asarray(law.start, float), np.asarray(law.end, float)
            if A.shape != (NU, N) or B.shape != (NU, N) or not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
                raise ValueError(f"commands: expected finite start and end of shape (6, {N}), got {A.shape} and {B.shape}")
            _, Xs = _open_loop_run(fn, N)(X0, np.vstack([A, B, h[None, :]]), np.repeat(p[:, None], N, axis=1))
            Xs = Xs.full().T
        elif hasattr(law, "flown"):           # a law flown in one call (transcription.closedloop.loop.TrackingLoop)
            A, B, Xs = law.flown(fn, X0, h, p, J_law)
        else:
            A, B, out, Xk = np.zeros((NU, N)), np.zeros((NU, N)), [], X0
            for k in range(N):
                A[:, k], B[:, k] = law.commands(k, float(times[k]), sensed(Xk, J_law, Jinv))
                X1, Xk_s = fn(Xk, np.concatenate([A[:, k], B[:, k], [h[k]]]), p)
                out.append(Xk_s.full().T)
                Xk = X1.full().ravel()
            Xs = np.vstack(out)
    except RuntimeError as e:
        raise FlightError(f"the continuous flight failed (CVODES): {str(e).strip().splitlines()[-1]}") from None
    return flight_record(model, times, X0, Xs, A, B, M, p[9:])


def flight_record(model: BodyModel, times: np.ndarray, X0: np.ndarray, Xs: np.ndarray, A: np.ndarray, B: np.ndarray,
                  samples: int, q: np.ndarray, moment: np.ndarray | None = None) -> Flight:
    """The :class:`Flight` of a flown motion, whatever engine flew it: node times (N+1,), X0 (18,), Xs (N M, 18) the
    states at s = 1/M, ..., 1 of each interval (M = ``samples``), the commands A, B (6, N) at the intervals' ends,
    q (21,) the actuators (:meth:`Actuators.vector`); the applied control by :func:`actuator_output` on the samples,
    its moment ``moment`` (N, M+1, 3) where another actuator gave it (reaction wheels)."""
    M, h = int(samples), np.diff(times)
    X = np.vstack([np.asarray(X0, float).reshape(1, NX), Xs])
    ts = times[:-1, None] + h[:, None] * (np.arange(M + 1) / M)[None, :]    # (N, M+1): s = 0, 1/M, ..., 1
    ts[:, -1] = times[1:]
    control = _applied(X, A, B, M, q)
    if moment is not None:
        control[..., 3:6] = moment
    return Flight(t=np.concatenate([[times[0]], ts[:, 1:].ravel()]), X=X, samples=M, command_start=A.T.copy(),
                  command_end=B.T.copy(), control_t=ts, control=control,
                  mass=float(model.mass), inertia=np.asarray(model.inertia, float))


def _applied(X: np.ndarray, A: np.ndarray, B: np.ndarray, M: int, q: np.ndarray) -> np.ndarray:
    """The applied control (N, M+1, 6) at s = 0, 1/M, ..., 1 of each interval: the actuators' output
    (:func:`actuator_output`) for the command a + s (b - a) on the flown state there."""
    N = A.shape[1]
    s = np.arange(M + 1) / M
    idx = np.arange(N)[:, None] * M + np.arange(M + 1)[None, :]            # sample index of (k, j)
    cmd = A.T[:, None, :] + s[None, :, None] * (B - A).T[:, None, :]        # (N, M+1, 6)
    n = N * (M + 1)
    # built once per size: building it cost as much as evaluating it
    u = _APPLIED.get(n, lambda: actuator_output().map(n))(X[idx.ravel()].T, cmd.reshape(n, NU).T, q)
    return np.asarray(u.full()).T.reshape(N, M + 1, NU)


_APPLIED = BoundedCache()
