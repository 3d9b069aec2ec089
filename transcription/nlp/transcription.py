"""The multiple-shooting NLP of a smooth-control Problem (docs/mathematics.md §6-§7, §10).

Decision variables per node k = 0..N (:class:`~transcription.nlp.layouts.NLPLayout`): the state X_k (18), the node
control u_k (6; first_order: nodes 1..N, lgvi: 0..N) and, with ``cayley_variables`` (default), the Cayley vector
c_k (3) of step k.  With c_k as unknowns every defect is explicit: step_given_c(X_k, c_k, w_k, h) - X_{k+1} = 0 (18
rows) and G(c_k; g(X_k, w_k)) = 0 (3 rows); without them the defect uses the Newton-solved step.  X_0 is fixed by
its bounds.

Costates (the hand-off to the indirect method, §6): with L = J + sum_k nu_k^T (step(X_k, w_k, h) - X_{k+1}) + ...
(the defect written as step minus next state), ``Solution.costates[k]`` (N, 12) is lambda_k = D(X_{k+1})^T nu_k,
D(X) = :func:`~transcription.geometry.state.tangent_basis`; then lambda_{k-1} = A_k^T lambda_k (eq. 28) and, for the
first-order scheme, u_{k+1} = -W^-1 B_k^T lambda_k / h (eqs. 26-27).  Eliminating the Cayley rows' own multipliers
gives the same nu_k.
"""
from __future__ import annotations

import hashlib

import casadi as ca
import numpy as np

from ..geometry.state import NU, NX, U_FORCE, U_MOMENT, X_ANG, tangent_basis
from . import blocks
from .layouts import NLPLayout, StageLayout, control_nodes
from .structured import Block, StructuredNLP
from ..options import DirectOptions
from ..results.start import Start
from ..ocp import (Problem, SmoothControl, TargetOrbit, TargetRendezvous,
                   orbit_residual, quadrature_weights, rendezvous_residual)
from .scaling import characteristic_scales, terminal_row_scales

NC = blocks.NC


