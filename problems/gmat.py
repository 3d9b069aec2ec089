"""A plan's thrust history as GMAT (R2020a and later) replays it: a thrust history file and a GMAT script.

The format is GMAT's own (ThrustHistoryFile and ThrustSegment resources, BeginFileThrust/EndFileThrust commands;
help pages https://gmat.sourceforge.net/docs/R2020a/html/ThrustHistoryFile.html and .../BeginFileThrust.html; the
reader, GMAT's plugins/ThrustFilePlugin/src/base/datareader/ThrustHistoryFile.cpp).  A file holds segments:

    BeginThrust {NAME}
    Start_Epoch = DD Mon YYYY hh:mm:ss.sss                 (UTC, Gregorian, milliseconds)
    Thrust_Vector_Coordinate_System = CS                   (a GMAT coordinate system)
    Thrust_Vector_Interpolation_Method = None | Linear | CubicSpline
    Mass_Flow_Rate_Interpolation_Method = None | Linear | CubicSpline
    ModelThrustAndMassRate                                 (or ModelThrustOnly, ModelAccelOnly, ModelAccelAndMassRate)
    t  Fx Fy Fz  mdot                                      (s from Start_Epoch; N (Accel: m/s^2); kg/s, > 0 depletes)
    ...
    EndThrust {NAME}

What is written: one segment PlanSegment from the plan's epoch (which must be a whole millisecond: GMAT's
Gregorian epochs have no finer digit), in the plan's inertial frame about its central body (EME2000 -> GMAT's
MJ2000Eq axes, ICRF/GCRF -> ICRF), the applied inertial force at the nodes (thrust in N when the mass is in kg,
else the acceleration in m/s^2) and a mass flow of 0 (the plan's body has a constant mass).  Between the nodes
GMAT interpolates as the plan's scheme applies its controls (transcription.dynamics.flight.interval_commands): an
LGVI's force varies linearly from u_k at t_k to u_{k+1} (Linear, rows t_0..t_N); the first-order scheme holds
u_{k+1} over (t_k, t_{k+1}] and GMAT's None holds the row at or before t, so row t_k carries u_{k+1} (rows
t_0..t_N, the last repeating u_N).  A body-frame force is R_j u_j at the nodes, interpolated in the inertial
frame: between the nodes it differs from R(t) u(t) by O(h^2), the order of the scheme.

The script starts a spacecraft at the OEM's first record (epoch, position and velocity, the same numbers), its
dry mass the plan's, a point-mass force model of the central body with the plan's GM, and propagates over the
horizon between BeginFileThrust and EndFileThrust, reporting the final state.  Only the central body's point mass
is modelled: a plan whose model has more (J2, gravity-gradient torques act on the attitude only) flies differently
in GMAT unless those forces are added.
"""
from __future__ import annotations

import numpy as np

from .epochs import Epoch
from .plan import ExportError, Plan, csv_units, need_scale, num, oem_state

SEGMENT = "PlanSegment"
MONTHS = ("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec")
#: GMAT's names of CCSDS centre names where they differ from the capitalized name
BODIES = {"MOON": "Luna"}
#: the plan's frame -> GMAT's axes
AXES = {"EME2000": "MJ2000Eq", "ICRF": "ICRF", "GCRF": "ICRF"}
#: coordinate systems every GMAT session defines
BUILT_IN = ("EarthMJ2000Eq", "EarthICRF")


def gregorian(epoch: Epoch, source: str) -> str:
    """``DD Mon YYYY hh:mm:ss.sss`` (GMAT's UTCGregorian) of a whole-millisecond epoch; ExportError otherwise."""
    ms = epoch.seconds * 1000
    if ms != ms.to_integral_value():
        raise ExportError(f"{source}: epoch: GMAT's Gregorian epochs are whole milliseconds, got {epoch.iso(12)}; give "
                          f"the maneuver's epoch to 1 ms for --format thf or gmat")
    hh, rem = divmod(int(epoch.seconds), 3600)
    mm, ss = divmod(rem, 60)
    frac = int(ms) % 1000
    d = epoch.day
    return f"{d.day:02d} {MONTHS[d.month - 1]} {d.year:04d} {hh:02d}:{mm:02d}:{ss:02d}.{frac:03d}"


def coordinate_system(plan: Plan, source: str) -> tuple[str, str, str]:
    """(GMAT coordinate system name, its origin body, its axes) of the plan's frame about its central body."""
    scale = need_scale(plan, "thf")
    if scale.center is None:
        raise ExportError(f"{source}: a thrust history needs the central body of its frame: give central_body: in "
                          f"the maneuver (or --center NAME)")
    body = BODIES.get(scale.center.upper(), scale.center.capitalize())
    axes = AXES[plan.frame]
    return f"{body}{axes}", body, axes


def rows(plan: Plan) -> tuple[str, np.ndarray, np.ndarray]:
    """(GMAT interpolation method, times (n,) in s from the epoch, force (n, 3) in file units) of the thrust
    history (module docstring)."""
    if plan.u_f is None:
        raise ExportError(f"{plan.source}: a thrust history needs smooth controls; this plan has none (impulsive or "
                          f"free motion)")
    t = np.asarray(plan.t, float)
    if len(plan.t_u) == len(t):                      # LGVI: u_k at t_k, linear between
        return "Linear", t, plan.u_f
    return "None", t, np.vstack([plan.u_f, plan.u_f[-1:]])   # first order: u_{k+1} held over (t_k, t_{k+1}]


