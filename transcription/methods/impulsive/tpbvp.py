"""The impulsive two-point boundary value problem (a state target, E1): the six conditions on x_N and R_N solved
for the momenta after the first impulse by the shared Newton-Armijo (docs/mathematics.md §5)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...geometry.state import Z_POS, Z_ROT, unpack_states
from ...dynamics.lgvi import CAYLEY_TOL
from ...geometry.so3 import log_so3_any, right_jacobian_inv
from ..newton import NewtonResult, newton_armijo
from ...ocp import Problem, TargetOrbit, TargetState
from ...outcome import Iterate
from .sensitivity import P_COLS, sensitivity, with_momenta


@dataclass(frozen=True)
class ImpulsiveSettings:
    """The impulsive method's numerical parameters (:class:`~.solve.Impulsive` holds them; tests set them)."""

    newton_tol: float = 1e-13      # Newton target for the six TPBVP conditions (|r|_inf) and its iteration limit
    newton_max_iter: int = 50
    newton_max_halvings: int = 34  # the TPBVP line search halves down to c ~ 1e-10
    stagnation_steps: int = 8      # consecutive line-search steps below 1e-2 after which Newton gives up (stagnated)
    kink_tol: float = 1e-8         # an impulse norm below this at the relaxed optimum means a kink of the cost
    max_step: float = 1.0          # single shooting of the relaxed case: the step cap in scaled unknowns
    #: the projection onto c = 0 stops at |c|_inf <= this (scaled); below the test tolerances, above round-off
    projection_tol: float = 1e-12
    projection_max_iter: int = 8
    armijo: float = 1e-4           # Armijo constant of the reduced line search


def tpbvp_residual(XN: np.ndarray, Xd: np.ndarray) -> np.ndarray:
    """r = [x_N - x_d; vee log(R_d^T R_N)] (6,): the six conditions of the TPBVP."""
    a, d = unpack_states(XN), unpack_states(Xd)
    return np.concatenate([a.x[0] - d.x[0], log_so3_any(d.R[0].T @ a.R[0])])


def tpbvp_jacobian(XN: np.ndarray, Xd: np.ndarray, Phi: np.ndarray) -> np.ndarray:
    """dr/dp (6 x 6) from Phi: rows x and Jr^-1 zeta, columns gamma_0 and Pi_0."""
    e = tpbvp_residual(XN, Xd)[3:]
    return np.vstack([Phi[Z_POS][:, P_COLS], right_jacobian_inv(e) @ Phi[Z_ROT][:, P_COLS]])


def initial_momenta(problem: Problem, kind: str) -> np.ndarray:
    """p from the initial state ('rollout': no impulse) or, for a state target, 'interpolate':
    Pi_0^+ = J log(R_0^T R_d) / T (the constant rate that turns R_0 into R_d)."""
    a = unpack_states(problem.X0)
    p = np.concatenate([a.gamma[0], a.Pi[0]])
    if kind == "interpolate" and isinstance(problem.terminal, TargetState):
        d = unpack_states(problem.terminal.X)
        p[3:] = problem.disc.J @ log_so3_any(a.R[0].T @ d.R[0]) / problem.T
    return p


def simulate_momenta(problem: Problem, p: np.ndarray) -> tuple[np.ndarray, float]:
    """Free rollout (N+1, 18) from X0 with momenta p, and its largest relative Cayley residual."""
    X, res = problem.disc.simulate(with_momenta(problem.X0, p), None, problem.h, problem.N)
    return X, float(np.max(res)) if res.size else 0.0


def momentum_scales(problem: Problem) -> np.ndarray:
    """Characteristic sizes of p = (gamma_0^+, Pi_0^+) (6,): max(|gamma_0|, m L / T) and
    max(|Pi_0|, lambda_max(J) / T).  Used to scale the unknowns and to cap Newton steps."""
    a0 = unpack_states(problem.X0)
    J, T = problem.disc.J, problem.T
    L = max(np.abs(a0.x).max(), float(problem.terminal.radius) if isinstance(problem.terminal, TargetOrbit)
            else np.abs(unpack_states(problem.terminal.X).x).max())
    sg = max(np.abs(a0.gamma).max(), problem.model.mass * L / T)
    sP = max(np.abs(a0.Pi).max(), np.linalg.eigvalsh(J)[-1] / T)
    return np.r_[np.full(3, sg), np.full(3, sP)]


def solve_tpbvp(problem: Problem, p0: np.ndarray, s: ImpulsiveSettings, alpha: float = 1e-4,
                progress: Callable[[Iterate], None] | None = None) -> tuple[NewtonResult, np.ndarray]:
    """Newton-Armijo on the six conditions from p0 with the settings s; returns (NewtonResult, X of its last point)."""
    Xd = problem.terminal.X
    memo: dict[bytes, tuple[np.ndarray, float]] = {}

    def rollout(p):
        key = p.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = simulate_momenta(problem, p)
        return memo[key]

    def residual(p):
        X, res = rollout(p)
        return (tpbvp_residual(X[-1], Xd) if np.all(np.isfinite(X[-1])) else np.full(6, np.nan)), res

    def jacobian(p):
        X, _ = rollout(p)
        return tpbvp_jacobian(X[-1], Xd, sensitivity(problem.disc, X, problem.h))

    nr = newton_armijo(p0, residual, jacobian, tol=s.newton_tol, norm=np.inf, alpha=alpha, max_iter=s.newton_max_iter,
                       max_halvings=s.newton_max_halvings, aux_tol=CAYLEY_TOL, step_scale=momentum_scales(problem),
                       stagnation_steps=s.stagnation_steps, progress=progress)
    return nr, rollout(nr.x)[0]
