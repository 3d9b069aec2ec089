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
* Relaxed (an orbit target, E2): the four terminal conditions C = 0 of
  :func:`~transcription.problem.orbit_conditions`, the post-impulse momenta they require, and the
  cost sum_i |v_i| of the four impulses written directly, from a feasible start
  (:func:`relaxed_start`: a TPBVP to a point of the target set).  Two transcriptions
  (``DirectOptions.transcription``):

  - ``single_shooting`` (default; the paper's formulation): the six unknowns p, X_N(p) by the free
    rollout, four constraints.  :class:`ReducedRelaxed` gives exact derivatives: dX_N/dp by the
    forward sweep of the step Jacobians (Phi, in ambient coordinates) and the Hessian of the
    Lagrangian by the second-order adjoint sweep; the per-step Functions are compiled to C
    (``jit``).  :func:`_relaxed_reduced` is Newton's method on the constraint manifold (a
    feasible-point SQP: null-space Newton step, projection back onto C = 0, Armijo on the cost).
    A plain SQP with an l1 merit function crawled (see there): the terminal conditions are
    strongly curved in p.  At N = 800 it takes 6 iterations (22 rollouts) against IPOPT's 127 on the multiple-shooting NLP below.
  - ``multiple_shooting``: the NLP of the one builder (transcription.nlp) -- the dynamics blocks
    with u = 0, x_0 and R_0 fixed, (gamma_0, Pi_0) free -- solved by IPOPT with the exact Hessian.
    An independent formulation of the same problem (the tests compare the two optima).  Along the
    spin about the dumbbell's axis the cost is nearly flat (reduced curvature 5e-5 .. 1e-3 in scaled
    units) with several minima: at N = 400 single shooting stops at 2.51878 and multiple shooting
    at 2.47736 from the same start (both are local minima; at N = 100 and 800 the two agree).

  Why no epigraph: the sum of norms is smooth wherever every impulse is nonzero, and at this
  optimum all four are (the solve reports ``min_impulse_norm``; a value near 0 means the optimum
  sits on a kink: Result.kink).  Both smooth epigraphs were tried, |v|^2 <= s^2 and the convex
  perspective form |v|^2/s <= s with s >= 0: IPOPT converged to ~1e-6 and then, when the barrier
  parameter fell, took a huge step along the nearly flat direction of the spin about the
  dumbbell's axis (the cost is invariant to its phase; its curvature is ~1e-5 in scaled units)
  and ended in restoration failure, at N = 100 and N = 800 and with several option sets.
  :func:`relaxed_jacobian` gives the Phi-based gradient dC/dp, used by the tests to check the
  reduced KKT conditions of the returned solution.

