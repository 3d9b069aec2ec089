"""Initial guesses for the direct method (node states, controls, Cayley vectors; docs/mathematics.md §7, §10).

Starts made from the problem's data (a :class:`~transcription.results.start.Start` whose ``origin`` says which),
selected by :attr:`~transcription.options.DirectOptions.initial_guess` (``'auto'``, the default, lets the objective's
strategy try them in its order):

* ``'rollout'``: free motion (zero controls) of the problem's discretization from X0; only the terminal conditions
  are violated.
* ``'interpolate'``: the SE(3) geodesic (screw motion) g(s) = exp(s log(g_d g_0^-1)) g_0, s = t/T: R(s) = Exp(s w)
  R_0, x(s) = q + Exp(s w)(x_0 - q) + s d n about the screw axis (unit n = w/|w| through q, pitch d = n^T p).
  Momenta: gamma = m dx/dt (inertial), Pi = J R^T w / T (body), plus a linear blend of the endpoint mismatches.
  Zero controls.  At a rotation by exactly pi the axis turns with x_0 x gamma_0 (else with Pi_0, inertial).
* ``'orbit'``: the screw interpolation in a frame turning with the orbit (:func:`orbit_interpolation`).

:func:`perturbed` adds symmetry-breaking controls (time objective); :func:`aimed` turns the body to aim another
start's force (a body-fixed engine).  An orbit target is stood for by
:func:`~transcription.ocp.estimate.target_estimate` (a point of the orbit reached by a Hohmann-like transfer).
"""
from __future__ import annotations

from dataclasses import replace
from itertools import product

import numpy as np

from ..dynamics.lgvi import Discretization
from ..geometry.so3 import exp_so3, log_so3_any, rotation_between
from ..geometry.state import NU, U_FORCE, U_MOMENT, X_ANG, X_ROT, pack_state, unpack_states
from ..ocp import KeepIn, KeepOut, Problem
from ..ocp.estimate import target_estimate
from ..results.start import Origin, Start

KINDS = ("rollout", "interpolate", "orbit")


def _start(problem: Problem, X: np.ndarray, U: np.ndarray | None, origin: Origin, T: float | None = None) -> Start:
    """A Start of node states X on ``problem``'s grid (its node times, scaled to the horizon T when given), controls
    U (zero when None)."""
    t = problem.times if T is None else problem.times * (float(T) / problem.T)
    U = np.zeros((NU, problem.disc.n_controls(problem.N))) if U is None else U
    return Start(t=t, X=X, U=U, scheme=problem.scheme, origin=origin)


def rollout(problem: Problem) -> Start:
    """The free motion of ``problem``'s discretization from X0 over its steps (controls zero)."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.steps, problem.N)
    return _start(problem, X, None, Origin.rollout)


def _rest_to_rest(x: np.ndarray) -> np.ndarray:
    """The fraction of a rest-to-rest turn at constant |acceleration| done at x = t / tau in [0, 1]: 2 x^2, then
    1 - 2 (1 - x)^2."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.5, 2.0 * x**2, 1.0 - 2.0 * (1.0 - x) ** 2)


