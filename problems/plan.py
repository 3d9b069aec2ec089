"""What every export writes: a converged Solution's plan at its nodes, in the file's units, with its physical
reading (:class:`Plan`, :func:`plan_of`), shared by the CCSDS/CSV exports (problems/export.py) and GMAT's thrust
history (problems/gmat.py).  Units: see problems/export.py.  Every failure is an :class:`ExportError` (one line;
the CLI exits 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bodies import PRESETS, Scale
from .epochs import DEFAULT_FRAME, Epoch, default_epoch

#: relative agreement of GM with 4π² for a file to count as normalized (as problems.units does)
_NORMALIZED_TOL = 1e-9


class ExportError(ValueError):
    """An export that cannot be written; ``str(e)`` is one line ``SOURCE: what is wrong and what to do``."""


@dataclass(frozen=True)
class Plan:
    """What an export writes: a converged Solution's node arrays (file units) and its context; ``u_f`` is the
    applied inertial force (``Solution.f_inertial``: R_j u_f,j for a body-frame force), ``f_body`` (n, 3) the same
    force in the body frame, R_j^T u_f,j with R_j the attitude at the node the control belongs to, ``throttle`` (n,)
    the force control's size over its bound (the actuator's ``magnitude / scale``: |u_f| / bound for a ball or an
    engine, the largest component over the largest limit for a box; None when unbounded), ``mass`` the body's
    (constant) mass in the file's unit."""

    name: str
    source: str
    method: str
    scheme: str
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    R: np.ndarray
    Omega: np.ndarray
    t_u: np.ndarray | None
    u_f: np.ndarray | None
    u_m: np.ndarray | None
    f_body: np.ndarray | None
    throttle: np.ndarray | None
    mass: float
    impulses: dict | None
    epoch: Epoch
    frame: str
    mu: float | None
    scale: Scale | None

    @property
    def quaternions(self) -> np.ndarray:
        """(N+1, 4) scalar-first Hamilton quaternions of R, continuous in sign (plots.quaternions)."""
        from .plots import quaternions

        return quaternions(self.R)


def plan_of(source, *, maneuver=None, method: str | None = None, reference_radius: float | None = None,
            body: str = "earth", mass_kg: float | None = None, center: str | None = None) -> Plan:
    """The :class:`Plan` of a results directory (a path), a :class:`~problems.store.Run`, a Solution or a
    Comparison (with ``maneuver`` for its epoch, frame and units; without one: those the Solution carries
    (``Solution.physical``, set by ``se3ocp.solve`` of a maneuver file), else J2000.0, EME2000, unnamed units).
    ``method``: which solution (default: direct, else the only one)."""
    from .store import Run, applicable, read_run

    where = str(source) if isinstance(source, (str, Path)) else getattr(maneuver, "source", "<solution>")
    if isinstance(source, (str, Path)):
        source = read_run(Path(source))
    if isinstance(source, Run):
        maneuver, where, source = source.maneuver, str(getattr(source, "directory", where)), source.result
    sols = applicable(source)
    if method is None:
        method = "direct" if "direct" in sols else next(iter(sols), None)
    if method not in sols:
        raise ExportError(f"{where}: no {method} solution to export (have: {', '.join(sols) or 'none'})")
    sol = sols[method]
    if not sol.converged:
        raise ExportError(f"{where}: the {method} solution did not converge ({sol.result.value}): a plan that was not "
                          f"found is not exported")
    phys = getattr(maneuver, "physical", None) or sol.physical
    problem = sol.problem if sol.problem is not None else getattr(maneuver, "problem", None)
    model = getattr(problem, "model", None)
    mu = getattr(model, "mu", None)
    scale = _scale(where, phys, mu, reference_radius, body, mass_kg, center)
    tr = sol.trajectory
    f_body, throttle = _body_force(sol, problem)
    return Plan(name=getattr(maneuver, "name", None) or getattr(problem, "name", "") or "se3ocp", source=where,
                method=method, scheme=sol.scheme, t=np.asarray(tr.t, float), x=tr.x, v=tr.v, R=tr.R,
                Omega=tr.Omega, t_u=sol.control_times, u_f=sol.f_inertial, u_m=sol.u_m, f_body=f_body,
                throttle=throttle, mass=float(getattr(model, "mass", math.nan)), impulses=sol.impulses,
                epoch=phys.epoch if phys else default_epoch(), frame=phys.frame if phys else DEFAULT_FRAME, mu=mu,
                scale=scale)