Options: the direct method's (:class:`~transcription.options.DirectOptions`): ``transcription``
(relaxed); ``tol``, ``max_iter`` (single shooting: the scaled reduced gradient and the iteration
limit; multiple shooting: IPOPT's; ``max_iter`` also bounds the TPBVP's Newton iterations, at
most NEWTON_MAX_ITER); ``options`` (raw IPOPT options, multiple shooting); ``jit``; ``initial_guess`` 'rollout' (no impulse) or
'interpolate' (Pi_0^+ = J log(R_0^T R_d)/T) for the TPBVP, which restarts from the other guess if
Newton fails from the first; ``terminal_tol`` the largest max |C| of a converged relaxed solve.
"""
from __future__ import annotations

import dataclasses
import time
from functools import lru_cache
from typing import Callable

import casadi as ca
import numpy as np

from . import blocks
from .guess import cayley_vectors
from .layout import NX, NZ, X_ANG, X_MOM, X_POS, X_ROT, Z_ANG, Z_MOM, Z_POS, Z_ROT, pack_state, split_state, unpack_states
from .lgvi import CAYLEY_TOL
from . import codegen
from .lie import chart, hat, log_so3_any, right_jacobian_inv, tangent_readback
from .newton import newton_armijo
from .nlp import Block, StructuredNLP, ipopt_history
from .options import DirectOptions
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
#: single shooting of the relaxed case: the step cap in scaled unknowns
MAX_STEP = 1.0


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
    from .direct import NLPLayout, ipopt_options, make_ipopt

    t_build = time.perf_counter()
    disc, N, h = problem.disc, problem.N, problem.h
    a0 = unpack_states(problem.X0)
    sp = _relaxed_unknown_scales(problem)
    sg, sPi = sp[0], sp[3:]
    rate = sPi[0] / disc.J[0, 0]
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
    # the direct method's IPOPT settings (tolerances, 'acceptable' only at a floor, MUMPS, raw options)
    solver = make_ipopt("impulsive_relaxed", nlp, ipopt_options(opts), progress, sg, phase="nlp")
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


# ------------------------------------------------------------- relaxed: single shooting
def _relaxed_unknown_scales(problem: Problem) -> np.ndarray:
    """Scales of p = (gamma_0^+, Pi_0^+) for the relaxed problem (6,): the linear momentum scale of
    :func:`_momentum_scales`; angular momenta per body axis J_ii times a rate scale, so that a unit
    change of any scaled Pi_i turns the body by about the same angle (the spin about the dumbbell's
    axis, J_11 << J_22, is otherwise 100x too sensitive)."""
    disc = problem.disc
    a0 = unpack_states(problem.X0)
    rate = max(np.abs(np.linalg.solve(disc.J, a0.Pi[0])).max(), 1.0 / problem.T)
    return np.r_[np.full(3, momentum_scales(problem)[0]), np.diag(disc.J) * rate]


@lru_cache(maxsize=None)
def _free_step_derivatives(disc, jit: bool) -> tuple[ca.Function, ca.Function, ca.Function]:
    """Per-step derivative Functions of the free step F (u = 0) in ambient coordinates (R as 9 numbers).

    ``free_fwd``  (S[18x6], X[18], c0[3], h) -> dF/dX S           (forward sensitivity, 6 directions)
    ``free_adj``  (mu[18], X[18], c0[3], h)  -> dF/dX^T mu        (adjoint)
    ``free_hess`` (X[18], c0[3], h, mu[18], S[18x6]) -> S^T d2(mu^T F)/dX2 S (6 x 6)

    All differentiate ``disc.step_seeded`` seeded with the step's Cayley root c0, whose first to
    third derivatives equal those of the solved step (lgvi.py).  The rollout X_N(p) = F o ... o F
    (X_0(p)) is a composition of maps R^18 -> R^18 with X_0 affine in p, so the chain rule in
    ambient coordinates is exact and needs no chart.  jit: compiled to C (codegen.compiled, which
    falls back to the interpreter).
    """
    X, c0, h = ca.SX.sym("X", NX), ca.SX.sym("c0", 3), ca.SX.sym("h")
    mu, S, q = ca.SX.sym("mu", NX), ca.SX.sym("S", NX, 6), ca.SX.sym("q", 6)
    w0 = ca.DM.zeros(disc.nw)
    F = disc.step_seeded(X, w0, h, c0)
    fwd = ca.Function(f"{disc.scheme}_free_fwd", [S, X, c0, h], [ca.jtimes(F, X, S)], ["S", "X", "c0", "h"], ["S1"])
    adj = ca.Function(f"{disc.scheme}_free_adj", [mu, X, c0, h], [ca.jtimes(F, X, mu, True)],
                      ["mu", "X", "c0", "h"], ["mu0"])
    Hq = ca.hessian(ca.dot(mu, disc.step_seeded(X + ca.mtimes(S, q), w0, h, c0)), q)[0]
    hess = ca.Function(f"{disc.scheme}_free_hess", [X, c0, h, mu, S], [ca.substitute(Hq, q, ca.DM.zeros(6))],
                       ["X", "c0", "h", "mu", "S"], ["T"])
    if jit:
        fwd, adj, hess = (codegen.compiled(f) for f in (fwd, adj, hess))
    return fwd, adj, hess


@lru_cache(maxsize=None)
def _rollout_derivatives(disc, N: int, jit: bool) -> tuple[ca.Function, ca.Function]:
    """Sweeps over N free steps along given nodes X (18 x N, nodes 0..N-1) and Cayley roots (3 x N).

    ``sens`` (X, roots, h, S0[18x6]) -> S_N = dX_N/dX_0 S0
    ``hess`` (X, roots, h, S0, muN[18]) -> sum_k S_k^T d2(mu_{k+1}^T F)/dX2 S_k, with S_{k+1} = A_k S_k
             and mu_k = A_k^T mu_{k+1} (A_k = dF/dX at node k), mu_N = muN.
    Only small arrays cross into Python (the per-step matrices stay inside CasADi).
    """
    fwd, adj, hess = _free_step_derivatives(disc, jit)
    X, roots, h = ca.MX.sym("X", NX, N), ca.MX.sym("roots", 3, N), ca.MX.sym("h")
    S0, muN = ca.MX.sym("S0", NX, 6), ca.MX.sym("muN", NX)
    H = ca.repmat(h, 1, N)
    S = fwd.mapaccum(f"{disc.scheme}_free_fwd_acc{N}", N)(S0, X, roots, H)        # S_1 .. S_N
    sens = ca.Function(f"{disc.scheme}_free_sens{N}", [X, roots, h, S0], [S[:, -6:]], ["X", "roots", "h", "S0"], ["SN"])
    rev = list(range(N - 1, -1, -1))
    mu = adj.mapaccum(f"{disc.scheme}_free_adj_acc{N}", N)(muN, X[:, rev], roots[:, rev], H)  # mu_{N-1} .. mu_0
    mu1 = ca.horzcat(mu[:, rev[1:]], muN)                                                     # mu_1 .. mu_N
    Sk = ca.horzcat(S0, S[:, : 6 * (N - 1)])                                                  # S_0 .. S_{N-1}
    T = hess.map(N)(X, roots, H, mu1, Sk)
    Tsum = ca.mtimes(T, ca.repmat(ca.DM.eye(6), N, 1))
    hfn = ca.Function(f"{disc.scheme}_free_hess{N}", [X, roots, h, S0, muN], [Tsum], ["X", "roots", "h", "S0", "muN"],
                      ["T"])
    return sens, hfn


class ReducedRelaxed:
    """The relaxed problem in the six unknowns p only (single shooting), in scaled variables y = p / s_y.

    f(y) = (|p_gamma - gamma_0| + |p_Pi - Pi_0| + |gamma_N^+(x_N) - gamma_N| + |Pi_N|) / s_f,
    c(y) = C(X_N(p)) / (r_d, r_d, 1, 1), X_N(p) the free rollout from X_0^+.  Exact first and second
    derivatives: S_k = dX_k/dy (18 x 6, ambient) by S_{k+1} = A_k S_k, S_0 = the momentum columns;
    S_N read back to tangent coordinates is Phi[:, (gamma_0, Pi_0)] diag(s_y) (the tests check it
    against :func:`sensitivity`).  The Hessian of L = f + lam^T c is the second-order adjoint
    S_N^T d2l/dX_N2 S_N + sum_k S_k^T d2(mu_{k+1}^T F)/dX2 S_k + d2f_0/dy2 with mu_N = dl/dX_N
    and mu_k = A_k^T mu_{k+1} (l = the X_N-dependent part of L; f_0 the initial-impulse part).
    """

    def __init__(self, problem: Problem, jit: bool = True):
        self.problem = problem
        disc, N = problem.disc, problem.N
        self.sy = _relaxed_unknown_scales(problem)
        self.sf = float(self.sy[0])
        rd = float(problem.terminal.radius)
        self.sc = np.array([rd, rd, 1.0, 1.0])
        a0 = unpack_states(problem.X0)
        XN, y, lam = ca.SX.sym("XN", NX), ca.SX.sym("y", 6), ca.SX.sym("lam", 4)
        C, gp, Pp = orbit_conditions(XN, problem.terminal, problem.model.mass, problem.model.mu)
        _, gN, _, PN = split_state(XN)
        p = y * ca.DM(self.sy)
        f0 = (ca.norm_2(p[:3] - ca.DM(a0.gamma[0])) + ca.norm_2(p[3:] - ca.DM(a0.Pi[0]))) / self.sf
        fN = (ca.norm_2(gp - gN) + ca.norm_2(Pp - PN)) / self.sf
        c = C / ca.DM(self.sc)
        ell = fN + ca.dot(lam, c)
        self.value_fn = ca.Function("reduced_value", [XN, y], [f0 + fN, c])
        self.first_fn = ca.Function("reduced_first", [XN, y], [ca.gradient(fN, XN), ca.jacobian(c, XN),
                                                              ca.gradient(f0, y)])
        self.second_fn = ca.Function("reduced_second", [XN, y, lam], [ca.hessian(ell, XN)[0], ca.hessian(f0, y)[0]])
        self.sens_fn, self.hess_fn = _rollout_derivatives(disc, N, jit)
        self.S0 = np.zeros((NX, 6))
        self.S0[P_ROWS_X, np.arange(6)] = self.sy

    def p(self, y: np.ndarray) -> np.ndarray:
        return self.sy * y

    def rollout(self, y: np.ndarray) -> np.ndarray:
        """Node states (N+1, 18); NaN if a Cayley solve failed."""
        X, res = _simulate(self.problem, self.p(y))
        return X if res <= CAYLEY_TOL else np.full_like(X, np.nan)

    def value(self, X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
        f, c = self.value_fn(X[-1], y)
        return float(f), np.array(c).ravel()

    def first(self, X: np.ndarray, y: np.ndarray) -> dict:
        """grad f (6,), Jacobian of c (4 x 6), S_N = dX_N/dy (18 x 6) and the Cayley roots."""
        roots = cayley_vectors(X).T
        SN = np.array(self.sens_fn(X[:-1].T, roots, self.problem.h, self.S0))
        dfN, dc, df0 = (np.array(v) for v in self.first_fn(X[-1], y))
        return {"g": SN.T @ dfN.ravel() + df0.ravel(), "Jc": dc @ SN, "SN": SN, "roots": roots,
                "dfN": dfN.ravel(), "dc": dc}

    def hessian(self, X: np.ndarray, y: np.ndarray, lam: np.ndarray, d1: dict) -> np.ndarray:
        """Exact Hessian of L = f + lam^T c in y (6 x 6), the second-order adjoint of the class docstring."""
        SN = d1["SN"]
        muN = d1["dfN"] + d1["dc"].T @ lam
        HX, H0 = (np.array(v) for v in self.second_fn(X[-1], y, lam))
        T = np.array(self.hess_fn(X[:-1].T, d1["roots"], self.problem.h, self.S0, muN))
        H = SN.T @ HX @ SN + H0 + T
        return 0.5 * (H + H.T)


def _null_space(Jc: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the null space of a full-row-rank Jc (m x n) -> (n x (n - m))."""
    Q, _ = np.linalg.qr(Jc.T, mode="complete")
    return Q[:, Jc.shape[0]:]


