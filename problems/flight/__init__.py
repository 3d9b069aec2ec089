"""Flying a plan (issue 25): a Monte Carlo of flights through the continuous equations of a truth model,
open loop and with the tracker, on a local process pool or a Dask cluster.

    import se3ocp
    man = se3ocp.load("configs/e3_inclination_change.yaml", ["horizon.N=400", "discretization=lgvi"])
    res = se3ocp.fly(man, {"truth": {"gravity": {"kind": "j2", "J2": 1.08e-3, "radius": 0.9}},
                           "errors": {"force_scale": 0.02}, "runs": 50})
    res.statistics()["lqr"]["position_miss"]["p95"]

* ``schema`` -- the ``flight:`` block (:class:`FlightSpec`: truth, errors, feedback, mpc, weights, navigation, runs,
  seed);
* ``navigation`` -- the plan's estimator, each run's measurement noise, the estimation errors (with ``navigation:``);
* ``plan`` -- the plan as plain data, the truth body, and each run's errors from its own
  ``SeedSequence(seed).spawn(runs)[i]`` (so the statistics do not depend on the workers);
* ``task`` -- :func:`fly_runs`, the unit of work (a few runs, every feedback mode), and the figures of
  merit of a flight (terminal misses against the plan's last node, delta-v, peaks, saturation, margins);
* ``run`` -- :func:`run_flights` on any executor of ``problems.sweep.executors``, :class:`FlightResult`
  and its statistics (mean, p50, p95, p99.7);
* ``output`` -- flights.csv, summary.json, runs/NNNN.npz, plan.npz, gains.npz; ``figures`` -- the figures;
* ``command`` -- ``se3ocp fly``.

How a flight is flown (``truth.integrator: basilisk``: in Basilisk's spacecraft instead, problems.flight.basilisk):
the truth body (the plan's, under the flight's gravity, with the run's inertia)
is integrated by the continuous engine (transcription/flight, docs/mathematics.md §11) from the run's
initial state, the plan's controls applied between the nodes as the scheme defines them, through the
run's actuators (scale factors, misalignment rotations); with feedback ``lqr`` the tracker's correction
(docs/mathematics.md §12), computed from the flown state at each node (with ``navigation:``, from the estimate of
its noisy measurement, §12 *Navigation*), is added over the interval; with
``mpc`` the remainder of the plan is re-planned from the flown state every ``mpc.replan_every`` steps
(transcription/mpc.py, docs/mathematics.md §12) and flown open loop in between.  With ``actuators`` (``actuators``
module) the force is delivered by on/off thruster pulses and the moment by reaction wheels, period by period
(transcription/closedloop/actuated.py, docs/mathematics.md §11).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from .run import FlightResult, run_flights
from .schema import FlightSpec, parse_flight, preset_gravity, with_changes

__all__ = ["FlightResult", "FlightSpec", "fly", "load_flight", "parse_flight", "run_flights", "with_changes"]


def load_flight(path: str | Path, maneuver=None) -> FlightSpec:
    """The flight block of a YAML file holding ``{flight: {...}}`` (a maneuver file with one, or a file of
    its own) for ``maneuver`` (its central-body preset fills a j2 truth's J2 and radius); ConfigError naming the
    file and field."""
    from ..schema import Validator, read_yaml_file

    doc = read_yaml_file(path)
    if not isinstance(doc, dict) or "flight" not in doc:
        Validator(str(path)).fail("flight", "missing: the file must hold a mapping with a 'flight' block")
    return parse_flight(doc["flight"], str(path), preset=preset_gravity(getattr(maneuver, "physical", None)))


def fly(plan, flight: FlightSpec | Mapping | str | Path | None = None, *, maneuver=None, runs: int | None = None,
        feedback: str | None = None, workers: int | None = 1, scheduler: str | None = None,
        save_runs: int = 0) -> FlightResult:
    """Fly a plan ``runs`` times (``se3ocp.fly``).

    plan: a Maneuver (solved first by the direct method) or a converged smooth-control Solution with
    ``maneuver=`` the Maneuver it solves.  flight: a FlightSpec, a flight block (mapping), a YAML file
    holding one, or None (the maneuver's own ``flight:`` block, else the defaults).  runs, feedback
    ('none', 'lqr', 'mpc', 'both', 'all'): change the block's.  workers (default 1: in-process), scheduler (a Dask
    address): where the runs go.  save_runs: keep the whole flights of the first runs (``saved``)."""
    from ...transcription.results.solution import Solution
    from ..api import solve
    from ..maneuvers import Maneuver

    if isinstance(plan, Maneuver):
        maneuver, plan = plan, solve(plan, "direct")
    if not isinstance(plan, Solution) or not isinstance(maneuver, Maneuver):
        raise TypeError("fly: expected a Maneuver, or a Solution and maneuver= the Maneuver it solves")
    check_plan(plan)
    spec = _spec(flight, maneuver)
    spec = with_changes(spec, spec_source(flight, maneuver), runs=runs, feedback=feedback)
    check_feedback(maneuver, spec, spec_source(flight, maneuver))
    check_truth(maneuver, spec, spec_source(flight, maneuver))
    check_replanned_plan(maneuver, plan, spec, spec_source(flight, maneuver))
    check_truth_plan(plan, spec, spec_source(flight, maneuver))
    return run_flights(maneuver, plan, spec, workers=workers, scheduler=scheduler, save_runs=save_runs)


def check_plan(sol) -> None:
    """ValueError unless ``sol`` is a converged plan with smooth controls (what a flight flies)."""
    if sol.controls is None or sol.problem is None or sol.problem.kind != "smooth":
        raise ValueError(f"the {sol.method} solution has no smooth controls: only smooth-control plans are flown")
    if not sol.converged:
        raise ValueError(f"the {sol.method} plan did not converge ({sol.result}: {sol.message}); nothing to fly")


def check_feedback(maneuver, spec: FlightSpec, source: str) -> None:
    """ConfigError (``flight.feedback``) when MPC is asked for a plan whose re-plans the indirect method's
    Newton step does not cover (transcription.closedloop.mpc)."""
    from ...transcription.closedloop.mpc import replan_not_covered
    from ..schema import ConfigError

    reason = replan_not_covered(maneuver.problem) if "mpc" in spec.modes else ""
    if reason:
        raise ConfigError(source, "flight.feedback", f"mpc re-plans by the indirect method's Newton step, which "
                          f"does not cover {reason}; fly this plan with none or lqr")


def check_truth(maneuver, spec: FlightSpec, source: str) -> None:
    """ConfigError when the maneuver cannot carry the flight's truth forces (problems.flight.forces.check_forces) or
    its actuators (problems.flight.actuators.check_actuators), or when the truth is Basilisk's and Basilisk is not
    installed."""
    from ..schema import ConfigError
    from .actuators import check_actuators
    from .basilisk import available
    from .forces import check_forces

    if spec.integrator == "basilisk" and not available():
        raise ConfigError(source, "flight.truth.integrator", "basilisk needs Basilisk installed (pip install "
                          "'se3ocp[basilisk]', PyPI bsk); or fly with integrator cvodes")
    bad = check_forces(maneuver, spec.resolved["truth"]) or check_actuators(maneuver, spec.actuators)
    if bad:
        raise ConfigError(source, f"flight.{bad[0]}", bad[1])


def check_truth_plan(plan, spec: FlightSpec, source: str) -> None:
    """ConfigError (``flight.truth.integrator``) when a Basilisk truth is asked for a plan on a non-uniform mesh:
    Basilisk's clock steps by one fixed length (problems.flight.basilisk)."""
    from ..schema import ConfigError

    if spec.integrator == "basilisk" and not plan.uniform:
        d = plan.steps
        raise ConfigError(source, "flight.truth.integrator", f"basilisk flies plans of equal steps only; this plan's "
                          f"steps range from {d.min():.6g} to {d.max():.6g} (a refined mesh): fly it with cvodes")


def check_replanned_plan(maneuver, plan, spec: FlightSpec, source: str) -> None:
    """ConfigError (``flight.feedback``) when MPC is asked for a plan that touches a path constraint the re-plans
    only check (transcription.closedloop.mpc.touching; within the direct method's solver.direct.terminal_tol)."""
    from ...transcription.closedloop.mpc import touching
    from ..schema import ConfigError

    tol = maneuver.direct.terminal_tol
    reason = touching(maneuver.problem, plan.trajectory.X, tol) if "mpc" in spec.modes else ""
    if reason:
        raise ConfigError(source, "flight.feedback", f"mpc: {reason}, within solver.direct.terminal_tol {tol:g}: the "
                          f"re-plans' Newton step leaves out a path constraint that is active; fly this plan with none or lqr")


def spec_source(flight: Any, maneuver) -> str:
    return str(flight) if isinstance(flight, (str, Path)) else maneuver.source


def _spec(flight: Any, maneuver) -> FlightSpec:
    if isinstance(flight, FlightSpec):
        return flight
    if isinstance(flight, (str, Path)):
        return load_flight(flight, maneuver)
    if flight is None:
        flight = maneuver.resolved.get("flight", {})
    return parse_flight(dict(flight), maneuver.source, preset=preset_gravity(maneuver.physical))
