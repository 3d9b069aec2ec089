"""What a flight needs besides the flight block: the plan as plain data (so that a worker process or a
Dask worker can rebuild it), the truth body, and each run's sampled errors.

Sampling (docs: problems/flight/__init__.py).  Run i draws its errors from its own generator,
``default_rng(SeedSequence(seed).spawn(runs)[i])``, always the same standard normals in the same order
(whatever the 1-sigma values, so that switching one error on leaves the others' draws unchanged):

    initial offset z0 (12: position, velocity, attitude, angular velocity), force scale (1), force
    misalignment (3), moment scale (1), moment misalignment (3), inertia scale (3),

so a run's errors depend on the seed and its index only, never on the workers or the order runs finish in.
"""
from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass

import numpy as np

from ...transcription.dynamics.flight import Actuators
from ...transcription.geometry.state import NX, X_ANG, X_MOM, X_POS, X_ROT
from ...transcription.geometry.so3 import exp_so3
from ...transcription.dynamics.model import BodyModel
from ...transcription.outcome import Result
from ...transcription.results.solution import Solution
from ...transcription.dynamics.trajectory import Trajectory
from ...transcription.results.start import start_of
from ..maneuvers import Maneuver, _body, parse_maneuver
from ..schema import Validator
from .schema import FlightSpec

#: standard normals drawn per run, in this order (see the module docstring)
DRAWS = (("position", 3), ("velocity", 3), ("attitude", 3), ("angular_velocity", 3), ("force_scale", 1),
         ("force_misalignment", 3), ("moment_scale", 1), ("moment_misalignment", 3), ("inertia_scale", 3))


def plan_payload(man: Maneuver, sol: Solution) -> dict:
    """The plan as plain data: the resolved maneuver document, its source, the method, the node times,
    states and controls, and the costates of its warm start (the re-plans' warm start, transcription.closedloop.mpc;
    absent when it has none); ``key`` identifies it (workers cache what they build from it)."""
    doc = copy.deepcopy(man.resolved)
    arrays = {"t": np.asarray(sol.trajectory.t, float), "X": np.asarray(sol.trajectory.X, float),
              "U": np.asarray(sol.controls, float)}
    warm = sol.warm
    dual = {"costates": sol.costates if warm is None else warm.costates, "lam0": None if warm is None else warm.lam0}
    arrays.update({k: np.asarray(v, float) for k, v in dual.items() if v is not None})
    h = hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode())
    for a in arrays.values():
        h.update(a.tobytes())
    return {"doc": doc, "source": man.source, "method": sol.method, **arrays, "key": h.hexdigest()}


_PLANS: dict = {}


def load_plan(payload: dict) -> tuple[Maneuver, Solution]:
    """The Maneuver and the plan's Solution (its trajectory and controls) of a :func:`plan_payload`,
    built once per process."""
    key = payload["key"]
    if key not in _PLANS:
        if len(_PLANS) >= 4:
            _PLANS.clear()
        man = parse_maneuver(copy.deepcopy(payload["doc"]), payload["source"])
        problem = plan_problem(man.problem, payload["t"])
        model = problem.model
        warm = start_of(payload["t"], payload["X"], payload["U"], man.problem.scheme, payload["method"],
                        costates=payload.get("costates"), lam0=payload.get("lam0"))
        sol = Solution(method=payload["method"], solver="", result=Result.converged, verdict="the plan",
                       trajectory=Trajectory(t=payload["t"], X=payload["X"], mass=model.mass, inertia=model.inertia),
                       cost=float("nan"), terminal_error=float("nan"), problem=problem, controls=payload["U"], warm=warm)
        _PLANS[key] = (man, sol)
    return _PLANS[key]


def plan_problem(problem, t: np.ndarray):
    """The maneuver's Problem on the plan's own steps (node times t, (N+1,)): a plan refined on an adaptive mesh
    (docs/mathematics.md §16) has more and unequal steps than the file's N, which the re-plans of MPC run on
    (transcription.closedloop.mpc.Replanner.steps); the Problem itself for a plan of equal steps (a re-plan takes its h)."""
    d = np.diff(np.asarray(t, float))
    h = (t[-1] - t[0]) / d.size
    if np.all(np.abs(d - h) <= 1e-9 * abs(h)):          # uniform, as Solution.uniform
        return problem
    return problem.replace(N=int(d.size), mesh=d)


