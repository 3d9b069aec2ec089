"""The continuous check of a Solution (docs/mathematics.md §11): how the plan flies in continuous time.

The Solution's controls (impulses: free motion after the initial impulse) are flown from its initial state through
eqs. (1)-(4) (:func:`~transcription.dynamics.flight.fly`) and compared with the plan's nodes.  The flown attitude is
re-projected onto SO(3) (:func:`~transcription.geometry.so3.nearest_rotation`) before any angle is measured.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..geometry.state import X_ANG, X_MOM, X_POS, X_ROT
from ..geometry.so3 import exp_so3, log_so3_batch, nearest_rotation, orthogonality_error, rotation_angle
from ..ocp import MARGIN_DIMENSION, STATE_COMPONENTS, TargetRendezvous, TargetState, quadrature_weights, terminal_error
from ..outcome import Result
from ..dynamics.trajectory import Trajectory
from ..dynamics.flight import DEFAULT_SAMPLES, Actuators, FlightError, OpenLoop, fly

if TYPE_CHECKING:  # pragma: no cover
    from .solution import Solution


#: a plan flown in continuous time that misses its target by more than this fraction of what its maneuver changes is
#: said to (its message, the CLI's table): the issue's 1 % of the maneuver
FLOWN_MISS_TOL = 0.01
#: a plan whose flown path leaves a path constraint between its nodes by more than this (the units of scaled_miss,
#: :func:`margin_scales`: rad for a cone -- 5.7e-4 deg --, a fraction of L for a radius, rad per time unit for a rate)
#: is said to (its message, the CLI's table), unless ``solver.constraints_tolerance`` gives another: issue 42's
#: "continuous margin >= -1e-3 deg, or a status that says it is not"
PATH_MARGIN_TOL = 1e-5
#: the attitude error given at the start of the flights that measure its growth (rad) and the growth beyond which a
#: plan is said to be unstable open loop (:func:`attitude_amplification`): a torque-free body keeps an attitude error
#: as it is (1); measured, LEO engine plans that fly within 1 % grow it 4.7-30 times (raise_in_phase and two raises
#: written with it), the phasing of configs/leo/phasing_across_gradient.yaml 255-1590 times (N = 300-600)
PERTURBATION_RAD, UNSTABLE_GROWTH = 1e-6, 100.0
#: the cure a path note names (:meth:`ContinuousCheck.path_note`)
PATH_CURE = ("set solver.constraints_tolerance (or solver.accuracy) to refine the mesh where the path leaves it, or "
             "raise horizon.N")


@dataclass(frozen=True, eq=False)
class ContinuousCheck:
    """A plan flown in continuous time, against its own nodes (the problem's units; angles in rad).

    terminal_position |x(T) - x_N|, terminal_velocity |v(T) - v_N| (inertial), terminal_attitude angle(R_N^T R(T)),
    terminal_rate |Omega(T) - Omega_N| (body); terminal_error: the largest of the four.  target_error: the
    Solution's terminal-error measure (docs/mathematics.md §8) at the flown final state (nan without a target).
    max_position_deviation, max_attitude_deviation over the nodes; t, position_deviation, attitude_deviation (N+1,).
    min_margins: each path constraint's smallest margin over all samples (``min_margin_<kind>``, ``_2``, ...).
    orthogonality_drift: max |R^T R - I|_F before re-projection.  samples: per node interval.  elapsed_s: wall
    time.  message: '' or why the flight failed (then the numbers are nan).

    What the maneuver changes (:func:`maneuver_change`; nan where it does not apply): change_position,
    change_velocity, change_attitude (rad) -- for a state, rendezvous or orbit target, each changed component's
    smallest measure (the radius change or the free motion's distance to the target; the plan's delta-v or the free
    motion's velocity distance; the slew or the free motion's angle); change_target -- for any target, the terminal-error measure of
    the free motion (what the controls must remove).  :attr:`maneuver_fraction` is the flown miss relative to it.

    margin_tolerances: for each key of min_margins, the violation (margin below 0, in the margin's own unit: deg for
    a cone, length for a radius, rate) the plan is allowed (:func:`path_tolerances`); a larger one is said by
    :meth:`path_note` and :meth:`path_violations`.  Empty: not judged.
    """

    terminal_position: float
    terminal_velocity: float
    terminal_attitude: float
    terminal_rate: float
    terminal_error: float
    target_error: float
    max_position_deviation: float
    max_attitude_deviation: float
    min_margins: dict[str, float]
    orthogonality_drift: float
    samples: int
    elapsed_s: float
    t: np.ndarray = field(repr=False)
    position_deviation: np.ndarray = field(repr=False)
    attitude_deviation: np.ndarray = field(repr=False)
    message: str = ""
    change_position: float = float("nan")
    change_velocity: float = float("nan")
    change_attitude: float = float("nan")
    change_target: float = float("nan")
    margin_tolerances: dict[str, float] = field(default_factory=dict)
    attitude_growth: float = float("nan")

    @property
    def ok(self) -> bool:
        return not self.message

    def path_violations(self) -> list[tuple[str, float, float]]:
        """(margin key, violation, tolerance) of every path constraint the flown path leaves by more than its
        tolerance (:attr:`margin_tolerances`), the violation -min_margin > 0 in the margin's own unit."""
        return [(k, -float(m), float(self.margin_tolerances[k])) for k, m in self.min_margins.items()
                if k in self.margin_tolerances and -m > self.margin_tolerances[k]]

    def path_note(self) -> str:
        """'' or, when the flown path leaves a path constraint between the nodes by more than its tolerance, the
        sentence that says so, naming each constraint and its violation (deg for a cone; the problem's units for a
        radius or a rate -- the CLI's table repeats it in the file's) and the cure."""
        bad = self.path_violations()
        if not bad:
            return ""
        unit = {"angle": " deg", "length": " length units", "angular_rate": " rad per time unit"}
        what = ", ".join(f"{margin_kind(k)} by {v:.3g}{unit.get(MARGIN_DIMENSION.get(margin_kind(k)), '')} "
                         f"(tolerance {t:.3g})" for k, v, t in bad)
        return (f"flown in continuous time the path leaves its constraints between the nodes: {what}: the scheme's "
                f"error at this N; {PATH_CURE}")

    def miss_note(self) -> str:
        """'' or, when the flown miss exceeds :data:`FLOWN_MISS_TOL` of the maneuver, the sentence that says so (in
        the problem's units; the CLI's table repeats it in the file's)."""
        f = self.maneuver_fraction
        if not f > FLOWN_MISS_TOL:
            return ""
        what = ", ".join(f"attitude (deg) {np.degrees(m):.3g} of {np.degrees(c):.3g}" if n == "attitude" else
                         f"{n} {m:.3g} of {c:.3g}" for n, m, c in self.maneuver_parts()) or \
            f"terminal error {self.target_error:.3g} of {self.change_target:.3g}"
        return (f"flown in continuous time the plan misses its target by {100 * f:.2g} % of the maneuver ({what}), "
                f"above {100 * FLOWN_MISS_TOL:g} %: " + (self.unstable_note() or "the scheme's error at this N"))

    def unstable_note(self) -> str:
        """'' or, when an attitude error at the start grows more than :data:`UNSTABLE_GROWTH`-fold in the flight
        (:attr:`attitude_growth`, measured for a plan that misses by more than :data:`FLOWN_MISS_TOL`), the sentence
        that says the plan is unstable open loop and names the cure."""
        if not self.attitude_growth > UNSTABLE_GROWTH:
            return ""
        return (f"the plan is unstable open loop (an attitude error at the start grows up to {self.attitude_growth:.3g}"
                f" times in the flight), so the scheme's error at this N is amplified, as any error of a real flight "
                f"would be: fly it with feedback (se3ocp fly --feedback lqr); a larger horizon.N shrinks only what is "
                f"amplified")

    @property
    def maneuver_fraction(self) -> float:
        """The flown terminal miss as a fraction of what the maneuver changes: for a state target the largest of
        terminal_position / change_position, terminal_velocity / change_velocity and terminal_attitude /
        change_attitude over the components the maneuver changes (a change above a millionth of its scale,
        :func:`maneuver_change`); otherwise target_error / change_target.  nan when nothing is changed or the
        flight failed."""
        fr = [m / c for _, m, c in self.maneuver_parts()]
        if not fr and np.isfinite(self.change_target) and self.change_target > 0:
            fr = [self.target_error / self.change_target]
        return float(max(fr)) if fr else float("nan")

    def maneuver_parts(self) -> list[tuple[str, float, float]]:
        """(component, terminal miss, change) of each component the maneuver changes: 'position', 'velocity',
        'attitude' (rad); [] for other targets (then the target-error measure applies)."""
        parts = (("position", self.terminal_position, self.change_position),
                 ("velocity", self.terminal_velocity, self.change_velocity),
                 ("attitude", self.terminal_attitude, self.change_attitude))
        return [(n, float(m), float(c)) for n, m, c in parts if np.isfinite(c) and c > 0]

    def summary(self) -> dict[str, Any]:
        """JSON-ready scalars, named for summary.json (``continuous_...``)."""
        out = {"continuous_terminal_error": self.terminal_error, "continuous_terminal_position": self.terminal_position,
               "continuous_terminal_velocity": self.terminal_velocity,
               "continuous_terminal_attitude_rad": self.terminal_attitude, "continuous_terminal_rate": self.terminal_rate,
               "continuous_target_error": self.target_error,
               "continuous_max_position_deviation": self.max_position_deviation,
               "continuous_max_attitude_deviation_rad": self.max_attitude_deviation,
               "continuous_orthogonality_drift": self.orthogonality_drift, "continuous_samples": self.samples,
               "continuous_check_s": self.elapsed_s, "continuous_change_position": self.change_position,
               "continuous_change_velocity": self.change_velocity,
               "continuous_change_attitude_rad": self.change_attitude, "continuous_change_target": self.change_target,
               "continuous_maneuver_fraction": self.maneuver_fraction,
               "continuous_attitude_growth": self.attitude_growth}
        out.update({f"continuous_{k}": v for k, v in self.min_margins.items()})
        out.update({f"continuous_tolerance_{k}": v for k, v in self.margin_tolerances.items()})
        if self.message:
            out["continuous_message"] = self.message
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in out.items()}

    def arrays(self) -> dict[str, np.ndarray]:
        """The per-node arrays, named for the .npz file of a results directory (``continuous_...``)."""
        return {"continuous_t": self.t, "continuous_position_deviation": self.position_deviation,
                "continuous_attitude_deviation": self.attitude_deviation}

    @classmethod
    def from_record(cls, block: dict[str, Any], arrays: dict[str, np.ndarray]) -> "ContinuousCheck | None":
        """The check read back from a results directory: the ``continuous_...`` scalars of a summary.json method
        block (:meth:`summary`) and the arrays of its .npz (:meth:`arrays`); None if the run has none."""
        if "continuous_terminal_error" not in block or "continuous_t" not in arrays:
            return None

        def num(key):
            v = block.get(f"continuous_{key}")
            return float("nan") if v is None else float(v)

        margins = {k[len("continuous_"):]: num(k[len("continuous_"):]) for k in block
                   if k.startswith("continuous_min_margin_")}
        tols = {k: num(f"tolerance_{k}") for k in margins if f"continuous_tolerance_{k}" in block}
        return cls(*(num(k) for k in _SCALARS), margins, num("orthogonality_drift"), int(block.get("continuous_samples") or 0),
                   num("check_s"), np.asarray(arrays["continuous_t"], float),
                   np.asarray(arrays["continuous_position_deviation"], float),
                   np.asarray(arrays["continuous_attitude_deviation"], float), str(block.get("continuous_message", "")),
                   *(num(k) for k in ("change_position", "change_velocity", "change_attitude_rad", "change_target")),
                   tols, num("attitude_growth"))


