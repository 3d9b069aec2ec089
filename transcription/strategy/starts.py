"""Initial guesses for the direct method (node states, controls, Cayley vectors).

Two kinds, selected by :attr:`~transcription.options.DirectOptions.initial_guess` (``'auto'``, the
default, tries them in the order of :func:`transcription.strategy.plan.guess_plan`):

* ``'rollout'``: free motion (all controls zero) of the problem's own
  discretization from X0.  Every node then satisfies the discrete dynamics exactly,
  so only the terminal conditions are violated at the start.
* ``'interpolate'``: the geodesic (screw motion) of SE(3) between the initial and
  the desired configuration, g(s) = exp(s log(g_d g_0^-1)) g_0 with s = t/T,
  i.e. R(s) = Exp(s w) R_0 and x(s) = q + Exp(s w)(x_0 - q) + s d n about the
  screw axis (unit n = w/|w| through q, pitch d = n^T p).  For a half orbit
  (x_0 = -x_d, R_d = Rz(180) R_0) this is the circular arc, not the straight chord
  through the attracting centre.  Momenta are the kinematic ones of that motion,
  gamma = m dx/dt (inertial) and Pi = J R^T w / T (body), plus a linear blend of
  the endpoint mismatches so that they equal the given momenta at s = 0 and s = 1.
  Controls are zero.  At a rotation by exactly pi the sign of the axis is
  ambiguous; the one turning with the initial orbital angular momentum
  x_0 x gamma_0 (or, failing that, with Pi_0 in the inertial frame) is chosen.

For the time objective :func:`perturbed_interpolation_guess` adds symmetry-breaking controls.
For an orbit target, which has no single terminal state, :func:`target_estimate` stands for it
(a point of the orbit reached by a Hohmann-like transfer, :func:`relaxed_start_target`): the
scales of the direct method, its guesses and the impulsive method's feasible start aim at it.
All return a :class:`Guess`; Cayley vectors are c_k = cay^-1(R_k^T R_{k+1})
(docs/mathematics.md §2), consistent with the node attitudes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.state import NU, U_FORCE, U_MOMENT, X_ANG, X_ROT, pack_state, unpack_states
from ..geometry.so3 import exp_so3, log_so3_any, rotation_between, step_cayley_vectors
from ..ocp import Problem, TargetOrbit, TargetRendezvous, TargetState, orbit_conditions, rendezvous_state


@dataclass(frozen=True)
class Guess:
    """X: (N+1, 18) node states; U: (6, n_controls) controls; C: (N, 3) Cayley vectors of the steps;
    iterations and seconds spent making it, and on what (``prepared_on``: a guess that is the solution of a
    relaxed problem or of a coarser grid); h: its step size (a free final time; None: the problem's)."""

    X: np.ndarray
    U: np.ndarray
    C: np.ndarray
    iterations: int = 0
    seconds: float = 0.0
    prepared_on: str = ""
    h: float | None = None
    #: what the solve that made it reports on to the Solution of this one (the multistart's spread)
    stats: dict = field(default_factory=dict)
    #: the primal-dual point of the NLP that made it, (nlp_key, x, lam_g, lam_x) scaled as that NLP's: it starts
    #: IPOPT on an NLP of the same key (the fuel homotopy's last smoothed level: same scales and structure)
    duals: tuple | None = None


def cayley_vectors(X: np.ndarray) -> np.ndarray:
    """c_k = cay^-1(R_k^T R_{k+1}) (N, 3) of node states X (N+1, 18): consistent with the attitudes
    (:func:`~transcription.geometry.so3.step_cayley_vectors`)."""
    return step_cayley_vectors(unpack_states(X).R)


def warm_guess(warm) -> Guess:
    """The Guess of a warm start (a :class:`~transcription.results.start.WarmStart`, fitted to the problem's grid:
    :meth:`~transcription.results.start.WarmStart.fit`): its nodes, controls and Cayley vectors, with its step size."""
    return Guess(X=warm.X, U=warm.U, C=cayley_vectors(warm.X), h=warm.h)


def rollout_guess(disc, X0: np.ndarray, N: int, h) -> Guess:
    """Free motion of ``disc`` from X0 over N steps of size h (or the N sizes h_k of a mesh; controls zero)."""
    X, _ = disc.simulate(X0, None, h, N)
    return Guess(X=X, U=np.zeros((NU, disc.n_controls(N))), C=cayley_vectors(X))


#: aimed_guess turns the body fully where |f_j| >= this fraction of max_j |f_j|, proportionally below
AIM_FRACTION = 0.1


def aimed_guess(disc, guess: Guess, axis: np.ndarray, thrust_range: tuple[float, float], h: float) -> Guess:
    """A body-fixed engine's start from a guess whose force points anywhere (the problem's solution without the
    engine): its inertial force f_j = applied_force(R_j, u_f,j) kept, the attitude turned by the smallest
    rotation taking the engine axis R_j a onto f_j / |f_j| (by a fraction min(1, |f_j| / (AIM_FRACTION max |f|))
    of its angle, so that a vanishing force leaves the attitude as it was), the force then T_j a with T_j = |f_j|
    clipped to ``thrust_range``; Pi from the new attitudes (Pi_k = J Log(R_k^T R_{k+1}) / h, the last node's
    kept).  A control at node j of the first-order scheme belongs to node j = 1..N.  The dynamics' defects are
    not zero: the solver closes them."""
    X, U = guess.X.copy(), guess.U.copy()
    s = unpack_states(X)
    nodes = np.arange(X.shape[0]) if U.shape[1] == X.shape[0] else np.arange(1, X.shape[0])
    f = np.asarray(disc.applied_force(s.R[nodes], U[U_FORCE].T), dtype=float)
    nf = np.linalg.norm(f, axis=1)
    if not nf.max(initial=0.0) > 0:
        return guess
    a = np.asarray(axis, dtype=float)
    pointing = np.einsum("nij,j->ni", s.R[nodes], a)
    target = np.where((nf > 0)[:, None], f / np.where(nf > 0, nf, 1.0)[:, None], pointing)
    turn = rotation_between(pointing, target)
    share = np.minimum(1.0, nf / (AIM_FRACTION * nf.max()))
    partial = np.array([exp_so3(w * c) for w, c in zip(np.array([log_so3_any(Q) for Q in turn]), share)])
    R = s.R.copy()
    R[nodes] = np.einsum("nij,njk->nik", partial, s.R[nodes])
    hs = np.broadcast_to(np.asarray(h, dtype=float), (len(R) - 1,))     # one step size, or a mesh's h_k
    Omega = np.array([log_so3_any(R[k].T @ R[k + 1]) / hs[k] for k in range(len(R) - 1)])
    X[:, X_ROT] = np.swapaxes(R, 1, 2).reshape(len(R), 9)
    X[:-1, X_ANG] = Omega @ np.asarray(disc.J).T
    U[U_FORCE] = np.outer(a, np.clip(nf, *thrust_range))
    return Guess(X=X, U=U, C=cayley_vectors(X), iterations=guess.iterations, seconds=guess.seconds,
                 prepared_on=guess.prepared_on, h=guess.h)


def screw_path(X0: np.ndarray, Xd: np.ndarray, s: np.ndarray, mass: float, J: np.ndarray, T: float) -> np.ndarray:
    """SE(3) geodesic between the configurations of X0 and Xd at parameters s in [0, 1].

    Returns node states (len(s), 18): see the module docstring for the momenta.
    """
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
    Rs = np.array([exp_so3(si * w) @ R0 for si in s])
    gam = mass * vs
    Pis = np.einsum("ij,kjl,l->ki", J, np.swapaxes(Rs, 1, 2), w / T)
    # blend the endpoint mismatches away linearly
    g_a, g_b = a.gamma[0] - gam[0], d.gamma[0] - gam[-1]
    P_a, P_b = a.Pi[0] - Pis[0], d.Pi[0] - Pis[-1]
    gam = gam + (1 - s)[:, None] * g_a + s[:, None] * g_b
    Pis = Pis + (1 - s)[:, None] * P_a + s[:, None] * P_b
    return pack_state(xs, gam, Rs, Pis)


def interpolation_guess(disc, X0: np.ndarray, Xd: np.ndarray, N: int, T: float, s: np.ndarray | None = None) -> Guess:
    """SE(3) screw interpolation from X0 to Xd at the N+1 nodes t_k = k T / N (``s``: the normalized node times
    t_k / T of a non-uniform mesh); zero controls."""
    s = np.linspace(0.0, 1.0, N + 1) if s is None else np.asarray(s, dtype=float)
    X = screw_path(X0, Xd, s, disc.model.mass, disc.J, T)
    return Guess(X=X, U=np.zeros((NU, disc.n_controls(N))), C=cayley_vectors(X))


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


def orbit_interpolation_guess(disc, X0: np.ndarray, Xd: np.ndarray, N: int, T: float,
                              s: np.ndarray | None = None) -> Guess | None:
    """The screw interpolation (:func:`screw_path`) taken in the frame Q(phi) turning about the orbit normal n
    with the orbit, then turned back: x = Q x', R = Q R', gamma = Q (gamma' + m phi' n x x'), Pi = Pi' + J R'^T n
    phi', where the primed path runs from X0 to Q(Phi)^T X_d (momenta relative to the turning frame) and phi
    advances at the circular mean motion sqrt(mu / |x'|^3), scaled to the total turn Phi (:func:`orbit_turn`);
    zero controls.  Why: over several revolutions the screw interpolation between the end configurations turns
    once at most (the five-orbit phasing: a quarter turn in five periods, held against gravity), while this
    path follows the orbits -- for a transfer between near-circular orbits a spiral.  ``s``: the normalized node
    times of a non-uniform mesh (None: uniform).  None without a central body or an orbit normal."""
    Phi = orbit_turn(X0, Xd, T, disc.model.mu)
    if Phi is None:
        return None
    n, m, J = orbit_axis(X0), disc.model.mass, np.asarray(disc.J)
    s = np.linspace(0.0, 1.0, N + 1) if s is None else np.asarray(s, float)
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
    X = pack_state(x, gam, R, Pi)
    return Guess(X=X, U=np.zeros((NU, disc.n_controls(N))), C=cayley_vectors(X))


def implied_effort(disc, X: np.ndarray, h, W: np.ndarray) -> tuple[float, float]:
    """The efforts sum_k h_k (1/2) u^T W u of the force and of the moment (W: 6x6, force then moment; each part
    with its own block) that fly the path of node states X (N+1, 18) in the continuous equations, by finite
    differences of the path's own motion (h: the step size, or the N step sizes h_k of a mesh): node velocities
    v_k = (x_{k+1} - x_{k-1}) / (h_{k-1} + h_k) and body rates Omega_k = (Log(R_{k-1}^T R_k) / h_{k-1} +
    Log(R_k^T R_{k+1}) / h_k) / 2, the given ones gamma / m and J^-1 Pi at the two ends; at the step midpoints
    u_f = m dv/dt + m mu x / |x|^3 (the point-mass attraction; no J2) and u_m = J dOmega/dt - J Omega x Omega
    (no gravity-gradient torque).  A cheap judge of interpolated starts that all meet the target (a rollout
    needs no control and misses it instead): the start a solver has least to change; the ends count, so a path
    that does not move as the body moves at its ends pays for the jump."""
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


def perturbed_interpolation_guess(disc, X0: np.ndarray, Xd: np.ndarray, N: int, T: float, size: np.ndarray,
                                  seed: int = 0, s: np.ndarray | None = None) -> Guess:
    """The screw interpolation with controls drawn (seeded, normal) at the size ``size`` (6,) of
    each control component (their bounds; 0 for a removed control).

    Why (time-optimal slews): the eigenaxis maneuver -- the screw motion driven about one axis --
    is a stationary point of the time-optimal problem whatever its optimality, because every
    off-axis control has zero gradient there; an exactly symmetric start stays on it (measured:
    the asymmetric slew of configs/slew_time_optimal.yaml ends at the eigenaxis time 34.31 from
    the plain interpolation, at 28.625 from this guess for 8 of 8 seeds at N = 100).
    """
    g = interpolation_guess(disc, X0, Xd, N, T, s)
    rng = np.random.default_rng(seed)
    U = np.clip(np.asarray(size, float)[:, None] * rng.standard_normal(g.U.shape), -np.asarray(size)[:, None],
                np.asarray(size)[:, None])
    return Guess(X=g.X, U=U, C=g.C)


def make_guess(kind: str, disc, X0: np.ndarray, Xd: np.ndarray, N: int, T: float, s: np.ndarray | None = None) -> Guess:
    """Dispatch on ``kind`` in {'rollout', 'interpolate', 'orbit'} ('orbit' without a central body: the screw
    interpolation); ``s``: the normalized node times of a non-uniform mesh (None: uniform), the rollout then
    taking the steps T (s_{k+1} - s_k)."""
    if kind == "rollout":
        return rollout_guess(disc, X0, N, T / N if s is None else T * np.diff(s))
    if kind == "interpolate":
        return interpolation_guess(disc, X0, Xd, N, T, s)
    if kind == "orbit":   # without a central body (or an orbit normal) the turning frame stands still
        return orbit_interpolation_guess(disc, X0, Xd, N, T, s) or interpolation_guess(disc, X0, Xd, N, T, s)
    raise ValueError(f"initial_guess must be 'rollout', 'interpolate' or 'orbit', got {kind!r}")


# ------------------------------------------------------------------ orbit targets


def _transfer_angle(r0: float, r1: float, mu: float, T: float) -> float:
    """Angle travelled in time T on the Hohmann-type ellipse from radius r0 towards r1.

    Starts at periapsis (r0 <= r1) or apoapsis; Kepler's equation by Newton.
    """
    a = 0.5 * (r0 + r1)
    e = abs(r1 - r0) / (r1 + r0)
    n = np.sqrt(mu / a**3)
    M0 = 0.0 if r0 <= r1 else np.pi

    def true_anomaly(M):
        E = M
        for _ in range(50):
            E -= (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        return 2.0 * np.arctan2(np.sqrt(1 + e) * np.sin(E / 2), np.sqrt(1 - e) * np.cos(E / 2))

    return float(np.mod(true_anomaly(M0 + n * T) - true_anomaly(M0), 2 * np.pi))


def relaxed_start_target(problem: Problem) -> np.ndarray:
    """A point of the relaxed terminal set to aim the feasibility TPBVP at (18-vector).

    x_N: on the target orbit, at the Hohmann transfer angle (:func:`_transfer_angle`) from the
    projection of x_0 onto the orbit plane, turning with the initial orbital motion; R_N: the body
    axis along +-e_n (the sign closer to R_0 b), another body axis radial.  Momenta: those
    required after the terminal impulse.
    """
    target: TargetOrbit = problem.terminal
    n, a, _ = target.plane_basis()
    s0 = unpack_states(problem.X0)
    x0, g0, R0 = s0.x[0], s0.gamma[0], s0.R[0]
    xp = x0 - (n @ x0) * n
    xp = xp / np.linalg.norm(xp) if np.linalg.norm(xp) > 1e-12 else a
    sigma = 1.0 if n @ np.cross(x0, g0) >= 0 else -1.0
    nu = _transfer_angle(float(np.linalg.norm(x0)), float(target.radius), problem.model.mu, problem.T)
    c, s = np.cos(sigma * nu), np.sin(sigma * nu)
    xN = float(target.radius) * (c * xp + s * np.cross(n, xp))
    # inertial frame (e_axis, radial, their cross product) carried by the body frame (b, b2, b x b2)
    e_axis = n if n @ (R0 @ target.body_axis) >= 0 else -n
    e_rad = xN / np.linalg.norm(xN)
    b = target.body_axis
    b2 = np.eye(3)[int(np.argmin(np.abs(b)))]
    b2 = b2 - (b2 @ b) * b
    b2 /= np.linalg.norm(b2)
    RN = np.column_stack([e_axis, e_rad, np.cross(e_axis, e_rad)]) @ np.column_stack([b, b2, np.cross(b, b2)]).T
    _, gp, Pp = orbit_conditions(pack_state(xN, np.zeros(3), RN, np.zeros(3)), target, problem.model.mass,
                                 problem.model.mu)
    return pack_state(xN, gp, RN, Pp)


def target_estimate(problem: Problem) -> np.ndarray:
    """A terminal state (18) standing for the target: a state target's X (its free components
    hold placeholders), or for an orbit target a point of the orbit reached by a Hohmann-like
    transfer (:func:`relaxed_start_target`), for a rendezvous target the target's state at the problem's T
    (with a free final time its guess; free attitude components those of X0).  For scales and guesses."""
    if isinstance(problem.terminal, TargetState):
        return problem.terminal.X
    if isinstance(problem.terminal, TargetRendezvous):
        return rendezvous_state(problem.terminal, problem.T, problem.model.mass, problem.model.mu, problem.X0)
    return relaxed_start_target(problem)


__all__ = ["Guess", "cayley_vectors", "rollout_guess", "interpolation_guess", "make_guess",
           "perturbed_interpolation_guess", "relaxed_start_target", "screw_path", "target_estimate"]
