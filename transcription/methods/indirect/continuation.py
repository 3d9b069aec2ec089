"""The indirect method's outer loops around the fixed-problem Newton iteration: the continuation in the control
bounds from the unbounded problem, and the free final time (docs/mathematics.md §10)."""
from __future__ import annotations

from typing import Any

import numpy as np

from ...geometry.state import NU, U_FORCE, U_MOMENT
from .control import NB, NO_NORM, THRUSTER

def bound_continuation(newton, lam, bd, fns, args, law) -> tuple[Any, list[str]]:
    """Newton from lambda_0 = 0 on the unbounded problem (removed controls stay removed), then on the bounded one
    from its solution; if that fails, along law.continuation_stages bounds shrinking geometrically from the unbounded
    controls' peaks to bd (:func:`stage_bounds`): semismooth Newton converges only locally.  Returns the last stage's
    NewtonResult (history and iterations of all stages) and a line per stage."""
    free_bd = np.r_[np.where(bd[:NU] == 0, 0.0, np.inf), NO_NORM, NO_NORM, np.zeros(NB - NU - 2)]  # no engine
    first = newton(lam, free_bd, "unbounded")
    history, iters, stages = list(first.history), first.iterations, [f"unbounded: {first.result.value} in "
                                                                      f"{first.iterations} iterations"]
    if not first.result.successful:
        first.message = f"the unbounded first stage of the bound continuation: {first.message}"
        return first, stages
    U = np.array(fns.shoot(first.x, *args, free_bd)[3])
    peak = np.r_[np.abs(U).max(axis=1), [np.linalg.norm(U[sl], axis=0).max() ** 2 for sl in (U_FORCE, U_MOMENT)],
                 np.linalg.norm(U[U_FORCE], axis=0).max()]
    paths = [[1.0], [(j + 1) / law.continuation_stages for j in range(law.continuation_stages)]]
    for path in paths:
        x, ok = first.x, True
        for t in path:
            nr = newton(x, stage_bounds(bd, peak, t), f"bounds {t:.2g}")
            history += nr.history
            iters += nr.iterations
            stages.append(f"bounds at {t:.2g} of the way: {nr.result.value} in {nr.iterations} iterations")
            x, ok = nr.x, nr.result.successful
            if not ok:
                break
        if ok:
            break
    nr.history, nr.iterations = history, iters
    return nr, stages


def stage_bounds(bd: np.ndarray, peak: np.ndarray, t: float) -> np.ndarray:
    """The bound data at fraction t of the way (geometrically) from max(peak, bound) down to the bound, b(t) =
    b max(peak / b, 1)^(1 - t): the box half-widths and squared norm bounds (peak: the free solution's largest
    |u_i| and |u_blk|^2, NU + 2 values) and an engine's T_max (peak[-1]: the free force's largest norm; its axis
    and T_min stay).  Absent bounds and removed controls stay as they are."""
    idx = list(range(NU + 2)) + ([THRUSTER.start + 7] if bd[THRUSTER][-1] else [])
    b, pk = bd[idx], np.r_[peak[:NU + 2], peak[-1]][:len(idx)]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(np.isfinite(b) & (b > 0) & (b < NO_NORM), np.maximum(pk / b, 1.0), 1.0)
    out = bd.copy()
    out[idx] = np.where(ratio > 1.0, b * ratio ** (1.0 - t), b)
    return out


def free_final_time(solve_at, dL_dh, lam, h, lo, hi, N, law) -> tuple[Any, float, dict]:
    """The free final time: h in [lo, hi] with dJ*/dh = dL/dh = 0 (or at a bound with dL/dh pointing out), by a
    safeguarded secant iteration on g(h) = dL/dh, each g from a fixed-h shooting from the previous lambda_0: inside a
    sign-change bracket once one is known (bisection when a step leaves it), clipped to [lo, hi] before.  Stops when
    the step is below law.free_time_rtol h, fails after law.free_time_max_outer.  Returns (the NewtonResult at the
    final h, with the history and iterations of every inner solve; h; a summary)."""
    history, iters, evals = [], 0, []

    def at(h, lam, first=False):
        nr = solve_at(lam, h, first, f"T = {N * h:.10g}: ")
        nonlocal iters
        history.extend(nr.history)
        iters += nr.iterations
        g = dL_dh(nr.x, h) if nr.result.successful else np.nan
        evals.append((float(N * h), float(g)))
        return nr, g

    def done(nr, h, converged, message):
        nr.history, nr.iterations = history, iters
        return nr, h, {"converged": converged, "T": N * h, "dL_dh": evals[-1][1], "evaluations": evals,
                       "message": message}

    h = min(max(h, lo), hi)
    nr, g = at(h, lam, first=True)
    below, above = (lo, None), (hi, None)          # the bracket: g < 0 at below, g > 0 at above
    prev = None
    for _ in range(law.free_time_max_outer):
        if not nr.result.successful:
            return done(nr, h, False, f"free final time: the shooting at T = {N * h:.10g} failed")
        if g == 0.0:
            return done(nr, h, True, f"free final time T = {N * h:.12g} (dL/dh = 0)")
        if g < 0:
            below = (h, g)
        else:
            above = (h, g)
        if (g < 0 and h >= hi) or (g > 0 and h <= lo):
            return done(nr, h, True, f"free final time at its bound T = {N * h:.12g} (dL/dh = {g:.3e} points "
                                     "out of the interval)")
        if prev is None:    # a first secant point: a small step downhill
            cand = h * (1.0 - 1e-3 * np.sign(g))
        else:
            hp, gp = prev
            cand = h - g * (h - hp) / (g - gp) if g != gp else np.nan
        a, b = below[0], above[0]
        if below[1] is not None and above[1] is not None:
            if not (min(a, b) < cand < max(a, b)):
                cand = 0.5 * (a + b)
        elif not np.isfinite(cand):
            cand = hi if g < 0 else lo
        cand = min(max(cand, lo), hi)
        step = abs(cand - h)
        prev = (h, g)
        nr, g = at(cand, nr.x)
        h = cand
        if step <= law.free_time_rtol * h and nr.result.successful:
            return done(nr, h, True, f"free final time T = {N * h:.12g} (dL/dh = {g:.3e}, last step "
                                     f"{step / h:.1e} h, {len(evals)} shootings)")
    return done(nr, h, False, f"free final time: no convergence in {law.free_time_max_outer} outer iterations "
                              f"(T = {N * h:.12g}, dL/dh = {g:.3e})")
