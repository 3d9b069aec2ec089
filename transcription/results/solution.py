"""What every method returns: one result code, one progress record, one Solution.

A :class:`Solution` is data: a failed solve is a Solution whose ``result`` says why, never an exception unless the
caller asks (``throw=True`` raises :class:`SolveError`).  Its trajectory is the **re-simulation** of the discrete
equations with the returned controls or impulses (docs/mathematics.md §8): ``terminal_error`` is measured on what a
user would fly.
"""
from __future__ import annotations

import enum
import html
import math
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from types import MappingProxyType
from typing import Any, Mapping

import numpy as np

from ..dynamics.trajectory import Trajectory
from ..geometry.state import U_FORCE, U_MOMENT, split_state
from ..geometry.so3 import rotation_angle
from ..outcome import Iterate, Result
from . import check
from .burns import Burn, burns
from .check import control_weights, scaled_miss
from ..ocp import Problem, SmoothControl, TargetState, control_activity, engine_figures
from .start import Start
from .trace import Attempt, totals


class SolveError(RuntimeError):
    """Raised by ``solve(..., throw=True)`` for a Solution that is not successful; ``.solution`` is it."""

    def __init__(self, solution: "Solution"):
        self.solution = solution
        super().__init__(f"{solution.method}: {solution.result}: {solution.message}")


