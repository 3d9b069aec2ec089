"""The direct method's solve: one NLP (built once per Problem and options) solved by IPOPT -- or fatrop's stage-ordered
form -- from one Start; which starts to try is the strategy's (:mod:`transcription.strategy`)."""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Mapping

import casadi as ca
import numpy as np

from ...dynamics.lgvi import two_point
from ...geometry.state import NU, X_ANG
from ...nlp.curvature import Curvature, least_curvature
from ...nlp.solvers import ipopt_options, make_ipopt
from ...nlp.transcription import SmoothTranscription
from ...ocp import Problem
from ...options import DirectOptions
from ...outcome import Result
from ...results.solution import Solution
from ...results.start import Origin, Start
from ..base import Progress, failed_solution
from .fatrop import solve_fatrop
from .solution import nlp_solution


def transcription(problem: Problem, options: DirectOptions,
                  stage_order: bool = False) -> tuple[SmoothTranscription, float]:
    """The NLP of ``problem`` for ``options`` (built once, kept with the Problem:
    :meth:`~transcription.ocp.Problem.memo`) and the seconds building it took now (0 when built before)."""
    made = []

    def build():
        t0 = time.perf_counter()
        tr = SmoothTranscription(problem, options, stage_order=stage_order)
        made.append(time.perf_counter() - t0)
        return tr

    tr = problem.memo(("direct", bool(options.cayley_variables), bool(options.jit), stage_order), build)
    return tr, (made[0] if made else 0.0)


class _Listener:
    """The progress of one NLP's solves: its solver's iteration callback, numbered from 0 in each solve and sent to
    that solve's ``report`` (the solvers of an NLP are kept and reused by the solves that follow)."""

    def __init__(self):
        self.report, self.k = None, 0

    def __call__(self, it) -> None:
        if self.report is not None:
            self.report(replace(it, iteration=self.k))
        self.k += 1


def _solver(tr: SmoothTranscription, ipopt: dict[str, Any], listen: bool) -> tuple[ca.Function, float]:
    """IPOPT with ``ipopt`` on the NLP ``tr`` (made once per options and kept on ``tr``; with ``listen`` its
    iterations go to ``tr.listener``) and the seconds it took to make it (0 when kept)."""
    key = (tuple(sorted((k, str(v)) for k, v in ipopt.items())), listen)
    solvers = tr.__dict__.setdefault("solvers", {})
    if key in solvers:
        return solvers[key], 0.0
    t0 = time.perf_counter()
    listener = tr.__dict__.setdefault("listener", _Listener())
    solvers[key] = make_ipopt("direct_ms", tr.nlp, ipopt, listener if listen else None, tr.scales.objective)
    return solvers[key], time.perf_counter() - t0


def rollout_start(problem: Problem) -> Start:
    """The free motion from X0 on ``problem``'s grid (controls zero)."""
    X, _ = problem.disc.simulate(problem.X0, None, problem.steps, problem.N)
    return Start(t=problem.times, X=X, U=np.zeros((NU, problem.disc.n_controls(problem.N))), scheme=problem.scheme,
                 origin=Origin.rollout)


def on_grid(problem: Problem, start: Start | None) -> Start:
    """``start`` on ``problem``'s grid (resampled if it is not; the free motion when None).  Resampled onto another
    number of steps of an LGVI, its angular momenta are those its attitudes imply (Discretization.implied_momenta):
    interpolated linearly they broke the Cayley rows by up to 0.1 (scaled) where the body turns fast, and a
    refinement level of an engine raise started at a residual of 1.9 and failed (docs/mathematics.md §11)."""
    if start is None:
        return rollout_start(problem)
    fitted = start.fit(problem.N, problem.scheme, problem.fractions)[0]
    if fitted is start or start.N == problem.N or not two_point(problem.scheme):
        return fitted
    X = fitted.X.copy()
    X[:-1, X_ANG] = problem.disc.implied_momenta(X, fitted.U, problem.steps)
    return replace(fitted, X=X) if np.all(np.isfinite(X)) else fitted


