"""The least peak force: min sigma + price (1/2) sum_j omega_j u_m,j^T W_m u_m,j subject to |u_f,j| <= sigma at every
control node -- the smallest thrust a force pointing anywhere needs for the maneuver (docs/mathematics.md §14,
*Within the engine's thrust*).

sigma is one variable of the NLP (the objective's variable at the first control node; the others held at 0 by their
bounds), its rows (|u_f,j|^2 - sigma^2) / s_f^2 <= 0.  The moment's effort keeps the attitude determined (sigma does not
see it); its price is s_f / e_m, s_f the force's scale and e_m the moment effort at the characteristic moments, so the
two terms are of one size in the scaled NLP.  On a problem whose translation does not depend on the attitude (the
relaxation of a body-fixed engine, :func:`~transcription.objectives.effort.relaxation`) the moment's term leaves the
peak as it is.  Not a file's objective: the effort strategy asks it whether an engine's thrust can be enough
(:meth:`~transcription.objectives.effort.RelaxedStart.within_hull`); the indirect method does not cover it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import casadi as ca
import numpy as np

from ..dynamics.lgvi import per_discretization
from ..geometry.state import NU, U_FORCE, U_MOMENT
from ..nlp.scaling import control_magnitudes
from ..nlp.structured import Block, BlockFunction
from ..ocp import Objective, Problem, ProblemError, quadrature_weights
from ..strategy.core import Composed, Solve, Warm


@per_discretization
def peak_node(disc) -> BlockFunction:
    """One control node j: v = [u_j / s_u (6); sigma / s_f], p = [s_u (6); s_f; omega_j h p / s_obj; vec W_m (9)];
    rows (|u_f|^2 - sigma^2) / s_f^2 (<= 0), cost omega_j h p (1/2) u_m^T W_m u_m / s_obj (the moment's effort at its
    price p)."""
    v, p = ca.SX.sym("v", NU + 1), ca.SX.sym("p", NU + 2 + 9)
    u, sigma = v[:NU] * p[:NU], v[NU] * p[NU]
    um = u[U_MOMENT]
    cost = p[NU + 1] * 0.5 * ca.bilin(ca.reshape(p[NU + 2:], 3, 3), um, um)
    rows = (ca.dot(u[U_FORCE], u[U_FORCE]) - sigma**2) / p[NU]**2
    return BlockFunction(ca.Function("peak_node", [v, p], [cost, rows], ["v", "p"], ["cost", "rows"]))


@per_discretization
def peak_cost(disc) -> BlockFunction:
    """sigma / s_obj: v = [sigma / s_f], p = [s_f; s_obj]."""
    v, p = ca.SX.sym("v", 1), ca.SX.sym("p", 2)
    return BlockFunction(ca.Function("peak_cost", [v, p], [v[0] * p[0] / p[1], ca.SX(0, 1)], ["v", "p"],
                                     ["cost", "rows"]))


@dataclass(frozen=True)
class PeakForce(Objective):
    """min sigma + price * (the moment's effort), |u_f,j| <= sigma (module docstring)."""

    name: ClassVar[str] = "peak_force"
    fatrop: ClassVar[str] = "fatrop is not used for the peak force (its one variable joins every stage)"

    def via_lgvi(self, problem) -> bool:
        return False

    def check(self, control) -> None:
        if control.force_bound is not None and control.force_bound.removed:
            raise ProblemError("control.objective", "the peak force needs a force")

    @staticmethod
    def _price(problem: Problem, sU: np.ndarray) -> float:
        """The moment effort's price s_f / e_m (module docstring) at the control scales sU (6,)."""
        e_m = 0.5 * problem.T * float(np.sum(np.diag(problem.control.W_m) * sU[U_MOMENT]**2))
        return float(sU[U_FORCE].max()) / e_m if e_m > 0 else 0.0

    def scales(self, problem: Problem, sU: np.ndarray) -> tuple[np.ndarray, float]:
        return sU, float(sU[U_FORCE].max())

    def value(self, problem: Problem, U: np.ndarray, h: float) -> float:
        U = np.asarray(U, float)
        omega = quadrature_weights(problem.scheme, problem.N, problem.steps_of(h))
        moment = 0.5 * float(np.einsum("k,ik,ij,jk->", omega, U[U_MOMENT], problem.control.W_m, U[U_MOMENT]))
        return least_peak_force(U) + self._price(problem, control_magnitudes(problem)) * moment

    def slacks(self, tr) -> int:
        return 1

    def slack_scales(self, tr) -> np.ndarray:
        return tr.magnitudes[:1]

    def slack_values(self, tr, U: np.ndarray) -> np.ndarray:
        S = np.zeros((1, U.shape[1]))
        S[0, 0] = least_peak_force(U)
        return S

    def slack_bounds(self, tr, lbx: np.ndarray, ubx: np.ndarray) -> None:
        iS = tr.layout.iS[0]
        lbx[iS[0]] = max(lbx[iS[0]], 0.0)
        lbx[iS[1:]] = ubx[iS[1:]] = 0.0

    def blocks(self, tr) -> list:
        problem, lay, sc = tr.problem, tr.layout, tr.scales
        nU, s_f, sigma = len(lay.control_nodes), tr.magnitudes[0], lay.iS[0, 0]
        if tr.free_h:
            raise ValueError("the peak force is an objective of a fixed final time")
        weight = tr.omega_per_h * problem.h * self._price(problem, sc.U) / sc.objective
        data = np.vstack([np.repeat(np.r_[sc.U, s_f][:, None], nU, axis=1), weight[None, :],
                          np.repeat(problem.control.W_m.ravel(order="F")[:, None], nU, axis=1)])
        nodes = Block("peak", peak_node(problem.disc), np.vstack([lay.iUn, np.full((1, nU), sigma)]), data,
                      lbg=-np.inf, ubg=0.0)
        cost = Block("peak_cost", peak_cost(problem.disc), np.array([sigma]), np.array([s_f, sc.objective]))
        return [(nodes, np.array([s_f**2])), (cost, np.zeros(0))]

    def strategy(self, problem: Problem, options) -> "PeakStrategy":
        return PeakStrategy()


@dataclass(frozen=True)
class PeakStrategy(Composed):
    """From a given start (the effort strategy gives its relaxed optimum), one warm solve; else one solve from the
    method's own start (the free motion)."""

    def compose(self, problem: Problem, options, start=None):
        return Warm() if start is not None else Solve(label="rollout")


def least_peak_force(U: np.ndarray) -> float:
    """max_j |u_f,j| of controls U (6, n)."""
    return float(np.linalg.norm(np.asarray(U, float)[U_FORCE], axis=0).max(initial=0.0))


__all__ = ["PeakForce", "PeakStrategy", "least_peak_force", "peak_cost", "peak_node"]
