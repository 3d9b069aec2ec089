"""The continuous check on by default, and accuracy on demand (issue 26; transcription/accuracy.py,
docs/mathematics.md §11).

* Every successful smooth-control Solution of ``solve`` carries its continuous check (``sol.continuous``),
  equal to a check run by hand on it (the same flight: to round-off, 1e-15 absolute on a miss of 1e-2);
  ``continuous_check=False`` (API) and ``solver.continuous_check: false`` (file, ``--set``) switch it off; a
  failed solve and an impulsive plan carry none.
* The check is in summary.json (``continuous_*``), read back from a results directory with its per-node
  deviations to round-off, in the CLI's table (a ``cont. miss`` column), in ``repr``/HTML, in report.html (a
  section with its table) and in a figure (``fig_continuous``, its terminal values the check's misses).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.accuracy import CHECK_ENV, AccuracyOptions
from se3ocp.transcription.flight import continuous_check

from support import config, maneuver


@pytest.fixture(scope="module")
def e3_both():
    return se3ocp.solve(maneuver("e3", 40, "lgvi"), "both")


def test_the_check_is_on_by_default_and_is_the_check(e3_both, monkeypatch):
    monkeypatch.delenv(CHECK_ENV, raising=False)
    sol = se3ocp.solve(maneuver("e3", 40, "lgvi"), continuous_check=True)
    for s in (sol, e3_both.direct, e3_both.indirect):
        assert s.continuous is not None and s.continuous.ok
        again = continuous_check(s)
        assert abs(again.terminal_error - s.continuous.terminal_error) <= 1e-15
        assert 1e-4 < s.continuous.terminal_error < 1e-1      # the LGVI at N = 40 misses visibly (O(h^2))
    assert AccuracyOptions().continuous_check is True


def test_the_check_switched_off(monkeypatch):
    monkeypatch.delenv(CHECK_ENV, raising=False)
    assert se3ocp.solve(maneuver("e3", 20), continuous_check=False).continuous is None
    man = se3ocp.load(config("e3"), ["horizon.N=20", "solver.continuous_check=false"])
    assert man.accuracy.continuous_check is False and man.resolved["solver"]["continuous_check"] is False
    assert se3ocp.solve(man).continuous is None
    assert se3ocp.solve(man, continuous_check=True).continuous is not None     # the keyword wins
    monkeypatch.setenv(CHECK_ENV, "0")
    assert se3ocp.solve(maneuver("e3", 20).problem).continuous is None   # a Problem: the environment's default


def test_bad_option_is_one_line():
    with pytest.raises(se3ocp.ConfigError, match=r"solver\.continuous_check: expected true or false"):
        se3ocp.load(config("e3"), ["solver.continuous_check=3"])


def test_failed_and_impulsive_solves_skip_it():
    failed = se3ocp.solve(maneuver("e3", 20), max_iter=1, initial_guess="interpolate")
    assert not failed.converged and failed.continuous is None
    imp = se3ocp.solve(maneuver("e1"))
    assert imp.converged and imp.continuous is None


def test_repr_html_and_cli_table(e3_both):
    from se3ocp.problems.cli.progress import table

    s = e3_both.direct
    miss = f"{s.continuous.terminal_error:.1e}"
    assert f"continuous miss {miss}" in repr(s)
    assert s.display()["continuous miss"] == miss and f"<td>{miss}</td>" in s._repr_html_()
    rows = table([e3_both.direct, e3_both.indirect])
    assert "cont. miss" in rows[0] and f"{s.continuous.terminal_error:.2e}" in rows[2]


def test_summary_read_back_report_and_figure(e3_both, tmp_path):
    from se3ocp.problems import store
    from se3ocp.problems.plots import figures
    from se3ocp.problems.report import write_report

    man = maneuver("e3", 40, "lgvi")
    store.write_run(tmp_path, man, e3_both)
    summ = json.loads((tmp_path / "summary.json").read_text())
    for m, s in e3_both.solutions.items():
        b = summ["methods"][m]
        assert b["continuous_terminal_error"] == s.continuous.terminal_error
        assert b["continuous_terminal_attitude_rad"] == s.continuous.terminal_attitude
    run = store.read_run(tmp_path)
    for m, s in run.solutions.items():
        c, c0 = s.continuous, e3_both.solutions[m].continuous
        assert c.terminal_error == c0.terminal_error and c.samples == c0.samples
        assert np.array_equal(c.position_deviation, c0.position_deviation)
        assert np.array_equal(c.attitude_deviation, c0.attitude_deviation)
    html = write_report(tmp_path, draw=False).read_text()
    assert 'id="continuous"' in html and "terminal position miss" in html
    assert f"{e3_both.direct.continuous.terminal_position:.2e}" in html
    fig = figures(e3_both, ("continuous",))["continuous"]
    top, bottom = fig.axes[0], fig.axes[1]
    assert "radii" in top.get_ylabel() and "deg" in bottom.get_ylabel() and "orbital periods" in bottom.get_xlabel()
    y = top.get_lines()[0].get_ydata()
    assert y[-1] == pytest.approx(e3_both.direct.continuous.terminal_position, rel=1e-15)
    a = bottom.get_lines()[0].get_ydata()
    assert a[-1] == pytest.approx(np.degrees(e3_both.direct.continuous.terminal_attitude), rel=1e-15)


def test_no_figure_without_a_check():
    from se3ocp.problems.plots import figures

    sol = se3ocp.solve(maneuver("e3", 20), continuous_check=False)
    assert "continuous" not in figures(sol)
