"""The block Functions of the multiple-shooting NLPs (see :mod:`.structured` for what a block is).

Each builder returns an SX Function ``(v, p) -> (cost, rows)`` in *scaled* variables: physical = v * scale, rows
divided by their scales, cost by the objective scale, every scale (and the step size, weights, targets) part of the
data p.  Builders with only structural arguments return a :class:`~.structured.BlockFunction` kept on the
Discretization with its compiled derivatives.

    dynamics(disc, with_c, controls, free_h)   one step k -> k+1 (docs/mathematics.md §2-§3, §6)
        v = [X_k (18); c_k (3, with_c); w_k (nw, controls); X_{k+1} (18); h / h_scale (1, free_h)]
        p = [h (or h_scale, free_h); sX (18); sC (3, with_c); sW (nw, controls); sG (3, with_c);
             theta (the model's numbers, ``disc.model.parameters``)]
        rows = [(step(X_k, c_k, w_k, h) - X_{k+1}) / sX (18); G(c_k) / sG (3, with_c)]
        (the step of ``disc.parametric()``: the model's numbers are data); no cost (transcription.objectives)
    control_node(disc, norm_f, norm_m, thruster)   one control node j's bounds (docs/mathematics.md §10, §14)
        v = u_j (6); p = [sU (6); b_f; b_m (norm bounds); vec(Q) (9, thruster: the engine frame [a, b, c],
             column-major; b_f its max)]
        rows = [(|u_f|^2 - b_f^2) / b_f^2 (norm_f, <= 0); (|u_m|^2 - b_m^2) / b_m^2 (norm_m, <= 0);
                Q^T u_f / b_f (thruster: the thrust a^T u_f / max in [min/max, 1], the off-axis b^T u_f, c^T u_f = 0)]
    time_cost(disc)                               the time objective
        v = [h / h_scale]; p = [h_scale; N / s_obj]; cost = N h / s_obj
    state_target(disc, fixed)                  the terminal conditions of a state target
        v = X_N (18); p = [sX (18); Xd (18); row scales (3 per fixed component)]
        rows = terminal_residual(X_N, Xd) / scales (docs/mathematics.md §6); cost 0
    node_rows(name, rows_of, scales)              rows g(X) / scales of one node (path constraints, orbit target)
    terminal_time_rows(name, rows_of, scales, free_h)   rows g(X_N, T) / scales (rendezvous target)
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..geometry.state import NU, NX, U_FORCE, U_MOMENT, X_ANG, X_MOM, X_POS
from ..dynamics.lgvi import per_discretization
from ..ocp import STATE_COMPONENTS, state_residual
from .structured import BlockFunction

NC = 3


def dynamics_sizes(disc, with_c: bool, controls: bool, free_h: bool = False) -> tuple[int, int]:
    """(nv, np) of :func:`dynamics`."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    return NX + nc + nw + NX + (1 if free_h else 0), 1 + NX + nc + nw + nc + disc.model.parameters.size


@per_discretization
def dynamics(disc, with_c: bool, controls: bool, free_h: bool = False) -> BlockFunction:
    """The dynamics block of one step (module docstring)."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    nv, npar = dynamics_sizes(disc, with_c, controls, free_h)
    v = ca.SX.sym("v", nv)
    p = ca.SX.sym("p", npar)
    h = p[0] * v[-1] if free_h else p[0]
    sX = p[1:1 + NX]
    i = 1 + NX
    sC = p[i:i + nc]
    i += nc
    sW = p[i:i + nw]
    i += nw
    sG = p[i:i + nc]
    i += nc
    theta = p[npar - disc.model.parameters.size:]
    X = v[:NX] * sX
    w = v[NX + nc:NX + nc + nw] * sW if controls else ca.DM.zeros(disc.nw)
    X1 = v[NX + nc + nw:NX + nc + nw + NX] * sX
    core = disc.parametric()
    if with_c:
        Xn, G = core.step_given_c(X, v[NX:NX + nc] * sC, w, h, theta)
        rows = ca.vertcat((Xn - X1) / sX, G / sG)
    else:
        Xn, _ = core.step(X, w, h, theta)
        rows = (Xn - X1) / sX
    tag = f"{disc.scheme}{'_c' if with_c else ''}{'_u' if controls else ''}{'_freeh' if free_h else ''}"
    return BlockFunction(ca.Function(f"dynamics_{tag}", [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"]))


@per_discretization
def control_node(disc, norm_f: bool, norm_m: bool, thruster: bool = False) -> BlockFunction:
    """The bounds of one control node: norm bounds and channel rows (module docstring).  The channel rows are linear
    in u_f, so IPOPT keeps an engine's off-axis force zero to round-off, not merely to the tolerance."""
    v = ca.SX.sym("v", NU)
    p = ca.SX.sym("p", NU + 2 + (9 if thruster else 0))
    u = v * p[:NU]
    bf, bm = p[NU], p[NU + 1]
    rows = []
    if norm_f:
        rows.append((ca.dot(u[U_FORCE], u[U_FORCE]) - bf**2) / bf**2)
    if norm_m:
        rows.append((ca.dot(u[U_MOMENT], u[U_MOMENT]) - bm**2) / bm**2)
    if thruster:
        rows.append(ca.mtimes(ca.reshape(p[NU + 2:NU + 11], 3, 3).T, u[U_FORCE]) / bf)
    name = "_".join(w for w in ("control_node", f"{'f' if norm_f else ''}{'m' if norm_m else ''}",
                                "thruster" if thruster else "") if w)
    return BlockFunction(ca.Function(name, [v, p], [ca.SX(0), ca.vertcat(*rows)], ["v", "p"], ["cost", "rows"]))


