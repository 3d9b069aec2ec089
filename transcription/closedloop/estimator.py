"""Navigation: noisy measurements of the flown state and the estimator between them and the tracker
(docs/mathematics.md §12, *Navigation*).

Measurement (every node k in ``measured``; each error 1-sigma, Gaussian, independent): the state the law senses
(transcription.dynamics.flight.sensed) with

    x + n_x,   gamma + m n_v,   R Exp(n_theta) (body frame),   Pi + J n_omega   (the rate Omega + n_omega; J the law's),

i.e. Y = X (+) (F n + c), n ~ N(0, I_12), F = blockdiag(s_x I, m s_v I, s_theta I, s_omega J) (:func:`noise_factor`),
the measurement covariance R_y = F F^T, and c (12) a constant bias of the run (prior covariance P_c; 0 without).  (+) and (-) are :func:`~transcription.closedloop.tracking.retract` and
:func:`~transcription.closedloop.tracking.tangent_error`: additive on x, gamma, Pi, R = R_ref Exp(zeta) (body).

Estimator ``ekf``: a multiplicative extended Kalman filter on R^6 x SO(3) x R^3 with a disturbance.  The estimate
is a state X^ (18, R^ a rotation matrix) and f^ (6), a persisting force (inertial) and moment (body) the plan's
linearization does not explain (thrust errors, unmodelled gravity); the error e = X (-) X^ (12; attitude: delta theta
in the estimate's body frame, R = R^ Exp(delta theta)), f - f^ and the bias's c - c^ (c^ constant) have covariance P
(30 x 30).  With the plan's own
maps A_k, Bu_k (transcription.closedloop.tracking.Gains; Bu_k: a control held over step k) and rho_k = h_k / h:

    predict   z^ = X^_k (-) X_k,   X^-_{k+1} = X_{k+1} (+) (A_k z^ + Bu_k (du_k + f^_k) + eps_k),   f^-_{k+1} = f^_k,
              P^-_{k+1} = Phi_k P_k Phi_k^T + rho_k blockdiag(Q_z,k, Q_f, 0),   Phi_k = [[A_k, Bu_k, 0], [0, I, 0], [0, 0, I]],
    update    nu = Y_k (-) X^-_k - c^,   S = H P^- H^T + R_y,   G = P^- H^T S^-1   (30 x 12),
              X^_k = X^-_k (+) G_z nu,   f^_k = f^-_k + G_f nu,   c^ += G_c nu,
              P_k = (I - G H) P^- (I - G H)^T + G R_y G^T (Joseph),

H = [I 0 I] (a bias is observable only through the dynamics: the rate's through the attitude); eps_k (12) is the plan's local error, X(t_{k+1}) (-) X_{k+1} of the continuous flight of the plan's body over
step k from its node X_k (:func:`local_errors`): the plan is exact for its discrete equations, not for the continuous
ones the truth follows, and the per-step difference is known before the flight.  The tracker reads X^_k and the
disturbance r^_k = Bu_k f^_k / rho_k (per mean step, its r); the local errors reach it as its own feedforward (the
same eps in its gains: transcription.closedloop.tracking.Gains.with_local_errors).  The
Jacobians are the plan's (the linearization about the plan, equal to the estimate's to first order in their
distance), so the covariances and gains do not depend on the measurements: computed once per plan
(:func:`navigation_filter`).  A component measured without noise or bias is taken as measured (its row of G_z the
identity); with neither at all the tracker reads the measurement, i.e. the flown state, and estimates its
disturbance itself, as without navigation.  Default process noise (:func:`plan_filter`): f a random walk drifting by
a tenth of the tracker's characteristic controls over the horizon, and the state wandering beyond it by 1 % of a
measurement's 1-sigma per step plus each step's local error squared (eps_k is the continuous step's from the plan's
node, not from the flown state: known to about its own size; docs/mathematics.md §12).

Estimator ``none``: the tracker reads the measurement itself (X^ = Y), and between measurements the last one
carried forward by the plan's linearization (G = [I; 0]: P is the covariance of that); the tracker estimates its
disturbance from the measurements itself.

Shapes: Xref (N+1, 18), A (N, 12, 12), Bu (N, 12, 6), rho (N,), measured (N,) bool, G (N, 30, 12), P (N, 30, 30),
eps (N, 12).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..dynamics.flight import Actuators, OpenLoop, interval_integrator
from ..geometry.state import NU, NX, NZ
from .tracking import retract, tangent_error

#: estimators: a multiplicative EKF, or the raw measurement
ESTIMATORS = ("ekf", "none")
#: the estimator's state: the error e (12), the disturbance f (6), the measurements' constant bias c (12)
N_STATE = NZ + NU + NZ


def noise_factor(sigmas, mass: float, inertia: np.ndarray) -> np.ndarray:
    """F (12, 12) (module docstring) of 1-sigma ``sigmas`` = (position, velocity, attitude (rad, body), rate (rad per
    time unit, body)) for a body of ``mass`` whose law knows its inertia as ``inertia`` (3x3): R_y = F F^T."""
    sx, sv, sa, sw = (float(s) for s in sigmas)
    F = np.zeros((NZ, NZ))
    F[0:3, 0:3], F[3:6, 3:6], F[6:9, 6:9] = sx * np.eye(3), mass * sv * np.eye(3), sa * np.eye(3)
    F[9:12, 9:12] = sw * np.asarray(inertia, float)
    return F


def measure(X: np.ndarray, F: np.ndarray, n: np.ndarray, bias: np.ndarray | None = None) -> np.ndarray:
    """Y (18,): the state X (18,) measured with the standard normal draws n (12,) and a constant ``bias`` c (12, in
    tangent coordinates; None: 0): X (+) (F n + c)."""
    return retract(X, F @ n + (0.0 if bias is None else np.asarray(bias, float)))


def measurement_nodes(t: np.ndarray, period: float | None) -> np.ndarray:
    """(N,) bool: the nodes t_0..t_{N-1} (of t (N+1,)) at which a measurement is taken, the first node at or after
    each multiple of ``period`` from t_0 (None: every node)."""
    t = np.asarray(t, float)
    if period is None:
        return np.ones(t.size - 1, bool)
    slot = np.floor((t[:-1] - t[0]) / period * (1 + 1e-12) + 1e-9).astype(np.int64)
    return np.r_[True, slot[1:] > slot[:-1]]


@dataclass(frozen=True, eq=False)
class NavigationFilter:
    """The estimator of one plan (module docstring): its nodes Xref, maps A, Bu, step ratios rho, the nodes
    ``measured``, the gains G (N, 30, 12) and posterior covariances P (N, 30, 30) of [e; f; c] at each node (G = 0
    where nothing is measured), R_y (12, 12), ``estimator`` ('ekf' or 'none'), the local errors eps (N, 12), ``raw``:
    the tracker reads the measurement itself (the estimator 'none', or neither noise nor bias: X^ = Y = X); ``exact``
    (12,) bool: the components measured with neither noise nor bias."""

    Xref: np.ndarray
    A: np.ndarray
    Bu: np.ndarray
    rho: np.ndarray
    measured: np.ndarray
    G: np.ndarray
    P: np.ndarray
    Ry: np.ndarray
    estimator: str = "ekf"
    eps: np.ndarray | None = None
    raw: bool = False
    exact: np.ndarray | None = None

    @property
    def N(self) -> int:
        return self.A.shape[0]

    @cached_property
    def information(self) -> np.ndarray:
        """(N, 12, 12): the pseudo-inverse of each node's P_zz (the NEES e^T P_zz^+ e of an error e)."""
        return np.linalg.pinv(self.P[:, :NZ, :NZ], rcond=1e-13, hermitian=True)

    def nees(self, errors: np.ndarray) -> np.ndarray:
        """(n,): e_k^T P_zz,k^+ e_k of the errors (n, 12) at the first n nodes (12 degrees of freedom when the
        estimator is consistent; fewer with components measured without noise)."""
        e = np.asarray(errors, float)
        return np.einsum("ki,kij,kj->k", e, self.information[:len(e)], e)