#: the projection onto c = 0 stops at |c|_inf <= this (scaled); below the test tolerances, above round-off
PROJECTION_TOL = 1e-12
PROJECTION_MAX_ITER = 8


class _Point:
    """A point y of the reduced problem with its rollout, values and (lazily) first derivatives."""

    def __init__(self, red: ReducedRelaxed, y: np.ndarray, X: np.ndarray | None = None):
        self.red, self.y = red, y
        self.X = red.rollout(y) if X is None else X
        self.f, self.c = red.value(self.X, y)
        self._d1 = None

    @property
    def ok(self) -> bool:
        return bool(np.isfinite(self.f) and np.all(np.isfinite(self.c)))

    @property
    def d1(self) -> dict:
        if self._d1 is None:
            self._d1 = self.red.first(self.X, self.y)
        return self._d1


def _project(pt: _Point, tol: float, max_iter: int, damped: bool) -> tuple[_Point, int, bool]:
    """Minimum-norm Newton onto c(y) = 0: y <- y - Jc^T (Jc Jc^T)^-1 c(y), Jc fresh at every iterate.

    damped: Armijo backtracking on |c|_2 (to reach the constraint set from afar); otherwise an
    iterate must halve |c|_2 or the projection fails (a line-search trial is then shortened).
    Returns (point, rollouts, success)."""
    n = 0
    for _ in range(max_iter + 1):
        if not pt.ok:
            return pt, n, False
        e = float(np.linalg.norm(pt.c))
        if np.abs(pt.c).max() <= tol:
            return pt, n, True
        Jc = pt.d1["Jc"]
        dy = -Jc.T @ np.linalg.solve(Jc @ Jc.T, pt.c)
        a = 1.0
        while True:
            trial = _Point(pt.red, pt.y + a * dy)
            n += 1
            et = float(np.linalg.norm(trial.c)) if trial.ok else np.inf
            if et <= (1.0 - 1e-4 * a) * e if damped else et <= 0.5 * e:
                break
            if not damped or a < 1e-6:
                return trial, n, False
            a *= 0.5
        pt = trial
    return pt, n, bool(pt.ok and np.abs(pt.c).max() <= tol)