class SmoothTranscription:
    """The multiple-shooting NLP of a smooth-control Problem: layout, scales, blocks, bounds.  Blocks
    (transcription.nlp.blocks), in this order: the dynamics of every step, the control nodes' norm bounds and channel
    rows, the objective's blocks (:meth:`~transcription.ocp.objective.Objective.blocks`), one block per path constraint
    (nodes 1..N), the terminal target (state, orbit, or rendezvous: a function of X_N and T = N h).  On a non-uniform
    mesh step k's dynamics data holds h_k = r_k h (h the mean step, the unknown of a free final time).  Box bounds,
    removed controls, the objective's own variables' bounds and the free step's range are variable bounds.

    ``stage_order``: fatrop's layout (:class:`~transcription.nlp.layouts.StageLayout`) with X_0 and, for the LGVI, the
    lifting gaps as rows (:func:`~transcription.methods.direct.fatrop.covers`).  Attributes: ``layout``, ``scales``,
    ``nlp`` (:class:`~transcription.nlp.structured.StructuredNLP`), ``lbx``/``ubx``, ``w_scale`` (physical w = w_scale *
    scaled w), ``g_scale`` (physical row = g_scale * scaled row), ``defect_rows`` (18, N) rows of the defects step -
    X_{k+1} in g, ``constraint_rows`` (per path constraint), ``h_scale``.
    """

    def __init__(self, problem: Problem, options: DirectOptions, stage_order: bool = False):
        N = problem.N
        self.problem, self.options, self.stage_order = problem, options, stage_order
        self.objective = problem.control.objective
        self.free_h = problem.free_time
        self.with_c = True if stage_order else bool(options.cayley_variables)
        n_slack = self.objective.slacks(self)
        self.layout = StageLayout(N, problem.scheme, n_slack) if stage_order else \
            NLPLayout(N, control_nodes(problem.disc, N), self.with_c, n_slack=n_slack, free_h=self.free_h)
        self.scales = characteristic_scales(problem)
        self.h_scale = problem.h
        self.w_scale = self._variable_scales()
        blist, row_scales = self._blocks()
        self.nlp = StructuredNLP(self.layout.n, blist, jit=bool(options.jit) and not stage_order)
        self.g_scale = np.empty(self.nlp.ng)
        for blk in blist:
            self.g_scale[self.nlp.rows(blk.name)] = row_scales[blk.name][:, None]
        self.defect_rows = self.nlp.rows("dynamics")[:NX]
        self.constraint_rows = [self.nlp.rows(f"constraint{i}")[0] for i in range(len(problem.constraints))]
        self.lbx, self.ubx = self._variable_bounds()

    @property
    def point_key(self) -> tuple:
        """The identity of this NLP's scaled points: ``nlp.key`` and the variable and row scales (a point of another
        NLP with the same key means the same physical values here)."""
        return self.nlp.key, hashlib.sha1(self.w_scale.tobytes() + self.g_scale.tobytes()).hexdigest()

    @property
    def magnitudes(self) -> np.ndarray:
        """(2,) the scales of the control magnitudes |u_f|, |u_m|: the largest force and moment scales."""
        return self.magnitude_scales(self.problem, self.scales)

    @staticmethod
    def magnitude_scales(problem: Problem, scales=None) -> np.ndarray:
        """(2,) the scales of the control magnitudes |u_f|, |u_m| of ``problem`` (:attr:`magnitudes`)."""
        sU = (scales or characteristic_scales(problem)).U
        return np.array([sU[U_FORCE].max(), sU[U_MOMENT].max()])

    @property
    def omega_per_h(self) -> np.ndarray:
        """omega_j / h at the control nodes, h the (mean) step: the quadrature weights at h = 1 of the mesh."""
        problem = self.problem
        return quadrature_weights(problem.scheme, problem.N, 1.0 if problem.uniform else problem.mesh)

    def node_parameters(self, head: np.ndarray, shared: np.ndarray, *rows: np.ndarray) -> np.ndarray:
        """The parameters of each control node's objective block (n_p, n_controls): ``head`` (the scales) on every
        node, omega_j / h (:attr:`omega_per_h`), ``shared`` on every node, then the per-node ``rows``."""
        nU = len(self.layout.control_nodes)
        return np.vstack([np.repeat(np.asarray(head, float)[:, None], nU, axis=1), self.omega_per_h[None, :],
                          np.repeat(np.asarray(shared, float)[:, None], nU, axis=1), *rows])

    def node_variables(self, own: bool = True) -> np.ndarray:
        """The variables of each control node's block (n, n_controls): its controls, its objective's variables (with
        ``own``) and the free step size."""
        lay, nU = self.layout, len(self.layout.control_nodes)
        return np.vstack([lay.iUn] + ([lay.iS] if own and lay.n_slack else [])
                         + ([np.full((1, nU), lay.ih)] if self.free_h else []))

    def _variable_scales(self) -> np.ndarray:
        lay, sc = self.layout, self.scales
        ws = np.full(lay.n, np.nan)
        ws[lay.iX] = sc.X[:, None]
        ws[lay.iU] = sc.U[:, None]
        if lay.n_slack:
            ws[lay.iS] = self.objective.slack_scales(self)[:, None]
        if self.with_c:
            ws[lay.iC] = sc.C[:, None]
        if getattr(lay, "iUp", None) is not None:
            ws[lay.iUp] = sc.U[:, None]
        if self.free_h:
            ws[lay.ih] = self.h_scale
        return ws

    def _blocks(self) -> tuple[list[Block], dict[str, np.ndarray]]:
        """The blocks (class docstring, in that order) and the scales of each block's rows."""
        blist, row_scales = [], {}
        for blk, scales in [self._dynamics_block(), self._control_block(), *self.objective.blocks(self),
                            *self._constraint_blocks(), *self._stage_order_blocks(), self._terminal_block()]:
            if blk is not None:
                blist.append(blk)
                row_scales[blk.name] = scales
        return blist, row_scales

    def _dynamics_block(self):
        problem, lay, sc, with_c = self.problem, self.layout, self.scales, self.with_c
        disc, N, h = problem.disc, problem.N, problem.h
        sW = np.asarray(disc.stage_controls(np.repeat(sc.U[:, None], 2, axis=1)), dtype=float)[:, 0]
        sG = np.full(NC, h * sc.X[X_ANG].max())                        # G ~ h Pi
        dyn = blocks.dynamics(disc, with_c, True, self.free_h)
        data = blocks.dynamics_data(disc, h, sc.X, sc.C if with_c else None, sW, sG if with_c else None)
        if not problem.uniform:    # step k's own size: h_k, or r_k h_scale times the free mean step (§16)
            data = np.repeat(data[:, None], N, axis=1)
            data[0] = problem.mesh * self.h_scale if self.free_h else problem.steps
        iV = np.vstack([lay.iX[:, :-1]] + ([lay.iC] if with_c else []) + [lay.stage_controls(disc), lay.iX[:, 1:]]
                       + ([np.full((1, N), lay.ih)] if self.free_h else []))
        return Block("dynamics", dyn, iV, data, compile=True), np.concatenate([sc.X] + ([sG] if with_c else []))

    def _control_block(self):
        """The control nodes' rows: each part's ball |u|^2 <= radius^2 and the force's channel rows Q^T u_f / scale
        in [lo, hi] / scale (:mod:`~transcription.ocp.actuators`); None without either."""
        problem, sc = self.problem, self.scales
        control: SmoothControl = problem.control
        force, moment = control.force_bound, control.moment_bound
        ball = [b is not None and 0.0 < b.radius < np.inf for b in (force, moment)]
        if moment is not None and moment.channel_rows:
            raise ValueError("the NLP states channel rows for the force only")
        ruled = force if force is not None and force.channel_rows else None
        if not (any(ball) or ruled):
            return None, None
        bf = force.scale() if ball[0] or ruled else 1.0
        bm = moment.scale() if ball[1] else 1.0
        Q, lo, hi = ruled.channels if ruled else (np.zeros((3, 0)), np.zeros(0), np.zeros(0))
        n_ball = sum(ball)
        lbg = np.r_[np.full(n_ball, -np.inf), lo / bf]
        ubg = np.r_[np.zeros(n_ball), hi / bf]
        fn = blocks.control_node(problem.disc, ball[0], ball[1], ruled is not None)
        blk = Block("controls", fn, self.layout.iUn, np.r_[sc.U, bf, bm, Q.ravel(order="F")], lbg=lbg, ubg=ubg)
        return blk, np.ones(n_ball + len(lo))

    def _constraint_blocks(self):
        sc, J = self.scales, self.problem.model.inertia
        out = []
        for i, con in enumerate(self.problem.constraints):
            scale = con.row_scale(sc.X[0])
            fn = blocks.node_rows(f"path_{con.kind}", lambda X, c=con: c.expression(X, J), np.array([scale]))
            out.append((Block(f"constraint{i}", fn, self.layout.iX[:, 1:], sc.X, lbg=0.0, ubg=np.inf),
                        np.array([scale])))
        return out

    def _stage_order_blocks(self):
        """fatrop: the LGVI's lifting rows and X_0 as constraint rows."""
        if not self.stage_order:
            return []
        lay, sc = self.layout, self.scales
        out = []
        if lay.iUp is not None:
            out.append((Block("lift", _lift_function(), np.vstack([lay.iUp, lay.iU[:, 1:]]), np.zeros(0)), sc.U))
        out.append((Block("initial", _initial_rows_function(), lay.iX[:, 0],
                          np.concatenate([self.problem.X0 / sc.X])), sc.X))
        return out

    def _terminal_block(self):
        problem, lay, sc = self.problem, self.layout, self.scales
        target = problem.terminal
        tsc = terminal_row_scales(problem, sc)
        if isinstance(target, TargetOrbit):
            m, mu = problem.model.mass, problem.model.mu
            fn = blocks.node_rows("orbit_target", lambda X: orbit_residual(X, target, m, mu), tsc)
            return Block("terminal", fn, lay.iX[:, -1], sc.X), tsc
        if isinstance(target, TargetRendezvous):  # the target point moves with T = N h
            m, mu = problem.model.mass, problem.model.mu
            fn = blocks.terminal_time_rows("rendezvous_target", lambda X, T: rendezvous_residual(X, T, target, m, mu),
                                           tsc, self.free_h)
            iV = np.r_[lay.iX[:, -1], [lay.ih]] if self.free_h else lay.iX[:, -1]
            return Block("terminal", fn, iV, np.r_[sc.X, problem.N * self.h_scale if self.free_h else problem.T]), tsc
        return (Block("terminal", blocks.state_target(problem.disc, target.fixed), lay.iX[:, -1],
                      np.concatenate([sc.X, target.X, tsc])), tsc)

    def _variable_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """lbx, ubx (scaled): X_0 fixed (not in stage order), box bounds and removed controls, the objective's own
        variables' bounds (:meth:`~transcription.ocp.objective.Objective.slack_bounds`), the free step size's
        range."""
        problem, lay, sc = self.problem, self.layout, self.scales
        control: SmoothControl = problem.control
        lbx, ubx = np.full(lay.n, -np.inf), np.full(lay.n, np.inf)
        if not self.stage_order:
            lbx[lay.iX[:, 0]] = ubx[lay.iX[:, 0]] = problem.X0 / sc.X
        for sl, bound in ((U_FORCE, control.force_bound), (U_MOMENT, control.moment_bound)):
            box = None if bound is None else bound.variable_box()
            if box is not None:
                lbx[lay.iU[sl]] = (box[0] / sc.U[sl])[:, None]
                ubx[lay.iU[sl]] = (box[1] / sc.U[sl])[:, None]
        self.objective.slack_bounds(self, lbx, ubx)
        if self.free_h:
            lo, hi = problem.time_bounds
            lbx[lay.ih], ubx[lay.ih] = lo / problem.N / self.h_scale, hi / problem.N / self.h_scale
        return lbx, ubx

    def initial_point(self, start: Start) -> np.ndarray:
        """Scaled decision vector of a :class:`~transcription.results.start.Start` on this NLP's grid, clipped to the
        bounds; a force with channel rows is projected onto its channels' box first (so those rows hold)."""
        U, engine = start.U, self.problem.control.force_bound
        if engine is not None and engine.channel_rows:
            U = U.copy()
            U[U_FORCE] = engine.project(U[U_FORCE].T).T
        w = self.layout.pack(start.X.T, U, start.C.T if self.layout.with_c else None,
                             self.objective.slack_values(self, U), h=start.h) / self.w_scale
        return np.clip(w, self.lbx, self.ubx)

    def costates(self, X: np.ndarray, lam_g: np.ndarray, sign: float = 1.0) -> np.ndarray:
        """lambda_k = D(X_{k+1})^T nu_k (N, 12), nu_k the multiplier of step - X_{k+1} (module docstring), with
        nu = s_obj lam_g / g_scale on the defect rows (``sign`` -1 where the solver saw the rows negated)."""
        nu = sign * self.scales.objective * lam_g[self.defect_rows] / self.g_scale[self.defect_rows]
        return np.stack([tangent_basis(X[:, k + 1]).T @ nu[:, k] for k in range(self.problem.N)])

    def multipliers(self, lam_g: np.ndarray) -> np.ndarray:
        """The solver's multipliers lam_g in physical units, nu = s_obj lam_g / g_scale (a warm start across scales)."""
        return self.scales.objective * np.asarray(lam_g, float) / self.g_scale

    def scaled_multipliers(self, nu: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`multipliers`: lam_g of this NLP's scales from physical multipliers."""
        return np.asarray(nu, float) * self.g_scale / self.scales.objective


def _lift_function() -> ca.Function:
    """fatrop, lgvi: the gap rows v_{k+1} - u'_{k+1} of the lifted node control (scaled alike)."""
    v = ca.SX.sym("v", 2 * NU)
    return ca.Function("lift_rows", [v, ca.SX.sym("p", 0)], [ca.SX(0), v[NU:] - v[:NU]], ["v", "p"], ["cost", "rows"])


def _initial_rows_function() -> ca.Function:
    """fatrop: X_0 - X0 as constraint rows (scaled; p = X0 / sX)."""
    v, p = ca.SX.sym("v", NX), ca.SX.sym("p", NX)
    return ca.Function("initial_rows", [v, p], [ca.SX(0), v - p], ["v", "p"], ["cost", "rows"])
