"""The fuel KKT guard and the escape from a false minimum of the fuel NLP (docs/mathematics.md, "The fuel KKT guard").

The direct method's fuel objective is the epigraph u = s d, |d|^2 <= 1, s >= 0 with the cost
sum_j omega_j (w_f s_f,j + w_m s_m,j) (:func:`~transcription.nlp.blocks.control_node`).  With mu_j (3) the
multiplier of the row u_j - s_j d_j = 0 of one part (force or moment) at node j (physical units: the NLP's
Lagrangian is J + mu_j^T (u_j - s_j d_j) + ..., so mu_j = -(the gradient in u_j of the rest of the Lagrangian)),
the NLP's stationarity in s_j on a coast node (s_j = 0) only asks

    mu_j^T d_j <= w omega_j                    (for the direction d_j the solver happens to hold),

whereas the L1 problem's (the subdifferential of w omega_j |u| at u = 0 is the ball of radius w omega_j) asks

    |mu_j| <= w omega_j,   i.e.   sigma_j = |mu_j| / (w omega_j) - 1 <= 0   (the switching function).

A KKT point of the NLP with sigma_j > 0 on a coast node is not a minimum of the L1 problem: thrust along
mu_j / |mu_j| (the primer direction) lowers the cost at the rate (|mu_j| - w omega_j) per unit of s_j.
:func:`switching` computes sigma on the coast nodes of a converged solve from its own multipliers, :func:`guarded`
reports it and, when it exceeds GUARD_TOL, escapes: d_j re-aimed along mu_j / |mu_j| on the offending nodes and the
same NLP re-solved warm from there (the homotopy's WARM_LEVEL options), at most ESCAPES times while the cost falls.

A force with a body-fixed engine (u_f = T a, T >= 0) can only thrust along a: its value is
(a^T mu_j + nu_a / max) / (w omega_j) - 1 with nu_a the multiplier of the engine's axis row, and its primer a
(:func:`switching`).  Not checked: a part with weight 0 or removed (a norm bound of 0).
"""
from __future__ import annotations

import numpy as np

from ..ocp import ThrusterBound, quadrature_weights
from ..results.solution import Solution
from .homotopy import Point, counted_parts as checked_parts, point_guess

#: a node is a coast node of a part when its magnitude s is below COAST_RTOL times the part's magnitude scale
#: (its bound, or the largest scale of its controls): an interior-point solution's coast magnitudes are ~1e-9 of it
COAST_RTOL = 1e-6
#: the guard fails when sigma exceeds this on a coast node (partial nodes hold sigma = 0 to ~1e-9 at IPOPT's tol).
#: Measured on the fuel raise's optima: the largest sigma of a coast node -8.0e-4 (LGVI, N = 40), -1.5e-3 (first
#: order, N = 40 on the mesh r_k = 1.5 + sin 2.3k), -1.8e-3 (LGVI, N = 25); the false minima +7.4e-4 (LGVI, N = 40
#: on that mesh, nodes 3 and 4), +1.3e-2 and +8.8e-4 (two of the three 25-step starts), +9.4e-3 (N = 20)
GUARD_TOL = 1e-6
#: at most this many escapes (re-aim, re-solve) per solve, each within ESCAPE_BUDGET NLP iterations
ESCAPES = 3
ESCAPE_BUDGET = 500
#: Attempt label of an escape (``<ESCAPE> k``); not a start of the multistart
ESCAPE = "fuel guard escape"
PARTS = ("force", "moment")
#: the second try of an escape whose plain re-aim did not lower the cost: the offending nodes' magnitudes set to
#: ESCAPE_KICK times their scale (u = s d with it).  A coast node with |d| < 1 is also a KKT point of the NLP (the
#: direction's length is free at s = 0): from the re-aimed point IPOPT can shorten d again instead of raising s
#: (the raise at N = 20 from the interpolation: the plain re-aim came back to the same point, 0.8126981586 against
#: 0.8126981548; with the kick 0.8097587356, then 0.8096587682 with the guard passed)
ESCAPE_KICK = 1e-3