#: the summary keys (after ``continuous_``) of the first eight fields of ContinuousCheck, in order
_SCALARS = ("terminal_position", "terminal_velocity", "terminal_attitude_rad", "terminal_rate", "terminal_error",
            "target_error", "max_position_deviation", "max_attitude_deviation_rad")


def margin_keys(constraints) -> list[str]:
    """The summary keys of path constraints' margins: ``min_margin_<kind>``, with ``_2``, ``_3``, ... for a
    kind repeated (the names of results.figures_of_merit)."""
    seen: dict[str, int] = {}
    keys = []
    for c in constraints:
        seen[c.kind] = seen.get(c.kind, 0) + 1
        keys.append(f"min_margin_{c.kind}" + (f"_{seen[c.kind]}" if seen[c.kind] > 1 else ""))
    return keys


def margin_kind(key: str) -> str:
    """The constraint kind of a margin key of :func:`margin_keys` ('min_margin_keep_out_2' -> 'keep_out')."""
    kind = key.removeprefix("min_margin_")
    head, _, tail = kind.rpartition("_")
    return head if tail.isdigit() else kind


def margin_scales(problem) -> list[float]:
    """The factor that takes each path constraint's margin into the units of :func:`scaled_miss` (its
    ``margin_scale``): a cone's (deg) pi / 180, a radius's 1 / L, a rate's 1, a wheel's momentum 1 / its limit."""
    L = characteristic_length(problem)
    return [c.margin_scale(L) for c in problem.constraints]