def _turned_in(problem: Problem, R: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """The attitudes R (N+1, 3, 3) (R[0] the initial one, the others aimed) with the first nodes replaced by the
    rest-to-rest turn from R[0] to the aimed attitude at the turn's end, at angular acceleration ``alpha``: the turn
    takes tau = 2 sqrt(theta / alpha) for its angle theta (found from the aim at node 1, then at tau).  Returns the
    attitudes and the mask of the nodes turning."""
    t = problem.times
    R = R.copy()
    tau = 0.0
    for _ in range(2):
        k = min(int(np.searchsorted(t, tau)), len(t) - 1) if tau > 0 else 1
        w = log_so3_any(R[k] @ R[0].T)
        tau = 2.0 * np.sqrt(np.linalg.norm(w) / alpha)
    turning = t < tau
    turning[0] = False
    sigma = _rest_to_rest(t[turning] / tau)
    R[turning] = np.array([exp_so3(c * w) @ R[0] for c in sigma])
    return R, turning


def aimed(problem: Problem, start: Start, axis: np.ndarray, thrust_range: tuple[float, float], *,
          fraction: float, frame: Discretization | None = None, alpha: float | None = None) -> Start:
    """A body-fixed engine's start from ``start`` (on the problem's grid) whose force points anywhere
    (docs/mathematics.md §14): the attitude turned by min(1, |f_j| / (``fraction`` max |f|)) of the smallest rotation
    taking the engine axis R_j a onto the inertial force f_j = applied_force(R_j, u_f,j) of ``frame`` (the
    discretization ``start`` was solved on: its force frame; the problem's by default); the force then T_j a,
    T_j = |f_j| clipped to ``thrust_range``; Pi_k = J Log(R_k^T R_{k+1}) / h_k (the last node's kept).  With
    ``alpha`` (the angular acceleration the moment's size gives), the body does not jump from its initial attitude
    to the aim: it turns there rest to rest at that acceleration (:func:`_turned_in`), thrusting meanwhile only the
    part of f_j along its engine, T_j = max(0, (R_j a)^T f_j).  The defects are left to the solver."""
    disc, h = problem.disc, problem.steps
    X, U = start.X.copy(), start.U.copy()
    s = unpack_states(X)
    nodes = np.arange(X.shape[0]) if U.shape[1] == X.shape[0] else np.arange(1, X.shape[0])
    f = np.asarray((frame or disc).applied_force(s.R[nodes], U[U_FORCE].T), dtype=float)
    nf = np.linalg.norm(f, axis=1)
    if not nf.max(initial=0.0) > 0:
        return start
    a = np.asarray(axis, dtype=float)
    pointing = np.einsum("nij,j->ni", s.R[nodes], a)
    target = np.where((nf > 0)[:, None], f / np.where(nf > 0, nf, 1.0)[:, None], pointing)
    turn = rotation_between(pointing, target)
    share = np.minimum(1.0, nf / (fraction * nf.max()))
    partial = np.array([exp_so3(w * c) for w, c in zip(np.array([log_so3_any(Q) for Q in turn]), share)])
    R = s.R.copy()
    R[nodes] = np.einsum("nij,njk->nik", partial, s.R[nodes])
    thrust = nf
    if alpha is not None and alpha > 0:
        R[0] = s.R[0]
        R, turning = _turned_in(problem, R, alpha)
        along = np.einsum("nij,j,ni->n", R[nodes], a, f)
        thrust = np.where(turning[nodes], np.maximum(along, 0.0), nf)
    hs = np.broadcast_to(np.asarray(h, dtype=float), (len(R) - 1,))     # one step size, or a mesh's h_k
    Omega = np.array([log_so3_any(R[k].T @ R[k + 1]) / hs[k] for k in range(len(R) - 1)])
    X[:, X_ROT] = np.swapaxes(R, 1, 2).reshape(len(R), 9)
    X[:-1, X_ANG] = Omega @ np.asarray(disc.J).T
    U[U_FORCE] = np.outer(a, np.clip(thrust, *thrust_range))
    return Start(t=start.t, X=X, U=U, scheme=start.scheme, origin=Origin.aimed, source=start.source)


def rotation_geodesic(Ra: np.ndarray, w: np.ndarray, f: np.ndarray, J: np.ndarray, duration: float):
    """The attitudes Exp(f_k w) Ra (len(f), 3, 3) along the geodesic from Ra by the inertial rotation vector w at
    fractions f of it, turned at the constant rate w / ``duration``, and their body angular momenta
    Pi_k = J R_k^T w / duration (len(f), 3)."""
    Rs = np.array([exp_so3(c * w) @ Ra for c in f])
    return Rs, np.einsum("ij,kjl,l->ki", J, np.swapaxes(Rs, 1, 2), w / duration)


def screw_path(X0: np.ndarray, Xd: np.ndarray, s: np.ndarray, mass: float, J: np.ndarray, T: float) -> np.ndarray:
    """SE(3) geodesic between the configurations of X0 and Xd at s in [0, 1] (module docstring): states (len(s), 18)."""
    a, d = unpack_states(X0), unpack_states(Xd)
    x0, xd, R0, Rd = a.x[0], d.x[0], a.R[0], d.R[0]
    Rrel = Rd @ R0.T                       # inertial-frame relative rotation
    prefer = np.cross(x0, a.gamma[0])
    if np.linalg.norm(prefer) < 1e-12:
        prefer = R0 @ a.Pi[0]
    w = log_so3_any(Rrel, prefer)           # inertial rotation vector of the whole motion
    theta = np.linalg.norm(w)
    p = xd - Rrel @ x0                      # y -> Rrel y + p maps x0 to xd
    s = np.asarray(s, dtype=float)
    if theta < 1e-9:
        n = np.zeros(3)
        q = np.zeros(3)
        xs = x0[None, :] + s[:, None] * p[None, :]
        vs = np.repeat(p[None, :] / T, len(s), axis=0)
    else:
        n = w / theta
        dpitch = n @ p
        p_perp = p - dpitch * n
        q = np.linalg.lstsq(np.eye(3) - Rrel, p_perp, rcond=1e-10)[0]
        q = q - (n @ q) * n
        Es = np.array([exp_so3(si * w) for si in s])
        xs = q[None, :] + Es @ (x0 - q) + s[:, None] * dpitch * n[None, :]
        vs = np.cross(w / T, xs - q[None, :]) + (dpitch / T) * n[None, :]
    Rs, Pis = rotation_geodesic(R0, w, s, J, T)
    gam = mass * vs
    # blend the endpoint mismatches away linearly
    g_a, g_b = a.gamma[0] - gam[0], d.gamma[0] - gam[-1]
    P_a, P_b = a.Pi[0] - Pis[0], d.Pi[0] - Pis[-1]
    gam = gam + (1 - s)[:, None] * g_a + s[:, None] * g_b
    Pis = Pis + (1 - s)[:, None] * P_a + s[:, None] * P_b
    return pack_state(xs, gam, Rs, Pis)


def interpolation(problem: Problem, T: float | None = None) -> Start:
    """The SE(3) screw interpolation from X0 to the target (:func:`~transcription.ocp.estimate.target_estimate`) at
    the nodes of ``problem``'s grid over the horizon T (the problem's by default); zero controls."""
    T = problem.T if T is None else float(T)
    s = problem.times / problem.T
    X = screw_path(problem.X0, target_estimate(problem), s, problem.model.mass, problem.disc.J, T)
    return _start(problem, X, None, Origin.interpolate, T)


def orbit_axis(X0: np.ndarray) -> np.ndarray | None:
    """The unit orbit normal x_0 x gamma_0 / |x_0 x gamma_0| of X0 (None when the initial motion is radial or at
    rest)."""
    a = unpack_states(X0)
    h = np.cross(a.x[0], a.gamma[0])
    return h / np.linalg.norm(h) if np.linalg.norm(h) > 1e-12 * max(np.linalg.norm(a.x[0]), 1e-300) else None


def orbit_turn(X0: np.ndarray, Xd: np.ndarray, T: float, mu: float) -> float | None:
    """The angle Phi the orbit turns in T (radians about :func:`orbit_axis`): the in-plane angle from x_0 to x_d
    plus the whole revolutions 2 pi k that bring it nearest to the free motion's angle over T, the integral of
    the circular mean motion sqrt(mu / r^3) along r linear from |x_0| to |x_d| (None without an orbit normal)."""
    n = orbit_axis(X0)
    if n is None or not mu:
        return None
    x0, xd = unpack_states(X0).x[0], unpack_states(Xd).x[0]
    base = np.arctan2(n @ np.cross(x0, xd), x0 @ xd - (n @ x0) * (n @ xd)) % (2 * np.pi)
    r = np.linspace(np.linalg.norm(x0), np.linalg.norm(xd), 65)
    free = T * float(np.mean(np.sqrt(mu / r ** 3)))
    return float(base + 2 * np.pi * max(0, round((free - base) / (2 * np.pi))))


def orbit_interpolation(problem: Problem) -> Start | None:
    """The screw interpolation (:func:`screw_path`) in the frame Q(phi) turning about the orbit normal n, turned back
    (docs/mathematics.md §10): x = Q x', R = Q R', gamma = Q (gamma' + m phi' n x x'), Pi = Pi' + J R'^T n phi', the
    primed path from X0 to Q(Phi)^T X_d (momenta relative to the frame), phi advancing at the circular mean motion
    sqrt(mu / |x'|^3) scaled to the total turn Phi (:func:`orbit_turn`); zero controls.  It follows the orbits over
    several revolutions.  None without a central body or an orbit normal."""
    disc, X0, Xd, T = problem.disc, problem.X0, target_estimate(problem), problem.T
    Phi = orbit_turn(X0, Xd, T, disc.model.mu)
    if Phi is None:
        return None
    n, m, J = orbit_axis(X0), disc.model.mass, np.asarray(disc.J)
    s = problem.times / T
    a, d = unpack_states(X0), unpack_states(Xd)
    Qd = exp_so3(-Phi * n)
    xdr, Rdr = d.x[0] @ Qd.T, Qd @ d.R[0]
    path = screw_path(X0, pack_state(xdr, d.gamma[0], Rdr, d.Pi[0]), s, m, J, T)   # its positions only
    speed = np.sqrt(disc.model.mu / np.maximum(np.linalg.norm(path[:, :3], axis=1), 1e-300) ** 3)
    mid = 0.5 * (speed[1:] + speed[:-1]) * np.diff(s)          # the mean motion integrated over each step / T
    phi = Phi * np.concatenate([[0.0], np.cumsum(mid)]) / np.sum(mid)
    rate = speed * Phi / (T * np.sum(mid))        # d phi / dt at the nodes
    ends = [pack_state(x, g - m * w * np.cross(n, x), R, P - J @ R.T @ n * w)     # momenta relative to the frame
            for x, g, R, P, w in ((a.x[0], a.gamma[0], a.R[0], a.Pi[0], rate[0]),
                                  (xdr, d.gamma[0] @ Qd.T, Rdr, d.Pi[0], rate[-1]))]
    rel = unpack_states(screw_path(*ends, s, m, J, T))
    Q = np.array([exp_so3(p * n) for p in phi])
    x = np.einsum("kij,kj->ki", Q, rel.x)
    gam = np.einsum("kij,kj->ki", Q, rel.gamma + m * rate[:, None] * np.cross(n, rel.x))
    R = np.einsum("kij,kjl->kil", Q, rel.R)
    Pi = rel.Pi + np.einsum("ij,kjl,l->ki", J, np.swapaxes(rel.R, 1, 2), n) * rate[:, None]
    return _start(problem, pack_state(x, gam, R, Pi), None, Origin.orbit)


def implied_effort(disc, X: np.ndarray, h, W: np.ndarray) -> tuple[float, float]:
    """The efforts sum_k h_k (1/2) u^T W u of the force and of the moment (W: 6x6, force then moment) that fly the
    path X (N+1, 18) in the continuous equations, by finite differences (h: the step size or the N h_k;
    docs/mathematics.md §10): node velocities v_k = (x_{k+1} - x_{k-1}) / (h_{k-1} + h_k) and body rates Omega_k =
    (Log(R_{k-1}^T R_k) / h_{k-1} + Log(R_k^T R_{k+1}) / h_k) / 2 (gamma / m and J^-1 Pi at the ends); at the step
    midpoints u_f = m dv/dt + m mu x / |x|^3 (no J2) and u_m = J dOmega/dt - J Omega x Omega (no gravity-gradient
    torque).  A cheap judge of interpolated starts that all meet the target."""
    st = unpack_states(X)
    m, J, mu = disc.model.mass, np.asarray(disc.J, float), disc.model.mu or 0.0
    hk = np.broadcast_to(np.asarray(h, float), (X.shape[0] - 1,))
    v = np.vstack([st.gamma[:1] / m, (st.x[2:] - st.x[:-2]) / (hk[1:] + hk[:-1])[:, None], st.gamma[-1:] / m])
    step = np.array([log_so3_any(a.T @ b) for a, b in zip(st.R[:-1], st.R[1:])]) / hk[:, None]   # (N, 3) rates
    Jinv = np.linalg.inv(J)
    Om = np.vstack([st.Pi[:1] @ Jinv.T, 0.5 * (step[1:] + step[:-1]), st.Pi[-1:] @ Jinv.T])
    x, Om_mid = 0.5 * (st.x[1:] + st.x[:-1]), 0.5 * (Om[1:] + Om[:-1])
    f = m * np.diff(v, axis=0) / hk[:, None]
    if mu:
        f = f + m * mu * x / np.maximum(np.linalg.norm(x, axis=1), 1e-300)[:, None] ** 3
    u = np.diff(Om, axis=0) @ J.T / hk[:, None] - np.cross(Om_mid @ J.T, Om_mid)
    W = np.asarray(W, float)
    return (float(0.5 * np.einsum("k,ki,ij,kj->", hk, f, W[U_FORCE, U_FORCE], f)),
            float(0.5 * np.einsum("k,ki,ij,kj->", hk, u, W[U_MOMENT, U_MOMENT], u)))


def perturbed(problem: Problem, size: np.ndarray, seed: int = 0, T: float | None = None,
              base: Start | None = None) -> Start:
    """The screw interpolation (over the horizon T, the problem's by default; or the start ``base``) with controls
    drawn (seeded, normal) at the size ``size`` (6,) of each control component (their bounds; 0 for a removed
    control).  It breaks the symmetry of the eigenaxis maneuver, a stationary point of the time-optimal problem
    (docs/mathematics.md §10)."""
    g = interpolation(problem, T) if base is None else base
    rng = np.random.default_rng(seed)
    size = np.asarray(size, float)[:, None]
    return Start(t=g.t, X=g.X, U=np.clip(size * rng.standard_normal(g.U.shape), -size, size), scheme=g.scheme,
                 origin=Origin.interpolate)


def obstacles(problem: Problem) -> list[tuple[int, np.ndarray, float, np.ndarray]]:
    """The fixed-direction cones of ``problem``'s path constraints as regions the body axis must avoid: (index in
    problem.constraints, unit axis s, half-angle alpha (rad), body axis b); a keep-out cone (d, a) is itself, a
    keep-in cone (d, a) avoids the cone (-d, 180 deg - a).  Cones about a moving direction are left out."""
    out = []
    for i, c in enumerate(problem.constraints):
        if isinstance(c, (KeepOut, KeepIn)) and not c.moving:
            d, a = np.asarray(c.direction, float), np.radians(c.angle_deg)
            out.append((i, d, a) if isinstance(c, KeepOut) else (i, -d, np.pi - a))
            out[-1] += (np.asarray(c.body_axis, float),)
    return out


def closest_approach(problem: Problem, R: np.ndarray) -> list[tuple[int, int, float]]:
    """For each obstacle (:func:`obstacles`) along attitudes R (N+1, 3, 3): (its index, the node k nearest its axis,
    the least angle (rad) from its axis), in the order of the obstacles."""
    out = []
    for i, s, alpha, b in obstacles(problem):
        ang = np.arccos(np.clip(np.einsum("kij,j,i->k", R, b, s), -1.0, 1.0))
        k = int(np.argmin(ang))
        out.append((i, k, float(ang[k])))
    return out


def _waypoint(Rk: np.ndarray, Rprev: np.ndarray, Rnext: np.ndarray, s: np.ndarray, alpha: float, b: np.ndarray,
              side: int, clearance: float) -> np.ndarray:
    """The attitude Rk turned so that its body axis p = Rk b lies ``clearance`` (rad) outside the cone (s, alpha) on
    the ``side`` (+1: the side of s where p already is; -1: the opposite side), by the smallest rotation."""
    p = Rk @ b
    d = p - (p @ s) * s
    if np.linalg.norm(d) < 1e-6:          # through the axis: the sides lie across the path's direction
        d = np.cross(s, Rnext @ b - Rprev @ b)
    d = d / max(np.linalg.norm(d), 1e-300)
    q = np.cos(alpha + clearance) * s + side * np.sin(alpha + clearance) * d
    return rotation_between(p[None], q[None])[0] @ Rk


def detour(problem: Problem, sides: dict[int, int], clearance: float, T: float | None = None) -> Start:
    """The screw interpolation (:func:`interpolation`, over T) with its attitude routed round the cones of ``sides``
    ({index in problem.constraints: +1 the near side, -1 the far side}): a waypoint where the straight path passes
    nearest each cone's axis (:func:`closest_approach`), turned ``clearance`` (rad) outside the cone on that side
    (:func:`_waypoint`), joined by geodesics R(t) = Exp(f Log(R_b R_a^T)) R_a at constant rate between the waypoints'
    nodes; Pi = J R^T w / dt on each piece (body), the endpoint mismatches blended away as in :func:`screw_path`.
    Positions and linear momenta as the interpolation's; zero controls.  One start per homotopy class of the path
    round the cones (which side of each)."""
    g = interpolation(problem, T)
    st = unpack_states(g.X)
    R, J, t = st.R, np.asarray(problem.disc.J, float), g.t
    cones = {i: (s, a, b) for i, s, a, b in obstacles(problem)}
    anchors = [(0, R[0])]
    for i, k, _ in sorted(closest_approach(problem, R), key=lambda c: c[1]):
        if i in sides and 0 < k < len(R) - 1 and k > anchors[-1][0]:
            anchors.append((k, _waypoint(R[k], R[k - 1], R[k + 1], *cones[i], sides[i], clearance)))
    anchors.append((len(R) - 1, R[-1]))
    Rn, Pi = R.copy(), np.zeros_like(st.Pi)
    for (ka, Ra), (kb, Rb) in zip(anchors[:-1], anchors[1:]):
        Rn[ka:kb + 1], Pi[ka:kb + 1] = rotation_geodesic(Ra, log_so3_any(Rb @ Ra.T),
                                                         (t[ka:kb + 1] - t[ka]) / (t[kb] - t[ka]), J, t[kb] - t[ka])
    a, d = unpack_states(problem.X0), unpack_states(target_estimate(problem))
    f = (t - t[0]) / (t[-1] - t[0])
    Pi = Pi + (1 - f)[:, None] * (a.Pi[0] - Pi[0]) + f[:, None] * (d.Pi[0] - Pi[-1])
    return replace(g, X=pack_state(st.x, st.gamma, Rn, Pi))


def cone_classes(problem: Problem, reach_deg: float, most: int) -> list[tuple[tuple[int, int], ...]]:
    """The homotopy classes of the attitude path round the cones the straight (screw) path passes within
    ``reach_deg`` of (:func:`closest_approach`): every choice of a side (+1 near, -1
    far) for each, as ((constraint index, side), ...), at most ``most`` of them (the cones nearest the path first);
    [] when no cone is in the way.  A cone the path is nearest at one of its ends is left out: :func:`detour` has no
    node to route there, so its sides would be one start.  How many turns round a cone is not enumerated."""
    R = unpack_states(interpolation(problem).X).R
    near = {i: a for i, _, a, _ in obstacles(problem)}
    close = sorted((ang - near[i], i) for i, k, ang in closest_approach(problem, R)
                   if ang < near[i] + np.radians(reach_deg) and 0 < k < len(R) - 1)
    idx = [i for _, i in close][:max(0, int(np.log2(max(most, 1))))]
    return [tuple(zip(idx, sides)) for sides in product((1, -1), repeat=len(idx))] if idx else []


def class_name(problem: Problem, sides: tuple[tuple[int, int], ...]) -> str:
    """The words of one homotopy class (:func:`cone_classes`): 'keep_out 1 on the near side, ...' (1-based)."""
    return ", ".join(f"{problem.constraints[i].kind} {i + 1} on the {'near' if s > 0 else 'far'} side" for i, s in sides)


def make(kind: str, problem: Problem) -> Start:
    """Dispatch on ``kind`` in :data:`KINDS`: the free motion, the screw interpolation, or the screw interpolation
    turning with the orbit ('orbit'; without a central body or an orbit normal: the screw interpolation)."""
    if kind == "rollout":
        return rollout(problem)
    if kind == "interpolate":
        return interpolation(problem)
    if kind == "orbit":   # without a central body (or an orbit normal) the turning frame stands still
        return orbit_interpolation(problem) or interpolation(problem)
    raise ValueError(f"initial_guess must be one of {', '.join(KINDS)}, got {kind!r}")


__all__ = ["KINDS", "aimed", "class_name", "closest_approach", "cone_classes", "detour", "implied_effort", "obstacles", "interpolation", "make", "orbit_interpolation", "orbit_turn",
           "perturbed", "rollout", "screw_path"]
