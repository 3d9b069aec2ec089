"""The YAML maneuver schema (problems/maneuvers.py): the bundled configs load into the Problem they state,
bad input is named precisely."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from se3ocp.transcription.objectives import Time
from se3ocp.problems.models import Dumbbell
from se3ocp.problems.maneuvers import load_maneuver, parse_maneuver
from se3ocp.problems.schema import ConfigError, yaml_load
from se3ocp.transcription.geometry.state import unpack_states
from se3ocp.transcription.geometry.so3 import rot_x, rot_y, rot_z

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
E3 = CONFIGS / "e3_inclination_change.yaml"


def base_doc():
    return yaml_load(E3.read_text())


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.stem)
def test_bundled_configs_load(path):
    man = load_maneuver(path)
    assert man.N > 0 and man.T > 0
    orth = np.linalg.norm(man.initial.R.T @ man.initial.R - np.eye(3))
    assert orth <= 1e-15


def test_spec_examples_match_spec():
    """The examples' numbers (docs/mathematics.md §9) reproduced from the YAML (to 1e-14)."""
    body = Dumbbell()
    e1 = load_maneuver(CONFIGS / "e1_impulsive_tpbvp.yaml")
    np.testing.assert_allclose(e1.terminal.R, rot_z(150) @ rot_y(90), atol=1e-15)
    x = e1.terminal.position
    assert abs(np.linalg.norm(x) - 2) <= 1e-14
    v = e1.terminal.velocity
    assert abs(np.linalg.norm(v) - np.sqrt(4 * np.pi**2 / 2)) <= 1e-13
    assert abs(v @ x) <= 1e-13 and np.cross(x, v)[2] > 0

    e3 = load_maneuver(E3)
    Rd = rot_x(30) @ rot_z(180)
    np.testing.assert_allclose(e3.terminal.R, Rd, atol=1e-15)
    np.testing.assert_allclose(e3.terminal.velocity, rot_x(30) @ [0, -2 * np.pi, 0], atol=1e-14)
    np.testing.assert_allclose(e3.terminal.omega, Rd.T @ rot_x(30) @ [0, 0, 2 * np.pi], atol=1e-14)
    np.testing.assert_allclose(e3.problem.control.W_m, 1e4 * np.eye(3))
    np.testing.assert_allclose(e3.problem.control.W_f, np.eye(3))
    np.testing.assert_array_equal(e3.problem.terminal.X, e3.terminal.vector(body))
    np.testing.assert_array_equal(e3.problem.X0, e3.initial.vector(body))
    assert e3.problem.scheme == "first_order" and e3.problem.N == 500 and e3.problem.T == 0.5
    s = unpack_states(e3.terminal.vector(body))
    np.testing.assert_allclose(s.Pi[0], body.inertia @ e3.terminal.omega, rtol=1e-15)

    e2 = load_maneuver(CONFIGS / "e2_impulsive_relaxed.yaml")
    np.testing.assert_allclose(e2.terminal.normal, rot_x(10) @ [0, 0, 1], atol=1e-15)


def test_yaml12_floats():
    assert yaml_load("a: 1.0e4")["a"] == 1e4 and yaml_load("a: 1e-3")["a"] == 1e-3


def test_override_and_resolved():
    man = load_maneuver(E3, ["horizon.N=100", "solver.indirect.max_iter=7", "control.weights.moment=[1, 2, 3]"])
    assert man.N == 100 and man.indirect.max_iter == 7
    np.testing.assert_allclose(man.problem.control.W_m, np.diag([1, 2, 3]))
    assert man.resolved["horizon"]["N"] == 100
    assert man.resolved["solver"]["direct"]["solver"] == "ipopt"  # defaults written out
    # the resolved config is itself a valid config giving the same maneuver
    again = parse_maneuver(yaml.safe_load(yaml.safe_dump(man.resolved)), "resolved")
    np.testing.assert_array_equal(again.problem.X0, man.problem.X0)
    assert again.direct == man.direct and again.indirect == man.indirect


