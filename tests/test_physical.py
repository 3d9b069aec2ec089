"""Physical units, epochs and orbital elements (problems/bodies.py, epochs.py, elements.py, physical.py):
the central-body preset, the unit names, J2000.0 in UTC, the elements against published examples, and
the unit checks -- each mistake refused in one line naming the field, each legitimate borderline case
accepted."""
from __future__ import annotations

import math
import subprocess
import sys
from decimal import Decimal

import numpy as np
import pytest

from se3ocp.problems.bodies import PRESETS, Scale, UnitSystem
from se3ocp.problems.elements import ElementsError, elements_of, state_of
from se3ocp.problems.epochs import J2000_UTC, Epoch, EpochError, j2000_utc, second_digits
from se3ocp.problems.maneuvers import parse_maneuver
from se3ocp.problems.physical import radians_hint
from se3ocp.problems.schema import ConfigError, yaml_load

from support import CONFIGS, ROOT

MU_KM = 398600.4418


def leo(**changes) -> dict:
    """The LEO example's document with top-level changes (None deletes a key)."""
    doc = yaml_load((CONFIGS / "leo_raise_slew.yaml").read_text())
    for k, v in changes.items():
        if v is None:
            doc.pop(k, None)
        else:
            doc[k] = v
    return doc


def refused(doc, field: str, *words: str) -> str:
    with pytest.raises(ConfigError) as e:
        parse_maneuver(doc, "f.yaml")
    msg = str(e.value)
    assert e.value.field == field and "\n" not in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


# ---------------------------------------------------------------------------- epochs
def test_j2000_in_utc_from_tt_and_the_leap_second_table():
    """J2000.0 = 2000-01-01T12:00:00 TT; TT - TAI = 32.184 s, TAI - UTC = 32 s in 2000, so 11:58:55.816 UTC."""
    assert J2000_UTC == "2000-01-01T11:58:55.816"
    assert j2000_utc().iso(3) == J2000_UTC


def test_epochs_are_exact_and_refuse_what_is_not_utc():
    e = Epoch.parse("2026-12-31T23:59:59.999999999999Z")
    assert e.seconds == Decimal("86399.999999999999")
    assert e.plus(1e-12).iso(12) == "2027-01-01T00:00:00.000000000000"
    assert e.iso(3) == "2027-01-01T00:00:00.000"                            # rounding carries into the next day
    assert Epoch.parse("2026-03-20").plus(0.1).iso(20).endswith("00:00:00.10000000000000000555")  # the float, exactly
    assert e.plus(86400.5).minus(e) == Decimal("86400.5")
    for bad in ("2026-02-30T00:00:00", "2026-03-20T24:00:00", "2016-12-31T23:59:60", "2026-03-20T12:00:00+01:00",
                "20 March 2026", 2026):
        with pytest.raises(EpochError):
            Epoch.parse(bad)
    assert second_digits(5560.0) == 9 and second_digits(0.5) == 13 and second_digits(1e-9) == 15


# ---------------------------------------------------------------------------- presets and units
def test_earth_preset_in_km_and_m():
    man = parse_maneuver(leo(), "leo")
    assert man.problem.model.mu == pytest.approx(MU_KM, rel=1e-15)
    assert man.central_body_radius == pytest.approx(6378.1366, rel=1e-15)
    assert (man.physical.units, man.physical.center) == (UnitSystem("km"), "EARTH")
    assert parse_maneuver(man.resolved, "again").problem.model.mu == man.problem.model.mu   # the resolved file re-reads
    doc = leo(central_body={"name": "earth", "units": "m"}, horizon={"T": 5560.0, "N": 10})
    for block in ("initial", "terminal"):
        doc[block]["elements"]["a"] *= 1000.0
    m = parse_maneuver(doc, "leo_m")
    assert m.problem.model.mu == 3.986004418e14 and m.central_body_radius == 6378136.6
    doc = leo(gravity={"kind": "j2"})
    g = parse_maneuver(doc, "j2").resolved["gravity"]
    assert (g["J2"], g["radius"]) == (1.0826359e-3, pytest.approx(6378.1366, rel=1e-15))


def test_unit_names_follow_from_length_mass_time():
    km, m = UnitSystem("km"), UnitSystem("m")
    assert [km.unit(q) for q in ("force", "moment", "velocity", "inertia", "angular_impulse")] == [
        "kN", "kN·km", "km/s", "kg·km²", "kN·km·s"]
    assert [m.unit(q) for q in ("force", "moment", "impulse")] == ["N", "N·m", "N·s"]
    assert km.display("force") == ("N", 1000.0) and km.display("moment") == ("N·m", 1e6)
    assert m.display("moment") == ("N·m", 1.0) and km.display("length") == ("km", 1.0)


def test_reference_orbit_scale_is_its_period():
    s = Scale.reference_orbit("earth", 6778.137, 4 * math.pi**2)
    a = 6778137.0
    assert s.length_m == a and s.time_s == pytest.approx(2 * math.pi * math.sqrt(a**3 / PRESETS["earth"].gm), rel=1e-15)


