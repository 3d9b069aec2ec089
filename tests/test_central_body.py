"""The central body's radius (model.central_body_radius): a smooth maneuver gets the path
constraint |x| >= clearance once, the direct method goes around the body, and a converged path
through it is flagged inside_central_body, through the CLI and through the API."""
from __future__ import annotations

import json

import numpy as np
import pytest

from se3ocp.transcription.outcome import Result
from support import CONFIGS
from test_cli import run


def test_central_body_radius_adds_min_radius_once():
    """central_body_radius > 0 on a smooth maneuver adds the path constraint min_radius = clearance
    (radius + the dumbbell's length/2 + sphere_radius), also to the resolved file; a given min_radius
    at least as large is not duplicated, a smaller one is kept beside it; radius 0 (every bundled
    maneuver) and impulsive control add nothing."""
    from se3ocp.problems.maneuvers import load_maneuver, parse_maneuver
    from se3ocp.transcription.ocp import MinRadius

    e3 = CONFIGS / "e3_inclination_change.yaml"
    m = load_maneuver(e3, ["model.central_body_radius=0.5"])
    assert m.clearance == pytest.approx(0.57)
    assert [c.radius for c in m.problem.constraints if isinstance(c, MinRadius)] == [pytest.approx(0.57)]
    assert m.resolved["constraints"] == [{"kind": "min_radius", "radius": pytest.approx(0.57)}]
    again = parse_maneuver(m.resolved, "resolved")  # the resolved file states the same problem
    assert [c.radius for c in again.problem.constraints] == [pytest.approx(0.57)]
    m = load_maneuver(e3, ["model.central_body_radius=0.5", "constraints=[{kind: min_radius, radius: 0.8}]"])
    assert [c.radius for c in m.problem.constraints] == [0.8]
    m = load_maneuver(e3, ["model.central_body_radius=0.5", "constraints=[{kind: min_radius, radius: 0.3}]"])
    assert sorted(c.radius for c in m.problem.constraints) == [0.3, pytest.approx(0.57)]
    m = load_maneuver(CONFIGS / "e1_impulsive_tpbvp.yaml", ["model.central_body_radius=0.5"])
    assert m.problem.constraints == ()
    for cfg in sorted(CONFIGS.glob("*.yaml")):
        m = load_maneuver(cfg)
        if m.physical.preset is not None:  # a preset's radius (leo_raise_slew.yaml: the Earth's) is enforced
            assert [c.radius for c in m.problem.constraints if isinstance(c, MinRadius)] == [m.clearance], cfg.name
            continue
        assert m.central_body_radius == 0.0, cfg.name
        assert not any(c.radius == m.clearance for c in m.problem.constraints if isinstance(c, MinRadius)), cfg.name


def test_path_through_the_central_body_is_avoided_when_a_radius_is_given(tmp_path):
    """E3 in 0.05 periods: the unconstrained optimum cuts through |x| = 0.14; with
    central_body_radius 0.5 the enforced clearance makes the direct method go around (exit 0,
    every node at |x| >= 0.57 to the path tolerance), and the indirect method says it does not apply."""
    out = tmp_path / "o"
    r = run("compare", CONFIGS / "e3_inclination_change.yaml", "--set", "horizon.T=0.05", "--set", "horizon.N=50",
             "--set", "model.central_body_radius=0.5", "--out", out, "--no-figures", "--quiet")
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["methods"]["direct"]["status"] == "converged"
    assert s["methods"]["indirect"]["status"] == "not_applicable"
    with np.load(out / "direct.npz") as z:
        assert np.linalg.norm(z["x"], axis=1).min() >= 0.57 - 1e-6


def test_converged_path_inside_the_body_is_flagged_through_the_api():
    """The check runs on the re-simulated path of every method through the API too (se3ocp.solve on
    a Maneuver): the direct solution through the dumbbell's clearance is inside_central_body and not
    converged, the message names the closest node, and the Comparison's verdict follows."""
    from se3ocp.problems import api

    man = api.load(CONFIGS / "e3_inclination_change.yaml", ["horizon.T=0.02", "horizon.N=50"])
    sol = api.solve(man, "direct")
    assert sol.result is Result.inside_central_body and not sol.converged
    assert "enters the central body" in sol.message and "node" in sol.message
    with pytest.raises(Exception):
        api.solve(man, "direct", throw=True)
