"""Exports (problems/export.py) read back by an independent CCSDS library (ccsds-ndm) and compared with
the npz arrays of the results directory they were written from, for every bundled example.

Tolerances: positions, velocities, quaternions, rates and controls to 1e-12 relative (the files print
17 significant digits; the only other error is one rounding of the unit conversion); epochs to 1e-12
of the horizon (the files print enough decimals for 1e-13).  The quaternion convention is checked
against the direction cosine matrix of the CCSDS attitude standard (A(q) = Rᵀ, written out here from
the standard's formula, not from our code) and against scipy's Rotation."""
from __future__ import annotations

import csv as _csv
import datetime as dt
import io
import math
from decimal import Decimal
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import se3ocp
from se3ocp.problems.export import ExportError, export
from se3ocp.problems.store import read_run, write_run
from se3ocp.transcription.ocp import NormBound

from support import CONFIGS

ndm = pytest.importorskip("ccsds_ndm.ndm_io", reason="ccsds-ndm (a test dependency) reads the CCSDS files back")
Rotation = pytest.importorskip("scipy.spatial.transform").Rotation

EXAMPLES = sorted(CONFIGS.glob("*.yaml")) + sorted((CONFIGS / "everyday").glob("*.yaml"))
#: the reference orbit of the normalized examples' exports: 400 km above the Earth's equatorial radius
REF_KM = 6778.137
GM_EARTH = 3.986004418e14
#: steps per orbit of the initial radius (at least N_MIN): the multi-orbit examples need them for the Cayley map
STEPS_PER_ORBIT, N_MIN = 40, 40
CREATED = "2026-12-03T00:00:00"


def profile(man) -> np.ndarray | None:
    """Deterministic smooth controls (6 x n_controls) for a simulation of a smooth example: a rotating
    force of 1e-3 m max(|x_0|, 1) / T^2 and a moment of 1e-3 tr(J) / T^2 (zero where a norm bound of 0
    removes the control); None for a file without smooth control."""
    p = man.problem
    if man.control_kind != "smooth":
        return None
    n = p.disc.n_controls(p.N)
    s = np.linspace(0.0, 2 * np.pi, n)
    shape = np.vstack([np.sin(s), np.cos(s), 0.5 * np.ones(n)])
    f = 1e-3 * p.model.mass * max(np.linalg.norm(man.initial.position), 1.0) / p.T**2
    m = 1e-3 * np.trace(p.model.inertia) / p.T**2
    removed = [isinstance(b, NormBound) and b.b == 0 for b in (p.control.force_bound, p.control.moment_bound)]
    return np.vstack([0.0 * shape if removed[0] else f * shape, 0.0 * shape if removed[1] else m * shape[::-1]])


@lru_cache(maxsize=None)
def run_of(path: Path, root: str) -> Path:
    """A results directory of the example at a small N: impulsive examples solved (their impulses are
    part of the export), the others simulated under :func:`profile` (the export, not the optimum, is
    under test; a solve of the LEO example is exported in its own test)."""
    man = se3ocp.load(path)
    N = N_MIN
    mu = man.problem.model.mu
    if mu is not None:
        period = 2 * math.pi * math.sqrt(np.linalg.norm(man.initial.position) ** 3 / mu)
        N = max(N_MIN, math.ceil(STEPS_PER_ORBIT * man.T / period))
    man = se3ocp.load(path, [f"horizon.N={N}"])
    result = se3ocp.solve(man, "direct") if man.control_kind == "impulsive" else se3ocp.simulate(man, profile(man))
    assert all(s.converged for s in [result]), (path.stem, result.message)
    out = Path(root) / path.stem
    write_run(out, man, result)
    return out


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    return str(tmp_path_factory.mktemp("export_runs"))


def scale_of(man) -> tuple[float, float, dict]:
    """(metres per length unit, seconds per time unit, export keywords) the test expects for ``man``."""
    units = man.physical.units
    if units is not None:
        return {"m": 1.0, "km": 1000.0}[units.length], 1.0, {}
    if man.problem.model.mu is not None and math.isclose(man.problem.model.mu, 4 * math.pi**2, rel_tol=1e-12):
        L = REF_KM * 1000.0
        return L, 2 * math.pi * math.sqrt(L**3 / GM_EARTH), {"reference_radius": REF_KM}
    return math.nan, math.nan, {}


