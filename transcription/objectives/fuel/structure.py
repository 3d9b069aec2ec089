"""The structured fuel finish (docs/mathematics.md §23-§24): a fuel problem on a finer grid finished from its coarser
grid's optimum on that optimum's switching structure B (per part, force and moment: the burn nodes).

The objective :meth:`Fuel.structured <transcription.objectives.fuel.Fuel.structured>` (the NLP's ``l1`` block), in
place of the epigraph u = s d (:mod:`.nlp`) whose indefinite Hessian slows IPOPT: on a coast node u_j = 0 and s_j = 0
(their bounds); on a burn node

    rho_delta(u_j) = sqrt(|u_j|^2 + delta^2) - delta <= s_j,   s_j >= 0,   cost sum_j omega_j (w_f s_f,j + w_m s_m,j),

delta a fraction of the part's reference r (:func:`.homotopy.smoothing_reference`).  An engine's force has the linear
row a^T u_f - s_f <= 0 on every node (no rounding, never pruned).  The switching function (:func:`switching_l1`):
mu_j is the multiplier of the bound u_j = 0 on a coast node, nu_j u_j / sqrt(|u_j|^2 + delta^2) on a burn node; a
point with sigma_j <= the guard's tol on every coast node is a KKT point of the L1 problem and of the epigraph NLP.
:class:`StructuredFinish`: widen, rough solve, prune, exact solve, guard, widen where sigma_j > tol, repeat.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from ...geometry.state import U_FORCE, U_MOMENT
from ...methods.direct import transcription
from ...nlp.transcription import SmoothTranscription
from ...ocp import Problem
from ...results.solution import Solution
from ...results.start import Point, Start
from ...strategy.core import Context, collapsed
from .guard import PARTS, Guarded, counted_parts, linear_parts, switching_values, verdict
from .homotopy import smoothing_reference


def burn_structure(problem: Problem, U: np.ndarray, scales: np.ndarray, dilate: int, burn_rtol: float) -> np.ndarray:
    """(2, nU) bool: the burn nodes of controls U (6, nU) -- |u_j| > burn_rtol x the part's scale (``scales``, (2,),
    physical) -- widened by ``dilate`` nodes on each side; a part whose fuel is not counted (weight 0) burns
    everywhere (its control is free), a removed one nowhere."""
    c = problem.control
    mags = np.stack([np.linalg.norm(U[sl], axis=0) for sl in (U_FORCE, U_MOMENT)])
    burn = mags > burn_rtol * np.asarray(scales)[:, None]
    wide = burn.copy()
    for k in range(1, dilate + 1):
        wide[:, k:] |= burn[:, :-k]
        wide[:, :-k] |= burn[:, k:]
    for i, (b, wt, linear) in enumerate(zip((c.force_bound, c.moment_bound), (c.W_f[0, 0], c.W_m[0, 0]),
                                            linear_parts(problem))):
        if b is not None and b.removed:
            wide[i] = False
        elif wt <= 0 or linear:
            wide[i] = True
    return wide


def switching_l1(tr: SmoothTranscription, point: Point, coast_rtol: float) -> dict:
    """The switching values of a point of the structured NLP ``tr`` (its objective on a structure): the keys of
    :func:`.guard.switching`: 'sigma' (2, nU) on the coast nodes of the L1 problem -- the structure's coast nodes and
    the burn nodes with |u_j| < coast_rtol x scale -- (nan elsewhere and on parts not checked), 'value' on every node,
    'mu' (2, 3, nU) physical, 'primer', 'nodes', 'checked'.  mu_j = s_obj lam_x(u_j) / sU on a coast node of the
    structure (module docstring) and nu_j u_j / sqrt(|u_j|^2 + delta^2) on a burn node, nu_j the multiplier of its
    row |u_j| - s_j <= 0."""
    lay, objective = tr.layout, tr.objective
    w = np.asarray(point.x, float) * tr.w_scale
    delta = np.asarray(objective.rounding, float) * tr.magnitudes
    mu = np.empty((2, 3, len(lay.control_nodes)))
    mags = np.empty((2, mu.shape[2]))
    nu = tr.multipliers(point.lam_g)[tr.nlp.rows("fuel")]        # (2, nU): |u_f| - s_f, |u_m| - s_m
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        iu = lay.iU[sl]
        u = w[iu]
        mags[i] = np.linalg.norm(u, axis=0)
        fixed = tr.scales.objective * np.asarray(point.lam_x, float)[iu] / tr.w_scale[iu]
        burning = nu[i] * u / np.sqrt(mags[i] ** 2 + delta[i] ** 2)
        mu[i] = np.where(objective.burn[i][None, :], burning, fixed)
    coast = ~objective.burn | (mags < coast_rtol * tr.magnitudes[:, None])
    return switching_values(tr, w, mu, coast)


def _nodes(burn: np.ndarray) -> str:
    return f"force {int(burn[0].sum())}, moment {int(burn[1].sum())}"


@dataclass(frozen=True)
class StructuredFinish:
    """The fuel problem from a start near its optimum (a coarser grid's optimum resampled, a level's point, a
    continuation's optimum) on its switching structure (docs/mathematics.md §23-§24); ``label`` names it in the trace.

    ``dilate``: the start's burn nodes (magnitude > ``burn_rtol`` x the part's scale) widened by this many nodes on
    each side (the fine grid resolves the switching times the coarse one rounds to its nodes).  ``rough``: the rough
    solve's rounding (x the part's scale), from IPOPT's own start with the ``cold`` options (the adaptive barrier
    for a start from another grid; the continuation's finish passes a small barrier: :mod:`.continuation`).
    ``prune``: burn nodes the rough solve took below this x the scale become coast nodes.  ``exact``: the rounding of
    the solves on the pruned structure.  ``rounds``: at most this many solves (a round after the first widens the
    structure), each within ``budget`` iterations.  ``resolved``: the start resolves the switching times (an adaptive
    level of refinement).  ``scale_nodes``: on a grid of N > scale_nodes steps every solve sees the objective scaled by
    N / scale_nodes (IPOPT's obj_scaling_factor): a node's share of the fuel falls as 1/N while the barrier's pull on
    it does not, so on a fine grid IPOPT's own barrier start wanders and a warm start's multipliers, the rough solve's,
    stay balanced only if every solve sees the same scale (docs/mathematics.md §23).  ``fallback``: the epigraph NLP from the same start
    with these IPOPT options (a small barrier, the point pushed off its bounds as little as possible), within
    ``fallback_budget`` iterations (None: max_iter); None: no fallback.  ``guard``: the guard's tolerances and kick
    (:class:`.guard.Guarded`; a coast node with sigma_j > tol joins B, its control started at kick x r along mu_j).
    ``shared_duals``: the first solve starts with the start's multipliers (of its NLP, ``start.nlp_key``) on the rows
    both NLPs share (:meth:`~transcription.nlp.structured.StructuredNLP.shared_rows`: the dynamics, controls, path and
    terminal rows; the fuel rows at 0): for a start that is the optimum of a neighbouring problem on the same grid (a
    continuation's), where IPOPT's own estimate left the rough solve regularizing its Hessian at every iteration
    (docs/mathematics.md §25).  ``warm``: the IPOPT options of the warm solves (pruned, widened; None: the guard's
    warm options).  A warm solve that fails is solved once more from its primal point with the ``cold`` options."""

    guard: Guarded
    label: str = "structured finish"
    dilate: int = 2
    burn_rtol: float = 1e-6
    rough: float = 1e-5
    cold: Mapping = field(default_factory=lambda: {"mu_strategy": "adaptive"})
    prune: float = 1e-3
    exact: float = 1e-6
    rounds: int = 4
    budget: int = 500
    resolved: bool = False
    scale_nodes: int = 200
    fallback: Mapping | None = field(default_factory=lambda: {"mu_init": 1e-6, "bound_push": 1e-9, "bound_frac": 1e-9,
                                                              "slack_bound_push": 1e-9, "slack_bound_frac": 1e-9})
    fallback_budget: int | None = None
    shared_duals: bool = False
    warm: Mapping | None = None

    def run(self, problem: Problem, start: Start, ctx: Context) -> Solution:
        sol, stats = self.finish(problem, start, ctx)
        if (sol.converged and stats["fuel_guard"] == "passed") or self.fallback is None:
            return replace(collapsed(sol, self.label, "its rounds"), problem=problem).with_notes(**stats)
        budget = {} if self.fallback_budget is None else {"max_iter": min(int(ctx.options.max_iter),
                                                                            self.fallback_budget)}
        tried = collapsed(sol, f"{self.label}, on its switching structure", "its rounds").trace
        fb = ctx.solve(problem, start.primal(), self.label, ipopt=self.fallback, **budget)
        said = stats["fuel_structure"] + ["not kept: the fuel NLP finished from the same start"]
        return replace(fb, trace=tried + fb.trace).with_notes(fuel_structure=said)

    def finish(self, problem: Problem, start: Start, ctx: Context) -> tuple[Solution, dict]:
        """The rounds: the last Solution (converged or not; on the structured problem) with
        the trace of every solve, and stats: :func:`~.guard.verdict`'s of its switching values, ``fuel_structure``
        (one line per round), ``fuel_structure_rounds``."""
        ref = smoothing_reference(problem, start.U)      # the parts' bounds, an unbounded part's largest magnitude
        per_scale = ref / SmoothTranscription.magnitude_scales(problem)   # a rounding x ref, in the NLP's terms
        burn = burn_structure(problem, start.U, ref, 0 if self.resolved else self.dilate, self.burn_rtol)
        extra = {"obj_scaling_factor": max(1.0, problem.N / self.scale_nodes)}
        log, trace, v = [], [], {}
        point, sol = None, None
        for rnd in range(1, self.rounds + 1):
            rough = point is None and not self.resolved
            said = [f"solve {rnd}: burn nodes {_nodes(burn)} of {burn.shape[1]}"]
            phase = "rough" if rough else "resolved" if point is None or point.lam_g is None else "widened"
            p, sol, what = self._solve(problem, ctx, burn, self.rough if rough else self.exact, per_scale, start, point,
                                       extra, phase, trace)
            said.append(f"rough (delta {self.rough:.0e}) {what}" if rough else
                        f"exact on the resolved structure, from IPOPT's own start: {what}" if phase == "resolved"
                        else what)
            tr, _ = transcription(p, ctx.options)
            if sol.converged and phase != "resolved":     # the resolved structure's first solve is not pruned
                pruned, x0 = self._pruned(tr, sol.warm.point.x, ref)
                point = Point(tr.point_key, x0, sol.warm.point.lam_g, _released(tr, sol.warm.point.lam_x, pruned))
                if rough or (pruned != p.control.objective.burn).any():
                    burn = pruned
                    p, sol, what = self._solve(problem, ctx, burn, self.exact, per_scale, start, point, extra, "pruned",
                                               trace)
                    tr, _ = transcription(p, ctx.options)
                    said.append(f"pruned to {_nodes(burn)}: {what}")
            if not sol.converged:
                log.append("; ".join(said))
                break
            point = sol.warm.point
            sw = switching_l1(tr, point, self.guard.coast_rtol)
            v = verdict(sw, self.guard.tol)
            log.append(f"{'; '.join(said)}; cost {sol.cost:.10g}, switching function up to {v['fuel_switching_max']:+.1e}")
            if v["fuel_guard"] != "failed":
                break
            burn, x0 = self._widened(tr, point.x, sw, ref)
            point = Point(tr.point_key, x0, point.lam_g, _released(tr, point.lam_x, burn))
            log[-1] += "; widened at " + "; ".join(
                f"{part} {', '.join(map(str, sw['nodes'][burn[i] & ~p.control.objective.burn[i]]))}"
                for i, part in enumerate(PARTS) if (burn[i] & ~p.control.objective.burn[i]).any())
        stats = {"fuel_guard": "failed", **v, "fuel_structure": log, "fuel_structure_rounds": len(log)}
        return replace(sol, trace=tuple(trace)), stats

    def _solve(self, problem, ctx, burn, rounding, per_scale, start, point, extra, phase, trace):
        """One solve of the structured problem (``burn``, ``rounding`` x the part's reference) from ``start`` (the
        first) or ``point`` (scaled, with multipliers: warm; a warm solve that fails is solved again from its x with
        IPOPT's own start).  (problem, Solution, what it did in words); its attempts appended to ``trace``."""
        c = problem.control
        p = problem.replace(control=replace(c, objective=c.objective.structured(burn, rounding * per_scale)))
        budget = min(int(ctx.options.max_iter), self.budget)
        tries = [(point, self.warm or self.guard.warm, "")] if point is not None and point.lam_g is not None else []
        first = start.primal() if point is None else replace(start.primal(), point=replace(point, lam_g=None,
                                                                                          lam_x=None))
        if point is None and self.shared_duals and start.multipliers is not None and start.nlp_key is not None:
            nlp = transcription(p, ctx.options)[0].nlp
            first = replace(first, multipliers=nlp.shared_rows(start.nlp_key, start.multipliers), nlp_key=nlp.key)
        tries.append((None, self.cold, "from IPOPT's own start: " if tries else ""))
        said = []
        for warm, options, prefix in tries:      # a failed warm solve: again, cold (class docstring)
            s = first if warm is None else replace(start.primal(), point=warm)
            sol = ctx.solve(p, s, f"structured {phase}{' cold' if prefix else ''}", ipopt={**extra, **options},
                            max_iter=budget)
            trace += sol.trace
            said.append(f"{prefix}{sol.stats.get('solver_status', sol.result)} in {sol.trace[-1].iterations} "
                        f"iterations")
            if sol.converged:
                break
        return p, sol, ", then ".join(said)

    def _pruned(self, tr, x: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The structure without the burn nodes whose magnitude the solve took below ``prune`` x the part's reference
        ``ref`` (a linear part, an engine's force, is never pruned: :func:`.guard.linear_parts`), and x with their
        controls and magnitudes at 0."""
        base = tr.objective.burn
        burn, x = base.copy(), x.copy()
        w = x * tr.w_scale
        pruned = counted_parts(tr.problem) & ~linear_parts(tr.problem)
        for i, sl in enumerate((U_FORCE, U_MOMENT)):
            iu = tr.layout.iU[sl]
            off = base[i] & (np.linalg.norm(w[iu], axis=0) < self.prune * ref[i]) & pruned[i]
            burn[i, off] = False
            x[iu[:, off]] = 0.0
            x[tr.layout.iS[i, off]] = 0.0
        return burn, x

    def _widened(self, tr, x: np.ndarray, sw: dict, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The structure with the coast nodes whose sigma > tol burning, and x with their controls set to the guard's
        kick x the part's reference ``ref`` along the primer (scaled)."""
        base = tr.objective.burn
        burn, x = base.copy(), x.copy()
        for i, sl in enumerate((U_FORCE, U_MOMENT)):
            bad = np.flatnonzero(~base[i] & np.isfinite(sw["sigma"][i]) & (sw["sigma"][i] > self.guard.tol))
            burn[i, bad] = True
            iu = tr.layout.iU[sl][:, bad]
            x[iu] = self.guard.kick * ref[i] * sw["primer"][i][:, bad] / tr.w_scale[iu]
            x[tr.layout.iS[i, bad]] = self.guard.kick * ref[i] / tr.magnitudes[i]
        return burn, x


def _released(tr, lam_x: np.ndarray, burn: np.ndarray) -> np.ndarray:
    """lam_x with the bound multipliers of the nodes whose flags ``burn`` changes set to 0 (they held for the old
    structure)."""
    lam_x = lam_x.copy()
    lam_x[tr.layout.iU[:, np.any(burn != tr.objective.burn, axis=0)]] = 0.0
    return lam_x


__all__ = ["StructuredFinish", "burn_structure", "switching_l1"]
