"""The fuel objective's block of the direct method's NLP: one per control node (docs/mathematics.md §19, §23).

    fuel_node(disc, free_h)            the epigraph (:attr:`Fuel.epigraph`)
        v = [u_j (6); s_f, s_m, d_f (3), d_m (3) (magnitudes and directions); h / h_scale (1, free_h)]
        p = [sU (6); sS (2); omega_j / h; h (or h_scale); w_f; w_m; s_obj; a (3, an engine's axis);
             r_f, r_m, eps (the smoothing references and the homotopy's eps, 0 = the fuel objective)]
        rows = [|d_f|^2 - 1, |d_m|^2 - 1 (<= 0); (u_f - s_f d_f) / sS_f, (u_m - s_m d_m) / sS_m (= 0)]
        cost = omega_j (w_f phi(s_f) + w_m phi(s_m)) / s_obj,  phi(s) = (1 - eps) s + eps s^2 / (2 r)
    fuel_node(..., engine=True)        the force an engine's (:attr:`~transcription.ocp.actuators.Actuator.engine_axis`)
        its magnitude is its thrust, linear: rows = [|d_m|^2 - 1 (<= 0); (a^T u_f - s_f) / sS_f (= 0);
        (u_m - s_m d_m) / sS_m (= 0)], d_f unused (held by its bounds, :meth:`Fuel.slack_bounds`)
    fuel_node(..., l1=True)            on a fixed switching structure (:attr:`Fuel.burn`)
        v = [u_j (6); s_f, s_m; h / h_scale (free_h)]; p = [... as above; b_f, b_m (1 on a burn node of the part, 0
        on a coast node, whose u and s are fixed to 0 by their bounds); delta_f, delta_m]
        rows = [(b_f (sqrt(|u_f|^2 + delta_f^2) - delta_f - s_f) - (1 - b_f) sS_f) / sS_f (<= 0); the same of u_m];
        an engine's force: a^T u_f - s_f <= 0 on every node (no rounding; T = 0 is the engine row's bound).

    channel_node(disc, free_h)         the fuel counted on the actuators' channels (:meth:`Fuel.on_channels`)
        v = [u_j (6); s (6) (each channel's |T_i|, the force's then the moment's); h / h_scale (free_h)]
        p = [sU (6); sS (2); omega_j / h; h (or h_scale); w_f; w_m; s_obj; vec Q_f (9); vec Q_m (9)]
        rows = [(T_f - s_f) / sS_f, (-T_f - s_f) / sS_f, (T_m - s_m) / sS_m, (-T_m - s_m) / sS_m (<= 0)],
        T = Q^T u; cost = omega_j (w_f sum_i s_f,i + w_m sum_i s_m,i) / s_obj: linear, a linear program's epigraph of
        sum_i |T_i| -- no bilinear term, no false coast (a channel at 0 with |dL/dT_i| < w is one of the problem's)

The epigraph is the magnitude-direction split u = s d, |d| <= 1, s >= 0, with the cost omega_j (w_f s_f + w_m s_m):
at the optimum s = |u|.  Unlike |u|^2 <= s^2 its constraint gradients do not vanish where the control is off
(u = s = 0), which is where a fuel-optimal control spends its coast arcs (with |u|^2 <= s^2 IPOPT declared the E3 fuel
problem locally infeasible after 424 iterations); but it is bilinear, and a coast node of its KKT points need not be
one of the fuel problem's (the guard, :mod:`.guard`).  An engine's force needs none of it: on the engine's rows
(T = a^T u_f in [min, max], no off-axis force) |u_f| = T, and the force's part of the NLP is linear.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...dynamics.lgvi import per_discretization
from ...geometry.state import NU, U_FORCE, U_MOMENT
from ...nlp.structured import Block, BlockFunction


def on_channels(problem) -> tuple[np.ndarray, np.ndarray] | None:
    """(Q_f, Q_m) where both parts' fuel is counted on their actuators' channels
    (:attr:`~transcription.ocp.actuators.Actuator.fuel_channels`), or None (a part unbounded or gimballed: the
    2-norm, the epigraph)."""
    c = problem.control
    Q = [None if b is None else b.fuel_channels for b in (c.force_bound, c.moment_bound)]
    return None if any(q is None for q in Q) else (Q[0], Q[1])


def fuel_slacks(U: np.ndarray) -> np.ndarray:
    """The fuel epigraph's variables (8, n) of controls U (6, n): magnitudes |u_f|, |u_m| and unit directions
    (u / |u|, or e1 where the control is 0)."""
    out = []
    for sl in (U_FORCE, U_MOMENT):
        n = np.linalg.norm(U[sl], axis=0)
        d = np.where(n > 0, U[sl] / np.where(n > 0, n, 1.0), np.array([[1.0], [0.0], [0.0]]))
        out.append((n, d))
    (nf, df), (nm, dm) = out
    return np.vstack([nf, nm, df, dm])


@per_discretization
def fuel_node(disc, free_h: bool, l1: bool = False, engine: bool = False) -> BlockFunction:
    """The fuel objective at one control node (module docstring)."""
    ns = 2 if l1 else 8
    v = ca.SX.sym("v", NU + ns + (1 if free_h else 0))
    p = ca.SX.sym("p", NU + 2 + 5 + 3 + 3 + (4 if l1 else 0))
    sU, sS = p[:NU], p[NU:NU + 2]
    i = NU + 2
    omega_per_h, hp, wf, wm, s_obj = (p[i + k] for k in range(5))
    axis, (rf, rm, eps) = p[i + 5:i + 8], (p[i + 8], p[i + 9], p[i + 10])
    h = hp * v[-1] if free_h else hp
    u = v[:NU] * sU
    sf, sm = v[NU] * sS[0], v[NU + 1] * sS[1]
    if l1:   # the burn flags b_f, b_m of the node (0 or 1) and the roundings delta_f, delta_m (physical)
        bfl, bml, df_, dm_ = p[-4], p[-3], p[-2], p[-1]
        mag_f = ca.dot(axis, u[U_FORCE]) if engine else ca.sqrt(ca.dot(u[U_FORCE], u[U_FORCE]) + df_**2) - df_
        mag_m = ca.sqrt(ca.dot(u[U_MOMENT], u[U_MOMENT]) + dm_**2) - dm_
        # rounded |u| <= s on a burn node; -1 <= 0 on a coast node (u = s = 0 there: no row at its bound)
        rows = [(bfl * (mag_f - sf) - (1.0 - bfl) * sS[0]) / sS[0], (bml * (mag_m - sm) - (1.0 - bml) * sS[1]) / sS[1]]
    else:
        df, dm = v[NU + 2:NU + 5], v[NU + 5:NU + 8]
        if engine:      # the force's magnitude is its thrust (module docstring)
            rows = [ca.dot(dm, dm) - 1.0, (ca.dot(axis, u[U_FORCE]) - sf) / sS[0], (u[U_MOMENT] - sm * dm) / sS[1]]
        else:
            rows = [ca.dot(df, df) - 1.0, ca.dot(dm, dm) - 1.0, (u[U_FORCE] - sf * df) / sS[0],
                    (u[U_MOMENT] - sm * dm) / sS[1]]
    # the homotopy's smoothing: phi(s) = (1 - eps) s + eps s^2 / (2 r), phi = s at eps = 0
    phi_f = (1.0 - eps) * sf + eps * sf**2 / (2.0 * rf)
    phi_m = (1.0 - eps) * sm + eps * sm**2 / (2.0 * rm)
    cost = omega_per_h * h * (wf * phi_f + wm * phi_m) / s_obj
    name = "_".join(w for w in ("fuel_node", "l1" if l1 else "", "engine" if engine else "",
                                "freeh" if free_h else "") if w)
    return BlockFunction(ca.Function(name, [v, p], [cost, ca.vertcat(*rows)], ["v", "p"], ["cost", "rows"]))


@per_discretization
def channel_node(disc, free_h: bool) -> BlockFunction:
    """The fuel objective counted on channels at one control node (module docstring)."""
    v = ca.SX.sym("v", NU + 6 + (1 if free_h else 0))
    p = ca.SX.sym("p", NU + 2 + 5 + 18)
    sU, sS = p[:NU], p[NU:NU + 2]
    omega_per_h, hp, wf, wm, s_obj = (p[NU + 2 + k] for k in range(5))
    Qf, Qm = ca.reshape(p[NU + 7:NU + 16], 3, 3), ca.reshape(p[NU + 16:NU + 25], 3, 3)
    h = hp * v[-1] if free_h else hp
    u = v[:NU] * sU
    sf, sm = v[NU:NU + 3] * sS[0], v[NU + 3:NU + 6] * sS[1]
    Tf, Tm = Qf.T @ u[U_FORCE], Qm.T @ u[U_MOMENT]
    rows = ca.vertcat((Tf - sf) / sS[0], (-Tf - sf) / sS[0], (Tm - sm) / sS[1], (-Tm - sm) / sS[1])
    cost = omega_per_h * h * (wf * ca.sum1(sf) + wm * ca.sum1(sm)) / s_obj
    return BlockFunction(ca.Function("fuel_channels" + ("_freeh" if free_h else ""), [v, p], [cost, rows],
                                     ["v", "p"], ["cost", "rows"]))


def channel_blocks(tr, channels: tuple[np.ndarray, np.ndarray]) -> list:
    """The fuel block counted on the channels (Q_f, Q_m) of the NLP ``tr``, with its row scales (module
    docstring)."""
    problem, sc, control, sS = tr.problem, tr.scales, tr.problem.control, tr.magnitudes
    shared = np.r_[problem.h, control.W_f[0, 0], control.W_m[0, 0], sc.objective,
                   channels[0].ravel(order="F"), channels[1].ravel(order="F")]
    data = tr.node_parameters(np.r_[sc.U, sS], shared)
    block = Block("fuel", channel_node(problem.disc, tr.free_h), tr.node_variables(), data,
                  lbg=np.full(12, -np.inf), ubg=np.zeros(12))
    return [(block, np.repeat(sS, 6))]


def fuel_blocks(objective, tr) -> list:
    """The fuel block of the NLP ``tr`` for the Fuel ``objective`` (module docstring), with its row scales."""
    problem, lay, sc = tr.problem, tr.layout, tr.scales
    control = problem.control
    nU, sS = len(lay.control_nodes), tr.magnitudes
    engine = None if control.force_bound is None else control.force_bound.engine_axis
    l1 = not objective.epigraph
    ref = sS if objective.reference is None else np.asarray(objective.reference, float).reshape(2)
    shared = np.r_[problem.h, control.W_f[0, 0], control.W_m[0, 0], sc.objective,
                   engine if engine is not None else np.zeros(3), ref, objective.smoothing]
    structure = ([objective.burn.astype(float), np.repeat((np.asarray(objective.rounding, float) * sS)[:, None], nU,
                                                          axis=1)] if l1 else [])
    data = tr.node_parameters(np.r_[sc.U, sS], shared, *structure)
    fn = fuel_node(problem.disc, tr.free_h, l1, engine is not None)
    if l1:
        lbg, ubg, scales = np.full(2, -np.inf), np.zeros(2), sS
    elif engine is not None:
        lbg, ubg = np.r_[-np.inf, np.zeros(4)], np.zeros(5)
        scales = np.r_[1.0, sS[0], np.repeat(sS[1], 3)]
    else:
        lbg, ubg = np.r_[-np.inf, -np.inf, np.zeros(6)], np.zeros(8)
        scales = np.r_[1.0, 1.0, np.repeat(sS, 3)]
    return [(Block("fuel", fn, tr.node_variables(), data, lbg=lbg, ubg=ubg), scales)]


def fuel_rows(objective, tr, rows: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """The rows (3, nU) u - s d of the force and of the moment among the epigraph's fuel rows ``rows`` (nr, nU) of
    the NLP ``tr`` (the force's None where its magnitude is an engine's, linear: module docstring)."""
    force = tr.problem.control.force_bound
    if force is not None and force.engine_axis is not None:
        return None, rows[2:5]
    return rows[2:5], rows[5:8]


__all__ = ["channel_blocks", "channel_node", "fuel_blocks", "fuel_node", "fuel_rows", "fuel_slacks", "on_channels"]
