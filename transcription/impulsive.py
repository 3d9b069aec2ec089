"""Optimal impulsive control (docs/mathematics.md §5): impulses at t = 0 and t = T, free motion between.

Unknowns p = (gamma_0^+, Pi_0^+) in R^6 (inertial linear momentum, body angular momentum just
after the initial impulse; this order follows the state layout).  X_0^+ = X0 with its momenta
replaced by p; X_N = free rollout of the problem's discretization (u = 0) from X_0^+; the terminal
impulse brings (gamma_N, Pi_N) to the required (gamma_N^+, Pi_N^+).

Sensitivity (eqs. 18-20): Phi = A_{N-1} ... A_0 (12 x 12) is the product of the left-trivialized
step Jacobians ``disc.variation`` along the rollout; since dgamma_0 and dPi_0 are additive tangent
directions, dz_N/dp = Phi[:, (gamma, Pi) columns].  :func:`sensitivity` builds Phi that way;
:func:`sensitivity_ad` differentiates the whole rollout composed with the chart at X_0 and reads
back at X_N (a second AD route, for the tests).

* TPBVP (a state target, E1): the six conditions r(p) = [x_N - x_d; vee log(R_d^T R_N)] = 0 are
  solved by the shared Newton-Armijo (transcription.newton); the Jacobian is
  [Phi_xp; Jr^-1(vee log(R_d^T R_N)) Phi_zeta p] (Jr^-1 the inverse right Jacobian of SO(3), exact
  for the log residual).  The impulses follow: gamma_N^+ = gamma_d, Pi_N^+ = Pi_d.  There is
  nothing left to optimize: the six conditions fix p (a Lambert problem on SE(3)).
* Relaxed (an orbit target, E2): the multiple-shooting NLP of the one builder
  (transcription.nlp): the dynamics blocks with u = 0, x_0 and R_0 fixed, (gamma_0, Pi_0) free, the
  four terminal conditions C = 0 of :func:`~transcription.problem.orbit_conditions` and the cost
  sum_i |v_i| of the four impulses written directly, solved by IPOPT with the exact Hessian from a
  feasible start (:func:`relaxed_start`: a TPBVP to a point of the target set).

  Why no epigraph: the sum of norms is smooth wherever every impulse is nonzero, and at this
  optimum all four are (the solve reports ``min_impulse_norm``; a value near 0 means the optimum
  sits on a kink: Result.kink).  Both smooth epigraphs were tried, |v|^2 <= s^2 and the convex
  perspective form |v|^2/s <= s with s >= 0: IPOPT converged to ~1e-6 and then, when the barrier
  parameter fell, took a huge step along the nearly flat direction of the spin about the
  dumbbell's axis (the cost is invariant to its phase; its curvature is ~1e-5 in scaled units)
  and ended in restoration failure, at N = 100 and N = 800 and with several option sets.
  :func:`relaxed_jacobian` gives the Phi-based gradient dC/dp, used by the tests to check the
  reduced KKT conditions of the returned solution.

Options: the direct method's (:class:`~transcription.options.DirectOptions`): ``tol``,
``max_iter``, ``options`` for the relaxed NLP (``max_iter`` also bounds the TPBVP's Newton
iterations, at most NEWTON_MAX_ITER); ``initial_guess`` 'rollout' (no impulse) or
'interpolate' (Pi_0^+ = J log(R_0^T R_d)/T) for the TPBVP, which restarts from the other guess if
Newton fails from the first; ``terminal_tol`` the largest max |C| of a converged relaxed solve.
"""
from __future__ import annotations

import time
from functools import lru_cache
from typing import Callable

import casadi as ca
import numpy as np

