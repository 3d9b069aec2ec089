"""Plans other tools can read: CCSDS OEM 2.0 and AEM 1.0 (KVN) and a CSV (``se3ocp export``, ``se3ocp.export``).

What is written (the nodes of the discrete solution, nothing interpolated):

* **OEM** (CCSDS 502.0-B-2, KVN, version 2.0): epoch, position (km), velocity (km/s) of the centre of
  mass in REF_FRAME (the maneuver's ``frame:``, default EME2000) about CENTER_NAME, TIME_SYSTEM UTC.
* **AEM** (CCSDS 504.0-B-1, KVN, version 1.0): epoch and attitude quaternion, ATTITUDE_TYPE
  QUATERNION, QUATERNION_TYPE LAST (Q1 Q2 Q3 QC: vector part first, scalar last), REF_FRAME_A the
  inertial frame, REF_FRAME_B = SC_BODY_1 (the body axes e1, e2, e3 of the maneuver file),
  ATTITUDE_DIR A2B: the quaternion is the coordinate transformation from A to B, i.e. its direction
  cosine matrix (CCSDS/Wertz form) maps inertial components to body components, A(q) = Rᵀ with R the
  file's body-to-inertial attitude; as a Hamilton quaternion acting on vectors it is the rotation R
  (it turns the inertial axes onto the body axes).  Signs are continuous (consecutive quaternions
  have a positive dot product, so interpolation never crosses q -> -q); QC >= 0 at the first epoch
  (the standard recommends QC >= 0, which a continuous sequence cannot always keep).
* **CSV**: one row per node: t, the UTC epoch (when times are seconds), position, velocity,
  quaternion (as in the AEM), body angular velocity, thrust (inertial force) and torque (body); a
  header row names every column's unit.  Controls sit on the row of their time: LGVI controls u_k at
  node k; first-order controls u_k (k = 1..N) at t_k, applied over the step (t_{k-1}, t_k] (the row
  t_0 has none).  Impulsive maneuvers have no thrust columns; their four impulses are comment lines.

Units: OEM and AEM need lengths in km and times in s, so the maneuver must name its units
(``units:`` or ``central_body:``, problems/bodies.py).  Normalized orbit units (GM = 4π², no physical
unit) are read physically only when asked: ``reference_radius`` (km) places the reference circular
orbit about a preset body (``body``, default earth), which fixes the length unit (that radius) and the
time unit (its period); without it OEM/AEM are refused and the CSV is written in the normalized units,
named so in its header.  Epochs are UTC = epoch + t (problems/epochs.py), printed with enough decimals
that each is within 1e-13 of the horizon of its exact value; numbers are printed with 17 significant
digits, so a reader recovers the arrays to one rounding of the unit conversion.  Every failure is an
:class:`ExportError` (one line; the CLI exits 2).
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bodies import PRESETS, Scale
from .epochs import Epoch, EpochError, check_no_leap_second, default_epoch, second_digits, DEFAULT_FRAME

FORMATS = ("oem", "aem", "csv")
ORIGINATOR = "se3ocp"
BODY_FRAME = "SC_BODY_1"
#: relative agreement of GM with 4π² for a file to count as normalized (as problems.units does)
_NORMALIZED_TOL = 1e-9


class ExportError(ValueError):
    """An export that cannot be written; ``str(e)`` is one line ``SOURCE: what is wrong and what to do``."""


@dataclass(frozen=True)
class Plan:
    """What an export writes: a converged Solution's node arrays (file units) and its context; ``u_f`` is the
    applied inertial force (``Solution.f_inertial``: R_j u_f,j for a body-frame force)."""

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
    Comparison (with ``maneuver`` for its epoch, frame and units; without one: J2000.0, EME2000,
    unnamed units).  ``method``: which solution (default: direct, else the only one)."""
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
    phys = getattr(maneuver, "physical", None)
    problem = sol.problem if sol.problem is not None else getattr(maneuver, "problem", None)
    mu = getattr(getattr(problem, "model", None), "mu", None)
    scale = _scale(where, phys, mu, reference_radius, body, mass_kg, center)
    tr = sol.trajectory
    return Plan(name=getattr(maneuver, "name", None) or getattr(problem, "name", "") or "se3ocp", source=where,
                method=method, scheme=sol.scheme, t=np.asarray(tr.t, float), x=tr.x, v=tr.v, R=tr.R,
                Omega=tr.Omega, t_u=sol.control_times, u_f=sol.f_inertial, u_m=sol.u_m, impulses=sol.impulses,
                epoch=phys.epoch if phys else default_epoch(), frame=phys.frame if phys else DEFAULT_FRAME, mu=mu,
                scale=scale)


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