# ---------------------------------------------------------------------------- orbital elements
def test_elements_against_vallado_example_2_5_and_2_6():
    """Vallado, Fundamentals of Astrodynamics and Applications, Examples 2-5 (RV2COE) and 2-6 (COE2RV):
    r = (6524.834, 6862.875, 6448.296) km, v = (4.901327, 5.533756, -1.976341) km/s <->
    p = 11067.790 km, e = 0.83285, i = 87.87 deg, RAAN = 227.89 deg, argp = 53.38 deg, nu = 92.335 deg."""
    el = elements_of(MU_KM, [6524.834, 6862.875, 6448.296], [4.901327, 5.533756, -1.976341])
    assert el["a"] * (1 - el["e"] ** 2) == pytest.approx(11067.790, abs=1e-2)
    assert el["e"] == pytest.approx(0.832853, abs=1e-6)
    for k, ref in (("i_deg", 87.870), ("raan_deg", 227.898), ("argp_deg", 53.38), ("nu_deg", 92.335)):
        assert el[k] == pytest.approx(ref, abs=5e-3), k
    e = 0.83285
    x, v = state_of(MU_KM, 11067.790 / (1 - e * e), e, 87.87, 227.89, 53.38, 92.335)
    # the published elements are rounded (argp to 0.01 deg: up to 1e-4 rad * 9600 km = 0.8 km of position)
    np.testing.assert_allclose(x, [6525.344, 6861.535, 6449.125], atol=0.1)
    np.testing.assert_allclose(v, [4.902276, 5.533124, -1.975709], atol=1e-4)
    back = state_of(MU_KM, **el)                     # the unrounded elements give the example's state back
    np.testing.assert_allclose(back[0], [6524.834, 6862.875, 6448.296], rtol=1e-12)
    np.testing.assert_allclose(back[1], [4.901327, 5.533756, -1.976341], rtol=1e-12)


def test_elements_against_curtis_example_4_7_hyperbola():
    """Curtis, Orbital Mechanics for Engineering Students, Example 4.7: h = 80000 km^2/s, e = 1.4,
    i = 30, RAAN = 40, argp = 60, nu = 30 deg -> r = (-4040, 4815, 3629) km, v = (-10.39, -4.772, 1.744) km/s."""
    mu, h, e = 398600.0, 80000.0, 1.4
    x, v = state_of(mu, h**2 / mu / (1 - e * e), e, 30.0, 40.0, 60.0, 30.0)
    np.testing.assert_allclose(x, [-4040, 4815, 3629], atol=0.6)
    np.testing.assert_allclose(v, [-10.39, -4.772, 1.744], atol=6e-3)


def test_elements_round_trip():
    rng = np.random.default_rng(7)
    for _ in range(200):
        e = rng.uniform(0.01, 0.95) if rng.random() < 0.8 else rng.uniform(1.05, 3.0)
        a = rng.uniform(7000, 40000) * (1 if e < 1 else -1)
        nu_max = 179.0 if e < 1 else 0.95 * math.degrees(math.acos(-1 / e))
        el = dict(a=a, e=e, i_deg=rng.uniform(1, 179), raan_deg=rng.uniform(0, 360), argp_deg=rng.uniform(0, 360),
                  nu_deg=rng.uniform(-nu_max, nu_max) % 360)
        back = elements_of(MU_KM, *state_of(MU_KM, **el))
        assert back["a"] == pytest.approx(a, rel=1e-9) and back["e"] == pytest.approx(e, rel=1e-9, abs=1e-12)
        for k in ("i_deg", "raan_deg", "argp_deg", "nu_deg"):
            assert abs((back[k] - el[k] + 180) % 360 - 180) <= 1e-7, k


def test_elements_in_a_file_and_their_errors():
    man = parse_maneuver(leo(), "leo")
    x, v = man.initial.position, man.initial.velocity
    assert np.linalg.norm(x) == pytest.approx(6778.137, rel=1e-15)
    assert np.linalg.norm(v) == pytest.approx(math.sqrt(MU_KM / 6778.137), rel=1e-15)
    assert math.degrees(math.acos(np.cross(x, v)[2] / np.linalg.norm(np.cross(x, v)))) == pytest.approx(51.6, rel=1e-13)
    assert "elements" in man.resolved["initial"]                      # the resolved file keeps the user's form
    for change, field in (({"e": 1.0}, "initial.elements.e"), ({"e": 0.5, "a": -7000.0}, "initial.elements.a"),
                          ({"e": 2.0, "a": -7000.0, "nu_deg": 130.0}, "initial.elements.nu_deg")):
        doc = leo()
        doc["initial"]["elements"].update(change)
        refused(doc, field)
    doc = leo()
    doc["initial"]["position"] = [7000.0, 0, 0]
    refused(doc, "initial.position", "not both")
    with pytest.raises(ElementsError):
        state_of(MU_KM, 7000.0, -0.1, 0, 0, 0, 0)


