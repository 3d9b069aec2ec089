"""The exact two-body flow on a symbolic graph: the drift of the Kepler-split LGVI (docs/mathematics.md §2a).

For x'' = -mu x / |x|^3 the state (x, v) after a time h is Lagrange's f and g (universal variables, Battin §4.5):

    alpha = 2/r0 - |v0|^2/mu,   sigma0 = x0.v0 / sqrt(mu),   z = alpha chi^2
    F(chi) = sigma0 chi^2 C(z) + (1 - alpha r0) chi^3 S(z) + r0 chi - sqrt(mu) h = 0        (Kepler's equation)
    x1 = f x0 + g v0,   v1 = fd x0 + gd v0
    f = 1 - chi^2 C / r0,   g = h - chi^3 S / sqrt(mu),   fd = sqrt(mu) chi (z S - 1) / (r r0),   gd = 1 - chi^2 C / r

with the Stumpff functions C(z) = sum_k (-z)^k / (2k+2)!, S(z) = sum_k (-z)^k / (2k+3)!: entire series, summed to
:data:`STUMPFF_TERMS` terms by Horner's rule -- one expression for elliptic (z > 0) and hyperbolic (z < 0) steps, no
branch and no cancellation of 1 - cos at small z.  Kepler's equation is solved by :data:`NEWTON_ITERS` Newton
iterations (F'(chi) = r) unrolled on the graph from its second-order series root, so the flow stays a plain SX
expression with the implicit function's derivatives; its relative residual |F(chi)| / (sqrt(mu) |h|) is an output
(the step reports it beside the Cayley residual), or |z| / Z_MAX > 1 for a step past the series' range.  Valid for
|z| <= :data:`Z_MAX` (a step of at most ~3 rad of eccentric anomaly: three steps per orbit), where the truncated
series are exact to round-off.

    kepler_drift(mu) (x[3], v[3], h) -> (x1[3], v1[3], res)
"""
from __future__ import annotations

import functools
import math

import casadi as ca

#: terms of the Stumpff series: the first omitted term is below 1e-17 of C and S for |z| <= Z_MAX
STUMPFF_TERMS = 18
#: the |z| = |alpha| chi^2 up to which the truncated series are exact to round-off (tests/test_kepler.py)
Z_MAX = 10.0
#: unrolled Newton iterations on Kepler's equation: from the second-order series root the error is O((n h)^3);
#: quadratic convergence reaches round-off in three for n h <= 0.5 rad and in five up to |z| = Z_MAX
NEWTON_ITERS = 6


def stumpff(z):
    """(C(z), S(z)) by their series (module docstring); z a number or an SX/MX expression."""
    C = 1.0 / math.factorial(2 * STUMPFF_TERMS)
    S = 1.0 / math.factorial(2 * STUMPFF_TERMS + 1)
    for k in range(STUMPFF_TERMS - 2, -1, -1):
        C = 1.0 / math.factorial(2 * k + 2) - z * C
        S = 1.0 / math.factorial(2 * k + 3) - z * S
    return C, S


def kepler_force(mu: float, m, x):
    """The central body's point-mass force on a mass m at x (3): -mu m x / |x|^3 (what the drift flies exactly)."""
    r = ca.norm_2(x)
    return -mu * m * x / r**3


@functools.lru_cache(maxsize=None)
def kepler_drift(mu: float) -> ca.Function:
    """``kepler_drift`` (x[3], v[3], h) -> (x1[3], v1[3], res): the two-body flow over h (module docstring)."""
    x, v, h = ca.SX.sym("x", 3), ca.SX.sym("v", 3), ca.SX.sym("h")
    smu = math.sqrt(mu)
    r0 = ca.norm_2(x)
    alpha = 2.0 / r0 - ca.dot(v, v) / mu
    sigma0 = ca.dot(x, v) / smu

    def kepler(chi):
        z = alpha * chi**2
        C, S = stumpff(z)
        F = sigma0 * chi**2 * C + (1 - alpha * r0) * chi**3 * S + r0 * chi - smu * h
        r = sigma0 * chi * (1 - z * S) + (1 - alpha * r0) * chi**2 * C + r0        # F'(chi)
        return F, r, C, S, z

    s = smu * h / r0
    chi = s - sigma0 * s**2 / (2 * r0)                                            # series root, O((n h)^3)
    for _ in range(NEWTON_ITERS):
        F, r, *_ = kepler(chi)
        chi = chi - F / r
    F, r, C, S, z = kepler(chi)
    f = 1 - chi**2 * C / r0
    g = h - chi**3 * S / smu
    x1 = f * x + g * v
    r1 = ca.norm_2(x1)
    fd = smu * chi * (z * S - 1) / (r1 * r0)
    gd = 1 - chi**2 * C / r1
    v1 = fd * x + gd * v
    # a step past the series' range reports |z| / Z_MAX > 1: failed, like an unsolved equation
    res = ca.fmax(ca.fabs(F) / ca.fmax(smu * ca.fabs(h), 1e-300), ca.if_else(ca.fabs(z) > Z_MAX, ca.fabs(z) / Z_MAX, 0))
    return ca.Function("kepler_drift", [x, v, h], [x1, v1, res], ["x", "v", "h"], ["x1", "v1", "res"])
