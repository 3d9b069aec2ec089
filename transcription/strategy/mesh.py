"""Adaptive (non-uniform) meshes for refinement to a tolerance (docs/mathematics.md §16), used by
:func:`transcription.strategy.refine.refine`.

* :func:`local_errors` -- step doubling with the plan's own scheme: step k from X_k taken again as two half steps
  (the LGVI's node controls interpolated, u_{k+1/2} = (u_k + u_{k+1}) / 2; the first-order u_{k+1} held); a local
  error C_k h_k^{p+1} (p the scheme's order) makes the difference to X_{k+1} C_k h_k^{p+1} (1 - 2^-p), so
  e_k = difference / (1 - 2^-p), in the units of the continuous miss (position / L, velocity / V, angle, rate).
* :func:`equidistributed_density` -- with C(t) = e_k / h_k^{p+1} piecewise constant, sum_k C_k h_k^{p+1} is least for
  a given number of steps at h(t) = a C(t)^(-1/p) (equidistribution), where sum_k e_k = a^p T; a is chosen for the
  sum asked.  The node density 1/h(t) per level stays within [1/merge, split] times the old one (:class:`Refinement`)
  and each step's is the largest of its own and its neighbours'.
* :func:`aimed_density` -- the sum asked is the one whose predicted terminal miss, the signed contributions c_k of the
  steps each scaled by its refinement, is the miss aimed at (the cancellations the new mesh keeps counted, not those
  it removes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.state import NZ, unpack_states
from ..geometry.so3 import log_so3_batch


@dataclass(frozen=True)
class Refinement:
    """The parameters of refinement to a tolerance: each level's N (:mod:`.refine`) and adaptive mesh (this module)."""

    #: N of the next level = safety N (miss / tol)^(1/p), at least twice N and at most growth N -- every level, the
    #: adaptive ones too (an adaptive mesh with more steps is coarsened to growth N in its own density, §16)
    safety: float = 1.2
    growth: int = 32
    #: the most an adaptive mesh is credited with over a uniform one of the same order: steps / adaptive_gain (§16)
    adaptive_gain: float = 2.0
    #: per level, a step is split into at most split steps and at most merge steps are merged into one
    split: float = 32.0
    merge: float = 4.0
    max_targets: int = 32   # at most this many violated node intervals (the worst) set the drift's steps of one level
    #: the least share of the path tolerance left to the chords between the nodes, and to the drift before them
    min_share: float = 0.05


def local_errors(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, order: int) -> np.ndarray:
    """The local error z_k (N, 12) of each step of the plan X (N+1, 18), controls U (6, n_controls), step sizes
    ``steps`` (N,), by step doubling (module docstring), in the tangent coordinates [dx; dgamma; zeta; dPi] at
    X_{k+1} (transcription.geometry.state.tangent_basis): two half steps minus the plan's step, over (1 - 2^-p)."""
    disc, N = problem.disc, len(steps)
    W = np.asarray(disc.stage_controls(U), dtype=float)
    if two_point(disc.scheme):
        nu = W.shape[0] // 2
        mid = 0.5 * (W[:nu] + W[nu:])
        Wa, Wb = np.vstack([W[:nu], mid]), np.vstack([mid, W[nu:]])
    else:
        Wa = Wb = W
    F = disc.step.map(N)
    half = 0.5 * np.asarray(steps, dtype=float)[None, :]
    X1, _ = F(X[:-1].T, Wa, half)
    X2, _ = F(X1, Wb, half)
    a, b = unpack_states(X[1:]), unpack_states(np.asarray(X2.full()).T)
    zeta = log_so3_batch(np.einsum("kji,kjl->kil", a.R, b.R))
    return np.hstack([b.x - a.x, b.gamma - a.gamma, zeta, b.Pi - a.Pi]) / (1.0 - 2.0 ** (-order))


