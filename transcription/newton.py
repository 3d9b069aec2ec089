"""Newton-Armijo on a square system F(x) = 0: the one Newton loop of the project.

Used by the indirect method (x = the initial costate, F = the terminal residual z_N, Psi its
Jacobian) and by the impulsive two-point boundary value problem (x = the momenta after the first
impulse, F = the six terminal conditions on x_N, R_N).  The iteration is the paper's (Kelley
1995; docs/mathematics.md §6):

    D = -J(x)^-1 F(x);  c = 1, 1/2, 1/4, ... until |F(x + c D)|_2 <= (1 - alpha c) |F(x)|_2;
    x <- x + c D;       stop when the convergence norm of F is <= tol.

Refinements, each optional and reported in the result:

* ``residual`` returns (F, aux): a trial whose ``aux`` exceeds ``aux_tol`` (the largest relative
  Cayley residual of its rollout: the controls or momenta turn the body too fast for h) or whose F
  is not finite is rejected like one that does not decrease.
* a full step that lands at or below ``tol`` is accepted even if Armijo's test fails there.
* ``step_scale``: every direction is capped to |D / step_scale|_inf <= 1 (a crude trust region).
* ``floor_factor``: round-off floor detection.  When the full step fails Armijo, the round-off
  level of F at x is *measured* (:func:`noise_level`); if |F| is within ``floor_factor`` of it
  there is no further decrease to be had: stop with Result.round_off_floor (or floor_too_high
  above ``floor_accept``).  Also after NEAR_FLOOR_HALVINGS failed halvings within
  floor_factor^2 of the level.
* ``stagnation_steps``: stop (stagnated) after that many consecutive steps with c < 1e-2.

Every rollout is recorded as an :class:`~transcription.results.Iterate` (the initial point, then
every line-search trial), ``progress`` receives one per accepted iteration.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .results import Iterate, Result

_EPS = np.finfo(float).eps
#: near the floor (|F| <= floor_factor^2 x the measured level) the line search gives up after this many halvings
NEAR_FLOOR_HALVINGS = 3


@dataclass
class NewtonResult:
    """x: the last accepted point; F: its residual; result/message: why it stopped; iterations:
    accepted Newton steps; history: every rollout; floor: |F| at a detected round-off floor;
    noise: the last measured round-off level; rejected_aux: aux values of rejected trials."""

    x: np.ndarray
    F: np.ndarray
    result: Result
    message: str
    iterations: int
    history: list[Iterate] = field(default_factory=list)
    floor: float | None = None
    noise: float | None = None
    rejected_aux: list[float] = field(default_factory=list)


def noise_level(residual: Callable[[np.ndarray], np.ndarray], x: np.ndarray, F: np.ndarray, J: np.ndarray,
                n: int = 3, ulps: float = 4.0, seed: int = 0) -> float:
    """Measured round-off level of |F|_2 at x.

    Perturbs x by a few ulps (relative ``ulps * eps``, seeded) and returns the largest
    |F(x') - F(x) - J (x' - x)|_2 over ``n`` draws: what is left after the linear part is
    evaluation noise.  For the costate shooting of E3/E4 it is far above the a-priori
    eps |J| |x| because the rod-axis rotation (tiny J_11) amplifies the rounding of the recursion.
    """
    rng = np.random.default_rng(seed)
    out = 0.0
    for _ in range(n):
        xp = x * (1.0 + ulps * _EPS * rng.standard_normal(x.size))
        out = max(out, float(np.linalg.norm(residual(xp) - F - J @ (xp - x))))
    return out


def newton_armijo(x0: np.ndarray, residual: Callable[[np.ndarray], tuple[np.ndarray, float]],
                  jacobian: Callable[[np.ndarray], np.ndarray], *, tol: float, norm: float = 2, alpha: float = 1e-4,
                  max_iter: int = 50, max_halvings: int = 30, aux_tol: float = np.inf,
                  step_scale: np.ndarray | None = None, floor_factor: float | None = None, floor_accept: float = 1e-8,
                  stagnation_steps: int | None = None, progress: Callable[[Iterate], None] | None = None,
                  check_interrupt: Callable[[], bool] | None = None) -> NewtonResult:
    """Solve F(x) = 0 from x0 (see the module docstring).  ``norm``: the norm of the convergence
    test (2 or np.inf); Armijo's test uses the 2-norm.  ``check_interrupt``: returns True to stop
    (Result.interrupted) between rollouts.  The caller checks that F(x0) is usable (aux, finite)."""
    t0 = time.perf_counter()
    x = np.asarray(x0, dtype=float).copy()
    F, aux0 = residual(x)
    e = float(np.linalg.norm(F))
    history = [Iterate(iteration=0, residual=e, residual_inf=float(np.abs(F).max()), aux=aux0, elapsed_s=0.0)]
    J = jacobian(x)
    it, small, floor, noise = 0, 0, None, None
    rejected: list[float] = []

    def conv(F):
        return float(np.linalg.norm(F, ord=norm))

    def done(result, message):
        return NewtonResult(x, F, result, message, it, history, floor, noise, rejected)

    while True:
        if not (np.all(np.isfinite(F)) and np.all(np.isfinite(J))):
            return done(Result.non_finite, f"non-finite residual or Jacobian at iteration {it}")
        if conv(F) <= tol:
            return done(Result.converged, f"|F| = {conv(F):.3e} <= {tol:.1e} after {it} iterations")
        if it >= max_iter:
            return done(Result.max_iterations, f"no convergence in {max_iter} iterations (|F| = {e:.3e})")
        try:
            D = -np.linalg.solve(J, F)
        except np.linalg.LinAlgError:
            return done(Result.singular_jacobian, f"singular Jacobian at iteration {it} (|F| = {e:.3e})")
        if not np.all(np.isfinite(D)):
            return done(Result.singular_jacobian, f"ill-conditioned Jacobian at iteration {it} (|F| = {e:.3e})")
        if step_scale is not None:
            r = np.abs(D / step_scale).max()
            D = D / r if r > 1.0 else D
        it += 1
        c, stop = 1.0, None
        for j in range(max_halvings + 1):
            if check_interrupt is not None and check_interrupt():
                it -= 1
                return done(Result.interrupted, f"interrupted at iteration {it + 1} (|F| = {e:.3e})")
            xt = x + c * D
            if np.array_equal(xt, x):
                stop = (Result.stagnated, f"the step no longer changes x (|F| = {e:.3e}, c = {c:.1e})")
                break
            Ft, at = residual(xt)
            valid = bool(np.all(np.isfinite(Ft)) and at <= aux_tol)
            et = float(np.linalg.norm(Ft)) if valid else float("inf")
            ok = valid and (et <= (1.0 - alpha * c) * e or (c == 1.0 and conv(Ft) <= tol))
            if not valid and np.isfinite(at) and at > aux_tol:
                rejected.append(float(at))
            history.append(Iterate(iteration=it, trial=j + 1, step=c, residual=et,
                                   residual_inf=float(np.abs(Ft).max()) if valid else et, accepted=ok, aux=at,
                                   elapsed_s=time.perf_counter() - t0))
            if ok:
                break
            if floor_factor is not None:
                if j == 0:
                    noise = noise_level(lambda y: residual(y)[0], x, F, J)
                    if e <= floor_factor * noise:
                        floor = e
                        stop = (Result.round_off_floor,
                                f"round-off floor reached after {it - 1} iterations: |F| = {e:.3e} (measured "
                                f"round-off level {noise:.1e}); the full Newton step gives {et:.3e}, no further "
                                "decrease possible")
                        break
                elif j == NEAR_FLOOR_HALVINGS and noise is not None and e <= floor_factor**2 * noise:
                    floor = e
                    stop = (Result.round_off_floor,
                            f"round-off floor reached after {it - 1} iterations: |F| = {e:.3e} (measured round-off "
                            f"level {noise:.1e}); {j + 1} line-search trials, none decreases it")
                    break
            c *= 0.5
        else:
            stop = (Result.line_search_failed,
                    f"line search failed after {max_halvings} halvings at iteration {it} (|F| = {e:.3e})")
        if stop is not None:
            it -= 1  # the failed iteration did not change x
            result, message = stop
            if result is Result.round_off_floor and e > floor_accept:
                result = Result.floor_too_high
                message += f"; the floor is above floor_accept = {floor_accept:.0e}: not accepted"
            return done(result, message)
        x, F, e = xt, Ft, et
        J = jacobian(x)
        small = small + 1 if c < 1e-2 else 0
        if progress is not None:
            progress(Iterate(iteration=it, residual=e, residual_inf=float(np.abs(F).max()), step=c, aux=at,
                             elapsed_s=time.perf_counter() - t0))
        if stagnation_steps is not None and small >= stagnation_steps:
            return done(Result.stagnated, f"{small} consecutive steps shorter than 1e-2 (|F| = {e:.3e})")