def test_rotations_product_left_to_right():
    doc = base_doc()
    doc["initial"]["attitude"] = {"rotations": [["z", 150], ["y", 90]]}
    man = parse_maneuver(doc, "t.yaml")
    np.testing.assert_allclose(man.initial.R, rot_z(150) @ rot_y(90), atol=1e-15)


def test_matrix_projected_onto_so3():
    doc = base_doc()
    R = np.round(rot_z(30), 8)  # what a user types: 8 digits
    doc["initial"]["attitude"] = {"matrix": R.tolist()}
    man = parse_maneuver(doc, "t.yaml")
    assert np.linalg.norm(man.initial.R.T @ man.initial.R - np.eye(3)) <= 1e-15
    assert np.abs(man.initial.R - rot_z(30)).max() <= 1e-8


def _set(doc, dotted, value):
    node = doc
    *head, last = dotted.split(".")
    for k in head:
        node = node.setdefault(k, {})
    if value is _DELETE:
        del node[last]
    else:
        node[last] = value


_DELETE = object()

BAD = [
    ("unknown top key", "colour", "red", "colour"),
    ("unknown nested key", "horizon.dt", 0.1, "horizon.dt"),
    ("missing N", "horizon.N", _DELETE, "horizon.N"),
    ("N zero", "horizon.N", 0, "horizon.N"),
    ("N negative", "horizon.N", -5, "horizon.N"),
    ("N fractional", "horizon.N", 10.5, "horizon.N"),
    ("T zero", "horizon.T", 0.0, "horizon.T"),
    ("T string", "horizon.T", "long", "horizon.T"),
    ("T infinite", "horizon.T", float("inf"), "horizon.T"),
    ("T nan", "horizon.T", float("nan"), "horizon.T"),
    ("mass zero", "model.mass", 0.0, "model.mass"),
    ("mass negative", "model.mass", -1.0, "model.mass"),
    ("mass bool", "model.mass", True, "model.mass"),
    ("length negative", "model.length", -0.1, "model.length"),
    ("mu zero", "model.mu", 0.0, "model.mu"),
    ("unknown model kind", "model.kind", "cube", "model.kind"),
    ("position short", "initial.position", [1.0, 0.0], "initial.position"),
    ("position string entry", "initial.position", [1.0, "a", 0.0], "initial.position[1]"),
    ("velocity missing", "initial.velocity", _DELETE, "initial.velocity"),
    ("non-rotation matrix", "initial.attitude", {"matrix": [[1, 0, 0], [0, 2, 0], [0, 0, 1]]}, "initial.attitude.matrix"),
    ("reflection matrix", "initial.attitude", {"matrix": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]}, "initial.attitude.matrix"),
    ("bad rotation axis", "initial.attitude", {"rotations": [["w", 10]]}, "initial.attitude.rotations[0]"),
    ("zero axis", "initial.attitude", {"axis_angle": [0, 0, 0, 10]}, "initial.attitude.axis_angle"),
    ("unknown attitude form", "initial.attitude", {"euler": [1, 2, 3]}, "initial.attitude"),
    ("discretization", "discretization", "rk4", "discretization"),
    ("control kind", "control.kind", "bang", "control.kind"),
    ("weight zero", "control.weights.moment", 0, "control.weights.moment"),
    ("weight negative entry", "control.weights.force", [1, -1, 1], "control.weights.force[1]"),
    ("weight matrix not SPD", "control.weights.force", [[1, 2, 0], [2, 1, 0], [0, 0, 1]], "control.weights.force"),
    ("weight matrix not symmetric", "control.weights.moment", [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]], "control.weights.moment"),
    ("max_iter overflow", "solver.direct", {"max_iter": 1e30}, "solver.direct.max_iter"),
    ("raw option null", "solver.direct", {"options": {"mu_init": None}}, "solver.direct.options.mu_init"),
    ("unavailable linear solver", "solver.direct", {"options": {"linear_solver": "ma57"}}, "solver.direct.options.linear_solver"),
    ("momentum overflow", "initial.velocity", [1e308, 0.0, 0.0], "initial"),
    ("position at origin", "initial.position", [0.0, 0.0, 0.0], "initial.position"),
    ("direct solver", "solver.direct", {"solver": "snopt"}, "solver.direct.solver"),
    ("indirect unknown", "solver.indirect", {"tolerance": 1e-9}, "solver.indirect.tolerance"),
    ("alpha out of range", "solver.indirect", {"alpha": 1.5}, "solver.indirect.alpha"),
    ("box bound zero", "control.bounds", {"moment": {"box": [1, 0, 1]}}, "control.bounds.moment.box[1]"),
    ("norm bound negative", "control.bounds", {"force": {"norm": -1}}, "control.bounds.force.norm"),
    ("bound form unknown", "control.bounds", {"force": {"sphere": 1}}, "control.bounds.force"),
    ("objective unknown", "control.objective", "energy", "control.objective"),
    ("time objective, unbounded", "control.objective", "time", "control.bounds"),
    ("time objective, fixed T", "control", {"kind": "smooth", "objective": "time",
                                            "bounds": {"force": {"norm": 10}, "moment": {"norm": 1}}}, "horizon.T"),
    ("free T min > max", "horizon.T", {"free": True, "guess": 0.5, "min": 0.6, "max": 0.4}, "horizon.T"),
    ("free T guess outside", "horizon.T", {"free": True, "guess": 0.9, "min": 0.4, "max": 0.6}, "horizon.T.guess"),
    ("free T not true", "horizon.T", {"free": False, "guess": 0.5, "min": 0.4, "max": 0.6}, "horizon.T.free"),
    ("fuel with matrix weights", "control", {"kind": "smooth", "objective": "fuel", "weights": {"force": [1, 2, 3]}},
     "control.weights.force"),
    ("constraint kind unknown", "constraints", [{"kind": "stay_cool"}], "constraints[0].kind"),
    ("constraint not a list", "constraints", {"kind": "min_radius", "radius": 1}, "constraints"),
    ("constraint missing key", "constraints", [{"kind": "min_radius"}], "constraints[0].radius"),
    ("keep-out violated at start", "constraints",
     [{"kind": "keep_out", "body_axis": [1, 0, 0], "direction": [1, 0.1, 0], "min_angle_deg": 30}], "constraints[0]"),
    ("keep-in violated at the end", "constraints",
     [{"kind": "keep_in", "body_axis": [1, 0, 0], "direction": [1, 0, 0], "max_angle_deg": 90}], "constraints[0]"),
    ("min radius violated at start", "constraints", [{"kind": "min_radius", "radius": 1.5}], "constraints[0]"),
    ("angle out of range", "constraints",
     [{"kind": "keep_out", "body_axis": [1, 0, 0], "direction": [0, 0, 1], "min_angle_deg": 180}],
     "constraints[0].min_angle_deg"),
    ("gravity kind unknown", "gravity", {"kind": "newtonian"}, "gravity.kind"),
    ("j2 without J2", "gravity", {"kind": "j2", "radius": 0.5}, "gravity.J2"),
    ("J2 for point mass", "gravity", {"kind": "point_mass", "J2": 1e-3}, "gravity.J2"),
    ("rigid body without inertia", "model", {"kind": "rigid_body", "mass": 1.0}, "model.inertia"),
    ("rigid body inertia not SPD", "model", {"kind": "rigid_body", "inertia": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]},
     "model.inertia"),
    ("rigid body with a length", "model", {"kind": "rigid_body", "inertia": [1, 2, 3], "length": 0.1}, "model.length"),
    ("empty terminal", "terminal", {}, "terminal"),
    ("terminal without control", "control", _DELETE, "control"),
]