def path_tolerances(problem, tol: float | None = None) -> dict[str, float]:
    """Each path constraint's allowed violation in its margin's own unit (by :func:`margin_keys`): ``tol`` (the
    units of scaled_miss; default :data:`PATH_MARGIN_TOL`) divided by its :func:`margin_scales`."""
    tol = PATH_MARGIN_TOL if tol is None else float(tol)
    return {k: tol / s for k, s in zip(margin_keys(problem.constraints), margin_scales(problem))}


def continuous_check(sol: "Solution", samples: int = DEFAULT_SAMPLES,
                     path_tol: float | None = None) -> ContinuousCheck | None:
    """Fly ``sol``'s controls (impulsive: free motion from the state after the initial impulse) from its
    initial state over its node times through eqs. (1)-(4), sampled ``samples`` times per interval, and
    measure the flight against the plan (:class:`ContinuousCheck`).  ``path_tol``: the path constraints'
    allowed violation (:func:`path_tolerances`; ``solver.constraints_tolerance``, default
    :data:`PATH_MARGIN_TOL`).  None where there is nothing to fly: no problem, a method that does not apply, or a
    plan that is not finite."""
    prob, traj = sol.problem, sol.trajectory
    if prob is None or sol.result is Result.not_applicable or not np.all(np.isfinite(traj.X)):
        return None
    t0 = time.perf_counter()
    N = traj.X.shape[0] - 1
    law = OpenLoop.free(N) if sol.controls is None else OpenLoop.of_controls(prob.scheme, sol.controls)
    try:
        flight = fly(prob.model, traj.X[0], traj.t, law, Actuators(force_frame=prob.disc.force_frame), samples=samples)
    except FlightError as e:
        nan, nodes = float("nan"), np.full(N + 1, np.nan)
        return ContinuousCheck(nan, nan, nan, nan, nan, nan, nan, nan, {k: nan for k in margin_keys(prob.constraints)},
                               nan, int(samples), time.perf_counter() - t0, traj.t, nodes, nodes, message=str(e),
                               margin_tolerances=path_tolerances(prob, path_tol))
    X, R = flight.X.copy(), flight.trajectory().R
    drift = float(orthogonality_error(R)[0].max())
    X[:, X_ROT] = np.swapaxes(nearest_rotation(R), -1, -2).reshape(-1, 9)     # vec(R) column-major
    flown = Trajectory(t=flight.t, X=X, mass=traj.mass, inertia=traj.inertia)
    k = np.arange(N + 1) * flight.samples
    dx = np.linalg.norm(flown.x[k] - traj.x, axis=1)
    dR = rotation_angle(np.einsum("kji,kjl->kil", traj.R, flown.R[k]))
    end = (float(dx[-1]), float(np.linalg.norm(flown.v[-1] - traj.v[-1])), float(dR[-1]),
           float(np.linalg.norm(flown.Omega[-1] - traj.Omega[-1])))
    margins = {key: float(np.min(c.margin(flown))) for key, c in zip(margin_keys(prob.constraints), prob.constraints)}
    change = maneuver_change(sol, samples)
    check = ContinuousCheck(*end, max(end), _target_error(sol, X[-1]), float(dx.max()), float(dR.max()), margins,
                            drift, flight.samples, 0.0, traj.t.copy(), dx, dR, "", *change,
                            path_tolerances(prob, path_tol))
    if check.maneuver_fraction > FLOWN_MISS_TOL:
        check = replace(check, attitude_growth=attitude_amplification(prob, traj, law, flown, samples))
    return replace(check, elapsed_s=time.perf_counter() - t0)


