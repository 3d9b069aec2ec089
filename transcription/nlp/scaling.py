"""The scales of the direct method's NLP (docs/mathematics.md §7, *Scaling*): every variable divided by a
characteristic magnitude (:func:`characteristic_scales`), every row by its variable's, the objective by its value at
the characteristic controls (:meth:`~transcription.ocp.objective.Objective.scales`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..ocp.estimate import target_estimate
from ..geometry.state import U_FORCE, U_MOMENT, X_ANG, X_MOM, unpack_states
from ..ocp import Problem, SmoothControl, TargetOrbit, terminal_rows
from . import blocks

@dataclass(frozen=True)
class Scales:
    """Characteristic magnitudes: state (18,), control (6,), Cayley (3,), objective scalar."""

    X: np.ndarray
    U: np.ndarray
    C: np.ndarray
    objective: float


def _state_magnitudes(problem: Problem) -> tuple[float, float, float, np.ndarray]:
    """(L, sg, sP, eigenvalues of J): the position, linear and angular momentum scales of
    :func:`characteristic_scales`."""
    a, d = unpack_states(problem.X0), unpack_states(target_estimate(problem))
    m, J, T = problem.model.mass, problem.disc.J, problem.T
    ev = np.linalg.eigvalsh(J)
    L = max(np.abs(a.x).max(), np.abs(d.x).max(), np.abs(d.x - a.x).max())
    L = L if L > 0 else 1.0
    sg = max(np.abs(a.gamma).max(), np.abs(d.gamma).max(), m * L / T)
    sP = max(np.abs(a.Pi).max(), np.abs(d.Pi).max(), ev[-1] / T)
    return L, sg, sP, ev


def control_magnitudes(problem: Problem) -> np.ndarray:
    """The characteristic control magnitudes (6,) before the objective balances them: the bounds' sizes where a
    control is bounded; else the momentum scales / T (:func:`characteristic_scales`), at most the problem's
    ``control_scales`` (the sizes of the bounds a relaxation dropped)."""
    L, sg, sP, _ = _state_magnitudes(problem)
    sU = np.concatenate([np.full(3, sg / problem.T), np.full(3, sP / problem.T)])
    if problem.control_scales is not None:
        sU = np.minimum(sU, problem.control_scales)
    control: SmoothControl = problem.control
    for sl, bound in ((U_FORCE, control.force_bound), (U_MOMENT, control.moment_bound)):
        if bound is not None and not bound.removed:
            sU[sl] = bound.sizes()
    return sU


def characteristic_scales(problem: Problem) -> Scales:
    """Magnitudes of the unknowns from the boundary data, the horizon, the body and the bounds.

    (max-norms throughout) positions L = max(|x0|, |xd|, |xd - x0|) (1 if all vanish: attitude-only
    maneuvers); linear momenta max(|gamma0|, |gammad|, m L / T); angular momenta max(|Pi0|, |Pid|,
    lambda_max(J) / T); forces and moments: :func:`control_magnitudes` (their bounds, or the scales a
    relaxation kept, or the momentum scale / T); attitude entries 1; Cayley vector h |Omega| / 2 with
    |Omega| the angular-momentum scale / lambda_min(J).  The objective's scale (and, for the effort
    objective, the control scales balanced): :meth:`~transcription.ocp.objective.Objective.scales`.
    """
    L, sg, sP, ev = _state_magnitudes(problem)
    sX = np.concatenate([np.full(3, L), np.full(3, sg), np.ones(9), np.full(3, sP)])
    sC = np.full(3, 0.5 * problem.h * sP / ev[0])
    sU, obj = problem.control.objective.scales(problem, control_magnitudes(problem))
    return Scales(X=sX, U=sU, C=sC, objective=obj)


def terminal_row_scales(problem: Problem, sc: Scales) -> np.ndarray:
    """Scales of the terminal rows of the NLP (the row divided by its scale is what the solver sees):
    a state target's fixed components (:func:`~transcription.nlp.blocks.state_target_scales`); an orbit
    target's :func:`~transcription.ocp.orbit_residual` rows (radius, out-of-plane position, the body
    axis (2), linear and angular momentum); a rendezvous target's rows as a state target's with its given
    components."""
    target = problem.terminal
    if isinstance(target, TargetOrbit):
        return np.concatenate([[target.radius, target.radius, 1.0, 1.0], sc.X[X_MOM], sc.X[X_ANG]])
    return blocks.state_target_scales(sc.X, target.fixed)    # a state or a rendezvous target


def scaled_terminal_miss(problem: Problem, XN: np.ndarray) -> float:
    """max |terminal row| / its scale at the final state XN (18,): how far XN is from the target in units of
    the problem's characteristic scales, as the solver sees it (inf if XN is not finite)."""
    XN = np.asarray(XN, float)
    if not np.all(np.isfinite(XN)):
        return float("inf")
    rows = np.asarray(terminal_rows(XN, problem), float).ravel()
    return float(np.max(np.abs(rows / terminal_row_scales(problem, characteristic_scales(problem)))))
