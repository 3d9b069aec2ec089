"""Issue 24, a force in the body frame and one body-fixed engine (docs/mathematics.md §14): the schema, the
Problem's checks, the direct method with a ThrusterBound, the results (f_inertial, engine on-time), the
continuous flight of a body-frame plan."""
from __future__ import annotations

import numpy as np
import pytest

from se3ocp.transcription.lgvi import discretization
from se3ocp.transcription.problem import ProblemError, SmoothControl, ThrusterBound

from support import maneuver, problem


# ------------------------------------------------------------------------------------------------ schema
def test_force_frame_reaches_the_discretization():
    assert problem("e3", 20).disc.force_frame == "inertial"              # the default: the paper's case
    assert problem("e3", 20, None, "control.force_frame=body").disc.force_frame == "body"
    man = maneuver("leo_body_engine", 40)
    b = man.problem.control.force_bound
    assert man.problem.disc.force_frame == "body" and isinstance(b, ThrusterBound)
    assert np.array_equal(b.axis, [1.0, 0.0, 0.0]) and b.max == 1e-3 and b.min == 0.0
    assert man.resolved["control"]["force_frame"] == "body"
    assert man.resolved["control"]["bounds"]["force"] == {"thruster": {"axis": [1.0, 0.0, 0.0], "max": 1e-3, "min": 0.0}}


def test_thruster_axis_is_normalized_and_min_defaults_to_zero():
    man = maneuver("e3", 20, None, "control.force_frame=body",
                   "control.bounds={force: {thruster: {axis: [0, 3, 4], max: 10}}}")
    b = man.problem.control.force_bound
    assert np.allclose(b.axis, [0.0, 0.6, 0.8], rtol=0, atol=1e-16) and b.min == 0.0 and b.max == 10.0


def test_bounds_margin_shrinks_the_thruster_max():
    b = maneuver("leo_body_engine", 40, None, "control.bounds_margin=0.1").problem.control.force_bound
    assert b.max == pytest.approx(0.9e-3, rel=1e-15) and b.min == 0.0


def test_the_problem_refuses_a_thruster_on_an_inertial_force():
    p = problem("e3", 20)
    thruster = SmoothControl(force_bound=ThrusterBound([1, 0, 0], 10.0))
    with pytest.raises(ProblemError, match="body"):
        p.replace(control=thruster)
    body = p.replace(disc=discretization(p.model, p.scheme, force_frame="body"), control=thruster)
    assert isinstance(body.control.force_bound, ThrusterBound)