@dataclass(frozen=True, eq=False)
class Solution:
    """Outcome of one solve (or one simulation), never changed: a check that adds to it makes a new one
    (:func:`dataclasses.replace`, :meth:`with_notes`).

    method: 'direct' | 'indirect' | 'simulate'; solver: 'ipopt', 'fatrop', 'newton-armijo', ...; result: a
    :class:`Result`; verdict: the method's sentence on its last solve; trace: the method solves the strategy made
    (:class:`~transcription.results.trace.Attempt`), from which iterations, build_s and solve_s are summed; notes:
    what strategies and checks added, in words (``message`` renders the three).  trajectory: the re-simulation.
    controls: (6, n_controls) [u_f (inertial); u_m (body)] at ``control_times`` or None.  impulses: {dgamma0, dPi0
    (at t = 0), dgammaN, dPiN (at t = T)} (3,) each.  costates: (N, 12) lambda_k (indirect; the direct method's mapped
    from the NLP multipliers) or None.  history: the :class:`Iterate` records of the last solve.  stats:
    method-specific numbers, read-only.  problem: the :class:`~transcription.ocp.Problem` solved.  warm: what the next
    solve can start from (:class:`~transcription.results.start.Start` or None).  Derived: N, T, h (the mean step T/N),
    steps (N,) (h_k), ``scheme``, control_times, u_f (n, 3) (in ``force_frame``), u_m (n, 3) (body), f_inertial
    (n, 3): the applied inertial force, R_j u_f,j for a body-frame force, else u_f (docs/mathematics.md §14).
    Computed once when asked: delta_v, burns (:mod:`~transcription.results.burns`), propellant.
    """

    method: str
    solver: str
    result: Result
    verdict: str
    trajectory: Trajectory
    cost: float
    terminal_error: float
    problem: "Problem | None" = field(default=None, repr=False)
    controls: np.ndarray | None = None
    impulses: dict[str, np.ndarray] | None = None
    costates: np.ndarray | None = None
    history: tuple[Iterate, ...] = ()
    stats: Mapping[str, Any] = field(default_factory=dict)
    trace: tuple[Attempt, ...] = ()
    notes: tuple[str, ...] = ()
    warm: Start | None = field(default=None, repr=False)
    #: the continuous check (transcription.results.check.ContinuousCheck): the plan flown through the continuous
    #: equations (None: not flown)
    continuous: Any = field(default=None, repr=False)
    #: refinement to ``solver.accuracy`` (transcription/strategy/refine.py): one record per mesh level (level, N,
    #: miss, iterations, time, ...); empty without refinement
    mesh: tuple = field(default=(), repr=False)
    #: what the application layer knows of the physical world the problem lives in (problems/: the maneuver file's
    #: epoch, frame, units and central body, a problems.physical.Physical), carried so that exports of this Solution
    #: need not be told them; None for a Problem built in Python.  Set by the caller, never read by the core.
    physical: Any = field(default=None, repr=False)

    # derived, computed once: the horizon, the scheme, the controls' times and components
    N: int = field(init=False, repr=False)
    T: float = field(init=False, repr=False)
    h: float = field(init=False, repr=False)
    steps: np.ndarray = field(init=False, repr=False)
    scheme: str = field(init=False, repr=False)
    control_times: np.ndarray | None = field(init=False, repr=False)
    u_f: np.ndarray | None = field(init=False, repr=False)
    u_m: np.ndarray | None = field(init=False, repr=False)
    force_frame: str = field(init=False, repr=False)
    f_inertial: np.ndarray | None = field(init=False, repr=False)

    def __getstate__(self) -> dict:
        """Pickled with its read-only ``stats`` as a plain dict (a mappingproxy does not pickle)."""
        return {**self.__dict__, "stats": dict(self.stats)}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, stats=MappingProxyType(state["stats"]))

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        put("stats", MappingProxyType(dict(self.stats)))
        put("history", tuple(self.history))
        put("trace", tuple(self.trace))
        put("notes", tuple(n for n in self.notes if n))
        put("mesh", tuple(self.mesh))
        t = self.trajectory.t
        put("N", len(t) - 1)
        put("T", float(t[-1]))
        put("h", self.T / self.N)
        put("steps", np.diff(t))
        put("scheme", self.problem.scheme if self.problem is not None else "")
        c = self.controls
        # controls u_0..u_N (lgvi) at t_0..t_N, or u_1..u_N (first_order) at t_1..t_N; u_f inertial, u_m body
        put("control_times", None if c is None else (t[1:] if c.shape[1] == len(t) - 1 else t))
        put("u_f", None if c is None else c[U_FORCE].T)
        put("u_m", None if c is None else c[U_MOMENT].T)
        disc = getattr(self.problem, "disc", None)
        put("force_frame", getattr(disc, "force_frame", "inertial"))
        f = self.u_f
        if c is not None and self.force_frame != "inertial" and len(t):
            nodes = np.searchsorted(t, self.control_times)     # the node each control belongs to
            f = np.asarray(disc.applied_force(self.trajectory.R[nodes], self.u_f), dtype=float)
        put("f_inertial", f)

    # ------------------------------------------------------------------ the force's use, computed once when asked
    @cached_property
    def delta_v(self) -> float:
        """sum_j omega_j |u_f,j| / m (impulses: (|dgamma_0| + |dgamma_N|) / m; nan with neither), in the problem's
        velocity unit (:func:`~transcription.results.check.delta_v`)."""
        return check.delta_v(self)

    @cached_property
    def burns(self) -> tuple[Burn, ...]:
        """The burns of the force controls above 1e-3 of the force bound (of the peak |u_f| without one): a tuple of
        :class:`~transcription.results.burns.Burn` (() without smooth controls).  Another threshold:
        ``transcription.results.burns.burns(sol, threshold)``."""
        return burns(self)

    @cached_property
    def propellant(self) -> float:
        """m delta_v / c, the propellant of the plan's impulse for an engine of exhaust velocity c (nan without
        one, or without smooth controls): the dynamics keep the mass constant, so this is the rocket equation's
        m (1 - exp(-delta_v / c)) to first order in delta_v / c (transcription.results.burns)."""
        bound = getattr(getattr(self.problem, "control", None), "force_bound", None)
        c = None if bound is None else bound.exhaust_velocity
        if c is None or self.controls is None:
            return float("nan")
        return float(self.trajectory.mass * self.delta_v / c)

    # ------------------------------------------------------------------ derived from the trace
    @property
    def iterations(self) -> int:
        """The iterations of every solve of the trace (the starts' own solves included)."""
        return totals(self.trace)[0]

    @property
    def build_s(self) -> float:
        return totals(self.trace)[1]

    @property
    def solve_s(self) -> float:
        return totals(self.trace)[2]

    @property
    def message(self) -> str:
        """What happened, in words: the verdict on the last solve, the starts tried (when there were several) and the
        notes; rendered from the data, never parsed back."""
        parts = [self.verdict] if self.verdict else []
        if len(self.trace) > 1:
            lines, before = [], None
            for a in self.trace:       # a start not run says why once: the verdict's words, or its neighbour's
                said = a.result is None and a.note and (a.note == self.verdict or a.note == before)
                lines.append(f"{a.label}: {'as said' if a.note == self.verdict else 'the same'}" if said else a.line())
                before = a.note if a.result is None else None
            parts.append("initial guesses tried: " + "; ".join(lines))
        return "; ".join(parts + list(self.notes))

    def with_notes(self, *notes: str, **stats) -> "Solution":
        """This Solution with ``notes`` added to its message and ``stats`` to its stats."""
        return replace(self, notes=self.notes + tuple(notes), stats={**self.stats, **stats})

    @property
    def converged(self) -> bool:
        return self.result.successful

    @property
    def uniform(self) -> bool:
        """Its node times are equally spaced (to round-off): a uniform mesh."""
        d = self.steps
        return bool(d.size == 0 or np.all(np.abs(d - self.h) <= 1e-9 * abs(self.h)))

    @property
    def continuous_miss(self) -> float | None:
        """The continuous check's terminal miss as ``solver.accuracy`` judges it
        (:func:`~transcription.results.check.scaled_miss`).  None when not flown (or without a Problem), nan when the
        flight failed; the raw components are ``continuous.terminal_*``."""
        if self.continuous is None or self.problem is None:
            return None
        return scaled_miss(self.continuous, self.problem)

    # ------------------------------------------------------------------ display
    def display(self) -> dict[str, str]:
        """What a notebook shows of this Solution, as text (scalars only): method, status, cost, terminal error,
        continuous miss ('-' when not flown), max |R^T R - I|, iterations, build and solve seconds, N, T, scheme."""
        def num(x, fmt):
            return "-" if x is None or not np.isfinite(x) else format(float(x), fmt)

        na = self.result is Result.not_applicable
        orth = self.trajectory.orthogonality()["max_orthogonality_error"] if len(self.trajectory.t) else math.nan
        return {"method": self.method, "status": self.result.value, "cost": num(math.nan if na else self.cost, ".10g"),
                "terminal error": num(math.nan if na else self.terminal_error, ".1e"),
                "continuous miss": num(self.continuous_miss, ".1e"),
                "flown miss": "-" if self.continuous is None or not np.isfinite(self.continuous.maneuver_fraction)
                else f"{100 * self.continuous.maneuver_fraction:.2g} % of the maneuver",
                "max |R^T R - I|": num(math.nan if na else orth, ".1e"), "iterations": str(self.iterations),
                "build s": num(self.build_s, ".2f"), "solve s": num(self.solve_s, ".2f"), "N": str(self.N),
                "T": num(self.T, ".6g"), "scheme": self.scheme or "-"}

    def __repr__(self) -> str:
        d = self.display()
        return (f"Solution({d['method']} {d['status']}: cost {d['cost']}, terminal error {d['terminal error']}, "
                f"continuous miss {d['continuous miss']}, flown miss {d['flown miss']}, "
                f"max |R^T R - I| {d['max |R^T R - I|']}, {d['iterations']} iterations, build {d['build s']} s, "
                f"solve {d['solve s']} s; N = {d['N']}, T = {d['T']}, {d['scheme']})")

    def _repr_html_(self) -> str:
        return html_table([self], caption=f"{self.method}: {self.result.message}")

    # ------------------------------------------------------------------ output
    def summary(self) -> dict[str, Any]:
        """JSON-ready scalar summary (the per-method block of summary.json)."""
        out = {
            "method": self.method,
            "status": self.result.value,
            "message": self.message,
            "converged": bool(self.converged),
            "cost": float(self.cost),
            "terminal_error": float(self.terminal_error),
            "iterations": int(self.iterations),
            "build_s": float(self.build_s),
            "solve_s": float(self.solve_s),
            "N": int(self.N),
            "T": float(self.T),
            "h": float(self.h),
            "discretization": self.scheme,
            "solver": self.solver,
        }
        out.update(self.trajectory.orthogonality())
        if not self.uniform:                # a non-uniform mesh (docs/mathematics.md §16)
            out.update(h_min=float(self.steps.min()), h_max=float(self.steps.max()))
        if self.controls is not None:
            out["force_frame"] = self.force_frame
            out.update(burn_summary(self))
        # scalars, and lists of words
        out.update({k: v for k, v in self.stats.items() if isinstance(v, (int, float, str, bool, type(None))) or
                    (isinstance(v, list) and all(isinstance(x, str) for x in v))})
        if self.trace:                      # the solves tried (what a failure tried), in words
            out["guesses_tried"] = [a.line() for a in self.trace]
        out.update(figures_of_merit(self))
        if self.continuous is not None:     # the continuous check: continuous_* keys
            out.update(self.continuous.summary())
            out["continuous_miss"] = self.continuous_miss     # the scaled miss shown and bounded by accuracy
        if self.mesh:                       # refinement to solver.accuracy: the mesh history
            out["mesh_history"] = [dict(m) for m in self.mesh]
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        """Arrays for the .npz file: t, x, v, gamma, R, Omega, Pi (nodes); u_f (in the problem's force frame),
        u_m (body), t_u, f_inertial (the applied inertial force R_j u_f,j, or u_f) (controls); lam (costates);
        impulses."""
        tr = self.trajectory
        out = {"t": tr.t, "x": tr.x, "v": tr.v, "gamma": tr.gamma, "R": tr.R, "Omega": tr.Omega, "Pi": tr.Pi}
        if self.controls is not None:
            out["u_f"], out["u_m"], out["t_u"] = self.u_f, self.u_m, self.control_times
            out["f_inertial"] = self.f_inertial
        if self.impulses is not None:
            out.update({k: np.asarray(v) for k, v in self.impulses.items()})
        if self.costates is not None:
            out["lam"] = self.costates
        if self.continuous is not None:     # the continuous check's deviation at each node (its figure)
            out.update(self.continuous.arrays())
        return out


