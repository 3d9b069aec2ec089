"""The structured fuel finish (docs/mathematics.md §23): a fuel problem on a finer grid finished from its coarser
grid's optimum on that optimum's switching structure.

On the fine grid the epigraph u = s d of the fuel NLP (:func:`~transcription.nlp.blocks.control_node`) is what makes
IPOPT slow: the (s, d) block of the Hessian of the Lagrangian is [[0, -mu^T], [-mu, s w omega I]], indefinite
wherever mu is not along d (every coast node, every burn node away from the optimum), and IPOPT regularizes it at
most iterations (the raise's 400-step finish from its 100-step optimum resampled: 362 iterations, 27-31 s; 203 with
the coast nodes' (s, d) fixed at 0).  A fuel-optimal control is bang-off-bang, and the coarser optimum says where it
is off.  So the fine grid is solved on a switching structure B (per part, force and moment: the burn nodes), by the
NLP of ``SmoothTranscription(..., burn=B, rounding=delta)`` (``control_node(..., l1=True)``): on a coast node
u_j = 0 and s_j = 0 (their bounds); on a burn node

    rho_delta(u_j) = sqrt(|u_j|^2 + delta^2) - delta <= s_j,   s_j >= 0,   cost sum_j omega_j (w_f s_f,j + w_m s_m,j),

delta a fraction of the part's magnitude scale: the row's gradient never vanishes and its Hessian is positive
semidefinite.

The switching function (:func:`switching_l1`): on a coast node of B, mu_j is the multiplier of the bound that fixes
u_j = 0 (the same -(gradient in u_j of the rest of the Lagrangian) as the epigraph's mu_j, :mod:`.fuel_guard`); on a
burn node mu_j = nu_j u_j / sqrt(|u_j|^2 + delta^2), nu_j <= w omega_j the row's multiplier, so a burn node the
optimum switched off (|u_j| ~ delta) has sigma_j < 0.  A point with sigma_j <= GUARD_TOL on every coast node is a KKT
point of the L1 problem, and of the epigraph NLP too (s = |u|, d = u / |u| on the burn nodes; s = 0,
d = mu / (w omega) on the coast ones).

:func:`structured_finish`: B = the coarse optimum's burn nodes widened by DILATE nodes on each side; the rough solve
(delta = ROUGH x the scale, IPOPT's own start with ROUGH_OPTIONS); the burn nodes it switched off (below PRUNE_RTOL
x the scale) pruned; the solve with delta = EXACT x the scale from there, warm; the guard.  Coast nodes with
sigma_j > GUARD_TOL join B (their control started at ESCAPE_KICK x the scale along mu_j / |mu_j|) and the NLP is
solved again, warm, and pruned again: at most ROUNDS solves.  A warm solve that fails is solved once more from
the same primal point with IPOPT's own barrier start (ROUGH_OPTIONS): on the raise's adaptive 4826-step level of
accuracy 1e-6 (from its 200-step optimum) the pruned solve warm from the rough one's multipliers (WARM_LEVEL, the
barrier at 1e-9) wandered (primal infeasibility up to 1.4) and ended Infeasible_Problem_Detected after 59
iterations; from its own barrier start the same point converged in 36, the guard passed (docs/mathematics.md §16).
From an adaptive level's optimum that resolves the switching times (:func:`resolves`: refinement to an accuracy
after its first adaptive level) the finish is one exact solve on the resampled burn nodes, neither widened, rough nor
pruned, with the objective scaled by N / RESOLVED_NODES (``resolved``; docs/mathematics.md §23).
Not for fatrop: :func:`applies`.

The roundings, the pruning threshold and the widening's kick are fractions of each part's reference r
(:func:`~.homotopy.smoothing_reference`: its bound, or without one the start's largest magnitude): an unbounded
part's scale is a guess from the boundary data (the raise without its moment bound at N = 100: with the scale the
finish failed and the epigraph NLP took 1900 iterations, 43 s; with r 786, 7.7 s; docs §24).  A body-fixed engine's
force (:func:`engine`) has the magnitude a^T u_f = T, linear and exact on the engine's rows: its row is
a^T u_f - s_f <= 0 on every node (no rounding, never pruned; T = 0 is the engine row's bound, where a fixed u_f = 0
would leave the engine's rows constant).
"""
from __future__ import annotations

