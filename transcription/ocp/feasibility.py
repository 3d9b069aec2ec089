"""Necessary conditions checked before a solve (docs/mathematics.md §13).

A smooth problem whose requirements exceed what any admissible control can achieve in the horizon is reported at
once (``Result.infeasible`` with the reason, no iteration).  Each check compares a requirement of the target with an
upper bound on what the controls can achieve:

* linear momentum:  |gamma_N - gamma_0| <= T F_max;
* angular momentum (inertial): |R_N Pi_N - R_0 Pi_0| <= T M_max (|Pi_N| - |Pi_0| when R_N is free);
* position:  |x_N - x_0| <= (1/m) sum or integral of the largest |gamma| the force allows;
* attitude:  angle(R_0^T R_N) <= the sum of the largest step angles the moment bound and the
  rate limit allow;
* orbit (a central body, circular orbits at both ends): the least impulsive delta-v between them
  (:func:`orbit_delta_v`) <= T F_max / m, the most the engine can give.

They apply where the body is structurally free of external forces (force checks) or moments (moment checks), F_max,
M_max the largest norm a bound allows.  Each bound is derived for the discrete scheme (steps below 90 degrees, §2) and
for the continuous maneuver; a problem is refused only when its requirement exceeds *both*.  O(N) arithmetic.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.state import X_ANG, split_state
from . import MaxAngularRate, Problem, SmoothControl, TargetOrbit, TargetState
from ..geometry.so3 import rotation_angle
from ..outcome import Result

#: a requirement is refused only when it exceeds the largest achievable value by more than this fraction of it plus
#: SLACK times the size of the quantities compared (a target met to a solver's tolerance is never refused)
RTOL, SLACK = 1e-9, 1e-6
#: the sums over the steps are taken in chunks of this many steps (N may be 10^7)
_CHUNK = 1_000_000
#: the most steps a horizon may have (problems.maneuvers.MAX_N): a step hint beyond it is no hint
MAX_STEPS = 10_000_000


def _limit(bound) -> float:
    """The largest |u| a bound allows (inf without one; a body-fixed engine's max: |R u_f| = |u_f| = T, so the
    bounds of docs/mathematics.md §13 hold in either frame)."""
    return math.inf if bound is None else bound.largest_norm()


def _free_of(model) -> tuple[bool, bool]:
    """(no external force, no external moment): the model's force and moment are structurally zero."""
    try:
        f, M = model.forces(ca.SX.sym("x", 3), ca.SX.sym("R", 3, 3))
        return bool(ca.SX(f).is_zero()), bool(ca.SX(M).is_zero())
    except Exception:  # noqa: BLE001 - a model we cannot inspect gets no check, never a false refusal
        return False, False


def _ramp(a: float, b: float, B: float, T: float) -> float:
    """integral over [0, T] of min(a + B t, b + B (T - t)) (b may be inf): the largest integral of |p(t)|
    when |p(0)| = a, |p(T)| = b and |dp/dt| <= B."""
    if not math.isfinite(b):
        return a * T + 0.5 * B * T * T
    ts = min(max((b - a + B * T) / (2.0 * B), 0.0), T) if B > 0 else (T if a <= b else 0.0)
    return a * ts + 0.5 * B * ts * ts + b * (T - ts) + 0.5 * B * (T - ts) ** 2


def _steps(a: float, b: float, B: float, h: float, N: int, offset: float, fn) -> float:
    """sum over k = 0..N-1 of fn(min(a + (k + offset) h B, b + (N - k - offset) h B)): the bound on the
    momentum a step uses (first-order scheme: offset 0, the node momentum; LGVI: 1/2, the mid-step one)."""
    total = 0.0
    for k0 in range(0, N, _CHUNK):
        k = np.arange(k0, min(N, k0 + _CHUNK), dtype=float)
        p = np.minimum(a + (k + offset) * h * B, b + (N - k - offset) * h * B)
        total += float(np.sum(fn(p)))
    return total


