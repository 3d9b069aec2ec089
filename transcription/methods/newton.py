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
  above ``floor_accept``).  Also after ``near_floor_halvings`` failed halvings within
  floor_factor^2 of the level.  And when the line search has halved the step until x + c D == x (the full
  step having failed): no representable change of x along D decreases |F|, the floor of x's resolution.
* ``stagnation_steps``: stop (stagnated) after that many consecutive steps with c < 1e-2.
* the Jacobian at x is computed when a direction needs it: not at the point where the iteration stops.

Every rollout is recorded as an :class:`~transcription.results.solution.Iterate` (the initial point, then
every line-search trial), ``progress`` receives one per accepted iteration.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..outcome import Iterate, Result


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
        xp = x * (1.0 + ulps * np.finfo(float).eps * rng.standard_normal(x.size))
        out = max(out, float(np.linalg.norm(residual(xp) - F - J @ (xp - x))))
    return out


class _Run:
    """The state of one Newton-Armijo iteration (x, F, |F|, J, the iteration count, the history, the measured
    round-off floor and noise, the rejected aux values) and its two steps: the direction and the line search."""

    def __init__(self, x0, residual, jacobian, *, tol, norm, alpha, max_halvings, aux_tol, floor_factor,
                 near_floor_halvings, check_interrupt):
        self.residual, self.jacobian, self.tol, self.norm, self.alpha = residual, jacobian, tol, norm, alpha
        self.max_halvings, self.aux_tol, self.floor_factor = max_halvings, aux_tol, floor_factor
        self.near_floor_halvings = near_floor_halvings
        self.check_interrupt = check_interrupt
        self.t0 = time.perf_counter()
        self.x = np.asarray(x0, dtype=float).copy()
        self.F, aux0 = residual(self.x)
        self.e = float(np.linalg.norm(self.F))
        self.history = [Iterate(iteration=0, residual=self.e, residual_inf=float(np.abs(self.F).max()), aux=aux0,
                                elapsed_s=0.0)]
        self._J = None           # J(x), computed when a direction needs it (:attr:`J`)
        self.it, self.floor, self.noise = 0, None, None
        self.rejected: list[float] = []

    @property
    def J(self) -> np.ndarray:
        """The Jacobian at x, computed on first use: not at the point where the iteration converges (a rollout and its
        linearization saved per Newton solve)."""
        if self._J is None:
            self._J = self.jacobian(self.x)
        return self._J

    def conv(self, F) -> float:
        return float(np.linalg.norm(F, ord=self.norm))

    def done(self, result: Result, message: str) -> NewtonResult:
        return NewtonResult(self.x, self.F, result, message, self.it, self.history, self.floor, self.noise,
                            self.rejected)

    def direction(self, step_scale) -> tuple[np.ndarray | None, tuple | None]:
        """D = -J^-1 F (capped by step_scale), or a stop (result, message) before it."""
        F, J, e, it = self.F, self.J, self.e, self.it
        try:
            D = -np.linalg.solve(J, F)
        except np.linalg.LinAlgError:
            return None, (Result.singular_jacobian, f"singular Jacobian at iteration {it} (|F| = {e:.3e})")
        if not np.all(np.isfinite(D)):
            return None, (Result.singular_jacobian, f"ill-conditioned Jacobian at iteration {it} (|F| = {e:.3e})")
        if step_scale is not None:
            r = np.abs(D / step_scale).max()
            D = D / r if r > 1.0 else D
        return D, None

    def line_search(self, D: np.ndarray) -> tuple[tuple | None, tuple | None]:
        """c = 1, 1/2, ... until Armijo's test holds: ((x_t, F_t, |F_t|, aux_t, c), None), or (None, a stop:
        interrupted, stagnated, the round-off floor, line search failed)."""
        x, e, it = self.x, self.e, self.it
        c = 1.0
        for j in range(self.max_halvings + 1):
            if self.check_interrupt is not None and self.check_interrupt():
                return None, (Result.interrupted, f"interrupted at iteration {it} (|F| = {e:.3e})")
            xt = x + c * D
            if np.array_equal(xt, x):
                if self.floor_factor is not None:   # the full step failed: the resolution of x is the floor
                    self.floor = e
                    return None, (Result.round_off_floor, f"round-off floor reached after {it - 1} iterations: |F| = "
                                                          f"{e:.3e}; the step c D no longer changes x (c = {c:.1e})")
                return None, (Result.stagnated, f"the step no longer changes x (|F| = {e:.3e}, c = {c:.1e})")
            Ft, at = self.residual(xt)
            valid = bool(np.all(np.isfinite(Ft)) and at <= self.aux_tol)
            et = float(np.linalg.norm(Ft)) if valid else float("inf")
            ok = valid and (et <= (1.0 - self.alpha * c) * e or (c == 1.0 and self.conv(Ft) <= self.tol))
            if not valid and np.isfinite(at) and at > self.aux_tol:
                self.rejected.append(float(at))
            self.history.append(Iterate(iteration=it, trial=j + 1, step=c, residual=et,
                                        residual_inf=float(np.abs(Ft).max()) if valid else et, accepted=ok, aux=at,
                                        elapsed_s=time.perf_counter() - self.t0))
            if ok:
                return (xt, Ft, et, at, c), None
            stop = self._at_floor(j, et)
            if stop is not None:
                return None, stop
            c *= 0.5
        return None, (Result.line_search_failed,
                      f"line search failed after {self.max_halvings} halvings at iteration {it} (|F| = {e:.3e})")

    def _at_floor(self, j: int, et: float) -> tuple | None:
        """After the j-th failed trial: the round-off floor stop (module docstring) if |F| is at the measured
        round-off level, else None."""
        if self.floor_factor is None:
            return None
        e, it, ff = self.e, self.it, self.floor_factor
        if j == 0:
            self.noise = noise_level(lambda y: self.residual(y)[0], self.x, self.F, self.J)
            if e <= ff * self.noise:
                self.floor = e
                return (Result.round_off_floor,
                        f"round-off floor reached after {it - 1} iterations: |F| = {e:.3e} (measured round-off level "
                        f"{self.noise:.1e}); the full Newton step gives {et:.3e}, no further decrease possible")
        elif j == self.near_floor_halvings and self.noise is not None and e <= ff**2 * self.noise:
            self.floor = e
            return (Result.round_off_floor,
                    f"round-off floor reached after {it - 1} iterations: |F| = {e:.3e} (measured round-off "
                    f"level {self.noise:.1e}); {j + 1} line-search trials, none decreases it")
        return None


