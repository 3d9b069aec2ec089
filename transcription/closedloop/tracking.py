"""Tracking a plan: a discrete-time, time-varying LQR on the plan's own linearized maps (docs/mathematics.md §12).

The error of a state X from the plan's node X_k is z = [x - x_k; gamma - gamma_k; vee log(R_k^T R); Pi - Pi_k] in
R^12, the tangent coordinates of A_k, B_k (§4; attitude error in the body frame).  A correction du_k (6: force
inertial, moment body) is held over [t_k, t_{k+1}]: z_{k+1} = A_k z_k + Bu_k du_k, Bu_k = B_k [I; I] for the lgvi
(w_k = [u_k + du_k; u_{k+1} + du_k]), B_k for first_order (w_k = u_{k+1} + du_k) (:func:`held`).  du_k = -K_k z_k -
L_k r_k minimizes sum_{k<N} h_k (z_k^T Q z_k + du_k^T R du_k) + z_N^T Q_N z_N with a persisting disturbance r
(:func:`riccati`; r_k estimated by :class:`Tracker`), minus f_k where the plan's known local errors eps_k are given
(:func:`feedforward`, :meth:`Gains.with_local_errors`); step k is linearized at its own h_k.  Default weights: Bryson's
rule (:func:`bryson_weights`).  The inputs are the actuators' channels (:func:`input_channels`: one body-fixed engine's
thrust along its axis and the moment; A_k's attitude columns carry d(R u_b)/dR); a removed control gets no feedback;
the correction is limited to the plan's headroom below the actuators' bounds (:meth:`Tracker.limit`).  The state's
Pi is the law's J Omega of the measured rate (transcription.dynamics.flight.sensed).

Shapes: K, L (N, 6, 12), P (N+1, 12, 12), S (N, 6, 6), A (N, 12, 12), B (N, 12, nw), X (N+1, 18), U (6, n_controls),
eps (N, 12), f (N, 6).
NumPy, except the linearization (the plan's CasADi ``variation``, mapped once).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Callable, Mapping

import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.state import NU, NX, NZ, U_FORCE, U_MOMENT, X_ANG, X_MOM, X_POS, X_ROT, Z_ANG, Z_MOM, Z_POS, Z_ROT
from ..geometry.so3 import exp_so3, log_so3
from ..ocp import Actuator, SmoothControl, actuator_bounds

#: the default closed-loop bandwidth omega_c = min(BANDWIDTH_PER_HORIZON / T, BANDWIDTH_PER_STEP / h) (rad per time
#: unit): time constant T/60, but never below ~3 steps (far from the discrete loop's sampling limit)
BANDWIDTH_PER_HORIZON = 60.0
BANDWIDTH_PER_STEP = 0.3
#: the default terminal acceptable errors are the running ones times this ratio rho (Q_N = 1 / (rho e)^2)
TERMINAL_RATIO = 1.0
#: Bryson scales a caller may give (``weights`` mapping): acceptable errors (per block: a number or 3) and
#: characteristic controls (force, moment), plus the bandwidth and the terminal ratio
SCALE_KEYS = ("position", "momentum", "attitude", "angular_momentum", "force", "moment", "bandwidth", "terminal_ratio")


# ------------------------------------------------------------------------------- errors
def tangent_error(X, Xref) -> np.ndarray:
    """z (12,) of a state X (18,) from Xref (18,): [x - x_r; gamma - gamma_r; vee log(R_r^T R); Pi - Pi_r]
    (the attitude error in the body frame of the reference; exact inverse of :func:`retract`)."""
    X, Xref = np.asarray(X, float).reshape(NX), np.asarray(Xref, float).reshape(NX)
    R = X[X_ROT].reshape(3, 3, order="F")
    Rr = Xref[X_ROT].reshape(3, 3, order="F")
    return np.concatenate([X[X_POS] - Xref[X_POS], X[X_MOM] - Xref[X_MOM], log_so3(Rr.T @ R), X[X_ANG] - Xref[X_ANG]])


def tangent_errors(X, Xref) -> np.ndarray:
    """:func:`tangent_error` node by node: X, Xref (n, 18) -> (n, 12)."""
    return np.array([tangent_error(a, b) for a, b in zip(np.atleast_2d(X), np.atleast_2d(Xref))])


def retract(Xref, z) -> np.ndarray:
    """The state X (18,) at tangent coordinates z (12,) from Xref: additive on x, gamma, Pi; R = R_r Exp(zeta)."""
    Xref, z = np.asarray(Xref, float).reshape(NX), np.asarray(z, float).reshape(NZ)
    X = Xref.copy()
    X[X_POS] += z[Z_POS]
    X[X_MOM] += z[Z_MOM]
    X[X_ANG] += z[Z_ANG]
    X[X_ROT] = (Xref[X_ROT].reshape(3, 3, order="F") @ exp_so3(z[Z_ROT])).ravel(order="F")
    return X


# ------------------------------------------------------------------------------- saturation
def saturate(u, force_bound=None, moment_bound=None) -> tuple[np.ndarray, np.ndarray]:
    """Controls u (..., 6) projected onto the actuators (:meth:`~transcription.ocp.actuators.Actuator.project`;
    docs/mathematics.md §10, §14).  Returns (projected controls, (...) bool: some component was changed)."""
    u = np.array(u, dtype=float)
    v = u.copy()
    for sl, bound in ((U_FORCE, force_bound), (U_MOMENT, moment_bound)):
        if bound is not None:
            v[..., sl] = bound.project(v[..., sl])
    return v, np.any(v != u, axis=-1)


# ------------------------------------------------------------------------------- weights
@dataclass(frozen=True)
class TrackingWeights:
    """The tracking cost sum_{k<N} h_k (z^T Q z + du^T R du) + z_N^T Q_N z_N: Q, Q_N (12, 12) in the
    order of z, R (6, 6) in the order of u; ``scales``: the Bryson scales they came from (acceptable
    errors per block and characteristic controls, 3 each; bandwidth, T), empty if given directly."""

    Q: np.ndarray
    R: np.ndarray
    Q_N: np.ndarray
    scales: dict = field(default_factory=dict)

    def __post_init__(self):
        for name, n in (("Q", NZ), ("R", NU), ("Q_N", NZ)):
            M = np.asarray(getattr(self, name), dtype=float)
            if M.shape != (n, n) or not np.all(np.isfinite(M)) or not np.allclose(M, M.T, rtol=1e-12, atol=0.0):
                raise ValueError(f"tracking weight {name}: expected a finite symmetric {n}x{n} matrix")
            if np.linalg.eigvalsh(M).min() < -1e-12 * max(1.0, np.abs(M).max()):
                raise ValueError(f"tracking weight {name}: expected a positive semi-definite matrix")
            object.__setattr__(self, name, M)


def characteristic_controls(control: SmoothControl, U: np.ndarray, mass: float, inertia: np.ndarray,
                            T: float) -> tuple[np.ndarray, np.ndarray]:
    """(u_f, u_m) (3 each): the actuators' bounds (box per component, a norm for all three) where bounded,
    else the plan's peak |u_f| and |u_m|; a control the plan never uses: m / T^2 (one length unit in
    T) and lambda_max(J) / T^2 (one radian in T).  A removed control: 0."""
    bounds = actuator_bounds(control)
    peaks = [np.linalg.norm(U[sl], axis=0).max(initial=0.0) for sl in (U_FORCE, U_MOMENT)]
    fallback = (mass / T**2, float(np.linalg.eigvalsh(inertia).max()) / T**2)
    out = []
    for bound, peak, fb in zip(bounds, peaks, fallback):
        out.append(bound.sizes() if bound is not None else np.full(3, peak if peak > 0 else fb))
    return out[0], out[1]


def bryson_weights(control: SmoothControl, U: np.ndarray, mass: float, inertia: np.ndarray, T: float, h: float,
                   **given) -> TrackingWeights:
    """The default tracking weights (docs/mathematics.md §12), Bryson's rule:

        Q = diag(1 / (T e_i^2)),  R = diag(1 / (T u_i^2)),  Q_N = diag(1 / (rho e_i)^2),
        e_x = u_f / (m omega_c^2),  e_gamma = u_f / omega_c,  e_zeta,i = u_m,i / (J_ii omega_c^2),  e_Pi = u_m / omega_c

    with characteristic controls u (:func:`characteristic_controls`), omega_c = min(BANDWIDTH_PER_HORIZON / T,
    BANDWIDTH_PER_STEP / h) and rho = TERMINAL_RATIO: the acceptable errors e are what u corrects in 1/omega_c.  The
    blocks a removed control drives get weight 0.  ``given`` overrides any of :data:`SCALE_KEYS` (a number or 3)."""
    unknown = set(given) - set(SCALE_KEYS)
    if unknown:
        raise ValueError(f"tracking weights: unknown scales {sorted(unknown)}; expected some of "
                         f"{', '.join(SCALE_KEYS)}")
    uf, um = characteristic_controls(control, U, mass, inertia, T)
    w = float(given.get("bandwidth", min(BANDWIDTH_PER_HORIZON / T, BANDWIDTH_PER_STEP / h)))
    rho = float(given.get("terminal_ratio", TERMINAL_RATIO))
    if not (np.isfinite(w) and w > 0 and np.isfinite(rho) and rho > 0):
        raise ValueError("tracking weights: bandwidth and terminal_ratio must be positive numbers")
    uf = _three(given.get("force", uf), "force")
    um = _three(given.get("moment", um), "moment")
    Jd = np.diag(np.asarray(inertia, float))
    e = {"position": uf / (mass * w**2), "momentum": uf / w, "attitude": um / (Jd * w**2), "angular_momentum": um / w}
    e = {k: _three(given.get(k, v), k) for k, v in e.items()}
    rf, rm = control.removed
    q = np.concatenate([_inv2(e["position"], rf), _inv2(e["momentum"], rf), _inv2(e["attitude"], rm),
                        _inv2(e["angular_momentum"], rm)])
    r = np.concatenate([_inv2(uf, rf), _inv2(um, rm)])
    scales = {**{k: v.tolist() for k, v in e.items()}, "force": uf.tolist(), "moment": um.tolist(), "bandwidth": w,
              "terminal_ratio": rho, "T": float(T)}
    return TrackingWeights(Q=np.diag(q / T), R=np.diag(r / T), Q_N=np.diag(q / rho**2), scales=scales)


def _three(v, name) -> np.ndarray:
    a = np.broadcast_to(np.asarray(v, dtype=float), (3,)).copy() if np.ndim(v) <= 1 else None
    if a is None or a.shape != (3,) or not np.all(np.isfinite(a)) or not np.all(a >= 0):
        raise ValueError(f"tracking weights: {name}: expected a non-negative number or 3 of them")
    return a


def _inv2(e: np.ndarray, removed: bool) -> np.ndarray:
    """1 / e^2, 0 for a removed block (and for an infinite acceptable error)."""
    if removed:
        return np.zeros(3)
    with np.errstate(divide="ignore"):
        return np.where(e > 0, 1.0 / np.maximum(e, 1e-300) ** 2, np.inf)


# ------------------------------------------------------------------------------- gains
def riccati(A: np.ndarray, Bu: np.ndarray, Q: np.ndarray, R: np.ndarray, Q_N: np.ndarray,
            active: np.ndarray | None = None,
            rho: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The finite-horizon discrete LQR with a constant state disturbance r (docs/mathematics.md §12):
    z_{k+1} = A_k z_k + Bu_k du_k + rho_k r, A (N, n, n), Bu (N, n, m), stage weights Q (n, n), R (m, m) (times the
    mean step h), terminal Q_N; ``rho`` (N,): h_k / h of a non-uniform mesh (None: all 1).  From P_N = Q_N, M_N = 0:

        S_k = rho_k R + Bu_k^T P_{k+1} Bu_k,   K_k = S_k^-1 Bu_k^T P_{k+1} A_k,
        L_k = S_k^-1 Bu_k^T (rho_k P_{k+1} + M_{k+1}),
        P_k = rho_k Q + K_k^T rho_k R K_k + (A_k - Bu_k K_k)^T P_{k+1} (A_k - Bu_k K_k)   (Joseph form: symmetric PSD),
        M_k = (A_k - Bu_k K_k)^T (M_{k+1} + rho_k P_{k+1}),

    so du_k = -K_k z_k - L_k r minimizes the cost-to-go z^T P_k z + 2 z^T M_k r + const, (du - du_k)^T S_k (du - du_k)
    + const in du.  ``active`` (m,) bool: the inputs that exist (the others get K = L = 0, S = I there).
    Returns K, L (N, m, n), P (N+1, n, n), S (N, m, m)."""
    N, n, m = Bu.shape
    act = np.ones(m, bool) if active is None else np.asarray(active, bool)
    K, L = np.zeros((N, m, n)), np.zeros((N, m, n))
    SS = np.tile(np.eye(m), (N, 1, 1))
    P = np.zeros((N + 1, n, n))
    P[N] = Q_N
    M = np.zeros((n, n))
    Ra = R[np.ix_(act, act)]
    for k in range(N - 1, -1, -1):
        Qk, Rk, Pr = (Q, Ra, P[k + 1]) if rho is None else (rho[k] * Q, rho[k] * Ra, rho[k] * P[k + 1])
        B = Bu[k][:, act]
        BtP = B.T @ P[k + 1]
        S = Rk + BtP @ B
        SS[k][np.ix_(act, act)] = S
        Ka = np.linalg.solve(S, BtP @ A[k])
        K[k][act] = Ka
        L[k][act] = np.linalg.solve(S, B.T @ (Pr + M))
        Acl = A[k] - B @ Ka
        M = Acl.T @ (M + Pr)
        Pk = Qk + Ka.T @ Rk @ Ka + Acl.T @ P[k + 1] @ Acl
        P[k] = 0.5 * (Pk + Pk.T)
    return K, L, P, SS


