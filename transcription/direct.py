"""Direct method: the discrete equations stacked into a multiple-shooting NLP (docs/mathematics.md §6-§7).

Smooth control (effort objective)::

    min  sum_j omega_j (1/2) u_j^T W u_j,        W = blkdiag(W_f, W_m)
    s.t. X_{k+1} = step(X_k, w_k, h),   k = 0..N-1   (eqs. 7-11 or 21-25)
         X_0 = X0,   terminal_residual(X_N) = 0     (the fixed components of the target)

with the quadrature weights of :func:`~transcription.problem.quadrature_weights`.  Impulsive
control is delegated to :mod:`transcription.impulsive` (the TPBVP by Newton shooting, the
relaxed orbit target by an NLP built with the same blocks).

Transcription
-------------
Decision variables per node k = 0..N (see :class:`NLPLayout`, the only place that knows the
order): the state X_k (18), the node control u_k (6; first_order: nodes 1..N, lgvi: nodes 0..N)
and, with ``cayley_variables`` (default), the Cayley vector c_k (3) of step k = 0..N-1.  With c_k
as unknowns every defect is explicit: X_{k+1} - step_given_c(X_k, c_k, w_k, h) = 0 (18 rows) and
the Cayley equation G(c_k; g(X_k, w_k)) = 0 (3 rows); without them the defect uses the
Newton-solved step.  The NLP is the sum of the blocks of :mod:`transcription.blocks`
(dynamics with the effort cost, the terminal target) assembled by the one builder,
:class:`transcription.nlp.StructuredNLP`; X_0 is fixed by its bounds.  IPOPT gets the exact
Hessian assembled block by block; ``solver: fatrop`` gets the same blocks in stage order.

Scaling (:func:`characteristic_scales`): every variable is divided by a characteristic magnitude
(positions by the orbit size, momenta by their boundary values or what the horizon requires,
controls by momentum change over the horizon, c by h |Omega| / 2), every constraint row by the
magnitude of its variable, and the objective by its value at the characteristic controls.  The
control scales are then balanced so that no control's cost curvature W_i s_i^2 is below
``BALANCE`` = 1e-2 of the largest: with W_m = I the moment directions would otherwise carry a
scaled Hessian of ~1e-8, IPOPT's inertia correction swamps them and the solve stalls at
"Solved_To_Acceptable_Level" (measured, E3 N = 100); balanced it reaches Solve_Succeeded.

Costates (the hand-off to the indirect method, docs/mathematics.md §6)
----------------------------------------------------------------------
Write the Lagrangian of the unscaled NLP as L = J + sum_k nu_k^T (step(X_k, w_k, h) - X_{k+1}) + ...,
nu_k in R^18 the multiplier of the step-k defect *written as step minus next state*.
``Solution.costates[k]`` (k = 0..N-1, shape (N, 12)) is lambda_k = D(X_{k+1})^T nu_k, where
D(X) = :func:`~transcription.lie.tangent_basis` maps tangent coordinates z = [dx; dgamma; zeta; dPi]
to dX.  With this sign the discrete necessary conditions read lambda_{k-1} = A_k^T lambda_k (eq. 28)
and, for the first-order scheme, u_{k+1} = -W^-1 B_k^T lambda_k / h (eqs. 26-27); both are tested.
With Cayley unknowns their rows carry their own multipliers; eliminating those gives the same nu_k.
"""
from __future__ import annotations


import time
from dataclasses import dataclass, replace
from typing import Any, Callable

import casadi as ca
import numpy as np

from . import blocks
from .guess import Guess, cayley_vectors, make_guess, perturbed_interpolation_guess
from .layout import NU, NX, X_ANG, X_MOM, X_POS, X_ROT, unpack_states
from .feasibility import step_failure
from .lgvi import CAYLEY_TOL
from .lie import exp_so3, log_so3_any, tangent_basis
from .nlp import Block, ProgressCallback, StructuredNLP, ipopt_history, solve_time_split
from .options import DirectOptions, raw_solver_value
from .problem import (BoxBound, NormBound, Problem, SmoothControl, TargetOrbit, TargetState, control_activity,
                      objective_value, orbit_residual, quadrature_weights, terminal_error, terminal_rows)
from .results import Iterate, Result, Solution, Trajectory, result_of_solver_status

NC = blocks.NC
BALANCE = 1e-2  # smallest allowed ratio of scaled control cost curvatures (characteristic_scales)

#: MUMPS settings for this (already scaled, banded) KKT system: AMD ordering, no permuting scaling,
#: no row/column scaling.  Measured on E3 first_order N = 1000: the IPOPT call fell 1.9 s -> 0.7 s (MUMPS'
#: automatic ordering and its maximum-transversal scaling cost more than they bring here); the scaling
#: (``mumps_scaling`` 0 instead of IPOPT's automatic 77), computed at every factorization of a matrix whose
#: rows and columns are already scaled (:func:`characteristic_scales`), costs ~10 % of the solve on the
#: small NLPs (the slews and the time objective's 25-step starts) with the same iterations and optima to 10
#: digits on the 15 maneuvers of configs/ (docs/bench_notes.md).  Raw ``options`` override them.
MUMPS_DEFAULTS: dict[str, Any] = {"mumps_permuting_scaling": 0, "mumps_pivot_order": 0, "mumps_scaling": 0}


