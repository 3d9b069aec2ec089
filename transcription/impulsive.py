"""Optimal impulsive control (SPEC §5): impulses at t = 0 and t = T, free motion between.

Unknowns p = (gamma_0^+, Pi_0^+) in R^6 (inertial linear momentum, body angular
momentum just after the initial impulse; this order follows the state layout).
X_0^+ = X0 with its momenta replaced by p; X_N = free rollout of the problem's
discretization (u = 0) from X_0^+; the terminal impulse brings (gamma_N, Pi_N) to
the required (gamma_N^+, Pi_N^+).

Sensitivity (SPEC §4 eqs. 18-20): Phi = A_{N-1} ... A_0 (12 x 12) is the product of
the left-trivialized step Jacobians ``disc.variation`` along the rollout; since
dgamma_0 and dPi_0 are additive tangent directions, dz_N/dp = Phi[:, [3:6, 9:12]].
:func:`sensitivity` builds Phi that way; :func:`sensitivity_ad` differentiates the
whole rollout composed with the chart at X_0 and reads back at X_N (a second AD route).

* TPBVP (terminal an 18-vector Xd, E1): the six conditions
  r(p) = [x_N - x_d; vee log(R_d^T R_N)] = 0 are solved by Newton with Armijo
  backtracking on |r|; the Jacobian is [Phi_xp; Jr^-1(vee log(R_d^T R_N)) Phi_zeta p]
  (Jr^-1 the inverse right Jacobian of SO(3), exact for the log residual).  The
  impulses follow: gamma_N^+ = gamma_d, Pi_N^+ = Pi_d.  There is nothing left to
  optimize: the six conditions fix p (a Lambert problem on SE(3)).
* Relaxed (terminal an OrbitTarget, E2): a multiple-shooting NLP (node states and
  Cayley vectors as in the direct method, u = 0, x_0 and R_0 fixed, (gamma_0, Pi_0)
  free) with the four terminal conditions
  C = [|x_N| - r_d; e_n^T x_N; a^T R_N e_1; b^T R_N e_1] = 0 ((a, b) an orthonormal
  basis of the orbit plane), the terminal momenta gamma_N^+ = m sqrt(mu/r_d)
  (e_n x x_N)/r_d, Pi_N^+ = 0, and the cost sum_i |v_i| written directly, solved by
  IPOPT with the exact Hessian from a feasible start (:func:`relaxed_start`: a TPBVP
  to a point of the target set).

  Why no epigraph: the sum of norms is smooth wherever every impulse is nonzero, and
  at this optimum all four are (the solve reports ``min_impulse_norm``; a value near 0
  means the optimum sits on a kink and converged is then False).  Both smooth
  epigraphs were tried, |v|^2 <= s^2 and the convex perspective form |v|^2/s <= s
  with s >= 0: IPOPT converged to ~1e-6 and then, when the barrier parameter fell,
  took a huge step along the nearly flat direction of the spin about the dumbbell's
  axis (the cost is invariant to its phase; its curvature is ~1e-5 in scaled units)
  and ended in restoration failure, at N = 100 and N = 800 and with several option
  sets.  Without the four barrier terms IPOPT reaches Solve_Succeeded.
  The Jacobians are AD through the same step Function; :func:`relaxed_jacobian`
  gives the Phi-based gradient dC/dp of SPEC §5, used by the tests to check the
  reduced KKT conditions of the returned solution.

Options (``problem.options``, the YAML ``solver.direct`` block): ``tol``, ``max_iter``,
``options`` (IPOPT tol / iteration limit / raw options of the relaxed NLP; defaults 1e-10,
3000); ``newton_tol``, ``newton_max_iter`` (TPBVP: |r|_inf target and iteration limit,
defaults 1e-13 and 50); ``initial_guess`` ('rollout' = no impulse, default; 'attitude'
(or the direct block's 'interpolate') = Pi_0^+ = J log(R_0^T R_d)/T; TPBVP only: if
Newton fails from one guess it restarts from the other unless ``fallback`` is False);
``terminal_tol`` (relaxed: max |C| for converged, default 1e-8).
"""
from __future__ import annotations

import dataclasses
import time
from functools import lru_cache
from typing import Any, Callable

import casadi as ca
import numpy as np