from . import blocks
from .guess import cayley_vectors
from .layout import NX, NZ, X_ANG, X_MOM, X_POS, X_ROT, Z_ANG, Z_MOM, Z_POS, Z_ROT, pack_state, split_state, unpack_states
from .lgvi import CAYLEY_TOL
from .lie import chart, hat, log_so3_any, right_jacobian_inv, tangent_readback
from .newton import newton_armijo
from .nlp import Block, StructuredNLP, ipopt_history
from .options import DirectOptions, raw_solver_value
from .problem import Problem, TargetOrbit, TargetState, impulse_cost, orbit_conditions, terminal_error
from .results import Iterate, Result, Solution, Trajectory, result_of_solver_status

#: tangent coordinates of the unknowns p = (gamma_0^+, Pi_0^+) inside z
P_COLS = np.r_[np.arange(Z_MOM.start, Z_MOM.stop), np.arange(Z_ANG.start, Z_ANG.stop)]
P_ROWS_X = np.r_[np.arange(X_MOM.start, X_MOM.stop), np.arange(X_ANG.start, X_ANG.stop)]

#: Newton target for the six TPBVP conditions (|r|_inf) and its iteration limit
NEWTON_TOL = 1e-13
NEWTON_MAX_ITER = 50
#: the TPBVP line search halves down to c ~ 1e-10
NEWTON_MAX_HALVINGS = 34
#: consecutive line-search steps below 1e-2 after which Newton gives up (stagnated)
STAGNATION_STEPS = 8
#: an impulse norm below this at the relaxed optimum means a kink of the cost
KINK_TOL = 1e-8


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
    """Phi = A_{N-1} ... A_0 (12 x 12, eq. 19) along node states X (N+1, 18).

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


# ---------------------------------------------------------------------------- TPBVP
def tpbvp_residual(XN: np.ndarray, Xd: np.ndarray) -> np.ndarray:
    """r = [x_N - x_d; vee log(R_d^T R_N)] (6,): the six conditions of the TPBVP."""
    a, d = unpack_states(XN), unpack_states(Xd)
    return np.concatenate([a.x[0] - d.x[0], log_so3_any(d.R[0].T @ a.R[0])])


def tpbvp_jacobian(XN: np.ndarray, Xd: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """dr/dp (6 x 6) from Phi: rows x and Jr^-1 zeta, columns gamma_0 and Pi_0."""
    e = tpbvp_residual(XN, Xd)[3:]
    return np.vstack([Phi[Z_POS][:, P_COLS], right_jacobian_inv(e) @ Phi[Z_ROT][:, P_COLS]])


def initial_momenta(problem: Problem, kind: str) -> np.ndarray:
    """p from the initial state ('rollout': no impulse) or, for a state target, 'interpolate':
    Pi_0^+ = J log(R_0^T R_d) / T (the constant rate that turns R_0 into R_d)."""
    a = unpack_states(problem.X0)
    p = np.concatenate([a.gamma[0], a.Pi[0]])
    if kind == "interpolate" and isinstance(problem.terminal, TargetState):
        d = unpack_states(problem.terminal.X)
        p[3:] = problem.disc.J @ log_so3_any(a.R[0].T @ d.R[0]) / problem.T
    return p


def _simulate(problem: Problem, p: np.ndarray) -> tuple[np.ndarray, float]:
    """Free rollout (N+1, 18) from X0 with momenta p, and its largest relative Cayley residual."""
    X, res = problem.disc.simulate(with_momenta(problem.X0, p), None, problem.h, problem.N)
    return X, float(np.max(res)) if res.size else 0.0


def momentum_scales(problem: Problem) -> np.ndarray:
    """Characteristic sizes of p = (gamma_0^+, Pi_0^+) (6,): max(|gamma_0|, m L / T) and
    max(|Pi_0|, lambda_max(J) / T).  Used to scale the unknowns and to cap Newton steps."""
    a0 = unpack_states(problem.X0)
    J, T = problem.disc.J, problem.T
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius) if isinstance(problem.terminal, TargetOrbit)
            else np.abs(unpack_states(problem.terminal.X).x).max())
    sg = max(np.abs(a0.gamma).max(), problem.model.mass * L / T)
    sP = max(np.abs(a0.Pi).max(), np.linalg.eigvalsh(J)[-1] / T)
    return np.r_[np.full(3, sg), np.full(3, sP)]


def solve_tpbvp(problem: Problem, p0: np.ndarray, tol: float = NEWTON_TOL, max_iter: int = NEWTON_MAX_ITER,
                alpha: float = 1e-4, progress: Callable[[Iterate], None] | None = None):
    """Newton-Armijo on the six conditions from p0; returns (NewtonResult, X of its last point)."""
    Xd = problem.terminal.X
    memo: dict[bytes, tuple[np.ndarray, float]] = {}

    def rollout(p):
        key = p.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = _simulate(problem, p)
        return memo[key]

    def residual(p):
        X, res = rollout(p)
        return (tpbvp_residual(X[-1], Xd) if np.all(np.isfinite(X[-1])) else np.full(6, np.nan)), res

    def jacobian(p):
        X, _ = rollout(p)
        return tpbvp_jacobian(X[-1], Xd, sensitivity(problem.disc, X, problem.h))

    nr = newton_armijo(p0, residual, jacobian, tol=tol, norm=np.inf, alpha=alpha, max_iter=max_iter,
                       max_halvings=NEWTON_MAX_HALVINGS, aux_tol=CAYLEY_TOL, step_scale=momentum_scales(problem),
                       stagnation_steps=STAGNATION_STEPS, progress=progress)
    return nr, rollout(nr.x)[0]


# -------------------------------------------------------------------------- relaxed
def relaxed_jacobian(XN: np.ndarray, target: TargetOrbit, Phi: np.ndarray) -> np.ndarray:
    """dC/dp (4 x 6) from Phi: dC/dz_N (4 x 12) times Phi[:, (gamma_0, Pi_0) columns].

    d|x|/dx = x^T/|x|; d(R b) = R S(zeta) b = -R S(b) zeta.
    """
    n, a, b = target.plane_basis()
    x, _, R, _ = split_state(XN)
    dC = np.zeros((4, NZ))
    dC[0, Z_POS] = x / np.linalg.norm(x)
    dC[1, Z_POS] = n
    dAxis = -R @ hat(target.body_axis)
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


def relaxed_start_target(problem: Problem) -> np.ndarray:
    """A point of the relaxed terminal set to aim the feasibility TPBVP at (18-vector).

    x_N: on the target orbit, at the Hohmann transfer angle (:func:`_transfer_angle`) from the
    projection of x_0 onto the orbit plane, turning with the initial orbital motion; R_N: the body
    axis along +-e_n (the sign closer to R_0 b), another body axis radial.  Momenta: those
    required after the terminal impulse.
    """
    target: TargetOrbit = problem.terminal
    n, a, _ = target.plane_basis()
    s0 = unpack_states(problem.X0)
    x0, g0, R0 = s0.x[0], s0.gamma[0], s0.R[0]
    xp = x0 - (n @ x0) * n
    xp = xp / np.linalg.norm(xp) if np.linalg.norm(xp) > 1e-12 else a
    sigma = 1.0 if n @ np.cross(x0, g0) >= 0 else -1.0
    nu = _transfer_angle(float(np.linalg.norm(x0)), float(target.radius), problem.model.mu, problem.T)
    c, s = np.cos(sigma * nu), np.sin(sigma * nu)
    xN = float(target.radius) * (c * xp + s * np.cross(n, xp))
    # inertial frame (e_axis, radial, their cross product) carried by the body frame (b, b2, b x b2)
    e_axis = n if n @ (R0 @ target.body_axis) >= 0 else -n
    e_rad = xN / np.linalg.norm(xN)
    b = target.body_axis
    b2 = np.eye(3)[int(np.argmin(np.abs(b)))]
    b2 = b2 - (b2 @ b) * b
    b2 /= np.linalg.norm(b2)
    RN = np.column_stack([e_axis, e_rad, np.cross(e_axis, e_rad)]) @ np.column_stack([b, b2, np.cross(b, b2)]).T
    _, gp, Pp = orbit_conditions(pack_state(xN, np.zeros(3), RN, np.zeros(3)), target, problem.model.mass,
                                 problem.model.mu)
    return pack_state(xN, gp, RN, Pp)


def relaxed_start(problem: Problem) -> tuple[np.ndarray, list[Iterate], str]:
    """Feasible start for the relaxed NLP: Newton-Armijo on the TPBVP towards
    :func:`relaxed_start_target` (Pi_0^+ guessed from the attitude change, then with no impulse
    if that fails).  Returns (p, history records, status)."""
    q = problem.replace(terminal=TargetState(relaxed_start_target(problem)), control=problem.control)
    hist: list[Iterate] = []
    status = "not_run"
    for kind in ("interpolate", "rollout"):
        nr, _ = solve_tpbvp(q, initial_momenta(q, kind), tol=1e-12)
        hist += [_phase(r, f"start_{kind}") for r in nr.history]
        status = nr.result.value
        if nr.result.successful:
            return nr.x, hist, f"converged ({kind} guess)"
    return initial_momenta(problem, "rollout"), hist, f"start TPBVP failed: {status}; starting from no impulse"


def _phase(rec: Iterate, phase: str) -> Iterate:
    from dataclasses import replace

    return replace(rec, phase=phase)


def relaxed_blocks(problem: Problem, sX: np.ndarray, s_obj: float):
    """The boundary blocks of the relaxed NLP (instantiated once; built per problem).

    initial: v = X_0 (scaled) -> cost (|gamma_0 - gamma_0,given| + |Pi_0 - Pi_0,given|) / s_obj.
    terminal: v = X_N -> rows C / (r_d, r_d, 1, 1), cost (|gamma_N^+ - gamma_N| + |Pi_N^+ - Pi_N|) / s_obj.
    """
    a0 = unpack_states(problem.X0)
    target: TargetOrbit = problem.terminal
    rd = float(target.radius)
    v = ca.SX.sym("v", NX)
    X = v * ca.DM(sX)
    _, g0, _, P0 = split_state(X)
    cost0 = (ca.norm_2(g0 - ca.DM(a0.gamma[0])) + ca.norm_2(P0 - ca.DM(a0.Pi[0]))) / s_obj
    none = ca.SX.sym("p", 0)
    initial = ca.Function("impulse_initial", [v, none], [cost0, ca.SX(0, 1)], ["v", "p"], ["cost", "rows"])
    C, gp, Pp = orbit_conditions(X, target, problem.model.mass, problem.model.mu)
    _, gN, _, PN = split_state(X)
    costN = (ca.norm_2(gp - gN) + ca.norm_2(Pp - PN)) / s_obj
    terminal = ca.Function("orbit_terminal", [v, none], [costN, C / ca.DM([rd, rd, 1.0, 1.0])], ["v", "p"],
                           ["cost", "rows"])
    norms = ca.Function("impulse_norms", [v], [ca.vertcat(ca.norm_2(g0 - ca.DM(a0.gamma[0])),
                                                           ca.norm_2(P0 - ca.DM(a0.Pi[0])))])
    normsN = ca.Function("impulse_norms_N", [v], [ca.vertcat(ca.norm_2(gp - gN), ca.norm_2(Pp - PN))])
    return initial, terminal, norms, normsN


def _relaxed_nlp(problem: Problem, p0: np.ndarray, opts: DirectOptions, progress):
    """Multiple-shooting NLP of the relaxed case (module docstring), started from the rollout of p0.

    Variables (scaled): node states X_k and Cayley vectors c_k (:class:`~transcription.direct.NLPLayout`,
    no controls); X_0 has x, R fixed and (gamma, Pi) = p free.  Returns (p, IPOPT stats, build_s,
    solve_s, min impulse norm, objective scale).
    """
    from .direct import NLPLayout, make_ipopt

    t_build = time.perf_counter()
    disc, N, h = problem.disc, problem.N, problem.h
    a0 = unpack_states(problem.X0)
    # angular momenta per body axis: J_ii times a rate scale, so that a unit change of any scaled
    # Pi_i turns the body by about the same angle (the spin about the dumbbell's axis, J_11 << J_22,
    # is otherwise 100x too sensitive)
    sg = momentum_scales(problem)[0]
    rate = max(np.abs(np.linalg.solve(disc.J, a0.Pi[0])).max(), 1.0 / problem.T)
    sPi = np.diag(disc.J) * rate
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius))
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), sPi])
    sC = np.full(3, 0.5 * h * rate)
    sG = np.full(3, h * sPi.max())
    lay = NLPLayout(N, [], True)
    w_scale = lay.pack(np.repeat(sX[:, None], N + 1, axis=1), np.zeros((6, 0)), np.repeat(sC[:, None], N, axis=1))
    dyn = blocks.dynamics(disc, True, False, False)
    initial, terminal, norms0, normsN = relaxed_blocks(problem, sX, sg)
    iV = np.vstack([lay.iX[:, :-1], lay.iC, lay.iX[:, 1:]])
    nlp = StructuredNLP(lay.n, [Block("dynamics", dyn, iV, blocks.dynamics_data(disc, h, sX, sC, None, sG), compile=True),
                                Block("initial", initial, lay.iX[:, 0], np.zeros(0)),
                                Block("terminal", terminal, lay.iX[:, -1], np.zeros(0))], jit=bool(opts.jit))
    ipopt = {"tol": float(opts.tol), "max_iter": int(opts.max_iter), "print_level": 0, "sb": "yes",
             "hessian_approximation": "exact", **{k: raw_solver_value(v) for k, v in opts.options.items()}}
    solver = make_ipopt("impulsive_relaxed", nlp, ipopt, progress, sg, phase="nlp")
    lbx = np.full(lay.n, -np.inf)
    ubx = np.full(lay.n, np.inf)
    fixed = lay.iX[np.r_[np.arange(X_POS.start, X_POS.stop), np.arange(X_ROT.start, X_ROT.stop)], 0]
    lbx[fixed] = ubx[fixed] = problem.X0[np.r_[0:3, 6:15]] / w_scale[fixed]
    X, _ = _simulate(problem, p0)
    y0 = lay.pack(X.T, np.zeros((6, 0)), cayley_vectors(X).T) / w_scale
    build_s = time.perf_counter() - t_build
    t0 = time.perf_counter()
    out = solver(x0=y0, lbx=lbx, ubx=ubx, lbg=nlp.lbg, ubg=nlp.ubg)
    solve_s = time.perf_counter() - t0
    y = np.array(out["x"]).ravel()
    Xo, _, _ = lay.unpack(y * w_scale)
    p = np.r_[Xo[X_MOM, 0], Xo[X_ANG, 0]]
    min_norm = float(min(np.min(np.array(norms0(y[lay.iX[:, 0]]))), np.min(np.array(normsN(y[lay.iX[:, -1]])))))
    return p, solver.stats(), build_s, solve_s, min_norm, sg


# ---------------------------------------------------------------------------- entry
def _impulses(problem: Problem, p: np.ndarray, XN: np.ndarray, gp: np.ndarray, Pp: np.ndarray):
    a0, aN = unpack_states(problem.X0), unpack_states(XN)
    return {"dgamma0": p[:3] - a0.gamma[0], "dPi0": p[3:] - a0.Pi[0], "dgammaN": gp - aN.gamma[0], "dPiN": Pp - aN.Pi[0]}


def solve_impulsive(problem: Problem, opts: DirectOptions, progress: Callable[[Iterate], None] | None = None) -> Solution:
    """Solve an impulsive Problem (module docstring) by the direct method.

    The Solution has solver 'newton-armijo' (TPBVP) or 'ipopt' (relaxed); ``impulses`` =
    {dgamma0, dPi0 (at t = 0), dgammaN, dPiN (at t = T)}; cost = the sum of the four impulse norms;
    trajectory = the re-simulation from X_0^+ (X0 with the post-impulse momenta) with u = 0, its
    last node the state just *before* the terminal impulse (``stats['XN_plus']`` is the state
    after it).  terminal_error: TPBVP: the error of X_N^+ against the target (the momenta are
    matched by the impulse); relaxed: max |C|.
    """
    disc, N = problem.disc, problem.N
    t0 = time.perf_counter()
    disc.rollout(N)
    model = problem.model
    if isinstance(problem.terminal, TargetOrbit):
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        p0, history, start_status = relaxed_start(problem)
        start_s = time.perf_counter() - t1
        p, stats, nlp_build_s, solve_s, min_norm, scale = _relaxed_nlp(problem, p0, opts, progress)
        build_s += nlp_build_s
        solve_s += start_s
        X, _ = _simulate(problem, p)
        C, gp, Pp = orbit_conditions(X[-1], problem.terminal, model.mass, model.mu)
        err = float(np.abs(C).max())
        status = str(stats.get("return_status", "unknown"))
        result = result_of_solver_status(status)
        message = f"IPOPT: {status}; max |C| = {err:.2e} on the re-simulation"
        if result is Result.converged and not err <= opts.terminal_tol:
            result = Result.terminal_error
        if min_norm <= KINK_TOL:
            result = Result.kink
            message += (f"; an impulse norm is {min_norm:.1e}: the optimum is at a kink of the sum of norms, where the "
                        "smooth formulation does not apply")
        history = history + ipopt_history(stats, scale, phase="nlp")
        iterations = int(stats.get("iter_count", 0))
        solver_name = "ipopt"
        extra = {"solver_status": status, "kkt_tol": float(opts.tol), "terminal_conditions": C.tolist(),
                 "start_status": start_status, "min_impulse_norm": min_norm}
    else:
        Xd = problem.terminal.X
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        first = opts.initial_guess
        history, attempts, iterations = [], [], 0
        for kind in (first, "rollout" if first == "interpolate" else "interpolate"):
            # Newton may stagnate at a local minimum of |r|: restart from the other guess
            nr, X = solve_tpbvp(problem, initial_momenta(problem, kind), max_iter=min(opts.max_iter, NEWTON_MAX_ITER),
                                progress=progress)
            history += [_phase(r, kind) for r in nr.history]
            attempts.append(f"{kind}: {nr.result.value} in {nr.iterations} iterations")
            iterations += nr.iterations
            if nr.result.successful:
                break
        solve_s = time.perf_counter() - t1
        p, result = nr.x, nr.result
        d = unpack_states(Xd)
        gp, Pp = d.gamma[0], d.Pi[0]
        r = tpbvp_residual(X[-1], Xd)
        message = f"Newton-Armijo ({'; '.join(attempts)}); |r|_inf = {np.abs(r).max():.2e} (six conditions on x_N, R_N)"
        if nr.rejected_aux and not result.successful:
            message += (f"; {len(nr.rejected_aux)} trials were rejected because a Cayley equation was not solved "
                        f"(residual up to {max(nr.rejected_aux):.1e}): use a smaller step h = T/N (increase horizon.N)")
        solver_name = "newton-armijo"
        extra = {"residual_inf": float(np.abs(r).max()), "newton_status": nr.result.value, "start": kind}
    imp = _impulses(problem, p, X[-1], gp, Pp)
    XNp = with_momenta(X[-1], np.r_[gp, Pp])
    if isinstance(problem.terminal, TargetState):
        err = terminal_error(X[-1], problem, XN_plus=XNp)
    extra["XN_plus"] = XNp
    return Solution(method="direct", solver=solver_name, result=result, message=message,
                    trajectory=Trajectory(t=problem.h * np.arange(N + 1), X=X, mass=model.mass, inertia=model.inertia),
                    cost=impulse_cost(imp), terminal_error=float(err), iterations=iterations, build_s=build_s,
                    solve_s=solve_s, problem=problem, impulses=imp, history=history, stats=extra)
