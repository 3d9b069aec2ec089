"""Plans other tools can read: CCSDS OEM 2.0 and AEM 1.0 (KVN), a CSV, and GMAT's thrust history with a script that
replays it (problems/gmat.py) (``se3ocp export``, ``se3ocp.export``).

What is written (the nodes of the discrete solution, nothing interpolated):

* **OEM** (CCSDS 502.0-B-2, KVN, version 2.0): epoch, position (km), velocity (km/s) of the centre of
  mass in REF_FRAME (the maneuver's ``frame:``, default EME2000) about CENTER_NAME, TIME_SYSTEM UTC (or TAI, TT,
  GPS), INTERPOLATION HERMITE of INTERPOLATION_DEGREE 3 (:data:`INTERPOLATION`, why there).  CCSDS 502.0 gives the
  OEM no mass keyword (MASS is an OPM spacecraft parameter, not an OEM metadata or data item), so the body's mass
  is a COMMENT at the start of the data: ``MASS = 500 [kg], constant over the plan ...``.
* **AEM** (CCSDS 504.0-B-1, KVN, version 1.0): epoch and attitude quaternion, ATTITUDE_TYPE
  QUATERNION, QUATERNION_TYPE LAST (Q1 Q2 Q3 QC: vector part first, scalar last), REF_FRAME_A the
  inertial frame, REF_FRAME_B = SC_BODY_1 (the body axes e1, e2, e3 of the maneuver file),
  ATTITUDE_DIR A2B: the quaternion is the coordinate transformation from A to B, i.e. its direction
  cosine matrix (CCSDS/Wertz form) maps inertial components to body components, A(q) = Rᵀ with R the
  file's body-to-inertial attitude; as a Hamilton quaternion acting on vectors it is the rotation R
  (it turns the inertial axes onto the body axes).  Signs are continuous (consecutive quaternions
  have a positive dot product, so interpolation never crosses q -> -q); QC >= 0 at the first epoch
  (the standard recommends QC >= 0, which a continuous sequence cannot always keep).
* **CSV**: one row per node: t, the epoch (UTC or the time system asked, when times are seconds), position,
  velocity, quaternion (as in the AEM), body angular velocity, mass, thrust (inertial force), torque (body),
  thrust in the body frame (fb = R^T f, R the row's attitude) and, for a bounded force, the throttle (|u_f| over
  the bound, :class:`~problems.plan.Plan`); a header row names every column's unit.  Controls sit on the row of
  their time: LGVI controls u_k at node k; first-order controls u_k (k = 1..N) at t_k, applied over the step
  (t_{k-1}, t_k] (the row t_0 has none).  Impulsive maneuvers have no thrust columns; their four impulses are comment lines.

Units: OEM and AEM need lengths in km and times in s, so the maneuver must name its units
(``units:`` or ``central_body:``, problems/bodies.py).  Normalized orbit units (GM = 4π², no physical
unit) are read physically only when asked: ``reference_radius`` (km) places the reference circular
orbit about a preset body (``body``, default earth), which fixes the length unit (that radius) and the
time unit (its period); without it OEM/AEM are refused and the CSV is written in the normalized units,
named so in its header.  Epochs are UTC = epoch + t (problems/epochs.py), or that instant labelled in TAI (UTC +
TAI-UTC of the epoch's date: 37 s since 2017), TT (TAI + 32.184 s) or GPS (TAI - 19 s), printed with enough decimals
that each is within 1e-13 of the horizon of its exact value; numbers are printed with 17 significant
digits, so a reader recovers the arrays to one rounding of the unit conversion.  Every failure is an
:class:`ExportError` (one line; the CLI exits 2).
"""
from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path

import numpy as np

from .bodies import Scale
from .epochs import TIME_SYSTEMS, EpochError, check_no_leap_second, offset_from_utc, second_digits
from .plan import ExportError, Plan, csv_units, need_scale, num, oem_state, plan_of

FORMATS = ("oem", "aem", "csv", "thf", "gmat")
ORIGINATOR = "se3ocp"
BODY_FRAME = "SC_BODY_1"


