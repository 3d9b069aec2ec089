"""The control of the indirect method: the saturated law u = sat(-(s/h) W^-1 B_c^T lambda) of the costate
(docs/mathematics.md §6, §10), the control bounds as data, and the effort cost."""
from __future__ import annotations

from typing import Callable

import casadi as ca
import numpy as np

from ...geometry.state import NU, NX, U_FORCE, U_MOMENT
from ...dynamics.lgvi import Discretization, discretization, per_discretization
from ...ocp import Problem
from .switching import on_off

#: length of the bound data ``bd`` of the per-step Functions: the box half-widths b (6; inf: no box, 0: removed), the
#: squared norm bounds (force, moment; NO_NORM: none), a body-fixed engine (:data:`THRUSTER`, 9) and the fuel
#: objective's homotopy parameter eps (:data:`FUEL_EPS`)
NB = 18
NO_NORM = 1e300
#: the engine's part of ``bd`` (:class:`~transcription.ocp.ThrusterBound`, docs/mathematics.md §15): the unit
#: axis a (3), q = W_f a / (a^T W_f a) (3), T_min, T_max, and 1 (0 without an engine: all 0)
THRUSTER = slice(8, 17)
#: the index in ``bd`` of eps of the fuel objective's switching law (:func:`.switching.on_off`, docs/mathematics.md
#: §19): 0 (effort: the saturation) or in (0, 1] (the norm-bounded blocks follow the on/off law of eps)
FUEL_EPS = 17


def saturate(v, bd):
    """u = the minimizer of (1/2) u^T W u - u^T W v over the control bounds, v (6) the unconstrained minimizer
    (docs/mathematics.md §10, §15): each component clipped to its box, then each block scaled into its norm ball,

        u_i = min(max(v_i, -b_i), b_i),   u_blk <- u_blk sqrt(n_blk^2 / max(|u_blk|^2, n_blk^2));

    for the fuel objective (``bd[FUEL_EPS]`` = eps > 0) the on/off law :func:`.switching.on_off` on each norm-bounded
    block (§19); for a force with one body-fixed engine (axis a) the W_f-projection onto its segment,

        u_f = T a,   T = min(max(q^T v_f, T_min), T_max),   q = W_f a / (a^T W_f a).

    Exact for the weights the indirect method accepts (:func:`~.solve.not_covered`: a box with a diagonal block of W,
    a norm with an isotropic one, an engine with any).  Without bounds u = v bit for bit; the squared form keeps the
    derivative finite at u = 0.
    """
    u = ca.fmin(ca.fmax(v, -bd[:NU]), bd[:NU])
    blocks = []
    eps = bd[FUEL_EPS]
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        ub, n2 = u[sl], bd[NU + i]
        effort = ub * ca.sqrt(n2 / ca.fmax(ca.dot(ub, ub), n2))
        # the fuel objective (eps > 0): on/off along v (a removed control, clipped to 0 above, stays 0)
        blocks.append(ca.if_else(eps > 0, on_off(ub, ca.sqrt(n2), ca.if_else(eps > 0, eps, 1.0)), effort))
    e = bd[THRUSTER]
    thrust = ca.fmin(ca.fmax(ca.dot(e[3:6], v[U_FORCE]), e[6]), e[7])
    blocks[0] = ca.if_else(e[8], thrust * e[0:3], blocks[0])
    return ca.vertcat(*blocks)


def saturation() -> ca.Function:
    """``saturation`` (v[6], bd[NB]) -> (u[6], D[6x6]): :func:`saturate` and its (generalized) Jacobian
    D = du/dv, the element of the Clarke Jacobian that CasADi's derivatives of min/max pick (the active
    branch; 1/2 at an exact tie) -- what the semismooth Newton method differentiates through."""
    v, bd = ca.SX.sym("v", NU), ca.SX.sym("bd", NB)
    u = saturate(v, bd)
    return ca.Function("saturation", [v, bd], [u, ca.jacobian(u, v)], ["v", "bd"], ["u", "D"])


