"""Global structure of time-optimal problems (issue 42): starts across the problem's own estimate of its minimum time
and one strategy per homotopy class of the attitude path round its cones (:class:`TimeStrategy`).  Each default solve
is checked against independent single-start solves on the same grid run to the solver's own limit (no coarse grid, no
multistart), and against closed-form bounds.  The two cone slews and the plane change were written after the
strategy; the slew past one cone and the raise are the issue's two maneuvers (configs/slew_keep_out_time.yaml,
configs/orbit_raise_time.yaml)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import unpack_states
from se3ocp.transcription.objectives.time import cone_classes, estimate_times
from se3ocp.transcription.ocp.estimate import eigenaxis_time, transfer_time
from se3ocp.transcription.strategy import starts

from support import default, maneuver, single


def test_minimum_time_estimates_in_closed_form():
    """The raise 1 -> 1.2 (mu = 4 pi^2) at thrust 3: Hohmann's delta-v / 3 = 0.18210; the 120 deg slew about the
    principal z axis (J_z = 2364, |u_z| <= 50): 2 sqrt(theta J_z / 50); a plane change between equal radii needs no
    Hohmann delta-v: no estimate, no extra starts."""
    mu, a, b = 4 * math.pi ** 2, 1.0, 1.2
    dv = math.sqrt(mu / a) * (math.sqrt(2 * b / (a + b)) - 1) + math.sqrt(mu / b) * (1 - math.sqrt(2 * a / (a + b)))
    raise_ = maneuver("orbit_raise_time").problem
    assert transfer_time(raise_) == pytest.approx(dv / 3.0, rel=1e-12) and abs(dv / 3.0 - 0.1821) < 1e-4
    slew = maneuver("slew_keep_out_time").problem
    assert eigenaxis_time(slew) == pytest.approx(2 * math.sqrt(2 * math.pi / 3 * 2364.0 / 50.0), rel=1e-12)
    # x 1, 2, 4: 19.90, 39.80 (within 5 % of the guess 40: counted once), 79.6 clipped to the bound 70
    assert estimate_times(slew, (1.0, 2.0, 4.0)) == pytest.approx([19.902060, 70.0], rel=1e-6)
    assert estimate_times(maneuver("plane_change_time").problem, (1.0, 2.0, 4.0)) == []


def test_cone_classes_route_the_start_on_either_side():
    """The 120 deg slew passes 5.7 deg below the Sun's axis: two classes; the detour's waypoint puts the tracker
    45 deg (40 + the 5 deg clearance) from the Sun, below the slew plane on the near side and above it on the far
    side; both starts meet the file's ends."""
    p = maneuver("slew_keep_out_time").problem
    assert cone_classes(p, 10.0, 4) == [((0, 1),), ((0, -1),)]
    sun = np.asarray(p.constraints[0].direction)
    R_end = unpack_states(p.terminal.X).R[0]
    for side, sign in ((1, -1.0), (-1, 1.0)):
        R = unpack_states(starts.detour(p, {0: side}, math.radians(5.0)).X).R
        axis = R[:, :, 0]                                       # R e1: the tracker, inertial
        angles = np.degrees(np.arccos(np.clip(axis @ sun, -1, 1)))
        k = int(np.argmin(np.abs(angles - 45.0)))
        assert abs(angles[k] - 45.0) < 1e-9 and np.sign(axis[k, 2]) == sign
        assert np.allclose(R[0], np.eye(3), atol=1e-12) and np.allclose(R[-1], R_end, atol=1e-12)
    two = maneuver("slew_two_cones_time").problem
    assert {c for cls in cone_classes(two, 10.0, 4) for c in cls} == {(0, 1), (0, -1), (1, 1), (1, -1)}
    assert len(cone_classes(two, 10.0, 4)) == 4 and len(cone_classes(two, 10.0, 2)) == 2     # at most 2: one cone


