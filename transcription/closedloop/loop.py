"""A tracking loop flown in one call: the tracker's law (docs/mathematics.md §12) evaluated inside the flight's
CasADi Function, node interval by node interval, so that a whole closed-loop flight is one ``mapaccum`` of
CVODES intervals (a loop in C) instead of a Python loop asking a law for each interval's command.

The law is :class:`transcription.closedloop.tracking.Tracker`'s without saturation (an unbounded plan): at node k,
from the flown state X_k,

    z_k = [x - x_k; gamma - gamma_k; vee log(R_k^T R); J_law Omega - Pi_k]    (tangent_error, log by atan2),
    r_k = z_k - A_{k-1} z_{k-1} - Bu_{k-1} du_{k-1} - eps_{k-1}   (r_0 = 0),     du_k = -K_k z_k - f_k - L_k r_k / rho_{k-1},

with Omega = J_truth^-1 Pi the measured rate and J_law the inertia the law believes (the plan's: the rate is
tracked, transcription.dynamics.flight.sensed), eps and f the plan's known local errors and their feedforward (0
without them; transcription.closedloop.tracking.Gains.with_local_errors), rho_{k-1} = h_{k-1} / h (1 on a uniform
mesh), and the interval's command is (a_k + du_k, b_k + du_k).  The accumulated state is
S = [X (18); z_{k-1} (12); du_{k-1} (6)].  The same numbers as the per-interval path (tested to 1e-10 relative); the
attitude error is taken below ~0.9 pi (:func:`~transcription.geometry.so3.log_so3_small`).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..geometry.state import NU, NX, NZ, X_ANG, X_MOM, X_POS, X_ROT
from ..geometry.so3 import exp_so3, log_so3_small
from ..dynamics.flight import N_P, N_W, BoundedCache, OpenLoop

#: per-interval data of the law: X_k (18), K_k (6 x 12), L_k (6 x 12), A_{k-1} (12 x 12), Bu_{k-1} (12 x 6), f_k (6),
#: eps_{k-1} (12), the weight of the disturbance term (0 at k = 0 or without it, else 1 / rho_{k-1}: 1 on a uniform mesh)
N_G = NX + 2 * NU * NZ + NZ * NZ + NZ * NU + NU + NZ + 1
#: where f_k starts in the law's data
_F = NX + 2 * NU * NZ + NZ * NZ + NZ * NU
N_S = NX + NZ + NU


def symbolic_error(X, Xr):
    """X (-) Xr (12) of two symbolic states (18): :func:`~transcription.closedloop.tracking.tangent_error` with the
    attitude's log taken by :func:`~transcription.geometry.so3.log_so3_small` (below ~0.9 pi)."""
    R, Rr = ca.reshape(X[X_ROT], 3, 3), ca.reshape(Xr[X_ROT], 3, 3)
    return ca.vertcat(X[X_POS] - Xr[X_POS], X[X_MOM] - Xr[X_MOM], log_so3_small(ca.mtimes(Rr.T, R)), X[X_ANG] - Xr[X_ANG])


def symbolic_retract(Xr, z):
    """Xr (+) z (18) of a symbolic state (18) and tangent vector (12): :func:`~transcription.closedloop.tracking.retract`."""
    R = ca.mtimes(ca.reshape(Xr[X_ROT], 3, 3), exp_so3(z[6:9]))
    return ca.vertcat(Xr[X_POS] + z[0:3], Xr[X_MOM] + z[3:6], ca.reshape(R, 9, 1), Xr[X_ANG] + z[9:12])


def symbolic_sensed(X, J_law, Jinv):
    """The state (18) a law reads from the symbolic truth state X: its Pi replaced by J_law J_truth^-1 Pi
    (transcription.dynamics.flight.sensed), J_law and J_truth^-1 given column-major (9 each)."""
    return ca.vertcat(X[0:X_ANG.start], ca.mtimes(ca.reshape(J_law, 3, 3), ca.mtimes(ca.reshape(Jinv, 3, 3), X[X_ANG])))