def _need_scale(plan: Plan, fmt: str) -> Scale:
    if plan.scale is not None:
        return plan.scale
    if plan.mu is not None and math.isclose(plan.mu, 4.0 * math.pi**2, rel_tol=_NORMALIZED_TOL):
        why = ("is in normalized orbit units (GM = 4π², no physical unit); give a reference radius in km "
               "(--reference-radius, the radius of the reference orbit about --central-body, default earth)")
    else:
        why = "does not name its units; give units: {length: km | m, mass: kg, time: s} (or central_body:) in the maneuver"
    raise ExportError(f"{plan.source}: CCSDS {fmt.upper()} needs km and s, but the maneuver {why}, or export --format csv")


def _epochs(plan: Plan, scale: Scale) -> list[str]:
    seconds = plan.t * scale.time_s
    try:
        check_no_leap_second(plan.epoch, float(seconds[-1]))
    except EpochError as e:
        raise ExportError(f"{plan.source}: {e}") from None
    d = second_digits(float(seconds[-1] - seconds[0]))
    return [plan.epoch.plus(float(s)).iso(d) for s in seconds]


def _num(a) -> str:
    """Numbers with 17 significant digits (exact round trip of a double)."""
    return " ".join(f"{float(x):.16e}" for x in np.ravel(a))


def _header(kind: str, version: str, plan: Plan, comments: list[str], created: str | None) -> list[str]:
    created = created or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    return ([f"CCSDS_{kind}_VERS = {version}"] + [f"COMMENT {c}" for c in comments] +
            [f"CREATION_DATE = {created}", f"ORIGINATOR = {ORIGINATOR}", ""])


def _context(plan: Plan, scale: Scale) -> list[str]:
    out = [f"se3ocp plan {plan.name}: the {plan.method} solution ({plan.scheme} scheme, {len(plan.t) - 1} steps) "
           f"at its nodes, nothing interpolated",
           f"epochs: UTC = {plan.epoch.iso(6)} + t, t in s; units: {scale.origin}"]
    if plan.impulses is not None:
        out.append("impulsive maneuver: velocities are those after the impulse at the first epoch and before the "
                   "impulse at the last")
    return out


def oem(plan: Plan, created: str | None = None) -> str:
    """The CCSDS OEM 2.0 KVN text of a plan (km, km/s)."""
    scale = _need_scale(plan, "oem")
    if plan.mu is None or scale.center is None:
        raise ExportError(f"{plan.source}: an OEM's positions need the central body they are relative to "
                          f"(CENTER_NAME): give central_body: in the maneuver (or --center NAME), or export "
                          f"--format aem for the attitude")
    ep = _epochs(plan, scale)
    km, kms = scale.length_m / 1000.0, scale.length_m / scale.time_s / 1000.0
    lines = _header("OEM", "2.0", plan, _context(plan, scale) + [
        f"positions in km and velocities in km/s, inertial, in {plan.frame} about {scale.center}"], created)
    lines += ["META_START", f"OBJECT_NAME = {plan.name}", f"OBJECT_ID = {plan.name}", f"CENTER_NAME = {scale.center}",
              f"REF_FRAME = {plan.frame}", "TIME_SYSTEM = UTC", f"START_TIME = {ep[0]}", f"STOP_TIME = {ep[-1]}",
              "META_STOP", ""]
    lines += [f"{e} {_num(x * km)} {_num(v * kms)}" for e, x, v in zip(ep, plan.x, plan.v)]
    return "\n".join(lines) + "\n"