def feedforward(A: np.ndarray, Bu: np.ndarray, K: np.ndarray, S: np.ndarray, P: np.ndarray, eps: np.ndarray,
                E: np.ndarray, active: np.ndarray) -> np.ndarray:
    """f (N, 6): the LQR's answer to a known disturbance sequence (docs/mathematics.md §12, *Known local errors*).
    With z_{k+1} = A_k z_k + Bu_k du_k + eps_k and the cost of :func:`riccati`, the cost-to-go gains a term 2 z^T s_k
    and du_k = -K_k z_k - f_k, from s_N = 0:

        f_k = S_k^-1 Bu_k^T (P_{k+1} eps_k + s_{k+1}),   s_k = (A_k - Bu_k K_k)^T (P_{k+1} eps_k + s_{k+1}),

    in the input channels v = E^T du that exist (``active``; :func:`input_channels`), K, S (in du's coordinates), P of
    :func:`riccati` (``Gains``), A (N, 12, 12), Bu (N, 12, 6)."""
    N, n, m = Bu.shape
    f = np.zeros((N, m))
    s = np.zeros(n)
    act = np.asarray(active, bool)
    for k in range(N - 1, -1, -1):
        g = P[k + 1] @ eps[k] + s
        Bc = (Bu[k] @ E)[:, act]
        Sc = (E.T @ S[k] @ E)[np.ix_(act, act)]
        f[k] = E[:, act] @ np.linalg.solve(Sc, Bc.T @ g)
        s = (A[k] - Bu[k] @ K[k]).T @ g
    return f


