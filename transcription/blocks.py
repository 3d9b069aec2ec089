"""The block Functions of the multiple-shooting NLPs (see transcription.nlp for what a block is).

Each builder returns an SX Function ``(v, p) -> (cost, rows)`` in *scaled* variables: the
physical value of a local variable is v * (its scale), rows are divided by their scales and the
cost by the objective scale, every scale being part of the data p.  Problem data (step size,
weights, targets) are data too, so one Function -- and its compiled derivatives -- serves every
problem of the same structure; builders with only structural arguments are cached.

    dynamics(disc, with_c, controls, effort)   one step k -> k+1 (docs/mathematics.md §2-§3, §6)
        v = [X_k (18); c_k (3, with_c); w_k (nw, controls); X_{k+1} (18)]
        p = [h; sX (18); sC (3, with_c); sW (nw, controls); sG (3, with_c); s_obj; W_f (9); W_m (9) (effort)]
        rows = [(step(X_k, c_k, w_k, h) - X_{k+1}) / sX (18); G(c_k) / sG (3, with_c)]
        cost = the step's share of sum_j omega_j (1/2) u_j^T W u_j, / s_obj (effort; else 0)
    state_target(fixed)                        the terminal conditions of a state target
        v = X_N (18); p = [sX (18); Xd (18); row scales (3 per fixed component)]
        rows = terminal_residual(X_N, Xd) / scales (docs/mathematics.md §6); cost 0
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from .layout import NU, NX
from .problem import STATE_COMPONENTS, state_residual

NC = 3


def dynamics_sizes(disc, with_c: bool, controls: bool, effort: bool) -> tuple[int, int]:
    """(nv, np) of :func:`dynamics`."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    return NX + nc + nw + NX, 1 + NX + nc + nw + nc + (1 + 18 if effort else 0)


@lru_cache(maxsize=None)
def dynamics(disc, with_c: bool, controls: bool, effort: bool) -> ca.Function:
    """The dynamics block of one step (module docstring); cached per (Discretization, flags)."""
    nc = NC if with_c else 0
    nw = disc.nw if controls else 0
    nv, npar = dynamics_sizes(disc, with_c, controls, effort)
    v = ca.SX.sym("v", nv)
    p = ca.SX.sym("p", npar)
    h = p[0]
    sX = p[1:1 + NX]
    i = 1 + NX
    sC = p[i:i + nc]
    i += nc
    sW = p[i:i + nw]
    i += nw
    sG = p[i:i + nc]
    i += nc
    X = v[:NX] * sX
    w = v[NX + nc:NX + nc + nw] * sW if controls else ca.DM.zeros(disc.nw)
    X1 = v[NX + nc + nw:] * sX
    if with_c:
        Xn, G = disc.step_given_c(X, v[NX:NX + nc] * sC, w, h)
        rows = ca.vertcat((Xn - X1) / sX, G / sG)
    else:
        Xn, _ = disc.step(X, w, h)
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
    tag = f"{disc.scheme}{'_c' if with_c else ''}{'_u' if controls else ''}{'_effort' if effort else ''}"
    return ca.Function(f"dynamics_{tag}", [v, p], [cost, rows], ["v", "p"], ["cost", "rows"])


def dynamics_data(disc, h: float, sX, sC, sW, sG, s_obj=None, W_f=None, W_m=None) -> np.ndarray:
    """The data vector p of :func:`dynamics` (None entries are omitted: match the flags)."""
    parts = [[h], sX]
    parts += [sC] if sC is not None else []
    parts += [sW] if sW is not None else []
    parts += [sG] if sG is not None else []
    if s_obj is not None:
        parts += [[s_obj], np.asarray(W_f, float).ravel(order="F"), np.asarray(W_m, float).ravel(order="F")]
    return np.concatenate([np.asarray(a, dtype=float).ravel() for a in parts])


@lru_cache(maxsize=None)
def state_target(fixed: tuple[str, ...]) -> ca.Function:
    """The terminal rows of a state target with the components ``fixed`` (module docstring)."""
    nr = 3 * len(fixed)
    v = ca.SX.sym("v", NX)
    p = ca.SX.sym("p", 2 * NX + nr)
    sX, Xd, sr = p[:NX], p[NX:2 * NX], p[2 * NX:]
    rows = state_residual(v * sX, Xd, fixed) / sr
    tag = "_".join(c[:3] for c in fixed)
    return ca.Function(f"state_target_{tag}", [v, p], [ca.SX(0), rows], ["v", "p"], ["cost", "rows"])


def state_target_scales(sX: np.ndarray, fixed: tuple[str, ...]) -> np.ndarray:
    """Row scales of :func:`state_target`: the state scales of each block, 1 for the attitude."""
    per = {"position": sX[0:3], "velocity": sX[3:6], "attitude": np.ones(3), "angular_velocity": sX[15:18]}
    return np.concatenate([per[c] for c in fixed])


__all__ = ["NC", "STATE_COMPONENTS", "dynamics", "dynamics_data", "dynamics_sizes", "state_target",
           "state_target_scales"]
