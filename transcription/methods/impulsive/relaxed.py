"""The relaxed impulsive problem (an orbit target, E2): its feasible start, the Phi-based gradient of its
conditions, and its multiple-shooting NLP (``transcription: multiple_shooting``; single shooting is
:mod:`.reduced`).  See the package docstring for the formulation."""
from __future__ import annotations

import time
from dataclasses import replace

import casadi as ca
import numpy as np

from ...geometry.state import cayley_vectors
from ...ocp.estimate import relaxed_start_target
from ...geometry.state import NX, NZ, X_ANG, X_MOM, X_POS, X_ROT, Z_POS, Z_ROT, split_state, unpack_states
from ...geometry.so3 import hat
from ...nlp import blocks
from ...nlp.layouts import NLPLayout
from ...nlp.solvers import ipopt_options, make_ipopt
from ...nlp.structured import Block, StructuredNLP
from ...options import DirectOptions
from ...ocp import Problem, TargetOrbit, TargetState, orbit_conditions
from ...outcome import Iterate
from .sensitivity import P_COLS
from .tpbvp import ImpulsiveSettings, initial_momenta, momentum_scales, simulate_momenta, solve_tpbvp


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


def relaxed_start(problem: Problem, settings: ImpulsiveSettings) -> tuple[np.ndarray, list[Iterate], str]:
    """Feasible start for the relaxed NLP: Newton-Armijo on the TPBVP towards
    :func:`~transcription.strategy.starts.relaxed_start_target` (Pi_0^+ guessed from the attitude change, then with no impulse
    if that fails).  Returns (p, history records, status)."""
    q = problem.replace(terminal=TargetState(relaxed_start_target(problem)), control=problem.control)
    hist: list[Iterate] = []
    status = "not_run"
    for kind in ("interpolate", "rollout"):
        nr, _ = solve_tpbvp(q, initial_momenta(q, kind), replace(settings, newton_tol=1e-12))
        hist += [replace(r, phase=f"start_{kind}") for r in nr.history]
        status = nr.result.value
        if nr.result.successful:
            return nr.x, hist, f"converged ({kind} guess)"
    return initial_momenta(problem, "rollout"), hist, f"start TPBVP failed: {status}; starting from no impulse"


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


def relaxed_nlp(problem: Problem, p0: np.ndarray, options: DirectOptions, progress):
    """Multiple-shooting NLP of the relaxed case (module docstring), started from the rollout of p0.

    Variables (scaled): node states X_k and Cayley vectors c_k (:class:`~transcription.nlp.layouts.NLPLayout`,
    no controls); X_0 has x, R fixed and (gamma, Pi) = p free.  Returns (p, IPOPT stats, build_s,
    solve_s, min impulse norm, objective scale).
    """
    t_build = time.perf_counter()
    disc, N, h = problem.disc, problem.N, problem.h
    a0 = unpack_states(problem.X0)
    sp = relaxed_unknown_scales(problem)
    sg, sPi = sp[0], sp[3:]
    rate = sPi[0] / disc.J[0, 0]
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius))
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), sPi])
    sC = np.full(3, 0.5 * h * rate)
    sG = np.full(3, h * sPi.max())
    lay = NLPLayout(N, [], True)
    w_scale = lay.pack(np.repeat(sX[:, None], N + 1, axis=1), np.zeros((6, 0)), np.repeat(sC[:, None], N, axis=1))
    dyn = blocks.dynamics(disc, True, False)
    initial, terminal, norms0, normsN = relaxed_blocks(problem, sX, sg)
    iV = np.vstack([lay.iX[:, :-1], lay.iC, lay.iX[:, 1:]])
    nlp = StructuredNLP(lay.n, [Block("dynamics", dyn, iV, blocks.dynamics_data(disc, h, sX, sC, None, sG), compile=True),
                                Block("initial", initial, lay.iX[:, 0], np.zeros(0)),
                                Block("terminal", terminal, lay.iX[:, -1], np.zeros(0))], jit=bool(options.jit))
    # the direct method's IPOPT settings (tolerances, 'acceptable' only at a floor, MUMPS, raw options)
    solver = make_ipopt("impulsive_relaxed", nlp, ipopt_options(options), progress, sg, phase="nlp")
    lbx = np.full(lay.n, -np.inf)
    ubx = np.full(lay.n, np.inf)
    fixed = lay.iX[np.r_[np.arange(X_POS.start, X_POS.stop), np.arange(X_ROT.start, X_ROT.stop)], 0]
    lbx[fixed] = ubx[fixed] = problem.X0[np.r_[np.arange(X_POS.start, X_POS.stop), np.arange(X_ROT.start, X_ROT.stop)]] \
        / w_scale[fixed]
    X, _ = simulate_momenta(problem, p0)
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


def relaxed_unknown_scales(problem: Problem) -> np.ndarray:
    """Scales of p = (gamma_0^+, Pi_0^+) for the relaxed problem (6,): the linear momentum scale of
    :func:`~.tpbvp.momentum_scales`; angular momenta per body axis J_ii times a rate scale, so that a unit
    change of any scaled Pi_i turns the body by about the same angle (the spin about the dumbbell's
    axis, J_11 << J_22, is otherwise 100x too sensitive)."""
    disc = problem.disc
    a0 = unpack_states(problem.X0)
    rate = max(np.abs(np.linalg.solve(disc.J, a0.Pi[0])).max(), 1.0 / problem.T)
    return np.r_[np.full(3, momentum_scales(problem)[0]), np.diag(disc.J) * rate]