#: the colour of a status in notebooks (as in report.html: converged green, not applicable grey, else red)
_STATUS_COLOUR = {True: "#1a7f37", None: "#6e7781", False: "#cf222e"}


def html_table(solutions: list[Solution], caption: str = "", footer: str = "") -> str:
    """An HTML table of Solutions for notebooks: a row per Solution with its :meth:`Solution.display` and its
    message beneath (escaped), the status coloured; ``caption`` above and ``footer`` below (escaped)."""
    cols = list(solutions[0].display())
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    rows = []
    for s in solutions:
        d = s.display()
        ok = None if s.result is Result.not_applicable else s.converged
        cells = "".join(f'<td style="color:{_STATUS_COLOUR[ok]};font-weight:bold">{html.escape(v)}</td>'
                        if c == "status" else f"<td>{html.escape(v)}</td>" for c, v in d.items())
        rows.append(f"<tr>{cells}</tr><tr><td colspan=\"{len(cols)}\" style=\"text-align:left;font-size:smaller\">"
                    f"{html.escape(s.message)}</td></tr>")
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    foot = f"<p>{html.escape(footer)}</p>" if footer else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>{foot}"


def figures_of_merit(sol: "Solution") -> dict[str, Any]:
    """What an engineer reads off a maneuver (docs/mathematics.md §8), computed once (summary.json, the report, sweeps):
    delta_v = sum_j omega_j |u_f,j| / m (impulsive: (|dgamma_0| + |dgamma_N|) / m); angular_impulse = sum_j omega_j
    |u_m,j| (impulsive: |dPi_0| + |dPi_N|), omega_j the quadrature weights of the scheme
    (transcription.ocp.quadrature_weights) at h = T/N (at the steps h_k of a mesh); peak_force, peak_moment = max_j
    |u_f,j|, max_j |u_m,j|; engine_on_time (and engine_off_axis_relative) of transcription.ocp.engine_figures; with a
    bound (not a removed control), force_time_at_bound / moment_time_at_bound = sum of omega_j over the controls at the
    bound (transcription.ocp.control_activity); with a state target fixing the attitude, terminal_attitude_error_deg =
    angle(R_d^T R_N); with path constraints, min_margin_<kind> (``_2``, ... for repeats) = min_k margin_k in the
    constraint's unit (< 0: violated).  Fields that do not apply are left out; a Result.not_applicable Solution has
    none.  Pure."""
    out: dict[str, Any] = {}
    if sol.result is Result.not_applicable:
        return out
    prob = sol.problem
    if sol.controls is not None:
        uf, um = sol.u_f, sol.u_m
        om = control_weights(sol)
        nf, nm = np.linalg.norm(uf, axis=1), np.linalg.norm(um, axis=1)
        out.update(delta_v=sol.delta_v, angular_impulse=float(om @ nm),
                   peak_force=float(nf.max(initial=0.0)), peak_moment=float(nm.max(initial=0.0)))
        ctrl = getattr(prob, "control", None)
        if isinstance(ctrl, SmoothControl):
            for name, act in control_activity(ctrl, sol.controls, om, sol.control_times).items():
                out[f"{name}_time_at_bound"] = act["time_at_bound"]
        out.update(engine_figures(uf, om, getattr(ctrl, "force_bound", None)))
    elif sol.impulses is not None:
        imp = sol.impulses
        out.update(delta_v=sol.delta_v, angular_impulse=float(np.linalg.norm(imp["dPi0"]) + np.linalg.norm(imp["dPiN"])))
    term = getattr(prob, "terminal", None)
    if isinstance(term, TargetState) and "attitude" in term.fixed and np.all(np.isfinite(sol.trajectory.X[-1])):
        Rd = split_state(term.X)[2]
        out["terminal_attitude_error_deg"] = float(np.degrees(rotation_angle(Rd.T @ sol.trajectory.R[-1])))
    seen: dict[str, int] = {}
    for c in getattr(prob, "constraints", ()):
        seen[c.kind] = seen.get(c.kind, 0) + 1
        key = f"min_margin_{c.kind}" + (f"_{seen[c.kind]}" if seen[c.kind] > 1 else "")
        out[key] = float(np.min(c.margin(sol.trajectory)))
    return out