from .direct import NLPLayout, _Progress, shooting_defects
from .guess import cayley_vectors, log_so3_any
from .layout import NX, NZ, pack_state, X_ANG, X_MOM, X_POS, X_ROT, Z_ANG, Z_MOM, Z_POS, Z_ROT, split_state, unpack_states
from .lgvi import chart, tangent_readback
from .lie import hat
from .problem import ImpulsiveProblem, OrbitTarget
from .results import Solution, Trajectory, terminal_error_full

#: tangent coordinates of the unknowns p = (gamma_0^+, Pi_0^+) inside z
P_COLS = np.r_[np.arange(Z_MOM.start, Z_MOM.stop), np.arange(Z_ANG.start, Z_ANG.stop)]
P_ROWS_X = np.r_[np.arange(X_MOM.start, X_MOM.stop), np.arange(X_ANG.start, X_ANG.stop)]


def with_momenta(X0: np.ndarray, p: np.ndarray) -> np.ndarray:
    """X0 (18,) with (gamma, Pi) replaced by p = (gamma^+, Pi^+) (6,)."""
    X = np.array(X0, dtype=float).reshape(NX)
    X[P_ROWS_X] = np.asarray(p, dtype=float).ravel()
    return X


# --------------------------------------------------------------------- sensitivity
@lru_cache(maxsize=None)
def _variation_map(disc, N: int) -> ca.Function:
    return disc.variation.map(N)


def sensitivity(disc, X: np.ndarray, h: float, W: np.ndarray | None = None) -> np.ndarray:
    """Phi = A_{N-1} ... A_0 (12 x 12, SPEC eq. 19) along node states X (N+1, 18).

    W: stage controls (nw x N) or None (free motion).  A_k = disc.variation(X_k, w_k, h).
    """
    N = X.shape[0] - 1
    W = np.zeros((disc.nw, N)) if W is None else W
    A, _ = _variation_map(disc, N)(X[:-1].T, W, h)
    A = np.array(A)
    Phi = np.eye(NZ)
    for k in range(N):
        Phi = A[:, NZ * k: NZ * (k + 1)] @ Phi
    return Phi


@lru_cache(maxsize=None)
def _sensitivity_ad_fn(disc, N: int) -> ca.Function:
    X0 = ca.MX.sym("X0", NX)
    z = ca.MX.sym("z", NZ)
    h = ca.MX.sym("h")
    roll = disc.rollout(N)
    XN = roll(chart(X0, z), ca.DM.zeros(disc.nw, N), h)[0][:, -1]
    dXN = ca.jacobian(XN, z)
    XNbar = roll(X0, ca.DM.zeros(disc.nw, N), h)[0][:, -1]
    dXN = ca.substitute(dXN, z, ca.DM.zeros(NZ))
    return ca.Function("phi_ad", [X0, h], [tangent_readback(XNbar, dXN)], ["X0", "h"], ["Phi"])


def sensitivity_ad(disc, X0: np.ndarray, h: float, N: int) -> np.ndarray:
    """Phi by AD of the whole free rollout composed with the chart at X0, read back at X_N (12 x 12)."""
    return np.array(_sensitivity_ad_fn(disc, N)(X0, h))


def right_jacobian_inv(phi: np.ndarray) -> np.ndarray:
    """Jr^-1(phi): Log(Exp(phi) Exp(d)) = phi + Jr^-1(phi) d + O(d^2)."""
    t2 = float(phi @ phi)
    S = hat(phi)
    if t2 < 1e-8:
        coef = 1.0 / 12.0 + t2 / 720.0
    else:
        t = np.sqrt(t2)
        coef = 1.0 / t2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t))
    return np.eye(3) + 0.5 * S + coef * (S @ S)


# ---------------------------------------------------------------------------- TPBVP
def tpbvp_residual(XN: np.ndarray, Xd: np.ndarray) -> np.ndarray:
    """r = [x_N - x_d; vee log(R_d^T R_N)] (6,): the six conditions of the TPBVP (SPEC §5)."""
    a, d = unpack_states(XN), unpack_states(Xd)
    return np.concatenate([a.x[0] - d.x[0], log_so3_any(d.R[0].T @ a.R[0])])