def box_qp(S: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_iter: int = 50) -> np.ndarray:
    """argmin (1/2) x^T S x + g^T x over lo <= x <= hi (S symmetric positive definite, infinite limits allowed):
    a primal active-set method from the clipped unconstrained minimizer, exact at its end."""
    x = np.clip(np.linalg.solve(S, -g), lo, hi)
    act = (x == lo) | (x == hi)
    for _ in range(max_iter):
        f = ~act
        y = x.copy()
        if f.any():
            y[f] = np.linalg.solve(S[np.ix_(f, f)], -(g[f] + S[np.ix_(f, act)] @ x[act]))
        p = y - x
        with np.errstate(divide="ignore", invalid="ignore"):
            steps = np.where(p < 0, (lo - x) / p, np.where(p > 0, (hi - x) / p, np.inf))
        j = int(np.argmin(steps))
        if steps[j] < 1.0:                         # a limit blocks the step: take it up to there
            x = x + steps[j] * p
            x[j] = lo[j] if p[j] < 0 else hi[j]
            act[j] = True
            continue
        x = y
        lam = np.where(x == lo, 1.0, -1.0) * (S @ x + g)    # >= 0 at an optimal active limit
        lam[~act] = np.inf
        i = int(np.argmin(lam))
        if lam[i] >= -1e-12 * max(1.0, np.abs(g).max()):
            return x
        act[i] = False
    return x