def _epochs(plan: Plan, scale: Scale, system: str = "UTC") -> list[str]:
    """The node epochs in ``system`` (:data:`~problems.epochs.TIME_SYSTEMS`): the start's label
    (problems.epochs.offset_from_utc) + t, in days of 86400 s; a span over a leap second is refused in UTC only."""
    if system not in TIME_SYSTEMS:
        raise ExportError(f"time system: expected one of {', '.join(TIME_SYSTEMS)}, got {system!r}")
    seconds = plan.t * scale.time_s
    if system == "UTC":
        try:
            check_no_leap_second(plan.epoch, float(seconds[-1]))
        except EpochError as e:
            raise ExportError(f"{plan.source}: {e}") from None
    try:
        start = plan.epoch.plus(offset_from_utc(system, plan.epoch))
    except EpochError as e:
        raise ExportError(f"{plan.source}: epoch: {e}") from None
    d = second_digits(float(seconds[-1] - seconds[0]))
    return [start.plus(float(s)).iso(d) for s in seconds]


def _header(kind: str, version: str, plan: Plan, comments: list[str], created: str | None) -> list[str]:
    created = created or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    return ([f"CCSDS_{kind}_VERS = {version}"] + [f"COMMENT {c}" for c in comments] +
            [f"CREATION_DATE = {created}", f"ORIGINATOR = {ORIGINATOR}", ""])


def _context(plan: Plan, scale: Scale, system: str = "UTC") -> list[str]:
    label = "" if system == "UTC" else f", labelled in {system} ({_offset_words(system)})"
    out = [f"se3ocp plan {plan.name}: the {plan.method} solution ({plan.scheme} scheme, {len(plan.t) - 1} steps) "
           f"at its nodes, nothing interpolated",
           f"epochs: UTC = {plan.epoch.iso(6)} + t, t in s{label}; units: {scale.origin}"]
    if plan.impulses is not None:
        out.append("impulsive maneuver: velocities are those after the impulse at the first epoch and before the "
                   "impulse at the last")
    return out


def _offset_words(system: str) -> str:
    return {"TAI": "TAI = UTC + TAI-UTC, 37 s since 2017-01-01", "TT": "TT = TAI + 32.184 s",
            "GPS": "GPS = TAI - 19 s"}[system]


#: the OEM's interpolation: Hermite on position and velocity over 2 nodes, a cubic (degree 3) per interval.  The
#: nodes are those of a second-order scheme (first order for first_order): their error is O(h^2) and the
#: velocities agree with the positions' derivative to O(h^2).  The cubic Hermite interpolant's own error,
#: h^4 max|x^(4)| / 384, is two orders below that, so a higher degree adds nothing the nodes contain; and over
#: more nodes (a Lagrange of degree 7 or 9, usual for propagated ephemerides) it would span up to 8 steps of a
#: plan whose thrust can switch on and off between them, and oscillate there.
INTERPOLATION, INTERPOLATION_DEGREE = "HERMITE", 3


def oem(plan: Plan, created: str | None = None, time_system: str = "UTC") -> str:
    """The CCSDS OEM 2.0 KVN text of a plan (km, km/s; epochs in ``time_system``); INTERPOLATION HERMITE of degree
    3 (:data:`INTERPOLATION`); the body's mass, which the OEM has no keyword for, is a COMMENT of the data."""
    scale = need_scale(plan, "oem")
    if plan.mu is None or scale.center is None:
        raise ExportError(f"{plan.source}: an OEM's positions need the central body they are relative to "
                          f"(CENTER_NAME): give central_body: in the maneuver (or --center NAME), or export "
                          f"--format aem for the attitude")
    ep = _epochs(plan, scale, time_system)
    lines = _header("OEM", "2.0", plan, _context(plan, scale, time_system) + [
        f"positions in km and velocities in km/s, inertial, in {plan.frame} about {scale.center}"], created)
    lines += ["META_START", f"OBJECT_NAME = {plan.name}", f"OBJECT_ID = {plan.name}", f"CENTER_NAME = {scale.center}",
              f"REF_FRAME = {plan.frame}", f"TIME_SYSTEM = {time_system}", f"START_TIME = {ep[0]}",
              f"STOP_TIME = {ep[-1]}", f"INTERPOLATION = {INTERPOLATION}",
              f"INTERPOLATION_DEGREE = {INTERPOLATION_DEGREE}", "META_STOP", ""]
    lines += [f"COMMENT {c}" for c in _mass_comment(plan, scale)]
    lines += [f"{e} {num(oem_state(plan, scale, k))}" for k, e in enumerate(ep)]
    return "\n".join(lines) + "\n"


def _mass_comment(plan: Plan, scale: Scale) -> list[str]:
    """The mass as a comment (CCSDS 502.0 gives the OEM no mass keyword; the OPM's MASS is not allowed in it)."""
    if not math.isfinite(plan.mass):
        return []
    value, unit = (plan.mass * scale.mass_kg, "kg") if scale.mass_kg is not None else (plan.mass, "mass units")
    return [f"MASS = {value:.17g} [{unit}], constant over the plan (a rigid body of constant mass); the OEM has no "
            f"mass keyword"]


