"""The fuel KKT guard and the escape from a false minimum of the fuel NLP (docs/mathematics.md §22).

With mu_j (3, physical) the multiplier of the epigraph row u_j - s_j d_j = 0 (:mod:`.nlp`) of one part at node j,
the NLP's stationarity on a coast node (s_j = 0) only asks mu_j^T d_j <= w omega_j, whereas the L1 problem's asks

    |mu_j| <= w omega_j,   i.e.   sigma_j = |mu_j| / (w omega_j) - 1 <= 0   (the switching function).

:func:`switching` computes sigma on the coast nodes of a converged solve from its own multipliers; :class:`Guarded`
reports it and, where it exceeds the tolerance, re-aims d_j along the primer mu_j / |mu_j| and re-solves warm.  A part
whose magnitude is linear (an engine's force), with weight 0 or removed is not checked (:func:`checked_parts`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ...methods.direct import transcription
from ...ocp import Problem, quadrature_weights
from ...results.solution import Solution
from ...results.start import Point
from ...strategy.core import Context
from .nlp import fuel_rows

PARTS = ("force", "moment")


def counted_parts(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts (force, moment) whose fuel counts: weight > 0 and not removed (a norm bound of 0)."""
    c = problem.control
    return np.array([not (b is not None and b.removed) and wt > 0
                     for b, wt in zip((c.force_bound, c.moment_bound), (c.W_f[0, 0], c.W_m[0, 0]))])