@dataclass(frozen=True)
class Gains:
    """The tracker of one plan (docs/mathematics.md §12); NumPy data (picklable).

    K, L (N, 6, 12): du_k = -K_k z_k - L_k r_k.  P (N+1, 12, 12): the cost-to-go z^T P_k z; S (N, 6, 6) its Hessian
    in du_k (the metric under saturation).  A (N, 12, 12), B (N, 12, nw): the plan's variations (§4).  t (N+1,),
    X (N+1, 18): the plan's nodes; U (6, n_controls): its controls (lgvi u_0..u_N, first_order u_1..u_N); h: the mean
    step T/N; steps (N,): the h_k of a non-uniform mesh (None: uniform; §16).  force_bound, moment_bound: the bounds
    the commands are clipped to (the plan's widened by its bounds_margin); removed: (force, moment) removed.  eps
    (N, 12), f (N, 6): the plan's known local errors and their feedforward (:meth:`with_local_errors`; None: none).
    """

    K: np.ndarray
    L: np.ndarray
    P: np.ndarray
    S: np.ndarray
    A: np.ndarray
    B: np.ndarray
    t: np.ndarray
    X: np.ndarray
    U: np.ndarray
    scheme: str
    h: float
    weights: TrackingWeights
    force_bound: Actuator | None = None
    moment_bound: Actuator | None = None
    removed: tuple = (False, False)
    steps: np.ndarray | None = None
    eps: np.ndarray | None = None
    f: np.ndarray | None = None

    @property
    def N(self) -> int:
        return self.K.shape[0]

    def with_local_errors(self, eps: np.ndarray) -> "Gains":
        """These gains with the plan's known local errors eps (N, 12) -- what each step of the continuous flight from
        the plan's node under its commands adds to z beyond A_k z_k + Bu_k du_k (transcription.closedloop.estimator.
        local_errors) -- and their feedforward f (N, 6) (:func:`feedforward`): du_k = -K_k z_k - f_k - L_k r_k, r now
        the disturbance beyond eps."""
        eps = np.asarray(eps, float).reshape(self.N, NZ)
        E, active = input_channels(self.force_bound, self.moment_bound, self.removed)
        return replace(self, eps=eps, f=feedforward(self.A, self.Bu, self.K, self.S, self.P, eps, E, active))

    def known(self, k: int) -> np.ndarray:
        """eps_k (12,): the plan's known local error of step k (0 without them)."""
        return np.zeros(NZ) if self.eps is None else self.eps[k]

    def forward(self, k: int) -> np.ndarray:
        """f_k (6,): the feedforward of step k (0 without local errors)."""
        return np.zeros(NU) if self.f is None else self.f[k]

    @cached_property
    def rho(self) -> np.ndarray | None:
        """(N,) h_k / h of a non-uniform mesh (:func:`riccati`'s weights), None on a uniform one."""
        return None if self.steps is None else self.steps / self.h

    def step(self, k: int) -> float:
        """The size h_k of step k."""
        return self.h if self.steps is None else float(self.steps[k])

    def per_mean_step(self, k: int, r: np.ndarray) -> np.ndarray:
        """A disturbance r (12,) that step k explained as the disturbance of a step of the mean size h
        (:func:`riccati`'s r: r / rho_k, :attr:`rho`; r itself on a uniform mesh)."""
        return r if self.steps is None else r / self.rho[k]

    @property
    def Bu(self) -> np.ndarray:
        """(N, 12, 6): the input matrices of a correction held over each step (:func:`held`)."""
        return held(self.B, self.scheme)

    def error(self, k: int, X) -> np.ndarray:
        """z (12,) of the state X from the plan's node k."""
        return tangent_error(X, self.X[k])

    def plan_stage(self, k: int) -> np.ndarray:
        """The plan's node controls of step k as rows: lgvi (2, 6) [u_k; u_{k+1}], first_order (1, 6) [u_{k+1}]."""
        return self.U[:, k:k + 2].T if two_point(self.scheme) else self.U[:, k:k + 1].T

    def tracker(self, feedback: bool = True, disturbance: bool = True, r0: np.ndarray | None = None) -> "Tracker":
        """A fresh feedback law for one flight (:class:`Tracker`; r0: a disturbance estimate handed over)."""
        return Tracker(self, feedback, disturbance, r0)