def seconds_since(epoch: str, start: str) -> Decimal:
    """Seconds from ``start`` to ``epoch`` (ISO-8601 UTC, days of 86400 s), parsed here independently."""
    def parse(s):
        day = dt.date.fromisoformat(s[:10])
        hh, mm, ss = s[11:].split(":")
        return day, Decimal(int(hh) * 3600 + int(mm) * 60) + Decimal(ss)
    (d1, s1), (d0, s0) = parse(epoch), parse(start)
    return (d1 - d0).days * 86400 + s1 - s0


def check_epochs(epochs: list[str], t: np.ndarray, time_s: float, start: str) -> None:
    T = float(t[-1] - t[0]) * time_s
    got = np.array([float(seconds_since(e, start)) for e in epochs])
    assert np.max(np.abs(got - t * time_s)) <= 1e-12 * T


def rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def ccsds_dcm(q1, q2, q3, qc) -> np.ndarray:
    """The direction cosine matrix of a CCSDS quaternion (attitude data messages, annex: rotation from
    frame A to frame B), written out element by element."""
    return np.array([
        [q1 * q1 - q2 * q2 - q3 * q3 + qc * qc, 2 * (q1 * q2 + q3 * qc), 2 * (q1 * q3 - q2 * qc)],
        [2 * (q1 * q2 - q3 * qc), -q1 * q1 + q2 * q2 - q3 * q3 + qc * qc, 2 * (q2 * q3 + q1 * qc)],
        [2 * (q1 * q3 + q2 * qc), 2 * (q2 * q3 - q1 * qc), -q1 * q1 - q2 * q2 + q3 * q3 + qc * qc]])


def arrays(run: Path) -> dict:
    npz = next(run.glob("*.npz"))
    with np.load(npz) as z:
        return {k: z[k] for k in z.files}


def cli_export(run: Path, fmt: str, out: Path, kw: dict, capsys) -> tuple[int, str]:
    """``se3ocp export RUN --format FMT --out OUT`` (in-process: the CLI's code path); (exit status, stderr)."""
    from se3ocp.problems.cli import main

    argv = ["export", str(run), "--format", fmt, "--out", str(out), "--quiet"]
    if "reference_radius" in kw:
        argv += ["--reference-radius", repr(kw["reference_radius"])]
    rc = main(argv)
    return rc, capsys.readouterr().err


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_every_example_exports_and_reads_back(path, root, tmp_path, capsys):
    """``se3ocp export`` of every bundled example as OEM, AEM and CSV, read back and compared with its
    npz; a format the example cannot give (an OEM without a central body, CCSDS without physical
    units) is refused with one line saying why (exit 2, nothing written)."""
    run = run_of(path, root)
    man = read_run(run).maneuver
    a = arrays(run)
    L, Tu, kw = scale_of(man)
    start = man.physical.epoch.iso(12)
    has_units = not math.isnan(L)
    has_center = man.problem.model.mu is not None
    for fmt in ("oem", "aem", "csv"):
        out = tmp_path / f"{path.stem}.{fmt}"
        rc, err = cli_export(run, fmt, out, kw, capsys)
        if fmt != "csv" and (not has_units or (fmt == "oem" and not has_center)):
            assert rc == 2 and not out.exists(), err
            assert len(err.splitlines()) == 1 and ("needs km and s" in err or "CENTER_NAME" in err), err
            continue
        assert rc == 0, err
        if fmt == "csv":
            check_csv(out.read_text(), a, man, L, Tu, start)
            continue
        msg = ndm.NdmIo().from_path(out)
        (check_oem if fmt == "oem" else check_aem)(msg, a, man, L, Tu, start)