# ---------------------------------------------------------------------------- layouts
class NLPLayout:
    """Order of the NLP decision vector: node-major blocks [X_k, u_k?, s_k?, c_k?], k = 0..N, then
    the global h.

    X_k (18) at every node; u_k (6) and the slacks s_k (``n_slack``: the fuel epigraph) at the
    nodes that carry a control (``control_nodes``); c_k (3) at nodes 0..N-1 when ``with_c``; the
    step size h last when ``free_h``.  :meth:`pack` and :meth:`unpack` are the only routines that
    know the order.  Shapes: X (18, N+1) (column k = node k), U (6, n_controls), S (n_slack,
    n_controls), C (3, N).  ``iX``, ``iU``, ``iS``, ``iC`` are the index arrays of those shapes,
    ``ih`` the index of h (or None).
    """

    def __init__(self, N: int, control_nodes: list[int] | range, with_c: bool, n_slack: int = 0, free_h: bool = False):
        self.N = int(N)
        self.control_nodes = list(control_nodes)
        self.with_c = bool(with_c)
        self.n_slack = int(n_slack)
        has_u = np.zeros(self.N + 1, dtype=bool)
        has_u[self.control_nodes] = True
        iX = np.zeros((NX, self.N + 1), dtype=int)
        iU = np.zeros((NU, len(self.control_nodes)), dtype=int)
        iS = np.zeros((self.n_slack, len(self.control_nodes)), dtype=int)
        iC = np.zeros((NC, self.N if with_c else 0), dtype=int)
        pos, ju = 0, 0
        for k in range(self.N + 1):
            iX[:, k] = np.arange(pos, pos + NX)
            pos += NX
            if has_u[k]:
                iU[:, ju] = np.arange(pos, pos + NU)
                pos += NU
                iS[:, ju] = np.arange(pos, pos + self.n_slack)
                pos += self.n_slack
                ju += 1
            if with_c and k < self.N:
                iC[:, k] = np.arange(pos, pos + NC)
                pos += NC
        self.ih = pos if free_h else None
        self.n = pos + (1 if free_h else 0)
        self.iX, self.iU, self.iS, self.iC = iX, iU, iS, iC

    def stage_controls(self, disc) -> np.ndarray:
        """Indices (nw, N) of the stage controls w_k (first_order: u_{k+1}; lgvi: [u_k; u_{k+1}])."""
        return np.rint(np.asarray(disc.stage_controls(self.iU.astype(float)))).astype(np.int64)

    def unpack(self, w):
        """w (n,) -> (X (18, N+1), U (6, nU), C (3, N) or None) (NumPy)."""
        w = np.asarray(w, dtype=float).ravel()
        return w[self.iX], w[self.iU], (w[self.iC] if self.with_c else None)

    def pack(self, X, U, C=None, S=None, h=None) -> np.ndarray:
        """NumPy (X (18, N+1), U (6, nU), C (3, N), S (n_slack, nU), h) -> w (n,).  C required iff
        ``with_c``; S defaults to the fuel epigraph's point of U (:func:`_fuel_slacks`); h required
        iff the layout has it."""
        w = np.full(self.n, np.nan)
        w[self.iX] = np.asarray(X, dtype=float)
        U = np.asarray(U, dtype=float)
        w[self.iU] = U
        if self.n_slack:
            w[self.iS] = np.asarray(S, dtype=float) if S is not None else _fuel_slacks(U)
        if self.with_c:
            if C is None:
                raise ValueError("this layout has Cayley variables: C (3, N) is required")
            w[self.iC] = np.asarray(C, dtype=float)
        if self.ih is not None:
            if h is None:
                raise ValueError("this layout has a free step size: h is required")
            w[self.ih] = float(h)
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


def _fuel_slacks(U: np.ndarray) -> np.ndarray:
    """The fuel epigraph's variables (8, n) of controls U (6, n): magnitudes |u_f|, |u_m| and unit
    directions (u / |u|, or e1 where the control is 0)."""
    out = []
    for sl in (slice(0, 3), slice(3, 6)):
        n = np.linalg.norm(U[sl], axis=0)
        d = np.where(n > 0, U[sl] / np.where(n > 0, n, 1.0), np.array([[1.0], [0.0], [0.0]]))
        out.append((n, d))
    (nf, df), (nm, dm) = out
    return np.vstack([nf, nm, df, dm])


class StageLayout(NLPLayout):
    """Stage-ordered decision vector for fatrop: [s_0, q_0, s_1, q_1, ..., s_N].

    first_order: state s_k = X_k (18), stage control q_k = [u_{k+1} (6); c_k (3)].
    lgvi: the step couples u_k and u_{k+1}, so u_k is lifted into the state: s_k = [X_k; v_k]
    (24, v_k = u_k) and q_k = [u'_{k+1}; c_k] with the gap v_{k+1} - u'_{k+1} = 0, i.e. u_{k+1}
    appears twice (v_{k+1} and its copy u'_{k+1}).  iU are the node controls (lgvi: the v_j),
    iUp (lgvi) the copies u'_{k+1}; ns, nq the state and stage-control sizes.
    """

    def __init__(self, N: int, scheme: str):
        self.N, self.scheme, self.with_c, self.n_slack, self.ih = int(N), scheme, True, 0, None
        lift = scheme == "lgvi"
        self.ns, self.nq = NX + (NU if lift else 0), NU + NC
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
        self.iX, self.iC, self.iS = iX, iC, np.zeros((0, len(range(N + 1) if lift else range(1, N + 1))), dtype=int)
        self.iU = iV if lift else iQ
        self.iUp = iQ if lift else None
        self.control_nodes = list(range(N + 1)) if lift else list(range(1, N + 1))

    def stage_controls(self, disc) -> np.ndarray:
        return np.vstack([self.iU[:, :-1], self.iUp]) if self.iUp is not None else self.iU

    def pack(self, X, U, C=None, S=None, h=None) -> np.ndarray:
        w = np.full(self.n, np.nan)
        w[self.iX] = np.asarray(X, dtype=float)
        w[self.iU] = np.asarray(U, dtype=float)
        w[self.iC] = np.asarray(C, dtype=float)
        if self.iUp is not None:
            w[self.iUp] = np.asarray(U, dtype=float)[:, 1:]
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


def control_nodes(disc, N: int) -> range:
    """Nodes carrying a control: 0..N (lgvi) or 1..N (first_order)."""
    return range(0, N + 1) if disc.scheme == "lgvi" else range(1, N + 1)


# --------------------------------------------------------------------------- scaling
@dataclass(frozen=True)
class Scales:
    """Characteristic magnitudes: state (18,), control (6,), Cayley (3,), objective scalar."""

    X: np.ndarray
    U: np.ndarray
    C: np.ndarray
    objective: float


def target_estimate(problem: Problem) -> np.ndarray:
    """A terminal state (18) standing for the target: a state target's X (its free components
    hold placeholders), or for an orbit target a point of the orbit reached by a Hohmann-like
    transfer (:func:`~transcription.impulsive.relaxed_start_target`).  For scales and guesses."""
    if isinstance(problem.terminal, TargetState):
        return problem.terminal.X
    from .impulsive import relaxed_start_target

    return relaxed_start_target(problem)


def characteristic_scales(problem: Problem) -> Scales:
    """Magnitudes of the unknowns from the boundary data, the horizon, the body and the bounds.

    (max-norms throughout) positions L = max(|x0|, |xd|, |xd - x0|) (1 if all vanish: attitude-only
    maneuvers); linear momenta max(|gamma0|, |gammad|, m L / T); angular momenta max(|Pi0|, |Pid|,
    lambda_max(J) / T); forces and moments: momentum scale / T, or their bounds; attitude entries
    1; Cayley vector h |Omega| / 2 with |Omega| the angular-momentum scale / lambda_min(J).  For
    the effort objective the control scales are raised so that W_i s_i^2 >= BALANCE * max_j
    W_j s_j^2 (see the module docstring).  Objective: its value for controls of the characteristic
    size held over the horizon (time: T).
    """
    a, d = unpack_states(problem.X0), unpack_states(target_estimate(problem))
    m, J, T, h = problem.model.mass, problem.disc.J, problem.T, problem.h
    control: SmoothControl = problem.control
    ev = np.linalg.eigvalsh(J)
    L = max(np.abs(a.x).max(), np.abs(d.x).max(), np.abs(d.x - a.x).max())
    L = L if L > 0 else 1.0
    sg = max(np.abs(a.gamma).max(), np.abs(d.gamma).max(), m * L / T)
    sP = max(np.abs(a.Pi).max(), np.abs(d.Pi).max(), ev[-1] / T)
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), np.full(3, sP)])
    sU = np.concatenate([np.full(3, sg / T), np.full(3, sP / T)])
    for sl, bound in ((slice(0, 3), control.force_bound), (slice(3, 6), control.moment_bound)):
        if isinstance(bound, BoxBound):
            sU[sl] = bound.b
        elif isinstance(bound, NormBound) and bound.b > 0:
            sU[sl] = bound.b
    sC = np.full(3, 0.5 * h * sP / ev[0])
    if control.objective == "effort":
        Wdiag = np.diag(control.W)
        cw = Wdiag * sU**2
        sU = sU * np.sqrt(np.maximum(1.0, BALANCE * cw.max() / cw))
        obj = 0.5 * T * float(np.sum(Wdiag * sU**2))
    elif control.objective == "time":
        obj = T
    else:
        rf, rm = control.removed
        obj = T * ((0.0 if rf else control.W_f[0, 0] * sU[:3].max()) + (0.0 if rm else control.W_m[0, 0] * sU[3:].max()))
    return Scales(X=sX, U=sU, C=sC, objective=obj)