@pytest.mark.parametrize("label,key,value,field", BAD, ids=[b[0] for b in BAD])
def test_bad_input_names_file_and_field(label, key, value, field):
    doc = base_doc()
    doc["model"]["mass"] = 10.0
    _set(doc, key, copy.deepcopy(value))
    with pytest.raises(ConfigError) as ei:
        parse_maneuver(doc, "bad.yaml")
    msg = str(ei.value)
    assert msg.startswith(f"bad.yaml: {field}:"), msg
    assert "\n" not in msg


def test_orbit_normal_zero_rejected_and_normalized():
    doc = yaml_load((CONFIGS / "e2_impulsive_relaxed.yaml").read_text())
    doc["terminal"]["orbit"]["normal"] = [0, 0, 0]
    with pytest.raises(ConfigError, match="terminal.orbit.normal"):
        parse_maneuver(doc, "e2.yaml")
    doc["terminal"]["orbit"]["normal"] = [0, 0, 5]
    man = parse_maneuver(doc, "e2.yaml")
    np.testing.assert_allclose(man.terminal.normal, [0, 0, 1])


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_maneuver(tmp_path / "missing.yaml")
    p = tmp_path / "broken.yaml"
    p.write_text("name: x\nhorizon: {T: 1, N: [\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_maneuver(p)
    p.write_text("- a list\n- not a mapping\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_maneuver(p)


def test_partial_terminal_and_orbit_target_for_smooth_control():
    """Smooth control: terminal components left out are free; an orbit target is accepted."""
    doc = base_doc()
    del doc["terminal"]["velocity"], doc["terminal"]["angular_velocity"]
    man = parse_maneuver(doc, "t.yaml")
    assert man.problem.terminal.free == {"velocity", "angular_velocity"}
    assert man.problem.terminal.fixed == ("position", "attitude")
    doc = base_doc()
    doc["terminal"] = {"orbit": {"radius": 1.2, "normal": [0, 0, 2], "angular_velocity": [0, 0, 1]}}
    t = parse_maneuver(doc, "t.yaml").problem.terminal
    assert t.radius == 1.2 and np.allclose(t.normal, [0, 0, 1]) and np.allclose(t.Pi, Dumbbell().inertia @ [0, 0, 1])


def test_rigid_body_bounds_free_time_constraints_resolved_round_trip():
    doc = base_doc()
    doc["model"] = {"kind": "rigid_body", "mass": 2.0, "inertia": [3.0, 2.0, 1.0]}
    doc["gravity"] = {"kind": "none"}
    doc["horizon"] = {"N": 50, "T": {"free": True, "guess": 1.0, "min": 0.5, "max": 2.0}}
    doc["control"] = {"kind": "smooth", "objective": "time",
                      "bounds": {"moment": {"box": [1, 2, 3]}, "force": {"norm": 0.0}}}
    doc["constraints"] = [{"kind": "max_angular_rate", "value": 50.0}]
    man = parse_maneuver(doc, "t.yaml")
    p = man.problem
    assert p.free_time and p.time_bounds == (0.5, 2.0) and p.T == 1.0 and p.model.mu is None
    assert np.allclose(p.model.inertia, np.diag([3.0, 2.0, 1.0])) and p.model.mass == 2.0
    assert p.control.objective == Time() and p.control.removed == (True, False)
    assert np.allclose(p.control.moment_bound.b, [1, 2, 3]) and p.constraints[0].value == 50.0
    again = parse_maneuver(yaml.safe_load(yaml.safe_dump(man.resolved)), "resolved")
    assert again.problem.time_bounds == p.time_bounds and again.problem.control.objective == Time()


def test_orbit_normal_is_normalized_and_near_rotation_projected():
    """Documented choices: a non-unit orbit normal is normalized; a matrix within 1e-6 of SO(3) is projected onto it."""
    from se3ocp.problems.maneuvers import load_maneuver

    m = load_maneuver(CONFIGS / "e2_impulsive_relaxed.yaml", ["terminal.orbit.normal=[0, 0, 2.5]"])
    assert np.allclose(m.terminal.normal, [0, 0, 1], atol=0, rtol=1e-15)
    m = load_maneuver(CONFIGS / "e3_inclination_change.yaml",
                      ["initial.attitude={matrix: [[1.0000001, 0, 0], [0, 1, 0], [0, 0, 1]]}"])
    R = m.initial.R
    assert np.abs(R.T @ R - np.eye(3)).max() <= 1e-15 and abs(np.linalg.det(R) - 1) <= 1e-15