def check_oem(msg, a, man, L, Tu, start):
    assert msg.id == "CCSDS_OEM_VERS" and msg.version == "2.0"
    assert msg.header.originator == "se3ocp" and msg.header.creation_date
    (seg,) = msg.body.segment
    md = seg.metadata
    assert (md.object_name, md.center_name, md.ref_frame, str(md.time_system)) == (man.name, "EARTH", "EME2000", "UTC")
    assert (md.interpolation, int(md.interpolation_degree)) == ("HERMITE", 3)
    mass_kg = man.problem.model.mass * (1.0 if man.physical.units is not None else math.nan)
    (comment,) = [c for c in seg.data.comment if c.startswith("MASS = ")]
    if math.isfinite(mass_kg):
        assert float(comment.split()[2]) == mass_kg and comment.split()[3] == "[kg],"
    sv = seg.data.state_vector
    assert len(sv) == len(a["t"]) and md.start_time == sv[0].epoch and md.stop_time == sv[-1].epoch
    check_epochs([s.epoch for s in sv], a["t"], Tu, start)
    x = np.array([[s.x.value, s.y.value, s.z.value] for s in sv])
    v = np.array([[s.x_dot.value, s.y_dot.value, s.z_dot.value] for s in sv])
    assert rel(x, a["x"] * (L / 1000.0)) <= 1e-12
    assert rel(v, a["v"] * (L / Tu / 1000.0)) <= 1e-12


def check_aem(msg, a, man, L, Tu, start):
    assert msg.id == "CCSDS_AEM_VERS" and msg.version == "1.0"
    (seg,) = msg.body.segment
    md = seg.metadata
    assert (md.ref_frame_a, md.ref_frame_b, md.attitude_dir.value, md.time_system.value) == (
        "EME2000", "SC_BODY_1", "A2B", "UTC")
    assert (md.attitude_type.value, md.quaternion_type.value) == ("QUATERNION", "LAST")
    states = [s.quaternion_state for s in seg.data.attitude_state]
    assert len(states) == len(a["t"]) and md.start_time == states[0].epoch and md.stop_time == states[-1].epoch
    check_epochs([s.epoch for s in states], a["t"], Tu, start)
    q = np.array([[s.quaternion.q1, s.quaternion.q2, s.quaternion.q3, s.quaternion.qc] for s in states])
    check_quaternions(q, a["R"])


def check_quaternions(q: np.ndarray, R: np.ndarray) -> None:
    """Unit, the CCSDS A -> B transformation A(q) = R^T, scipy's quaternion of R up to sign, continuous."""
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1.0)) <= 1e-15 * 4
    for qk, Rk in zip(q, R):
        assert np.max(np.abs(ccsds_dcm(*qk) - Rk.T)) <= 1e-12
    ref = Rotation.from_matrix(R).as_quat()          # scalar last, the active rotation R
    sign = np.sign(np.einsum("ij,ij->i", ref, q))
    assert np.max(np.abs(q - sign[:, None] * ref)) <= 1e-12
    assert q[0, 3] >= 0 and np.all(np.einsum("ij,ij->i", q[1:], q[:-1]) > 0)