def attitude_amplification(prob, traj: Trajectory, law, flown: Trajectory, samples: int) -> float:
    """How much the plan's open-loop flight amplifies an attitude error: the same controls flown three more times, from
    the initial attitude turned by :data:`PERTURBATION_RAD` about each body axis; at each sample the 3 x 3 sensitivity
    S of the attitude error (Log(R^T R_i)^v / delta, column i) and its largest singular value, the largest over the
    flight (nan if a flight fails).  A torque-free body keeps an attitude error (1); an unstable attitude motion (a
    body held across the gravity gradient) grows it exponentially, and with it the scheme's error and a real flight's."""
    X0, cols = traj.X[0], []
    R0 = X0[X_ROT].reshape(3, 3, order="F")
    for axis in np.eye(3):
        Xi = X0.copy()
        Xi[X_ROT] = (R0 @ np.asarray(exp_so3(PERTURBATION_RAD * axis), float)).ravel(order="F")
        try:
            other = fly(prob.model, Xi, traj.t, law, Actuators(force_frame=prob.disc.force_frame), samples=samples)
        except FlightError:
            return float("nan")
        D = np.einsum("kji,kjl->kil", flown.R, nearest_rotation(other.trajectory().R))
        cols.append(log_so3_batch(D) / PERTURBATION_RAD)
    return float(np.linalg.svd(np.stack(cols, axis=2), compute_uv=False)[:, 0].max())