def terminal_row_scales(problem: Problem, sc: Scales) -> np.ndarray:
    """Scales of the terminal rows of the NLP (the row divided by its scale is what the solver sees):
    a state target's fixed components (:func:`~transcription.blocks.state_target_scales`); an orbit
    target's :func:`~transcription.problem.orbit_residual` rows (radius, out-of-plane position, the body
    axis (2), linear and angular momentum)."""
    target = problem.terminal
    if isinstance(target, TargetOrbit):
        return np.concatenate([[target.radius, target.radius, 1.0, 1.0], sc.X[3:6], sc.X[15:18]])
    return blocks.state_target_scales(sc.X, target.fixed)


def scaled_terminal_miss(problem: Problem, XN: np.ndarray) -> float:
    """max |terminal row| / its scale at the final state XN (18,): how far XN is from the target in units of
    the problem's characteristic scales, as the solver sees it (inf if XN is not finite)."""
    XN = np.asarray(XN, float)
    if not np.all(np.isfinite(XN)):
        return float("inf")
    rows = np.asarray(terminal_rows(XN, problem), float).ravel()
    return float(np.max(np.abs(rows / terminal_row_scales(problem, characteristic_scales(problem)))))


# ---------------------------------------------------------------------- transcription
class SmoothTranscription:
    """The multiple-shooting NLP of a smooth-control Problem: layout, scales, blocks, bounds.

    Blocks (transcription.blocks): the dynamics of every step (with the effort cost), the control
    nodes' norm bounds and fuel epigraph (with the fuel cost), the time cost, one block per path
    constraint (nodes 1..N; node 0 is given and checked when the file is read), the terminal
    target (a state target's fixed components, or an orbit target).  Box bounds on the controls,
    removed controls (a norm bound of 0), the slacks' signs and the free step size's range are
    variable bounds.

    ``stage_order``: fatrop's stage-ordered layout (:class:`StageLayout`) with X_0 as constraint
    rows (fatrop takes no fixed variables) and, for the LGVI, the lifting rows (fixed-time effort
    problems without bounds or path constraints only).  Attributes: ``layout``, ``scales``,
    ``nlp`` (:class:`~transcription.nlp.StructuredNLP`), ``lbx``/``ubx``, ``w_scale`` (physical w =
    w_scale * scaled w), ``g_scale`` (physical row = g_scale * scaled row), ``defect_rows`` (18, N)
    rows of the step defects "step - X_{k+1}" in g, ``h_scale``.
    """

    def __init__(self, problem: Problem, opts: DirectOptions, stage_order: bool = False):
        disc, N, h = problem.disc, problem.N, problem.h
        self.problem, self.opts = problem, opts
        control: SmoothControl = problem.control
        free_h, effort, fuel = problem.free_time, control.objective == "effort", control.objective == "fuel"
        with_c = True if stage_order else bool(opts.cayley_variables)
        self.layout = lay = StageLayout(N, disc.scheme) if stage_order else \
            NLPLayout(N, control_nodes(disc, N), with_c, n_slack=blocks.FUEL_SLACKS if fuel else 0, free_h=free_h)
        self.scales = sc = characteristic_scales(problem)
        self.h_scale = h
        sS = np.array([sc.U[:3].max(), sc.U[3:].max()])
        ws = np.full(lay.n, np.nan)
        ws[lay.iX] = sc.X[:, None]
        ws[lay.iU] = sc.U[:, None]
        if fuel:
            ws[lay.iS] = np.r_[sS, np.ones(6)][:, None]
        if with_c:
            ws[lay.iC] = sc.C[:, None]
        if getattr(lay, "iUp", None) is not None:
            ws[lay.iUp] = sc.U[:, None]
        if free_h:
            ws[lay.ih] = self.h_scale
        self.w_scale = ws

        sW = np.asarray(disc.stage_controls(np.repeat(sc.U[:, None], 2, axis=1)), dtype=float)[:, 0]
        sG = np.full(NC, h * sc.X[X_ANG].max())                        # G ~ h Pi
        dyn = blocks.dynamics(disc, with_c, True, effort, free_h)
        data = blocks.dynamics_data(disc, h, sc.X, sc.C if with_c else None, sW, sG if with_c else None,
                                    *((sc.objective, control.W_f, control.W_m) if effort else ()))
        iV = np.vstack([lay.iX[:, :-1]] + ([lay.iC] if with_c else []) + [lay.stage_controls(disc), lay.iX[:, 1:]]
                       + ([np.full((1, N), lay.ih)] if free_h else []))
        blist = [Block("dynamics", dyn, iV, data, compile=True)]
        row_scales = {"dynamics": np.concatenate([sc.X] + ([sG] if with_c else []))}

        norm_f = isinstance(control.force_bound, NormBound) and control.force_bound.b > 0
        norm_m = isinstance(control.moment_bound, NormBound) and control.moment_bound.b > 0
        if norm_f or norm_m or fuel:
            nU = len(lay.control_nodes)
            omega_per_h = quadrature_weights(disc.scheme, N, 1.0)
            bf = control.force_bound.b if norm_f else 1.0
            bm = control.moment_bound.b if norm_m else 1.0
            cdata = np.vstack([np.repeat(np.r_[sc.U, sS][:, None], nU, axis=1), omega_per_h[None, :],
                               np.repeat(np.array([[h, bf, bm, control.W_f[0, 0], control.W_m[0, 0], sc.objective]]).T,
                                         nU, axis=1)])
            iN = np.vstack([lay.iU] + ([lay.iS] if fuel else []) + ([np.full((1, nU), lay.ih)] if free_h else []))
            n_ineq = int(norm_f) + int(norm_m) + (2 if fuel else 0)
            lbg = np.r_[np.full(n_ineq, -np.inf), np.zeros(6 if fuel else 0)]
            blist.append(Block("controls", blocks.control_node(free_h, norm_f, norm_m, fuel), iN, cdata,
                               lbg=lbg, ubg=0.0))
            row_scales["controls"] = np.r_[np.ones(n_ineq), np.repeat(sS, 3) if fuel else []]
        if control.objective == "time":
            blist.append(Block("time", blocks.time_cost(), np.array([lay.ih]), np.array([self.h_scale, N / sc.objective])))
            row_scales["time"] = np.zeros(0)
        J = problem.model.inertia
        for i, con in enumerate(problem.constraints):
            scale = {"min_radius": sc.X[0], "max_angular_rate": con.value**2 if con.kind == "max_angular_rate" else 1.0
                     }.get(con.kind, 1.0)
            name = f"constraint{i}"
            blist.append(Block(name, blocks.node_rows(f"path_{con.kind}", lambda X, c=con: c.expression(X, J),
                                                      np.array([scale])),
                               lay.iX[:, 1:], sc.X, lbg=0.0, ubg=np.inf))
            row_scales[name] = np.array([scale])
        if stage_order and lay.iUp is not None:
            blist.append(Block("lift", _lift_function(), np.vstack([lay.iUp, lay.iU[:, 1:]]), np.zeros(0)))
            row_scales["lift"] = sc.U
        if stage_order:
            blist.append(Block("initial", _initial_rows_function(), lay.iX[:, 0], np.concatenate([problem.X0 / sc.X])))
            row_scales["initial"] = sc.X
        target = problem.terminal
        tsc = terminal_row_scales(problem, sc)
        if isinstance(target, TargetOrbit):
            m, mu = problem.model.mass, problem.model.mu
            blist.append(Block("terminal", blocks.node_rows("orbit_target", lambda X: orbit_residual(X, target, m, mu),
                                                            tsc), lay.iX[:, -1], sc.X))
        else:
            blist.append(Block("terminal", blocks.state_target(target.fixed), lay.iX[:, -1],
                               np.concatenate([sc.X, target.X, tsc])))
        row_scales["terminal"] = tsc
        self.nlp = StructuredNLP(lay.n, blist, jit=bool(opts.jit) and not stage_order)
        self.g_scale = np.empty(self.nlp.ng)
        for blk in blist:
            self.g_scale[self.nlp.rows(blk.name)] = row_scales[blk.name][:, None]
        self.defect_rows = self.nlp.rows("dynamics")[:NX]
        self.constraint_rows = [self.nlp.rows(f"constraint{i}")[0] for i in range(len(problem.constraints))]

        self.lbx = np.full(lay.n, -np.inf)
        self.ubx = np.full(lay.n, np.inf)
        if not stage_order:
            self.lbx[lay.iX[:, 0]] = self.ubx[lay.iX[:, 0]] = problem.X0 / sc.X
        for sl, bound in ((slice(0, 3), control.force_bound), (slice(3, 6), control.moment_bound)):
            if isinstance(bound, BoxBound):
                self.lbx[lay.iU[sl]] = (-bound.b / sc.U[sl])[:, None]
                self.ubx[lay.iU[sl]] = (bound.b / sc.U[sl])[:, None]
            elif isinstance(bound, NormBound) and bound.b == 0:
                self.lbx[lay.iU[sl]] = self.ubx[lay.iU[sl]] = 0.0
                if fuel:
                    k = 0 if sl.start == 0 else 1
                    self.lbx[lay.iS[k]] = self.ubx[lay.iS[k]] = 0.0
        if fuel:
            self.lbx[lay.iS[:2]] = np.maximum(self.lbx[lay.iS[:2]], 0.0)
        if free_h:
            lo, hi = problem.time_bounds
            self.lbx[lay.ih], self.ubx[lay.ih] = lo / N / self.h_scale, hi / N / self.h_scale

    def initial_point(self, guess: Guess, h: float | None = None) -> np.ndarray:
        """Scaled decision vector of a :class:`~transcription.guess.Guess` (and step size h)."""
        w = self.layout.pack(guess.X.T, guess.U, guess.C.T if self.layout.with_c else None,
                             h=self.problem.h if h is None else h) / self.w_scale
        return np.clip(w, self.lbx, self.ubx)

    def costates(self, X: np.ndarray, lam_g: np.ndarray, sign: float = 1.0) -> np.ndarray:
        """lambda_k = D(X_{k+1})^T nu_k (N, 12), nu_k = multiplier of step - X_{k+1} (module docstring).

        The solver's Lagrangian is f_s + lam_g^T g_s with g_s = (step - X_{k+1}) / g_scale and
        f_s = J / objective scale, so nu = objective_scale * lam_g / g_scale on the defect rows
        (``sign`` -1 where the solver saw the rows negated).
        """
        nu = sign * self.scales.objective * lam_g[self.defect_rows] / self.g_scale[self.defect_rows]
        return np.stack([tangent_basis(X[:, k + 1]).T @ nu[:, k] for k in range(self.problem.N)])