def thf(plan: Plan) -> str:
    """The thrust history file of a plan (module docstring)."""
    scale = need_scale(plan, "thf")
    start = gregorian(plan.epoch, plan.source)
    cs, _body, _axes = coordinate_system(plan, plan.source)
    method, t, f = rows(plan)
    u = csv_units(plan)
    if scale.mass_kg is not None:
        model, values = "ModelThrustAndMassRate", f * u["force"][1]                      # N
    else:
        model, values = "ModelAccelAndMassRate", f / plan.mass * scale.length_m / scale.time_s**2   # m/s^2
    lines = [f"BeginThrust {{{SEGMENT}}}", f"Start_Epoch = {start}", f"Thrust_Vector_Coordinate_System = {cs}",
             f"Thrust_Vector_Interpolation_Method = {method}", "Mass_Flow_Rate_Interpolation_Method = None", model]
    lines += [f"{num(tk * scale.time_s)} {num(fk)} {num(0.0)}" for tk, fk in zip(t, values)]
    lines.append(f"EndThrust {{{SEGMENT}}}")
    return "\n".join(lines) + "\n"


def script(plan: Plan, thf_name: str) -> str:
    """The GMAT script replaying ``thf_name`` (the :func:`thf` of this plan) from the OEM's first record."""
    scale = need_scale(plan, "gmat")
    start = gregorian(plan.epoch, plan.source)
    cs, body, axes = coordinate_system(plan, plan.source)
    if plan.mu is None:
        raise ExportError(f"{plan.source}: the GMAT script needs the central body's GM; the maneuver has no gravity")
    state = oem_state(plan, scale, 0)
    gm = plan.mu * scale.length_m**3 / scale.time_s**2 / 1e9                               # km^3/s^2
    T = float(plan.t[-1] - plan.t[0]) * scale.time_s
    mass = plan.mass * scale.mass_kg if scale.mass_kg is not None else 1.0
    lines = [f"% GMAT (R2020a or later) script written by se3ocp: the plan {plan.name} ({plan.method} solution, "
             f"{plan.scheme} scheme, {len(plan.t) - 1} steps) replayed from its first epoch.",
             f"% The spacecraft starts at the OEM's first record (the same epoch, position and velocity); the thrust "
             f"history {thf_name} acts between BeginFileThrust and EndFileThrust.",
             f"% Forces: the point mass of {body} with the plan's GM; anything else the plan's model has is not here.",
             f"% {thf_name} is named relative to GMAT's working directory: give its full path if it is elsewhere."]
    if scale.mass_kg is None:
        lines.append("% The plan's mass unit is not kg: the history gives accelerations (m/s^2), the mass is nominal.")
    lines += ["", "Create Spacecraft Craft;", "Craft.DateFormat = UTCGregorian;", f"Craft.Epoch = '{start}';",
             f"Craft.CoordinateSystem = {cs};", "Craft.DisplayStateType = Cartesian;"]
    lines += [f"Craft.{k} = {num(val)};" for k, val in zip(("X", "Y", "Z", "VX", "VY", "VZ"), state)]
    lines += [f"Craft.DryMass = {mass!r};", ""]
    if cs not in BUILT_IN:
        lines += [f"Create CoordinateSystem {cs};", f"{cs}.Origin = {body};", f"{cs}.Axes = {axes};", ""]
    lines += [f"{body}.Mu = {gm!r};", "", "Create ForceModel PlanForces;", f"PlanForces.CentralBody = {body};",
              f"PlanForces.PointMasses = {{{body}}};", "PlanForces.Drag = None;", "PlanForces.SRP = Off;", "",
              "Create Propagator PlanProp;", "PlanProp.FM = PlanForces;", "PlanProp.Type = RungeKutta89;",
              "PlanProp.Accuracy = 1e-13;", "", f"Create ThrustSegment {SEGMENT};", f"{SEGMENT}.ThrustScaleFactor = 1;",
              "", "Create ThrustHistoryFile PlanThrust;", f"PlanThrust.AddThrustSegment = {{'{SEGMENT}'}};",
              f"PlanThrust.FileName = '{thf_name}';", "", "Create ReportFile PlanReport;",
              f"PlanReport.Filename = '{thf_name.rsplit('.', 1)[0]}_gmat_final.txt';", "PlanReport.Precision = 16;", "",
              "BeginMissionSequence;", "BeginFileThrust PlanThrust(Craft);",
              f"Propagate PlanProp(Craft) {{Craft.ElapsedSecs = {T!r}}};", "EndFileThrust PlanThrust(Craft);",
              f"Report PlanReport Craft.UTCGregorian Craft.{cs}.X Craft.{cs}.Y Craft.{cs}.Z Craft.{cs}.VX "
              f"Craft.{cs}.VY Craft.{cs}.VZ;"]
    return "\n".join(lines) + "\n"


__all__ = ["coordinate_system", "gregorian", "rows", "script", "thf"]
