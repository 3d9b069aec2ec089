"""Costs and what the controls do (docs/mathematics.md §5-§6, §10): quadrature weights, effort, fuel, the
objective of a problem, the activity of bounded controls, the impulse cost."""
from __future__ import annotations

import numpy as np

from ..layout import U_FORCE, U_MOMENT
from .controls import BoxBound, NormBound, SmoothControl
from .definition import Problem


def quadrature_weights(scheme: str, N: int, h: float) -> np.ndarray:
    """omega_j of the controls (in the order of their nodes): first_order, controls u_1..u_N:
    h (1, ..., 1); lgvi, node controls u_0..u_N: the trapezoidal h (1/2, 1, ..., 1, 1/2), so that
    both approximate the integral of (1/2) u^T W u."""
    if scheme == "lgvi":
        om = np.full(N + 1, float(h))
        om[[0, -1]] = 0.5 * h
        return om
    return np.full(N, float(h))


def effort_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (1/2) u_j^T W u_j for U (6, n_controls), W = blkdiag(W_f, W_m)."""
    U = np.asarray(U, dtype=float)
    return float(0.5 * np.einsum("k,ik,ij,jk->", omega, U, control.W, U))


def fuel_cost(U: np.ndarray, control: SmoothControl, omega: np.ndarray) -> float:
    """sum_j omega_j (w_f |u_f,j| + w_m |u_m,j|) for U (6, n_controls) (the fuel objective)."""
    U = np.asarray(U, dtype=float)
    return float(np.sum(omega * (control.W_f[0, 0] * np.linalg.norm(U[U_FORCE], axis=0)
                                 + control.W_m[0, 0] * np.linalg.norm(U[U_MOMENT], axis=0))))


def objective_value(problem: "Problem", U: np.ndarray, h: float) -> float:
    """The objective of a smooth-control problem for controls U with step size h: effort, fuel
    (with the quadrature weights of the scheme) or the final time N h."""
    control: SmoothControl = problem.control
    if control.objective == "time":
        return float(problem.N * h)
    omega = quadrature_weights(problem.scheme, problem.N, h)
    return fuel_cost(U, control, omega) if control.objective == "fuel" else effort_cost(U, control, omega)


def control_activity(control: SmoothControl, U: np.ndarray, weights: np.ndarray, times: np.ndarray) -> dict:
    """Where the bounded controls sit on their bounds, per control ('force', 'moment'): at_bound_fraction
    (of the control nodes at the bound, :meth:`BoxBound.active` / :meth:`NormBound.active`: within
    AT_BOUND_RTOL), time_at_bound = sum_j omega_j over them (``weights`` the quadrature weights, so that
    it is the time the controls at the bound act), and switch_times: for a box bound every sign change
    of a component (the switches of a bang-bang control; linear interpolation between the node
    ``times``), for a norm bound the times where the control enters or leaves the bound (midpoints).
    Removed and unbounded controls are left out."""
    U = np.asarray(U, dtype=float)
    t = np.asarray(times, dtype=float)
    out = {}
    for name, sl, bound in (("force", U_FORCE, control.force_bound), ("moment", U_MOMENT, control.moment_bound)):
        if bound is None or (isinstance(bound, NormBound) and bound.b == 0):
            continue
        u = U[sl].T
        at = bound.active(u)
        if isinstance(bound, BoxBound):
            switches = []
            for i in range(3):
                ui = u[:, i]
                k = np.flatnonzero(ui[:-1] * ui[1:] < 0)
                switches.append([float(t[j] + (t[j + 1] - t[j]) * ui[j] / (ui[j] - ui[j + 1])) for j in k])
        else:
            k = np.flatnonzero(at[:-1] != at[1:])
            switches = [float(0.5 * (t[j] + t[j + 1])) for j in k]
        out[name] = {"bound": "box" if isinstance(bound, BoxBound) else "norm",
                     "at_bound_fraction": float(at.mean()) if len(at) else 0.0,
                     "time_at_bound": float(np.asarray(weights, float) @ at), "switch_times": switches}
    return out


def impulse_cost(impulses: dict[str, np.ndarray]) -> float:
    """The sum of the norms of the impulses (docs/mathematics.md §5)."""
    return float(sum(np.linalg.norm(v) for v in impulses.values()))
