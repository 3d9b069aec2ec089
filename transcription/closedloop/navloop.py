"""The tracker fed by the estimator, flown in one call: the measurement, the estimator's update and prediction
(transcription.closedloop.estimator, docs/mathematics.md §12 *Navigation*) and the tracker's law (transcription.
closedloop.loop) evaluated inside the flight's CasADi Function, node interval by node interval, so that a navigated
flight is one ``mapaccum`` of CVODES intervals like a flight without navigation (a loop in C instead of a Python law
asked for each interval's command).

At node k, from the flown state X (the law's sensing: Pi -> J_law J_truth^-1 Pi) and the predicted estimate X^-, f^-:

    Y = X (+) (F n_k + c),   nu = Y (-) X^- - c^,   X^ = X^- (+) G_z,k nu,   f^ = f^- + G_f,k nu,   c^ <- c^ + G_c,k nu
                                                                                  (G_k = 0: no measurement; c the bias),
    z = X^ (-) X_k,    du = -K_k z - f_k - L_k (c_f Bu_k f^ + c_r (z - A_{k-1} z_{k-1} - Bu_{k-1} du_{k-1} - eps_{k-1})),
    X^-_{k+1} = X_{k+1} (+) (A_k z + Bu_k (du + f^) + eps_k),   f^-_{k+1} = f^,

with c_f = 1 / rho_k for the ekf (its disturbance beyond eps, the plan's local errors, which the tracker's feedforward f
answers: transcription.closedloop.tracking.Gains.with_local_errors) and c_r the tracker's own disturbance weight for
the raw measurement (estimator none).  The accumulated state is
S = [X (18); X^- (18); f^- (6); c^ (12); z_{k-1} (12); du_{k-1} (6)]; each interval also returns
e = X (-) X^ (12).  The same numbers as :class:`~transcription.closedloop.estimator.Navigated` with the
per-interval law (tested to 1e-10).  (+), (-): :func:`~transcription.closedloop.tracking.retract`, ``tangent_error``.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..dynamics.flight import N_P, N_W, BoundedCache
from ..geometry.state import NU, NX, NZ
from .estimator import N_STATE, NavigationFilter
from .loop import _F, N_G, TrackingLoop, symbolic_error, symbolic_retract, symbolic_sensed

#: the accumulated state and the per-interval data beyond the tracker's (N_G + 9: its law and vec(J_law)): X_{k+1} (18),
#: A_k (144), Bu_k (72), G_k (360), vec(F) (144), n_k (12), eps_k (12), the bias c (12), c_f, c_r
N_S = 2 * NX + NU + NZ + NZ + NU
N_E = NX + NZ * NZ + NZ * NU + N_STATE * NZ + NZ * NZ + 3 * NZ + 2


@dataclass(eq=False)
class NavigatedLoop:
    """The tracker's loop (``loop``: :class:`~transcription.closedloop.loop.TrackingLoop` of the plan's gains) fed by
    the estimator ``nav`` with the measurement noise factor F (12, 12), the run's standard normal draws (N, 12) and
    its constant measurement bias (12, tangent coordinates; None: 0).
    The flight engine flies it in one call (:meth:`flown`); ``errors`` (N, 12) after it: X (-) X^ at each node."""

    loop: TrackingLoop
    nav: NavigationFilter
    F: np.ndarray
    draws: np.ndarray
    bias: np.ndarray | None = None
    errors: np.ndarray | None = None

    def data(self) -> np.ndarray:
        """(N_G + N_E, N): the tracker's per-interval data (its own disturbance weight moved to c_r) and the
        estimator's, column k for interval k (matrices column-major; module docstring)."""
        nav, lp, N = self.nav, self.loop, self.nav.N
        law = lp.data()
        weight = law[-1].copy()
        law[-1] = 0.0
        cf = np.zeros(N) if nav.raw or not lp.disturbance else 1.0 / nav.rho
        cr = weight if nav.raw else np.zeros(N)
        flat = [np.asarray(M, float).transpose(0, 2, 1).reshape(N, -1) for M in (nav.A, nav.Bu, nav.G)]
        F = np.repeat(np.asarray(self.F, float).reshape(1, -1, order="F"), N, axis=0)
        bias = np.repeat(np.zeros((1, NZ)) if self.bias is None else np.reshape(self.bias, (1, NZ)), N, axis=0)
        return law, np.hstack([nav.Xref[1:], *flat, F, self.draws[:N], nav.eps, bias, cf[:, None], cr[:, None]]).T

    def flown(self, fn: ca.Function, X0: np.ndarray, h: np.ndarray, p: np.ndarray, law_inertia: np.ndarray):
        """As :meth:`TrackingLoop.flown` (start, end commands (6, N) each, samples Xs (N M, 18)); sets ``errors``."""
        N = h.size
        lp = self.loop
        W = np.vstack([lp.plan.start, lp.plan.end, h[None, :]])
        S0 = np.concatenate([X0, self.nav.Xref[0], np.zeros(NU + NZ + NZ + NU)])
        law, est = self.data()
        g = np.vstack([law, np.repeat(np.asarray(law_inertia, float).reshape(9, 1, order="F"), N, axis=1), est])
        _, Xs, cmd, e = _run(fn, N)(S0, W, g, np.repeat(p[:, None], N, axis=1))
        self.errors = e.full().T
        cmd = cmd.full()
        return cmd[:NU], cmd[NU:], Xs.full().T