class Tracker:
    """The feedback law of one flight (docs/mathematics.md §12), called once per step, k = 0, 1, ..., N-1:

        z_k = tangent_error(X, X_k),
        r_k = z_k - A_{k-1} z_{k-1} - B_{k-1} (w_{k-1} - w_{k-1}^plan) - eps_{k-1}   (r_0 = 0; per mean step on a mesh),
        du_k = -K_k z_k - f_k - L_k r_k,   commands = the plan's rows of step k + du_k,

    w_{k-1} the commands issued, eps and f the plan's known local errors and their feedforward
    (:meth:`Gains.with_local_errors`; 0 without them): r_k is what the last step did that neither the linearization
    nor the plan's own discretization error explains, taken as persisting.  ``r0``: an estimate handed over for step
    0 (:meth:`unexplained`).  The correction is limited to the plan's symmetric headroom (:meth:`limit`: a box by
    :func:`box_qp` in the metric S_k, a norm by scaling; an engine's thrust to its own one-sided box).  feedback
    False: the plan's controls only; disturbance False: du_k = -K_k z_k.  ``saturated_steps`` counts the limited
    steps."""

    def __init__(self, gains: Gains, feedback: bool = True, disturbance: bool = True, r0: np.ndarray | None = None):
        self.gains, self.feedback, self.disturbance = gains, bool(feedback), bool(disturbance)
        self.r0 = None if r0 is None else np.asarray(r0, float).reshape(NZ)
        self.box = box_limits(gains.force_bound, gains.moment_bound)
        self.norms = [(sl, b.radius) for sl, b in ((U_FORCE, gains.force_bound), (U_MOMENT, gains.moment_bound))
                      if b is not None and np.isfinite(b.radius)]
        self.engine = gains.force_bound if gains.force_bound is not None and gains.force_bound.channel_rows else None
        self.bounded = bool(self.norms) or bool(np.isfinite(self.box).any()) or self.engine is not None
        self.k = -1
        self.z = self.dw = None
        self.saturated_steps = 0

    def correction(self, k: int, X, r: np.ndarray | None = None) -> np.ndarray:
        """du_k (6,) for the state X at t_k, within the headroom of step k (0 without feedback); the flight
        engine's per-interval law (transcription.flight.ClosedLoop) adds it to both ends of the interval.  ``r``: the
        disturbance per mean step estimated elsewhere (a navigation filter, transcription.closedloop.estimator),
        used instead of the tracker's own."""
        g = self.gains
        if k != self.k + 1 or not 0 <= k < g.N:
            raise ValueError(f"Tracker: expected step {self.k + 1} (steps 0..{g.N - 1} in order), got {k}")
        du = np.zeros(NU)
        if self.feedback:
            z = g.error(k, X)
            du = -g.K[k] @ z - g.forward(k)
            if self.disturbance and r is not None:
                du -= g.L[k] @ np.asarray(r, float).reshape(NZ)
            elif self.disturbance and k > 0:
                du -= g.L[k] @ g.per_mean_step(k - 1, z - g.A[k - 1] @ self.z - g.B[k - 1] @ self.dw - g.known(k - 1))
            elif self.disturbance and self.r0 is not None:          # k = 0: an estimate handed over
                du -= g.L[0] @ self.r0
            self.z = z
            if self.bounded:
                du, limited = self.limit(k, du, g.plan_stage(k))
                self.saturated_steps += limited
        self.dw = np.tile(du, 2 if two_point(g.scheme) else 1)
        self.k = k
        return du

    def unexplained(self, k: int, X) -> np.ndarray | None:
        """r_k (12,) for the state X at t_k, without taking the step (None before the first step or without the
        disturbance estimate), per step of the mean size h: handed to a re-planned trajectory's tracker (mpc)."""
        g = self.gains
        if not (self.feedback and self.disturbance) or self.k < 0 or k != self.k + 1 or k >= g.N:
            return None
        return g.per_mean_step(k - 1, g.error(k, X) - g.A[k - 1] @ self.z - g.B[k - 1] @ self.dw - g.known(k - 1))

    def command(self, k: int, X) -> np.ndarray:
        """The node commands (rows, 6) of step k from the state X at t_k (rows: 2 lgvi, 1 first_order): the
        plan's rows + :meth:`correction` (clipped to the actuators' bounds only where the plan itself
        exceeds them by round-off)."""
        plan = self.gains.plan_stage(k)
        cmd, _ = saturate(plan + self.correction(k, X), self.gains.force_bound, self.gains.moment_bound)
        return cmd

    def limit(self, k: int, du: np.ndarray, plan: np.ndarray) -> tuple[np.ndarray, bool]:
        """du (6,) limited to the symmetric headroom of the plan's rows (rows, 6) of step k (an engine's thrust: to
        min(lo - T_min, 0) <= dT <= max(hi - T_max, 0) over the rows, docs/mathematics.md §12); and whether it was."""
        hb = np.maximum(self.box - np.abs(plan).max(axis=0), 0.0)
        limited = bool(np.any(np.abs(du) > hb))
        if limited:
            S = self.gains.S[k]
            du = box_qp(S, -S @ du, -hb, hb)
        for sl, b in self.norms:
            hn = max(b - np.linalg.norm(plan[:, sl], axis=1).max(), 0.0)
            n = np.linalg.norm(du[sl])
            if n > hn:
                du[sl] *= hn / n
                limited = True
        if self.engine is not None:   # channel rows (an engine: along its axis only, within its thrust headroom)
            Q, lo, hi = self.engine.channels
            T = plan[:, U_FORCE] @ Q
            kept = Q @ np.clip(Q.T @ du[U_FORCE], np.minimum(lo - T.min(axis=0), 0.0), np.maximum(hi - T.max(axis=0), 0.0))
            limited = limited or bool(np.linalg.norm(du[U_FORCE] - kept) > 1e-9 * self.engine.scale())
            du[U_FORCE] = kept
        return du, limited

    def delivered(self, extra: np.ndarray) -> None:
        """The actuators delivered this step's commands plus ``extra`` (6,) held over the step (on/off pulses: an
        impulse carried or cut, transcription.closedloop.pulses): the next disturbance estimate compares with that."""
        self.dw = self.dw + np.tile(np.asarray(extra, float).reshape(NU), 2 if two_point(self.gains.scheme) else 1)

    @property
    def saturated_fraction(self) -> float:
        """The fraction of the steps so far whose correction the actuators' bounds limited."""
        return self.saturated_steps / (self.k + 1) if self.k >= 0 else 0.0