import time

import numpy as np

from .starts import Guess
from ..geometry.state import U_FORCE, U_MOMENT
from ..nlp.solvers import ipopt_options, make_ipopt
from ..options import DirectOptions
from ..ocp import NormBound, Problem, ThrusterBound
from ..results.solution import Solution
from ..results.start import WarmStart
from .fuel_guard import COAST_RTOL, ESCAPE_KICK, GUARD_TOL, PARTS, checked_parts, switching_values, verdict
from .homotopy import WARM_LEVEL, smoothing_reference
from ..methods.direct.solution import nlp_solution
from ..nlp.transcription import SmoothTranscription

#: the coarse optimum's burn nodes (magnitude > BURN_RTOL x the part's scale) are widened by DILATE nodes on each side:
#: the fine grid resolves the switching times the coarse one rounds to its nodes (the raise 100 -> 400: 23 force burn
#: nodes, 29 widened; with the 23 alone its 400-step problem is infeasible)
DILATE = 2
BURN_RTOL = 1e-6
#: the rough solve's rounding delta (x the part's scale): smooth where the widened nodes switch off.  With 1e-9 in one
#: solve, those nodes pass |u| ~ delta, where the row's curvature is 1e9 times the scale's: from four 100- and 200-step
#: starts 90, 214, 330 and 500 (not converged) iterations at N = 400; with 1e-5, 50-84
ROUGH = 1e-5
#: ... its IPOPT options (the primal point only: IPOPT's own barrier start, adaptive barrier; with the default monotone
#: barrier 84-129 iterations from those starts)
ROUGH_OPTIONS = {"mu_strategy": "adaptive"}
#: burn nodes the rough solve took below PRUNE_RTOL x the scale are pruned (coast): there it leaves ~delta of thrust,
#: up to 4e-7 of the raise's cost
PRUNE_RTOL = 1e-3
#: the rounding of the solves on the pruned structure: on burn nodes of |u| >= PRUNE_RTOL x the scale it moves the
#: gradient by < EXACT^2 / (2 PRUNE_RTOL^2) = 5e-7, and the raise's cost at N = 400 is 4.5e-10 (relative) above the
#: delta -> 0 limit (1e-8 after it: 42 more iterations)
EXACT = 1e-6
#: at most this many rounds (a solve and its pruning; a round after the first widens the structure) ...
ROUNDS = 4
#: ... and NLP iterations per solve
ROUND_BUDGET = 500
#: a warm start on a non-uniform mesh (an adaptive level of refinement to an accuracy, docs/mathematics.md §16) with
#: more than this fraction of the problem's steps resolves the switching times: :func:`structured_finish` with
#: ``resolved`` (the first adaptive level, from the uniform N, and uniform levels, which at least double N, are
#: finished as from a coarser grid).  The raise at accuracy 1e-6, 4826 -> 4923 adaptive steps: the exact solve
#: converged in 91 iterations (21 without the scaled objective), guard passed, where the widened rough solve did not
#: converge in 500
RESOLVED_FRACTION = 0.5
#: ... and its solves see the objective scaled by N / RESOLVED_NODES (IPOPT's obj_scaling_factor, at least 1): each
#: node's share of the fuel falls with its step, the barrier's pull does not, so on a fine grid IPOPT's own barrier
#: start wanders.  The raise, 4923 -> 6216 adaptive steps: unscaled the exact solve was at primal infeasibility 36
#: after 80 iterations (at cost 3.7 after 20); scaled by 31, Solve_Succeeded in 38, guard passed
RESOLVED_NODES = 200


def applies(problem: Problem, options: DirectOptions) -> bool:
    """Whether the structured finish covers ``problem``: the fuel objective, IPOPT."""
    return problem.control.objective == "fuel" and options.solver == "ipopt"


def resolves(warm: WarmStart, n_to: int) -> bool:
    """Whether the optimum ``warm`` (before it is fitted to the new grid) resolves the switching times of a grid of
    ``n_to`` steps (a warm start finished with ``resolved``, :func:`structured_finish`): its mesh is non-uniform (an
    adaptive level) and has more than RESOLVED_FRACTION n_to steps."""
    return warm.N > RESOLVED_FRACTION * n_to and not warm.uniform