def newton_armijo(x0: np.ndarray, residual: Callable[[np.ndarray], tuple[np.ndarray, float]],
                  jacobian: Callable[[np.ndarray], np.ndarray], *, tol: float, norm: float = 2, alpha: float = 1e-4,
                  max_iter: int = 50, max_halvings: int = 30, aux_tol: float = np.inf,
                  step_scale: np.ndarray | None = None, floor_factor: float | None = None, floor_accept: float = 1e-8,
                  stagnation_steps: int | None = None, near_floor_halvings: int = 3,
                  progress: Callable[[Iterate], None] | None = None,
                  check_interrupt: Callable[[], bool] | None = None) -> NewtonResult:
    """Solve F(x) = 0 from x0 (see the module docstring).  ``norm``: the norm of the convergence
    test (2 or np.inf); Armijo's test uses the 2-norm.  ``near_floor_halvings``: near the floor (|F| <=
    floor_factor^2 x the measured level) the line search gives up after this many halvings.  ``check_interrupt``: returns True to stop
    (Result.interrupted) between rollouts.  The caller checks that F(x0) is usable (aux, finite)."""
    run = _Run(x0, residual, jacobian, tol=tol, norm=norm, alpha=alpha, max_halvings=max_halvings, aux_tol=aux_tol,
               floor_factor=floor_factor, near_floor_halvings=near_floor_halvings, check_interrupt=check_interrupt)
    small = 0
    while True:
        if not np.all(np.isfinite(run.F)):
            return run.done(Result.non_finite, f"non-finite residual at iteration {run.it}")
        if run.conv(run.F) <= tol:
            return run.done(Result.converged, f"|F| = {run.conv(run.F):.3e} <= {tol:.1e} after {run.it} iterations")
        if run.it >= max_iter:
            return run.done(Result.max_iterations, f"no convergence in {max_iter} iterations (|F| = {run.e:.3e})")
        if not np.all(np.isfinite(run.J)):
            return run.done(Result.non_finite, f"non-finite Jacobian at iteration {run.it}")
        D, stop = run.direction(step_scale)
        if stop is not None:
            return run.done(*stop)
        run.it += 1
        trial, stop = run.line_search(D)
        if stop is not None:
            run.it -= 1  # the failed iteration did not change x
            result, message = stop
            if result is Result.round_off_floor and run.e > floor_accept:
                result = Result.floor_too_high
                message += f"; the floor is above floor_accept = {floor_accept:.0e}: not accepted"
            return run.done(result, message)
        run.x, run.F, run.e, at, c = trial
        run._J = None
        small = small + 1 if c < 1e-2 else 0
        if progress is not None:
            progress(Iterate(iteration=run.it, residual=run.e, residual_inf=float(np.abs(run.F).max()), step=c, aux=at,
                             elapsed_s=time.perf_counter() - run.t0))
        if stagnation_steps is not None and small >= stagnation_steps:
            return run.done(Result.stagnated, f"{small} consecutive steps shorter than 1e-2 (|F| = {run.e:.3e})")