def _refuse(need: float, bounds: list[float], scale: float) -> bool:
    """The requirement ``need`` exceeds every bound (discrete, continuous) beyond the tolerances."""
    return need > max(bounds) * (1.0 + RTOL) + SLACK * scale


#: the orbit check refuses only a delta-v above the engine's capacity by more than this fraction: the point-mass
#: estimate ignores the perturbations of the field (the Earth's J2 = 1.1e-3 changes circular speeds by about that)
ORBIT_RTOL = 1e-2
#: an orbit is circular for the orbit check when its eccentricity is below this (elements with e = 0 give ~1e-16)
CIRCULAR_E = 1e-6


def orbit_delta_v(mu: float, r1: float, r2: float) -> float:
    """The least impulsive delta-v between coplanar circular orbits of radii r1 and r2 about GM ``mu``: Hohmann's
    two impulses, or the bi-elliptic limit (sqrt 2 - 1)(v1 + v2) where smaller (r2 / r1 beyond 11.94); a plane change
    or a fixed phase only adds to it, and a continuous burn needs at least the impulsive optimum."""
    a, b = min(r1, r2), max(r1, r2)
    va, vb = math.sqrt(mu / a), math.sqrt(mu / b)
    hohmann = va * (math.sqrt(2 * b / (a + b)) - 1) + vb * (1 - math.sqrt(2 * a / (a + b)))
    return min(hohmann, (math.sqrt(2) - 1) * (va + vb))


def _circular_radius(mu: float, x: np.ndarray, v: np.ndarray) -> float | None:
    """|x| if (x, v) is a circular orbit about mu (eccentricity below CIRCULAR_E), else None."""
    r = float(np.linalg.norm(x))
    e = (np.dot(v, v) / mu - 1 / r) * x - np.dot(x, v) / mu * v
    return r if r > 0 and np.linalg.norm(e) < CIRCULAR_E else None


def orbit_capacity(problem: Problem) -> tuple[float, float, float, float] | None:
    """(r0, r1, need, can) of the orbit check (module docstring): the radii of the circular orbits at both ends, the
    least impulsive delta-v between them and the most the force bound gives in the horizon, T F_max / m; None where
    the check does not apply (no central body, no force bound, an end not on a circular orbit, no position and
    velocity or orbit target)."""
    mu, m, target, F = problem.model.mu, problem.model.mass, problem.terminal, _limit(problem.control.force_bound)
    if not mu or not math.isfinite(F):
        return None
    T = problem.time_bounds[1] if problem.free_time else problem.T
    x0, g0, _, _ = split_state(problem.X0)
    r0 = _circular_radius(mu, x0, g0 / m)
    if isinstance(target, TargetOrbit):
        r1 = float(target.radius)
    elif isinstance(target, TargetState) and {"position", "velocity"} <= set(target.fixed):
        xd, gd, _, _ = split_state(target.X)
        r1 = _circular_radius(mu, xd, gd / m)
    else:
        return None
    if r0 is None or r1 is None:
        return None
    return r0, r1, orbit_delta_v(mu, r0, r1), T * F / m


def _orbit_capacity(problem: Problem, Tw: str) -> str | None:
    """The orbit check's refusal, or None when it holds or does not apply."""
    cap = orbit_capacity(problem)
    if cap is None:
        return None
    r0, r1, need, can = cap
    if need > can * (1 + ORBIT_RTOL):
        F, m = _limit(problem.control.force_bound), problem.model.mass
        return (f"the orbit change from radius {r0:.8g} to {r1:.8g} needs a delta-v of at least {need:.4g} (Hohmann), "
                f"more than the force bound |u_f| <= {F:.4g} can give the mass {m:.6g} in {Tw}: at most T |u_f| / m = "
                f"{can:.4g}")
    return None


