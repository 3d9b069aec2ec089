"""The fuel objective in the indirect method (docs/mathematics.md §16): the homotopy in eps of the switching law
(:func:`.switching.on_off`) from an effort-like problem (eps = 1) or near the fuel optimum (a start from a solution)
down to FUEL_EPS_END, each stage a Newton-Armijo shooting from the previous stage's lambda_0."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ...newton import NewtonResult
from ...problem import NormBound, Problem, ThrusterBound
from .control import FUEL_EPS

#: the homotopy: the first eps from lambda_0 = 0 (the bounded problem with the effort-like cost |u|^2 / (2 b)) and
#: from a solution's costates (a fuel optimum's, e.g. the direct method's: the switching nodes sit at S ~ 0), the
#: factor per stage (its square root after a failed stage, up to FUEL_EPS_FACTOR_MAX), and the last eps.  The fuel
#: cost of the eps-problem's optimum exceeds the fuel optimum by at most eps/2 relative (§16); measured on the
#: bundled raise it is O(eps^2).
FUEL_EPS_COLD = 1.0
FUEL_EPS_WARM = 1e-2
FUEL_EPS_FACTOR = 0.1
FUEL_EPS_FACTOR_MAX = 0.9
FUEL_EPS_END = 1e-6
#: the homotopy stops earlier, at eps <= FUEL_EPS_SETTLE, once the fuel cost's estimated change to eps = 0
#: (:func:`remaining`) is at most FUEL_COST_RTOL relative
FUEL_EPS_SETTLE = 1e-2
FUEL_COST_RTOL = 1e-9


def fuel_not_covered(problem: Problem) -> list[str]:
    """What of the fuel objective the indirect method does not cover: its law is for norm bounds (or removed
    controls) on both blocks, at a fixed final time."""
    reasons = []
    for name, bound in (("force", problem.control.force_bound), ("moment", problem.control.moment_bound)):
        if not isinstance(bound, NormBound):
            kind = "an engine" if isinstance(bound, ThrusterBound) else "no bound" if bound is None else "a box bound"
            reasons.append(f"the fuel objective with {kind} on the {name} (its switching law needs a norm bound)")
    if problem.free_time:
        reasons.append("the fuel objective with a free final time")
    return reasons


def with_eps(bd: np.ndarray, eps: float) -> np.ndarray:
    """The bound data ``bd`` with the fuel homotopy's eps."""
    out = np.array(bd, dtype=float)
    out[FUEL_EPS] = eps
    return out


def fuel_homotopy(stage: Callable[[np.ndarray, float, bool], NewtonResult], cost: Callable[[np.ndarray, float], float],
                  lam: np.ndarray, cold: bool) -> tuple[NewtonResult, float, dict]:
    """eps from FUEL_EPS_COLD (``cold``: from lambda_0 = 0) or FUEL_EPS_WARM down to FUEL_EPS_END by the factor
    FUEL_EPS_FACTOR per stage (after a failed stage from the last solution by the factor's square root, until it
    exceeds FUEL_EPS_FACTOR_MAX), or until, at eps <= FUEL_EPS_SETTLE, the fuel cost's estimated change to eps = 0
    (:func:`remaining`) is at most FUEL_COST_RTOL relative;
    ``stage(lam, eps, first)`` the Newton solve at eps (first: the first stage), ``cost(lam, eps)`` the fuel cost
    of its solution.
    Returns (the last successful stage's NewtonResult, its history and iterations those of all stages -- or the
    first stage's failure --, its eps, a summary for the stats)."""
    eps, factor, good = (FUEL_EPS_COLD if cold else FUEL_EPS_WARM), FUEL_EPS_FACTOR, None
    history, iters, stages, costs = [], 0, [], []
    x = np.asarray(lam, dtype=float)
    while True:
        nr = stage(x, eps, good is None)
        history += nr.history
        iters += nr.iterations
        stages.append(f"eps {eps:.1e}: {nr.result.value} in {nr.iterations}")
        if nr.result.successful:
            costs.append((eps, cost(nr.x, eps)))
            good = (nr, eps)
            settled = remaining(costs) <= FUEL_COST_RTOL * abs(costs[-1][1]) and eps <= FUEL_EPS_SETTLE
            if eps <= FUEL_EPS_END * (1 + 1e-9) or settled:
                break
        elif good is None or factor ** 0.5 > FUEL_EPS_FACTOR_MAX:
            break
        else:
            factor = factor ** 0.5
        x, eps = good[0].x, max(good[1] * factor, FUEL_EPS_END)
    done = good is not None and (good[1] <= FUEL_EPS_END * (1 + 1e-9) or (
        remaining(costs) <= FUEL_COST_RTOL * abs(costs[-1][1]) and good[1] <= FUEL_EPS_SETTLE))
    out = good[0] if good is not None else nr
    if good is not None and not done:
        out.result, out.message = nr.result, (f"the fuel homotopy stopped at eps = {good[1]:.1e} (the stage at eps "
                                              f"= {eps:.1e} failed: {nr.message})")
    elif done:
        out.message += (f" (fuel homotopy: eps {stages[0].split(':')[0][4:]} -> {good[1]:.1e} in {len(stages)} stages; "
                        f"the fuel cost's estimated change to eps = 0: {remaining(costs) / abs(costs[-1][1]):.0e} "
                        "relative)")
    out.history, out.iterations = history, iters
    return out, (good[1] if good is not None else eps), {"eps": good[1] if good else eps, "stages": stages,
                                                           "costs": costs, "converged": done,
                                                           "remaining": remaining(costs)}


def remaining(costs: list[tuple[float, float]]) -> float:
    """The estimated change of the fuel cost from the last stage to eps = 0, eps |dJ/deps| by the last two stages'
    (eps, J) (the cost is O(eps)-close to the fuel optimum's, docs/mathematics.md §16); inf before two stages."""
    if len(costs) < 2:
        return float("inf")
    (e0, J0), (e1, J1) = costs[-2:]
    return e1 * abs(J1 - J0) / abs(e0 - e1)