def engine(problem: Problem) -> ThrusterBound | None:
    """The body-fixed engine of ``problem``'s force (None without one): its magnitude is the thrust, linear, and its
    force burns on every node of the structure (T = 0 is the engine row's bound, :func:`burn_structure`)."""
    b = problem.control.force_bound
    return b if isinstance(b, ThrusterBound) else None


def burn_structure(problem: Problem, U: np.ndarray, scales: np.ndarray, dilate: int = DILATE) -> np.ndarray:
    """(2, nU) bool: the burn nodes of controls U (6, nU) -- |u_j| > BURN_RTOL x the part's scale (``scales``,
    (2,), physical) -- widened by ``dilate`` nodes on each side; a part whose fuel is not counted (weight 0) burns
    everywhere (its control is free), a removed one nowhere."""
    c = problem.control
    mags = np.stack([np.linalg.norm(U[sl], axis=0) for sl in (U_FORCE, U_MOMENT)])
    burn = mags > BURN_RTOL * np.asarray(scales)[:, None]
    wide = burn.copy()
    for k in range(1, dilate + 1):
        wide[:, k:] |= burn[:, :-k]
        wide[:, :-k] |= burn[:, k:]
    for i, (b, wt) in enumerate(zip((c.force_bound, c.moment_bound), (c.W_f[0, 0], c.W_m[0, 0]))):
        if isinstance(b, NormBound) and b.b == 0:
            wide[i] = False
        elif wt <= 0 or isinstance(b, ThrusterBound):
            wide[i] = True
    return wide


def switching_l1(tr: SmoothTranscription, x: np.ndarray, lam_g: np.ndarray, lam_x: np.ndarray) -> dict:
    """The switching values of a point of the structured NLP ``tr`` (``tr.burn`` set): x, lam_x the solver's scaled
    primal point and bound multipliers.  The keys of :func:`.fuel_guard.switching`: 'sigma' (2, nU) on the coast
    nodes of the L1 problem -- the structure's coast nodes and the burn nodes with |u_j| < COAST_RTOL x scale --
    (nan elsewhere and on parts not checked), 'value' on every node, 'mu' (2, 3, nU) physical, 'primer',
    'nodes', 'checked'.  mu_j = s_obj lam_x(u_j) / sU on a coast node of the structure (module docstring) and
    nu_j u_j / sqrt(|u_j|^2 + delta^2) on a burn node, nu_j the multiplier of its row |u_j| - s_j <= 0."""
    lay = tr.layout
    w = np.asarray(x, float) * tr.w_scale
    delta = tr.l1_rounding
    mu = np.empty((2, 3, len(lay.control_nodes)))
    mags = np.empty((2, mu.shape[2]))
    rows = tr.nlp.rows("controls")      # (nr, nU): norms; engine (3); |u_f| - s_f, |u_m| - s_m (the last two)
    nus = tr.multipliers(lam_g)
    nu = nus[rows[-2:]]
    eng = engine(tr.problem)
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        iu = lay.iU[sl]
        u = w[iu]
        mags[i] = np.linalg.norm(u, axis=0)
        fixed = tr.scales.objective * np.asarray(lam_x, float)[iu] / tr.w_scale[iu]
        burning = nu[i] * (eng.axis[:, None] if i == 0 and eng else u / np.sqrt(mags[i] ** 2 + delta[i] ** 2))
        mu[i] = np.where(tr.burn[i][None, :], burning, fixed)
    coast = ~tr.burn | (mags < COAST_RTOL * tr.slack_scales[:, None])
    # an engine's rate along its axis is nu_j + nu_a / max, nu_a the multiplier of its axis row (rows[-5])
    return switching_values(tr, w, mu, coast, None if eng is None else nus[rows[-5]])


def _widened(tr: SmoothTranscription, x: np.ndarray, sw: dict, ref: np.ndarray,
             tol: float = GUARD_TOL) -> tuple[np.ndarray, np.ndarray]:
    """The structure with the coast nodes whose sigma > tol burning, and x with their controls set to ESCAPE_KICK x
    the part's reference ``ref`` along the primer (scaled)."""
    burn, x = tr.burn.copy(), x.copy()
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        bad = np.flatnonzero(~tr.burn[i] & np.isfinite(sw["sigma"][i]) & (sw["sigma"][i] > tol))
        burn[i, bad] = True
        iu = tr.layout.iU[sl][:, bad]
        x[iu] = ESCAPE_KICK * ref[i] * sw["primer"][i][:, bad] / tr.w_scale[iu]
        x[tr.layout.iS[i, bad]] = ESCAPE_KICK * ref[i] / tr.slack_scales[i]
    return burn, x


