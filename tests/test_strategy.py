"""Issue 27: defaults that end at the best answer the tool can reach, and say how.

* the indirect method's fallback: a start from ``initial_costate`` (zero) that fails is started again from the
  direct solution (``from_direct``, with its T for a free final time), and the Solution says which start
  succeeded (message, ``attempts``, ``stats['fallback']``).
"""
from __future__ import annotations

import numpy as np

import se3ocp
from se3ocp.transcription.results import Result
from support import maneuver

#: configs/everyday/detumble.yaml: Newton from lambda_0 = 0 ends at max_iterations (|z_N| ~ 1.5 after 50
#: iterations), from the direct solution's costates it converges in 1-3
DETUMBLE = "everyday/detumble"


def test_a_failed_cold_start_falls_back_to_the_direct_solution():
    """The detumble at N = 40: the cold start fails (asserted: otherwise the test tests nothing), the default
    converges from the direct solution's costates to the direct cost (1e-8 relative) and says so."""
    man = maneuver(DETUMBLE, 40)
    cold = se3ocp.solve(man, "indirect", fallback=False)
    assert not cold.converged and cold.result is Result.max_iterations, cold.message
    sol = se3ocp.solve(man, "indirect")
    assert sol.converged, sol.message
    assert [a.result for a in sol.attempts] == [Result.max_iterations, sol.result]
    assert sol.attempts[0].label == "initial_costate zero" and sol.attempts[1].label.startswith("from_direct")
    assert sol.stats["fallback"] == "from_direct" and sol.stats["direct_status"] == "converged"
    assert "started from the direct solution (initial_costate from_direct) after the start from initial_costate " \
           "zero failed (max_iterations" in sol.message
    assert sol.iterations == cold.iterations + sol.attempts[1].iterations
    assert abs(sol.cost - sol.stats["direct_cost"]) <= 1e-8 * sol.cost
    assert sol.terminal_error <= 1e-10


def test_compare_uses_its_direct_solution_for_the_fallback():
    """'both': the indirect method falls back to the direct solution already computed (no second direct solve:
    no direct_solve_s in its stats), and the verdict is 'agree'."""
    both = se3ocp.solve(maneuver(DETUMBLE, 40), "both")
    assert both.indirect.stats["fallback"] == "from_direct" and "direct_solve_s" not in both.indirect.stats
    assert both.same_extremal, both.verdict
    assert both.verdict.startswith("agree")


def test_a_free_final_time_falls_back_with_the_direct_methods_T():
    """The detumble with T free in [0.05, 0.15]: the cold start fails, the fallback starts from the direct
    solution's T (0.15, where dL/dh < 0 points out of the interval) and reaches it with the same cost."""
    man = maneuver(DETUMBLE, 40, None, "horizon.T={free: true, guess: 0.1, min: 0.05, max: 0.15}")
    sol = se3ocp.solve(man, "indirect")
    assert sol.converged, sol.message
    assert sol.attempts[0].result is Result.max_iterations
    assert "its T = 0.15)" in sol.attempts[1].label
    assert abs(sol.trajectory.t[-1] - 0.15) <= 1e-12
    assert abs(sol.cost - sol.stats["direct_cost"]) <= 1e-8 * sol.cost


def test_no_fallback_without_a_direct_solution():
    """When the direct method does not converge either, the cold start's failure is the result, and the
    attempts say that the fallback had nothing to start from."""
    man = maneuver(DETUMBLE, 40)
    sol = se3ocp.solve(man, "indirect", direct={"max_iter": 2})
    assert sol.result is Result.max_iterations and sol.message.startswith("no convergence in 50 iterations")
    assert sol.attempts[1].result is None and "not available (the direct method ended" in sol.attempts[1].note
    assert sol.stats["fallback"] == "failed" and np.isfinite(sol.stats["direct_solve_s"])