def propagated_errors(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The contribution c_k = A_{N-1} ... A_{k+1} z_k (N, 12) of each step's local error z_k to the error of the
    final node, A_j the step's variation in tangent coordinates (Discretization.variation, docs/mathematics.md §4):
    the linearized global error is sum_k c_k (its terminal miss is what refinement drives below the tolerance)."""
    A, N = variations(problem, X, U, steps), len(steps)
    c = np.empty_like(z)
    P = np.eye(NZ)
    for k in range(N - 1, -1, -1):
        c[k] = P @ z[k]
        P = P @ A[k]
    return c


def variations(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """The variation A_k (N, 12, 12) of every step of the plan X (N+1, 18) with controls U and step sizes ``steps``
    (N,): dz_{k+1} = A_k dz_k in the tangent coordinates of transcription.geometry.state.tangent_basis (docs/mathematics.md
    §4, Discretization.variation)."""
    disc, N = problem.disc, len(steps)
    W = np.asarray(disc.stage_controls(U), dtype=float)
    A, _ = disc.variation.map(N)(X[:-1].T, W, np.asarray(steps, dtype=float)[None, :])
    return np.asarray(A.full()).reshape(NZ, N, NZ).transpose(1, 0, 2)   # [k, i, j] = A_k[i, j]


def tangent_norms(c: np.ndarray, problem, L: float, V: float, angle: float = 1.0, rate: float = 1.0) -> np.ndarray:
    """max(|dx| / L, |dgamma| / (m V), |zeta| / angle, |J^-1 dPi| / rate) of tangent vectors c (M, 12) -> (M,): the
    units of the continuous miss (transcription.strategy.refine.scaled_miss: angle = rate = 1), or with the
    maneuver's changes as L, V and angle (and rate = inf: not counted) those of its fraction of the maneuver
    (refine.miss_units)."""
    c = np.atleast_2d(c)
    Jinv = np.linalg.inv(problem.model.inertia)
    return np.max(np.stack([np.linalg.norm(c[:, 0:3], axis=1) / L,
                            np.linalg.norm(c[:, 3:6], axis=1) / (problem.model.mass * V),
                            np.linalg.norm(c[:, 6:9], axis=1) / angle,
                            np.linalg.norm(c[:, 9:12] @ Jinv.T, axis=1) / rate]), axis=0)


def error_estimate(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, order: int, L: float,
                   V: float, angle: float = 1.0, rate: float = 1.0) -> tuple[np.ndarray, float, np.ndarray]:
    """(e (N,), predicted, c (N, 12)): each step's signed contribution c_k to the terminal error
    (:func:`propagated_errors`), its size e_k = |c_k| and the predicted terminal miss |sum_k c_k|, in the units of
    :func:`tangent_norms`."""
    c = propagated_errors(problem, X, U, steps, local_errors(problem, X, U, steps, order))
    return (tangent_norms(c, problem, L, V, angle, rate),
            float(tangent_norms(c.sum(axis=0), problem, L, V, angle, rate)[0]), c)


def equidistributed_density(steps: np.ndarray, errors: np.ndarray, order: int, total: float,
                            rules: Refinement = Refinement()) -> np.ndarray:
    """The node density 1/h(t) (N,) on the old steps h (N,) whose local errors, e (N,) now, sum to about ``total``
    equidistributed in time (module docstring; p = ``order``), bounded to [1/merge, split] times the old one."""
    h = np.asarray(steps, dtype=float)
    e = np.asarray(errors, dtype=float)
    T = float(h.sum())
    C = np.where(np.isfinite(e), e, np.nanmax(e, initial=0.0)) / h ** (order + 1)
    C = np.maximum(C, 1e-12 * max(C.max(initial=0.0), 1e-300))
    C = np.max(np.stack([C, np.r_[C[:1], C[:-1]], np.r_[C[1:], C[-1:]]]), axis=0)   # a neighbour's error counts
    a = (max(total, 1e-300) / T) ** (1.0 / order)
    return np.clip(C ** (1.0 / order) / a, 1.0 / (rules.merge * h), rules.split / h)


def aimed_density(problem, steps: np.ndarray, c: np.ndarray, order: int, aim: float, units: tuple,
                  rules: Refinement = Refinement(), margin: float = 1.0) -> np.ndarray:
    """The node density (N,) of :func:`equidistributed_density` whose predicted terminal miss is ``aim``.  Refined to
    the density rho_k, step k's signed contribution c_k (N, 12) (:func:`propagated_errors`) becomes
    c_k (rho_k h_k)^-p: an order-p scheme's error per unit time goes as h^p (and the LGVI's one error of a step
    holding a control jump, ~ jump h^2, as well).  The predicted miss |sum_k c_k (rho_k h_k)^-p| (:func:`tangent_norms`
    with ``units``: L, V[, angle, rate]) keeps the signs, so it counts the cancellations between the steps' errors
    that the new mesh keeps and not those it removes: a switch's error resolved leaves the smooth part's, which may
    cancel less (docs/mathematics.md §16).  The equidistributed sum is found by bisection in its logarithm.  Where
    even every step split as far as one level may (:class:`Refinement` ``split``) predicts more than ``aim`` (a
    floor): if the floor is within ``aim`` x ``margin`` (the tolerance itself, ``aim`` being it over a safety
    margin), every step is split so (the closest this level comes, within the tolerance); beyond it, the density aims
    at the floor plus ``aim`` -- this level cannot meet the tolerance, so it makes its progress on the fewest steps
    that come within ``aim`` of the floor, and the next level goes on from a plan that resolves more."""
    h = np.asarray(steps, dtype=float)
    e = tangent_norms(c, problem, *units)

    def density(log_total: float) -> np.ndarray:
        return equidistributed_density(h, e, order, float(np.exp(log_total)), rules)

    def predicted(log_total: float) -> float:
        s = (density(log_total) * h) ** (-float(order))
        return float(tangent_norms((c * s[:, None]).sum(axis=0), problem, *units)[0])

    lo, hi = np.log(e.sum()) - 30.0, np.log(e.sum()) + 15.0     # beyond both of the density's bounds
    if predicted(hi) <= aim:
        return density(hi)
    floor = predicted(lo)        # every step split as far as one level may
    if floor > aim * margin:     # the tolerance out of this level's reach: the floor plus the aim, then more levels
        aim = floor + aim
    elif floor > aim:            # within reach only without the margin: as close as this level may come
        return density(lo)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if predicted(mid) <= aim else (lo, mid)
    return density(lo)


def density_steps(steps: np.ndarray, density: np.ndarray) -> np.ndarray:
    """New step sizes over the horizon of the old ``steps`` (N,) with the node density ``density`` (N,) (nodes per
    unit time, constant on each old step): the new nodes where its integral passes the integers (rescaled so
    that the last one is the horizon's end, kept exactly)."""
    h = np.asarray(steps, dtype=float)
    phi = np.r_[0.0, np.cumsum(np.asarray(density, dtype=float) * h)]
    n = max(int(np.ceil(phi[-1] - 1e-9)), 1)
    t_old = np.r_[0.0, np.cumsum(h)]
    t_new = np.interp(np.linspace(0.0, phi[-1], n + 1), phi, t_old)
    t_new[-1] = t_old[-1]
    return np.diff(t_new)


def subdivided_steps(steps: np.ndarray, factor: float) -> np.ndarray:
    """The mesh refined uniformly in its own density: about ``factor`` times as many steps, each old step's
    share kept (refinement for what the local errors do not locate, a path constraint between the nodes)."""
    h = np.asarray(steps, dtype=float)
    n = max(int(np.ceil(factor * len(h))), 1)
    t_old = np.r_[0.0, np.cumsum(h)]
    t_new = np.interp(np.linspace(0.0, len(h), n + 1), np.arange(len(h) + 1), t_old)
    t_new[-1] = t_old[-1]
    return np.diff(t_new)


# ---------------------------------------------------------------- path constraints between the nodes (§16)

def interval_margins(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, scales, samples: int,
                     restart: bool) -> np.ndarray:
    """The margins (n_constraints, N, M) of every path constraint, times ``scales`` (the units of
    transcription.strategy.refine.path_violation), at s = 1/M, ..., 1 of each node interval (M = ``samples``) of the
    plan's controls flown in continuous time (transcription.dynamics.flight): ``restart`` False -- one flight from X_0
    (as the continuous check); True -- each interval from the plan's node X_k (the chord alone, without the drift
    before t_k).  Raises FlightError if a flight fails."""
    from ..dynamics.flight import Actuators, FlightError, OpenLoop, fly, interval_integrator
    from ..dynamics.trajectory import Trajectory

    N, M, model = len(steps), int(samples), problem.model
    law, act = OpenLoop.of_controls(problem.scheme, U), Actuators(force_frame=problem.disc.force_frame)
    if restart:
        fn = interval_integrator(model, M)
        p = np.concatenate([np.linalg.inv(model.inertia).ravel(order="F"), act.vector()])
        try:
            _, Xs = fn.map(N)(X[:-1].T, np.vstack([law.start, law.end, np.asarray(steps, float)[None, :]]),
                              np.repeat(p[:, None], N, axis=1))
        except RuntimeError as e:
            raise FlightError(f"an interval flown from its node failed (CVODES): {str(e).strip()[-200:]}") from None
        Xs = np.asarray(Xs.full()).T                                        # (N M, 18), interval-major
    else:
        Xs = fly(model, X[0], np.r_[0.0, np.cumsum(steps)], law, act, samples=M).X[1:]
    traj = Trajectory(t=np.zeros(len(Xs)), X=Xs, mass=model.mass, inertia=model.inertia)
    return np.stack([c.margin(traj).reshape(N, M) * s for c, s in zip(problem.constraints, scales)])


def margin_gradients(constraint, X: np.ndarray, scale: float, mass: float, inertia: np.ndarray,
                     eps: float = 1e-6) -> np.ndarray:
    """w (K, 12): the gradient of ``constraint``'s margin (times ``scale``) at the states X (K, 18) in the tangent
    coordinates z of transcription.geometry.state.tangent_basis (X + D(X) z), by central differences of size eps (the
    margins are smooth in X; a cone's cosine is linear in R, so R + eps R S(e_i) off SO(3) costs only O(eps^2))."""
    from ..geometry.state import tangent_basis
    from ..dynamics.trajectory import Trajectory

    X = np.atleast_2d(np.asarray(X, float))
    K = X.shape[0]
    D = np.stack([tangent_basis(x) for x in X]).transpose(0, 2, 1)            # (K, 12, 18)
    S = np.concatenate([(X[:, None, :] + eps * D).reshape(-1, 18), (X[:, None, :] - eps * D).reshape(-1, 18)])
    m = constraint.margin(Trajectory(t=np.zeros(len(S)), X=S, mass=mass, inertia=inertia)) * scale
    return (m[:K * NZ] - m[K * NZ:]).reshape(K, NZ) / (2.0 * eps)


def drift_shares(A: np.ndarray, z: np.ndarray, nodes: np.ndarray, w: np.ndarray) -> np.ndarray:
    """S (n, N): S[i, k] = |w_i A_{j-1} ... A_{k+1} z_k| for k < j = nodes[i], 0 for k >= j -- step k's share of the
    flown path's drift at node j seen through the constraint's gradient w_i (12,): the linearized drift of the margin
    at node j is sum_k w_i A_{j-1} ... A_{k+1} z_k (z (N, 12) the local errors, A (N, 12, 12) the variations;
    :func:`propagated_errors` with node j for the final one)."""
    nodes = np.asarray(nodes, int)
    S = np.zeros((len(nodes), len(z)))
    V = np.asarray(w, float).copy()
    for k in range(int(nodes.max(initial=0)) - 1, -1, -1):
        live = nodes > k
        S[:, k] = np.where(live, np.abs(V @ z[k]), 0.0)
        V = np.where(live[:, None], V @ A[k], V)
    return S


def path_density(problem, X: np.ndarray, U: np.ndarray, steps: np.ndarray, order: int, tol: float, scales,
                 samples: int, rules: Refinement = Refinement()) -> np.ndarray | None:
    """The node density (N,) (nodes per unit time on each old step; 0 where nothing is asked) that aims the flown
    path's violation of the path constraints between the nodes at ``tol``; None when no constraint is left by more
    than tol (docs/mathematics.md §16, "Path constraints between the nodes").

    On interval k: v_k (the flight from X_0) = the chord c_k (flown from X_k) + the drift d_k = v_k - c_k of the steps
    before it (:func:`drift_shares`); tol = tol_c + tol_d split by :func:`chord_share`.  A step whose chord (near a
    contact at least its :func:`contact_sagitta`) is over tol_c gets h_k sqrt(tol_c / c_k); before each violated
    interval whose drift is over tol_d (the max_targets worst) the steps equidistribute their drift shares, their sum
    D aimed at tol_d D / d.  The largest density of the rules is kept, on each step and its two neighbours, at most
    split times the old one."""
    h = np.asarray(steps, float)
    gi = interval_margins(problem, X, U, h, scales, samples, restart=False).min(axis=2)
    v, worst = np.maximum(-gi.min(axis=0), 0.0), np.argmin(gi, axis=0)
    gs = interval_margins(problem, X, U, h, scales, samples, restart=True)
    c = np.maximum(-gs.min(axis=(0, 2)), 0.0)
    chord = np.maximum(c, contact_sagitta(problem, X, gs, scales))
    targets = np.argsort(-v)[:rules.max_targets]
    targets = targets[v[targets] > tol]
    if not targets.size:
        over = chord > tol
        return _with_neighbours(np.where(over, np.sqrt(chord / tol) / h, 0.0), h, rules.split) if over.any() else None
    z, A = local_errors(problem, X, U, h, order), variations(problem, X, U, h)
    w = np.vstack([margin_gradients(problem.constraints[worst[k]], X[k + 1], scales[worst[k]], problem.model.mass,
                                    problem.model.inertia) for k in targets])
    S = drift_shares(A, z, targets + 1, w)
    tol_c = chord_share(h, chord, S[0, :targets[0] + 1], order, tol, rules.min_share)
    tol_d = tol - tol_c
    dens = np.where(chord > tol_c, np.sqrt(chord / tol_c) / h, 0.0)
    for i, k in enumerate(targets):
        d, D = v[k] - c[k], S[i, :k + 1]
        if d > tol_d and D.sum() > 0:     # the shares' sum aimed at tol_d D / d: calibrated by the flight's drift
            dens[:k + 1] = np.maximum(dens[:k + 1], equidistributed_density(h[:k + 1], D, order, tol_d * D.sum() / d, rules))
    return _with_neighbours(dens, h, rules.split)


def chord_share(steps: np.ndarray, chord: np.ndarray, shares: np.ndarray, order: int, tol: float,
                min_share: float = Refinement.min_share) -> float:
    """tol_c: the part of ``tol`` for the chords (the rest, tol - tol_c, for the drift) for which the two rules of
    :func:`path_density` need the fewest steps together.  The chords' rule needs N_c = a / sqrt(tol_c) steps,
    a = sum over the steps with a chord of sqrt(c_k); equidistributing the worst interval's drift ``shares`` S_k
    (its first len(shares) steps, of total length T_s) needs N_d = b / tol_d^(1/p), b = T_s^(1/p) sum_k h_k
    (S_k / h_k^(p+1))^(1/p).  For p = 2 the least a / sqrt(tol_c) + b / sqrt(tol - tol_c) is at
    tol_c / tol_d = (a / b)^(2/3); the chords' part is kept within [min_share, 1 - min_share] tol."""
    h = np.asarray(steps, float)
    a = float(np.sqrt(np.maximum(chord, 0.0)).sum())
    hs = h[:len(shares)]
    b = float(hs.sum() ** (1.0 / order) * (hs * (np.asarray(shares) / hs ** (order + 1)) ** (1.0 / order)).sum())
    q = (a / b) ** (2.0 / 3.0) if b > 0 else np.inf
    return tol * float(np.clip(q / (1.0 + q) if np.isfinite(q) else 1.0, min_share, 1.0 - min_share))


def contact_sagitta(problem, X: np.ndarray, gs: np.ndarray, scales) -> np.ndarray:
    """sigma_k (N,): the chord violation a step may have when the re-solved plan's contact falls inside it -- the
    sagitta max_s [(1 - s) g_k + s g_{k+1} - g(s)] of each constraint's margin g over step k flown from the plan's
    node (``gs`` (n_constraints, N, M) of :func:`interval_margins` with restart; g_k the node margins), where
    min(g_k, g_{k+1}) <= the sagitta, at most a neighbouring step's (a contact is two-sided); 0 elsewhere.  Near a
    touch point g(t) ~ a (t - t_c)^2 it is a h_k^2 / 4 (§16)."""
    from ..dynamics.trajectory import Trajectory

    M = gs.shape[2]
    traj = Trajectory(t=np.zeros(len(X)), X=X, mass=problem.model.mass, inertia=problem.model.inertia)
    g = np.stack([c.margin(traj) * s for c, s in zip(problem.constraints, scales)])        # (n_c, N+1)
    sj = np.arange(1, M + 1) / M
    lin = (1.0 - sj) * g[:, :-1, None] + sj * g[:, 1:, None]
    sag = np.max(lin - gs, axis=2)
    sag = np.where(np.minimum(g[:, :-1], g[:, 1:]) <= sag, sag, 0.0)
    side = np.maximum(np.pad(sag[:, :-1], ((0, 0), (1, 0))), np.pad(sag[:, 1:], ((0, 0), (0, 1))))
    return np.max(np.minimum(sag, side), axis=0)


def _with_neighbours(dens: np.ndarray, h: np.ndarray, split: float) -> np.ndarray:
    """Each step's density the largest of its own and its two neighbours' (a contact moves by about a step when
    re-solved), at most split / h_k."""
    return np.minimum(np.max(np.stack([dens, np.r_[dens[:1], dens[:-1]], np.r_[dens[1:], dens[-1:]]]), axis=0),
                      split / h)


__all__ = ["Refinement", "aimed_density", "chord_share", "contact_sagitta", "density_steps", "drift_shares",
           "equidistributed_density", "error_estimate", "interval_margins", "local_errors", "margin_gradients",
           "path_density", "propagated_errors", "subdivided_steps", "tangent_norms", "variations"]