def necessary_conditions(problem: Problem) -> str | None:
    """The reason ``problem`` has no solution, or None if every necessary condition holds (or none
    applies: impulsive control, external forces and moments)."""
    ctrl, target = problem.control, problem.terminal
    if not isinstance(ctrl, SmoothControl):
        return None
    T = problem.time_bounds[1] if problem.free_time else problem.T
    Tw = f"T = {T:g}" + (" (the largest free final time)" if problem.free_time else "")
    orbit = _orbit_capacity(problem, Tw)
    if orbit or not isinstance(target, TargetState):
        return orbit
    model = problem.model
    N = problem.N
    h = T / N
    offset = 0.5 if two_point(problem.scheme) else 0.0
    no_force, no_moment = _free_of(model)
    x0, g0, R0, P0 = split_state(problem.X0)
    xd, gd, Rd, Pd = split_state(target.X)
    fixed = set(target.fixed)
    F, M = _limit(ctrl.force_bound), _limit(ctrl.moment_bound)
    if no_force and math.isfinite(F):
        if "velocity" in fixed:
            need = float(np.linalg.norm(gd - g0))
            if _refuse(need, [T * F], max(np.linalg.norm(g0), np.linalg.norm(gd))):
                return (f"the change of linear momentum |m v_N - m v_0| = {need:.6g} exceeds what the force bound "
                        f"|u_f| <= {F:.6g} can give in {Tw}: at most T |u_f| = {T * F:.6g}")
        if "position" in fixed:
            a, b = float(np.linalg.norm(g0)), float(np.linalg.norm(gd)) if "velocity" in fixed else math.inf
            need = float(np.linalg.norm(xd - x0))
            reach = [_steps(a, b, F, h, N, offset, lambda p: p) * h / model.mass, _ramp(a, b, F, T) / model.mass]
            if _refuse(need, reach, max(np.linalg.norm(x0), np.linalg.norm(xd))):
                return (f"the distance |x_N - x_0| = {need:.6g} exceeds the largest one the force bound |u_f| <= "
                        f"{F:.6g} allows in {Tw} from the given velocities: {max(reach):.6g}")
    return _rotation(problem, T, Tw, h, offset, no_moment, M, R0, P0, Rd, Pd, fixed)


def _rotation(problem, T, Tw, h, offset, no_moment, M, R0, P0, Rd, Pd, fixed) -> str | None:
    """The moment and rate checks of :func:`necessary_conditions`."""
    N = problem.N
    lam = np.linalg.eigvalsh(problem.model.inertia)
    lmin, lmax = float(lam[0]), float(lam[-1])
    if no_moment and math.isfinite(M) and "angular_velocity" in fixed:
        if "attitude" in fixed:
            need, what = float(np.linalg.norm(Rd @ Pd - R0 @ P0)), "|R_N Pi_N - R_0 Pi_0|"
        else:
            need, what = abs(float(np.linalg.norm(Pd)) - float(np.linalg.norm(P0))), "||Pi_N| - |Pi_0||"
        if _refuse(need, [T * M], max(np.linalg.norm(P0), np.linalg.norm(Pd))):
            return (f"the change of angular momentum {what} = {need:.6g} exceeds what the moment bound |u_m| <= "
                    f"{M:.6g} can give in {Tw}: at most T |u_m| = {T * M:.6g}")
    if "attitude" not in fixed:
        return None
    rates = [c.value for c in problem.constraints if isinstance(c, MaxAngularRate)]
    # the rows hold at nodes 1..N; node 0 (and a given node N) as given, whatever the limit
    ends = [np.linalg.norm(np.linalg.solve(problem.model.inertia, P)) for P in (P0, Pd)[:1 + ("angular_velocity" in fixed)]]
    W = max([min(rates)] + ends) if rates else math.inf
    torque = no_moment and math.isfinite(M)
    if not torque and not (math.isfinite(W) and (offset == 0.0 or (no_moment and math.isfinite(M)))):
        return None  # nothing bounds the rotation (the LGVI's node moments act within a step)
    a = float(np.linalg.norm(P0))
    b = float(np.linalg.norm(Pd)) if "angular_velocity" in fixed else math.inf
    kappa = (lmax + lmin) / (2.0 * math.sqrt(lmax * lmin))  # Kantorovich: |J n| / n^T J n <= kappa
    rate_step = kappa * h * W + (0.5 * h * h * M / lmin if offset else 0.0)  # sin(step angle) by the rate limit
    Mb = M if torque else math.inf

    def step_angles(p):
        s = np.minimum(h * p / lmin if torque else math.inf, rate_step)
        return np.arcsin(np.minimum(s, 1.0))

    need = float(rotation_angle(R0.T @ Rd))
    continuous = min(W * T, _ramp(a, b, Mb, T) / lmin if torque else math.inf)
    reach = [_steps(a, b, Mb if torque else 0.0, h, N, offset, step_angles), continuous]
    if _refuse(need, reach, 1.0):
        by = " and ".join(w for w, on in ((f"the moment bound |u_m| <= {M:.6g}", torque),
                                          (f"the rate limit |Omega| <= {W:.6g}", math.isfinite(W))) if on)
        return (f"the attitude change of {math.degrees(need):.6g} deg exceeds the largest rotation {by} "
                f"allow{'s' if ' and ' not in by else ''} in {Tw} from the given angular velocities: "
                f"{math.degrees(max(reach)):.6g} deg")
    return None