def switching_values(tr, w: np.ndarray, mu: np.ndarray, coast: np.ndarray, nu_axis=None) -> dict:
    """The switching values of :func:`switching` from the multipliers ``mu`` (2, 3, nU, physical) of a point ``w``
    (physical) of the NLP ``tr`` and its ``coast`` nodes (2, nU) bool; ``nu_axis`` (nU,): with a body-fixed engine,
    the multipliers of its axis row a^T u_f / max (physical), whose rate a^T mu_j + nu_a / max and primer a replace
    |mu_j| and mu_j / |mu_j| for the force (:func:`switching`).  The one place sigma is computed, for the epigraph NLP
    and the structured one (:func:`.fuel_structure.switching_l1`)."""
    problem, lay, c = tr.problem, tr.layout, tr.problem.control
    h = float(w[lay.ih]) if lay.ih is not None else problem.h
    omega = quadrature_weights(problem.scheme, problem.N, 1.0 if problem.uniform else problem.mesh) * h
    weights = np.array([c.W_f[0, 0], c.W_m[0, 0]])
    checked = checked_parts(problem)
    rate = np.linalg.norm(mu, axis=1)                       # (2, nU): the gain of thrust per unit of s
    with np.errstate(divide="ignore", invalid="ignore"):
        primer = mu / rate[:, None, :]
    if isinstance(c.force_bound, ThrusterBound):
        a = c.force_bound.axis
        rate[0], primer[0] = a @ mu[0] + nu_axis / c.force_bound.max, a[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        sigma = rate / (weights[:, None] * omega[None, :]) - 1.0
    return {"sigma": np.where(coast & checked[:, None], sigma, np.nan), "value": sigma, "mu": mu, "primer": primer,
            "nodes": np.asarray(lay.control_nodes), "checked": checked}


def switching(tr, x: np.ndarray, lam_g: np.ndarray) -> dict:
    """The switching values of a point of the fuel NLP ``tr`` (a SmoothTranscription at smoothing 0): x (n,) and
    lam_g (ng,) the solver's scaled primal point and constraint multipliers.

    Returns {'sigma': (2, nU) sigma_j = |mu_j| / (w omega_j) - 1 on the coast nodes (nan elsewhere and on parts not
    checked; 'value': the same on every node), 'mu': (2, 3, nU) the multipliers mu_j (physical), 'primer':
    (2, 3, nU) the unit direction thrust would take (mu_j / |mu_j|), 'nodes': the node index of each control node
    (first order 1..N, LGVI 0..N), 'checked': (2,) bool}.  omega_j = omega_j/h * h (the control block's data; h
    the point's own with a free final time).

    A body-fixed engine (u_f = T a, T >= min >= 0): thrust can only go along +a, and the engine's axis row
    a^T u_f / max (multiplier nu_a, physical) adds nu_a a / max to the gradient in u_f, so the force's value is
    sigma_j = (a^T mu_j + nu_a / max) / (w omega_j) - 1, signed, and its primer is a (module docstring)."""
    c = tr.problem.control
    w = np.asarray(x, float) * tr.w_scale
    rows = tr.nlp.rows("controls")      # (nr, nU): ...; engine (3); |d|^2 - 1 (2); u_f - s_f d_f (3); u_m - s_m d_m (3)
    nu = tr.multipliers(lam_g)
    mu = np.stack([nu[rows[-6:-3]], nu[rows[-3:]]])        # (2, 3, nU)
    coast = w[tr.layout.iS[:2]] < COAST_RTOL * tr.slack_scales[:, None]
    return switching_values(tr, w, mu, coast, nu[rows[-11]] if isinstance(c.force_bound, ThrusterBound) else None)


def verdict(sw: dict, tol: float = GUARD_TOL) -> dict:
    """Solution stats of :func:`switching`'s values: ``fuel_switching_max`` (the largest sigma on a coast node;
    -1 if there is none), ``fuel_switching_nodes`` ({part: [nodes with sigma > tol]}), ``fuel_guard_tol``,
    ``fuel_guard`` ('passed', 'failed' or 'not checked' when no part is checked)."""
    sigma = sw["sigma"]
    finite = sigma[np.isfinite(sigma)]
    bad = {p: [int(n) for n in sw["nodes"][np.isfinite(sigma[i]) & (sigma[i] > tol)]] for i, p in enumerate(PARTS)}
    state = "not checked" if not sw["checked"].any() else "failed" if any(bad.values()) else "passed"
    return {"fuel_guard": state, "fuel_switching_max": float(finite.max()) if finite.size else -1.0,
            "fuel_switching_nodes": {p: v for p, v in bad.items() if v}, "fuel_guard_tol": tol}


def reaimed(tr, point: Point, sw: dict, kick: float = 0.0, tol: float = GUARD_TOL) -> Point:
    """``point`` with d_j = mu_j / |mu_j| (the primer of :func:`switching`; scaled d has scale 1) on the coast nodes
    whose sigma > tol, so that mu_j^T d_j = |mu_j| > w omega_j there, and the bound multipliers of those nodes' s set
    to 0 (their old value, w omega_j - mu_j^T d_j, belonged to the old d); lam_g kept (but an engine's T >= min row
    there: 0).  ``kick`` > 0: s_j = kick times the magnitude's
    scale and u_j = s_j d_j on those nodes (:data:`ESCAPE_KICK`)."""
    x, lam_x, lam_g = point.x.copy(), point.lam_x.copy(), point.lam_g.copy()
    iS, iU = tr.layout.iS, tr.layout.iU
    for i in range(2):
        bad = np.flatnonzero(np.isfinite(sw["sigma"][i]) & (sw["sigma"][i] > tol))
        d = sw["primer"][i][:, bad]
        x[iS[2 + 3 * i:5 + 3 * i][:, bad]] = d
        if kick > 0.0:
            iu = iU[3 * i:3 * i + 3][:, bad]
            x[iS[i, bad]] = kick                                   # scaled s: its scale is tr.slack_scales[i]
            x[iu] = kick * tr.slack_scales[i] * d / tr.w_scale[iu]
        lam_x[iS[i, bad]] = 0.0
        if i == 0 and isinstance(tr.problem.control.force_bound, ThrusterBound):
            lam_g[tr.nlp.rows("controls")[-11, bad]] = 0.0     # the engine's T >= min row: held for the old d
    return Point(x, lam_g, lam_x)


def _nodes(v: dict) -> str:
    return "; ".join(f"{p} {', '.join(map(str, n))}" for p, n in v["fuel_switching_nodes"].items())


def _said(v: dict) -> str:
    return (f"not a minimum of the L1 problem: thrust would pay at nodes {_nodes(v)} (switching function up to "
            f"{v['fuel_switching_max']:+.1e} > {v['fuel_guard_tol']:.0e} on coast nodes)")


def guarded(run, sol: Solution) -> Solution:
    """The guard and the escape (module docstring) on a converged fuel solve ``sol`` of the plan run ``run``
    (:class:`~.solve._PlanRun`: its NLP ``tr``, the primal-dual ``points`` of its attempts and the :func:`switching`
    values of the converged ones, ``switchings``, ``attempt``).

    Stats: :func:`verdict`'s of the Solution returned, and ``fuel_escape`` (one line per escape: cost before and
    after, the guard after, or why it stopped).  The Solution returned is the lowest-cost converged one of ``sol``
    and its escapes; if its guard still fails, its message says so."""
    tr = run.tr
    point, sw = run.points[id(sol)], run.switchings[id(sol)]
    v = verdict(sw)
    log = []
    for k in range(1, ESCAPES + 1):
        if v["fuel_guard"] != "failed":
            break
        aimed = f"{k}: d re-aimed at {_nodes(v)} (switching function up to {v['fuel_switching_max']:+.1e})"
        for kick in (0.0, ESCAPE_KICK):
            start = point_guess(tr, reaimed(tr, point, sw, kick))
            new = run.attempt(f"{ESCAPE} {k}{' (kicked)' if kick else ''}", start, ESCAPE_BUDGET)
            if new.converged and new.cost < sol.cost:
                break
            why = f"cost {new.cost:.10g}, not lower than {sol.cost:.10g}" if new.converged else "not kept"
            log.append(f"{aimed}{f', s kicked to {kick:.0e}' if kick else ''}; {new.result}, {why}")
        else:
            log[-1] += ": stopped"
            break
        point, sw = run.points[id(new)], run.switchings[id(new)]
        v_new = verdict(sw)
        log.append(f"{aimed}{f', s kicked to {kick:.0e}' if kick else ''}; cost {sol.cost:.10g} -> {new.cost:.10g} in "
                   f"{new.iterations} iterations, guard {v_new['fuel_guard']} (max {v_new['fuel_switching_max']:+.1e})")
        # what the start's making reported (the coarse grid's multistart, the homotopy's levels) and its label
        new.stats = {**sol.stats, **new.stats, "initial_guess": sol.stats.get("initial_guess")}
        sol, v = new, v_new
    sol.stats.update(v)
    if log:
        sol.stats["fuel_escape"] = log
        sol.message += "; fuel KKT guard: escaped from a false minimum (" + "; ".join(log) + ")"
    if v["fuel_guard"] == "failed":
        sol.message += "; " + _said(v)
    return sol


def false_minima(verdicts: dict, starts: list, stats: dict) -> dict:
    """The multistart's starts (Attempts, :func:`~.plan.multistart`) whose converged point failed the guard
    (``verdicts``: id(Attempt) -> :func:`verdict`'s state, recorded by the plan run before any escape), as stats:
    ``multistart_false_minima`` (how many) and the multistart's sentence (``stats['multistart']``) extended to say
    which costs are false minima of the NLP rather than optima of the fuel problem ({} if none failed or there is no
    multistart).  Why: "the starts ended at 3 different optima" was said of the fuel raise's 25-step starts
    (0.812941, 0.813134, 0.816954) where the last two are false minima: both escape to 0.8129414920
    (docs/mathematics.md, "The fuel KKT guard")."""
    bad = [a for a in starts if verdicts.get(id(a)) == "failed"]
    if not bad or "multistart" not in stats:
        return {}
    costs = ", ".join(f"{a.cost:.6g}" for a in sorted(bad, key=lambda a: a.cost))
    return {"multistart_false_minima": len(bad),
            "multistart": f"{stats['multistart']}; of these, {len(bad)} ({costs}) fail the fuel KKT guard: false "
                          f"minima of the NLP, where thrust would pay on coast nodes, not optima of the fuel problem"}


__all__ = ["COAST_RTOL", "ESCAPE", "ESCAPES", "GUARD_TOL", "checked_parts", "false_minima", "guarded", "reaimed",
           "switching", "switching_values", "verdict"]
