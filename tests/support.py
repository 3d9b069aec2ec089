"""Test support: the bundled examples are defined once, in configs/, and the tests load them from there."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import se3ocp

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
#: short names of the bundled maneuver files
EXAMPLES = {"e1": "e1_impulsive_tpbvp", "e2": "e2_impulsive_relaxed", "e3": "e3_inclination_change",
            "e4": "e4_orbital_capture", "free": "free_tumble"}


def config(name: str) -> Path:
    """The path of a bundled maneuver file by its short name (e1..e4, free) or its stem."""
    return CONFIGS / f"{EXAMPLES.get(name, name)}.yaml"


def raise_on_mesh(N: int, scheme: str | None = None):
    """The bundled fuel raise on the irregular mesh r_k = 1.5 + sin(2.3 k), normalized to mean 1 (steps 0.33 to 1.67
    times the mean; tests/test_indirect_fuel.py, tests/test_fuel_guard.py)."""
    import numpy as np

    r = 1.5 + np.sin(2.3 * np.arange(N))
    return problem("orbit_raise_fuel", N, scheme).replace(mesh=r / r.mean())


@lru_cache(maxsize=None)
def _maneuver(name: str, sets: tuple[str, ...]):
    return se3ocp.load(config(name), sets)


def maneuver(name: str, N: int | None = None, scheme: str | None = None, *sets: str):
    """A bundled maneuver with N and the scheme overridden (cached: equal calls share the object)."""
    extra = ((f"horizon.N={N}",) if N is not None else ()) + ((f"discretization={scheme}",) if scheme else ())
    return _maneuver(name, extra + tuple(sets))


def problem(name: str, N: int | None = None, scheme: str | None = None, *sets: str):
    """The Problem of :func:`maneuver`."""
    return maneuver(name, N, scheme, *sets).problem


@lru_cache(maxsize=None)
def slew_comparison(N: int = 40):
    """The keep-out slew (configs/slew_keep_out.yaml: no central body, the force removed by a norm
    bound of 0, a keep-out cone) under a bang-bang moment about z, simulated and labelled as a
    converged direct run, beside the indirect method's Result.not_applicable, compared as
    ``compare`` does: a run with the shapes of the real one, in a tenth of a second."""
    import dataclasses

    import numpy as np

    from se3ocp.transcription.solve import compare

    man = _maneuver("slew_keep_out", (f"horizon.N={N}",))
    p = man.problem
    n = p.disc.n_controls(p.N)
    U = np.zeros((6, n))
    U[5] = np.where(np.linspace(0.0, p.T, n) < 0.5 * p.T, 0.05, -0.05)
    direct = dataclasses.replace(se3ocp.simulate(p, U), method="direct", solver="ipopt",
                                 result=se3ocp.Result.converged, verdict="simulated as a stand-in for IPOPT",
                                 cost=float(p.control.objective.value(p, U, p.h)))   # a converged plan has a cost
    return man, compare(direct, se3ocp.solve(man, "indirect"))


def perturbed_truth(sol):
    """A truth for closed-loop comparisons of a plan ``sol``: its body with the inertia 1 % off (diag 1.01, 0.99, 1),
    actuators with a 2 % thrust scale and a small misalignment, and its first state offset by 1e-4 in x and gamma:
    (body, Actuators, X0)."""
    import numpy as np

    from se3ocp.transcription.dynamics.flight import Actuators
    from se3ocp.transcription.geometry.so3 import exp_so3

    body = sol.problem.model
    truth = type(body)(mass=body.mass, inertia=body.inertia * np.array([1.01, 0.99, 1.0]), potential=body.potential,
                       forces=body.forces, mu=body.mu, markers=body.markers, name=body.name)
    act = Actuators(force_scale=1.02, force_misalignment=exp_so3(np.radians([0.3, -0.2, 0.1])))
    X0 = sol.trajectory.X[0].copy()
    X0[0:6] += 1e-4
    return truth, act, X0


def independent(name: str, make, N: int | None = None, *sets: str) -> float:
    """The cost of one plain solve of a bundled maneuver (N and ``sets`` overridden) from the start ``make(problem)``
    on its grid, within the solver's whole max_iter -- no strategy, no coarse grid, no multistart: an independent
    solve to check a default against (inf if it does not converge)."""
    from se3ocp.transcription.solve import solve_direct
    from se3ocp.transcription.strategy.core import Solve

    m = maneuver(name, N, None, *sets)
    s = solve_direct(m.problem, m.direct, strategy=Solve(make, "independent"))
    return s.cost if s.converged else float("inf")


def single(name: str, T: float | None, sides: tuple = (), N: int | None = None, seed: int = 0) -> float:
    """The minimum time (or cost) from one symmetry-breaking start (``seed`` over T; None: the file's T) routed round
    the cones on ``sides`` ((constraint index, +1 near / -1 far), ...; clearance 5 deg): :func:`independent`."""
    import math

    from se3ocp.transcription.objectives.time import start_sizes
    from se3ocp.transcription.strategy import starts

    def make(q):
        base = starts.detour(q, dict(sides), math.radians(5.0), T) if sides else None
        return starts.perturbed(q, start_sizes(q), seed, T=T, base=base)
    return independent(name, make, N)


def default(name: str, N: int | None = None):
    """The default solve of a bundled maneuver (``se3ocp.solve``) and its wall time in seconds."""
    import time

    t = time.perf_counter()
    sol = se3ocp.solve(maneuver(name, N))
    return sol, time.perf_counter() - t