def box_limits(force_bound, moment_bound) -> np.ndarray:
    """(6,) the box limit of each control component: b_i of a box, 0 for a removed control, inf otherwise
    (a norm bound is met by scaling)."""
    out = np.full(NU, np.inf)
    for sl, bound in ((U_FORCE, force_bound), (U_MOMENT, moment_bound)):
        box = None if bound is None else bound.variable_box()
        if box is not None:
            out[sl] = np.minimum(-box[0], box[1])
    return out


def tracking_gains(sol, weights: TrackingWeights | Mapping | None = None) -> Gains:
    """The time-varying LQR around the plan of ``sol`` (a Solution with smooth controls and its Problem).

    weights: None (:func:`bryson_weights`' defaults), a mapping of Bryson scales overriding some
    (:data:`SCALE_KEYS`), or :class:`TrackingWeights`.  The linearization is the plan's own (:func:`linearization`);
    on a non-uniform mesh :func:`riccati` weights step k by rho_k = h_k / h."""
    prob = sol.problem
    control = getattr(prob, "control", None)
    if not isinstance(control, SmoothControl) or sol.controls is None:
        raise ValueError("tracking_gains: the plan must be a Solution with smooth controls (and its Problem)")
    disc, h = prob.disc, sol.h
    steps = None if sol.uniform else np.asarray(sol.steps, float)     # the plan's own node times, not its Problem's
    X, U = np.asarray(sol.trajectory.X, float), np.asarray(sol.controls, float)
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
        raise ValueError("tracking_gains: the plan's trajectory or controls are not finite")
    model = prob.model
    if weights is None or isinstance(weights, Mapping):     # on a mesh the bandwidth's step is the mean step h
        weights = bryson_weights(control, U, model.mass, model.inertia, sol.T, h, **dict(weights or {}))
    A, B = linearization(disc, X, U, h if steps is None else steps)
    fb, mb = actuator_bounds(control)
    E, active = input_channels(fb, mb, control.removed)
    Kc, Lc, P, Sc = riccati(A, held(B, disc.scheme) @ E, h * weights.Q, h * (E.T @ weights.R @ E), weights.Q_N,
                            active, None if steps is None else steps / h)
    K, L, S = E @ Kc, E @ Lc, E @ Sc @ E.T           # back to the controls' coordinates (E orthogonal)
    return Gains(K=K, L=L, P=P, S=S, A=A, B=B, t=np.asarray(sol.trajectory.t, float), X=X, U=U, scheme=disc.scheme, h=h,
                 weights=weights, force_bound=fb, moment_bound=mb, removed=tuple(bool(r) for r in control.removed),
                 steps=steps)