@dataclass(frozen=True)
class Direct:
    """The direct method (module docstring): one IPOPT solve (``options.solver: fatrop``: one fatrop solve) from one
    Start.  ``options``: :class:`~transcription.options.DirectOptions` (``max_iter`` the budget); ``ipopt``: a
    strategy's IPOPT presets for this solve, never overriding the user's raw ``options.options``.  A start carrying a
    :class:`~transcription.results.start.Point` of this very NLP starts IPOPT at its x (clipped to the bounds) and,
    with ``warm_start_init_point: yes``, its multipliers; otherwise multipliers of an NLP of the same structure
    start its duals."""

    options: DirectOptions = field(default_factory=DirectOptions)
    ipopt: Mapping[str, Any] = field(default_factory=dict)
    name: ClassVar[str] = "direct"
    kind: ClassVar[str] = "smooth"

    def not_covered(self, problem: Problem) -> str:
        """What of ``problem`` the direct method's NLP does not cover: impulsive control (its impulsive solver does)."""
        return "" if problem.kind == "smooth" else "impulsive control (the direct method's impulsive solver covers it)"

    def replace(self, ipopt: Mapping[str, Any] | None = None, **options) -> "Direct":
        """This method with some options changed (DirectOptions fields) and, with ``ipopt``, those IPOPT options added
        to this solve's."""
        return Direct(self.options.replace(**options) if options else self.options,
                      {**self.ipopt, **(ipopt or {})})

    def curvature(self, problem: Problem, solution: Solution) -> Curvature | None:
        """The least curvature of the Lagrangian of ``problem``'s NLP on the active constraints' tangent space at
        ``solution``'s exact point (:func:`~transcription.nlp.curvature.least_curvature`; its direction in the
        NLP's scaled variables); None when the solution carries no point of this NLP (fatrop's, another grid's)."""
        point = solution.warm.point if solution.warm is not None else None
        if self.options.solver != "ipopt" or point is None or point.lam_g is None:
            return None
        tr, _ = transcription(problem, self.options)
        if point.key != tr.point_key:
            return None
        return least_curvature(tr.nlp, tr.lbx, tr.ubx, point.x, point.lam_g)

    def solve(self, problem: Problem, start: Start | None = None, report: Progress | None = None,
              label: str = "") -> Solution:
        """One solve of ``problem``'s NLP from ``start`` (resampled onto its grid if need be; the free motion when
        None); failures are data.  ``label`` names the solve in the Solution's trace (default: the start's origin)."""
        if problem.kind != "smooth":
            raise ValueError("the direct method's NLP solves smooth-control problems (impulsive ones: "
                             "transcription.methods.impulsive)")
        start = on_grid(problem, start)
        label = label or str(start.origin)
        if not start.finite:
            return failed_solution(problem, "direct", self.options.solver, Result.non_finite,
                                   "the initial guess is not finite (overflow or a singular potential along the free "
                                   "motion): check the model and the states")
        if self.options.solver == "fatrop":
            return solve_fatrop(problem, self.options, start, label)
        return self._ipopt(problem, start, report, label)

    def _ipopt(self, problem: Problem, start: Start, report: Progress | None, label: str) -> Solution:
        tr, build_s = transcription(problem, self.options)
        point = start.point if start.point is not None and start.point.key == tr.point_key else None
        exact = point is not None and point.lam_g is not None and self.ipopt.get("warm_start_init_point") == "yes"
        duals = not exact and start.multipliers is not None and start.nlp_key == tr.nlp.key
        ipopt = ipopt_options(self.options, warm_duals=exact or duals)
        for k, v in self.ipopt.items():
            ipopt.setdefault(k, v)
        solver, made_s = _solver(tr, ipopt, report is not None)
        x0 = tr.initial_point(start) if point is None else np.clip(point.x, tr.lbx, tr.ubx)
        args = dict(x0=x0, lbx=tr.lbx, ubx=tr.ubx, lbg=tr.nlp.lbg, ubg=tr.nlp.ubg)
        if exact:
            args.update(lam_g0=point.lam_g, lam_x0=point.lam_x)
        elif duals:
            args["lam_g0"] = tr.scaled_multipliers(start.multipliers)
        if report is not None:
            tr.listener.report, tr.listener.k = report, 0
        t0 = time.perf_counter()
        out = solver(**args)
        solve_s = time.perf_counter() - t0
        stats = solver.stats()
        return nlp_solution(problem, self.options, tr, out, stats, str(stats.get("return_status", "unknown")), "ipopt",
                            build_s + made_s, solve_s, label)


__all__ = ["Direct", "on_grid", "rollout_start", "transcription"]
