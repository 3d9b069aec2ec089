"""The fuel objective reached by continuation in its data (transcription/objectives/fuel/continuation.py,
docs/mathematics.md §25): a fuel problem with an unbounded counted part whose references differ by more than the
homotopy's effort_level_ratio -- configs/leo_body_engine.yaml with control.objective=fuel -- is reached from a bounded problem
whose homotopy starts from the file's own effort problem, through its weights and then its added bounds.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from se3ocp.transcription.objectives import Effort, Fuel
from se3ocp.transcription.objectives.fuel.continuation import ContinuationStart, counted_unbounded, significant
from se3ocp.transcription.objectives.fuel.homotopy import Homotopy
from se3ocp.transcription.ocp import NormBound
from support import maneuver, problem

FUEL = "control.objective=fuel"
#: leo_body_engine's effort optimum's largest moment (kN km; docs §21) and its engine bound (kN)
PEAK_M, ENGINE = 8.3e-9, 1e-3
#: the continuation and the homotopy with their default fields (the solves they compose are not run here)
fc, HOMOTOPY = ContinuationStart(None, None, None), Homotopy(None)
RATIO = HOMOTOPY.effort_level_ratio


def start_problem(p, U):
    return fc.start_problem(p, U, RATIO)


def _effort_controls(n: int, force: float, moment: float) -> np.ndarray:
    """Controls (6, n): force norms up to ``force``, moment norms up to ``moment`` (the effort optimum's shape does
    not matter to the start problem, only its largest magnitudes)."""
    ramp = np.linspace(0.0, 1.0, n)
    U = np.zeros((6, n))
    U[0], U[4] = force * ramp, moment * ramp[::-1]
    return U


def test_the_start_problem_bounds_the_unbounded_part_and_keeps_the_files_effort_problem():
    """start_problem(leo_body_engine, fuel): the moment bounded at margin x the effort optimum's largest moment
    rounded up to one significant digit (1.2 x 8.3e-9 -> 1e-8 kN km, a norm bound: a torque of any direction, as the
    file's); the fuel weights (1, 1e10) become (1, 1e10 x r_m / r_f) = (1, 1e5), and the homotopy's effort problem of
    the start (weights w_i' / r_i) is the file's effort problem scaled: W_m / W_f = 1e10 to round-off.  The engine
    bound is kept."""
    p = problem("leo_body_engine", 10, None, FUEL)
    U = _effort_controls(p.N + 1, 0.7 * ENGINE, PEAK_M)
    s = start_problem(p, U)
    c = s.control
    assert isinstance(c.moment_bound, NormBound)
    assert c.moment_bound.b == pytest.approx(1e-8, rel=1e-15)
    assert c.force_bound == p.control.force_bound and c.objective == Fuel()
    assert c.W_f[0, 0] == pytest.approx(1.0, rel=1e-15)
    assert c.W_m[0, 0] == pytest.approx(1e5, rel=1e-14)
    e = HOMOTOPY.effort_problem(s).control
    assert isinstance(e.objective, Effort)
    ratio = e.W_m[0, 0] / e.W_f[0, 0]
    assert ratio == pytest.approx(p.control.W_m[0, 0] / p.control.W_f[0, 0], rel=1e-13)


def test_the_added_bound_is_rounded_up_to_one_significant_digit():
    """significant: 9.96e-9 -> 1e-8, 1.01e-8 -> 2e-8, and a value already of one digit stays (1e-8, 2, 0.3)."""
    got = significant(np.array([9.96e-9, 1.01e-8, 1e-8, 2.0, 0.3]))
    assert np.allclose(got, [1e-8, 2e-8, 1e-8, 2.0, 0.3], rtol=1e-14, atol=0.0)


def test_no_start_problem_where_the_homotopy_starts_the_problem_itself():
    """None for a problem with every counted part bounded (the fuel raise, leo_engine_fuel) and for an unbounded part
    whose reference is within EFFORT_LEVEL_RATIO of the other's (the fuel raise with its moment unbounded and an
    effort moment of 1, against the force bound 40)."""
    U = _effort_controls(11, 1.0, 1.0)
    assert start_problem(problem("orbit_raise_fuel", 10), U) is None
    assert start_problem(problem("leo_engine_fuel", 10), _effort_controls(11, 7e-4, PEAK_M)) is None
    free = problem("orbit_raise_fuel", 10)
    free = free.replace(control=replace(free.control, moment_bound=None))
    assert counted_unbounded(free).tolist() == [False, True]
    assert 40.0 / 1.0 <= RATIO and start_problem(free, U) is None


def test_the_weights_rise_geometrically_to_the_files():
    """weight_steps: from the start's weights to the file's in round(log10(ratio)) steps of equal factor, the last
    exactly the file's weights, the bounds of the start kept on every step."""
    p = problem("leo_body_engine", 10, None, FUEL)
    s = start_problem(p, _effort_controls(p.N + 1, 0.7 * ENGINE, PEAK_M))
    steps = fc.weight_steps(s, p)
    ratio = p.control.W_m[0, 0] / s.control.W_m[0, 0]
    assert len(steps) == round(np.log10(ratio)) == 5
    w = np.array([s.control.W_m[0, 0]] + [q.control.W_m[0, 0] for q in steps])
    assert np.allclose(w[1:] / w[:-1], ratio ** (1 / 5), rtol=1e-12, atol=0.0)
    assert steps[-1].control.W_m[0, 0] == p.control.W_m[0, 0] and steps[-1].control.W_f[0, 0] == 1.0
    assert all(q.control.moment_bound == s.control.moment_bound for q in steps)
    assert fc.weight_steps(p, p) == []


def test_an_added_bound_is_raised_while_the_optimum_touches_it():
    """raised: the added moment bound times bound_factor when the controls reach it (within AT_BOUND_RTOL),
    None when they stay below it; the engine's own bound is never raised."""
    p = problem("leo_body_engine", 10, None, FUEL)
    s = start_problem(p, _effort_controls(p.N + 1, 0.7 * ENGINE, PEAK_M))
    b = s.control.moment_bound.b
    at = fc.raised(s, p, _effort_controls(p.N + 1, ENGINE, b))
    assert at.control.moment_bound.b == pytest.approx(fc.bound_factor * b, rel=1e-15)
    assert at.control.force_bound == p.control.force_bound
    assert fc.raised(s, p, _effort_controls(p.N + 1, ENGINE, 0.99 * b)) is None


class _Tried:
    """A step's Solution as the path reads it: converged or not, and its controls (warm.U)."""

    def __init__(self, converged: bool, U: np.ndarray):
        self.converged, self.warm = converged, (type("W", (), {"U": U})() if converged else None)


def test_a_step_that_fails_is_halved_in_the_logarithm_then_the_path_ends():
    """path: the weight steps in turn; after a step that did not converge, the geometric mean of the last converged
    problem's weights and the failed one's (1e6 -> 1e7 failed: 10^6.5, then 10^6.25), at most ``shorter`` times in a
    row, then the path ends; a converged shorter step resumes the nominal steps (the next above it: 1e7); with the
    weights at the file's, the added bound is raised while the controls touch it, each raise (10x) or shorter raise
    counting towards bound_steps by its factor."""
    p = problem("leo_body_engine", 10, None, FUEL)
    s = start_problem(p, _effort_controls(p.N + 1, 0.7 * ENGINE, PEAK_M))
    nxt, n = fc.path(s, p), p.N + 1
    b = s.control.moment_bound.b
    ok, bad = _Tried(True, _effort_controls(n, ENGINE, 0.5 * b)), _Tried(False, None)
    wm = lambda step: step[1].control.W_m[0, 0]     # noqa: E731
    first = nxt(p, ())
    assert wm(first) == pytest.approx(1e6, rel=1e-12)
    h = ((first[1], ok),)
    second = nxt(p, h)
    assert wm(second) == pytest.approx(1e7, rel=1e-12)
    h += ((second[1], bad),)
    half = nxt(p, h)
    assert wm(half) == pytest.approx(10 ** 6.5, rel=1e-12) and half[0].endswith("(shorter)")
    assert half[1].control.moment_bound.b == pytest.approx(b, rel=1e-15)
    quarter = nxt(p, h + ((half[1], bad),))
    assert wm(quarter) == pytest.approx(10 ** 6.25, rel=1e-12)
    h3 = h + ((half[1], bad), (quarter[1], bad))
    assert wm(nxt(p, h3)) == pytest.approx(10 ** 6.125, rel=1e-12)
    assert nxt(p, h3 + ((nxt(p, h3)[1], bad),)) is None              # shorter = 3 halvings in a row
    resumed = nxt(p, h + ((half[1], ok),))
    assert wm(resumed) == pytest.approx(1e7, rel=1e-12)
    # the weights at the file's: the bound raised while touched, until raised bound_factor^bound_steps in all
    last = fc.weight_steps(s, p)[-1]
    touch = _Tried(True, _effort_controls(n, ENGINE, b))
    raised = nxt(p, ((last, touch),))
    assert raised[1].control.moment_bound.b == pytest.approx(10 * b, rel=1e-15)
    assert nxt(p, ((last, _Tried(True, _effort_controls(n, ENGINE, 0.5 * b))),)) is None
    top = raised[1].replace(control=replace(raised[1].control, moment_bound=NormBound(b * 10 ** fc.bound_steps)))
    assert nxt(p, ((top, _Tried(True, _effort_controls(n, ENGINE, b * 10 ** fc.bound_steps))),)) is None


@pytest.mark.slow
@pytest.mark.xfail(strict=False, reason="issue 41: since casadi 3.8.2 the continuation's start (leo_engine_fuel's "
                   "problem, test_leo_fuel's xfail) does not converge and the default ends max_iterations after 4698 "
                   "iterations, 742 s (measured 2026-12-06; converged before in 11402, 892 s); the propellant "
                   "objective (tests/test_propellant.py) is the engine's fuel that converges")
def test_the_engine_raise_with_the_fuel_objective_converges():
    """configs/leo_body_engine.yaml on the LGVI with control.objective=fuel (the moment unbounded, w_m = 1e10), default
    options, N = 400 (issue 27, strictest reading of "the LEO fuel raise of the spacecraft issue converges"): converged by the
    continuation, the fuel KKT guard passed on the problem itself (not on a bounded step: its switching values on the
    coast nodes <= Guarded(None).tol), the re-simulated terminal error <= 1e-6, the thrust along the engine axis (off-axis
    force <= 1e-10 of the bound) with 0 <= T <= max.  The continuation's last bounded step had its bound inactive,
    and the answer is below every step with the file's weights (removing or raising a bound cannot raise the
    optimum the continuation follows; 1e-9 relative).  Flown in continuous time (the project's flight engine, not the
    LGVI), the plan's position misses its last node by about what the discrete orbit misses the continuous one, the
    free motion's miss on the same grid, within 5 % (measured 3.609 km against 3.508, 2.9 %: the moment's sharp
    single-node torques add an attitude miss of 0.032 rad against the free motion's 0.0007, and with it a little
    thrust misaimed -- unlike leo_engine_fuel's bounded wheels, 0.22 %).  (The epigraph NLP warm from this optimum is
    no independent check: it wandered to primal infeasibility 5.7e3 within 360 iterations.)  Measured:
    docs/mathematics.md §25: 30201.728488699235 in 11402 iterations, 892 s."""
    import re

    import se3ocp
    from se3ocp.transcription.results.check import continuous_check
    from se3ocp.transcription.objectives.fuel.guard import Guarded

    man = maneuver("leo_body_engine", None, "lgvi", FUEL)   # the figures below are the LGVI's
    p = man.problem
    sol = se3ocp.solve(man)
    lines = sol.stats.get("fuel_continuation")
    print(f"leo_body_engine fuel: {sol.result} cost {sol.cost!r} {sol.iterations} it; {lines}; "
          f"{sol.stats.get('fuel_structure')}")
    assert sol.converged and sol.stats["fuel_guard"] == "passed", sol.message
    assert sol.stats["fuel_switching_max"] <= Guarded(None).tol
    assert lines and lines[0].startswith("start:"), lines
    assert sol.terminal_error <= 1e-6
    b = p.control.force_bound
    T = b.thrust(sol.u_f)
    assert np.max(b.off_axis(sol.u_f)) <= 1e-10 * b.max
    assert T.min() >= -1e-10 * b.max and T.max() <= b.max * (1 + 1e-8)
    steps = [(m.group(1), float(m.group(2))) for m in (re.match(r"continuation (.*): converged in .*, cost (\S+)", l)
                                                       for l in lines) if m]
    bounded = [c for what, c in steps if what.startswith("|u_m| <=") or what == f"w_f 1, w_m {1e10:.3g}"]
    assert bounded and sol.cost <= min(bounded) * (1 + 1e-9), (sol.cost, steps)
    last = [float(m.group(1)) for m in (re.match(r"continuation \|u_m\| <= (\S+):", l) for l in lines) if m][-1]
    assert np.linalg.norm(sol.controls[3:], axis=0).max() < last
    free = continuous_check(se3ocp.simulate(p, np.zeros_like(sol.controls)))
    assert abs(sol.continuous.terminal_position - free.terminal_position) <= 0.05 * free.terminal_position