@per_discretization
def time_cost(disc) -> BlockFunction:
    """The time objective N h / s_obj (module docstring)."""
    v, p = ca.SX.sym("v", 1), ca.SX.sym("p", 2)
    return BlockFunction(ca.Function("time_cost", [v, p], [p[0] * v[0] * p[1], ca.SX(0, 1)], ["v", "p"],
                                     ["cost", "rows"]))


def node_rows(name: str, rows_of, scales: np.ndarray) -> ca.Function:
    """Rows g(X) / scales of one node state (v = X scaled, p = sX): a path constraint or an orbit target."""
    v, p = ca.SX.sym("v", NX), ca.SX.sym("p", NX)
    rows = rows_of(v * p) / ca.DM(np.asarray(scales, dtype=float))
    return ca.Function(name, [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"])


def terminal_time_rows(name: str, rows_of, scales: np.ndarray, free_h: bool) -> ca.Function:
    """Rows g(X_N, T) / scales of the final state and time (a rendezvous target): v = [X_N scaled (18); h / h_scale
    (1, free_h)], p = [sX (18); N h_scale (free_h) or T], T = p[18] v[18] (free_h) or p[18].  Built per problem."""
    v, p = ca.SX.sym("v", NX + (1 if free_h else 0)), ca.SX.sym("p", NX + 1)
    T = p[NX] * v[NX] if free_h else p[NX]
    rows = rows_of(v[:NX] * p[:NX], T) / ca.DM(np.asarray(scales, dtype=float))
    return ca.Function(name, [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"])


def dynamics_data(disc, h: float, sX, sC, sW, sG) -> np.ndarray:
    """The data vector p of :func:`dynamics` (None entries are omitted: match the flags); the model's numbers last."""
    parts = [[h], sX]
    parts += [sC] if sC is not None else []
    parts += [sW] if sW is not None else []
    parts += [sG] if sG is not None else []
    parts += [disc.model.parameters]
    return np.concatenate([np.asarray(a, dtype=float).ravel() for a in parts])


@per_discretization
def state_target(disc, fixed: tuple[str, ...]) -> BlockFunction:
    """The terminal rows of a state target with the components ``fixed`` (module docstring)."""
    nr = 3 * len(fixed)
    v = ca.SX.sym("v", NX)
    p = ca.SX.sym("p", 2 * NX + nr)
    sX, Xd, sr = p[:NX], p[NX:2 * NX], p[2 * NX:]
    rows = state_residual(v * sX, Xd, fixed) / sr
    tag = "_".join(c[:3] for c in fixed)
    return BlockFunction(ca.Function(f"state_target_{tag}", [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"]))


def state_target_scales(sX: np.ndarray, fixed: tuple[str, ...]) -> np.ndarray:
    """Row scales of :func:`state_target`: the state scales of each block, 1 for the attitude."""
    per = {"position": sX[X_POS], "velocity": sX[X_MOM], "attitude": np.ones(3), "angular_velocity": sX[X_ANG]}
    return np.concatenate([per[c] for c in fixed])


__all__ = ["NC", "STATE_COMPONENTS", "control_node", "dynamics", "dynamics_data", "dynamics_sizes", "node_rows",
           "state_target", "terminal_time_rows", "state_target_scales", "time_cost"]