def check_csv(text, a, man, L, Tu, start):
    rows = [r for r in _csv.reader(io.StringIO(text)) if r and not r[0].startswith("#")]
    head, body = rows[0], np.array(rows[1:], dtype=object)
    assert len(body) == len(a["t"])
    col = {h.split(" [")[0]: i for i, h in enumerate(head)}
    unit = {h.split(" [")[0]: h.split(" [")[1][:-1] for h in head if " [" in h}

    def num(names, rows=slice(None)):
        return np.array([[float(x) for x in r] for r in body[rows][:, [col[n] for n in names]]])

    physical = not math.isnan(L)
    t_scale, l_scale = (Tu, L / 1000.0) if physical else (1.0, 1.0)
    if physical:
        assert (unit["t"], unit["x"], unit["vx"], unit["wx"]) == ("s", "km", "km/s", "rad/s")
        check_epochs(list(body[:, col["epoch"]]), a["t"], Tu, start)
    else:
        assert "epoch" not in col and unit["x"] == "length"
    assert rel(num(["t"])[:, 0], a["t"] * t_scale) <= 1e-12
    assert rel(num(["x", "y", "z"]), a["x"] * l_scale) <= 1e-12
    assert rel(num(["vx", "vy", "vz"]), a["v"] * l_scale / t_scale) <= 1e-12
    assert rel(num(["wx", "wy", "wz"]), a["Omega"] / t_scale) <= 1e-12
    check_quaternions(num(["q1", "q2", "q3", "qc"]), a["R"])
    assert np.all(num(["mass"])[:, 0] == man.problem.model.mass)          # kg per file mass unit: 1 (or normalized)
    if "u_f" not in a:
        assert "fx" not in col
        return
    first = 1 if len(a["t_u"]) == len(a["t"]) - 1 else 0      # first order: no control on row t_0
    assert all(x == "" for x in body[:first, col["fx"]])
    mass = {"kg": 1.0}[man.physical.units.mass] if man.physical.units is not None else None
    if mass is not None:
        assert (unit["fx"], unit["mx"]) == ("N", "N*m")
        f_scale, m_scale = mass * L / Tu**2, mass * L**2 / Tu**2
    else:
        f_scale, m_scale = (L / 1000.0 / Tu**2, (L / 1000.0) ** 2 / Tu**2) if physical else (1.0, 1.0)
    assert rel(num(["fx", "fy", "fz"], slice(first, None)), a["f_inertial"] * f_scale) <= 1e-12
    assert rel(num(["mx", "my", "mz"], slice(first, None)), a["u_m"] * m_scale) <= 1e-12


def test_leo_plan_solved_and_exported_in_km_s_newtons(tmp_path):
    """The physical LEO example (km, kg, s), solved at N = 100: the OEM starts at the file's epoch,
    the CSV gives thrust in N (the file's kN times 1000) and torque in N*m (kN*km times 1e6)."""
    man = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=100"])
    sol = se3ocp.solve(man, "direct")
    assert sol.converged, sol.message
    write_run(tmp_path / "leo", man, sol)
    msg = ndm.NdmIo().from_string(export(tmp_path / "leo", "oem", created=CREATED))
    md = msg.body.segment[0].metadata
    assert md.start_time.startswith("2026-03-20T12:00:00.000000")
    assert seconds_since(md.stop_time, md.start_time) == pytest.approx(5560.0, rel=1e-15)
    rows = [r for r in _csv.reader(io.StringIO(export(sol, "csv", maneuver=man))) if r and not r[0].startswith("#")]
    head = rows[0]
    f = np.array([[float(r[head.index(c)]) for c in ("fx [N]", "fy [N]", "fz [N]")] for r in rows[1:]])
    m = np.array([[float(r[head.index(c)]) for c in ("mx [N*m]", "my [N*m]", "mz [N*m]")] for r in rows[1:]])
    assert rel(f, sol.u_f * 1e3) <= 1e-15 and rel(m, sol.u_m * 1e6) <= 1e-15
    assert 0.1 < np.linalg.norm(f, axis=1).max() < 10.0          # a spacecraft's thrust, in newtons


