"""Costs and what the controls do (docs/mathematics.md §5-§6, §10): quadrature weights, effort, fuel, the
objective of a problem, the activity of bounded controls, the impulse cost."""
from __future__ import annotations

import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.state import U_FORCE, U_MOMENT
from .controls import SmoothControl
from .problem import Problem


def quadrature_weights(scheme: str, N: int, h) -> np.ndarray:
    """omega_j of the controls (in the order of their nodes): first_order, controls u_1..u_N:
    h (1, ..., 1); lgvi, node controls u_0..u_N: the trapezoidal h (1/2, 1, ..., 1, 1/2), so that
    both approximate the integral of (1/2) u^T W u.  On a non-uniform mesh h is the N step sizes h_k
    (docs/mathematics.md §16): first_order omega_j = h_{j-1} (u_j acts over step j-1); lgvi the trapezoid
    per step, omega_j = (h_{j-1} + h_j) / 2 (h_{-1} = h_N = 0)."""
    hs = np.asarray(h, dtype=float)
    if hs.ndim:
        if hs.shape != (N,):
            raise ValueError(f"quadrature_weights: expected one step size or {N}, got shape {hs.shape}")
        if two_point(scheme):
            return 0.5 * (np.r_[hs, 0.0] + np.r_[0.0, hs])
        return hs.copy()
    if two_point(scheme):
        om = np.full(N + 1, float(h))
        om[[0, -1]] = 0.5 * h
        return om
    return np.full(N, float(h))


def effort_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (1/2) u_j^T W u_j for U (6, n_controls), W = blkdiag(W_f, W_m)."""
    U = np.asarray(U, dtype=float)
    return float(0.5 * np.einsum("k,ik,ij,jk->", omega, U, control.W, U))


def fuel_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|) for U (6, n_controls) (the fuel objective), each |u| the part's
    actuator's fuel rate (:meth:`~.actuators.Actuator.fuel`: sum_i |T_i| over a box's or an engine's channels), the
    2-norm for an unbounded part."""
    U = np.asarray(U, dtype=float)
    rate = [np.linalg.norm(U[sl], axis=0) if b is None else b.fuel(U[sl].T)
            for sl, b in ((U_FORCE, control.force_bound), (U_MOMENT, control.moment_bound))]
    return float(np.sum(omega * (control.W_f[0, 0] * rate[0] + control.W_m[0, 0] * rate[1])))


def objective_value(problem: "Problem", U: np.ndarray, h: float) -> float:
    """The objective of a smooth-control problem for controls U with (mean) step size h (its objective's value:
    :meth:`~transcription.ocp.objective.Objective.value`)."""
    return problem.control.objective.value(problem, U, h)


def control_activity(control: SmoothControl, U: np.ndarray, weights: np.ndarray, times: np.ndarray) -> dict:
    """Where the bounded controls sit on their bounds, per control ('force', 'moment'): at_bound_fraction (of the
    control nodes at the bound, :meth:`~.actuators.Actuator.active`), time_at_bound = sum_j omega_j over them
    (``weights`` the quadrature weights), and switch_times (:meth:`~.actuators.Actuator.switches` at the node
    ``times``).  Removed and unbounded controls are left out."""
    U = np.asarray(U, dtype=float)
    t = np.asarray(times, dtype=float)
    out = {}
    for name, sl, bound in (("force", U_FORCE, control.force_bound), ("moment", U_MOMENT, control.moment_bound)):
        if bound is None or bound.removed:
            continue
        u = U[sl].T
        at = bound.active(u)
        out[name] = {"bound": bound.kind, "at_bound_fraction": float(at.mean()) if len(at) else 0.0,
                     "time_at_bound": float(np.asarray(weights, float) @ at), "switch_times": bound.switches(u, t)}
    return out


#: the engine counts as on where |u_f| exceeds this fraction of its reference: the force bound's largest
#: |u_f| (an engine's max, a norm bound, |b| of a box) or, unbounded, the peak |u_f| of the controls
ENGINE_ON_RTOL = 1e-3


def engine_reference(bound, u_f: np.ndarray) -> float:
    """F_ref, the force the engine-on threshold is a fraction of: the largest |u_f| the bound allows
    (``largest_norm``), else the peak max_j |u_f,j| of the controls u_f (n, 3)."""
    if bound is not None:
        return bound.largest_norm()
    return float(np.linalg.norm(np.asarray(u_f, dtype=float), axis=1).max(initial=0.0))


def engine_figures(u_f: np.ndarray, weights: np.ndarray, bound) -> dict:
    """The engine's figures of merit (docs/mathematics.md §14) for force controls u_f (n, 3) with quadrature
    ``weights`` (n,): engine_on_time = sum_j omega_j over the controls with |u_f,j| > ENGINE_ON_RTOL F_ref
    (F_ref: a thruster's max, a norm bound b, |b|_2 of a box bound, else max_j |u_f,j|; 0 without force);
    for a thruster also engine_off_axis_relative = max_j |u_f,j - T_j a| / max (0 for a feasible control)."""
    u_f = np.asarray(u_f, dtype=float)
    n = np.linalg.norm(u_f, axis=1)
    ref = engine_reference(bound, u_f)
    out = {"engine_on_time": float(np.asarray(weights, float) @ (n > ENGINE_ON_RTOL * ref)) if ref > 0 else 0.0}
    if bound is not None and bound.fixed.any():     # an engine: the force it cannot give, relative to its size
        out["engine_off_axis_relative"] = float(bound.unavailable(u_f).max(initial=0.0) / bound.scale())
    return out


def impulse_cost(impulses: dict[str, np.ndarray]) -> float:
    """The sum of the norms of the impulses (docs/mathematics.md §5)."""
    return float(sum(np.linalg.norm(v) for v in impulses.values()))