def _body_force(sol, problem) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(R_j^T f_j (n, 3), throttle (n,) or None) of a Solution's force controls (:class:`Plan`); (None, None)
    without controls."""
    if sol.f_inertial is None:
        return None, None
    nodes = np.searchsorted(np.asarray(sol.trajectory.t, float), sol.control_times)   # the node of each control
    f_body = np.einsum("nji,nj->ni", np.asarray(sol.trajectory.R, float)[nodes], sol.f_inertial)
    bound = getattr(getattr(problem, "control", None), "force_bound", None)
    size = bound.scale() if bound is not None else math.inf
    throttle = bound.magnitude(sol.u_f) / size if math.isfinite(size) and size > 0 else None
    return f_body, throttle


def _scale(where, phys, mu, reference_radius, body, mass_kg, center) -> Scale | None:
    """The physical reading of the file's numbers, or None (see the module docstring)."""
    units = getattr(phys, "units", None)
    normalized = mu is not None and math.isclose(mu, 4.0 * math.pi**2, rel_tol=_NORMALIZED_TOL)
    if reference_radius is not None:
        if units is not None or not normalized:
            raise ExportError(f"{where}: a reference radius reads normalized orbit units (GM = 4π²); this maneuver "
                              f"{'names its units' if units is not None else 'is not in normalized units'}")
        if body not in PRESETS:
            raise ExportError(f"{where}: unknown central body {body!r} (known: {', '.join(PRESETS)})")
        if not (isinstance(reference_radius, (int, float)) and reference_radius > 0 and math.isfinite(reference_radius)):
            raise ExportError(f"{where}: expected a positive reference radius in km, got {reference_radius!r}")
        s = Scale.reference_orbit(body, float(reference_radius), mu)
    elif units is not None:
        s = Scale.of_units(units, getattr(phys, "center", None))
    else:
        return None
    if mass_kg is not None:
        if units is not None:
            raise ExportError(f"{where}: the maneuver names its mass unit ({units.mass}); a mass scale applies to "
                              f"normalized units only")
        s = Scale(s.length_m, s.time_s, float(mass_kg), s.center, s.origin + f", 1 mass unit = {float(mass_kg):.10g} kg")
    if center is not None:
        s = Scale(s.length_m, s.time_s, s.mass_kg, str(center).upper(), s.origin)
    return s


#: what each format is called in a refusal
FORMAT_NAMES = {"oem": "CCSDS OEM", "aem": "CCSDS AEM", "thf": "GMAT's thrust history", "gmat": "the GMAT script"}


def need_scale(plan: Plan, fmt: str) -> Scale:
    """The plan's physical scale, or ExportError saying what the format ``fmt`` needs."""
    if plan.scale is not None:
        return plan.scale
    if plan.mu is not None and math.isclose(plan.mu, 4.0 * math.pi**2, rel_tol=_NORMALIZED_TOL):
        why = ("is in normalized orbit units (GM = 4π², no physical unit); give a reference radius in km "
               "(--reference-radius, the radius of the reference orbit about --central-body, default earth)")
    else:
        why = "does not name its units; give units: {length: km | m, mass: kg, time: s} (or central_body:) in the maneuver"
    raise ExportError(f"{plan.source}: {FORMAT_NAMES[fmt]} needs km and s, but the maneuver {why}, or export --format csv")


def num(a) -> str:
    """Numbers with 17 significant digits (exact round trip of a double)."""
    return " ".join(f"{float(x):.16e}" for x in np.ravel(a))


def csv_units(plan: Plan) -> dict[str, tuple[str, float]]:
    """{quantity: (unit label, factor)} of the CSV: value written = factor * file value."""
    s = plan.scale
    if s is None:
        from .units import units_for

        u = units_for(plan.mu)
        return {q: (_ascii(u.unit(q)) or "1", 1.0) for q in ("time", "length", "velocity", "force", "moment")} | \
            {"angular_rate": (_ascii(u.unit("angular_rate")), 1.0), "mass": ("mass", 1.0), "ratio": ("1", 1.0)}
    L, T, M = s.length_m, s.time_s, s.mass_kg
    force = ("N", M * L / T**2) if M is not None else ("mass_unit*km/s^2", L / 1000.0 / T**2)
    moment = ("N*m", M * L**2 / T**2) if M is not None else ("mass_unit*km^2/s^2", (L / 1000.0) ** 2 / T**2)
    return {"time": ("s", T), "length": ("km", L / 1000.0), "velocity": ("km/s", L / 1000.0 / T),
            "angular_rate": ("rad/s", 1.0 / T), "force": force, "moment": moment,
            "mass": ("kg", M) if M is not None else ("mass_unit", 1.0), "ratio": ("1", 1.0)}


def _ascii(unit: str) -> str:
    return unit.replace("·", "*").replace("²", "^2").replace("³", "^3")


def oem_state(plan: Plan, scale: Scale, k: int) -> np.ndarray:
    """(6,) position (km) and velocity (km/s) of node k, as the OEM writes them."""
    return np.r_[plan.x[k] * (scale.length_m / 1000.0), plan.v[k] * (scale.length_m / scale.time_s / 1000.0)]


__all__ = ["ExportError", "Plan", "csv_units", "need_scale", "num", "oem_state", "plan_of"]
