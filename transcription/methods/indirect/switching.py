"""The switching law of a control block under a cost linear in |u| (docs/mathematics.md §19): the minimizer of the
discrete Hamiltonian, on/off in magnitude along the primer direction, smoothed by the homotopy parameter eps.

For a block with the fuel weight w (W_blk = w I) and a norm bound |u| <= b, let v = -(s/h) W^-1 B_c^T lambda be the
effort law's unconstrained control (:func:`~.control.control_law`): the coefficient of u in the Lagrangian per unit
quadrature weight is -W v, so the control minimizes

    w [ eps |u|^2 / 2 + (1 - eps) |u| - v^T u ]     over |u| <= b,

the cost of the eps-problem sum_j omega_j w (eps |u_j|^2 / 2 + (1 - eps) |u_j|) (eps = 1: the effort objective with
the same weights and bounds, whose law is the saturation u = v min(1, b / |v|); eps -> 0: the fuel objective).  The
minimizer points along v (the primer vector -B^T lambda), with the magnitude

    m(|v|) = clip((|v| - 1 + eps) / eps, 0, b),

the switching function S = |v| - 1 (= |sigma| / w - 1 with sigma of :func:`~.objectives.switching_function`; this
law at eps = 0 is the discrete Hamiltonian's minimizer): full thrust where S > eps (b - 1), off where S < -eps, a ramp
between (eps = 0: bang-off-bang, set-valued at S = 0).  Pure CasADi (SX or MX), no state of the project."""
from __future__ import annotations

import casadi as ca

#: |v|^2 below this is 0 in the direction v / |v| (the magnitude is 0 there for eps < 1; finite derivatives)
TINY = 1e-300


def on_off(v, b, eps):
    """u = m(|v|) v / |v| (module docstring) for one block v (3), the norm bound b and eps in (0, 1]; piecewise
    smooth in v (the magnitude clipped by min/max, differentiated like the other saturations: the active branch)."""
    n = ca.sqrt(ca.fmax(ca.dot(v, v), TINY))
    m = b * ca.fmin(ca.fmax((n - 1.0 + eps) / eps, 0.0), 1.0)
    return v * (m / n)

