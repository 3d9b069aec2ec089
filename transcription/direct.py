"""Direct method: multiple-shooting NLP on the discrete equations, solved by IPOPT.

Problem (SPEC §6, :class:`~transcription.problem.SmoothProblem`)::

    min  sum_j  omega_j * (1/2) u_j^T W u_j,        W = diag(W_f, W_m)
    s.t. X_{k+1} = step(X_k, w_k, h),   k = 0..N-1   (eqs. 7-11 or 21-25)
         X_0 = X0,   x_N, gamma_N, Pi_N = desired,   vee log(R_d^T R_N) = 0

with quadrature weights omega_j = h for the first-order scheme (controls u_1..u_N,
which is SPEC §6's sum (h/2) u^T W u) and the trapezoidal weights h (1/2, 1, ..., 1, 1/2)
for the LGVI scheme (node controls u_0..u_N; u_0 and u_N are priced h/2), so that
both approximate the integral of (1/2) u^T W u.

Transcription
-------------
Decision variables per node k = 0..N (see :class:`NLPLayout`, the only place that
knows the order): the state X_k (18), the node control u_k (6; first_order: nodes
1..N, lgvi: nodes 0..N) and, with ``options['cayley_variables']`` (default True),
the Cayley vector c_k (3) of step k = 0..N-1.  With c_k as unknowns every defect
is explicit: X_{k+1} - step_given_c(X_k, c_k, w_k, h) = 0 (18 rows) and the Cayley
equation G(c_k; g(X_k, w_k)) = 0 (3 rows, SPEC §2); without them the defect uses
the Newton-solved step (8 unrolled Newton iterations in every Hessian).
One stage Function is built and ``map``-ped over the horizon; the NLP is
SX-expanded and IPOPT uses the exact Hessian.  X_0 is fixed by its bounds.

Scaling (:func:`characteristic_scales`): every variable is divided by a characteristic
magnitude (positions by the orbit size, momenta by their boundary values or what the
horizon requires, controls by momentum change over the horizon, c by h |Omega| / 2),
every constraint row by the magnitude of its variable, and the objective by its value
at the characteristic controls.  The control scales are then balanced so that no
control's cost curvature W_i s_i^2 is below ``BALANCE`` = 1e-2 of the largest: with
W_m = I (SPEC §7 note) the moment directions would otherwise carry a scaled Hessian of
~1e-8, IPOPT's inertia correction swamps them and the solve stalls at
"Solved_To_Acceptable_Level" (measured, E3 N = 100); balanced it reaches
Solve_Succeeded (the optimal moments are then ~100x larger than with W_m = 1e4 I:
cheap moments tumble the body to use gravity-gradient forces).

Costates (hand-off to the indirect method, SPEC §6)
--------------------------------------------------
Write the Lagrangian of the unscaled NLP as

    L = J + sum_k nu_k^T (step(X_k, w_k, h) - X_{k+1}) + (terminal and Cayley terms),

nu_k in R^18 the multiplier of the step-k defect *written as step minus next state*.
``Solution.costates[k]`` (k = 0..N-1, shape (N, 12)) is lambda_k = D(X_{k+1})^T nu_k,
where D(X) maps tangent coordinates z = [dx; dgamma; zeta; dPi] (SPEC §4, dR = R S(zeta))
to dX.  With this sign the discrete necessary conditions read

    lambda_{k-1} = A_k^T lambda_k                       (SPEC eq. 28)
    sum over steps touching u_j of B^T lambda + omega_j W u_j = 0,

i.e. for the first-order scheme u_{k+1} = -W^-1 [lambda^2_k; lambda^4_k]  (eqs. 26-27),
where (A_k, B_k) = ``disc.variation`` at (X_k, w_k).  Both are tested.  With the
Cayley vectors as unknowns the 18 rows are X_{k+1} - step_given_c(X_k, c_k, w_k) (the
solver sees ``step_given_c - X_{k+1}``) and the Cayley rows carry their own multipliers;
eliminating those gives the same nu_k as for the Newton-solved step.  D and the
costates are evaluated at the NLP's node states (equal to the re-simulation to the
defect tolerance).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable

import casadi as ca
import numpy as np

from . import codegen
from .guess import Guess, cayley_vectors, make_guess
from .layout import NU, NX, NZ, X_ANG, X_MOM, X_POS, X_ROT, split_state, unpack_states
from .lie import hat, log_so3
from .problem import SmoothProblem
from .results import Solution, SolverOptionError, Trajectory, terminal_error_full

NC = 3  # Cayley vector
SOLVERS = ("ipopt", "fatrop")
BALANCE = 1e-2  # smallest allowed ratio of scaled control cost curvatures (characteristic_scales)

#: MUMPS settings for this (already scaled, banded) KKT system: AMD ordering, no permuting scaling.
#: Measured on E3 first_order N = 1000: the IPOPT call fell 1.9 s -> 0.7 s (MUMPS' automatic
#: ordering and its maximum-transversal scaling cost more than they bring here).  Raw ``options``
#: override them.
MUMPS_DEFAULTS: dict[str, Any] = {"mumps_permuting_scaling": 0, "mumps_pivot_order": 0}

#: options read from ``problem.options`` (the YAML ``solver.direct`` block) and their defaults
DIRECT_OPTION_DEFAULTS: dict[str, Any] = {
    "solver": "ipopt",
    "tol": 1e-10,
    "max_iter": 3000,
    "initial_guess": "rollout",
    "options": {},               # raw IPOPT options (e.g. {'print_level': 5, 'linear_solver': 'ma27'})
    "cayley_variables": True,    # c_k as decision variables with G(c_k) = 0 as constraints
    "terminal_tol": 1e-6,        # re-simulated terminal error above which the solve is not "converged"
    "fatrop_options": {},        # raw fatrop options (solver: fatrop), e.g. {'mu_init': 0.1}
    "fatrop_expand": False,      # fatrop: SX-expand the whole NLP (slower build, faster evaluations)
    # compile the stage Jacobian/Hessian to C (transcription/codegen.py): 1-2 s once per machine (cached on
    # disk), then every solve 1.4-1.8x faster; without a compiler (or SE3OCP_NO_JIT=1) the interpreter is used
    "jit": True,
}


# ---------------------------------------------------------------------------- layout
class NLPLayout:
    """Order of the NLP decision vector: node-major blocks [X_k, u_k?, c_k?], k = 0..N.

    X_k (18) at every node; u_k (6) at the nodes that carry a control (``control_nodes``);
    c_k (3) at nodes 0..N-1 when ``with_c``.  :meth:`pack` and :meth:`unpack` are the
    only routines that know the order; they work on NumPy arrays and on CasADi
    column vectors alike.

    Shapes: X (18, N+1) (column k = node k), U (6, n_controls), C (3, N).
    """

    def __init__(self, N: int, control_nodes: list[int] | range, with_c: bool):
        self.N = int(N)
        self.control_nodes = list(control_nodes)
        self.with_c = bool(with_c)
        has_u = np.zeros(self.N + 1, dtype=bool)
        has_u[self.control_nodes] = True
        iX = np.zeros((NX, self.N + 1), dtype=int)
        iU = np.zeros((NU, len(self.control_nodes)), dtype=int)
        iC = np.zeros((NC, self.N if with_c else 0), dtype=int)
        pos, ju = 0, 0
        for k in range(self.N + 1):
            iX[:, k] = np.arange(pos, pos + NX)
            pos += NX
            if has_u[k]:
                iU[:, ju] = np.arange(pos, pos + NU)
                pos += NU
                ju += 1
            if with_c and k < self.N:
                iC[:, k] = np.arange(pos, pos + NC)
                pos += NC
        self.n = pos
        self.iX, self.iU, self.iC = iX, iU, iC

    def unpack(self, w):
        """w (n,) or (n,1) -> (X (18, N+1), U (6, nU), C (3, N) or None), same backend as w."""
        if isinstance(w, (ca.SX, ca.MX, ca.DM)):
            def take(idx):
                return ca.reshape(w[idx.ravel(order="F").tolist()], idx.shape[0], idx.shape[1])
        else:
            w = np.asarray(w, dtype=float).ravel()

            def take(idx):
                return w[idx]
        C = take(self.iC) if self.with_c else None
        return take(self.iX), take(self.iU), C

    def pack(self, X, U, C=None) -> np.ndarray:
        """NumPy (X (18, N+1), U (6, nU), C (3, N)) -> w (n,).  C required iff ``with_c``."""
        w = np.full(self.n, np.nan)
        w[self.iX] = np.asarray(X, dtype=float)
        w[self.iU] = np.asarray(U, dtype=float)
        if self.with_c:
            if C is None:
                raise ValueError("this layout has Cayley variables: C (3, N) is required")
            w[self.iC] = np.asarray(C, dtype=float)
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


# --------------------------------------------------------------------------- scaling
@dataclass(frozen=True)
class Scales:
    """Characteristic magnitudes: state (18,), control (6,), Cayley (3,), objective scalar."""

    X: np.ndarray
    U: np.ndarray
    C: np.ndarray
    objective: float


def characteristic_scales(problem: SmoothProblem) -> Scales:
    """Magnitudes of the unknowns from the boundary data, the horizon and the body.

    positions L = max(|x0|, |xd|, |xd - x0|); linear momenta max(|gamma0|, |gammad|, m L / T);
    angular momenta max(|Pi0|, |Pid|, lambda_max(J) / T); forces and moments: momentum
    scale / T; attitude entries 1; Cayley vector h |Omega| / 2 with |Omega| the
    angular-momentum scale / lambda_min(J).  Control scales are raised so that
    W_i s_i^2 >= BALANCE * max_j W_j s_j^2 (see the module docstring).  Objective: its
    value for controls of the characteristic size held over the horizon.
    """
    a, d = unpack_states(problem.X0), unpack_states(problem.Xd)
    m, J, T, h = problem.disc.model.mass, problem.disc.J, problem.T, problem.h
    ev = np.linalg.eigvalsh(J)
    L = max(np.abs(a.x).max(), np.abs(d.x).max(), np.abs(d.x - a.x).max(), 1e-12)
    sg = max(np.abs(a.gamma).max(), np.abs(d.gamma).max(), m * L / T)
    sP = max(np.abs(a.Pi).max(), np.abs(d.Pi).max(), ev[-1] / T)
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), np.full(3, sP)])
    sU = np.concatenate([np.full(3, sg / T), np.full(3, sP / T)])
    sC = np.full(3, 0.5 * h * sP / ev[0])
    Wdiag = np.concatenate([np.asarray(problem.W_f, float).ravel(), np.asarray(problem.W_m, float).ravel()])
    # balance the cost weights: no control's curvature W_i s_i^2 below BALANCE times the largest
    cw = Wdiag * sU**2
    sU = sU * np.sqrt(np.maximum(1.0, BALANCE * cw.max() / cw))
    obj = 0.5 * T * float(np.sum(Wdiag * sU**2))
    return Scales(X=sX, U=sU, C=sC, objective=obj)


# ---------------------------------------------------------------------- quadrature
def control_nodes(disc, N: int) -> range:
    """Nodes carrying a control: 0..N (lgvi) or 1..N (first_order)."""
    return range(0, N + 1) if disc.scheme == "lgvi" else range(1, N + 1)


def quadrature_weights(disc, N: int, h: float) -> np.ndarray:
    """omega_j for the controls in ``control_nodes`` order: h (1/2, 1, .., 1, 1/2) or h (1, .., 1)."""
    if disc.scheme == "lgvi":
        om = np.full(N + 1, h)
        om[[0, -1]] = 0.5 * h
        return om
    return np.full(N, h)


def control_cost(U: np.ndarray, W: np.ndarray, omega: np.ndarray) -> float:
    """sum_j omega_j (1/2) u_j^T diag(W) u_j for U (6, nU), W (6,), omega (nU,)."""
    U = np.asarray(U, dtype=float)
    return float(0.5 * np.sum(omega[None, :] * W[:, None] * U**2))


# ------------------------------------------------------------------- tangent maps
def tangent_basis(X: np.ndarray) -> np.ndarray:
    """D(X) (18 x 12): dX = D z for z = [dx; dgamma; zeta; dPi], dR = R S(zeta), vec column-major."""
    R = unpack_states(X).R[0]
    D = np.zeros((NX, NZ))
    D[X_POS, 0:3] = np.eye(3)
    D[X_MOM, 3:6] = np.eye(3)
    D[X_ANG, 9:12] = np.eye(3)
    for i in range(3):
        D[X_ROT, 6 + i] = (R @ hat(np.eye(3)[i])).ravel(order="F")
    return D


def terminal_residual(X, Xd: np.ndarray):
    """CasADi: [x_N - x_d; gamma_N - gamma_d; vee log(R_d^T R_N); Pi_N - Pi_d] (12,) (SPEC §6)."""
    x, g, R, P = split_state(X)
    d = unpack_states(Xd)
    return ca.vertcat(x - d.x[0], g - d.gamma[0], log_so3(ca.mtimes(ca.DM(d.R[0].T), R)), P - d.Pi[0])


# ------------------------------------------------------------------------ defects
def shooting_defects(disc, h: float, Xs, Cs, Wst, sX: np.ndarray):
    """Scaled step defects of all N steps from ONE stage Function mapped over the horizon.

    Xs (18 x N+1), Cs (3 x N) or None, Wst (nw x N) CasADi matrices.  Rows per step:
    (step - X_{k+1}) / sX (18; explicit ``step_given_c`` when Cs is given) and, with Cs,
    the Cayley equation G(c_k) / (h sX_Pi) (3, SPEC §2).
    Returns (D (nd x N) CasADi, row scales (nd,)).
    """
    N = Xs.shape[1] - 1
    Xk = ca.MX.sym("Xk", NX)
    Xk1 = ca.MX.sym("Xk1", NX)
    wk = ca.MX.sym("wk", disc.nw)
    if Cs is not None:
        ck = ca.MX.sym("ck", NC)
        X1, G = disc.step_given_c(Xk, ck, wk, h)
        stage = ca.Function("stage_defect", [Xk, Xk1, ck, wk], [ca.vertcat(X1 - Xk1, G)],
                            ["Xk", "Xk1", "ck", "wk"], ["defect"])
        D = stage.map(N)(Xs[:, :-1], Xs[:, 1:], Cs, Wst)
        gsc = np.concatenate([sX, np.full(NC, h * sX[X_ANG].max())])  # G ~ h Pi
    else:
        X1, _ = disc.step(Xk, wk, h)
        stage = ca.Function("stage_defect", [Xk, Xk1, wk], [X1 - Xk1], ["Xk", "Xk1", "wk"], ["defect"])
        D = stage.map(N)(Xs[:, :-1], Xs[:, 1:], Wst)
        gsc = np.asarray(sX, dtype=float).copy()
    return D / ca.repmat(ca.DM(gsc), 1, N), gsc


# ------------------------------------------------------------- structured NLP
def _assemble(nrow: int, ncol: int, rows, cols, vals):
    """Sparse (nrow x ncol) MX from triplets (rows, cols, vals (ntrip,) MX); duplicates are summed.

    The sparsity is fixed at build time; the nonzeros are one sparse constant product
    P @ vals (P: nnz x ntrip, 0/1), linear in the number of triplets.
    """
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    keys, mapping = np.unique(cols * nrow + rows, return_inverse=True)   # column-major = CasADi's nonzero order
    sp = ca.Sparsity.triplet(nrow, ncol, (keys % nrow).tolist(), (keys // nrow).tolist())
    ntrip = len(rows)
    if len(np.unique(mapping)) == ntrip:            # no duplicates: a permutation
        perm = np.empty(ntrip, dtype=np.int64)
        perm[mapping] = np.arange(ntrip)
        nz = vals[perm.tolist()]
    else:
        P = ca.DM(ca.Sparsity.triplet(sp.nnz(), ntrip, mapping.tolist(), list(range(ntrip))), 1.0)
        nz = ca.mtimes(P, vals)
    return ca.sparsity_cast(nz, sp)


@lru_cache(maxsize=None)
def _stage_functions(disc, with_c: bool, jit: bool):
    """Scaled stage defect, its Jacobian and its Hessian as small SX Functions, built once per scheme.

    Stage variables v = [X_k; c_k (with_c); w_k] (scaled), X_{k+1} (scaled) enters linearly:
    d = step(X_k, c_k, w_k, h) / sX - X_{k+1} (18 rows) and G(c_k) / sG (3 rows).  The step and
    the scales are a parameter vector prm = [h; sX (18); sC (3, with_c); sW (nw); sG (3, with_c)]
    (:func:`_stage_parameters`), so the Functions (and their compiled code, with ``jit``) serve
    every problem of the scheme.  Returns (defect(v, X1, prm) -> d, jac(v, prm) -> nonzeros of
    dd/dv, hess(v, lam, prm) -> nonzeros of d^2 (lam^T d)/dv^2, Jacobian sparsity, Hessian sparsity,
    compiled flag).
    """
    nc = NC if with_c else 0
    nv = NX + nc + disc.nw
    npar = 1 + NX + nc + disc.nw + nc
    v = ca.SX.sym("v", nv)
    X1s = ca.SX.sym("X1s", NX)
    prm = ca.SX.sym("prm", npar)
    h = prm[0]
    sX = prm[1:1 + NX]
    sC = prm[1 + NX:1 + NX + nc]
    sW = prm[1 + NX + nc:1 + NX + nc + disc.nw]
    X = v[:NX] * sX
    w = v[NX + nc:] * sW
    if with_c:
        X1, G = disc.step_given_c(X, v[NX:NX + nc] * sC, w, h)
        d = ca.vertcat(X1 / sX - X1s, G / prm[npar - nc:])
    else:
        X1, _ = disc.step(X, w, h)
        d = X1 / sX - X1s
    nd = d.shape[0]
    lam = ca.SX.sym("lam", nd)
    Jv = ca.jacobian(d, v)
    Hv = ca.hessian(ca.dot(lam, d), v)[0]
    tag = f"{disc.scheme}{'_c' if with_c else ''}"
    defect = ca.Function(f"stage_defect_{tag}", [v, X1s, prm], [d], ["v", "X1", "prm"], ["d"])
    jac = ca.Function(f"stage_jac_{tag}", [v, prm], [ca.vertcat(*Jv.nonzeros())], ["v", "prm"], ["jnz"])
    hess = ca.Function(f"stage_hess_{tag}", [v, lam, prm], [ca.vertcat(*Hv.nonzeros())], ["v", "lam", "prm"], ["hnz"])
    compiled = False
    if jit:
        jac, hess = codegen.compiled(jac), codegen.compiled(hess)
        compiled = jac.class_name() == "External" and hess.class_name() == "External"
    return defect, jac, hess, Jv.sparsity(), Hv.sparsity(), compiled


def _stage_parameters(disc, h: float, sc: Scales, with_c: bool) -> tuple[np.ndarray, np.ndarray]:
    """(prm for :func:`_stage_functions`, defect row scales gsc (nd,))."""
    sW = np.asarray(disc.stage_controls(np.repeat(sc.U[:, None], 2, axis=1)), dtype=float)[:, 0]
    if with_c:
        sG = np.full(NC, h * sc.X[X_ANG].max())          # G ~ h Pi
        return np.concatenate([[h], sc.X, sc.C, sW, sG]), np.concatenate([sc.X, sG])
    return np.concatenate([[h], sc.X, sW]), np.asarray(sc.X, dtype=float).copy()


def _structured_nlp(problem: SmoothProblem, lay: NLPLayout, sc: Scales, w_scale: np.ndarray, wq: np.ndarray,
                    tsc: np.ndarray, ws, jit: bool = False):
    """Constraints g(ws) and exact derivative Functions of the scaled NLP, assembled stage by stage.

    Instead of SX-expanding the whole NLP and letting CasADi colour its Jacobian and
    Hessian (build time ~10 s at N = 1000, dominated by the symbolic Hessian of a
    graph N stages long), the stage defect's Jacobian and Hessian are formed once on
    the small SX stage graph, ``map``-ped over the horizon and scattered into the
    global sparse matrices with index maps fixed at build time.  Same NLP, same
    scaling, same exact Hessian; build and evaluation are linear in N.

    Returns (g (ng,) MX, defect row scales (nd,), dict with 'f' (MX objective) and the
    nlpsol options 'grad_f', 'jac_g', 'hess_lag').
    """
    disc, N, h = problem.disc, problem.N, problem.h
    with_c = lay.with_c
    defect, jac, hess, spJ, spH, compiled = _stage_functions(disc, with_c, bool(jit))
    prm_np, gsc = _stage_parameters(disc, h, sc, with_c)
    prm = ca.DM(prm_np)
    nd = len(gsc)
    # global indices of the stage variables v_k (nv x N)
    iW = np.rint(np.asarray(disc.stage_controls(lay.iU.astype(float)))).astype(np.int64)
    blocks = [lay.iX[:, :-1]] + ([lay.iC] if with_c else []) + [iW]
    iV = np.vstack(blocks)
    nv = iV.shape[0]
    if not all(np.array_equal(np.argsort(iV[:, k]), np.argsort(iV[:, 0])) for k in (0, N - 1)):
        raise AssertionError("stage variables are not ordered alike in every stage")
    V = ca.reshape(ws[iV.ravel(order="F").tolist()], nv, N)
    X1 = ca.reshape(ws[lay.iX[:, 1:].ravel(order="F").tolist()], NX, N)
    XN = ws[lay.iX[:, -1].tolist()]

    # terminal rows (scaled), as an SX Function of the scaled X_N
    xN = ca.SX.sym("xN", NX)
    term = terminal_residual(xN * ca.DM(sc.X), problem.Xd) / ca.DM(tsc)
    lamT = ca.SX.sym("lamT", NZ)
    JT = ca.jacobian(term, xN)
    HT = ca.triu(ca.hessian(ca.dot(lamT, term), xN)[0])
    term_f = ca.Function("terminal_rows", [xN], [term, ca.vertcat(*JT.nonzeros())])
    term_h = ca.Function("terminal_hess", [xN, lamT], [ca.vertcat(*HT.nonzeros())])

    ng = nd * N + NZ
    n = lay.n
    g = ca.vertcat(ca.vec(defect.map(N)(V, X1, prm)), term_f(XN)[0])

    # objective: 0.5 sum q_i ws_i^2 (q nonzero on the controls only)
    q = np.zeros(n)
    q[lay.iU] = wq * np.asarray(w_scale)[lay.iU] ** 2 / sc.objective
    qd = ca.DM(q)
    f = 0.5 * ca.dot(qd * ws, ws)

    # ---- Jacobian triplets: stage blocks, the -I of X_{k+1}, terminal block
    jr, jc = np.asarray(spJ.get_triplet()[0]), np.asarray(spJ.get_triplet()[1])
    ks = np.arange(N)
    rows = [(ks[None, :] * nd + jr[:, None]).ravel(order="F")]
    cols = [iV[jc, :].ravel(order="F")]
    rows.append((ks[None, :] * nd + np.arange(NX)[:, None]).ravel(order="F"))
    cols.append(lay.iX[:, 1:].ravel(order="F"))
    tr, tc = (np.asarray(a) for a in JT.sparsity().get_triplet())
    rows.append(nd * N + tr)
    cols.append(lay.iX[tc, -1])
    Jmap = jac.map(N)(V, prm)
    jvals = ca.vertcat(ca.vec(Jmap), ca.DM.ones(NX * N) * -1.0, term_f(XN)[1])
    Jg = _assemble(ng, n, np.concatenate(rows), np.concatenate(cols), jvals)

    # ---- Hessian of lam_f f + lam_g^T g, upper triangle (row <= col) in the global order
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", ng)
    hr, hc = (np.asarray(a) for a in spH.get_triplet())
    keep = iV[hr, 0] <= iV[hc, 0]                          # same ordering in every stage (checked)
    sel = np.flatnonzero(keep).tolist()
    Hmap = hess.map(N)(V, ca.reshape(lam_g[: nd * N], nd, N), prm)
    Hsel = Hmap[sel, :]
    hrows = [iV[hr[keep], :].ravel(order="F")]
    hcols = [iV[hc[keep], :].ravel(order="F")]
    ttr, ttc = (np.asarray(a) for a in HT.sparsity().get_triplet())
    hrows.append(lay.iX[ttr, -1])
    hcols.append(lay.iX[ttc, -1])
    qi = np.flatnonzero(q)
    hrows.append(qi)
    hcols.append(qi)
    hvals = ca.vertcat(ca.vec(Hsel), term_h(XN, lam_g[nd * N:]), lam_f * ca.DM(q[qi]))
    H = _assemble(n, n, np.concatenate(hrows), np.concatenate(hcols), hvals)
    p = ca.MX.sym("p", 0)
    derivs = {
        "f": f,
        "compiled": compiled,
        "grad_f": ca.Function("nlp_grad_f_s", [ws, p], [f, qd * ws], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("nlp_jac_g_s", [ws, p], [g, Jg], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("nlp_hess_l_s", [ws, p, lam_f, lam_g], [H], ["x", "p", "lam_f", "lam_g"],
                                ["triu_hess_gamma_x_x"]),
    }
    return g, gsc, derivs


# ------------------------------------------------------------------ iteration hook
class _Progress(ca.Callback):
    """IPOPT iteration callback forwarding {'iter', 'objective', 'inf_pr'} to a Python callable."""

    def __init__(self, nx: int, ng: int, fn: Callable[[dict], None], obj_scale: float):
        ca.Callback.__init__(self)
        self.nx, self.ng, self.fn, self.obj_scale, self.k = nx, ng, fn, obj_scale, 0
        self.construct("direct_progress", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg):
        g = np.array(arg[ca.nlpsol_out().index("g")]).ravel()
        f = float(arg[ca.nlpsol_out().index("f")])
        self.fn({"iter": self.k, "objective": f * self.obj_scale, "inf_pr_scaled": float(np.abs(g).max()) if g.size else 0.0})
        self.k += 1
        return [0]


# ----------------------------------------------------------------------- the NLP
class DirectNLP:
    """The scaled multiple-shooting NLP of one SmoothProblem, built once.

    Attributes: ``layout`` (NLPLayout), ``scales`` (Scales), ``solver`` (nlpsol),
    ``lbg``/``ubg``/``lbx``/``ubx``, ``w_scale`` (n,) (physical w = w_scale * scaled w),
    ``g_scale`` (ng,) (physical constraint = g_scale * scaled row), ``defect_rows``
    (18, N) indices of the step defects in g.
    """

    def __init__(self, problem: SmoothProblem, opts: dict[str, Any], progress: Callable[[dict], None] | None = None,
                 structured: bool = True):
        disc, N, h = problem.disc, problem.N, problem.h
        self.problem = problem
        self.opts = opts
        self.with_c = bool(opts["cayley_variables"])
        self.layout = lay = NLPLayout(N, control_nodes(disc, N), self.with_c)
        self.scales = sc = characteristic_scales(problem)
        self.omega = quadrature_weights(disc, N, h)
        self.W = np.concatenate([np.asarray(problem.W_f, float).ravel(), np.asarray(problem.W_m, float).ravel()])

        nU = len(lay.control_nodes)
        self.w_scale = lay.pack(np.repeat(sc.X[:, None], N + 1, axis=1), np.repeat(sc.U[:, None], nU, axis=1),
                                np.repeat(sc.C[:, None], N, axis=1) if self.with_c else None)
        ws = ca.MX.sym("w", lay.n)
        Xs, Us, Cs = lay.unpack(ws * ca.DM(self.w_scale))
        Wst = disc.stage_controls(Us)                         # nw x N stage controls

        tsc = np.concatenate([sc.X[X_POS], sc.X[X_MOM], np.ones(3), sc.X[X_ANG]])
        wq = ca.DM(self.W[:, None] * self.omega[None, :])              # 6 x nU
        derivs = {}
        self.compiled = False
        if structured:
            g, gsc, derivs = _structured_nlp(problem, lay, sc, self.w_scale, wq.full(), tsc, ws, bool(opts.get("jit")))
            f = derivs.pop("f")
            self.compiled = derivs.pop("compiled")
            nd = len(gsc)
        else:
            D, gsc = shooting_defects(disc, h, Xs, Cs, Wst, sc.X)
            nd = D.shape[0]
            term = terminal_residual(Xs[:, -1], problem.Xd)
            g = ca.vertcat(ca.vec(D), term / ca.DM(tsc))
            f = 0.5 * ca.sum1(ca.sum2(wq * Us**2)) / sc.objective
        self.g_scale = np.concatenate([np.tile(gsc, N), tsc])
        self.defect_rows = np.arange(nd * N).reshape(N, nd).T[:NX]      # (18, N)
        self.gap_rows = self.defect_rows

        # bounds: X_0 fixed
        lbx = np.full(lay.n, -np.inf)
        ubx = np.full(lay.n, np.inf)
        x0s = np.asarray(problem.X0, float) / sc.X
        lbx[lay.iX[:, 0]] = x0s
        ubx[lay.iX[:, 0]] = x0s
        self.lbx, self.ubx = lbx, ubx
        self.lbg = self.ubg = np.zeros(g.shape[0])

        # constr_viol_tol: the defects are what the re-simulation accumulates over N steps, so they
        # are driven well below tol (one extra Newton iteration, typically to round-off)
        ipopt = {"tol": float(opts["tol"]), "constr_viol_tol": 1e-2 * float(opts["tol"]),
                 "max_iter": int(opts["max_iter"]), "print_level": 0, "sb": "yes", "hessian_approximation": "exact",
                 **MUMPS_DEFAULTS}
        # IPOPT has no boolean options: YAML's yes/no/true/false arrive as bools
        ipopt.update({k: ("yes" if v else "no") if isinstance(v, bool) else v for k, v in (opts.get("options") or {}).items()})
        if opts.get("warm_start_duals"):
            ipopt.setdefault("warm_start_init_point", "yes")
        nlp_opts: dict[str, Any] = {"expand": not structured, "print_time": False, "ipopt": ipopt,
                                    "show_eval_warnings": False, **derivs}
        self._progress = None
        if progress is not None:
            self._progress = _Progress(lay.n, g.shape[0], progress, sc.objective)
            nlp_opts["iteration_callback"] = self._progress
        try:
            self.solver = ca.nlpsol("direct_ms", "ipopt", {"x": ws, "f": f, "g": g}, nlp_opts)
        except RuntimeError as exc:
            raise _option_error(exc, opts.get("options") or {}) from None

    # ------------------------------------------------------------------ helpers
    def initial_point(self, guess: Guess) -> np.ndarray:
        """Scaled decision vector of a :class:`Guess`."""
        C = guess.C.T if self.with_c else None
        return self.layout.pack(guess.X.T, guess.U, C) / self.w_scale

    def costates(self, X: np.ndarray, lam_g: np.ndarray) -> np.ndarray:
        """lambda_k = D(X_{k+1})^T nu_k (N, 12), nu_k = multiplier of step - X_{k+1} (see module doc).

        IPOPT's Lagrangian is f_s + lam_g^T g_s with g_s = (step - X_{k+1}) / g_scale and
        f_s = J / objective scale, so nu = objective_scale * lam_g / g_scale on the defect rows.
        """
        nu_all = self.scales.objective * lam_g / self.g_scale
        nu = nu_all[self.defect_rows]                                   # (18, N)
        return np.stack([tangent_basis(X[:, k + 1]).T @ nu[:, k] for k in range(self.problem.N)])


# ------------------------------------------------------------------------ fatrop
class StageLayout:
    """Stage-ordered decision vector for fatrop: [s_0, q_0, s_1, q_1, ..., s_N].

    first_order: state s_k = X_k (18), stage control q_k = [u_{k+1} (6); c_k (3)].
    lgvi: the step couples u_k and u_{k+1}, so u_k is lifted into the state: s_k = [X_k; v_k]
    (24, v_k = u_k) and q_k = [u'_{k+1}; c_k] with the gap v_{k+1} - u'_{k+1} = 0, i.e. u_{k+1}
    appears twice (v_{k+1} and its copy u'_{k+1}); the cost prices v_j.
    Index arrays as in :class:`NLPLayout`: iX (18, N+1), iU (6, n_controls) (lgvi: the v_j),
    iC (3, N); lgvi also iUp (6, N), the copies u'_{k+1}.  ns, nq: state and stage-control sizes.
    """

    def __init__(self, N: int, scheme: str):
        self.N, self.scheme = int(N), scheme
        lift = scheme == "lgvi"
        self.ns = NX + (NU if lift else 0)
        self.nq = NU + NC
        self.with_c = True
        iX = np.zeros((NX, N + 1), dtype=int)
        iV = np.zeros((NU, N + 1), dtype=int)
        iQ = np.zeros((NU, N), dtype=int)
        iC = np.zeros((NC, N), dtype=int)
        pos = 0
        for k in range(N + 1):
            iX[:, k] = np.arange(pos, pos + NX)
            pos += NX
            if lift:
                iV[:, k] = np.arange(pos, pos + NU)
                pos += NU
            if k < N:
                iQ[:, k] = np.arange(pos, pos + NU)
                pos += NU
                iC[:, k] = np.arange(pos, pos + NC)
                pos += NC
        self.n = pos
        self.iX, self.iC = iX, iC
        self.iU = iV if lift else iQ
        self.iUp = iQ if lift else None
        self.control_nodes = list(range(N + 1)) if lift else list(range(1, N + 1))

    def unpack(self, w):
        w = np.asarray(w, dtype=float).ravel()
        return w[self.iX], w[self.iU], w[self.iC]

    def pack(self, X, U, C) -> np.ndarray:
        w = np.full(self.n, np.nan)
        w[self.iX] = np.asarray(X, dtype=float)
        w[self.iU] = np.asarray(U, dtype=float)
        w[self.iC] = np.asarray(C, dtype=float)
        if self.iUp is not None:
            w[self.iUp] = np.asarray(U, dtype=float)[:, 1:]
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


class FatropNLP:
    """The same scaled NLP as :class:`DirectNLP` in fatrop's stage form (``structure_detection: auto``).

    Rows [gap_0, path_0, gap_1, path_1, ..., gap_{N-1}, path_{N-1}, path_N] with
    gap_k = s_{k+1} - Phi(s_k, q_k) (scaled by the state scales; for the LGVI the lifted rows are
    v_{k+1} - u'_{k+1}), path_k = G(c_k) (the Cayley equation, scaled as in DirectNLP), path_0 also
    X_0 - X0 (the initial state is a constraint row, not a bound), path_N the terminal residual.
    Every row is an equality (``equality`` flags).  No row depends on an earlier stage and the
    Hessian is block diagonal per stage.  The graph is MX with the stage Function mapped over the
    horizon; fatrop's interface derives the Jacobian and Hessian from it (``expand`` option:
    SX-expand the whole NLP first).
    Multipliers: nu_k (of step - X_{k+1}, as in DirectNLP) = -objective * lam_gap / row scale.
    """

    def __init__(self, problem: SmoothProblem, opts: dict[str, Any], expand: bool = False):
        disc, N, h = problem.disc, problem.N, problem.h
        self.problem, self.opts = problem, opts
        self.layout = lay = StageLayout(N, disc.scheme)
        self.scales = sc = characteristic_scales(problem)
        self.omega = quadrature_weights(disc, N, h)
        self.W = np.concatenate([np.asarray(problem.W_f, float).ravel(), np.asarray(problem.W_m, float).ravel()])
        lift = disc.scheme == "lgvi"
        ws_np = np.full(lay.n, np.nan)
        ws_np[lay.iX] = sc.X[:, None]
        ws_np[lay.iU] = sc.U[:, None]
        ws_np[lay.iC] = sc.C[:, None]
        if lift:
            ws_np[lay.iUp] = sc.U[:, None]
        self.w_scale = ws_np
        prm_np, gsc = _stage_parameters(disc, h, sc, True)
        defect = _stage_functions(disc, True, False)[0]
        ws = ca.MX.sym("w", lay.n)
        # stage variables v_k = [X_k; c_k; w_k] of the stage Function (scaled)
        iW = np.vstack([lay.iU[:, :-1], lay.iUp]) if lift else lay.iU
        iV = np.vstack([lay.iX[:, :-1], lay.iC, iW])
        V = ca.reshape(ws[iV.ravel(order="F").tolist()], iV.shape[0], N)
        X1 = ca.reshape(ws[lay.iX[:, 1:].ravel(order="F").tolist()], NX, N)
        D = -defect.map(N)(V, X1, ca.DM(prm_np))               # rows: X_{k+1} - step (18), -G (3)
        blocks = [D[:NX, :]]
        rs = [sc.X]
        if lift:
            blocks.append(ca.reshape(ws[lay.iU[:, 1:].ravel(order="F").tolist()] -
                                     ws[lay.iUp.ravel(order="F").tolist()], NU, N))
            rs.append(sc.U)
        blocks.append(D[NX:, :])
        rs.append(gsc[NX:])
        S = ca.vertcat(*blocks)                                  # per stage: gap (ns), path (3)
        nrow = S.shape[0]
        x0s = np.asarray(problem.X0, float) / sc.X
        init = ws[lay.iX[:, 0].tolist()] - ca.DM(x0s)
        tsc = np.concatenate([sc.X[X_POS], sc.X[X_MOM], np.ones(3), sc.X[X_ANG]])
        term = terminal_residual(ws[lay.iX[:, -1].tolist()] * ca.DM(sc.X), problem.Xd) / ca.DM(tsc)
        g = ca.vertcat(S[:, 0], init, ca.vec(S[:, 1:]), term)
        row_sc = np.concatenate(rs)
        self.g_scale = np.concatenate([row_sc, sc.X, np.tile(row_sc, N - 1), tsc])
        # gap rows of X (the 18 step rows) in g, per stage
        start = np.array([0] + [nrow + NX + (k - 1) * nrow for k in range(1, N)])
        self.gap_rows = start[None, :] + np.arange(NX)[:, None]           # (18, N)
        self.sign = -1.0
        wq = self.W[:, None] * self.omega[None, :]
        q = np.zeros(lay.n)
        q[lay.iU] = wq * ws_np[lay.iU] ** 2 / sc.objective
        f = 0.5 * ca.dot(ca.DM(q) * ws, ws)
        self.lbx = np.full(lay.n, -np.inf)
        self.ubx = np.full(lay.n, np.inf)
        self.lbg = self.ubg = np.zeros(g.shape[0])
        fat = {"tol": float(opts["tol"]), "constr_viol_tol": 1e-2 * float(opts["tol"]), "max_iter": int(opts["max_iter"]),
               "print_level": 0}
        fat.update({k: v for k, v in (opts.get("fatrop_options") or {}).items()})
        nlp_opts = {"equality": [True] * g.shape[0], "expand": bool(expand), "print_time": False, "fatrop": fat}
        # the structure stated rather than auto-detected (the same blocks either way); the interface's
        # setup is quadratic in N in both modes (scripts/fatrop_build_probe.py)
        npath = nrow - lay.ns
        nlp_opts.update({"structure_detection": "manual", "N": N, "nx": [lay.ns] * (N + 1),
                         "nu": [lay.nq] * N + [0], "ng": [npath + NX] + [npath] * (N - 1) + [NZ]})
        self.solver = ca.nlpsol("direct_fatrop", "fatrop", {"x": ws, "f": f, "g": g}, nlp_opts)

    def initial_point(self, guess: Guess) -> np.ndarray:
        return self.layout.pack(guess.X.T, guess.U, guess.C.T) / self.w_scale

    def costates(self, X: np.ndarray, lam_g: np.ndarray) -> np.ndarray:
        nu = self.sign * self.scales.objective * lam_g / self.g_scale
        nu = nu[self.gap_rows]
        return np.stack([tangent_basis(X[:, k + 1]).T @ nu[:, k] for k in range(self.problem.N)])


_CASADI_TYPE_HINTS = {"is_double": "expected a number", "is_int": "expected an integer",
                      "is_string": "expected a string", "No such IPOPT option": "unknown IPOPT option"}


def _option_error(exc: RuntimeError, raw: dict) -> SolverOptionError:
    """Turn CasADi's error on building the solver into a SolverOptionError naming the raw option."""
    text = str(exc)
    name = next((k for k in raw if f"option: {k}" in text or f"'{k}'" in text), None)
    if name is None and len(raw) == 1:
        name = next(iter(raw))
    hint = next((v for k, v in _CASADI_TYPE_HINTS.items() if k in text), None)
    if hint is None:
        hint = "rejected by IPOPT: " + (text.strip().splitlines()[-1] if text.strip() else "unknown reason")
    return SolverOptionError(name or "", f"{hint} (value {raw[name]!r})" if name else hint)


def check_solver_options(options: dict[str, Any]) -> None:
    """Raise :class:`SolverOptionError` if IPOPT rejects any raw option (tried on a one-variable NLP).

    Cheap (milliseconds), so front ends can reject bad options before doing any work.
    """
    raw = {k: ("yes" if v else "no") if isinstance(v, bool) else v for k, v in (options or {}).items()}
    x = ca.SX.sym("x")
    for k, v in raw.items():  # one at a time, so the culprit is named
        try:
            ca.nlpsol("option_check", "ipopt", {"x": x, "f": x**2}, {"ipopt": {k: v, "print_level": 0, "sb": "yes"},
                                                                   "print_time": False})
        except RuntimeError as exc:
            raise _option_error(exc, {k: v}) from None


def _warm_guess(problem: SmoothProblem, warm: Solution | None) -> Guess | None:
    """A Guess from a previous Solution of the same size (None if it does not fit)."""
    if warm is None or warm.controls is None:
        return None
    X = np.asarray(warm.trajectory.X, float)
    U = np.asarray(warm.controls, float)
    if X.shape != (problem.N + 1, NX) or U.shape != (NU, problem.disc.n_controls(problem.N)):
        return None
    return Guess(X=X, U=U, C=cayley_vectors(X))


def _options(problem: SmoothProblem) -> dict[str, Any]:
    opts = dict(DIRECT_OPTION_DEFAULTS)
    opts.update({k: v for k, v in (problem.options or {}).items() if k in DIRECT_OPTION_DEFAULTS})
    return opts


def _failure(problem: SmoothProblem, opts, status: str, message: str, build_s: float = 0.0) -> Solution:
    """A Solution for a solve that could not run: the free rollout, converged False."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.h, problem.N)
    return Solution(method="direct", solver=str(opts.get("solver")), discretization=problem.disc.scheme, N=problem.N,
                    h=problem.h, trajectory=Trajectory(t=problem.h * np.arange(problem.N + 1), X=X), status=status,
                    message=message, converged=False, cost=float("nan"),
                    terminal_error=terminal_error_full(X[-1], problem.Xd), iterations=0, build_s=build_s, solve_s=0.0)


def solve_direct(problem: SmoothProblem, progress: Callable[[dict], None] | None = None,
                 warm_start: Solution | None = None) -> Solution:
    """Solve a :class:`SmoothProblem` by multiple shooting + IPOPT (see the module docstring).

    ``problem.options`` (the YAML ``solver.direct`` block): ``solver`` ('ipopt'),
    ``tol``, ``max_iter``, ``initial_guess`` ('rollout' | 'interpolate'), ``options``
    (raw IPOPT options), ``cayley_variables`` (bool), ``terminal_tol``.
    ``progress``: optional callable receiving {'iter', 'objective', 'inf_pr_scaled'} per
    IPOPT iteration.

    Returns a :class:`Solution`: controls (6, n_controls) [u_f inertial; u_m body],
    trajectory = re-simulation from X0 with those controls, terminal_error on it,
    costates (N, 12) (module docstring), extra = {'ipopt_return_status', 'kkt_tol',
    'initial_guess', 'cayley_variables', 'n_variables', 'n_constraints',
    'max_defect', 'nlp_terminal_error', 'max_cayley_residual'}.  converged is True iff
    IPOPT returned Solve_Succeeded and the re-simulated terminal error is <= terminal_tol.

    ``warm_start``: a previous direct Solution of a problem with the same N and
    scheme (continuation, e.g. along a sweep): its trajectory and controls are the
    initial guess and, if it carries them, its NLP multipliers (``extra['nlp_nu']``,
    physical units) start IPOPT's duals (``warm_start_init_point``).
    Raises :class:`SolverOptionError` for raw IPOPT options the plugin rejects.
    """
    opts = _options(problem)
    if opts["solver"] not in SOLVERS:
        return _failure(problem, opts, "unsupported_solver",
                        f"solver {opts['solver']!r} is not available for the direct method (use one of {SOLVERS})")
    warm = _warm_guess(problem, warm_start)
    try:
        guess = warm or make_guess(opts["initial_guess"], problem.disc, problem.X0, problem.Xd, problem.N, problem.T)
    except ValueError as exc:
        return _failure(problem, opts, "invalid_option", str(exc))
    if not all(np.all(np.isfinite(a)) for a in (guess.X, guess.U, guess.C)):
        return _failure(problem, opts, "nan",
                        f"the initial guess ({'warm start' if warm else opts['initial_guess']}) is not finite "
                        f"(overflow or a singular potential along the free motion): check the model and the states")
    nu0 = warm_start.extra.get("nlp_nu") if warm is not None else None
    if nu0 is not None:
        opts = dict(opts, warm_start_duals=True)
    fat_extra: dict[str, Any] = {}
    if opts["solver"] == "fatrop":
        fsol, fat_extra = _solve_fatrop(problem, opts, guess)
        if fsol is not None:
            return fsol
    t0 = time.perf_counter()
    nlp = DirectNLP(problem, opts, progress)
    build_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    args = dict(x0=nlp.initial_point(guess), lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
    if nu0 is not None and len(nu0) == len(nlp.lbg):
        args["lam_g0"] = np.asarray(nu0) * nlp.g_scale / nlp.scales.objective
    sol = nlp.solver(**args)
    solve_s = time.perf_counter() - t0
    stats = nlp.solver.stats()
    status = str(stats.get("return_status", "unknown"))
    sol_out = _solution(problem, opts, nlp, sol, stats, status, "ipopt", build_s, solve_s)
    if fat_extra:
        sol_out.extra.update(fat_extra)
        sol_out.message = f"{fat_extra['fatrop_message']}; IPOPT fallback: {sol_out.message}"
        sol_out.build_s += fat_extra["fatrop_build_s"]
        sol_out.solve_s += fat_extra["fatrop_solve_s"]
    return sol_out


def _solve_fatrop(problem: SmoothProblem, opts, guess: Guess) -> tuple[Solution | None, dict[str, Any]]:
    """fatrop on the stage-ordered NLP; (Solution, {}) if it converged, else (None, fallback info)."""
    t0 = time.perf_counter()
    try:
        nlp = FatropNLP(problem, opts, expand=bool(opts.get("fatrop_expand", False)))
    except RuntimeError as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        return None, {"fatrop_fallback": True, "fatrop_status": "build_failed", "fatrop_message":
                      f"fatrop could not be set up ({msg[:300]})", "fatrop_build_s": time.perf_counter() - t0,
                      "fatrop_solve_s": 0.0}
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        sol = nlp.solver(x0=nlp.initial_point(guess), lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
        stats = nlp.solver.stats()
        status = "Solve_Succeeded" if stats.get("success") else f"fatrop_{stats.get('return_status', 'failed')}"
    except RuntimeError as exc:
        sol, stats, status = None, {}, f"fatrop_error: {str(exc).strip().splitlines()[-1][:200] if str(exc).strip() else ''}"
    solve_s = time.perf_counter() - t0
    out = None
    if sol is not None and all(np.all(np.isfinite(np.array(sol[k]))) for k in ("x", "lam_g")):
        out = _solution(problem, opts, nlp, sol, stats, status, "fatrop", build_s, solve_s)
        if out.converged:
            out.extra["fatrop_fallback"] = False
            return out, {}
    why = out.message if out is not None else status
    return None, {"fatrop_fallback": True, "fatrop_status": status,
                  "fatrop_message": f"fatrop did not converge ({why})", "fatrop_build_s": build_s,
                  "fatrop_solve_s": solve_s}


def solve_time_split(stats: dict, solve_s: float) -> dict[str, Any]:
    """Where a solve's wall time went, from CasADi's solver stats (IPOPT and fatrop alike).

    ``evaluations_s`` is the wall time spent in the NLP Functions (objective, constraints, their
    Jacobian and the Lagrangian Hessian: the ``t_wall_nlp_*`` stats), ``solver_internal_s`` the rest
    of ``solve_s`` (the solver's own linear algebra, line search and bookkeeping),
    ``evaluations_by_function`` the split of ``evaluations_s``.  After a fatrop -> IPOPT fallback the
    split describes the IPOPT call only (the failed attempt is ``extra['fatrop_solve_s']``, included in
    the Solution's solve_s).  For fatrop also ``fatrop_own_s``:
    fatrop's own time (its ``time_total`` less its evaluation callbacks), i.e. ``solver_internal_s``
    without the work of CasADi's interface (projecting the NLP Jacobian and Hessian into fatrop's
    stage blocks).
    """
    by = {k[len("t_wall_"):]: float(v) for k, v in stats.items() if k.startswith("t_wall_nlp_")}
    ev = float(sum(by.values()))
    out = {"evaluations_s": ev, "solver_internal_s": max(float(solve_s) - ev, 0.0), "evaluations_by_function": by}
    fat = stats.get("fatrop")
    if isinstance(fat, dict) and "time_total" in fat:
        cb = sum(float(fat.get(k, 0.0)) for k in ("eval_hess_time", "eval_jac_time", "eval_cv_time", "eval_grad_time",
                                                   "eval_obj_time"))
        out["fatrop_own_s"] = max(float(fat["time_total"]) - cb, 0.0)
    return out


def _solution(problem: SmoothProblem, opts, nlp, sol, stats, status: str, solver: str, build_s: float,
              solve_s: float) -> Solution:
    """The Solution of a finished NLP solve (IPOPT or fatrop): re-simulation, checks, costates."""

    w = np.array(sol["x"]).ravel() * nlp.w_scale
    Xn, U, _ = nlp.layout.unpack(w)
    lam_g = np.array(sol["lam_g"]).ravel()
    g_phys = np.array(sol["g"]).ravel() * nlp.g_scale
    Xsim, res = problem.disc.simulate(problem.X0, U, problem.h, problem.N)
    err = terminal_error_full(Xsim[-1], problem.Xd)
    cost = control_cost(U, nlp.W, nlp.omega)
    ok = status == "Solve_Succeeded" and err <= float(opts["terminal_tol"])
    label = "IPOPT" if solver == "ipopt" else solver
    if ok:
        message = f"{label}: {status}; re-simulated terminal error {err:.2e}"
    elif status == "Solve_Succeeded":
        message = (f"{label}: {status}, but the re-simulated terminal error {err:.2e} exceeds terminal_tol "
                   f"{opts['terminal_tol']:.1e} (max Cayley residual {float(np.max(res)):.1e})")
    else:
        message = f"{label} did not converge: {status}; re-simulated terminal error {err:.2e}"
    worst_cayley = float(np.max(res)) if res.size else 0.0
    if not ok and not worst_cayley <= 1e-10:
        message += (f"; the Cayley equation was not solved in the re-simulation (relative residual "
                    f"{worst_cayley:.1e}): the rotation per step is too large, use a smaller step h = T/N "
                    f"(increase horizon.N)")
    it = stats.get("iterations", {}) or {}
    history = [
        {"iter": i, "objective": float(o) * nlp.scales.objective, "inf_pr": float(p), "inf_du": float(d), "mu": float(m)}
        for i, (o, p, d, m) in enumerate(zip(it.get("obj", []), it.get("inf_pr", []), it.get("inf_du", []), it.get("mu", [])))
    ]
    extra = {
        "ipopt_return_status" if solver == "ipopt" else "fatrop_return_status": status,
        "kkt_tol": float(opts["tol"]),
        "initial_guess": opts["initial_guess"],
        "cayley_variables": nlp.layout.with_c,
        "n_variables": int(nlp.layout.n),
        "n_constraints": int(len(nlp.lbg)),
        "max_defect": float(np.abs(g_phys[nlp.gap_rows.ravel()]).max()),
        "nlp_terminal_error": terminal_error_full(Xn[:, -1], problem.Xd),
        "max_cayley_residual": worst_cayley,
        "jit": bool(getattr(nlp, "compiled", False)),
        "nlp_nu": nlp.scales.objective * lam_g / nlp.g_scale,  # physical multipliers, for warm starts
        **solve_time_split(stats, solve_s),
    }
    return Solution(method="direct", solver=solver, discretization=problem.disc.scheme, N=problem.N, h=problem.h,
                    trajectory=Trajectory(t=problem.h * np.arange(problem.N + 1), X=Xsim), status=status,
                    message=message, converged=bool(ok), cost=cost, terminal_error=err,
                    iterations=int(stats.get("iter_count", len(history))), build_s=build_s, solve_s=solve_s,
                    controls=U, costates=nlp.costates(Xn, lam_g), history=history, extra=extra)