QUATERNION_CONVENTION = [
    "QUATERNION_TYPE = LAST: Q1 Q2 Q3 QC, vector part first, scalar QC last",
    f"ATTITUDE_DIR = A2B: the coordinate transformation from REF_FRAME_A to REF_FRAME_B = {BODY_FRAME} (the body axes "
    "e1 e2 e3 of the maneuver file): v_body = A(q) v_inertial, A(q) = R^T with R the body-to-inertial attitude",
    "signs continuous: consecutive quaternions have a positive dot product (q and -q are one attitude); QC >= 0 first",
]


def aem(plan: Plan, created: str | None = None) -> str:
    """The CCSDS AEM 1.0 KVN text of a plan (quaternions, the convention in its comments)."""
    scale = _need_scale(plan, "aem")
    ep = _epochs(plan, scale)
    q = plan.quaternions
    lines = _header("AEM", "1.0", plan, _context(plan, scale) + QUATERNION_CONVENTION, created)
    meta = ["META_START", f"OBJECT_NAME = {plan.name}", f"OBJECT_ID = {plan.name}"]
    if scale.center is not None:
        meta.append(f"CENTER_NAME = {scale.center}")
    meta += [f"REF_FRAME_A = {plan.frame}", f"REF_FRAME_B = {BODY_FRAME}", "ATTITUDE_DIR = A2B", "TIME_SYSTEM = UTC",
             f"START_TIME = {ep[0]}", f"STOP_TIME = {ep[-1]}", "ATTITUDE_TYPE = QUATERNION", "QUATERNION_TYPE = LAST",
             "META_STOP", "", "DATA_START"]
    lines += meta + [f"{e} {_num(qk[[1, 2, 3, 0]])}" for e, qk in zip(ep, q)] + ["DATA_STOP"]
    return "\n".join(lines) + "\n"


def csv_units(plan: Plan) -> dict[str, tuple[str, float]]:
    """{quantity: (unit label, factor)} of the CSV: value written = factor * file value."""
    s = plan.scale
    if s is None:
        from .units import units_for

        u = units_for(plan.mu)
        return {q: (_ascii(u.unit(q)) or "1", 1.0) for q in ("time", "length", "velocity", "force", "moment")} | \
            {"angular_rate": (_ascii(u.unit("angular_rate")), 1.0)}
    L, T, M = s.length_m, s.time_s, s.mass_kg
    force = ("N", M * L / T**2) if M is not None else ("mass_unit*km/s^2", L / 1000.0 / T**2)
    moment = ("N*m", M * L**2 / T**2) if M is not None else ("mass_unit*km^2/s^2", (L / 1000.0) ** 2 / T**2)
    return {"time": ("s", T), "length": ("km", L / 1000.0), "velocity": ("km/s", L / 1000.0 / T),
            "angular_rate": ("rad/s", 1.0 / T), "force": force, "moment": moment}


def _ascii(unit: str) -> str:
    return unit.replace("·", "*").replace("²", "^2").replace("³", "^3")