def navigation_filter(Xref, A, Bu, rho, Ry, P0, Qz, Qf, measured, estimator: str = "ekf",
                      eps: np.ndarray | None = None, Pc: np.ndarray | None = None) -> NavigationFilter:
    """The estimator's gains and covariances (module docstring) for the plan's nodes Xref (N+1, 18), maps A (N, 12,
    12), Bu (N, 12, 6), step ratios rho (N,), measurement covariance Ry (12, 12), prior P0 (18, 18) of [e; f] at
    node 0, process noise per mean step Qz (12, 12, or (N, 12, 12) step by step) and Qf (6, 6) (scaled by rho_k),
    measured (N,) bool; ``eps`` (N, 12): the plan's local errors (:func:`local_errors`; None: none); ``Pc`` (12, 12):
    the prior of the measurements' constant bias c (None: no bias)."""
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}")
    A, Bu, rho, Ry = np.asarray(A, float), np.asarray(Bu, float), np.asarray(rho, float), np.asarray(Ry, float)
    N, n = A.shape[0], N_STATE
    H = np.hstack([np.eye(NZ), np.zeros((NZ, NU)), np.eye(NZ)])
    G, P = np.zeros((N, n, NZ)), np.zeros((N, n, n))
    Qz = np.broadcast_to(np.asarray(Qz, float), (N, NZ, NZ))
    Q = np.zeros((n, n))
    Q[NZ:NZ + NU, NZ:NZ + NU] = Qf
    Pm = np.zeros((n, n))
    Pm[:NZ + NU, :NZ + NU] = P0
    Pm[NZ + NU:, NZ + NU:] = 0.0 if Pc is None else Pc
    raw = estimator == "none" or not (np.any(Ry) or np.any(Pm[NZ + NU:, NZ + NU:]))
    exact = (np.diag(Ry) == 0.0) & (np.diag(Pm)[NZ + NU:] == 0.0)
    for k in range(N):
        if measured[k]:
            G[k] = H.T * (np.arange(n) < NZ)[:, None] if raw else _gain(Pm, Ry, H, exact)
            IGH = np.eye(n) - G[k] @ H
            P[k] = IGH @ Pm @ IGH.T + G[k] @ Ry @ G[k].T
        else:
            P[k] = Pm
        Phi = np.eye(n)
        Phi[:NZ, :NZ] = A[k]
        if not raw:
            Phi[:NZ, NZ:NZ + NU] = Bu[k]
        Q[:NZ, :NZ] = Qz[k]
        Pm = Phi @ P[k] @ Phi.T + rho[k] * Q
        Pm = 0.5 * (Pm + Pm.T)
    eps = np.zeros((N, NZ)) if eps is None else np.asarray(eps, float).reshape(N, NZ)
    return NavigationFilter(np.asarray(Xref, float), A, Bu, rho, np.asarray(measured, bool), G, P, Ry, estimator, eps,
                            bool(raw), exact)