QUATERNION_CONVENTION = [
    "QUATERNION_TYPE = LAST: Q1 Q2 Q3 QC, vector part first, scalar QC last",
    f"ATTITUDE_DIR = A2B: the coordinate transformation from REF_FRAME_A to REF_FRAME_B = {BODY_FRAME} (the body axes "
    "e1 e2 e3 of the maneuver file): v_body = A(q) v_inertial, A(q) = R^T with R the body-to-inertial attitude",
    "signs continuous: consecutive quaternions have a positive dot product (q and -q are one attitude); QC >= 0 first",
]


def aem(plan: Plan, created: str | None = None, time_system: str = "UTC") -> str:
    """The CCSDS AEM 1.0 KVN text of a plan (quaternions, the convention in its comments; epochs in ``time_system``)."""
    scale = need_scale(plan, "aem")
    ep = _epochs(plan, scale, time_system)
    q = plan.quaternions
    lines = _header("AEM", "1.0", plan, _context(plan, scale, time_system) + QUATERNION_CONVENTION, created)
    meta = ["META_START", f"OBJECT_NAME = {plan.name}", f"OBJECT_ID = {plan.name}"]
    if scale.center is not None:
        meta.append(f"CENTER_NAME = {scale.center}")
    meta += [f"REF_FRAME_A = {plan.frame}", f"REF_FRAME_B = {BODY_FRAME}", "ATTITUDE_DIR = A2B",
             f"TIME_SYSTEM = {time_system}",
             f"START_TIME = {ep[0]}", f"STOP_TIME = {ep[-1]}", "ATTITUDE_TYPE = QUATERNION", "QUATERNION_TYPE = LAST",
             "META_STOP", "", "DATA_START"]
    lines += meta + [f"{e} {num(qk[[1, 2, 3, 0]])}" for e, qk in zip(ep, q)] + ["DATA_STOP"]
    return "\n".join(lines) + "\n"


def _control_columns(plan: Plan, u) -> tuple[list[str], list[np.ndarray]]:
    """(header names, (n_controls, k) blocks in CSV units) of the control columns: thrust (inertial), torque
    (body), thrust in the body frame, throttle (when the force is bounded)."""
    f, m = u["force"], u["moment"]
    names = [f"{c} [{f[0]}]" for c in ("fx", "fy", "fz")] + [f"{c} [{m[0]}]" for c in ("mx", "my", "mz")]
    names += [f"{c} [{f[0]}]" for c in ("fbx", "fby", "fbz")]
    blocks = [plan.u_f * f[1], plan.u_m * m[1], plan.f_body * f[1]]
    if plan.throttle is not None:
        names.append(f"throttle [{u['ratio'][0]}]")
        blocks.append(plan.throttle[:, None])
    return names, blocks