def step_failure(problem: Problem, X: np.ndarray, residuals: np.ndarray, h: float) -> tuple[Result, str]:
    """(result, explanation) of a (re-)simulation whose steps failed (residuals above CAYLEY_TOL or not
    finite).  Non-finite states or residuals are ``non_finite``: the data overflow, and no step size
    helps.  Otherwise ``cayley_failed`` with the scheme's own condition (§2): a step turns the body by
    s = h |Pi_k| / lambda_min(J) < 1; the hint is the horizon.N that brings s to 1/2, or -- when that
    is beyond MAX_STEPS (a denormal inertia, an absurd spin) -- that no step size will do."""
    X = np.asarray(X, dtype=float)
    res = np.asarray(residuals, dtype=float).ravel()
    finite = np.all(np.isfinite(X), axis=1)
    if not finite.all() or not np.all(np.isfinite(res)):
        k = int(np.argmin(finite)) if not finite.all() else int(np.argmin(np.isfinite(res)))
        return Result.non_finite, (f"the state became non-finite at step {k}: the data overflow or "
                                   f"underflow (check the magnitudes of the mass, the inertia, the bounds and the "
                                   f"states); reducing the step size does not help")
    k = int(np.argmax(res)) if res.size else 0
    lmin = float(np.linalg.eigvalsh(problem.model.inertia)[0])
    Pi = X[min(k, len(X) - 1), X_ANG]
    scale = float(np.abs(Pi).max())
    P = scale * float(np.linalg.norm(Pi / scale)) if scale > 0 else 0.0  # |Pi| without overflow
    with np.errstate(all="ignore"):
        s = float(h * P / lmin)
    text = f"the Cayley equation of step {k} was not solved (relative residual {res[k] if res.size else 0:.1e})"
    need = math.ceil(problem.N * 2.0 * s) if math.isfinite(s) else math.inf
    if not s > 1.0:
        return Result.cayley_failed, f"{text}: the rotation per step is too large; use a smaller step h = T/N " \
                                     f"(increase horizon.N)"
    if need <= MAX_STEPS:
        return Result.cayley_failed, (f"{text}: the step turns the body by h |Pi| / lambda_min(J) = {s:.3g}, beyond "
                                      f"the scheme's limit 1; use a smaller step h = T/N (increase horizon.N to about "
                                      f"{need})")
    return Result.cayley_failed, (f"{text}: the step turns the body by h |Pi| / lambda_min(J) = {s:.3g}, beyond the "
                                  f"scheme's limit 1, and no step size can fix it (horizon.N would exceed {MAX_STEPS}): "
                                  f"the angular momentum |Pi| = {P:.3g} is too large for the "
                                  f"smallest principal moment {lmin:.3g}; check the inertia and the angular velocities")


__all__ = ["MAX_STEPS", "RTOL", "necessary_conditions", "step_failure"]