def test_refusals_are_one_line(tmp_path):
    """What cannot be exported says why in one line: normalized units without a reference radius, a
    reference radius for a file with units, an unconverged solution, an unknown format, a span over a
    leap second."""
    e3 = se3ocp.load(CONFIGS / "e3_inclination_change.yaml", ["horizon.N=20"])
    sim = se3ocp.simulate(e3)
    with pytest.raises(ExportError, match=r"normalized orbit units .*--reference-radius") as e:
        export(sim, "oem", maneuver=e3)
    assert "\n" not in str(e.value)
    export(sim, "csv", maneuver=e3)                          # the CSV says normalized in its header
    leo = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20"])
    leo_sim = se3ocp.simulate(leo)
    with pytest.raises(ExportError, match="names its units"):
        export(leo_sim, "oem", maneuver=leo, reference_radius=7000.0)
    with pytest.raises(ExportError, match="names its mass unit"):
        export(leo_sim, "csv", maneuver=leo, mass_kg=500.0)
    n = e3.problem.disc.n_controls(e3.problem.N)
    sim_u = se3ocp.simulate(e3, np.vstack([np.full((3, n), 0.3), np.full((3, n), 1e-4)]))
    text = export(sim_u, "csv", maneuver=e3, reference_radius=REF_KM, mass_kg=500.0)  # E3 as a 500 kg LEO craft
    head = next(line for line in text.splitlines() if not line.startswith("#")).split(",")
    assert "fx [N]" in head and "mx [N*m]" in head and "1 mass unit = 500 kg" in text
    rows = [r.split(",") for r in text.splitlines() if not r.startswith("#")][2:]  # header; row t_0 has no control
    L = REF_KM * 1000.0
    Tu = 2 * math.pi * math.sqrt(L**3 / GM_EARTH)
    f = np.array([[float(r[head.index(c)]) for c in ("fx [N]", "fy [N]", "fz [N]")] for r in rows])
    m = np.array([[float(r[head.index(c)]) for c in ("mx [N*m]", "my [N*m]", "mz [N*m]")] for r in rows])
    assert rel(f, sim_u.u_f * 500.0 * L / Tu**2) <= 1e-12 and rel(m, sim_u.u_m * 500.0 * L**2 / Tu**2) <= 1e-12
    bad = se3ocp.load(CONFIGS / "e3_inclination_change.yaml", ["horizon.N=20", "solver.direct.max_iter=1"])
    with pytest.raises(ExportError, match="did not converge"):
        export(se3ocp.solve(bad, "direct"), "oem", maneuver=bad, reference_radius=REF_KM)
    with pytest.raises(ExportError, match="format"):
        export(sim, "xml", maneuver=e3)
    leap = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20", "epoch=2016-12-31T23:00:00"])
    with pytest.raises(ExportError, match="leap second at the end of 2016-12-31"):
        export(se3ocp.simulate(leap), "aem", maneuver=leap)
    ok = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20", "epoch=2016-12-31T20:00:00"])
    export(se3ocp.simulate(ok), "aem", maneuver=ok)         # ends 21:32:40, before the leap second


