"""What to try next after a solve that did not converge, in the terms of the settings a user can change with
``--set`` (every strategy's failures say it: :func:`failure_hint`)."""
from __future__ import annotations

import numpy as np

from ..geometry.state import U_FORCE, U_MOMENT
from ..ocp.estimate import control_sizes
from ..options import DirectOptions
from ..outcome import Result
from ..results.solution import Solution


def failure_hint(sol: Solution, options: DirectOptions, binding_fraction: float = 0.1) -> str:
    """What to try next after a direct solve of a smooth problem that did not converge ('' if it did, was
    interrupted, or its message already says what to change): the settings a user can change with
    ``--set``, in the order most likely to help.  Why: a failure that only names IPOPT's status leaves the
    user to guess that another initial guess, more iterations or an easier neighbouring maneuver (reached
    by continuation) would do."""
    r = sol.result
    if sol.converged or r in (Result.interrupted, Result.cayley_failed, Result.invalid_option, Result.non_finite):
        return ""
    tips = [tip for tip in (_objective_tip(sol),) if tip]
    binding = binding_bound(sol, binding_fraction)
    if binding and r in (Result.infeasible, Result.max_iterations, Result.acceptable, Result.time_limit,
                                          Result.solver_failed):
        tips.append(binding)
    if r is not Result.infeasible and (weights := weights_tip(sol.problem)):   # weights do not make it feasible
        tips.append(weights)
    if r is Result.acceptable:
        tips.append("a looser solver.direct.tol (IPOPT stalled at its 'acceptable' level above it) or "
                    "solver.direct.options.acceptable_iter=0 (keep iterating)")
    if options.initial_guess != "auto":
        tips.append("solver.direct.initial_guess=auto (the screw interpolation and the free motion in turn)")
    elif r is Result.max_iterations:
        tips.append(budget_tip(sol, options))
    tips.append("an easier neighbouring maneuver (longer horizon.T, smaller change) reached by continuation: a sweep "
                "along the changed key with continuation (configs/sweeps/)")
    return "try " + "; or ".join(tips)


def _objective_tip(sol: Solution) -> str:
    """The objective's own tip for ``sol``'s problem ('' without a smooth problem or a tip)."""
    problem = sol.problem
    return problem.control.objective.failure_tip(problem) if problem is not None and problem.kind == "smooth" else ""


def weights_tip(problem, factor: float = 10.0) -> str:
    """The tip 'control.weights=auto' when the problem's weights price the moment against the force ``factor`` or more
    times away from the objective's weights in the actuators' terms (:meth:`~transcription.ocp.Objective.unit_weights`
    at :func:`~transcription.ocp.estimate.control_sizes`), with how far; '' when they price them alike, when a part is
    removed, or without those terms.  Why: a weight ratio chosen for another objective or by hand (a moment made
    almost free, or too dear for the body to turn and aim its engine) is a cause of failure the user can change in
    one key, and the other tips (iterations, tolerance, continuation) do not name it (issue 41: a raise in km with
    default weights failed and the hint suggested a looser tolerance).  ``factor``: an order of magnitude, the
    smallest mispricing named."""
    if problem is None or problem.kind != "smooth" or any(problem.control.removed):
        return ""
    c = problem.control
    sizes = control_sizes(problem)
    W = None if sizes is None else c.objective.unit_weights(*sizes)
    if W is None:
        return ""
    ratio = (np.trace(c.W_m) / np.trace(c.W_f)) / (np.trace(W[1]) / np.trace(W[0]))
    if 1.0 / factor < ratio < factor:
        return ""
    return (f"control.weights=auto (the weights price the moment {ratio:.1e} times its price in the actuators' "
            f"terms, force {sizes[0]:.3g} and moment {sizes[1]:.3g} in the file's units: "
            f"{'cheaper' if ratio < 1 else 'dearer'} against the force)")


def budget_tip(sol: Solution, options: DirectOptions) -> str:
    """The iteration tip of a solve that ended at its iteration limit, with the budgets its attempts actually ran on
    (an attempt that reached max_iterations spent its budget: its iterations less those spent making its guess).
    Why: the plan caps its first starts (the objectives' strategies' first budgets) below max_iter, and "a larger
    max_iter (now 3000)" after attempts that stopped at 600 promises what raising max_iter does not give them."""
    spent = [a.iterations for a in sol.trace if a.result is Result.max_iterations]
    capped = sorted({b for b in spent if b < options.max_iter})
    now = f"a larger solver.direct.max_iter (now {options.max_iter})"
    if not capped:
        return now
    return (f"{now} for the starts it bounds: the starts that reached their limit ran on "
            f"{' and '.join(map(str, spent))} iterations ({' and '.join(map(str, capped))}: the plan's cap on its first "
            "starts, which max_iter does not raise; solver.direct.initial_guess=rollout or interpolate gives one start "
            "the whole max_iter)")


def binding_bound(sol: Solution, fraction: float) -> str:
    """The control bound that binds the last iterate of a failed solve, in words ('' if none does): the one with
    the largest fraction of control nodes at it (within AT_BOUND_RTOL, :meth:`NormBound.active`), at least
    ``fraction``, with its value and the key to change.  Why: a solve that ends infeasible or at its
    iteration limit with the controls pinned to a bound is usually asking more than that bound gives in the
    horizon, and naming the bound says what to change."""
    if sol.controls is None or sol.problem is None or sol.problem.kind != "smooth":
        return ""
    c, U = sol.problem.control, np.asarray(sol.controls, float)
    best = None
    for name, sl, bound in (("force", U_FORCE, c.force_bound), ("moment", U_MOMENT, c.moment_bound)):
        if bound is None or bound.removed:
            continue
        at = float(np.mean(bound.active(U[sl].T)))
        if at >= fraction and (best is None or at > best[0]):
            best = (at, name, bound)
    if best is None:
        return ""
    at, name, bound = best
    sym = "u_f" if name == "force" else "u_m"
    return (f"the {name} bound {bound.describe(sym)} binds ({at:.0%} of the control nodes of the last iterate are at it): a larger "
            f"control.bounds.{name} or a longer horizon.T")


__all__ = ["binding_bound", "budget_tip", "failure_hint", "weights_tip"]