def input_channels(force_bound, moment_bound, removed=(False, False)) -> tuple[np.ndarray, np.ndarray]:
    """The tracker's inputs (docs/mathematics.md §12, *Input channels*): E (6, 6) = blockdiag(Q_f, Q_m), the
    actuators' channel directions (:attr:`~transcription.ocp.actuators.Actuator.channels`; I where unbounded), and
    ``active`` (6,) bool, the channels that exist: not held fixed (an engine's off-axis force) and not removed.  The
    LQR's input is the channel vector v = E^T du (an engine: its thrust T along the axis, in the body frame where the
    force is the body's), so it never asks for a force the actuator cannot give."""
    E, active = np.eye(NU), np.ones(NU, bool)
    for sl, bound, gone in ((U_FORCE, force_bound, removed[0]), (U_MOMENT, moment_bound, removed[1])):
        if gone:
            active[sl] = False
        elif bound is not None:
            Q, lo, hi = bound.channels
            E[sl, sl] = Q
            active[sl] = lo < hi
    return E, active


def sub_stepped(sol, h_max: float | None = None):
    """The plan of ``sol`` (a Solution on the plan's Problem) with each step longer than h_max (default the mean step)
    split into m_k = ceil(h_k / h_max) sub-steps of the scheme under the plan's controls between nodes (lgvi: linear
    u_k -> u_{k+1}; first order: u_{k+1} held), the last sub-node X_{k+1} itself (docs/mathematics.md §12); ``sol``
    itself if no step is longer."""
    from ..results.solution import Solution
    from ..dynamics.trajectory import Trajectory

    t, X, U, disc = np.asarray(sol.trajectory.t, float), np.asarray(sol.trajectory.X, float), sol.controls, sol.problem.disc
    hk = np.diff(t)
    m = np.maximum(1, np.ceil(hk / (sol.h if h_max is None else h_max) * (1 - 1e-12)).astype(int))
    if np.all(m == 1):
        return sol
    s = [np.arange(1, mk + 1) / mk for mk in m]                       # sub-node fractions of each step, ending at 1
    tt = np.concatenate([[t[0]]] + [np.r_[t[k] + hk[k] * s[k][:-1], t[k + 1]] for k in range(len(hk))])
    if two_point(disc.scheme):
        Ut = np.column_stack([U[:, 0]] + [np.c_[U[:, [k]] + s[k][None, :-1] * (U[:, [k + 1]] - U[:, [k]]), U[:, k + 1]]
                                          for k in range(len(hk))])
    else:
        Ut = np.column_stack([np.repeat(U[:, [k]], m[k], axis=1) for k in range(len(hk))])
    W, Xt, j = disc.stage_controls(Ut), [X[0]], 0
    for k, mk in enumerate(m):
        Xj = X[k]
        for i in range(mk - 1):
            Xj = np.asarray(disc.step(Xj, W[:, j + i], hk[k] / mk)[0]).ravel()
            Xt.append(Xj)
        Xt.append(X[k + 1])
        j += mk
    tr = sol.trajectory
    return Solution(method=sol.method, solver=sol.solver, result=sol.result, verdict=sol.message,
                    trajectory=Trajectory(t=tt, X=np.array(Xt), mass=tr.mass, inertia=tr.inertia), cost=sol.cost,
                    terminal_error=sol.terminal_error, problem=sol.problem, controls=Ut)


