"""Issue 42's acceptance, round 2: beyond-paper maneuvers of our own, written after the strategy (configs/, each
with what it is and the optimum found), whose default solve must reach the best optimum that independent solves
find -- plain solves on the file's grid from other starts (random symmetry-breaking controls over several final
times, routed round each cone on either side), each run to the solver's own limit (no coarse grid, no multistart)
-- within 1e-6 relative (the same NLP solved to IPOPT's tolerance; the optima found differ from each other by
far more), and within 60 s.  The other four are in tests/test_time_classes.py.  Slow: several solves each."""
from __future__ import annotations

import math

import pytest

from se3ocp.transcription.objectives.time import start_sizes
from se3ocp.transcription.ocp.estimate import transfer_time
from se3ocp.transcription.strategy import starts

from support import default, independent, maneuver, single

RTOL = 1e-6


def reaches(name: str, found: list[float]):
    """The default solve of ``name`` converged within 60 s at the best of the independent costs ``found`` (1e-6
    relative); the solve."""
    sol, wall = default(name)
    best = min(found)
    assert sol.converged and wall <= 60.0, (name, wall, sol.message)
    assert sol.cost == pytest.approx(best, rel=RTOL), (name, sol.cost, found)
    return sol


@pytest.mark.slow
def test_keep_in_slew_reaches_the_best_of_both_sides():
    """Slow (~10 s).  The 170 deg slew whose antenna stays within 56 deg of a station: single starts over T = 30
    and 60, straight and routed on either side of the cone's axis, seeds 0 and 1, all end at 26.1590 s; the cone
    is active (23.6019 s without it, the default's own multistart on 25 steps agreeing to 1e-8)."""
    found = [single("slew_keep_in_time", T, sides, seed=k) for T in (30.0, 60.0) for k in (0, 1)
             for sides in ((), ((0, 1),), ((0, -1),))]
    sol = reaches("slew_keep_in_time", found)
    assert [r.split(": ")[0] for r in sol.stats["homotopy_classes"]] == ["keep_in 1 on the near side",
                                                                          "keep_in 1 on the far side"]
    assert abs(sol.cost - 26.1590) < 1e-4


@pytest.mark.slow
def test_half_again_raise_reaches_the_fastest_transfer():
    """Slow (~10 s).  The raise 1 -> 1.5 at thrust 6 from the guess 0.5: single starts over T = 0.3, 0.6, 1.0
    (seeds 0, 1) all end at 0.541160; above the Hohmann bound delta-v / 6 = 0.19022."""
    mu, a, b = 4 * math.pi ** 2, 1.0, 1.5
    dv = math.sqrt(mu / a) * (math.sqrt(2 * b / (a + b)) - 1) + math.sqrt(mu / b) * (1 - math.sqrt(2 * a / (a + b)))
    assert transfer_time(maneuver("orbit_raise_time_half").problem) == pytest.approx(dv / 6.0, rel=1e-12)
    found = [single("orbit_raise_time_half", T, seed=k) for T in (0.3, 0.6, 1.0) for k in (0, 1)]
    sol = reaches("orbit_raise_time_half", found)
    assert sol.cost > dv / 6.0 and abs(sol.cost - 0.541160) < 1e-6


@pytest.mark.slow
def test_fifty_degree_plane_change_is_not_left_at_the_finish_jump():
    """Slow (~20 s).  The 50 deg plane change at thrust 15: single starts over T = 0.5, 0.8, 1.2 (seeds 0, 1) all end
    at 0.521151, above 2 v sin(25 deg) / 15 = 0.354.  Before the finish-jump fallback the default ended at 0.739079:
    25 steps 0.5209, finished on 50 steps at 0.7525; now the finish's jump is said and the starts on the grid kept."""
    found = [single("plane_change_time_50", T, seed=k) for T in (0.5, 0.8, 1.2) for k in (0, 1)]
    sol = reaches("plane_change_time_50", found)
    assert sol.cost >= 2 * 2 * math.pi * math.sin(math.radians(25.0)) / 15.0
    assert sol.stats["finish_jumps"] and "above the coarse optimum" in sol.message


