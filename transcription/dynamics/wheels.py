"""Reaction wheels in the truth (docs/mathematics.md §11, *Reaction wheels*).

n >= 3 wheels spin about body-fixed unit axes, the columns of A (3 x n).  h_w (n,) are the wheels' axial angular
momenta (inertial spin, wheel inertia included), tau (n,) the motor torques on the wheels.  With Pi = J Omega the
body's own angular momentum (the state's, transcription.geometry.state), the total H = J Omega + A h_w obeys
H' = H x Omega + M (body frame, M the external moment), so

    h_w' = tau,        Pi' = Pi x Omega + M + u_w,        u_w = -A tau + (A h_w) x Omega,

the wheels acting on the body through u_w: the motors' reaction and the gyroscopic coupling of their momentum.
Without external moment R (Pi + A h_w) is constant in the inertial frame.

The flight software (:class:`WheelController`) knows the nominal axes A; the truth flies the misaligned A_t.  Each
control period it turns the law's moment command u_m (affine a_m -> b_m, body) into wheel torques by the
pseudo-inverse, with the gyroscopic coupling at the period's start compensated,

    tau = A^+ (g - u_m),   g = (A h_w) x Omega   (h_w, Omega measured at t_k, held),

(so that u_w = u_m when A_t = A and nothing limits), each wheel's torque clipped at +-its torque limit and, where the
period would carry a wheel past its momentum limit -- at its end, or where its affine torque changes sign inside it --
its torques scaled so that it only reaches the limit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..geometry.state import NX, U_FORCE, split_state
from .flight import ATOL, MIN_STEP, N_ACTUATOR, RTOL, BoundedCache, actuator_output, equations_of_motion


@dataclass(frozen=True)
class Wheels:
    """n reaction wheels: ``axes`` (3, n) unit spin axes (body frame, columns) spanning R^3, ``torque_limit`` and
    ``momentum_limit`` (n,) positive (the file's moment and angular-impulse units)."""

    axes: np.ndarray
    torque_limit: np.ndarray
    momentum_limit: np.ndarray
    pinv: np.ndarray = field(init=False, repr=False, compare=False)    # A^+ (n, 3), computed once

    def __post_init__(self):
        A = np.asarray(self.axes, float)
        if A.ndim != 2 or A.shape[0] != 3 or A.shape[1] < 3 or not np.all(np.isfinite(A)):
            raise ValueError(f"wheels: expected axes of shape (3, n >= 3), got {A.shape}")
        if np.abs(np.linalg.norm(A, axis=0) - 1.0).max() > 1e-9:
            raise ValueError("wheels: expected unit axes")
        if np.linalg.matrix_rank(A, tol=1e-6) < 3:
            raise ValueError("wheels: the axes must span three dimensions (rank 3)")
        object.__setattr__(self, "axes", A)
        object.__setattr__(self, "pinv", np.linalg.pinv(A))
        for name in ("torque_limit", "momentum_limit"):
            v = np.broadcast_to(np.asarray(getattr(self, name), float), (A.shape[1],)).copy()
            if not (np.all(np.isfinite(v)) and np.all(v > 0)):
                raise ValueError(f"wheels: expected a positive {name.replace('_', ' ')} per wheel")
            object.__setattr__(self, name, v)

    @property
    def n(self) -> int:
        return self.axes.shape[1]

    def torques(self, u_m: np.ndarray, h_w: np.ndarray, Omega: np.ndarray) -> np.ndarray:
        """tau (n,) = A^+ ((A h_w) x Omega - u_m): the torques giving the body the moment u_m (3,) (module docstring)."""
        return self.pinv @ (np.cross(self.axes @ h_w, Omega) - np.asarray(u_m, float))


@dataclass
class WheelController:
    """The wheels' flight software over one flight (module docstring): :meth:`period` for k = 0, 1, ... in order.
    ``limited``: the periods in which some wheel's torque or momentum was limited."""

    wheels: Wheels
    limited: int = 0

    def period(self, a_m, b_m, h_w, Omega, h: float) -> tuple[np.ndarray, np.ndarray]:
        """The wheel torques (n,) at the start and end of a period of length h whose moment command goes from a_m to
        b_m (3, body), the wheels' momenta h_w (n,) and the body's rate Omega (3,) measured at its start."""
        w = self.wheels
        raw = np.array([w.torques(a_m, h_w, Omega), w.torques(b_m, h_w, Omega)])
        ta, tb = np.clip(raw, -w.torque_limit, w.torque_limit)
        limited = bool(np.any(np.abs(raw) > w.torque_limit))
        scale = np.ones(w.n)
        with np.errstate(divide="ignore", invalid="ignore"):
            turn = np.where(ta * tb < 0, ta / (ta - tb), 1.0)             # where an affine torque's momentum turns
        for s in (np.ones(w.n), turn):
            dh = h * (ta * s + 0.5 * (tb - ta) * s**2)                   # h_w(s) - h_w(0) at full torque
            over = np.abs(h_w + dh) > w.momentum_limit
            if over.any():                                              # to the limit on the side it goes
                room = np.sign(dh[over]) * w.momentum_limit[over] - h_w[over]
                scale[over] = np.minimum(scale[over], np.clip(room / dh[over], 0.0, 1.0))
        if np.any(scale < 1.0):
            ta, tb = ta * scale, tb * scale
            limited = True
        self.limited += limited
        return ta, tb


def moment_of_wheels(A, tau, h_w, Omega):
    """u_w = -A tau + (A h_w) x Omega (3,): the wheels' moment on the body (module docstring), CasADi or NumPy."""
    if isinstance(tau, (ca.SX, ca.MX)):
        return -ca.mtimes(A, tau) + ca.cross(ca.mtimes(A, h_w), Omega)
    return -A @ tau + np.cross(A @ h_w, Omega)


_INTEGRATORS = BoundedCache()


def wheel_integrator(model, n: int, samples: int, disturbance: ca.Function | None = None) -> ca.Function:
    """``flight_wheel_interval(Y0[18+n], w[7+2n], p[9+21+3n]) -> (Y1, Ys[(18+n) x M])``: one interval of length h of
    the body with n wheels (module docstring) in normalized time s, by CVODES as
    :func:`~transcription.dynamics.flight.interval_integrator`: Y = [X; h_w], w = [f_a (3); tau_a (n); f_b (3); tau_b (n);
    h] the force command (through the actuators' force model) and the wheel torques at both ends (affine between),
    p = [vec(J^-1); q (21, Actuators.vector()); vec(A_t) (the truth's axes, column-major)].  Built once per
    (potential, disturbance, mass, n, M)."""
    key = (id(model.forces), id(disturbance), float(model.mass), int(n), int(samples))
    return _INTEGRATORS.get(key, lambda: _wheel_integrator(model, n, samples, disturbance),
                            keep=(model.forces, disturbance))


def _wheel_integrator(model, n: int, samples: int, disturbance) -> ca.Function:
    eom, act = equations_of_motion(model, disturbance), actuator_output()
    ny, nw, npar = NX + n, 7 + 2 * n, 9 + N_ACTUATOR + 3 * n
    Y, w, p, s = ca.SX.sym("Y", ny), ca.SX.sym("w", nw), ca.SX.sym("p", npar), ca.SX.sym("s")
    X, hw = Y[:NX], Y[NX:]
    fa, ta, fb, tb, h = w[0:3], w[3:3 + n], w[3 + n:6 + n], w[6 + n:6 + 2 * n], w[6 + 2 * n]
    Jinv, At = ca.reshape(p[0:9], 3, 3), ca.reshape(p[9 + N_ACTUATOR:], 3, n)
    tau = ta + s * (tb - ta)
    f = act(X, ca.vertcat(fa + s * (fb - fa), ca.DM.zeros(3)), p[9:9 + N_ACTUATOR])[U_FORCE]
    _, _, _, Pi = split_state(X)
    u = ca.vertcat(f, moment_of_wheels(At, tau, hw, ca.mtimes(Jinv, Pi)))
    ode = h * ca.vertcat(eom(X, u, Jinv), tau)
    opts = {"reltol": RTOL, "abstol": ATOL, "max_num_steps": 100000, "min_step_size": MIN_STEP,
            "linear_multistep_method": "adams", "nonlinear_solver_iteration": "functional"}
    grid = [j / samples for j in range(1, samples + 1)]
    cv = ca.integrator("flight_wheel_cvodes", "cvodes", {"x": Y, "p": ca.vertcat(w, p), "t": s, "ode": ode}, 0.0, grid,
                       opts)
    Y0, wm, pm = ca.MX.sym("Y0", ny), ca.MX.sym("w", nw), ca.MX.sym("p", npar)
    Ys = cv(x0=Y0, p=ca.vertcat(wm, pm))["xf"]
    return ca.Function("flight_wheel_interval", [Y0, wm, pm], [Ys[:, -1], Ys], ["Y0", "w", "p"], ["Y1", "Ys"])


@dataclass
class WheelRecord:
    """What the wheels did in a flight: ``t`` (n_s,) sample times, ``h_w`` (n_s, n) momenta, ``torque_t`` (n_i, 2)
    and ``torque`` (n_i, 2, n) the torques at each interval's ends (affine between), the limits; and the peaks."""

    wheels: Wheels
    t: list = field(default_factory=list)
    h_w: list = field(default_factory=list)
    torque: list = field(default_factory=list)

    def peaks(self) -> tuple[np.ndarray, np.ndarray]:
        """(peak |tau_i|, peak |h_i|) (n,) each over the flight (torques affine: their peaks at the ends)."""
        return np.abs(np.array(self.torque)).max(axis=(0, 1)), np.abs(np.array(self.h_w)).max(axis=0)

    def summary(self) -> dict:
        """The flight's wheel figures (:func:`wheel_columns`): each wheel's peak torque and momentum as fractions of
        its limits, and the largest of each."""
        tau, hw = self.peaks()
        ft, fh = tau / self.wheels.torque_limit, hw / self.wheels.momentum_limit
        out = {"wheel_torque_used": float(ft.max()), "wheel_momentum_used": float(fh.max())}
        for i in range(self.wheels.n):
            out[f"wheel{i + 1}_torque_used"], out[f"wheel{i + 1}_momentum_used"] = float(ft[i]), float(fh[i])
        return out


def wheel_columns(n: int) -> tuple:
    """flights.csv's columns of a flight on n wheels (:meth:`WheelRecord.summary`)."""
    per = tuple(c for i in range(n) for c in (f"wheel{i + 1}_torque_used", f"wheel{i + 1}_momentum_used"))
    return ("wheel_torque_used", "wheel_momentum_used", *per)