def burn_summary(sol: "Solution") -> dict[str, Any]:
    """summary.json's record of the force's use, in the problem's units: ``burns`` (a list of the
    :class:`~transcription.results.burns.Burn` s as objects), ``switch_times`` ({force, moment}: the times each bounded
    control enters or leaves its bound, :func:`~transcription.ocp.control_activity`) and, for an engine with an
    exhaust velocity, ``exhaust_velocity``, ``propellant`` (m delta_v / c, the mass constant in the dynamics) and
    ``propellant_fraction`` (of the mass)."""
    out: dict[str, Any] = {"burns": [asdict(b) for b in sol.burns]}
    ctrl = getattr(sol.problem, "control", None)
    if isinstance(ctrl, SmoothControl):
        act = control_activity(ctrl, sol.controls, control_weights(sol), sol.control_times)
        out["switch_times"] = {name: a["switch_times"] for name, a in act.items()}
        c = ctrl.force_bound.exhaust_velocity if ctrl.force_bound is not None else None
        if c is not None:
            out.update(exhaust_velocity=c, propellant=sol.propellant,
                       propellant_fraction=sol.propellant / sol.trajectory.mass)
    return out


def to_jsonable(obj):
    """Convert numpy scalars/arrays, enums and dataclasses inside dicts/lists to plain Python."""
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating,)):
        return float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, Iterate):
        return to_jsonable(obj.as_dict())
    if hasattr(obj, "__dataclass_fields__"):
        return to_jsonable(asdict(obj))
    return obj
