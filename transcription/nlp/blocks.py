"""The block Functions of the multiple-shooting NLPs (see :mod:`.structured` for what a block is).

Each builder returns an SX Function ``(v, p) -> (cost, rows)`` in *scaled* variables: the
physical value of a local variable is v * (its scale), rows are divided by their scales and the
cost by the objective scale, every scale being part of the data p.  Problem data (step size,
weights, targets) are data too, so one Function -- and its compiled derivatives -- serves every
problem of the same structure: the builders with only structural arguments return a
:class:`~.structured.BlockFunction` built once per Discretization and kept on it (its derivatives with it;
``disc`` is their owner even where the block does not depend on the scheme).

    dynamics(disc, with_c, controls, effort, free_h)   one step k -> k+1 (docs/mathematics.md §2-§3, §6)
        v = [X_k (18); c_k (3, with_c); w_k (nw, controls); X_{k+1} (18); h / h_scale (1, free_h)]
        p = [h (or h_scale, free_h); sX (18); sC (3, with_c); sW (nw, controls); sG (3, with_c);
             s_obj; W_f (9); W_m (9) (effort); theta (the model's numbers, ``disc.model.parameters``)]
        rows = [(step(X_k, c_k, w_k, h) - X_{k+1}) / sX (18); G(c_k) / sG (3, with_c)]
        (the step of ``disc.parametric()``: mass, inertia and the potential's numbers are data, so the block and
        its compiled derivatives serve every model of the same structure -- compiled once)
        cost = the step's share of sum_j omega_j (1/2) u_j^T W u_j, / s_obj (effort; else 0)
    control_node(disc, free_h, norm_f, norm_m, fuel, thruster)   one control node j (docs/mathematics.md §10, §14)
        v = [u_j (6); s_f, s_m, d_f (3), d_m (3) (fuel: magnitudes and directions); h / h_scale (1, free_h)]
        p = [sU (6); sS (2); omega_j / h; h (or h_scale); b_f; b_m (norm bounds); w_f; w_m; s_obj;
             vec(Q) (9, thruster: the engine frame [a, b, c], column-major; b_f its max);
             r_f, r_m, eps (3, fuel: the smoothing references and the smoothing of the fuel homotopy, 0 = the fuel
             objective)]
        rows = [(|u_f|^2 - b_f^2) / b_f^2 (norm_f, <= 0); (|u_m|^2 - b_m^2) / b_m^2 (norm_m, <= 0);
                Q^T u_f / b_f (thruster: the thrust a^T u_f / max in [min/max, 1], the off-axis b^T u_f, c^T u_f = 0);
                |d_f|^2 - 1, |d_m|^2 - 1 (fuel, <= 0); (u_f - s_f d_f) / sS_f, (u_m - s_m d_m) / sS_m (fuel, = 0)]
        cost = omega_j (w_f phi(s_f) + w_m phi(s_m)) / s_obj (fuel; else 0), phi(s) = (1 - eps) s + eps s^2 / (2 r)
               (docs/mathematics.md, the fuel homotopy: phi = s at eps = 0)
    control_node(..., l1=True)                    the fuel cost on a fixed switching structure (docs/mathematics.md,
        §23): v = [u_j (6); s_f, s_m; h / h_scale (free_h)]; p = [... (as above, with r_f, r_m, eps); b_f, b_m (1 on
        a burn node of the part, 0 on a coast node, whose u and s are fixed to 0 by their bounds); delta_f, delta_m]
        rows += [(b_f (sqrt(|u_f|^2 + delta_f^2) - delta_f - s_f) - (1 - b_f) sS_f) / sS_f (<= 0); the same of u_m]
        (the epigraph's rows are not there); cost = omega_j (w_f phi(s_f) + w_m phi(s_m)) / s_obj as above.  With a
        body-fixed engine (thruster) the force's magnitude is its thrust a^T u_f, linear and exact on the engine's
        rows (|u_f| = T >= 0 there): no rounding, and the force burns on every node (T = 0 is the engine row's bound)
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


def dynamics_sizes(disc, with_c: bool, controls: bool, effort: bool, free_h: bool = False) -> tuple[int, int]:
    """(nv, np) of :func:`dynamics`."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    return NX + nc + nw + NX + (1 if free_h else 0), 1 + NX + nc + nw + nc + (1 + 18 if effort else 0) + \
        disc.model.parameters.size


