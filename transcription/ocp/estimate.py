"""Estimates of the target from the problem's data: a terminal state standing for the target of any kind (a state
target's own, a point of the target orbit, the rendezvous point), for scales and starts."""
from __future__ import annotations

import numpy as np

from ..geometry.so3 import log_so3_any
from ..geometry.state import pack_state, unpack_states
from .conditions import orbit_conditions, rendezvous_state
from .problem import Problem
from .targets import TargetOrbit, TargetRendezvous, TargetState


def _transfer_angle(r0: float, r1: float, mu: float, T: float) -> float:
    """Angle travelled in time T on the Hohmann-type ellipse from radius r0 towards r1, from periapsis (r0 <= r1) or
    apoapsis; Kepler's equation by Newton."""
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
    """A point of the relaxed terminal set to aim the feasibility TPBVP at (18-vector): x_N on the target orbit at the
    Hohmann transfer angle (:func:`_transfer_angle`) from x_0's projection, turning with the initial orbital motion;
    R_N: the body axis along +-e_n (the sign closer to R_0 b), another body axis radial; the momenta required after
    the terminal impulse."""
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


def control_sizes(problem: Problem) -> tuple[float, float] | None:
    """(F_c, M_c): the size of a force and of a moment for this spacecraft, in the problem's units (docs/mathematics.md
    §7, *Weights in the actuators' terms*): F_c the force bound's largest size; M_c the moment bound's largest size or,
    without one, the moment that turns the body half a revolution rest to rest in the orbit's time unit 1/n,
    4 pi lambda_max(J) n^2 with n = sqrt(mu / |x_0|^3) (aiming an engine follows the orbit's turning, one radian per
    1/n).  None without a force bound, with a removed force, or without a central body."""
    f = problem.control.force_bound
    M = moment_size(problem)
    if f is None or f.removed or M is None or not problem.model.mu:
        return None
    return float(np.max(f.sizes())), M


def moment_size(problem: Problem) -> float | None:
    """The size M_c of a moment for this spacecraft (:func:`control_sizes`): the moment bound's largest size, or around
    a central body 4 pi lambda_max(J) n^2; None otherwise (an unbounded moment without an orbit to measure it by)."""
    m, mu = problem.control.moment_bound, problem.model.mu
    if m is not None and not m.removed:
        return float(np.max(m.sizes()))
    if not mu:
        return None
    r0 = float(np.linalg.norm(unpack_states(problem.X0).x[0]))
    return float(4.0 * np.pi * np.linalg.eigvalsh(problem.disc.J)[-1] * mu / r0**3)


def largest_along(actuator, n: np.ndarray) -> float:
    """The largest t >= 0 with t n admissible for ``actuator`` (unit n, 3, in the part's frame): the channels
    Q^T (t n) in [lo, hi] and |t n| <= radius; 0 for a removed part, inf for a free one."""
    Q, lo, hi = actuator.channels
    c = np.asarray(Q, float).T @ np.asarray(n, float)
    t = float(actuator.radius)
    for cj, l, h in zip(c, lo, hi):
        if abs(cj) > 1e-12:
            t = min(t, (h if cj > 0 else -l) / abs(cj))
    return max(t, 0.0)


def eigenaxis_time(problem: Problem) -> float | None:
    """The time of the rest-to-rest bang-bang rotation about the eigenaxis n from R_0 to the target attitude R_d
    (radians theta = |Log(R_0^T R_d)|, n its body-frame axis): 2 sqrt(theta n^T J n / M_n), M_n the largest moment
    the bound gives along n (:func:`largest_along`), the gyroscopic torque ignored (none about a principal axis).  An
    estimate of a slew's minimum time (above it when the bound is a box: the time-optimal slew is not eigenaxis,
    Betts' 28.63 s against 34.31 s).  None without a fixed attitude target or a moment bound, or when it does not
    turn."""
    target, bound = problem.terminal, problem.control.moment_bound
    if not isinstance(target, TargetState) or "attitude" not in target.fixed or bound is None or bound.removed:
        return None
    w = log_so3_any(unpack_states(problem.X0).R[0].T @ unpack_states(target.X).R[0])
    theta = float(np.linalg.norm(w))
    if theta < 1e-9:
        return None
    n = w / theta
    M = largest_along(bound, n)
    return float(2.0 * np.sqrt(theta * float(n @ problem.disc.J @ n) / M)) if 0 < M < np.inf else None


def transfer_time(problem: Problem) -> float | None:
    """A lower bound on the time of an orbit change between circular orbits: the least impulsive delta-v between
    them (:func:`~transcription.ocp.feasibility.orbit_delta_v`, Hohmann's) over the largest acceleration the force
    bound gives, F_max / m (docs/mathematics.md §13).  None where that check does not apply or needs no delta-v."""
    from .feasibility import orbit_capacity         # feasibility's orbit check, computed once there
    cap = orbit_capacity(problem)
    if cap is None or not cap[2] > 0:
        return None
    T = problem.time_bounds[1] if problem.free_time else problem.T
    return float(cap[2] / (cap[3] / T))


def time_estimate(problem: Problem) -> float | None:
    """The problem's own estimate of its minimum time: the larger of :func:`transfer_time` (a bound) and
    :func:`eigenaxis_time` (an estimate) that apply; None when neither does."""
    known = [t for t in (transfer_time(problem), eigenaxis_time(problem)) if t is not None and np.isfinite(t)]
    return max(known) if known else None
