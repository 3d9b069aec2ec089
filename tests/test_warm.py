"""Warm starts as data (transcription/warm.py): every Solution carries one (``sol.warm``), ``solve(..., warm_start=sol)``
takes it across methods, N and schemes, resampled on SE(3), and says what it reused.

Tolerances: resampling reproduces what it must reproduce exactly (functions linear in time, rotations at
a constant rate, the nodes of the coarse grid on a refined one) to round-off (1e-13 .. 1e-12); warm-started
solves reach the cold optimum to 1e-10 in cost.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NU, X_ROT, pack_state, unpack_states
from se3ocp.transcription.geometry.so3 import exp_so3, orthogonality_error
from se3ocp.transcription.results.start import Start, as_start, start_of
from support import maneuver


def synthetic(N: int, scheme: str, **dual) -> Start:
    """A warm start over T = 2 whose states and controls are known functions of time: positions and momenta
    linear, the attitude turning at a constant rate (R(t) = exp(t w)), controls and costates linear."""
    T = 2.0
    t = np.linspace(0.0, T, N + 1)
    w = np.array([0.3, -0.2, 0.5])
    X = pack_state(np.outer(t, [1.0, 2.0, 3.0]), 1.0 + np.outer(t, [0.5, 0.0, -1.0]),
                   np.array([exp_so3(tk * w) for tk in t]), np.outer(t, [0.1, 0.2, 0.3]))
    tu = t if scheme == "lgvi" else t[1:] - 0.5 * T / N          # the control times (module docstring)
    U = np.vstack([a + b * tu for a, b in zip(np.arange(NU), np.linspace(-1, 1, NU))])
    tl = t[1:] - 0.5 * T / N
    lam = np.column_stack([k - 0.5 * k * tl for k in range(12)])
    return Start(t=t, X=X, U=U, scheme=scheme, source="direct", costates=lam, **dual)


def midpoints(w: Start) -> np.ndarray:
    return w.t[1:] - 0.5 * w.h


def control_times(w: Start) -> np.ndarray:
    return w.t if w.scheme == "lgvi" else midpoints(w)


def within(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """The new times inside the span of the old ones."""
    return (new >= old[0] - 1e-15) & (new <= old[-1] + 1e-15)


# ---------------------------------------------------------------------- resampling
def test_the_same_grid_is_the_warm_start_itself():
    w = synthetic(10, "first_order", multipliers=np.ones(5), nlp_key=(5, ()))
    same, notes = w.fit(10, "first_order")
    assert same is w and notes == ()


@pytest.mark.parametrize("scheme, new_scheme", [("first_order", "first_order"), ("lgvi", "lgvi"),
                                                ("first_order", "lgvi"), ("lgvi", "first_order")])
def test_resampling_is_exact_on_what_it_interpolates_exactly(scheme, new_scheme):
    """From N = 10 to N = 37 (and across schemes): linear positions, momenta, controls and costates and a
    constant-rate rotation come out exactly (to round-off) at the new nodes and control times; the attitudes
    stay on SO(3); T is kept; the multipliers and lambda_0 are dropped, and the notes say so."""
    w = synthetic(10, scheme, multipliers=np.ones(5), nlp_key=(5, ()), lam0=np.ones(12))
    f, notes = w.fit(37, new_scheme)
    ref = synthetic(37, new_scheme)
    assert f.N == 37 and f.scheme == new_scheme and f.T == w.T and f.source == "direct"
    assert np.abs(f.X - ref.X).max() <= 1e-13
    orth, det = orthogonality_error(unpack_states(f.X).R)
    assert orth.max() <= 1e-14 and det.max() <= 1e-14
    # held beyond the first and last old control times (and step midpoints, for the costates)
    inner_u = within(control_times(w), control_times(ref))
    inner_l = within(midpoints(w), midpoints(ref))
    assert inner_u.sum() >= 33 and inner_l.sum() >= 33
    assert np.abs(f.U[:, inner_u] - ref.U[:, inner_u]).max() <= 1e-13
    assert np.abs(f.costates[inner_l] - ref.costates[inner_l]).max() <= 1e-13
    assert f.multipliers is None and f.nlp_key is None and f.lam0 is None
    assert notes == (f"resampled from N = 10 ({scheme}) to N = 37 ({new_scheme}) on SE(3)",
                     "the NLP multipliers and the shooting unknown lambda_0 not reused (they belong to the other grid)")


def test_refining_keeps_the_old_nodes():
    """On a grid 3x finer every third node is an old node (the geodesic passes through its ends)."""
    w = synthetic(8, "lgvi")
    w = Start(t=w.t, X=np.vstack([w.X[:4], w.X[4:] * 1.0]), U=w.U ** 2, scheme="lgvi", source="indirect")
    f, _ = w.fit(24, "lgvi")
    assert np.abs(f.X[::3] - w.X).max() <= 1e-13 and np.abs(f.U[:, ::3] - w.U).max() <= 1e-12


def test_nothing_usable_is_no_warm_start():
    t, X = np.linspace(0, 1, 3), synthetic(2, "lgvi").X
    assert start_of(t, X, None, "lgvi", "direct") is None
    assert start_of(t, X, np.full((NU, 3), np.nan), "lgvi", "direct") is None
    w = start_of(t, X, np.zeros((NU, 3)), "lgvi", "direct", multipliers=np.array([np.nan]), nlp_key=(1, ()),
                      lam0=np.zeros(12))
    assert w.multipliers is None and w.nlp_key is None and np.array_equal(w.lam0, np.zeros(12))
    with pytest.raises(TypeError, match="warm_start"):
        as_start(np.zeros(12))


# ------------------------------------------------------------------- solves, by method
@lru_cache(maxsize=None)
def solved(name: str, N: int, method: str = "direct", scheme: str = "first_order"):
    return se3ocp.solve(maneuver(name, N, scheme), method)


@pytest.mark.parametrize("name", ["e3", "e4"])
@pytest.mark.parametrize("method", ["direct", "indirect"])
def test_a_solution_on_another_grid_saves_iterations(name, method):
    """Solved at N = 100, warm-started at N = 200 (first-order scheme, the README's): fewer iterations than
    the cold solve at N = 200, the same optimum (cost to 1e-10), and the Solution says it was resampled."""
    cold = solved(name, 200, method)
    warm = se3ocp.solve(maneuver(name, 200, "first_order"), method, warm_start=solved(name, 100, method))
    assert cold.converged and warm.converged, warm.message
    assert warm.iterations < cold.iterations, (warm.iterations, cold.iterations)
    assert abs(warm.cost - cold.cost) <= 1e-10 * cold.cost
    assert warm.stats["warm_start"] == f"the {method} solution (N = 100, first_order)"
    assert warm.stats["warm_start_resampled"] is True
    assert "resampled from N = 100 (first_order) to N = 200 (first_order) on SE(3)" in warm.message
    assert "not reused" in warm.stats["warm_start_notes"]


def test_direct_to_indirect_and_back():
    """A direct solution starts the indirect method (lambda_0 from its mapped costates, 'from_direct') and an
    indirect one the direct method (its trajectory and controls; IPOPT's multipliers cold), at another N;
    both reach the cold optimum."""
    d100, i100 = solved("e4", 100), solved("e4", 100, "indirect")
    man = maneuver("e4", 150, "first_order")
    ind = se3ocp.solve(man, "indirect", warm_start=d100)
    assert ind.converged and ind.stats["initial_costate"] == "from_direct"
    assert "lambda_0 from the resampled costates" in ind.message
    d = se3ocp.solve(man, warm_start=i100.warm)                        # a Start itself, not only a Solution
    assert d.converged and "IPOPT's multipliers started cold (the warm start carries none)" in d.message
    assert abs(ind.cost - d.cost) <= 1e-10 * d.cost


def test_the_same_grid_reuses_the_multipliers():
    """On the grid it was solved on, a direct solution restarts IPOPT at its optimum with its multipliers (a
    few iterations); on an NLP of another structure (no Cayley unknowns) the multipliers are not reused and
    the message says so, the primal still is."""
    d = solved("e3", 60)
    man = maneuver("e3", 60, "first_order")
    again = se3ocp.solve(man, warm_start=d)
    assert again.converged and again.iterations <= 2 and again.stats["warm_start_resampled"] is False
    assert again.stats["warm_start_notes"] == ""
    other = se3ocp.solve(man, warm_start=d, cayley_variables=False)
    assert other.converged and abs(other.cost - d.cost) <= 1e-10 * d.cost
    assert "IPOPT's multipliers started cold (they belong to an NLP of another structure)" in other.message


def test_the_indirect_restart_on_its_grid_takes_its_lambda_0():
    """On its own grid an indirect solution's lambda_0 is the start: already converged, nothing changes."""
    i = solved("e3", 60, "indirect")
    again = se3ocp.solve(maneuver("e3", 60, "first_order"), "indirect", warm_start=i)
    assert again.converged and again.stats["initial_costate"] == "warm_start" and again.iterations == 0
    assert np.array_equal(again.warm.lam0, i.warm.lam0) and again.cost == i.cost


def test_another_scheme():
    """A first-order solution starts the LGVI's direct and indirect solves (controls moved from the step
    midpoints to the nodes)."""
    d = solved("e3", 80)
    man = maneuver("e3", 80, "lgvi")
    for method in ("direct", "indirect"):
        s = se3ocp.solve(man, method, warm_start=d)
        assert s.converged, s.message
        assert "resampled from N = 80 (first_order) to N = 80 (lgvi)" in s.message


def test_what_carries_no_warm_start():
    """Solutions that carry nothing usable (a method that does not apply, an impulsive maneuver) have no warm
    start; given as one, the solve is cold and says so; the impulsive method says it does not use one."""
    na = se3ocp.solve(maneuver("e3_min_radius", 30), "indirect")
    assert na.result is se3ocp.Result.not_applicable and na.warm is None
    s = se3ocp.solve(maneuver("e3", 30, "first_order"), warm_start=na)
    assert s.converged and "the warm start given (indirect, not_applicable) carries nothing usable" in s.message
    e1 = se3ocp.solve(maneuver("e1", 30))
    assert e1.converged and e1.warm is None
    again = se3ocp.solve(maneuver("e1", 30), warm_start=solved("e3", 30))
    assert again.converged and "not used (the impulsive method starts from its own guesses)" in again.message


def test_warm_start_of_a_solution_is_its_resimulation():
    """sol.warm is the re-simulated trajectory, the controls, the costates and, for the indirect method, its
    shooting unknown; for the direct method the multipliers of its NLP with that NLP's key."""
    d, i = solved("e3", 40), solved("e3", 40, "indirect")
    assert np.array_equal(d.warm.X, d.trajectory.X) and np.array_equal(d.warm.U, d.controls)
    assert np.array_equal(d.warm.costates, d.costates) and d.warm.lam0 is None
    assert d.warm.multipliers.shape == (d.stats["n_constraints"],) and d.warm.nlp_key[0] == d.stats["n_variables"]
    assert i.warm.multipliers is None and i.warm.lam0.shape == (12,) and i.warm.source == "indirect"
    assert np.array_equal(i.warm.t, i.trajectory.t) and i.warm.X[:, X_ROT].shape == (41, 9)