def test_quaternion_convention_on_a_known_attitude():
    """Body x along inertial y (R = Rz(90)): the CCSDS quaternion (A2B, scalar last) is
    (0, 0, sin 45, cos 45), whose matrix maps the inertial y axis to the body x axis."""
    from se3ocp.problems.plots import quaternions

    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    q = quaternions(R[None])[0][[1, 2, 3, 0]]
    np.testing.assert_allclose(q, [0, 0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-16)
    np.testing.assert_allclose(ccsds_dcm(*q) @ [0, 1, 0], [1, 0, 0], atol=1e-15)


def test_cli_export_into_the_results_directory(root, capsys):
    """Without --out the plan goes into the results directory (plan.<format>), which stays one run."""
    from se3ocp.problems.cli import main

    run = run_of(CONFIGS / "leo_raise_slew.yaml", root)
    before = (run / "summary.json").read_bytes()
    assert main(["export", str(run), "--format", "aem", "--json"]) == 0
    assert capsys.readouterr().out.strip() == f'["{run}/plan.aem"]'
    assert ndm.NdmIo().from_path(run / "plan.aem").body.segment[0].metadata.object_name == "leo_raise_slew"
    assert (run / "summary.json").read_bytes() == before and not list(run.glob(".*.tmp"))


# ------------------------------------------------------------------------------------------ time systems
#: published offsets: TAI - UTC from IERS Bulletin C (37 s since 2017-01-01, 34 s from 2009-01-01 to 2012-07-01),
#: TT - TAI = 32.184 s (IAU 1991), GPS - UTC = TAI - UTC - 19 s (GPS time = UTC at 1980-01-06)
PUBLISHED = {"2026-03-20T12:00:00": {"UTC": 0, "TAI": 37, "TT": Decimal("69.184"), "GPS": 18},
             "2010-06-01T00:00:00": {"UTC": 0, "TAI": 34, "TT": Decimal("66.184"), "GPS": 15}}


@pytest.mark.parametrize("epoch", sorted(PUBLISHED))
@pytest.mark.parametrize("system", ["UTC", "TAI", "TT", "GPS"])
def test_time_systems_against_published_offsets(epoch, system):
    """OEM, AEM and CSV epochs in each time system, read back (ccsds-ndm for OEM and AEM): TIME_SYSTEM names it and
    every epoch is the UTC one plus the published offset of that system, exactly (to 1e-12 of the horizon)."""
    man = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20", f"epoch={epoch}"])
    sim = se3ocp.simulate(man)
    shift = Decimal(PUBLISHED[epoch][system])
    t = np.asarray(sim.trajectory.t, float)
    for fmt in ("oem", "aem"):
        seg = ndm.NdmIo().from_string(export(sim, fmt, created=CREATED, time_system=system)).body.segment[0]
        assert str(getattr(seg.metadata.time_system, "value", seg.metadata.time_system)) == system
        epochs = ([s.epoch for s in seg.data.state_vector] if fmt == "oem" else
                  [s.quaternion_state.epoch for s in seg.data.attitude_state])
        assert seconds_since(epochs[0], epoch) == shift
        got = np.array([float(seconds_since(e, epoch) - shift) for e in epochs])
        assert np.max(np.abs(got - t)) <= 1e-12 * t[-1]
    rows = [r for r in _csv.reader(io.StringIO(export(sim, "csv", time_system=system))) if r and r[0][0] != "#"]
    col = rows[0].index(f"epoch [{system}]")
    assert seconds_since(rows[1][col], epoch) == shift


def test_a_leap_second_is_refused_in_utc_only():
    """The span over the leap second at the end of 2016 cannot be labelled in UTC (days of 86400 s), but TAI counts
    none: its epochs are start (TAI - UTC = 36 s before 2017) + t, continuous across it."""
    man = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20", "epoch=2016-12-31T23:00:00"])
    sim = se3ocp.simulate(man)
    with pytest.raises(ExportError, match="leap second"):
        export(sim, "oem")
    seg = ndm.NdmIo().from_string(export(sim, "oem", time_system="TAI")).body.segment[0]
    epochs = [s.epoch for s in seg.data.state_vector]
    assert epochs[0].startswith("2016-12-31T23:00:36.000")
    check_epochs(epochs, np.asarray(sim.trajectory.t, float), 1.0, "2016-12-31T23:00:36")
    with pytest.raises(ExportError, match="time system: expected one of UTC, TAI, TT, GPS"):
        export(sim, "oem", time_system="TDB")


def test_cli_time_system(root, tmp_path, capsys):
    """``se3ocp export --time-system TT`` writes TIME_SYSTEM = TT, the start 69.184 s after the UTC epoch (2026)."""
    run = run_of(CONFIGS / "leo_raise_slew.yaml", root)
    from se3ocp.problems.cli import main

    assert main(["export", str(run), "--format", "oem", "--time-system", "TT", "--out", str(tmp_path / "p.oem"),
                 "--quiet"]) == 0
    md = ndm.NdmIo().from_path(tmp_path / "p.oem").body.segment[0].metadata
    assert str(md.time_system) == "TT" and seconds_since(md.start_time, "2026-03-20T12:00:00") == Decimal("69.184")


# ------------------------------------------------------------------------------- the API finds the units
def test_api_export_finds_the_units_of_the_maneuver_file():
    """A Solution of se3ocp.solve / se3ocp.simulate of a file carries the file's epoch, frame and units
    (Solution.physical): export(sol, "oem") without maneuver= is the export with it, byte for byte.  A Problem built
    in Python (no file) still has no units to find, and says so."""
    man = se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=20"])
    sim = se3ocp.simulate(man)
    assert sim.physical is man.physical and sim.with_notes("a note").physical is man.physical
    for fmt in ("oem", "aem", "csv"):
        assert export(sim, fmt, created=CREATED) == export(sim, fmt, maneuver=man, created=CREATED)
    sol = se3ocp.solve(se3ocp.load(CONFIGS / "leo_raise_slew.yaml", ["horizon.N=30"]))
    assert sol.converged and sol.physical is not None
    md = ndm.NdmIo().from_string(export(sol, "oem")).body.segment[0].metadata
    assert md.start_time.startswith("2026-03-20T12:00:00.000") and md.center_name == "EARTH"
    with pytest.raises(ExportError, match="does not name its units"):
        export(se3ocp.simulate(man.problem), "oem")


# ------------------------------------------------------------------- body-frame thrust, throttle and mass
ENGINE_AXIS = np.array([1.0, 0.0, 0.0])      # configs/leo_body_engine.yaml: thruster along body +x, 0..1 N


def engine_columns(text: str) -> dict[str, np.ndarray]:
    """The CSV's columns (header names without units -> float arrays over the rows that have controls)."""
    rows = [r for r in _csv.reader(io.StringIO(text)) if r and not r[0].startswith("#")]
    head, body = rows[0], [r for r in rows[1:] if r[rows[0].index("fx [N]")] != ""]
    return {h.split(" [")[0]: np.array([float(r[i]) for r in body]) for i, h in enumerate(head) if h != "epoch [UTC]"}


def check_engine_csv(text: str) -> None:
    """fb = A(q) f with A the CCSDS matrix of the row's quaternion (this file's formula, not the exporter's), along
    the engine axis to round-off, throttle = fb . axis / 1 N, mass 500 kg, units in the header."""
    head = next(r for r in _csv.reader(io.StringIO(text)) if r and not r[0].startswith("#"))
    assert {"fbx [N]", "fby [N]", "fbz [N]", "throttle [1]", "mass [kg]"} <= set(head)
    c = engine_columns(text)
    f = np.c_[c["fx"], c["fy"], c["fz"]]
    fb = np.c_[c["fbx"], c["fby"], c["fbz"]]
    A = np.array([ccsds_dcm(*q) for q in np.c_[c["q1"], c["q2"], c["q3"], c["qc"]]])
    big = np.max(np.linalg.norm(f, axis=1))
    assert 0.1 < big <= 1.0 + 1e-9                                   # newtons, an engine of at most 1 N
    assert np.max(np.abs(np.einsum("nij,nj->ni", A, f) - fb)) <= 1e-12 * big
    assert np.max(np.linalg.norm(fb - np.outer(fb @ ENGINE_AXIS, ENGINE_AXIS), axis=1)) <= 1e-12 * big
    assert np.max(np.abs(c["throttle"] - fb @ ENGINE_AXIS / 1.0)) <= 1e-12
    assert np.all(c["mass"] == 500.0)


def test_csv_body_thrust_of_an_engine_plan():
    """configs/leo_body_engine.yaml flown under an engine profile T(t) e1 (0 <= T <= 1 N, LGVI and first order): the
    CSV's body-frame thrust is the inertial thrust rotated by its row's attitude, along the engine axis."""
    for scheme in ("lgvi", "first_order"):
        man = se3ocp.load(CONFIGS / "leo_body_engine.yaml", ["horizon.N=200", f"discretization={scheme}"])
        n = man.problem.disc.n_controls(man.problem.N)
        T = 1e-3 * (0.5 + 0.5 * np.sin(np.linspace(0.0, 3.0, n)))      # kN
        U = np.vstack([np.outer(ENGINE_AXIS, T), np.full((3, n), 1e-10)])
        check_engine_csv(export(se3ocp.simulate(man, U), "csv"))


@pytest.mark.slow
def test_csv_body_thrust_of_the_solved_engine_plan():
    """The same of leo_body_engine solved (direct, N = 200, about 11 s: slow): the optimum's thrust in the body frame
    is along the engine, its throttle within [0, 1]."""
    man = se3ocp.load(CONFIGS / "leo_body_engine.yaml", ["horizon.N=200", "solver.continuous_check=false"])
    sol = se3ocp.solve(man)
    assert sol.converged, sol.message
    text = export(sol, "csv")
    check_engine_csv(text)
    assert np.all((engine_columns(text)["throttle"] >= -1e-9) & (engine_columns(text)["throttle"] <= 1 + 1e-9))