def linearization(disc, X: np.ndarray, U: np.ndarray, h: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A_k (N, 12, 12) and B_k (N, 12, nw) of the plan X (N+1, 18), U (6, n_controls): the variations of
    docs/mathematics.md §4 (``Discretization.variation``) at the plan's nodes, stage controls w_k and step
    sizes h (one, or the N step sizes h_k of a non-uniform mesh)."""
    N = X.shape[0] - 1
    W = disc.stage_controls(U)
    A, B = disc.variation.map(N)(X[:-1].T, W, h if np.ndim(h) == 0 else np.reshape(h, (1, N)))
    A = np.asarray(A).reshape(NZ, NZ, N, order="F").transpose(2, 0, 1)         # 12 x 12N: [A_0 A_1 ...]
    B = np.asarray(B).reshape(NZ, disc.nw, N, order="F").transpose(2, 0, 1)
    return A, B


def held(B: np.ndarray, scheme: str) -> np.ndarray:
    """Bu (N, 12, 6) of a correction du_k held over step k from B (N, 12, nw): lgvi B_k [I; I] (du_k enters
    both node controls of the stage control w_k = [u_k; u_{k+1}]), first_order B_k (w_k = u_{k+1})."""
    return B[:, :, :NU] + B[:, :, NU:] if two_point(scheme) else B


# ------------------------------------------------------------------------------- the discrete loop
@dataclass(frozen=True)
class DiscreteFlight:
    """A flight on a discrete model: X (N+1, 18) states, commands (N, rows, 6) the node commands of each
    step (rows 2 lgvi, 1 first_order), z (N+1, 12) the errors from the plan's nodes, saturated_fraction:
    of the steps whose correction the bounds limited (:class:`Tracker`)."""

    X: np.ndarray
    commands: np.ndarray
    z: np.ndarray
    saturated_fraction: float


def fly_discrete(gains: Gains, disc, X0, *, feedback: bool = True, disturbance: bool = True,
                 actuator: Callable[[np.ndarray], np.ndarray] | None = None) -> DiscreteFlight:
    """Fly the plan of ``gains`` on the discrete model ``disc`` (same scheme) from X0 (18,) under the
    :class:`Tracker`.  ``actuator``: what the actuators deliver for the commands (rows, 6), default the commands."""
    if disc.scheme != gains.scheme:
        raise ValueError(f"fly_discrete: the model's scheme {disc.scheme!r} is not the plan's {gains.scheme!r}")
    N = gains.N
    X = np.zeros((N + 1, NX))
    X[0] = np.asarray(X0, float).reshape(NX)
    rows = 2 if two_point(gains.scheme) else 1
    cmds = np.zeros((N, rows, NU))
    law = gains.tracker(feedback, disturbance)
    for k in range(N):
        cmds[k] = law.command(k, X[k])
        w = cmds[k] if actuator is None else actuator(cmds[k])
        X[k + 1] = np.asarray(disc.step(X[k], np.ravel(w), gains.step(k))[0]).ravel()
    return DiscreteFlight(X=X, commands=cmds, z=tangent_errors(X, gains.X), saturated_fraction=law.saturated_fraction)
