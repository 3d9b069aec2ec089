"""The fuel objective in the indirect method (docs/mathematics.md §19): the homotopy in eps of the switching law
(:func:`.switching.on_off`) from an effort-like problem (eps = 1) or near the fuel optimum (a start from a solution)
down to eps_end, each stage a Newton-Armijo shooting from the previous stage's lambda_0 (the parameters: FuelLaw's)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..newton import NewtonResult
from ...ocp import Problem
from .control import FUEL_EPS
from .structured import StructuredShooting, node_modes

def fuel_not_covered(problem: Problem) -> list[str]:
    """What of the fuel objective the indirect method does not cover: its law is for norm bounds (or removed
    controls) on both blocks, at a fixed final time."""
    reasons = []
    for name, bound in (("force", problem.control.force_bound), ("moment", problem.control.moment_bound)):
        if bound is None or not np.isfinite(bound.radius):
            kind = "no bound" if bound is None else bound.noun
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
                  lam: np.ndarray, cold: bool, law) -> tuple[NewtonResult, float, dict]:
    """eps from law.eps_cold (``cold``: from lambda_0 = 0) or law.eps_warm down to law.eps_end by law.eps_factor per
    stage (after a failed stage from the last solution by the factor's square root, up to law.eps_factor_max), or
    until, at eps <= law.eps_settle, the fuel cost's estimated change to eps = 0 (:func:`remaining`) is at most
    law.cost_rtol relative (``law``: a :class:`~.laws.FuelLaw`).  ``stage(lam, eps, first)``: the Newton solve at eps;
    ``cost(lam, eps)``: its solution's fuel cost.  Returns (the last successful stage's NewtonResult with the history
    and iterations of all stages, or the first stage's failure; its eps; a summary for the stats)."""
    eps, factor, good = (law.eps_cold if cold else law.eps_warm), law.eps_factor, None
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
            settled = remaining(costs) <= law.cost_rtol * abs(costs[-1][1]) and eps <= law.eps_settle
            if eps <= law.eps_end * (1 + 1e-9) or settled:
                break
        elif good is None or factor ** 0.5 > law.eps_factor_max:
            break
        else:
            factor = factor ** 0.5
        x, eps = good[0].x, max(good[1] * factor, law.eps_end)
    done = good is not None and (good[1] <= law.eps_end * (1 + 1e-9) or (
        remaining(costs) <= law.cost_rtol * abs(costs[-1][1]) and good[1] <= law.eps_settle))
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
    (eps, J) (the cost is O(eps)-close to the fuel optimum's, docs/mathematics.md §19); inf before two stages."""
    if len(costs) < 2:
        return float("inf")
    (e0, J0), (e1, J1) = costs[-2:]
    return e1 * abs(J1 - J0) / abs(e0 - e1)


def warm_controls(problem: Problem, warm) -> np.ndarray | None:
    """The controls of a warm start on the problem's grid -- on a non-uniform mesh at its node times (None without
    one): the switching structure to start from."""
    return None if warm is None else np.asarray(warm.fit(problem.N, problem.scheme, problem.fractions)[0].U, float)


def structured_finish(problem: Problem, lam: np.ndarray, U: np.ndarray, tol: float, law,
                      h: float | None = None) -> tuple[NewtonResult | None, dict]:
    """The conditions at eps = 0 on the switching structure of the controls U (:mod:`.structured`) from lambda_0 =
    lam: (the NewtonResult, x = lambda_0, when it converged consistent with the structure, else None; a summary for
    the stats, with the rollout's controls and costates on success).  An inconsistent solution is repaired (an
    active-set step) up to law.structure_repairs times (``law``: a :class:`~.laws.FuelLaw`).  h: the (mean) step size
    (default the problem's; step k at h_k = r_k h on a non-uniform mesh)."""
    if problem.disc.force_frame != "inertial":
        return None, {"skipped": "a body-fixed force (the structured conditions are written for an inertial one)"}
    modes, x, out = node_modes(problem, U, law.partial_rtol), np.asarray(lam, float), {"repairs": 0, "iterations": 0}
    for _ in range(law.structure_repairs + 1):
        st = StructuredShooting(problem, modes, h)
        nr = st.solve(x[:12], U, tol, law.structured_max_iter)
        out.update(partial_nodes=len(st.partial), result=nr.result.value, iterations=out["iterations"] + nr.iterations)
        if not nr.result.successful:
            return None, out
        why = st.check(nr.x)
        out["consistent"] = not why
        if not why:
            break
        out["inconsistent"] = why
        new, U = st.repaired(nr.x)
        if np.array_equal(new, modes) or out["repairs"] == law.structure_repairs:
            return None, out
        modes, x, out["repairs"] = new, nr.x, out["repairs"] + 1
    out.pop("inconsistent", None)
    _, _, Us, _, lams = st.fun(nr.x)
    out.update(magnitudes=[float(m) for m in nr.x[12:]], U=np.array(Us), costates=np.array(lams).T)
    nr.x = nr.x[:12]
    return nr, out


def solve_fuel(shooting, lam, h: float, first: bool, phase: str, law) -> NewtonResult:
    """The fuel objective at the step size h (``shooting``: the method's :class:`~.solve._Shooting`): from a solution
    (``shooting.warm_U``) first the structured conditions at eps = 0 on its switching structure; otherwise, or when
    that fails, the homotopy in eps (:func:`fuel_homotopy`), then the structured finish from its last converged
    stage's controls (also after a later stage failed).  The exact solution, when found, is ``shooting.structured``
    (U, costates); stats ``fuel_homotopy`` and ``fuel_structured``; ``law``: the :class:`~.laws.FuelLaw`."""
    opts, stats = shooting.options, shooting.stats
    U0 = getattr(shooting, "warm_U", None)
    if first and U0 is not None:
        nr, stats["fuel_structured"] = structured_finish(shooting.problem, lam, U0, opts.eps_S, law, h)
        if nr is not None:
            return _structured(shooting, nr, "from the warm start's switching structure")
    nr, eps, stats["fuel_homotopy"] = fuel_homotopy(
        lambda l, e, fst: shooting.fixed(l, h, fst and first, f"{phase}eps = {e:.1e}: ", with_eps(shooting.bd, e)),
        lambda l, e: shooting.cost(l, h, with_eps(shooting.bd, e)), lam, first and shooting.source == "zero", law)
    shooting.bd = with_eps(shooting.bd, eps)
    shooting.law = (shooting.Winv, shooting.bd)     # the final rollout's law: the last stage's eps
    if not stats["fuel_homotopy"]["costs"]:   # no stage converged: nothing to finish from
        return nr
    hk = shooting.problem.steps_of(h)   # h itself on a uniform mesh, h r_k on a non-uniform one
    U = np.array(shooting.fns.shoot(nr.x, shooting.X0, shooting.Xd, hk, shooting.Winv, shooting.bd)[3])
    fin, stats["fuel_structured"] = structured_finish(shooting.problem, nr.x, U, opts.eps_S, law, h)
    if fin is None:
        return nr
    fin.history, fin.iterations = nr.history + fin.history, nr.iterations + fin.iterations
    fin.message = (nr.message if nr.result.successful else
                   f"|z_N| = {np.linalg.norm(fin.F):.3e} after {fin.iterations} iterations ({nr.message})")
    return _structured(shooting, fin, f"from the switching structure at eps = {eps:.1e}")


def _structured(shooting, nr: NewtonResult, how: str) -> NewtonResult:
    """Keep the structured solution (controls, costates) for the Solution and say so in the message."""
    st = shooting.stats["fuel_structured"]
    shooting.structured = (st.pop("U"), st.pop("costates"))
    nr.message += (f"; exact switching structure (eps = 0) {how}: {st['partial_nodes']} partial nodes, "
                   "consistent (S > 0 on, S < 0 off)")
    return nr