def tpbvp_jacobian(XN: np.ndarray, Xd: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """dr/dp (6 x 6) from Phi: rows x and Jr^-1 zeta, columns gamma_0 and Pi_0."""
    e = tpbvp_residual(XN, Xd)[3:]
    return np.vstack([Phi[Z_POS][:, P_COLS], right_jacobian_inv(e) @ Phi[Z_ROT][:, P_COLS]])


def _guess_kind(opts: dict) -> str:
    """options['initial_guess'] for impulsive problems; the direct block's 'interpolate' means 'attitude'."""
    kind = str(opts.get("initial_guess", "rollout"))
    return "attitude" if kind == "interpolate" else kind


def _initial_p(problem: ImpulsiveProblem, kind: str) -> np.ndarray:
    a = unpack_states(problem.X0)
    p = np.concatenate([a.gamma[0], a.Pi[0]])
    if kind == "attitude" and not isinstance(problem.terminal, OrbitTarget):
        d = unpack_states(problem.terminal)
        p[3:] = problem.disc.J @ log_so3_any(a.R[0].T @ d.R[0]) / problem.T
    elif kind not in ("rollout", "attitude"):
        raise ValueError(f"initial_guess must be 'rollout', 'attitude' or 'interpolate', got {kind!r}")
    return p


#: a trial whose Cayley solves leave a relative residual above this is rejected by the line searches
CAYLEY_RES_TOL = 1e-10


def _simulate(problem: ImpulsiveProblem, p: np.ndarray, strict: bool = False) -> np.ndarray:
    """Free rollout (N+1, 18) from X0 with momenta p; strict: NaN if a Cayley solve failed."""
    X, res = problem.disc.simulate(with_momenta(problem.X0, p), None, problem.h, problem.N)
    if strict and (res.size and not np.max(res) <= CAYLEY_RES_TOL):
        X = np.full_like(X, np.nan)
    return X


#: Newton target for the six TPBVP conditions (|r|_inf) and its iteration limit
NEWTON_TOL = 1e-13
NEWTON_MAX_ITER = 50
#: an impulse norm below this at the relaxed optimum means a kink of the cost
KINK_TOL = 1e-8
#: consecutive line-search steps below 1e-2 after which Newton gives up ("stagnated")
STAGNATION_STEPS = 8


def _capped(d: np.ndarray, scale: np.ndarray, cap: float = 1.0) -> np.ndarray:
    """Limit a step to |d / scale|_inf <= cap (a crude trust region for the momenta)."""
    r = np.abs(d / scale).max()
    return d * (cap / r) if r > cap else d


def _newton_tpbvp(problem: ImpulsiveProblem, p: np.ndarray, tol: float, max_iter: int, alpha: float,
                  progress: Callable[[dict], None] | None):
    """Newton-Armijo on the six conditions; returns (p, X, history, status)."""
    Xd = np.asarray(problem.terminal, dtype=float)
    scale = _momentum_scales(problem)
    X = _simulate(problem, p)
    r = tpbvp_residual(X[-1], Xd)
    e = np.linalg.norm(r)
    history = []
    small_steps = 0
    for it in range(max_iter + 1):
        rec = {"iter": it, "residual_inf": float(np.abs(r).max()), "residual_2": float(e)}
        if np.abs(r).max() <= tol:
            history.append(rec)
            if progress:
                progress(rec)
            return p, X, history, "converged"
        if it == max_iter:
            history.append(rec)
            return p, X, history, "max_iter"
        Jac = tpbvp_jacobian(X[-1], Xd, sensitivity(problem.disc, X, problem.h))
        try:
            d = _capped(-np.linalg.solve(Jac, r), scale)
        except np.linalg.LinAlgError:
            history.append(rec)
            return p, X, history, "singular_jacobian"
        c = 1.0
        while True:
            pt = p + c * d
            Xt = _simulate(problem, pt, strict=True)
            rt = tpbvp_residual(Xt[-1], Xd)
            et = np.linalg.norm(rt)
            if np.isfinite(et) and (et <= (1.0 - alpha * c) * e or (c == 1.0 and et <= 1e-3 * tol)):
                break
            c *= 0.5
            if c < 1e-10:
                history.append(rec)
                return p, X, history, "line_search_failed"
        rec["step"] = c
        history.append(rec)
        small_steps = small_steps + 1 if c < 1e-2 else 0
        if small_steps >= STAGNATION_STEPS:
            return pt, Xt, history + [{"iter": it + 1, "residual_inf": float(np.abs(rt).max()),
                                       "residual_2": float(et)}], "stagnated"
        if progress:
            progress(rec)
        p, X, r, e = pt, Xt, rt, et
    return p, X, history, "max_iter"


# -------------------------------------------------------------------------- relaxed
def orbit_plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit normal e_n and an orthonormal basis (a, b) of the plane it defines."""
    n = np.asarray(normal, dtype=float).ravel()
    n = n / np.linalg.norm(n)
    t = np.eye(3)[int(np.argmin(np.abs(n)))]
    a = np.cross(n, t)
    a /= np.linalg.norm(a)
    return n, a, np.cross(n, a)


def relaxed_terminal(XN, target: OrbitTarget, mass: float, mu: float):
    """(C (4,), gamma_N^+ (3,), Pi_N^+ (3,)) for a CasADi or NumPy terminal state (SPEC §5).

    C = [|x_N| - r_d; e_n^T x_N; a^T R_N e_1; b^T R_N e_1]; gamma_N^+ inertial, Pi_N^+ = 0 body.
    """
    n, a, b = orbit_plane_basis(target.normal)
    rd = float(target.radius)
    if isinstance(XN, (ca.SX, ca.MX, ca.DM)):
        x, _, R, _ = split_state(XN)
        axis = R[:, 0]
        C = ca.vertcat(ca.norm_2(x) - rd, ca.dot(ca.DM(n), x), ca.dot(ca.DM(a), axis), ca.dot(ca.DM(b), axis))
        gp = mass * np.sqrt(mu / rd) * ca.cross(ca.DM(n), x) / rd
        return C, gp, ca.DM.zeros(3)
    s = unpack_states(XN)
    x, axis = s.x[0], s.R[0][:, 0]
    C = np.array([np.linalg.norm(x) - rd, n @ x, a @ axis, b @ axis])
    return C, mass * np.sqrt(mu / rd) * np.cross(n, x) / rd, np.zeros(3)


def _momentum_scales(problem: ImpulsiveProblem) -> np.ndarray:
    """Characteristic sizes of p = (gamma_0^+, Pi_0^+) (6,): max(|gamma_0|, m L / T) and
    max(|Pi_0|, lambda_max(J) / T).  Used to scale the unknowns and to cap Newton steps."""
    a0 = unpack_states(problem.X0)
    J, T = problem.disc.J, problem.T
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius) if isinstance(problem.terminal, OrbitTarget)
            else np.abs(unpack_states(problem.terminal).x).max())
    sg = max(np.abs(a0.gamma).max(), problem.disc.model.mass * L / T)
    sP = max(np.abs(a0.Pi).max(), np.linalg.eigvalsh(J)[-1] / T)
    return np.r_[np.full(3, sg), np.full(3, sP)]


def relaxed_jacobian(XN: np.ndarray, target: OrbitTarget, Phi: np.ndarray) -> np.ndarray:
    """dC/dp (4 x 6) from Phi: dC/dz_N (4 x 12) times Phi[:, (gamma_0, Pi_0) columns].

    d|x|/dx = x^T/|x|; d(R e1) = R S(zeta) e1 = -R S(e1) zeta.
    """
    n, a, b = orbit_plane_basis(target.normal)
    st = unpack_states(XN)
    x, R = st.x[0], st.R[0]
    dC = np.zeros((4, NZ))
    dC[0, Z_POS] = x / np.linalg.norm(x)
    dC[1, Z_POS] = n
    dAxis = -R @ hat(np.eye(3)[0])
    dC[2, Z_ROT] = a @ dAxis
    dC[3, Z_ROT] = b @ dAxis
    return dC @ Phi[:, P_COLS]


def _transfer_angle(r0: float, r1: float, mu: float, T: float) -> float:
    """Angle travelled in time T on the Hohmann-type ellipse from radius r0 towards r1.

    Starts at periapsis (r0 <= r1) or apoapsis; Kepler's equation by Newton.
    """
    a = 0.5 * (r0 + r1)
    e = abs(r1 - r0) / (r1 + r0)
    n = np.sqrt(mu / a**3)
    M0 = 0.0 if r0 <= r1 else np.pi

    def true_anomaly(M):
        E = M
        for _ in range(50):
            E -= (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        return 2.0 * np.arctan2(np.sqrt(1 + e) * np.sin(E / 2), np.sqrt(1 - e) * np.cos(E / 2))

    return float(np.mod(true_anomaly(M0 + n * T) - true_anomaly(M0), 2 * np.pi))


def relaxed_start_target(problem: ImpulsiveProblem) -> np.ndarray:
    """A point of the relaxed terminal set to aim the feasibility TPBVP at (18-vector).

    x_N: on the target orbit, at the Hohmann transfer angle (:func:`_transfer_angle`)
    from the projection of x_0 onto the orbit plane, turning with the initial orbital
    motion; R_N: columns (+-e_n, x_N/|x_N|, their cross product), the sign of e_n
    the one closer to R_0 e_1.  Momenta: those required after the terminal impulse.
    """
    target = problem.terminal
    n, a, _ = orbit_plane_basis(target.normal)
    s0 = unpack_states(problem.X0)
    x0, g0, R0 = s0.x[0], s0.gamma[0], s0.R[0]
    xp = x0 - (n @ x0) * n
    xp = xp / np.linalg.norm(xp) if np.linalg.norm(xp) > 1e-12 else a
    sigma = 1.0 if n @ np.cross(x0, g0) >= 0 else -1.0
    nu = _transfer_angle(float(np.linalg.norm(x0)), float(target.radius), problem.mu, problem.T)
    c, s = np.cos(sigma * nu), np.sin(sigma * nu)
    xN = float(target.radius) * (c * xp + s * np.cross(n, xp))
    e1 = n if n @ R0[:, 0] >= 0 else -n
    e2 = xN / np.linalg.norm(xN)
    RN = np.column_stack([e1, e2, np.cross(e1, e2)])
    _, gp, Pp = relaxed_terminal(pack_state(xN, np.zeros(3), RN, np.zeros(3)), target, problem.disc.model.mass,
                                 problem.mu)
    return pack_state(xN, gp, RN, Pp)


def relaxed_start(problem: ImpulsiveProblem) -> tuple[np.ndarray, list[dict], str]:
    """Feasible start for the relaxed NLP: Newton-Armijo on the TPBVP towards
    :func:`relaxed_start_target` (Pi_0^+ guessed from the attitude change, then with
    no impulse if that fails).  Returns (p, history records, status)."""
    q = dataclasses.replace(problem, terminal=relaxed_start_target(problem))
    hist: list[dict] = []
    status = "not_run"
    for kind in ("attitude", "rollout"):
        p, _, h, status = _newton_tpbvp(q, _initial_p(q, kind), 1e-12, 50, 1e-4, None)
        hist += [dict(r, phase=f"start_{kind}") for r in h]
        if status == "converged":
            return p, hist, f"converged ({kind} guess)"
    return _initial_p(problem, "rollout"), hist, f"start TPBVP failed: {status}; starting from no impulse"


def _relaxed_nlp(problem: ImpulsiveProblem, p0: np.ndarray, opts: dict, progress):
    """Multiple-shooting NLP of the relaxed case, started from p0.

    Variables (scaled): node states X_k and Cayley vectors c_k in the order of
    :class:`~transcription.direct.NLPLayout` (no controls).  X_0 has x, R fixed and
    (gamma, Pi) = p free.  Constraints: the step defects of
    :func:`~transcription.direct.shooting_defects` (u = 0) and C(X_N) = 0.  Objective:
    sum_i |v_i| of the four impulses, written directly (see the module docstring for
    why not an epigraph).  Returns (p, IPOPT stats, solve seconds, info) with info =
    {'scale': objective scale, 'min_impulse_norm', 'build_s'}.
    """
    t_build = time.perf_counter()
    disc, N, h = problem.disc, problem.N, problem.h
    a0 = unpack_states(problem.X0)
    m = disc.model.mass
    # angular momenta per body axis: J_ii times a rate scale, so that a unit change of any
    # scaled Pi_i turns the body by about the same angle (the spin about the dumbbell's
    # axis, J_11 << J_22, is otherwise 100x too sensitive)
    sg = _momentum_scales(problem)[0]
    rate = max(np.abs(np.linalg.solve(disc.J, a0.Pi[0])).max(), 1.0 / problem.T)
    sPi = np.diag(disc.J) * rate
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius))
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), sPi])
    sC = np.full(3, 0.5 * h * rate)
    lay = NLPLayout(N, [], True)
    w_scale = lay.pack(np.repeat(sX[:, None], N + 1, axis=1), np.zeros((6, 0)), np.repeat(sC[:, None], N, axis=1))
    y = ca.MX.sym("y", lay.n)
    Xs, _, Cs = lay.unpack(y * ca.DM(w_scale))
    D, _ = shooting_defects(disc, h, Xs, Cs, ca.DM.zeros(disc.nw, N), sX)
    XN = Xs[:, -1]
    C, gp, Pp = relaxed_terminal(XN, problem.terminal, m, problem.mu)
    _, g0, _, P0 = split_state(Xs[:, 0])
    _, gN, _, PN = split_state(XN)
    v = ca.horzcat(g0 - ca.DM(a0.gamma[0]), P0 - ca.DM(a0.Pi[0]), gp - gN, Pp - PN)   # 3 x 4 impulses
    norms = ca.sqrt(ca.sum1(v**2)).T
    rd = float(problem.terminal.radius)
    g = ca.vertcat(ca.vec(D), C / ca.DM([rd, rd, 1.0, 1.0]))
    f = ca.sum1(norms) / sg
    ipopt = {"tol": float(opts.get("tol", 1e-10)), "max_iter": int(opts.get("max_iter", 3000)), "print_level": 0,
             "sb": "yes", "hessian_approximation": "exact"}
    ipopt.update(dict(opts.get("options") or {}))
    nlp_opts: dict[str, Any] = {"expand": True, "print_time": False, "ipopt": ipopt}
    if progress is not None:
        nlp_opts["iteration_callback"] = _Progress(lay.n, g.shape[0], progress, sg)
    solver = ca.nlpsol("impulsive_relaxed", "ipopt", {"x": y, "f": f, "g": g}, nlp_opts)
    norms_fn = ca.Function("impulse_norms", [y], [norms])
    # bounds: x_0 and R_0 fixed.  Start: the free rollout from p0
    lbx = np.full(lay.n, -np.inf)
    ubx = np.full(lay.n, np.inf)
    fixed = lay.iX[np.r_[np.arange(X_POS.start, X_POS.stop), np.arange(X_ROT.start, X_ROT.stop)], 0]
    lbx[fixed] = ubx[fixed] = np.asarray(problem.X0)[np.r_[0:3, 6:15]] / w_scale[fixed]
    X = _simulate(problem, p0)
    y0 = lay.pack(X.T, np.zeros((6, 0)), cayley_vectors(X).T) / w_scale
    build_s = time.perf_counter() - t_build
    t0 = time.perf_counter()
    out = solver(x0=y0, lbx=lbx, ubx=ubx, lbg=0.0, ubg=0.0)
    solve_s = time.perf_counter() - t0
    yopt = np.array(out["x"]).ravel()
    Xo, _, _ = lay.unpack(yopt * w_scale)
    p = np.r_[Xo[X_MOM, 0], Xo[X_ANG, 0]]
    info = {"scale": sg, "min_impulse_norm": float(np.min(np.array(norms_fn(yopt)))), "build_s": build_s}
    return p, solver.stats(), solve_s, info


# ---------------------------------------------------------------------------- entry
def _impulses(problem: ImpulsiveProblem, p: np.ndarray, XN: np.ndarray, gp: np.ndarray, Pp: np.ndarray):
    a0, aN = unpack_states(problem.X0), unpack_states(XN)
    return {"dgamma0": p[:3] - a0.gamma[0], "dPi0": p[3:] - a0.Pi[0], "dgammaN": gp - aN.gamma[0], "dPiN": Pp - aN.Pi[0]}


def solve_impulsive(problem: ImpulsiveProblem, progress: Callable[[dict], None] | None = None) -> Solution:
    """Solve an :class:`ImpulsiveProblem` (SPEC §5); see the module docstring.

    Returns a :class:`Solution` with method 'impulsive', solver 'newton-armijo' (TPBVP)
    or 'ipopt' (relaxed); ``impulses`` = {dgamma0, dPi0 (at t = 0), dgammaN, dPiN
    (at t = T)}; cost = sum of the four impulse norms; trajectory = re-simulation
    from X_0^+ (X0 with the post-impulse momenta) with u = 0, its last node being the
    state just *before* the terminal impulse; ``extra['XN_plus']`` is the state after it.
    terminal_error: TPBVP: SPEC §8 error of X_N^+ against Xd (x and vee log R, the
    momenta being matched by the impulse); relaxed: max |C| (metres of |x_N| - r_d etc.).
    """
    opts = dict(problem.options or {})
    disc, N, h = problem.disc, problem.N, problem.h
    t0 = time.perf_counter()
    try:
        p0 = _initial_p(problem, _guess_kind(opts))
    except ValueError as exc:
        p0 = _initial_p(problem, "rollout")
        X = _simulate(problem, p0)
        return Solution(method="impulsive", solver="none", discretization=disc.scheme, N=N, h=h,
                        trajectory=Trajectory(t=h * np.arange(N + 1), X=X), status="invalid_option", message=str(exc),
                        converged=False, cost=float("nan"), terminal_error=float("nan"), iterations=0,
                        build_s=0.0, solve_s=0.0)
    disc.rollout(N)
    if isinstance(problem.terminal, OrbitTarget):
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        p0, start_hist, start_status = relaxed_start(problem)
        start_s = time.perf_counter() - t1
        p, stats, solve_s, out = _relaxed_nlp(problem, p0, opts, progress)
        build_s += out["build_s"]
        solve_s += start_s
        X = _simulate(problem, p)
        C, gp, Pp = relaxed_terminal(X[-1], problem.terminal, disc.model.mass, problem.mu)
        err = float(np.abs(C).max())
        status = str(stats.get("return_status", "unknown"))
        kink = out["min_impulse_norm"] <= KINK_TOL
        ok = status == "Solve_Succeeded" and err <= float(opts.get("terminal_tol", 1e-8)) and not kink
        message = f"IPOPT: {status}; max |C| = {err:.2e} on the re-simulation"
        if kink:
            message += (f"; an impulse norm is {out['min_impulse_norm']:.1e}: the optimum is at a kink of the "
                        "sum of norms, where the smooth formulation does not apply")
        it = stats.get("iterations", {}) or {}
        history = start_hist + [{"phase": "nlp", "iter": i, "objective": float(o) * out["scale"], "inf_pr": float(pr),
                                 "inf_du": float(du)}
                                for i, (o, pr, du) in enumerate(zip(it.get("obj", []), it.get("inf_pr", []),
                                                                    it.get("inf_du", [])))]
        iterations = int(stats.get("iter_count", len(history)))
        solver_name = "ipopt"
        extra = {"ipopt_return_status": status, "kkt_tol": float(opts.get("tol", 1e-10)),
                 "terminal_conditions": C.tolist(), "start_status": start_status,
                 "min_impulse_norm": out["min_impulse_norm"]}
    else:
        Xd = np.asarray(problem.terminal, dtype=float)
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        tol = float(opts.get("newton_tol", NEWTON_TOL))
        first = _guess_kind(opts)
        kinds = [first] + [k for k in ("rollout", "attitude") if k != first and opts.get("fallback", True)]
        history, attempts = [], []
        for kind in kinds:           # Newton may stagnate at a local minimum of |r|: restart from the other guess
            p, X, hist, status = _newton_tpbvp(problem, _initial_p(problem, kind), tol,
                                               int(opts.get("newton_max_iter", NEWTON_MAX_ITER)),
                                               float(opts.get("alpha", 1e-4)), progress)
            history += [dict(r, start=kind) for r in hist]
            attempts.append(f"{kind}: {status} in {len(hist) - 1} iterations")
            if status == "converged":
                break
        solve_s = time.perf_counter() - t1
        d = unpack_states(Xd)
        gp, Pp = d.gamma[0], d.Pi[0]
        r = tpbvp_residual(X[-1], Xd)
        err = float(np.abs(r).max())
        ok = status == "converged"
        message = f"Newton-Armijo ({'; '.join(attempts)}); |r|_inf = {err:.2e} (six conditions on x_N, R_N)"
        iterations = len(history) - len(attempts)
        solver_name = "newton-armijo"
        extra = {"residual_inf": err, "newton_status": status, "start": kind}
    imp = _impulses(problem, p, X[-1], gp, Pp)
    cost = float(sum(np.linalg.norm(v) for v in imp.values()))
    XNp = with_momenta(X[-1], np.r_[gp, Pp])
    if not isinstance(problem.terminal, OrbitTarget):
        err = terminal_error_full(XNp, problem.terminal)
    extra["XN_plus"] = XNp
    return Solution(method="impulsive", solver=solver_name, discretization=disc.scheme, N=N, h=h,
                    trajectory=Trajectory(t=h * np.arange(N + 1), X=X), status=status, message=message,
                    converged=bool(ok), cost=cost, terminal_error=float(err), iterations=iterations,
                    build_s=build_s, solve_s=solve_s, impulses=imp, history=history, extra=extra)