@dataclass(frozen=True, eq=False)
class TrackingLoop:
    """The tracker's law as data (module docstring): ``plan`` the plan's commands, ``Xref`` (N+1, 18) its nodes,
    K, L (N, 6, 12), A (N, 12, 12), Bu (N, 12, 6) (transcription.closedloop.tracking.Gains), ``disturbance``: with the
    disturbance estimate r_k; ``rho`` (N,): the relative step sizes h_k / h of a non-uniform mesh (None: uniform).
    The flight engine flies it in one call (:meth:`flown`)."""

    plan: OpenLoop
    Xref: np.ndarray
    K: np.ndarray
    L: np.ndarray
    A: np.ndarray
    Bu: np.ndarray
    disturbance: bool = True
    rho: np.ndarray | None = None
    f: np.ndarray | None = None
    eps: np.ndarray | None = None

    @classmethod
    def of_gains(cls, gains, disturbance: bool = True) -> "TrackingLoop":
        """The loop of a tracker's gains (transcription.closedloop.tracking.Gains) around its plan."""
        return cls(OpenLoop.of_controls(gains.scheme, gains.U), gains.X, gains.K, gains.L, gains.A, gains.Bu,
                   disturbance, gains.rho, gains.f, gains.eps)

    def data(self) -> np.ndarray:
        """(N_G, N): the per-interval data, column k for interval k (matrices column-major)."""
        N = self.K.shape[0]
        Ap, Bp = np.zeros_like(self.A), np.zeros_like(self.Bu)
        Ap[1:], Bp[1:] = self.A[:-1], self.Bu[:-1]
        flat = [np.asarray(M, float).transpose(0, 2, 1).reshape(N, -1) for M in (self.K, self.L, Ap, Bp)]
        f = np.zeros((N, NU)) if self.f is None else np.asarray(self.f, float)
        ep = np.zeros((N, NZ))
        if self.eps is not None:
            ep[1:] = np.asarray(self.eps, float)[:-1]
        weight = np.where(np.arange(N) > 0, 1.0 if self.disturbance else 0.0, 0.0)[:, None]
        if self.rho is not None:          # r_k came from step k-1: per mean step, r_k / rho_{k-1}
            weight[1:, 0] /= np.asarray(self.rho, float)[:-1]
        return np.hstack([np.asarray(self.Xref, float)[:N], *flat, f, ep, weight]).T

    def flown(self, fn: ca.Function, X0: np.ndarray, h: np.ndarray, p: np.ndarray, law_inertia: np.ndarray):
        """Fly the loop with the engine's interval integrator ``fn`` (``flight_interval``) from X0 over steps h
        (N,) with flight parameters p, the law knowing its body by ``law_inertia`` (3x3; the error of the angular
        momentum is J_law (Omega - Omega_k), Omega = J_truth^-1 Pi the measured rate, transcription.dynamics.flight.
        sensed): (start, end) commands (6, N) each and the samples Xs (N M, 18)."""
        N = h.size
        run = _loop_run(fn, N)
        W = np.vstack([self.plan.start, self.plan.end, h[None, :]])
        S0 = np.concatenate([X0, np.zeros(NZ + NU)])
        g = np.vstack([self.data(), np.repeat(np.asarray(law_inertia, float).reshape(9, 1, order="F"), N, axis=1)])
        _, Xs, cmd = run(S0, W, g, np.repeat(p[:, None], N, axis=1))
        cmd = cmd.full()
        return cmd[:NU], cmd[NU:], Xs.full().T


def tracking_interval(fn: ca.Function) -> ca.Function:
    """``flight_tracking_interval(S[36], w[13], g[N_G + 9], p[29]) -> (S1[36], Xs[18 x M], cmd[12])``: one node
    interval of the loop (module docstring) around the engine's ``flight_interval`` ``fn``: w = [a; b; h] the
    plan's command, g the law's data of the interval (:meth:`TrackingLoop.data`) and vec(J_law) (column-major),
    cmd = [a + du; b + du]."""
    S, w, g, p = ca.MX.sym("S", N_S), ca.MX.sym("w", N_W), ca.MX.sym("g", N_G + 9), ca.MX.sym("p", N_P)
    X, zp, dup = S[0:NX], S[NX:NX + NZ], S[NX + NZ:]
    Xr = g[0:NX]
    o = NX
    K, L = ca.reshape(g[o:o + NU * NZ], NU, NZ), ca.reshape(g[o + NU * NZ:o + 2 * NU * NZ], NU, NZ)
    o += 2 * NU * NZ
    A, Bu = ca.reshape(g[o:o + NZ * NZ], NZ, NZ), ca.reshape(g[o + NZ * NZ:o + NZ * NZ + NZ * NU], NZ, NU)
    f, ep = g[_F:_F + NU], g[_F + NU:_F + NU + NZ]
    z = symbolic_error(symbolic_sensed(X, g[N_G:], p[0:9]), Xr)            # the error of J_law Omega (sensed)
    r = z - ca.mtimes(A, zp) - ca.mtimes(Bu, dup) - ep
    du = -ca.mtimes(K, z) - f - g[N_G - 1] * ca.mtimes(L, r)
    a, b = w[0:NU] + du, w[NU:2 * NU] + du
    X1, Xs = fn(X, ca.vertcat(a, b, w[2 * NU]), p)
    return ca.Function("flight_tracking_interval", [S, w, g, p], [ca.vertcat(X1, z, du), Xs, ca.vertcat(a, b)],
                       ["S", "w", "g", "p"], ["S1", "Xs", "cmd"])


_RUNS = BoundedCache()


def _loop_run(fn: ca.Function, N: int) -> ca.Function:
    """:func:`tracking_interval` accumulated over N intervals (one call), built once per (integrator, N)."""
    return _RUNS.get((id(fn), N), lambda: tracking_interval(fn).mapaccum(f"flight_tracking_run{N}", N), keep=fn)