def truth_body(man: Maneuver, spec: FlightSpec) -> BodyModel:
    """The truth's body: the plan's body under the flight's gravity (the plan's own without one)."""
    if spec.gravity is None:
        return man.problem.model
    body, _, _, _ = _body(Validator(man.source), man.resolved["model"], spec.gravity)
    return body.body_model()


@dataclass(frozen=True)
class RunErrors:
    """One run's sampled errors: z0 (12) the initial offset in tangent coordinates from the plan's X_0
    (position, momentum m dv, attitude rotation vector (body), angular momentum J_truth dOmega);
    X0 (18) the truth's initial state (momenta of the truth body); actuators (scale factors and
    misalignment rotations); inertia (3x3) the truth's; seed: (entropy, spawn key) of its generator."""

    index: int
    z0: np.ndarray
    X0: np.ndarray
    actuators: Actuators
    inertia: np.ndarray
    seed: tuple

    def arrays(self) -> dict:
        """The errors as named arrays (runs/NNNN.npz)."""
        a = self.actuators
        return {"run": np.array(self.index), "seed_entropy": np.array(str(self.seed[0])),
                "seed_spawn_key": np.array(self.seed[1]), "initial_offset": self.z0, "X0": self.X0,
                "force_scale": np.array(a.force_scale), "moment_scale": np.array(a.moment_scale),
                "force_misalignment": a.force_misalignment, "moment_misalignment": a.moment_misalignment,
                "inertia": self.inertia}


def run_seeds(spec: FlightSpec) -> list[np.random.SeedSequence]:
    """One SeedSequence per run, spawned from the flight's seed."""
    return np.random.SeedSequence(spec.seed).spawn(spec.runs)


def sample_errors(spec: FlightSpec, index: int, seed: np.random.SeedSequence, X0: np.ndarray, mass: float,
                  inertia: np.ndarray, force_frame: str = "inertial") -> RunErrors:
    """Run ``index``'s errors from its SeedSequence (module docstring): the plan's initial state X0 (18)
    of a body of ``mass`` and ``inertia`` -> the truth's; the actuators take force commands in the plan's
    ``force_frame``."""
    rng = np.random.default_rng(seed)
    n = {name: rng.standard_normal(k) for name, k in DRAWS}
    e, ini = spec.errors, spec.errors["initial"]
    J = np.asarray(inertia, float)
    S = np.diag(np.sqrt(np.maximum(1.0 + e["inertia_scale"] * n["inertia_scale"], 1e-6)))
    Jt = S @ J @ S                                         # J_ii (1 + d_i) for a diagonal J; stays SPD
    Omega0 = np.linalg.solve(J, X0[X_ANG])
    dOmega = ini["angular_velocity"] * n["angular_velocity"]
    z0 = np.concatenate([ini["position"] * n["position"], mass * ini["velocity"] * n["velocity"],
                         np.radians(ini["attitude_deg"]) * n["attitude"], Jt @ (Omega0 + dOmega) - X0[X_ANG]])
    Xt = np.asarray(X0, float).copy()
    Xt[X_POS] += z0[0:3]
    Xt[X_MOM] += z0[3:6]
    Xt[X_ROT] = (X0[X_ROT].reshape(3, 3, order="F") @ exp_so3(z0[6:9])).ravel(order="F")
    Xt[X_ANG] += z0[9:12]
    act = Actuators(force_scale=1.0 + e["force_scale"] * float(n["force_scale"][0]),
                    moment_scale=1.0 + e["moment_scale"] * float(n["moment_scale"][0]),
                    force_misalignment=exp_so3(np.radians(e["force_misalignment_deg"]) * n["force_misalignment"]),
                    moment_misalignment=exp_so3(np.radians(e["moment_misalignment_deg"]) * n["moment_misalignment"]),
                    force_frame=force_frame)
    return RunErrors(index=index, z0=z0, X0=Xt.reshape(NX), actuators=act, inertia=Jt,
                     seed=(seed.entropy, tuple(seed.spawn_key)))


def truth_model(base: BodyModel, inertia: np.ndarray) -> BodyModel:
    """The truth body with the run's inertia: the base truth's potential and forces (so the flight
    engine's integrator, built per forces Function, is reused by every run)."""
    return BodyModel(mass=base.mass, inertia=inertia, potential=base.potential, forces=base.forces, mu=base.mu,
                     markers=base.markers, name=base.name)