@per_discretization
def dynamics(disc, with_c: bool, controls: bool, effort: bool, free_h: bool = False) -> BlockFunction:
    """The dynamics block of one step (module docstring)."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    nv, npar = dynamics_sizes(disc, with_c, controls, effort, free_h)
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
    cost = ca.SX(0)
    if effort:
        s_obj = p[i]
        W = ca.SX.zeros(NU, NU)
        W[0:3, 0:3] = ca.reshape(p[i + 1:i + 10], 3, 3)
        W[3:6, 3:6] = ca.reshape(p[i + 10:i + 19], 3, 3)
        if disc.scheme == "lgvi":            # trapezoidal: half of each node control's h-weighted cost
            uk, uk1 = w[:NU], w[NU:]
            cost = 0.25 * h * (ca.bilin(W, uk, uk) + ca.bilin(W, uk1, uk1))
        else:                                # first order: u_{k+1} weighted by h
            cost = 0.5 * h * ca.bilin(W, w, w)
        cost = cost / s_obj
    tag = f"{disc.scheme}{'_c' if with_c else ''}{'_u' if controls else ''}{'_effort' if effort else ''}" \
          f"{'_freeh' if free_h else ''}"
    return BlockFunction(ca.Function(f"dynamics_{tag}", [v, p], [cost, rows], ["v", "p"], ["cost", "rows"]))


#: the fuel epigraph's variables per control node: magnitudes s_f, s_m and unit directions d_f, d_m
FUEL_SLACKS = 8
#: ... and those of the fixed switching structure's (``l1``): the magnitudes s_f, s_m
L1_SLACKS = 2


@per_discretization
def control_node(disc, free_h: bool, norm_f: bool, norm_m: bool, fuel: bool, thruster: bool = False,
                 l1: bool = False) -> BlockFunction:
    """The block of one control node: norm bounds, a body-fixed engine and the fuel epigraph (module docstring);
    ``l1``: instead of the epigraph, the fuel cost of a fixed switching structure (no slacks; module docstring).

    The engine's rows are linear in u_f: IPOPT's steps satisfy a linear equality exactly (to the linear
    solver's round-off), so the off-axis force of the solution is zero to round-off, not merely to the tolerance.

    The fuel epigraph is the magnitude-direction split u_f = s_f d_f, |d_f| <= 1, s_f >= 0 (the same
    for u_m), with the cost omega_j (w_f s_f + w_m s_m): at the optimum s = |u|.  Unlike
    |u|^2 <= s^2 its constraint gradients do not vanish where the control is off (u = s = 0), which
    is where a fuel-optimal control spends its coast arcs (with |u|^2 <= s^2 IPOPT declared the
    E3 fuel problem locally infeasible after 424 iterations).
    """
    ns = FUEL_SLACKS if fuel else L1_SLACKS if l1 else 0
    v = ca.SX.sym("v", NU + ns + (1 if free_h else 0))
    p = ca.SX.sym("p", NU + 2 + 2 + 2 + 3 + (9 if thruster else 0) + (3 if fuel or l1 else 0) + (4 if l1 else 0))
    sU, sS = p[:NU], p[NU:NU + 2]
    i = NU + 2
    omega_per_h, hp, bf, bm, wf, wm, s_obj = (p[i + k] for k in range(7))
    h = hp * v[-1] if free_h else hp
    u = v[:NU] * sU
    rows = []
    if norm_f:
        rows.append((ca.dot(u[U_FORCE], u[U_FORCE]) - bf**2) / bf**2)
    if norm_m:
        rows.append((ca.dot(u[U_MOMENT], u[U_MOMENT]) - bm**2) / bm**2)
    if thruster:
        rows.append(ca.mtimes(ca.reshape(p[i + 7:i + 16], 3, 3).T, u[U_FORCE]) / bf)
    cost = ca.SX(0)
    if fuel:
        sf, sm = v[NU] * sS[0], v[NU + 1] * sS[1]
        df, dm = v[NU + 2:NU + 5], v[NU + 5:NU + 8]
        rows += [ca.dot(df, df) - 1.0, ca.dot(dm, dm) - 1.0]
        rows += [(u[U_FORCE] - sf * df) / sS[0], (u[U_MOMENT] - sm * dm) / sS[1]]
    if l1:   # the burn flags b_f, b_m of the node (0 or 1) and the roundings delta_f, delta_m (physical)
        bfl, bml, df_, dm_ = p[-4], p[-3], p[-2], p[-1]
        sf, sm = v[NU] * sS[0], v[NU + 1] * sS[1]
        mag_f = ca.dot(ca.reshape(p[i + 7:i + 10], 3, 1), u[U_FORCE]) if thruster else \
            ca.sqrt(ca.dot(u[U_FORCE], u[U_FORCE]) + df_**2) - df_
        mag_m = ca.sqrt(ca.dot(u[U_MOMENT], u[U_MOMENT]) + dm_**2) - dm_
        # rounded |u| <= s on a burn node; -1 <= 0 on a coast node (u = s = 0 there: no row at its bound)
        rows += [(bfl * (mag_f - sf) - (1.0 - bfl) * sS[0]) / sS[0], (bml * (mag_m - sm) - (1.0 - bml) * sS[1]) / sS[1]]
    if fuel or l1:
        # the homotopy's smoothing: phi(s) = (1 - eps) s + eps s^2 / (2 r), phi = s at eps = 0
        rf, rm, eps = (p[-3], p[-2], p[-1]) if fuel else (p[-7], p[-6], p[-5])
        phi_f = (1.0 - eps) * sf + eps * sf**2 / (2.0 * rf)
        phi_m = (1.0 - eps) * sm + eps * sm**2 / (2.0 * rm)
        cost = omega_per_h * h * (wf * phi_f + wm * phi_m) / s_obj
    # the name from its non-empty parts: CasADi refuses empty parts ("control_node__fuel": fuel without norm bounds)
    parts = ("control_node", f"{'f' if norm_f else ''}{'m' if norm_m else ''}", "thruster" if thruster else "",
             "fuel" if fuel else "", "l1" if l1 else "", "freeh" if free_h else "")
    return BlockFunction(ca.Function("_".join(w for w in parts if w), [v, p],
                                     [cost, ca.vertcat(*rows) if rows else ca.SX(0, 1)], ["v", "p"], ["cost", "rows"]))


@per_discretization
def time_cost(disc) -> BlockFunction:
    """The time objective N h / s_obj (module docstring)."""
    v, p = ca.SX.sym("v", 1), ca.SX.sym("p", 2)
    return BlockFunction(ca.Function("time_cost", [v, p], [p[0] * v[0] * p[1], ca.SX(0, 1)], ["v", "p"],
                                     ["cost", "rows"]))


def node_rows(name: str, rows_of, scales: np.ndarray) -> ca.Function:
    """A block of rows g(X) / scales of one node state (v = X scaled, p = sX): path constraints, or
    a terminal target given as a function of X_N (an orbit target).  Built per problem."""
    v, p = ca.SX.sym("v", NX), ca.SX.sym("p", NX)
    rows = rows_of(v * p) / ca.DM(np.asarray(scales, dtype=float))
    return ca.Function(name, [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"])


def terminal_time_rows(name: str, rows_of, scales: np.ndarray, free_h: bool) -> ca.Function:
    """A block of rows g(X_N, T) / scales of the final state and the final time T (a rendezvous target, whose
    point moves with T): v = [X_N scaled (18); h / h_scale (1, free_h)], p = [sX (18); N h_scale (free_h) or T],
    T = p[18] v[18] (free_h) or p[18].  Built per problem; with a free final time IPOPT gets the exact first
    and second derivatives in h through the block."""
    v, p = ca.SX.sym("v", NX + (1 if free_h else 0)), ca.SX.sym("p", NX + 1)
    T = p[NX] * v[NX] if free_h else p[NX]
    rows = rows_of(v[:NX] * p[:NX], T) / ca.DM(np.asarray(scales, dtype=float))
    return ca.Function(name, [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"])


def dynamics_data(disc, h: float, sX, sC, sW, sG, s_obj=None, W_f=None, W_m=None) -> np.ndarray:
    """The data vector p of :func:`dynamics` (None entries are omitted: match the flags); the model's numbers last."""
    parts = [[h], sX]
    parts += [sC] if sC is not None else []
    parts += [sW] if sW is not None else []
    parts += [sG] if sG is not None else []
    if s_obj is not None:
        parts += [[s_obj], np.asarray(W_f, float).ravel(order="F"), np.asarray(W_m, float).ravel(order="F")]
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


__all__ = ["FUEL_SLACKS", "NC", "STATE_COMPONENTS", "control_node", "dynamics", "dynamics_data", "dynamics_sizes", "node_rows",
           "state_target", "terminal_time_rows", "state_target_scales", "time_cost"]