def linear_parts(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts whose magnitude is linear in u, an engine's (|u| = a^T u: no epigraph, :mod:`.nlp`)."""
    c = problem.control
    return np.array([b is not None and b.engine_axis is not None for b in (c.force_bound, c.moment_bound)])


def checked_parts(problem: Problem) -> np.ndarray:
    """(2,) bool: the parts the guard checks: counted, with a magnitude that is not linear."""
    return counted_parts(problem) & ~linear_parts(problem)


def switching_values(tr, w: np.ndarray, mu: np.ndarray, coast: np.ndarray) -> dict:
    """The switching values of :func:`switching` from the multipliers ``mu`` (2, 3, nU, physical) of a point ``w``
    (physical) of the NLP ``tr`` and its ``coast`` nodes (2, nU) bool.  The one place sigma is computed, for the
    epigraph NLP and the structured one (:func:`.structure.switching_l1`)."""
    problem, lay, c = tr.problem, tr.layout, tr.problem.control
    h = float(w[lay.ih]) if lay.ih is not None else problem.h
    omega = quadrature_weights(problem.scheme, problem.N, 1.0 if problem.uniform else problem.mesh) * h
    weights = np.array([c.W_f[0, 0], c.W_m[0, 0]])
    checked = checked_parts(problem)
    rate = np.linalg.norm(mu, axis=1)                       # (2, nU): the gain of thrust per unit of s
    with np.errstate(divide="ignore", invalid="ignore"):
        primer = mu / rate[:, None, :]
        sigma = rate / (weights[:, None] * omega[None, :]) - 1.0
    return {"sigma": np.where(coast & checked[:, None], sigma, np.nan), "value": sigma, "mu": mu, "primer": primer,
            "nodes": np.asarray(lay.control_nodes), "checked": checked}


def switching(tr, point: Point, coast_rtol: float) -> dict:
    """The switching values of a point of the fuel NLP ``tr`` (a SmoothTranscription of the fuel epigraph):
    ``point`` its scaled primal point and constraint multipliers.

    Returns {'sigma': (2, nU) sigma_j = |mu_j| / (w omega_j) - 1 on the coast nodes (s below ``coast_rtol`` x the
    part's magnitude scale; nan elsewhere and on parts not checked), 'value': sigma on every node, 'mu': (2, 3, nU)
    physical, 'primer': (2, 3, nU) mu_j / |mu_j|, 'nodes': the node index of each control node (first order 1..N,
    LGVI 0..N), 'checked': (2,) bool}; omega_j uses the point's own h with a free final time."""
    w = np.asarray(point.x, float) * tr.w_scale
    rows = tr.nlp.rows("fuel")      # (8, nU) or, an engine's force, (5, nU): fuel_rows
    nu = tr.multipliers(point.lam_g)
    mu = np.stack([nu[r] if r is not None else np.zeros((3, rows.shape[1])) for r in fuel_rows(tr.objective, tr, rows)])
    coast = w[tr.layout.iS[:2]] < coast_rtol * tr.magnitudes[:, None]
    return switching_values(tr, w, mu, coast)


def verdict(sw: dict, tol: float) -> dict:
    """Solution stats of :func:`switching`'s values: ``fuel_switching_max`` (the largest sigma on a coast node;
    -1 if there is none), ``fuel_switching_nodes`` ({part: [nodes with sigma > tol]}), ``fuel_guard_tol``,
    ``fuel_guard`` ('passed', 'failed' or 'not checked' when no part is checked)."""
    sigma = sw["sigma"]
    finite = sigma[np.isfinite(sigma)]
    bad = {p: [int(n) for n in sw["nodes"][np.isfinite(sigma[i]) & (sigma[i] > tol)]] for i, p in enumerate(PARTS)}
    state = "not checked" if not sw["checked"].any() else "failed" if any(bad.values()) else "passed"
    return {"fuel_guard": state, "fuel_switching_max": float(finite.max()) if finite.size else -1.0,
            "fuel_switching_nodes": {p: v for p, v in bad.items() if v}, "fuel_guard_tol": tol}


def reaimed(tr, point: Point, sw: dict, tol: float, kick: float = 0.0) -> Point:
    """``point`` with d_j = mu_j / |mu_j| (the primer of :func:`switching`) on the coast nodes whose sigma > tol and
    the bound multipliers of those nodes' s set to 0 (they belonged to the old d); lam_g kept.  ``kick`` > 0: also
    s_j = kick times the magnitude's scale and u_j = s_j d_j there."""
    x, lam_x, lam_g = point.x.copy(), point.lam_x.copy(), point.lam_g.copy()
    iS, iU = tr.layout.iS, tr.layout.iU
    for i in range(2):
        bad = np.flatnonzero(np.isfinite(sw["sigma"][i]) & (sw["sigma"][i] > tol))
        d = sw["primer"][i][:, bad]
        x[iS[2 + 3 * i:5 + 3 * i][:, bad]] = d
        if kick > 0.0:
            iu = iU[3 * i:3 * i + 3][:, bad]
            x[iS[i, bad]] = kick                                   # scaled s: its scale is tr.magnitudes[i]
            x[iu] = kick * tr.magnitudes[i] * d / tr.w_scale[iu]
        lam_x[iS[i, bad]] = 0.0
    return Point(point.key, x, lam_g, lam_x)


def _nodes(v: dict) -> str:
    return "; ".join(f"{p} {', '.join(map(str, n))}" for p, n in v["fuel_switching_nodes"].items())


def _said(v: dict) -> str:
    return (f"not a minimum of the L1 problem: thrust would pay at nodes {_nodes(v)} (switching function up to "
            f"{v['fuel_switching_max']:+.1e} > {v['fuel_guard_tol']:.0e} on coast nodes)")


@dataclass(frozen=True)
class Guarded:
    """``inner``, then the fuel KKT guard on its converged epigraph solution and the escape from a false minimum
    (docs/mathematics.md §22): the offending coast nodes' directions re-aimed -- and, when that does not lower the
    cost, their magnitudes set to ``kick`` times their scale -- and the same NLP re-solved warm (``warm`` IPOPT
    options) within ``budget`` iterations, at most ``escapes`` times while the cost falls.  ``tol``: the guard fails
    where sigma exceeds it on a coast node.  ``coast_rtol``: a coast node's magnitude is below this times the part's
    scale.  Stats: :func:`verdict`'s and ``fuel_escape`` (one line per escape)."""

    inner: object
    warm: Mapping = field(default_factory=lambda: {"warm_start_init_point": "yes", "mu_init": 1e-9,
                                                   "warm_start_bound_push": 1e-9, "warm_start_slack_bound_push": 1e-9,
                                                   "warm_start_mult_bound_push": 1e-9})
    tol: float = 1e-6
    coast_rtol: float = 1e-6
    escapes: int = 3
    budget: int = 500
    kick: float = 1e-3
    label: str = "fuel guard escape"

    def check(self, sol: Solution, options) -> dict | None:
        """:func:`switching`'s values of a converged epigraph solution ``sol`` (None for another: a structured
        finish checks its own)."""
        objective = sol.problem.control.objective
        if not sol.converged or not getattr(objective, "epigraph", False) or sol.warm is None or \
                sol.warm.point is None:
            return None
        tr, _ = transcription(sol.problem, options)
        return switching(tr, sol.warm.point, self.coast_rtol) if sol.warm.point.key == tr.point_key else None

    def failed(self, sol: Solution, ctx: Context) -> bool:
        """Whether the converged ``sol`` fails the guard (a false minimum of the NLP)."""
        sw = self.check(sol, ctx.options)
        return sw is not None and verdict(sw, self.tol)["fuel_guard"] == "failed"

    def run(self, problem: Problem, start, ctx: Context) -> Solution:
        sol = self.inner.run(problem, start, ctx)
        sw = self.check(sol, ctx.options)
        if sw is None:
            return sol
        return self.escape(problem, sol, sw, ctx)

    def escape(self, problem: Problem, sol: Solution, sw: dict, ctx: Context) -> Solution:
        """The escapes from ``sol`` (its switching values ``sw``) and the stats (class docstring)."""
        tr, _ = transcription(problem, ctx.options)
        v, log, trace = verdict(sw, self.tol), [], list(sol.trace)
        for k in range(1, self.escapes + 1):
            if v["fuel_guard"] != "failed":
                break
            aimed = f"{k}: d re-aimed at {_nodes(v)} (switching function up to {v['fuel_switching_max']:+.1e})"
            for kick in (0.0, self.kick):
                start = replace(sol.warm, point=reaimed(tr, sol.warm.point, sw, self.tol, kick))
                new = ctx.solve(problem, start, f"{self.label} {k}{' (kicked)' if kick else ''}", ipopt=self.warm,
                                max_iter=min(int(ctx.options.max_iter), self.budget))
                trace += new.trace
                if new.converged and new.cost < sol.cost:
                    break
                why = f"cost {new.cost:.10g}, not lower than {sol.cost:.10g}" if new.converged else "not kept"
                log.append(f"{aimed}{f', s kicked to {kick:.0e}' if kick else ''}; {new.result}, {why}")
            else:
                log[-1] += ": stopped"
                break
            sw = switching(tr, new.warm.point, self.coast_rtol)
            v_new = verdict(sw, self.tol)
            log.append(f"{aimed}{f', s kicked to {kick:.0e}' if kick else ''}; cost {sol.cost:.10g} -> {new.cost:.10g} "
                       f"in {new.iterations} iterations, guard {v_new['fuel_guard']} (max "
                       f"{v_new['fuel_switching_max']:+.1e})")
            sol = replace(new, stats={**sol.stats, **new.stats, "initial_guess": sol.stats.get("initial_guess")},
                          notes=sol.notes)
            v = v_new
        notes = [] if not log else ["fuel KKT guard: escaped from a false minimum (" + "; ".join(log) + ")"]
        if v["fuel_guard"] == "failed":
            notes.append(_said(v))
        return replace(sol, trace=tuple(trace)).with_notes(*notes, **v, **({"fuel_escape": log} if log else {}))


__all__ = ["Guarded", "PARTS", "counted_parts", "reaimed", "switching", "switching_values", "verdict"]