def _solve(tr: SmoothTranscription, options: DirectOptions, x0: np.ndarray, duals, progress, extra: dict,
           phase: str = ""):
    """IPOPT on ``tr`` from x0 (scaled): warm from ``duals`` = (lam_g, lam_x) with the homotopy's WARM_LEVEL options,
    or with ROUGH_OPTIONS when None; ``extra`` IPOPT options too; its iterations to ``progress`` under ``phase``.
    Returns (out, stats)."""
    ipopt = ipopt_options(options.replace(max_iter=min(options.max_iter, ROUND_BUDGET)), warm_duals=duals is not None)
    for k, val in extra.items():
        ipopt.setdefault(k, val)
    for k, val in (ROUGH_OPTIONS if duals is None else WARM_LEVEL).items():
        ipopt.setdefault(k, val)
    solver = make_ipopt("fuel_structure", tr.nlp, ipopt, progress, tr.scales.objective, phase)
    args = dict(x0=np.clip(x0, tr.lbx, tr.ubx), lbx=tr.lbx, ubx=tr.ubx, lbg=tr.nlp.lbg, ubg=tr.nlp.ubg)
    if duals is not None:
        args.update(lam_g0=duals[0], lam_x0=duals[1])
    return solver(**args), solver.stats()


def _pruned(tr: SmoothTranscription, x: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The structure without the burn nodes whose magnitude the solve took below PRUNE_RTOL x the part's reference
    ``ref`` (an engine's force is never pruned: :func:`engine`), and x with their controls and magnitudes at 0."""
    burn, x = tr.burn.copy(), x.copy()
    w = x * tr.w_scale
    for i, sl in enumerate((U_FORCE, U_MOMENT)):
        iu = tr.layout.iU[sl]
        if i == 0 and engine(tr.problem) is not None:
            continue
        off = tr.burn[i] & (np.linalg.norm(w[iu], axis=0) < PRUNE_RTOL * ref[i]) & checked_parts(tr.problem)[i]
        burn[i, off] = False
        x[iu[:, off]] = 0.0
        x[tr.layout.iS[i, off]] = 0.0
    return burn, x


def _released(tr: SmoothTranscription, lam_x: np.ndarray, burn: np.ndarray) -> np.ndarray:
    """lam_x with the bound multipliers of the nodes whose flags ``burn`` changes set to 0 (they held for the old
    structure)."""
    lam_x = lam_x.copy()
    lam_x[tr.layout.iU[:, np.any(burn != tr.burn, axis=0)]] = 0.0
    return lam_x


def _nodes(burn: np.ndarray) -> str:
    return f"force {int(burn[0].sum())}, moment {int(burn[1].sum())}"


def structured_finish(problem: Problem, options: DirectOptions, guess: Guess, progress=None,
                      dilate: int = DILATE, resolved: bool = False, rounds: int = ROUNDS) -> tuple[Solution, dict]:
    """The fuel problem on ``problem``'s grid from ``guess`` (a coarser grid's optimum resampled) on its switching
    structure (module docstring).  ``resolved``: the guess is the optimum of a grid that already resolves the
    switching times (a previous level of refinement to an accuracy with more than RESOLVED_FRACTION of this grid's
    steps, :func:`resolves`): its own burn nodes are the structure (not widened), the first solve is the exact
    one (delta EXACT) from IPOPT's own barrier start, neither rough nor pruned (the guard and its widening as
    always), and every solve sees the objective scaled by N / RESOLVED_NODES.  Returns the last Solution (converged
    or not; its cost the L1 cost of its controls; its iterations and times those of every solve) and stats:
    :func:`~.fuel_guard.verdict`'s of its switching values, ``fuel_structure`` (one line per round: the burn nodes,
    each solve's status and iterations, the cost, the largest switching value, where it widened),
    ``fuel_structure_rounds``.  ``rounds``: at most this many rounds (ROUNDS; more for a step of the continuation,
    :mod:`.fuel_continuation`).  ``progress``: each solve's iterations, under 'structured rough', '... pruned',
    '... widened' (a round after the first), '... resolved' (``resolved``'s first), with ' cold' for a retry from
    IPOPT's own start."""
    t0 = time.perf_counter()
    ref = smoothing_reference(problem, guess.U)         # the parts' bounds, an unbounded part's largest magnitude
    per_scale = ref / SmoothTranscription.magnitude_scales(problem)     # a rounding x ref, in the NLP's terms
    burn = burn_structure(problem, guess.U, ref, 0 if resolved else dilate)
    extra = {"obj_scaling_factor": max(1.0, problem.N / RESOLVED_NODES)} if resolved else {}
    log, total = [], {"iterations": 0, "build_s": 0.0}

    def solve(burn, rounding, x0, duals, phase):
        tb = time.perf_counter()
        tr = SmoothTranscription(problem, options, burn=burn, rounding=rounding * per_scale)
        total["build_s"] += time.perf_counter() - tb
        start = tr.initial_point(guess, guess.h) if x0 is None else x0
        said = []
        tries = [(duals, "")] + ([(None, "from IPOPT's own start: ")] if duals is not None else [])
        for warm, prefix in tries:      # a failed warm solve: again, cold (module docstring)
            out, stats = _solve(tr, options, start, warm, progress, extra,
                                f"structured {phase}{' cold' if prefix else ''}")
            its = int(stats.get("iter_count", 0))
            total["iterations"] += its
            status = str(stats.get("return_status", "unknown"))
            said.append(f"{prefix}{status} in {its} iterations")
            if status == "Solve_Succeeded":
                break
        point = tuple(np.array(out[k]).ravel() for k in ("x", "lam_g", "lam_x"))
        return tr, out, stats, point, ", then ".join(said), status == "Solve_Succeeded"

    x0, duals, v = None, None, {}
    for rnd in range(1, rounds + 1):
        rough = duals is None and not resolved
        said = [f"solve {rnd}: burn nodes {_nodes(burn)} of {burn.shape[1]}"]
        tr, out, stats, point, what, ok = solve(burn, ROUGH if rough else EXACT, x0, duals,
                                                "rough" if rough else "resolved" if duals is None else "widened")
        said.append(f"rough (delta {ROUGH:.0e}) {what}" if rough else
                    f"exact on the resolved structure, from IPOPT's own start: {what}" if duals is None else what)
        if ok and (rough or duals is not None):     # the resolved structure's first solve is not pruned
            pruned, x0 = _pruned(tr, point[0], ref)
            duals = (point[1], _released(tr, point[2], pruned))
            if rough or (pruned != tr.burn).any():
                burn = pruned
                tr, out, stats, point, what, ok = solve(burn, EXACT, x0, duals, "pruned")
                said.append(f"pruned to {_nodes(burn)}: {what}")
        sol = nlp_solution(problem, options, tr, out, stats, str(stats.get("return_status", "unknown")), "ipopt",
                           total["build_s"], 0.0)
        if not (ok and sol.converged):
            log.append("; ".join(said))
            break
        x0, duals = point[0], point[1:]
        sw = switching_l1(tr, *point)
        v = verdict(sw)
        log.append(f"{'; '.join(said)}; cost {sol.cost:.10g}, switching function up to {v['fuel_switching_max']:+.1e}")
        if v["fuel_guard"] != "failed":
            break
        burn, x0 = _widened(tr, x0, sw, ref)
        duals = (duals[0], _released(tr, duals[1], burn))
        log[-1] += "; widened at " + "; ".join(f"{part} {', '.join(map(str, sw['nodes'][burn[i] & ~tr.burn[i]]))}"
                                              for i, part in enumerate(PARTS) if (burn[i] & ~tr.burn[i]).any())
    sol.iterations, sol.build_s = total["iterations"], total["build_s"]
    sol.solve_s = time.perf_counter() - t0 - total["build_s"]
    return sol, {**v, "fuel_structure": log, "fuel_structure_rounds": len(log)}


__all__ = ["DILATE", "EXACT", "PRUNE_RTOL", "RESOLVED_FRACTION", "RESOLVED_NODES", "ROUGH", "ROUNDS", "applies",
           "burn_structure", "resolves", "structured_finish", "switching_l1"]
