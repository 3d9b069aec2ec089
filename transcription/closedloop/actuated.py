"""A control law flown through real actuators (docs/mathematics.md §11): the force by on/off thrusters
(transcription.closedloop.pulses) and the moment by reaction wheels (transcription.dynamics.wheels), either or both,
one control period (node interval) at a time.

Each period: the law's command (a, b) from the state it senses at t_k; the pulse of the force command (or the affine
force itself); the wheels' torques from the moment command (or the affine moment itself, through the actuators'
moment model); the period flown as its parts between the pulse's edges, CVODES restarted at each; a tracker told what
was delivered (:meth:`~transcription.closedloop.tracking.Tracker.delivered`: the impulse carried or cut, the moment the
wheels' limits withheld, as a difference held over the step).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dynamics.flight import (DEFAULT_SAMPLES, Actuators, Flight, FlightError, flight_record, interval_integrator,
                               law_sensing, node_grid, sensed)
from ..dynamics.wheels import WheelController, WheelRecord, Wheels, moment_of_wheels, wheel_integrator
from ..geometry.state import NU, NX, U_FORCE, U_MOMENT, X_ANG
from .pulses import Modulator, Pulse, Pulses, segments


@dataclass
class Actuated:
    """A flight through real actuators: the Flight (its intervals the periods' parts, every node time among its
    samples; its controls the applied force and the moment on the body), the pulses' Modulator and the wheels'
    WheelRecord and WheelController (None where not flown)."""

    flight: Flight
    pulses: Modulator | None = None
    wheels: WheelRecord | None = None
    controller: WheelController | None = None

    def summary(self) -> dict:
        """The actuators' figures of the flight (pulses and wheels, :data:`PULSE_COLUMNS`, ``wheel_columns``)."""
        out = {} if self.pulses is None else self.pulses.summary(self.flight.mass)
        return out if self.wheels is None else {**out, **self.wheels.summary()}


def _parts(a_f, b_f, pulse: Pulse | None):
    """(s_lo, s_hi, force at s_lo, force at s_hi) of a period: the pulse's off/on/off parts, or the whole period."""
    if pulse is None:
        return [(0.0, 1.0, a_f, b_f)]
    return [(lo, hi, f, f) for lo, hi, f in segments(pulse)]


def fly_actuated(model, X0: np.ndarray, times: np.ndarray, law, pulses: Pulses | None = None,
                 wheels: Wheels | None = None, actuators: Actuators | None = None, samples: int = DEFAULT_SAMPLES,
                 disturbance=None, law_inertia: np.ndarray | None = None, tracker=None,
                 wheel_axes: np.ndarray | None = None, h_w0: np.ndarray | None = None) -> Actuated:
    """Fly ``law`` (per interval: ``commands(k, t_k, X) -> (a, b)``) from X0 (18,) over the node grid ``times`` as
    :func:`~transcription.dynamics.flight.fly` does (truth ``model``, force ``actuators``, ``disturbance``, the law
    reading the rate through ``law_inertia``), the force by ``pulses`` and the moment by ``wheels`` (the flight
    software's, nominal axes) whose truth axes are ``wheel_axes`` (3, n; default the nominal), their momenta from
    ``h_w0`` (n,; default 0).  Raises FlightError if the integrator fails."""
    (times, h), Xk = node_grid(times), np.asarray(X0, float).reshape(NX)
    M = int(samples)
    Jinv, J_law = law_sensing(model, law_inertia)
    q = (actuators or Actuators()).vector()
    mod = None if pulses is None else Modulator(pulses)
    if wheels is None:
        fn, pv, hw = interval_integrator(model, M, disturbance=disturbance), np.concatenate([Jinv.ravel("F"), q]), None
    else:
        At = np.asarray(wheels.axes if wheel_axes is None else wheel_axes, float)
        fn = wheel_integrator(model, wheels.n, M, disturbance)
        pv = np.concatenate([Jinv.ravel("F"), q, At.ravel("F")])
        hw = np.zeros(wheels.n) if h_w0 is None else np.asarray(h_w0, float).reshape(wheels.n)
        ctl, rec = WheelController(wheels), WheelRecord(wheels, h_w=[hw.copy()])
    A, B, out, edges, taus = [], [], [], [times[0]], []
    try:
        for k in range(h.size):
            a, b = (np.asarray(c, float).reshape(NU) for c in law.commands(k, float(times[k]), sensed(Xk, J_law, Jinv)))
            pulse = None if mod is None else mod.period(a[U_FORCE], b[U_FORCE], h[k])
            extra = np.zeros(NU)
            if pulse is not None:
                extra[U_FORCE] = (pulse.delivered - pulse.commanded) / h[k]
            if hw is not None:
                Om = Jinv @ Xk[X_ANG]
                ta, tb = ctl.period(a[U_MOMENT], b[U_MOMENT], hw, Om, h[k])
                g = np.cross(wheels.axes @ hw, Om)
                extra[U_MOMENT] = g - wheels.axes @ (0.5 * (ta + tb)) - 0.5 * (a[U_MOMENT] + b[U_MOMENT])
            if tracker is not None and extra.any():
                tracker.delivered(extra)
            for lo, hi, fa, fb in _parts(a[U_FORCE], b[U_FORCE], pulse):
                ml, mh = (a[U_MOMENT] + s * (b[U_MOMENT] - a[U_MOMENT]) for s in (lo, hi))
                if hw is None:
                    w = np.concatenate([fa, ml, fb, mh, [h[k] * (hi - lo)]])
                else:                                  # the moment is the wheels' torques' (the command recorded)
                    tl, th = (ta + s * (tb - ta) for s in (lo, hi))
                    w = np.concatenate([fa, tl, fb, th, [h[k] * (hi - lo)]])
                    taus.append((tl, th))
                Y1, Ys = fn(np.concatenate([Xk, [] if hw is None else hw]), w, pv)
                Ys = Ys.full().T
                A.append(np.concatenate([fa, ml]))
                B.append(np.concatenate([fb, mh]))
                out.append(Ys[:, :NX])
                Xk = Y1.full().ravel()[:NX]
                if hw is not None:
                    hw = Y1.full().ravel()[NX:]
                    rec.h_w.extend(Ys[:, NX:])
                    rec.torque.append(np.array([tl, th]))
                edges.append(times[k + 1] if hi >= 1.0 else times[k] + h[k] * hi)
    except RuntimeError as e:
        raise FlightError(f"the continuous flight failed (CVODES): {str(e).strip().splitlines()[-1]}") from None
    A, B, edges, Xs = np.array(A).T, np.array(B).T, np.array(edges), np.vstack(out)
    moment = None if hw is None else _wheel_moments(np.vstack([np.asarray(X0, float).reshape(1, NX), Xs]),
                                                    np.array(rec.h_w), taus, M, At, Jinv)
    flight = flight_record(model, edges, X0, Xs, A, B, M, q, moment)
    if hw is not None:
        rec.t = flight.t
    return Actuated(flight, mod, rec if hw is not None else None, ctl if hw is not None else None)


def _wheel_moments(X, h_w, taus, M, At, Jinv) -> np.ndarray:
    """(n_i, M+1, 3) the wheels' moment on the body u_w = -A_t tau + (A_t h_w) x Omega at each interval's samples."""
    s = np.arange(M + 1) / M
    out = np.zeros((len(taus), M + 1, 3))
    for i, (tl, th) in enumerate(taus):
        for j in range(M + 1):
            idx = i * M + j
            Om = Jinv @ X[idx, X_ANG]
            out[i, j] = moment_of_wheels(At, tl + s[j] * (th - tl), h_w[idx], Om)
    return out