@pytest.mark.slow
def test_keep_out_slew_reaches_the_faster_side():
    """Slow (~5 s).  The issue's slew (guess 40 s): before, the defaults ended at 39.23 s; an independent solve from
    one start at T = 30 on the 200 steps reaches 26.8125 s.  Now the default reaches it (1 %) within 60 s, the
    message naming both classes tried."""
    sol, wall = default("slew_keep_out_time")
    best = single("slew_keep_out_time", 30.0)
    assert sol.converged and wall <= 60.0
    assert abs(sol.cost - best) <= 0.01 * best and best < 30.0, (sol.cost, best)
    rows = sol.stats["homotopy_classes"]              # 'keep_out 1 on the near side: 26.8125 (332 iterations)'
    assert [r.split(": ")[0] for r in rows] == ["keep_out 1 on the near side", "keep_out 1 on the far side"]
    assert "homotopy classes tried: keep_out 1 on the near side" in sol.message
    assert min(float(r.split(": ")[1].split()[0]) for r in rows) == pytest.approx(sol.cost, rel=1e-5)
    assert all(int(r.split("(")[1].split()[0]) > 0 for r in rows) and sol.summary()["homotopy_classes"] == rows


@pytest.mark.slow
def test_orbit_raise_reaches_the_fastest_transfer():
    """Slow (~10 s).  The raise 1 -> 1.2 at thrust 3 from the guess 0.4: the default within 1 % of an independent
    start over T = 0.73 (4 times the Hohmann bound) on 200 and 100 steps, above the bound, within 60 s (at N = 100
    the finish from 25 steps wandered off for more than 10 min until the grids halved)."""
    for N in (200, 100):
        sol, wall = default("orbit_raise_time", N)
        best = single("orbit_raise_time", 0.73, N=N)
        assert sol.converged and wall <= 60.0, (N, wall, sol.message)
        assert abs(sol.cost - best) <= 0.01 * best and sol.cost >= transfer_time(maneuver("orbit_raise_time").problem)


@pytest.mark.slow
def test_two_cones_reach_the_best_of_four_classes():
    """Slow (~8 s).  Written after the strategy: the slew past two cones; independent single starts in each of the
    four classes and the straight one on the 100 steps end at 30.21 (straight), 30.21, 38.81, 26.22, 35.96; the
    default reaches the best (1 %) within 60 s, the four classes named."""
    sol, wall = default("slew_two_cones_time")
    classes = [(), ((0, 1), (1, 1)), ((0, 1), (1, -1)), ((0, -1), (1, 1)), ((0, -1), (1, -1))]
    found = [single("slew_two_cones_time", 30.0, c) for c in classes]
    assert sol.converged and wall <= 60.0 and len(sol.stats["homotopy_classes"]) == 4
    assert abs(sol.cost - min(found)) <= 0.01 * min(found), (sol.cost, found)
    assert found[0] > 1.1 * min(found)               # the straight start alone is not enough here


@pytest.mark.slow
def test_plane_change_above_the_impulsive_bound():
    """Slow (~6 s).  Written after the strategy: a 30 deg plane change at thrust 10; the default within 1 % of the
    best of independent starts over T = 0.6 and 1.0 on its 100 steps, and above 2 v sin(15 deg) / 10 = 0.325."""
    sol, wall = default("plane_change_time")
    best = min(single("plane_change_time", T) for T in (0.6, 1.0))
    assert sol.converged and wall <= 60.0 and abs(sol.cost - best) <= 0.01 * best
    assert sol.cost >= 2 * 2 * math.pi * math.sin(math.radians(15.0)) / 10.0


@pytest.mark.slow
def test_a_keep_in_cone_is_the_keep_out_cone_it_leaves_out():
    """Slow (~3 s).  The tracker kept within 140 deg of the anti-Sun direction is the same problem as kept 40 deg
    from the Sun: the same classes (named keep_in) and the same minimum time as the keep-out slew's independent
    solve, 26.8125 s (to 1e-6: the NLPs differ only in the sign of the cone's rows)."""
    sets = ("constraints=[{kind: keep_in, body_axis: [1, 0, 0], direction: [-0.5, -0.8660254037844386, -0.1], "
            "max_angle_deg: 140}]",)
    m = maneuver("slew_keep_out_time", None, None, *sets)
    assert cone_classes(m.problem, 10.0, 4) == [((0, 1),), ((0, -1),)]
    sol = se3ocp.solve(m)
    best = single("slew_keep_out_time", 30.0)
    assert sol.converged and sol.cost == pytest.approx(best, rel=1e-6)
    assert [r.split(": ")[0] for r in sol.stats["homotopy_classes"]] == ["keep_in 1 on the near side",
                                                                          "keep_in 1 on the far side"]