def _lift_function() -> ca.Function:
    """fatrop, lgvi: the gap rows v_{k+1} - u'_{k+1} of the lifted node control (scaled alike)."""
    v = ca.SX.sym("v", 2 * NU)
    return ca.Function("lift_rows", [v, ca.SX.sym("p", 0)], [ca.SX(0), v[NU:] - v[:NU]], ["v", "p"], ["cost", "rows"])


def _initial_rows_function() -> ca.Function:
    """fatrop: X_0 - X0 as constraint rows (scaled; p = X0 / sX)."""
    v, p = ca.SX.sym("v", NX), ca.SX.sym("p", NX)
    return ca.Function("initial_rows", [v, p], [ca.SX(0), v - p], ["v", "p"], ["cost", "rows"])


# ------------------------------------------------------------------------- solvers
#: IPOPT's relative objective change per iteration below which an 'acceptable' iterate may end the solve
#: (IPOPT's default, 1e20, lets 15 acceptable iterates end it however fast the objective still moves)
ACCEPTABLE_OBJ_CHANGE_TOL = 1e-12


def ipopt_options(opts: DirectOptions, warm_duals: bool = False) -> dict[str, Any]:
    """IPOPT options of a direct solve: tolerances, the exact Hessian, MUMPS_DEFAULTS, then the raw
    ``options`` (IPOPT has no booleans: true/false become yes/no).  constr_viol_tol: the defects
    are what the re-simulation accumulates over N steps, so they are driven well below tol.
    acceptable_obj_change_tol: IPOPT stops at its 'acceptable' level (not a success here) only once the
    objective has stopped changing, i.e. at a round-off floor, not while it still converges slowly (the
    five-orbit phasing, configs/everyday/phasing_5_orbits.yaml: stopped at 85 iterations with the dual
    infeasibility falling by a third per iteration; Solve_Succeeded at 120)."""
    ipopt = {"tol": float(opts.tol), "constr_viol_tol": 1e-2 * float(opts.tol), "max_iter": int(opts.max_iter),
             "acceptable_obj_change_tol": ACCEPTABLE_OBJ_CHANGE_TOL, "print_level": 0, "sb": "yes",
             "hessian_approximation": "exact", **MUMPS_DEFAULTS}
    ipopt.update({k: raw_solver_value(v) for k, v in opts.options.items()})
    if warm_duals:
        ipopt.setdefault("warm_start_init_point", "yes")
    return ipopt