def csv(plan: Plan, time_system: str = "UTC") -> str:
    """The CSV text of a plan (module docstring); '#' lines first, then the header row."""
    u = csv_units(plan)
    cols = [f"t [{u['time'][0]}]"]
    seconds = plan.scale is not None
    if seconds:
        cols.append(f"epoch [{time_system}]")
        ep = _epochs(plan, plan.scale, time_system)
    cols += [f"{c} [{u['length'][0]}]" for c in ("x", "y", "z")] + [f"{c} [{u['velocity'][0]}]" for c in ("vx", "vy", "vz")]
    cols += ["q1", "q2", "q3", "qc"] + [f"{c} [{u['angular_rate'][0]}]" for c in ("wx", "wy", "wz")]
    cols.append(f"mass [{u['mass'][0]}]")
    controls = plan.u_f is not None
    row_u = {}
    if controls:
        names, blocks = _control_columns(plan, u)
        cols += names
        values = np.hstack(blocks)
        for k, tk in enumerate(plan.t_u):
            row_u[int(np.searchsorted(plan.t, tk))] = values[k]
    lines = [f"# {c}" for c in _csv_comments(plan, u)] + [",".join(cols)]
    q = plan.quaternions
    for k in range(len(plan.t)):
        row = [num(plan.t[k] * u["time"][1])] + ([ep[k]] if seconds else [])
        row += [num(c) for c in plan.x[k] * u["length"][1]] + [num(c) for c in plan.v[k] * u["velocity"][1]]
        row += [num(c) for c in q[k][[1, 2, 3, 0]]] + [num(c) for c in plan.Omega[k] * u["angular_rate"][1]]
        row.append(num(plan.mass * u["mass"][1]))
        if controls:
            vals = row_u.get(k)
            row += [""] * len(names) if vals is None else [num(c) for c in vals]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def _csv_comments(plan: Plan, u) -> list[str]:
    s = plan.scale
    out = [f"se3ocp plan {plan.name}: the {plan.method} solution ({plan.scheme} scheme, {len(plan.t) - 1} steps), "
           f"frame {plan.frame}",
           f"units: {s.origin}" if s is not None else
           f"units: those of the maneuver file ({u['length'][0]}, {u['time'][0]}), not physical: no epoch column",
           "quaternion q1 q2 q3 qc (scalar last): " + QUATERNION_CONVENTION[1].split(": ", 1)[1] + "; signs continuous",
           "angular velocity w: body frame; thrust f: inertial frame; torque m: body frame; fb: the thrust in the body "
           "frame, R^T f with R the attitude of the row; throttle: |u_f| / its bound (an engine's or a ball's; a box: "
           "the largest component over the largest limit); mass: constant (a rigid body of constant mass)"]
    if plan.u_f is not None and plan.t_u is not None and len(plan.t_u) == len(plan.t) - 1:
        out.append("first-order scheme: the control on row t_k (k >= 1) is applied over (t_{k-1}, t_k]; row t_0 has none")
    if plan.impulses is not None:
        f, m = u["force"], u["moment"]
        imp = {k: np.asarray(val, float) for k, val in plan.impulses.items()}
        unit_i, fac_i = f"{f[0]}*{u['time'][0]}", f[1] * u["time"][1]
        unit_a, fac_a = f"{m[0]}*{u['time'][0]}", m[1] * u["time"][1]
        for k in ("dgamma0", "dgammaN"):
            out.append(f"impulse {k} (linear, inertial) [{unit_i}]: {num(imp[k] * fac_i)}")
        for k in ("dPi0", "dPiN"):
            out.append(f"impulse {k} (angular, body) [{unit_a}]: {num(imp[k] * fac_a)}")
    return out


def files(plan: Plan, format: str, stem: str, created: str | None = None,
          time_system: str = "UTC") -> dict[str, str]:
    """{file name: text} of an export of ``plan`` named ``stem`` + suffix: one file (``stem.<format>``), or for
    'gmat' the script ``stem.script`` and the thrust history ``stem.thf`` it replays (problems/gmat.py)."""
    from . import gmat

    if format not in FORMATS:
        raise ExportError(f"format: expected one of {', '.join(FORMATS)}, got {format!r}")
    if format == "gmat":
        thf_name = f"{Path(stem).name}.thf"
        return {f"{stem}.script": gmat.script(plan, thf_name), f"{stem}.thf": gmat.thf(plan)}
    text = {"oem": lambda: oem(plan, created, time_system), "aem": lambda: aem(plan, created, time_system),
            "csv": lambda: csv(plan, time_system), "thf": lambda: gmat.thf(plan)}[format]()
    return {f"{stem}.{format}": text}


def export(source, format: str = "oem", out: str | Path | None = None, *, maneuver=None, method: str | None = None,
           reference_radius: float | None = None, body: str = "earth", mass_kg: float | None = None,
           center: str | None = None, created: str | None = None, time_system: str = "UTC") -> str:
    """Export a plan (module docstring) as ``format`` (:data:`FORMATS`), its epochs in ``time_system`` ('UTC',
    'TAI', 'TT' or 'GPS'); returns the text (for 'gmat': the script) and, with ``out``, writes it to that file
    (atomically; for 'gmat' also the thrust history beside it, ``out`` with suffix .thf, which the script names).
    ``source``: a results directory, a Run, a Solution (which carries its maneuver's epoch, frame and units when
    solved from a file) or a Comparison; ``maneuver`` gives them otherwise.  Raises :class:`ExportError`."""
    if format not in FORMATS:
        raise ExportError(f"format: expected one of {', '.join(FORMATS)}, got {format!r}")
    plan = plan_of(source, maneuver=maneuver, method=method, reference_radius=reference_radius, body=body,
                   mass_kg=mass_kg, center=center)
    stem = str(Path(out).with_suffix("")) if out is not None else "plan"
    texts = files(plan, format, stem, created, time_system)
    main, *others = texts                           # the file asked for first, then what it names
    if out is not None:
        from .io import atomic_write_bytes

        for path, name in [(Path(out), main)] + [(Path(n), n) for n in others]:
            atomic_write_bytes(path, texts[name].encode("utf-8"))
    return texts[main]


__all__ = ["ExportError", "FORMATS", "Plan", "aem", "csv", "csv_units", "export", "files", "oem", "plan_of"]