# ---------------------------------------------------------------------------- unit checks
LEO_KM = {"position": [6778.137, 0.0, 0.0], "velocity": [0.0, 7.668558, 0.0], "attitude": "identity", "angular_velocity": [0, 0, 0]}


def test_gm_in_m3_with_positions_in_km_is_refused():
    """The issue's case: GM = 3.986e14 (m^3/s^2) with a LEO state in km (orbital elements would be
    converted with that GM, consistently: the mistake shows in positions and velocities)."""
    doc = leo(central_body=None, horizon={"T": 5560.0, "N": 50})
    doc["initial"] = dict(LEO_KM)
    doc["terminal"] = {"attitude": "identity"}
    doc["model"]["mu"] = 3.986004418e14
    refused(doc, "model.mu", "m^3/s^2 with positions in km")
    doc["model"]["mu"] = MU_KM                                                     # the right GM: accepted
    parse_maneuver(doc, "ok")


def test_positions_in_m_with_the_km_preset_and_a_contradicting_mu_are_refused():
    doc = leo()
    doc["initial"] = {"position": [6778137.0, 0, 0], "velocity": [0, 7668.6, 0], "attitude": "identity", "angular_velocity": [0, 0, 0]}
    refused(doc, "initial.velocity", "GM in km^3/s^2 with positions in m", "central_body earth")
    doc = leo()
    doc["model"]["mu"] = 3.986004418e14
    refused(doc, "model.mu", "m^3/s^2 while the lengths are in km")
    refused(leo(gravity={"kind": "none"}), "gravity.kind", "contradicts")


def test_gm_check_accepts_legitimate_borderline_states():
    """A hyperbola at 9000 circular speeds and a lander hovering at 0.1 m/s for 60 s above the Moon
    (GM 4902.8 km^3/s^2) pass; the same hover for 100 free-fall times is refused."""
    doc = leo(central_body=None, horizon={"T": 10.0, "N": 10})
    r = 7000.0
    doc["model"]["mu"] = MU_KM
    doc["initial"] = {"position": [r, 0, 0], "velocity": [0, 9000 * math.sqrt(MU_KM / r), 0],
                      "attitude": "identity", "angular_velocity": [0, 0, 0]}
    parse_maneuver(doc, "fast")
    doc["initial"]["velocity"] = [0, 1.1e4 * math.sqrt(MU_KM / r), 0]
    refused(doc, "model.mu", "times the circular speed")
    doc = leo(central_body=None, horizon={"T": 60.0, "N": 10})
    doc["model"]["mu"] = 4902.8
    doc["initial"] = {"position": [1740.0, 0, 0], "velocity": [0, 1e-4, 0], "attitude": "identity", "angular_velocity": [0, 0, 0]}
    parse_maneuver(doc, "hover")
    t_ff = 0.5 * math.pi * math.sqrt(1740.0**3 / (2 * 4902.8))
    doc["horizon"]["T"] = 101 * t_ff
    refused(doc, "model.mu", "fall to the centre")


@pytest.mark.parametrize("angle,name", [(math.pi / 2, "π/2"), (1.5708, "π/2"), (3.1416, "π"), (0.7854, "π/4"),
                                        (-math.pi / 3, "-π/3"), (2 * math.pi, "2π")])
def test_angles_in_radians_are_refused(angle, name):
    assert radians_hint(angle) == name
    doc = leo()
    doc["terminal"]["attitude"] = {"axis_angle": [0, 0, 1, angle]}
    refused(doc, "terminal.attitude.axis_angle[3]", name, "degrees")
    doc["terminal"]["attitude"] = {"rotations": [["x", 30], ["z", angle]]}
    refused(doc, "terminal.attitude.rotations[1][1]", name)


@pytest.mark.parametrize("angle", [3.14, 1.5, 6.3, 0.5, 1.047, 90.0, -45.0, 0.0, 360.0])
def test_angles_in_degrees_near_radian_values_pass(angle):
    """Small rotations in degrees that are not within 1e-4 of a simple fraction of π are accepted."""
    assert radians_hint(angle) is None
    doc = leo()
    doc["terminal"]["attitude"] = {"axis_angle": [0, 0, 1, angle]}
    parse_maneuver(doc, "deg")


def test_unit_mistake_exits_2_with_one_line(tmp_path):
    from se3ocp.problems.schema import yaml_dump

    doc = leo(central_body=None)
    doc["model"]["mu"] = 3.986004418e14
    doc["initial"], doc["terminal"] = dict(LEO_KM), {"attitude": "identity"}
    p = tmp_path / "bad.yaml"
    p.write_text(yaml_dump(doc))
    r = subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", "validate", str(p)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "model.mu" in lines[0] and "m^3/s^2 with positions in km" in lines[0], r.stderr