def target_point(prob, XF: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, set[str]]:
    """The point of the terminal set that a final state ``XF`` (18,) is measured against at the final time T:
    (position, momentum gamma = m v, attitude R or None, the components the target fixes).  A state target's own; a
    rendezvous's target at T (:meth:`~transcription.ocp.TargetRendezvous.point`); for a target orbit the point of its
    circle nearest XF's position (the projection on its plane, scaled to its radius) with the circular velocity there,
    sqrt(mu / r) n x e -- the orbit fixes position and velocity; its body-axis condition is no full attitude."""
    t, mass = prob.terminal, prob.model.mass
    if isinstance(t, TargetState):
        return t.X[X_POS], t.X[X_MOM], t.X[X_ROT].reshape(3, 3, order="F"), set(STATE_COMPONENTS) - set(t.free)
    if isinstance(t, TargetRendezvous):
        p, v = t.point(T, prob.model.mu)
        return np.asarray(p, float), mass * np.asarray(v, float), t.R, set(t.fixed)
    n = t.normal
    x = XF[X_POS] - (XF[X_POS] @ n) * n
    e = x / np.linalg.norm(x) if np.linalg.norm(x) > 0 else t.plane_basis()[1]
    return t.radius * e, mass * np.sqrt(prob.model.mu / t.radius) * np.cross(n, e), None, {"position", "velocity"}


def maneuver_change(sol: "Solution", samples: int = DEFAULT_SAMPLES) -> tuple[float, float, float, float]:
    """What the maneuver changes (:class:`ContinuousCheck`), each component the smallest of its measures, against the
    target's point (:func:`target_point`: a state, a rendezvous's target at T, the nearest point of a target orbit):

    * position: the distance between that point and where the free motion from the plan's initial state ends at its
      final time, and the change of radius | |x_d| - |x_0| | (a raise: the raise, not the phase it also fixes);
    * velocity: the same free-motion distance in velocity, and the plan's delta-v (:func:`delta_v`);
    * attitude (rad): the free motion's angle to the target attitude, and angle(R_0^T R_d) (the slew).

    A measure below a millionth of its scale (the orbit radius L and circular speed V of :func:`scaled_miss`, 1 rad)
    is not a change; a component the target leaves free, or one with no change, is nan (not part of the maneuver).
    The fourth number is the target-error measure of the free motion (any target).  All nan when the free motion
    cannot be flown or there is no target."""
    prob, traj = sol.problem, sol.trajectory
    nan4 = (float("nan"),) * 4
    if prob.terminal is None:
        return nan4
    N = traj.X.shape[0] - 1
    try:
        free = fly(prob.model, traj.X[0], traj.t, OpenLoop.free(N), Actuators(force_frame=prob.disc.force_frame),
                   samples=samples)
    except FlightError:
        return nan4
    XF = free.X[-1].copy()
    XF[X_ROT] = nearest_rotation(XF[X_ROT].reshape(3, 3, order="F")).reshape(9, order="F")
    target = terminal_error(XF, prob, T=float(traj.t[-1]))
    xd, gd, Rd, fixed = target_point(prob, XF, float(traj.t[-1]))
    X0 = traj.X[0]
    mass, L = prob.model.mass, characteristic_length(prob)
    V = float(np.sqrt(prob.model.mu / L)) if prob.model.mu else 1.0
    rot = lambda X: X[X_ROT].reshape(3, 3, order="F")                         # noqa: E731
    measures = {"position": ([np.linalg.norm(XF[X_POS] - xd), abs(np.linalg.norm(xd) - np.linalg.norm(X0[X_POS]))], L),
                "velocity": ([np.linalg.norm(XF[X_MOM] - gd) / mass, delta_v(sol)], V),
                "attitude": ([rotation_angle(Rd.T @ rot(XF)), rotation_angle(rot(X0).T @ Rd)] if Rd is not None
                             else [], 1.0)}
    out = []
    for k, (values, scale) in measures.items():
        changes = [float(c) for c in values if np.isfinite(c) and c > 1e-6 * scale]
        out.append(min(changes) if k in fixed and changes else float("nan"))
    return (*out, target)