def _gain(Pm: np.ndarray, Ry: np.ndarray, H: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """G (30, 12) = P^- H^T (H P^- H^T + Ry)^+, the pseudo-inverse in the metric of its diagonal (a component known
    exactly and measured without noise or bias adds nothing), and the rows of the components measured exactly (no
    noise, no bias) the identity (they are taken as measured)."""
    PH = Pm @ H.T
    S = H @ PH + Ry
    s = np.sqrt(np.diag(S))
    s[s == 0] = 1.0
    G = (PH / s) @ np.linalg.pinv(S / np.outer(s, s), rcond=1e-13, hermitian=True) / s
    E = np.flatnonzero(exact)
    G[E, :] = 0.0
    G[E, E] = 1.0
    return G


class Estimator:
    """The estimator of one flight (module docstring), asked in order k = 0, 1, ..., N-1: :meth:`estimate` with the
    measurement of node k (or None where none is taken) -> (X^_k, the disturbance r^_k per mean step the tracker
    reads, or None where the tracker estimates its own), then :meth:`predict` with the correction du_k issued.
    ``c``: the bias estimate c^ (12)."""

    def __init__(self, nav: NavigationFilter):
        self.nav, self.k = nav, 0
        self.Xm, self.fm, self.c = np.asarray(nav.Xref[0], float).copy(), np.zeros(NU), np.zeros(NZ)
        self.X = self.f = None

    def estimate(self, k: int, Y: np.ndarray | None):
        """(X^_k (18,), r^_k (12,) or None) from the measurement Y (18,) of node k (module docstring)."""
        nav = self.nav
        if k != self.k:
            raise ValueError(f"Estimator: expected node {self.k}, got {k}")
        X, f = self.Xm, self.fm
        if nav.measured[k] and Y is not None:
            if nav.raw:
                X = np.asarray(Y, float).reshape(NX).copy()
            else:
                nu = tangent_error(Y, self.Xm) - self.c
                X, f = retract(self.Xm, nav.G[k, :NZ] @ nu), self.fm + nav.G[k, NZ:NZ + NU] @ nu
                self.c = self.c + nav.G[k, NZ + NU:] @ nu
        self.X, self.f = X, f
        return X, (None if nav.raw else nav.Bu[k] @ f / nav.rho[k])

    def predict(self, du: np.ndarray) -> None:
        """Carry the estimate to node k+1 by the plan's linearization under the correction du (6,) issued at k."""
        nav, k = self.nav, self.k
        z = tangent_error(self.X, nav.Xref[k])
        z1 = nav.A[k] @ z + nav.Bu[k] @ (np.asarray(du, float).reshape(NU) + self.f) + nav.eps[k]
        self.Xm, self.fm, self.k = retract(nav.Xref[k + 1], z1), self.f, k + 1

    def error(self, X: np.ndarray) -> np.ndarray:
        """e (12,) = X (-) X^ of the current estimate from the state X (18,) it estimates."""
        return tangent_error(X, self.X)


def plan_filter(gains, F: np.ndarray, P0: np.ndarray, measured: np.ndarray, estimator: str = "ekf",
                drift: float = 0.1, wander: float = 0.01, eps: np.ndarray | None = None,
                Pc: np.ndarray | None = None) -> NavigationFilter:
    """The estimator of a tracker's plan (transcription.closedloop.tracking.Gains: its nodes, maps, steps) for the
    measurement noise factor F (12, 12; :func:`noise_factor`), the prior P0 (12, 12) of the initial state's error
    from the plan's first node and the nodes ``measured`` (N,), with the default process noise (module docstring):
    the disturbance f a random walk of ``drift`` times the tracker's characteristic controls u_c (its weights'
    scales) over the horizon T, Q_f = diag(drift u_c)^2 h / T, its prior diag(drift u_c)^2; the state's own
    Q_z,k = wander^2 R_y + diag(eps_k)^2 / rho_k per mean step (it wanders by ``wander`` of a measurement's 1-sigma
    per step beyond f, and the local error is known to about its own size); ``eps``: the plan's local errors
    (:func:`local_errors`; None: none); ``Pc``: the prior of the measurements' constant bias (None: none)."""
    Ry = F @ F.T
    sc = gains.weights.scales
    uc = np.concatenate([sc["force"], sc["moment"]]) * drift
    prior = np.zeros((NZ + NU, NZ + NU))
    prior[:NZ, :NZ], prior[NZ:, NZ:] = np.asarray(P0, float), np.diag(uc**2)
    rho = np.ones(gains.N) if gains.rho is None else gains.rho
    Qz = wander**2 * Ry + (0.0 if eps is None else np.einsum("ki,ij->kij", np.asarray(eps) ** 2, np.eye(NZ)) / rho[:, None, None])
    return navigation_filter(gains.X, gains.A, gains.Bu, rho, Ry, prior, Qz, np.diag(uc**2) * gains.h / sc["T"],
                             measured, estimator, eps, Pc)


def local_errors(gains, model, force_frame: str = "inertial", samples: int = 1) -> np.ndarray:
    """eps (N, 12): each step's local error, X(t_{k+1}) (-) X_{k+1} of the continuous flight of the plan's body
    ``model`` (transcription.dynamics.flight) over step k from the plan's node X_k under the plan's commands (nominal
    actuators; ``force_frame`` the plan's), against the plan's node X_{k+1}: what the plan's discrete map, and so A_k,
    leaves out of each step (its own discretization error).  One mapped call of the engine's interval integrator."""
    fn = interval_integrator(model, samples)
    plan = OpenLoop.of_controls(gains.scheme, gains.U)
    N, h = gains.N, np.diff(gains.t)
    p = np.concatenate([np.linalg.inv(model.inertia).ravel(order="F"), Actuators(force_frame=force_frame).vector()])
    X1, _ = fn.map(N)(gains.X[:-1].T, np.vstack([plan.start, plan.end, h[None, :]]), np.repeat(p[:, None], N, axis=1))
    X1 = np.asarray(X1.full()).T
    return np.array([tangent_error(X1[k], gains.X[k + 1]) for k in range(N)])


class Navigated:
    """The tracker fed by the estimator, as the correction of a transcription.dynamics.flight.ClosedLoop: at node k
    the sensed state X (18,) is measured with the draws ``draws[k]`` (N, 12 standard normals) and the run's constant
    ``bias`` (12; None: 0), estimated, the tracker's correction du_k computed from X^_k (and its disturbance), and the
    estimate carried to k+1.  ``errors`` (k, 12): X (-) X^ at the nodes so far.  (transcription.closedloop.navloop
    flies the same law in one call.)"""

    def __init__(self, nav: NavigationFilter, tracker, F: np.ndarray, draws: np.ndarray, bias: np.ndarray | None = None):
        self.nav, self.tracker, self.F, self.draws = nav, tracker, np.asarray(F, float), np.asarray(draws, float)
        self.bias = np.zeros(NZ) if bias is None else np.asarray(bias, float).reshape(NZ)
        self.estimator = Estimator(nav)
        self.errors = []

    def __call__(self, k: int, t: float, X: np.ndarray) -> np.ndarray:
        Y = measure(X, self.F, self.draws[k], self.bias) if self.nav.measured[k] else None
        Xh, d = self.estimator.estimate(k, Y)
        e = self.estimator.error(X)
        self.errors.append(e)
        du = self.tracker.correction(k, Xh, d)
        self.estimator.predict(du)
        return du