def make_ipopt(name: str, nlp: StructuredNLP, ipopt: dict[str, Any], progress: Callable[[Iterate], None] | None,
               obj_scale: float, phase: str = "") -> ca.Function:
    """An IPOPT nlpsol on a StructuredNLP with its block-assembled derivatives."""
    nlp_opts: dict[str, Any] = {"print_time": False, "ipopt": ipopt, "show_eval_warnings": False,
                                **nlp.derivative_functions()}
    if progress is not None:
        # the callback must outlive the solver call: it is kept on the NLP object
        nlp.callback = ProgressCallback(nlp.n, nlp.ng, progress, obj_scale, nlp.lbg, nlp.ubg, phase)
        nlp_opts["iteration_callback"] = nlp.callback
    return ca.nlpsol(name, "ipopt", {"x": nlp.w, "f": nlp.f, "g": nlp.g}, nlp_opts)


def _fatrop_solver(tr: SmoothTranscription, opts: DirectOptions) -> tuple[ca.Function, np.ndarray, np.ndarray]:
    """fatrop on the stage-ordered transcription: rows in stage order [gap_0, path_0, ..., path_N]
    with gap_k = s_{k+1} - Phi(s_k, q_k) (the dynamics rows negated, then the LGVI lifting rows),
    path_k = the Cayley rows (stage 0: and X_0 - X0), path_N the terminal rows; every row an
    equality.  CasADi's fatrop interface derives the Jacobian and Hessian from the graph.
    Returns (solver, row permutation, row signs) so that g_fatrop = sign * g[perm]."""
    nlp, lay, N = tr.nlp, tr.layout, tr.problem.N
    dyn, term, init = nlp.rows("dynamics"), nlp.rows("terminal")[:, 0], nlp.rows("initial")[:, 0]
    lift = nlp.rows("lift") if "lift" in [b.name for b in nlp.blocks] else np.zeros((0, N), dtype=int)
    perm, sign = [], []
    for k in range(N):
        gap = [dyn[:NX, k], lift[:, k]]
        path = [dyn[NX:, k]] + ([init] if k == 0 else [])
        for part, s in ((gap[0], -1.0), (gap[1], 1.0), *((p, 1.0) for p in path)):
            perm += list(part)
            sign += [s] * len(part)
    perm += list(term)
    sign += [1.0] * len(term)
    perm, sign = np.array(perm), np.array(sign)
    g = ca.DM(sign) * nlp.g[perm.tolist()]
    fat = {"tol": float(opts.tol), "constr_viol_tol": 1e-2 * float(opts.tol), "max_iter": int(opts.max_iter),
           "print_level": 0, **{k: raw_solver_value(v) for k, v in opts.fatrop_options.items()}}
    npath = dyn.shape[0] - NX
    nlp_opts = {"equality": [True] * len(perm), "expand": bool(opts.fatrop_expand), "print_time": False, "fatrop": fat,
                "structure_detection": "manual", "N": N, "nx": [lay.ns] * (N + 1), "nu": [lay.nq] * N + [0],
                "ng": [npath + NX] + [npath] * (N - 1) + [len(term)]}
    return ca.nlpsol("direct_fatrop", "fatrop", {"x": nlp.w, "f": nlp.f, "g": g}, nlp_opts), perm, sign