def delta_v(sol: "Solution") -> float:
    """The plan's delta-v: sum_j omega_j |u_f,j| / m with omega_j the scheme's quadrature weights
    (transcription.ocp.quadrature_weights, at the mesh's steps), or (|dgamma_0| + |dgamma_N|) / m of impulses;
    nan with neither."""
    mass = sol.trajectory.mass
    if sol.controls is not None:
        return float(control_weights(sol) @ np.linalg.norm(sol.u_f, axis=1) / mass)
    if sol.impulses is not None:
        imp = sol.impulses
        return float((np.linalg.norm(imp["dgamma0"]) + np.linalg.norm(imp["dgammaN"])) / mass)
    return float("nan")


def control_weights(sol: "Solution") -> np.ndarray:
    """omega_j (n,) of a plan's controls (n of them): the scheme's quadrature weights
    (transcription.ocp.quadrature_weights) at h = T/N, or at the steps h_k of a mesh -- those of its delta-v, its
    burns and its figures of merit."""
    n, N = sol.controls.shape[1], sol.N
    return quadrature_weights("lgvi" if n == N + 1 else "first_order", N, sol.h if sol.uniform else sol.steps)


def _target_error(sol: "Solution", XN: np.ndarray) -> float:
    """The Solution's terminal-error measure (problem.terminal_error) at the flown final state XN (18,):
    after the terminal impulse for an impulsive plan; nan without a target."""
    prob = sol.problem
    if prob.terminal is None:
        return float("nan")
    if sol.impulses is None:  # at the plan's final time (a rendezvous target moves with it)
        return terminal_error(XN, prob, T=float(sol.trajectory.t[-1]))
    plus = XN.copy()
    plus[X_MOM] += np.asarray(sol.impulses["dgammaN"], float)
    plus[X_ANG] += np.asarray(sol.impulses["dPiN"], float)
    return terminal_error(XN, prob, XN_plus=plus)


# ---------------------------------------------------------------------------- the miss in one number
def scaled_miss(check, problem) -> float:
    """The one scalar refinement drives below ``solver.accuracy``: the largest of the continuous check's terminal
    position miss relative to the characteristic length L, velocity miss relative to V, attitude miss (rad) and
    rate miss (rad per time unit).  With a central body L = |x_0| (the orbit radius: 1 in normalized units) and
    V = sqrt(mu / L) (the circular speed, 2 pi normalized); without one L = V = 1 (the file's units).  nan if the
    flight failed."""
    mu, L = problem.model.mu, characteristic_length(problem)
    V = float(np.sqrt(mu / L)) if mu else 1.0
    return float(max(check.terminal_position / L, check.terminal_velocity / V, check.terminal_attitude,
                     check.terminal_rate))


def characteristic_length(problem) -> float:
    """The characteristic length L of :func:`scaled_miss`: |x_0| with a central body, else 1."""
    L = float(np.linalg.norm(problem.X0[0:3])) if problem.model.mu else 1.0
    return L if L > 0 else 1.0