@pytest.mark.slow
def test_effort_slew_tries_both_sides_of_its_cone():
    """Slow (~3 s).  The effort slew past a cone 2 deg off its path: plain solves from the straight interpolation,
    from it routed on either side, and from it with random controls (seeds 0-3) end at 0.00124227 (near side) or
    0.00120915 (far side); the default tries both classes and keeps the far side's."""
    name = "slew_keep_out_effort"
    found = [independent(name, lambda q, s=s: starts.detour(q, dict(s), math.radians(5.0)) if s
                         else starts.interpolation(q)) for s in ((), ((0, 1),), ((0, -1),))]
    found += [independent(name, lambda q, k=k: starts.perturbed(q, start_sizes(q), k)) for k in range(4)]
    sol = reaches(name, found)
    near, far = (float(r.split(": ")[1].split()[0]) for r in sol.stats["homotopy_classes"])
    assert far < near * (1 - 0.02) and sol.cost == pytest.approx(far, rel=1e-5)


@pytest.mark.slow
def test_two_axes_slew_reaches_the_best_of_four_classes():
    """Slow (~50 s).  The slew past a Sun cone on the tracker and an Earth cone on the radiator: single starts over
    T = 30, straight and in three of the four classes, end at 24.4350 (straight; tracker and radiator on the near
    side), 27.2337 and 25.3659 (the fourth's, tracker near and radiator far, wandered 3000 iterations, 8 min on the
    loaded machine, without converging: left out); the default reaches the best, the four classes named."""
    classes = [(), ((0, 1), (1, 1)), ((0, -1), (1, 1)), ((0, -1), (1, -1))]
    found = [single("slew_two_axes_time", 30.0, c) for c in classes]
    sol = reaches("slew_two_axes_time", found)
    assert len(sol.stats["homotopy_classes"]) == 4 and max(found) > 1.1 * min(found)
    assert abs(sol.cost - 24.4350) < 1e-4


@pytest.mark.slow
def test_free_time_rendezvous_reaches_the_better_phasing():
    """Slow (~5 s).  The least-effort rendezvous with T free in [0.3, 1.5]: plain solves from the free motion and from
    the screw interpolation turning with the orbit, over the guesses T = 0.35, 0.5, 0.8, 1.1, 1.45, end at 0.182268
    (T = 0.697), 0.163349 (T = 1.302) or 7.297 (T at its bound 1.5).  (From the plain screw interpolation: 126.5 at
    the bound, or from 0.5 no convergence after 164 s: left out.)  Before the time guesses the default ended at
    0.182268 from the guess 0.8; now it tries 0.8, 0.4899 and 1.0954 and keeps 0.163349."""
    name = "rendezvous_free_time"
    found = [independent(name, lambda q, k=kind: starts.make(k, q), None, f"horizon.T.guess={g}")
             for g in (0.35, 0.5, 0.8, 1.1, 1.45) for kind in ("rollout", "orbit")]
    sol = reaches(name, found)
    assert [r.split(":")[0] for r in sol.stats["time_guesses"]] == ["T guess 0.8", "T guess 0.489898",
                                                                     "T guess 1.09545"]
    assert abs(sol.cost - 0.163349) < 1e-6 and abs(sol.T - 1.3016) < 1e-3 and sol.problem.T == 0.8


def test_effort_strategy_composes_classes_and_time_guesses():
    """No solve: the effort slew past one cone composes one strategy per side (named), the free-time rendezvous one
    per time guess (0.8 and the geometric means with the bounds 0.3 and 1.5), and a cone the straight path is
    nearest at an end node is no class (the keep-in slew's station mirrored to the far side of its path: the
    antenna is nearest the forbidden region at its first node, where no detour can route)."""
    from se3ocp.transcription.objectives.effort import EffortStrategy
    from se3ocp.transcription.strategy.core import BestOf, Guessed
    from se3ocp.transcription.strategy.starts import cone_classes

    m = maneuver("slew_keep_out_effort")
    plan = EffortStrategy().compose(m.problem, m.direct)
    assert isinstance(plan, BestOf) and [s.sides for s in plan.strategies] == [((0, 1),), ((0, -1),)]
    assert plan.names == ("keep_out 1 on the near side", "keep_out 1 on the far side")
    r = maneuver("rendezvous_free_time")
    plan = EffortStrategy().compose(r.problem, r.direct)
    assert all(isinstance(s, Guessed) and not s.inner.bracket_times for s in plan.strategies)
    assert [s.T for s in plan.strategies] == pytest.approx([0.8, math.sqrt(0.24), math.sqrt(1.2)], rel=1e-12)
    mirrored = maneuver("slew_keep_in_time", None, None, "constraints=[{kind: keep_in, body_axis: [0, 0, 1], "
                        "direction: [0.6644630243886747, -0.3420201433256687, 0.6644630243886747], max_angle_deg: 56}]")
    assert cone_classes(mirrored.problem, 10.0, 4) == []
    assert len(cone_classes(maneuver("slew_keep_in_time").problem, 10.0, 4)) == 2