def _relaxed_reduced(problem: Problem, p0: np.ndarray, opts: DirectOptions, progress):
    """Single shooting of the relaxed case in the six unknowns p, started from p0.

    Newton's method on the constraint manifold c(y) = 0 (a feasible-point SQP, as in the
    generalized reduced gradient method): at a feasible y the step is the SQP step with c = 0,
    d = -Z (Z^T H Z)^-1 Z^T g, Z an orthonormal basis of null(Jc), H the exact Hessian of the
    Lagrangian at the least-squares multipliers (:class:`ReducedRelaxed`); a trial y + alpha d is
    projected back onto c = 0 (:func:`_project`) and accepted when the cost decreases (Armijo on
    g^T d), else alpha is halved.  Z^T H Z is shifted to positive definite if it is not; steps are
    capped at MAX_STEP (scaled units).  A start off the constraint set is projected
    first.  Converged when |g + Jc^T lambda|_inf <= tol (the reduced gradient, scaled) at a point
    with |c|_inf <= 1e-12.

    Why not a plain SQP: the terminal conditions are strongly curved in p (a tangent step of
    scaled length 0.5 leaves |c| ~ 1e-2), so an l1-merit line search with a second-order
    correction crawled at steps 1/128 (N = 100: 3000 iterations at cost 2.5004 against 2.4767).

    Returns (p, result, iterations, history, rollouts, build_s, solve_s, min impulse norm, multipliers).
    """
    t_build = time.perf_counter()
    red = ReducedRelaxed(problem, jit=bool(opts.jit))
    build_s = time.perf_counter() - t_build
    t0 = time.perf_counter()
    tol, max_iter, max_step = float(opts.tol), int(opts.max_iter), MAX_STEP
    eta = 1e-4
    history: list[Iterate] = []
    pt = _Point(red, np.asarray(p0, dtype=float) / red.sy)
    pt, rollouts, ok = _project(pt, PROJECTION_TOL, 50, damped=True)
    rollouts += 1
    result = Result.max_iterations if ok else Result.infeasible
    for it in range(max_iter + 1 if ok else 0):
        g, Jc = pt.d1["g"], pt.d1["Jc"]
        lam = np.linalg.lstsq(Jc.T, -g, rcond=None)[0]
        Z = _null_space(Jc)
        rg = Z.T @ g
        inf_du = float(np.abs(g + Jc.T @ lam).max())
        rec = Iterate(iteration=it, cost=pt.f * red.sf, residual=float(np.abs(pt.c).max()), dual=inf_du, phase="sqp",
                      elapsed_s=time.perf_counter() - t0)
        if inf_du <= tol:
            result = Result.converged
            history.append(rec)
            if progress:
                progress(rec)
            break
        if it == max_iter:
            history.append(rec)
            break
        Hr = Z.T @ red.hessian(pt.X, pt.y, lam, pt.d1) @ Z
        ev = np.linalg.eigvalsh(Hr)
        delta = 0.0 if ev[0] > 1e-12 * max(1.0, ev[-1]) else -ev[0] + 1e-4 * max(1.0, abs(ev[-1]))
        d = -Z @ np.linalg.solve(Hr + delta * np.eye(Hr.shape[0]), rg)
        d *= min(1.0, max_step / max(np.abs(d).max(), 1e-300))
        D = float(g @ d)
        alpha, accepted = 1.0, False
        while alpha >= 1e-8:
            trial, n, ok = _project(_Point(red, pt.y + alpha * d), PROJECTION_TOL, PROJECTION_MAX_ITER, damped=False)
            rollouts += n + 1
            # compare f + lam^T c (the trial and pt satisfy c = 0 only to PROJECTION_TOL, which moves f by
            # lam^T c, more than the last Newton steps gain); allow 10 ulp of |f| for round-off
            slack = 10 * np.finfo(float).eps * abs(pt.f)
            if ok and trial.f + lam @ trial.c <= pt.f + lam @ pt.c + eta * alpha * D + slack:
                accepted = True
                break
            alpha *= 0.5
        rec = dataclasses.replace(rec, step=alpha)
        history.append(rec)
        if progress:
            progress(rec)
        if not accepted:
            result = Result.line_search_failed
            break
        pt = trial
    solve_s = time.perf_counter() - t0
    C, gp, Pp = orbit_conditions(pt.X[-1], problem.terminal, problem.model.mass, problem.model.mu)
    imp = _impulses(problem, red.p(pt.y), pt.X[-1], gp, Pp)
    multipliers = None
    if pt._d1 is not None:
        lam = np.linalg.lstsq(pt.d1["Jc"].T, -pt.d1["g"], rcond=None)[0]
        multipliers = (lam * red.sf / red.sc).tolist()
    return (red.p(pt.y), result, max(len(history) - 1, 0), history, rollouts, build_s, solve_s,
            float(min(np.linalg.norm(v) for v in imp.values())), multipliers)


