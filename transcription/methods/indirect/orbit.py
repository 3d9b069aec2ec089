"""The orbit target in the indirect method (docs/mathematics.md §19): the ten terminal conditions g(X_N) = 0 of
:func:`~transcription.ocp.orbit_residual` and the two transversality conditions K(X_N)^T lambda_{N-1} = 0.

The Lagrangian of §6 with the terminal conditions adjoined, L = J + sum_k lambda_k^T (step ⊖ X_{k+1}) + nu^T g(X_N),
is stationary in z_N (tangent coordinates at X_N, §4) when

    lambda_{N-1} = G^T nu,    G = d g(chart(X_N, z)) / dz at z = 0 (10 x 12),

i.e. lambda_{N-1} lies in the row space of G, the orthogonal complement of G's null space.  That null space is
spanned, wherever n x x_N != 0 and the body axis is not along a plane vector, by the two free motions on the
target set (the columns of K(X_N), 12 x 2; G K = 0 identically, tests/test_indirect_orbit.py):

    k_1 = [t; v_c n x t; 0; 0],  t = n x x_N    (sliding along the orbit, the circular momentum following)
    k_2 = [0; 0; b; 0]                           (spinning about the body axis b, which stays along the normal)

with v_c = m sqrt(mu / r_d) / r_d.  So nu is eliminated and the shooting residual stays square (12 x 12):

    F(lambda_0) = [g(X_N); K(X_N)^T lambda_{N-1}],
    dF/dlambda_0 = d[g; K^T lambda]/dz_N  dz_N/dlambda_0 + [0; K^T] dlambda_{N-1}/dlambda_0,

both derivatives of the rollout from the linearized recursion (:class:`~.shooting.ShootingFunctions`'s
``terminal_jac``), the terminal part from one SX Function of the target (:func:`orbit_shooting_function`)."""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...geometry.state import NX, NZ, chart, split_state
from ...ocp import Problem, TargetOrbit, orbit_residual


def null_basis(XN, target: TargetOrbit, mass: float, mu: float):
    """K(X_N) (12 x 2, SX): the two free motions on the orbit target set in tangent coordinates
    [dx; dgamma; zeta; dPi] at X_N (module docstring)."""
    n = ca.DM(target.normal)
    x = split_state(XN)[0]
    vc = mass * np.sqrt(mu / target.radius) / target.radius
    t = ca.cross(n, x)
    z3 = ca.DM.zeros(3)
    k1 = ca.vertcat(t, vc * ca.cross(n, t), z3, z3)
    k2 = ca.vertcat(z3, z3, ca.DM(target.body_axis), z3)
    return ca.horzcat(k1, k2)


def orbit_shooting_function(target: TargetOrbit, mass: float, mu: float) -> ca.Function:
    """``orbit_shooting`` (XN[18], lamN[12]) -> (F[12], JX[12x12], Jlam[12x12]): the residual F = [g(X_N) (10);
    K(X_N)^T lambda_{N-1} (2)] of the module docstring, JX = dF(chart(X_N, z), lamN)/dz at z = 0 and
    Jlam = dF/dlamN = [0; K^T]."""
    XN, lam, z = ca.SX.sym("XN", NX), ca.SX.sym("lamN", NZ), ca.SX.sym("z", NZ)

    def F(X):
        return ca.vertcat(orbit_residual(X, target, mass, mu), ca.mtimes(null_basis(X, target, mass, mu).T, lam))

    JX = ca.substitute(ca.jacobian(F(chart(XN, z)), z), z, ca.DM.zeros(NZ))
    return ca.Function("orbit_shooting", [XN, lam], [F(XN), JX, ca.jacobian(F(XN), lam)], ["XN", "lamN"],
                       ["F", "JX", "Jlam"])


class OrbitShooting:
    """The shooting residual and Jacobian of a problem with an orbit target (module docstring), in the form
    :func:`~transcription.methods.newton.newton_armijo` takes."""

    def __init__(self, problem: Problem):
        self.F = orbit_shooting_function(problem.terminal, problem.model.mass, problem.model.mu)

    def closures(self, fns, args: tuple):
        """(residual, jacobian) of lambda_0 for the shooting Functions ``fns`` at the data ``args`` = (X0, Xd, h,
        Winv, bd) (Xd is not read): residual -> (F, the rollout's largest Cayley residual), jacobian -> dF/dlam0."""
        def residual(lam):
            XN, lamN, r = fns.terminal(lam, *args)
            return np.array(self.F(XN, lamN)[0]).ravel(), float(r)

        def jacobian(lam):
            XN, lamN, dZ, dlamN = fns.terminal_jac(lam, *args)
            _, JX, Jl = self.F(XN, lamN)
            return np.array(JX) @ np.array(dZ) + np.array(Jl) @ np.array(dlamN)

        return residual, jacobian


def orbit_shooting(problem: Problem) -> OrbitShooting | None:
    """The :class:`OrbitShooting` of ``problem``, None unless its target is an orbit."""
    return OrbitShooting(problem) if isinstance(problem.terminal, TargetOrbit) else None
