"""The terminal conditions, defined once and used by every method, the re-simulation and the reports
(docs/mathematics.md §5-§6, §10): a state target's residual, an orbit target's conditions, a rendezvous
target's residual (a function of the final time), the terminal error."""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..geometry.state import pack_state, split_state
from ..geometry.so3 import is_symbolic, log_so3, mtimes
from .problem import Problem
from .targets import STATE_COMPONENTS, TargetOrbit, TargetRendezvous, TargetState


def state_residual(XN, Xd, fixed=STATE_COMPONENTS):
    """The terminal conditions of a state target (docs/mathematics.md §6): the blocks
    x_N - x_d, gamma_N - gamma_d (inertial), vee log(R_d^T R_N) (body frame at the target: three
    conditions, never nine) and Pi_N - Pi_d (body) of the ``fixed`` components, stacked.
    XN (and Xd): CasADi (18,1) (symbolic, differentiable) or NumPy (18,) (log accurate up to pi)."""
    x, g, R, P = split_state(XN)
    xd, gd, Rd, Pd = split_state(Xd)
    parts = {"position": x - xd, "velocity": g - gd, "attitude": log_so3(mtimes(Rd.T, R)), "angular_velocity": P - Pd}
    rows = [parts[c] for c in fixed]
    if is_symbolic(XN) or is_symbolic(Xd):
        return ca.vertcat(*rows)
    return np.concatenate([np.asarray(r, dtype=float).ravel() for r in rows])


def terminal_residual(XN, target: TargetState):
    """:func:`state_residual` of a :class:`TargetState` (its fixed components)."""
    return state_residual(XN, target.X, target.fixed)


def orbit_conditions(XN, target: TargetOrbit, mass: float, mu: float):
    """Relaxed terminal set (docs/mathematics.md §5): (C (4), gamma_N^+ (3), Pi_N^+ (3)).

    C = [|x_N| - r_d; e_n^T x_N; a^T R_N b; b'^T R_N b] with (a, b') a basis of the orbit plane and b
    the body axis; gamma_N^+ = m sqrt(mu/r_d) (e_n x x_N)/r_d (inertial) the momentum of the
    circular orbit after the terminal impulse; Pi_N^+ = the target's Pi (body).  CasADi or NumPy.
    """
    n, a, b = target.plane_basis()
    rd = float(target.radius)
    x, _, R, _ = split_state(XN)
    axis = mtimes(R, target.body_axis)
    vc = mass * np.sqrt(mu / rd) / rd
    if is_symbolic(XN):
        C = ca.vertcat(ca.norm_2(x) - rd, ca.dot(ca.DM(n), x), ca.dot(ca.DM(a), axis), ca.dot(ca.DM(b), axis))
        return C, vc * ca.cross(ca.DM(n), x), ca.DM(target.Pi)
    return np.array([np.linalg.norm(x) - rd, n @ x, a @ axis, b @ axis]), vc * np.cross(n, x), target.Pi.copy()


def orbit_residual(XN, target: TargetOrbit, mass: float, mu: float):
    """The orbit target's conditions at arrival under smooth control (10 rows, CasADi or NumPy):
    C (4) of :func:`orbit_conditions`, gamma_N - gamma^+(x_N) (3, inertial), Pi_N - Pi^+ (3, body)."""
    C, gp, Pp = orbit_conditions(XN, target, mass, mu)
    _, g, _, P = split_state(XN)
    if is_symbolic(XN):
        return ca.vertcat(C, g - gp, P - Pp)
    return np.concatenate([C, g - gp, P - Pp])


def rendezvous_state(target: TargetRendezvous, T: float, mass: float, mu: float, fill: np.ndarray) -> np.ndarray:
    """The state (18, NumPy) the rendezvous asks for at time T: the target's position and momentum m v(T), its
    attitude and angular momentum where given, else those of ``fill`` (18; placeholders for scales and guesses)."""
    p, v = target.point(float(T), mu)
    _, _, Rf, Pf = split_state(fill)
    return pack_state(p, mass * v, Rf if target.R is None else target.R, Pf if target.Pi is None else target.Pi)


def rendezvous_residual(XN, T, target: TargetRendezvous, mass: float, mu: float):
    """The rendezvous conditions at the final time T (docs/mathematics.md §10): x_N - p(T) (3), gamma_N - m v(T)
    (3, inertial), then the given attitude (vee log(R_d^T R_N), 3) and angular momentum (Pi_N - Pi_d, 3) as in
    :func:`state_residual`.  CasADi if XN or T is symbolic (differentiable in both: with a free final time
    T = N h the target point moves with h), else NumPy."""
    p, v = target.point(T, mu)
    x, g, _, _ = split_state(XN)
    rest = tuple(c for c in target.fixed if c in ("attitude", "angular_velocity"))
    Xd = rendezvous_state(target, 0.0, mass, mu, pack_state(np.zeros(3), np.zeros(3), np.eye(3), np.zeros(3)))
    tail = state_residual(XN, Xd, rest) if rest else None
    if is_symbolic(XN) or is_symbolic(T):
        return ca.vertcat(x - p, g - mass * v, *([tail] if rest else []))
    return np.concatenate([x - p, g - mass * v] + ([tail] if rest else []))


def terminal_rows(XN, problem: Problem, T=None):
    """The terminal residual rows at XN (NumPy or CasADi) of smooth control: an orbit target's
    :func:`orbit_residual`, a rendezvous target's :func:`rendezvous_residual` at the final time T (default the
    problem's T: with a free final time pass the solved one), a state target's :func:`terminal_residual`."""
    target = problem.terminal
    if isinstance(target, TargetOrbit):
        return orbit_residual(XN, target, problem.model.mass, problem.model.mu)
    if isinstance(target, TargetRendezvous):
        return rendezvous_residual(XN, problem.T if T is None else T, target, problem.model.mass, problem.model.mu)
    return terminal_residual(XN, target)


def terminal_error(XN: np.ndarray, problem: Problem, XN_plus: np.ndarray | None = None, T: float | None = None) -> float:
    """The terminal error of docs/mathematics.md §8 (NumPy): the max-norm of the terminal residual
    of a state target (for impulsive control evaluated after the terminal impulse, ``XN_plus``),
    of an orbit target max |C| (impulsive) or the max-norm of :func:`orbit_residual` (smooth), of a
    rendezvous target the max-norm of :func:`rendezvous_residual` at the final time T (default the problem's)."""
    if isinstance(problem.terminal, TargetOrbit):
        rows = terminal_rows(XN, problem) if problem.kind == "smooth" else \
            orbit_conditions(XN, problem.terminal, problem.model.mass, problem.model.mu)[0]
        return float(np.abs(rows).max())
    if isinstance(problem.terminal, (TargetState, TargetRendezvous)):
        X = XN if XN_plus is None else XN_plus
        if not np.all(np.isfinite(X)):
            return float("inf")
        return float(np.abs(terminal_rows(np.asarray(X, float), problem, T)).max())
    return float("nan")