# ---------------------------------------------------------------------------- entry
def _impulses(problem: Problem, p: np.ndarray, XN: np.ndarray, gp: np.ndarray, Pp: np.ndarray):
    a0, aN = unpack_states(problem.X0), unpack_states(XN)
    return {"dgamma0": p[:3] - a0.gamma[0], "dPi0": p[3:] - a0.Pi[0], "dgammaN": gp - aN.gamma[0], "dPiN": Pp - aN.Pi[0]}


def solve_impulsive(problem: Problem, opts: DirectOptions, progress: Callable[[Iterate], None] | None = None) -> Solution:
    """Solve an impulsive Problem (module docstring) by the direct method.

    The Solution has solver 'newton-armijo' (TPBVP), 'sqp' (relaxed, single shooting) or 'ipopt'
    (relaxed, multiple shooting); ``impulses`` =
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
        extra = {"transcription": opts.transcription}
        if opts.transcription == "multiple_shooting":
            p, stats, nlp_build_s, solve_s, min_norm, scale = _relaxed_nlp(problem, p0, opts, progress)
            status = str(stats.get("return_status", "unknown"))
            result = result_of_solver_status(status)
            history = history + ipopt_history(stats, scale, phase="nlp")
            iterations = int(stats.get("iter_count", 0))
            solver_name, label = "ipopt", "IPOPT"
            extra["solver_status"] = status
        else:
            p, result, iterations, hist, rollouts, nlp_build_s, solve_s, min_norm, multipliers = _relaxed_reduced(
                problem, p0, opts, progress)
            status = result.value
            history = history + hist
            solver_name, label = "sqp", f"single-shooting SQP ({iterations} iterations, {rollouts} rollouts)"
            extra.update(multipliers=multipliers, rollouts=rollouts)
        build_s += nlp_build_s
        solve_s += start_s
        X, _ = _simulate(problem, p)
        C, gp, Pp = orbit_conditions(X[-1], problem.terminal, model.mass, model.mu)
        err = float(np.abs(C).max())
        message = f"{label}: {status}; max |C| = {err:.2e} on the re-simulation"
        if result is Result.converged and not err <= opts.terminal_tol:
            result = Result.terminal_error
        if min_norm <= KINK_TOL:
            result = Result.kink
            message += (f"; an impulse norm is {min_norm:.1e}: the optimum is at a kink of the sum of norms, where the "
                        "smooth formulation does not apply")
        extra.update({"kkt_tol": float(opts.tol), "terminal_conditions": C.tolist(), "start_status": start_status,
                      "min_impulse_norm": min_norm})
    else:
        Xd = problem.terminal.X
        build_s = time.perf_counter() - t0
        t1 = time.perf_counter()
        first = "interpolate" if opts.initial_guess == "interpolate" else "rollout"  # auto: rollout first
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