def bound_data(problem: Problem) -> np.ndarray:
    """The bound data ``bd`` (NB) of a smooth-control problem (see :data:`NB`; for the fuel objective eps = 1, the
    start of its homotopy, :mod:`.fuel`)."""
    bd = np.r_[np.full(NU, np.inf), NO_NORM, NO_NORM, np.zeros(NB - NU - 2)]
    c = problem.control
    for i, (sl, bound) in enumerate(((U_FORCE, c.force_bound), (U_MOMENT, c.moment_bound))):
        if bound is None:
            continue
        box, a = bound.variable_box(), bound.engine_axis
        if a is not None:               # an engine (on the force): the W_f-projection onto its thrust segment
            bd[THRUSTER] = np.r_[a, c.W_f @ a / (a @ c.W_f @ a), *bound.engine_range, 1.0]
        elif box is not None:           # a symmetric box on the axes (0: removed)
            bd[sl] = np.minimum(-box[0], box[1])
        elif np.isfinite(bound.radius):
            bd[NU + i] = bound.radius ** 2
    law = problem.control.objective.indirect
    bd[FUEL_EPS] = law.eps if law is not None else 0.0
    return bd


def bounded(bd: np.ndarray) -> bool:
    """Whether bound data bd bounds a control (a removed control, b = 0, is structure, not a bound)."""
    box = bd[:NU]
    return bool(np.any(np.isfinite(box) & (box > 0)) or np.any(bd[NU:NU + 2] < NO_NORM) or bd[THRUSTER][-1] != 0)


@per_discretization
def control_matrix(disc: Discretization) -> ca.Function:
    """``{scheme}_control_matrix`` (h) -> B_c[12x6]: the tangent-coordinate derivative of X_{k+1} by the control the
    costate lambda_k determines (first_order: B_k by u_{k+1}; lgvi: B^b), u = -(s/h) Winv B_c^T lambda.  Taken from
    the graph (``disc.variation_seeded``) and checked, when built, to be constant and A_k and the Cayley right-hand
    side to be independent of that control: the assumptions of the forward costate recursion.  With a body-fixed
    force: the inertial scheme's, B'_c = T(X_{k+1}) B_c in body-momentum coordinates (docs/mathematics.md §15; the
    graph does not simplify R^T R = I, so it is built and checked there).
    """
    if disc.force_frame != "inertial":
        return control_matrix(discretization(disc.model, disc.scheme, disc.newton_iters))
    X = ca.SX.sym("X", NX)
    w = ca.SX.sym("w", disc.nw)
    h = ca.SX.sym("h")
    c0 = ca.SX.sym("c0", 3)
    A, B = disc.variation_seeded(X, w, h, c0)
    wb = w if disc.scheme == "first_order" else w[NU:]  # the control lambda_k determines
    Bc = B[:, -NU:]
    if ca.depends_on(A, wb) or ca.depends_on(Bc, ca.vertcat(X, w, c0)) or \
            ca.depends_on(disc.cayley_rhs(X, w, h), wb):
        raise ValueError("A_k or the Cayley equation depends on the control determined by lambda_k, or its B is not "
                         "constant: the forward costate recursion does not apply")
    return ca.Function(f"{disc.scheme}_control_matrix", [h], [Bc], ["h"], ["B"])


def control_scale(disc: Discretization) -> float:
    """s of the control law: 1 (first_order) or 2 (lgvi, see LGVI_CONDITIONS in .conditions)."""
    return 1.0 if disc.scheme == "first_order" else 2.0


def control_law(disc: Discretization, h, Winv, bd) -> Callable:
    """The one saturated control law of the costate (SX or MX alike): lambda -> (u, D),

        u = sat(-(s/h) Winv B_c^T lambda),   D = du/dv (the saturation's generalized Jacobian, :func:`saturation`)

    with B_c = :func:`control_matrix` (built once here) and s = :func:`control_scale` (first_order: u_{k+1}
    from lambda_k, eqs. 26-27; lgvi: u_j from lambda_{j-1})."""
    Bc = control_matrix(disc)(h)
    scale = control_scale(disc)

    def law(lam):
        return saturation()(-scale * ca.mtimes(Winv, ca.mtimes(Bc.T, lam)) / h, bd)

    return law


def weight_inverse(problem: Problem) -> np.ndarray:
    """blkdiag(W_f, W_m)^-1 (6x6) of a smooth-control problem."""
    return np.linalg.inv(problem.control.W)


def control_cost(problem: Problem, U: np.ndarray, h: float | None = None) -> float:
    """The cost of controls U (6 x n_controls) under the objective's law (:mod:`.laws`: the effort cost, the fuel cost
    for the fuel objective) with the quadrature weights of the scheme at the steps of the (mean) step size h
    (default: the problem's; on a non-uniform mesh the steps h r_k, docs/mathematics.md §16)."""
    return problem.control.objective.indirect.cost(problem, U, problem.h if h is None else h)
