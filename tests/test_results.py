"""What every method returns (transcription/results.py): the Solution and the Comparison in a notebook (their
repr and HTML: the status, cost, errors, iterations, times, N, T and scheme, never an array), the Attempt
records of the initial guesses and the words derived from them, and the Result codes."""
from __future__ import annotations

import math
from html.parser import HTMLParser

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.results.solution import Attempt, Solution
from se3ocp.transcription.outcome import Result, result_of_solver_status
from se3ocp.transcription.dynamics.trajectory import Trajectory
from support import maneuver


@pytest.fixture(scope="module")
def both():
    return se3ocp.solve(maneuver("e3", 20, "first_order"), "both")


class Cells(HTMLParser):
    """The text of every table cell and header of an HTML fragment, and its caption."""

    def __init__(self):
        super().__init__()
        self.cells, self.tags, self._in = [], [], None

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        self._in = tag if tag in ("td", "th", "caption", "p") else self._in

    def handle_endtag(self, tag):
        self._in = None if tag == self._in else self._in

    def handle_data(self, data):
        if self._in:
            self.cells.append(data)


def cells(fragment: str) -> Cells:
    c = Cells()
    c.feed(fragment)
    return c


def test_solution_repr_is_one_line_of_what_matters(both):
    s = both.direct
    r = repr(s)
    d = s.display()
    assert "\n" not in r and len(r) < 300 and "array" not in r and "[" not in r
    for text in (f"direct {s.result.value}", f"cost {s.cost:.10g}", f"terminal error {s.terminal_error:.1e}",
                 f"{s.iterations} iterations", "N = 20", "T = 0.5", "first_order", f"solve {s.solve_s:.2f} s"):
        assert text in r, (text, r)
    assert d["max |R^T R - I|"] == f"{s.trajectory.orthogonality()['max_orthogonality_error']:.1e}"
    assert str(s) == r


def test_solution_html_is_a_table_of_the_same(both):
    s = both.indirect
    c = cells(s._repr_html_())
    assert c.tags.count("table") == 1 and c.tags.count("tr") == 3          # header, the row, its message
    assert c.cells[0] == f"indirect: {s.result.message}"                     # the caption
    d = s.display()
    assert c.cells[1:1 + len(d)] == list(d) and c.cells[1 + len(d):1 + 2 * len(d)] == list(d.values())
    assert c.cells[-1] == s.message


def test_messages_are_escaped_and_not_applicable_shows_no_numbers():
    sol = Solution(method="indirect", solver="x", result=Result.not_applicable, verdict="<script>alert(1)</script>",
                   trajectory=Trajectory(np.linspace(0, 1, 3), np.tile(np.r_[np.zeros(6), np.eye(3).ravel(),
                                                                               np.zeros(3)], (3, 1))),
                   cost=1.0, terminal_error=0.5)
    html = sol._repr_html_()
    assert "<script>" not in html and "&lt;script&gt;" in html
    d = sol.display()
    assert d["cost"] == d["terminal error"] == d["max |R^T R - I|"] == "-" and d["scheme"] == "-"
    assert "#6e7781" in html                                                 # the grey of 'does not apply'


def test_comparison_shows_both_and_the_verdict(both):
    r = repr(both)
    assert r.startswith(f"Comparison({both.verdict}; cost relative difference") and r.count("Solution(") == 2
    c = cells(both._repr_html_())
    assert c.cells[0] == both.verdict and c.cells[-1].startswith("cost relative difference")
    assert c.tags.count("tr") == 5 and "array" not in r


def test_trajectory_and_warm_start_reprs_hold_no_array(both):
    t, w = both.direct.trajectory, both.direct.warm
    assert repr(t) == "Trajectory(N = 20, T = 0.5, mass 1)"
    assert repr(w) == ("Start(the direct solution (N = 20, first_order), T = 0.5; states, controls, multipliers, "
                       "costates)")
    assert "lambda_0" in repr(both.indirect.warm)


def test_attempt_lines():
    """The words of summary.json's guesses_tried, derived from the records."""
    assert Attempt("rollout", Result.max_iterations, 2).line() == "rollout: max_iterations in 2 iterations"
    assert Attempt("interpolate", Result.converged, 7, 22.3094466412).line() == \
        "interpolate: converged in 7 iterations, cost 22.30944664"
    made = Attempt("relaxed problem", Result.converged, 6)
    assert Attempt("relaxed", Result.converged, 37, 22.6).prepared((made,), "the relaxed problem").line() == \
        "relaxed: converged in 43 iterations (6 of them on the relaxed problem), cost 22.6"
    assert Attempt("coarse", None, note="not available").line() == "coarse: not available"
    assert math.isnan(Attempt("x", Result.infeasible, 3).cost)


def test_solver_statuses_map_to_results():
    assert result_of_solver_status("Solve_Succeeded") is Result.converged
    assert result_of_solver_status("Solved_To_Acceptable_Level") is Result.acceptable
    assert result_of_solver_status("something new") is Result.solver_failed
    assert all(r.message for r in Result) and {r for r in Result if r.successful} == {Result.converged,
                                                                                      Result.round_off_floor}