def navigated_interval(fn: ca.Function) -> ca.Function:
    """``flight_navigated_interval(S[72], w[13], g[N_G + 9 + N_E], p[29]) -> (S1, Xs[18 x M], cmd[12], e[12])``: one
    node interval of the navigated loop (module docstring) around the engine's ``flight_interval`` ``fn``."""
    S, w, g, p = ca.MX.sym("S", N_S), ca.MX.sym("w", N_W), ca.MX.sym("g", N_G + 9 + N_E), ca.MX.sym("p", N_P)
    X, Xm, fm = S[0:NX], S[NX:2 * NX], S[2 * NX:2 * NX + NU]
    o = 2 * NX + NU
    cm, zp, dup = S[o:o + NZ], S[o + NZ:o + 2 * NZ], S[o + 2 * NZ:]
    Xr, o = g[0:NX], NX
    K, L = ca.reshape(g[o:o + NU * NZ], NU, NZ), ca.reshape(g[o + NU * NZ:o + 2 * NU * NZ], NU, NZ)
    o += 2 * NU * NZ
    Ap, Bp = ca.reshape(g[o:o + NZ * NZ], NZ, NZ), ca.reshape(g[o + NZ * NZ:o + NZ * NZ + NZ * NU], NZ, NU)
    f, ep = g[_F:_F + NU], g[_F + NU:_F + NU + NZ]
    Xs_ = symbolic_sensed(X, g[N_G:N_G + 9], p[0:9])
    o = N_G + 9
    Xr1, o = g[o:o + NX], o + NX
    A, o = ca.reshape(g[o:o + NZ * NZ], NZ, NZ), o + NZ * NZ
    Bu, o = ca.reshape(g[o:o + NZ * NU], NZ, NU), o + NZ * NU
    G, o = ca.reshape(g[o:o + N_STATE * NZ], N_STATE, NZ), o + N_STATE * NZ
    F, o = ca.reshape(g[o:o + NZ * NZ], NZ, NZ), o + NZ * NZ
    n, eps, c, cf, cr = g[o:o + NZ], g[o + NZ:o + 2 * NZ], g[o + 2 * NZ:o + 3 * NZ], g[o + 3 * NZ], g[o + 3 * NZ + 1]
    Y = symbolic_retract(Xs_, ca.mtimes(F, n) + c)
    nu = symbolic_error(Y, Xm) - cm
    Xh, fh = symbolic_retract(Xm, ca.mtimes(G[0:NZ, :], nu)), fm + ca.mtimes(G[NZ:NZ + NU, :], nu)
    ch = cm + ca.mtimes(G[NZ + NU:, :], nu)
    z = symbolic_error(Xh, Xr)
    r = cf * ca.mtimes(Bu, fh) + cr * (z - ca.mtimes(Ap, zp) - ca.mtimes(Bp, dup) - ep)
    du = -ca.mtimes(K, z) - f - ca.mtimes(L, r)
    a, b = w[0:NU] + du, w[NU:2 * NU] + du
    X1, Xs = fn(X, ca.vertcat(a, b, w[2 * NU]), p)
    Xm1 = symbolic_retract(Xr1, ca.mtimes(A, z) + ca.mtimes(Bu, du + fh) + eps)
    return ca.Function("flight_navigated_interval", [S, w, g, p],
                       [ca.vertcat(X1, Xm1, fh, ch, z, du), Xs, ca.vertcat(a, b), symbolic_error(Xs_, Xh)],
                       ["S", "w", "g", "p"], ["S1", "Xs", "cmd", "e"])


_RUNS = BoundedCache()


def _run(fn: ca.Function, N: int) -> ca.Function:
    """:func:`navigated_interval` accumulated over N intervals (one call), built once per (integrator, N)."""
    return _RUNS.get((id(fn), N), lambda: navigated_interval(fn).mapaccum(f"flight_navigated_run{N}", N), keep=fn)