# ---------------------------------------------------------------------------- solve
def _free_motion_failure(problem: Problem, opts: DirectOptions, result: Result, message: str,
                         build_s: float = 0.0) -> Solution:
    """A Solution for a solve that could not run: the free rollout."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.h, problem.N)
    return Solution(method="direct", solver=opts.solver, result=result, message=message,
                    trajectory=trajectory(problem, X), cost=float("nan"), terminal_error=terminal_error(X[-1], problem),
                    iterations=0, build_s=build_s, solve_s=0.0, problem=problem)


def trajectory(problem: Problem, X: np.ndarray, h: float | None = None) -> "Trajectory":
    """The Trajectory of node states X (N+1, 18) of ``problem`` (times k h, h the problem's by default)."""
    m = problem.model
    return Trajectory(t=(problem.h if h is None else h) * np.arange(X.shape[0]), X=X, mass=m.mass, inertia=m.inertia)


def _constraint_report(problem: Problem, traj: Trajectory, tr: SmoothTranscription, lam_g: np.ndarray) -> list[dict]:
    """Per path constraint: kind, the minimum margin on the re-simulated trajectory (its units), the
    nodes where it is active (margin within 1e-6 of the constraint's scale) and the largest
    multiplier (physical units of the cost per unit of the smooth form g >= 0)."""
    out = []
    for con, rows in zip(problem.constraints, tr.constraint_rows):
        margin = con.margin(traj)
        mult = np.abs(tr.scales.objective * lam_g[rows] / tr.g_scale[rows])
        active = np.flatnonzero(margin[1:] <= 1e-6 * max(1.0, np.abs(margin).max())) + 1
        out.append({"kind": con.kind, "dimension": con.dimension, "min_margin": float(margin.min()),
                    "active_nodes": int(active.size),
                    "active_times": [float(traj.t[active[0]]), float(traj.t[active[-1]])] if active.size else [],
                    "max_multiplier": float(mult.max()) if mult.size else 0.0})
    return out


def _warm_guess(problem: Problem, warm: Solution | None) -> Guess | None:
    """A Guess from a previous Solution of the same size (None if it does not fit)."""
    if warm is None or warm.controls is None:
        return None
    X = np.asarray(warm.trajectory.X, float)
    U = np.asarray(warm.controls, float)
    if X.shape != (problem.N + 1, NX) or U.shape != (NU, problem.disc.n_controls(problem.N)):
        return None
    return Guess(X=X, U=U, C=cayley_vectors(X))


#: with initial_guess 'auto', the first guess of an effort problem (see ROLLOUT_FIRST_MISS; the relaxed
#: problem's solution when there are bounds or path constraints) gets at most this many NLP iterations
#: before the next one is tried: a solve that needs more is usually wandering.
AUTO_FIRST_BUDGET = 200
#: ... and which of the free motion (rollout) and the screw interpolation goes first: the rollout when it
#: ends within this many characteristic scales of the target (:func:`scaled_terminal_miss`, the terminal
#: rows as the solver sees them), else the interpolation.  A free motion that misses by far is a poor
#: start: doubling the orbit radius in one period (configs/everyday/orbit_double.yaml, miss 3.1) takes
#: > 1100 iterations from the rollout, 5 from the interpolation; the capture from a fast tumble
#: (capture_fast_tumble.yaml, 1.9) 185 to a local minimum of cost 97.0 against 10 to 32.7.  A near one is a
#: good start, and the interpolation's defects, spread over every step, cost iterations that grow with N:
#: E3 (0.52) 6 iterations from the rollout at N = 250, 1000 and 4000 against 7, 8 and 11 from the
#: interpolation; the 45 deg plane change (0.79) 9 against 12, the detumble (0.93) 6 against 8; E4 (0.78)
#: is the exception, 7-8 against 6.  Misses of the everyday cases: 0.30 ... 3.1 (docs/everyday.md).
ROLLOUT_FIRST_MISS = 1.0
#: ... except for the fuel objective, which starts from the rollout, and whose bang-off-bang solutions take
#: IPOPT longer from any start (configs/orbit_raise_fuel.yaml: 245 iterations from the rollout to a cost of
#: 0.818839; the interpolation, tried after 200, needed 743 more and stopped at a worse local minimum, 0.819259)
AUTO_FIRST_BUDGET_FUEL = 600
#: with initial_guess 'auto' and the time objective, this many symmetry-breaking starts are solved and
#: the fastest converged maneuver kept: time-optimal slews have several local minima (the asymmetric
#: slew of configs/slew_time_optimal.yaml: 28.63 s and 29.41 s, the first-order scheme at N = 100
#: reaching the latter from seed 0)
TIME_STARTS = 3
#: with initial_guess 'auto' and the time objective, the starts are solved on a coarser grid of
#: max(TIME_COARSE_MIN, N // 4) steps (recursively: that solve does the same), the best converged
#: maneuver is resampled to N steps and finished there; the fine-grid starts remain the fallback.
#: Each start costs a quarter (or less) of a fine one and the finish takes few iterations.
TIME_COARSE_MIN = 25


@dataclass(frozen=True)
class _ResampledGuess(Guess):
    """A Guess carrying the step size h of the solution it was resampled from (free final time)."""

    h: float | None = None


def _interp_rotations(R: np.ndarray, t: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Rotations R (n, 3, 3) at increasing times t (n,) interpolated along the geodesic of SO(3)
    between neighbouring nodes at the times tq (m,) -> (m, 3, 3)."""
    j = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
    s = np.clip((tq - t[j]) / (t[j + 1] - t[j]), 0.0, 1.0)
    out = np.empty((len(tq), 3, 3))
    for i, (jj, ss) in enumerate(zip(j, s)):
        w = log_so3_any(R[jj].T @ R[jj + 1])
        out[i] = R[jj] @ exp_so3(ss * w)
    return out


def resample_solution(problem: Problem, sol: Solution) -> _ResampledGuess:
    """A Guess on ``problem``'s grid (N steps) from a Solution of the same problem on another grid: node
    states interpolated in time at the solution's final time (positions, momenta linearly, attitudes
    along SO(3) geodesics), controls linearly at their times (first-order u_j at mid-step, LGVI u_k
    at the nodes), Cayley vectors consistent with the attitudes, h = T_sol / N."""
    disc, N = problem.disc, problem.N
    X = np.asarray(sol.trajectory.X, float)
    U = np.asarray(sol.controls, float)
    Nc = X.shape[0] - 1
    T = float(sol.T)
    tc, tf = np.linspace(0.0, T, Nc + 1), np.linspace(0.0, T, N + 1)
    Xf = np.empty((N + 1, NX))
    for sl in (X_POS, X_MOM, X_ANG):
        for i in range(sl.start, sl.stop):
            Xf[:, i] = np.interp(tf, tc, X[:, i])
    Rc = unpack_states(X).R
    Rf = _interp_rotations(Rc, tc, tf)
    Xf[:, X_ROT] = np.swapaxes(Rf, -1, -2).reshape(N + 1, 9)
    Xf[0], Xf[-1] = X[0], X[-1]
    if disc.scheme == "lgvi":
        uc, uf = tc, tf
    else:
        uc, uf = tc[1:] - 0.5 * T / Nc, tf[1:] - 0.5 * T / N
    Uf = np.vstack([np.interp(uf, uc, U[i]) for i in range(NU)])
    return _ResampledGuess(X=Xf, U=Uf, C=cayley_vectors(Xf), iterations=sol.iterations,
                           seconds=sol.build_s + sol.solve_s, h=T / N)


def _coarse_guess(problem: Problem, opts: DirectOptions, Nc: int) -> Guess | None:
    """The time objective's starts solved on Nc = max(TIME_COARSE_MIN, N // 4) steps (recursively), the
    best resampled to N steps (None if the coarse solve did not converge)."""
    sol = solve_direct(problem.replace(N=Nc), opts)
    return resample_solution(problem, sol) if sol.converged else None


def relaxation(problem: Problem) -> Problem | None:
    """The effort problem without its control bounds (a removed control stays removed) and path
    constraints, whose solution starts the solve of the full one (None if there is nothing to relax or
    the objective needs its bounds).  The bounded E3 (configs/e3_bounded.yaml): 6 + 37 iterations, 2.4 s,
    against 200 from the rollout then 37 from the interpolation, 12 s; the keep-out slew 5 + 11
    against 200 + 12."""
    c = problem.control
    removed = c.removed
    bounds = [b for b, r in zip((c.force_bound, c.moment_bound), removed) if b is not None and not r]
    if c.objective != "effort" or not (bounds or problem.constraints):
        return None
    keep = [b if r else None for b, r in zip((c.force_bound, c.moment_bound), removed)]
    return problem.replace(control=replace(c, force_bound=keep[0], moment_bound=keep[1]), constraints=())


def _relaxed_guess(problem: Problem, relaxed: Problem, opts: DirectOptions) -> Guess | None:
    """The Guess of :func:`relaxation`'s solution (None if it did not converge), with its iterations and time."""
    sol = solve_direct(relaxed, opts)
    guess = _warm_guess(problem, sol) if sol.converged else None
    return replace(guess, iterations=sol.iterations, seconds=sol.build_s + sol.solve_s) if guess is not None else None


def guess_plan(problem: Problem, opts: DirectOptions) -> tuple[list[tuple[str, Callable[[], Guess], int]], str]:
    """The initial guesses to try, as (label, maker, iteration budget), and how to pick the result:
    'first' (the first that converges), 'best' (the lowest cost of those that converge) or 'coarse'
    (the time objective: the first entry, the starts solved on a coarser grid and finished on this one,
    is kept if it converges, else the best of the fine-grid starts that follow); the
    ``initial_guess`` option (see :class:`~transcription.options.DirectOptions`)."""
    disc, X0, N, T = problem.disc, problem.X0, problem.N, problem.T

    def made(kind):
        return lambda: make_guess(kind, disc, X0, target_estimate(problem), N, T)

    if opts.initial_guess != "auto":
        return [(opts.initial_guess, made(opts.initial_guess), opts.max_iter)], "first"
    if problem.control.objective == "time":
        size = np.zeros(6)
        for sl, bound in ((slice(0, 3), problem.control.force_bound), (slice(3, 6), problem.control.moment_bound)):
            size[sl] = bound.b if isinstance(bound, BoxBound) else bound.b / np.sqrt(3.0)
        starts = [(f"interpolate with symmetry-breaking controls (seed {k})",
                   lambda k=k: perturbed_interpolation_guess(disc, X0, target_estimate(problem), N, T, size, seed=k),
                   opts.max_iter) for k in range(TIME_STARTS)]
        Nc = max(TIME_COARSE_MIN, N // 4)
        if Nc < N:
            return [(f"the best start on {Nc} steps, resampled",
                     lambda: _coarse_guess(problem, opts, Nc), opts.max_iter)] + starts, "coarse"
        return starts, "best"
    if problem.control.objective == "fuel":
        return [("rollout", made("rollout"), min(opts.max_iter, AUTO_FIRST_BUDGET_FUEL)),
                ("interpolate", made("interpolate"), opts.max_iter)], "first"
    rollout = made("rollout")()           # its final state decides the order (ROLLOUT_FIRST_MISS)
    order = [("interpolate", made("interpolate")), ("rollout", lambda: rollout)]
    if scaled_terminal_miss(problem, rollout.X[-1]) <= ROLLOUT_FIRST_MISS:
        order.reverse()
    plan = [(*order[0], min(opts.max_iter, AUTO_FIRST_BUDGET)), (*order[1], opts.max_iter)]
    relaxed = relaxation(problem)
    if relaxed is not None:
        plan.insert(0, ("the solution without bounds and path constraints",
                        lambda: _relaxed_guess(problem, relaxed, opts), min(opts.max_iter, AUTO_FIRST_BUDGET)))
    return plan, "first"


def failure_hint(sol: Solution, opts: DirectOptions) -> str:
    """What to try next after a direct solve of a smooth problem that did not converge ('' if it did, was
    interrupted, or its message already says what to change): the settings a user can change with
    ``--set``, in the order most likely to help.  Why: a failure that only names IPOPT's status leaves the
    user to guess that another initial guess, more iterations or an easier neighbouring maneuver (reached
    by continuation) would do."""
    r = sol.result
    if sol.converged or r in (Result.interrupted, Result.cayley_failed, Result.invalid_option, Result.non_finite):
        return ""
    tips = []
    if r is Result.acceptable:
        tips.append("a looser solver.direct.tol (IPOPT stalled at its 'acceptable' level above it) or "
                    "solver.direct.options.acceptable_iter=0 (keep iterating)")
    if opts.initial_guess != "auto":
        tips.append("solver.direct.initial_guess=auto (the screw interpolation and the free motion in turn)")
    elif r is Result.max_iterations:
        tips.append(f"a larger solver.direct.max_iter (now {opts.max_iter})")
    tips.append("an easier neighbouring maneuver (longer horizon.T, smaller change) reached by continuation: a sweep "
                "along the changed key with continuation (configs/sweeps/)")
    return "try " + "; or ".join(tips)


def solve_direct(problem: Problem, options: DirectOptions | None = None,
                 progress: Callable[[Iterate], None] | None = None, warm_start: Solution | None = None) -> Solution:
    """Solve ``problem`` by the direct method (see the module docstring); failures are data.

    The initial guesses of :func:`guess_plan` are tried in order until one converges (the message
    and ``stats['guesses_tried']`` say which were tried; ``iterations``, ``build_s`` and ``solve_s``
    are those of all of them).  ``warm_start``: a previous direct
    Solution of a problem of the same size (continuation, e.g. along a sweep): its trajectory,
    controls and step size are the only initial guess and, if it carries them
    (``stats['nlp_nu']``), its NLP multipliers start IPOPT's duals.

    Smooth control: controls (6, n_controls) [u_f inertial; u_m body]; trajectory = the
    re-simulation from X0 with those controls; terminal_error on it; costates (N, 12) from the
    multipliers.  The result is converged iff the solver converged, the re-simulated terminal
    error is <= terminal_tol and no path constraint is violated by more than terminal_tol.
    """
    opts = options or DirectOptions()
    if problem.kind == "impulsive":
        from .impulsive import solve_impulsive

        return solve_impulsive(problem, opts, progress)
    if problem.kind != "smooth":
        raise ValueError("the problem has no control to optimize (terminal and control are None): use simulate")
    warm = _warm_guess(problem, warm_start)
    plan, pick = ([("warm start", lambda: warm, opts.max_iter)], "first") if warm is not None else \
        guess_plan(problem, opts)
    h0 = warm_start.h if warm is not None else problem.h
    nu0 = warm_start.stats.get("nlp_nu") if warm is not None else None
    fallback: dict[str, Any] = {}
    if opts.solver == "fatrop":
        c = problem.control
        if problem.free_time or problem.constraints or c.objective != "effort" or c.bounded \
                or not isinstance(problem.terminal, TargetState):
            fallback = {"fatrop_fallback": True, "fatrop_status": "not_applicable", "fatrop_build_s": 0.0,
                        "fatrop_solve_s": 0.0, "fatrop_message": "fatrop is used for fixed-time effort problems to a "
                        "state target without bounds or path constraints"}
        else:
            fsol, fallback = _solve_fatrop(problem, opts, plan[0][1]())
            if fsol is not None:
                return fsol
    t0 = time.perf_counter()
    tr = SmoothTranscription(problem, opts)
    build_s = time.perf_counter() - t0
    solvers: dict[int, ca.Function] = {}
    tried: list[str] = []
    total_build, total_solve, total_iterations = 0.0, 0.0, 0
    sol, best = None, None
    for label, maker, budget in plan:
        guess = maker()
        if guess is None:
            tried.append(f"{label}: not available (the "
                         f"{'coarse-grid' if pick == 'coarse' else 'relaxed'} problem did not converge)")
            continue
        if not all(np.all(np.isfinite(a)) for a in (guess.X, guess.U, guess.C)):
            tried.append(f"{label}: not finite")
            continue
        t0 = time.perf_counter()
        if budget not in solvers:
            solvers[budget] = make_ipopt("direct_ms", tr.nlp, ipopt_options(opts.replace(max_iter=budget),
                                                                            warm_duals=nu0 is not None),
                                         progress, tr.scales.objective)
        solver = solvers[budget]
        total_build += time.perf_counter() - t0
        h_guess = getattr(guess, "h", None) or h0   # a resampled solution brings its own step size
        args = dict(x0=tr.initial_point(guess, h_guess), lbx=tr.lbx, ubx=tr.ubx, lbg=tr.nlp.lbg, ubg=tr.nlp.ubg)
        if nu0 is not None and len(nu0) == tr.nlp.ng:
            args["lam_g0"] = np.asarray(nu0) * tr.g_scale / tr.scales.objective
        t0 = time.perf_counter()
        out = solver(**args)
        solve_s = time.perf_counter() - t0
        total_solve += solve_s
        stats = solver.stats()
        sol = _solution(problem, opts, tr, out, stats, str(stats.get("return_status", "unknown")), "ipopt", build_s,
                        solve_s)
        if guess.iterations:   # the relaxed problem's solve counts: its iterations and time
            sol.iterations += guess.iterations
            sol.solve_s += guess.seconds
            total_solve += guess.seconds
        total_iterations += sol.iterations
        tried.append(f"{label}: {sol.result} in {sol.iterations} iterations" +
                     (f" ({guess.iterations} of them on the "
                      f"{'coarse grid' if isinstance(guess, _ResampledGuess) else 'relaxed problem'})"
                      if guess.iterations else "") +
                     (f", cost {sol.cost:.10g}" if pick != "first" and sol.converged else ""))
        sol.stats["initial_guess"] = label
        if sol.converged and (best is None or sol.cost < best.cost):
            best = sol
        if sol.result is Result.interrupted or (sol.converged and pick == "first"):
            break
        if pick == "coarse" and isinstance(guess, _ResampledGuess) and sol.converged:
            break   # finished on the fine grid: the fine-grid starts are only the fallback
    if sol is None:
        return _free_motion_failure(problem, opts, Result.non_finite,
                                    "the initial guess is not finite (overflow or a singular potential along the "
                                    "free motion): check the model and the states")
    sol = best if best is not None and sol.result is not Result.interrupted else sol
    # every guess tried counts: iterations and times are those of the whole solve
    sol.build_s, sol.solve_s, sol.iterations = build_s + total_build, total_solve, total_iterations
    sol.stats["guesses_tried"] = tried
    if len(tried) > 1:
        sol.message += "; initial guesses tried: " + "; ".join(tried)
    hint = failure_hint(sol, opts) if warm is None else ""
    if hint:
        sol.stats["hint"] = hint
        sol.message += f"; {hint}"
    if fallback:
        sol.stats.update(fallback)
        sol.message = f"{fallback['fatrop_message']}; IPOPT fallback: {sol.message}"
        sol.build_s += fallback["fatrop_build_s"]
        sol.solve_s += fallback["fatrop_solve_s"]
    return sol


def _solve_fatrop(problem: Problem, opts: DirectOptions, guess: Guess) -> tuple[Solution | None, dict[str, Any]]:
    """fatrop on the stage-ordered NLP; (Solution, {}) if it converged, else (None, fallback info)."""
    t0 = time.perf_counter()
    try:
        tr = SmoothTranscription(problem, opts, stage_order=True)
        solver, perm, sign = _fatrop_solver(tr, opts)
    except RuntimeError as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        return None, {"fatrop_fallback": True, "fatrop_status": "build_failed", "fatrop_message":
                      f"fatrop could not be set up ({msg[:300]})", "fatrop_build_s": time.perf_counter() - t0,
                      "fatrop_solve_s": 0.0}
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        out = solver(x0=tr.initial_point(guess), lbx=tr.lbx, ubx=tr.ubx, lbg=0.0, ubg=0.0)
        stats = solver.stats()
        status = "Solve_Succeeded" if stats.get("success") else f"fatrop_{stats.get('return_status', 'failed')}"
    except RuntimeError as exc:
        out, stats, status = None, {}, f"fatrop_error: {str(exc).strip().splitlines()[-1][:200] if str(exc).strip() else ''}"
    solve_s = time.perf_counter() - t0
    sol = None
    if out is not None and all(np.all(np.isfinite(np.array(out[k]))) for k in ("x", "lam_g")):
        lam = np.zeros(tr.nlp.ng)
        lam[perm] = sign * np.array(out["lam_g"]).ravel()
        gval = np.zeros(tr.nlp.ng)
        gval[perm] = sign * np.array(out["g"]).ravel()
        out = {"x": out["x"], "lam_g": lam, "g": gval}
        sol = _solution(problem, opts, tr, out, stats, status, "fatrop", build_s, solve_s)
        if sol.converged:
            sol.stats["fatrop_fallback"] = False
            return sol, {}
    why = sol.message if sol is not None else status
    return None, {"fatrop_fallback": True, "fatrop_status": status, "fatrop_message": f"fatrop did not converge ({why})",
                  "fatrop_build_s": build_s, "fatrop_solve_s": solve_s}


def _solution(problem: Problem, opts: DirectOptions, tr: SmoothTranscription, out, stats, status: str, solver: str,
              build_s: float, solve_s: float) -> Solution:
    """The Solution of a finished NLP solve (IPOPT or fatrop): re-simulation, checks, costates."""
    w = np.array(out["x"]).ravel() * tr.w_scale
    Xn, U, _ = tr.layout.unpack(w)
    h = float(w[tr.layout.ih]) if tr.layout.ih is not None else problem.h
    lam_g = np.array(out["lam_g"]).ravel()
    g_phys = np.array(out["g"]).ravel() * tr.g_scale
    Xsim, res = problem.disc.simulate(problem.X0, U, h, problem.N)
    err = terminal_error(Xsim[-1], problem)
    traj = trajectory(problem, Xsim, h)
    worst_cayley = float(np.max(res)) if res.size else 0.0
    result = result_of_solver_status(status)
    label = "IPOPT" if solver == "ipopt" else solver
    if result is Result.converged and not err <= opts.terminal_tol:
        result = Result.terminal_error
        message = (f"{label}: {status}, but the re-simulated terminal error {err:.2e} exceeds terminal_tol "
                   f"{opts.terminal_tol:.1e} (max Cayley residual {worst_cayley:.1e})")
    elif result is Result.converged:
        message = f"{label}: {status}; re-simulated terminal error {err:.2e}"
    else:
        message = f"{label} did not converge: {status}; re-simulated terminal error {err:.2e}"
    if not result.successful and not worst_cayley <= CAYLEY_TOL:  # non-finite, or the Cayley fold: say which
        result, why = step_failure(problem, Xsim, res, h)
        message += f"; in the re-simulation, {why}"
    stats_out = {
        "solver_status": status,
        "kkt_tol": float(opts.tol),
        "initial_guess": opts.initial_guess,
        "cayley_variables": tr.layout.with_c,
        "n_variables": int(tr.layout.n),
        "n_constraints": int(tr.nlp.ng),
        "max_defect": float(np.abs(g_phys[tr.defect_rows.ravel()]).max()),
        "nlp_terminal_error": terminal_error(Xn[:, -1], problem),
        "max_cayley_residual": worst_cayley,
        "jit": bool(tr.nlp.compiled),
        "nlp_nu": tr.scales.objective * lam_g / tr.g_scale,  # physical multipliers, for warm starts
        **solve_time_split(stats, solve_s),
    }
    if problem.free_time:
        stats_out["T"] = problem.N * h
    times = traj.t[1:] if U.shape[1] == problem.N else traj.t
    activity = control_activity(problem.control, U, quadrature_weights(problem.scheme, problem.N, h), times)
    if activity:
        stats_out["bounds"] = activity
    if problem.constraints:
        stats_out["constraints"] = _constraint_report(problem, traj, tr, lam_g)
        worst = min(c["min_margin"] for c in stats_out["constraints"])
        stats_out["min_constraint_margin"] = worst
        if result is Result.converged and worst < -opts.terminal_tol:
            result = Result.terminal_error
            message += f"; a path constraint is violated on the re-simulation by {-worst:.2e}"
    return Solution(method="direct", solver=solver, result=result, message=message, trajectory=traj,
                    cost=objective_value(problem, U, h), terminal_error=err,
                    iterations=int(stats.get("iter_count", 0)), build_s=build_s, solve_s=solve_s, problem=problem,
                    controls=U, costates=tr.costates(Xn, lam_g),
                    history=ipopt_history(stats, tr.scales.objective), stats=stats_out)