def csv(plan: Plan) -> str:
    """The CSV text of a plan (module docstring); '#' lines first, then the header row."""
    u = csv_units(plan)
    cols = [f"t [{u['time'][0]}]"]
    seconds = plan.scale is not None
    if seconds:
        cols.append("epoch [UTC]")
        ep = _epochs(plan, plan.scale)
    cols += [f"{c} [{u['length'][0]}]" for c in ("x", "y", "z")] + [f"{c} [{u['velocity'][0]}]" for c in ("vx", "vy", "vz")]
    cols += ["q1", "q2", "q3", "qc"] + [f"{c} [{u['angular_rate'][0]}]" for c in ("wx", "wy", "wz")]
    controls = plan.u_f is not None
    if controls:
        cols += [f"{c} [{u['force'][0]}]" for c in ("fx", "fy", "fz")] + [f"{c} [{u['moment'][0]}]" for c in ("mx", "my", "mz")]
    lines = [f"# {c}" for c in _csv_comments(plan, u)] + [",".join(cols)]
    q = plan.quaternions
    row_u = {}
    if controls:
        for k, tk in enumerate(plan.t_u):
            row_u[int(np.searchsorted(plan.t, tk))] = (plan.u_f[k], plan.u_m[k])
    for k in range(len(plan.t)):
        row = [_num(plan.t[k] * u["time"][1])] + ([ep[k]] if seconds else [])
        row += [_num(c) for c in plan.x[k] * u["length"][1]] + [_num(c) for c in plan.v[k] * u["velocity"][1]]
        row += [_num(c) for c in q[k][[1, 2, 3, 0]]] + [_num(c) for c in plan.Omega[k] * u["angular_rate"][1]]
        if controls:
            f, m = row_u.get(k, (None, None))
            row += [""] * 6 if f is None else [_num(c) for c in f * u["force"][1]] + [_num(c) for c in m * u["moment"][1]]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _csv_comments(plan: Plan, u) -> list[str]:
    s = plan.scale
    out = [f"se3ocp plan {plan.name}: the {plan.method} solution ({plan.scheme} scheme, {len(plan.t) - 1} steps), "
           f"frame {plan.frame}",
           f"units: {s.origin}" if s is not None else
           f"units: those of the maneuver file ({u['length'][0]}, {u['time'][0]}), not physical: no epoch column",
           "quaternion q1 q2 q3 qc (scalar last): " + QUATERNION_CONVENTION[1].split(": ", 1)[1] + "; signs continuous",
           "angular velocity w: body frame; thrust f: inertial frame; torque m: body frame"]
    if plan.u_f is not None and plan.t_u is not None and len(plan.t_u) == len(plan.t) - 1:
        out.append("first-order scheme: the control on row t_k (k >= 1) is applied over (t_{k-1}, t_k]; row t_0 has none")
    if plan.impulses is not None:
        f, m = u["force"], u["moment"]
        imp = {k: np.asarray(val, float) for k, val in plan.impulses.items()}
        unit_i, fac_i = f"{f[0]}*{u['time'][0]}", f[1] * u["time"][1]
        unit_a, fac_a = f"{m[0]}*{u['time'][0]}", m[1] * u["time"][1]
        for k in ("dgamma0", "dgammaN"):
            out.append(f"impulse {k} (linear, inertial) [{unit_i}]: {_num(imp[k] * fac_i)}")
        for k in ("dPi0", "dPiN"):
            out.append(f"impulse {k} (angular, body) [{unit_a}]: {_num(imp[k] * fac_a)}")
    return out


def export(source, format: str = "oem", out: str | Path | None = None, *, maneuver=None, method: str | None = None,
           reference_radius: float | None = None, body: str = "earth", mass_kg: float | None = None,
           center: str | None = None, created: str | None = None) -> str:
    """Export a plan (module docstring) as ``format`` ('oem', 'aem' or 'csv'); returns the text and, with
    ``out``, writes it to that file (atomically).  ``source``: a results directory, a Run, a Solution or a
    Comparison (then ``maneuver`` gives epoch, frame and units).  Raises :class:`ExportError`."""
    if format not in FORMATS:
        raise ExportError(f"format: expected one of {', '.join(FORMATS)}, got {format!r}")
    plan = plan_of(source, maneuver=maneuver, method=method, reference_radius=reference_radius, body=body,
                   mass_kg=mass_kg, center=center)
    text = {"oem": lambda: oem(plan, created), "aem": lambda: aem(plan, created), "csv": lambda: csv(plan)}[format]()
    if out is not None:
        from .io import atomic_write_bytes

        atomic_write_bytes(Path(out), text.encode("utf-8"))
    return text


__all__ = ["ExportError", "FORMATS", "Plan", "aem", "csv", "csv_units", "export", "oem", "plan_of"]
