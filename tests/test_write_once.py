"""``se3ocp solve``, ``compare`` and ``simulate`` validate once and write their run once (issue 40): the maneuver
file is parsed and validated once, each check of the request (which methods apply, the necessary conditions,
solver.accuracy within reach) runs once, and the figures and report.html are drawn from the result the command
holds -- nothing of the run is read back from disk (store.read_run is for ``plot``, ``report``, ``export``).
What is written is what the read-back path (``se3ocp plot DIR``) writes from the same run."""
from __future__ import annotations

import builtins
import collections
import io
import json
import os
import re
import shutil
from pathlib import Path

from se3ocp.problems import maneuvers, store
from se3ocp.problems.cli import main
from se3ocp.transcription import solve as tsolve
from se3ocp.transcription.ocp import feasibility
from se3ocp.transcription.strategy import refine

from support import config

#: the functions counted, by the name they are counted under: (module, attribute); a function imported into
#: two modules is counted in both, under one name
COUNTED = (("parse_maneuver", maneuvers), ("parse_maneuver", store), ("read_run", store),
           ("not_covered", tsolve), ("necessary_conditions", tsolve), ("necessary_conditions", feasibility),
           ("out_of_reach", tsolve), ("out_of_reach", refine))


def run_counted(monkeypatch, tmp_path: Path, argv: list[str]):
    """Run ``se3ocp argv`` in-process with the COUNTED functions counted and every file opened for reading
    under ``tmp_path`` (where the run is written) recorded.  Returns (exit status, {name: [first argument of
    each call]}, [paths read])."""
    calls = collections.defaultdict(list)
    reads = []

    def counting(name, fn):
        def counted(*args, **kwargs):
            calls[name].append(args[1] if name == "not_covered" else None)   # not_covered: the method asked
            return fn(*args, **kwargs)
        return counted

    for name, module in COUNTED:
        monkeypatch.setattr(module, name, counting(name, getattr(module, name)))
    real_open, root = builtins.open, tmp_path.resolve()

    def recording_open(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and not set(mode) & set("wax+") and \
                Path(file).resolve().is_relative_to(root):
            reads.append(str(file))
        return real_open(file, mode, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", recording_open)
    monkeypatch.setattr(io, "open", recording_open)     # pathlib's
    rc = main(argv)
    monkeypatch.undo()
    return rc, dict(calls), reads


def without_footer(html: str) -> str:
    """report.html without the time it was written."""
    return re.sub(r"<footer>Written by .*? on [^.]*\.", "<footer>", html)


def test_solve_validates_once_and_draws_what_it_holds(monkeypatch, tmp_path):
    out = tmp_path / "o"
    rc, calls, reads = run_counted(monkeypatch, tmp_path, ["solve", str(config("e3")), "--set", "horizon.N=20",
                                                           "--out", str(out), "--quiet"])
    assert rc == 0
    assert calls == {"parse_maneuver": [None], "not_covered": ["direct"], "necessary_conditions": [None],
                     "out_of_reach": [None]}       # read_run: never
    assert reads == []
    names = {p.name for p in out.iterdir()}
    figs = sorted(n[:-len(".png")] for n in names if n.startswith("fig_") and n.endswith(".png"))
    assert {"config.resolved.yaml", "summary.json", "direct.npz", "report.html", "fig_maneuver.png"} <= names
    assert names == {"config.resolved.yaml", "summary.json", "direct.npz", "report.html"} | \
        {f"{f}.{ext}" for f in figs for ext in ("png", "pdf")}
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(figs)
    assert json.loads((out / "summary.json").read_text())["methods"]["direct"]["converged"] is True
    # the same files as the read-back path draws from the same run: figures byte for byte, the same report
    again = tmp_path / "again"
    shutil.copytree(out, again)
    assert main(["plot", str(again), "--quiet"]) == 0
    assert without_footer((again / "report.html").read_text()) == without_footer(html)
    assert {f: (again / f"{f}.png").read_bytes() for f in figs} == {f: (out / f"{f}.png").read_bytes() for f in figs}


def test_simulate_validates_once_and_reads_nothing_back(monkeypatch, tmp_path):
    out = tmp_path / "o"
    rc, calls, reads = run_counted(monkeypatch, tmp_path, ["simulate", str(config("free")), "--out", str(out),
                                                           "--quiet"])
    assert rc == 0
    assert calls == {"parse_maneuver": [None]} and reads == []
    names = {p.name for p in out.iterdir()}
    assert {"config.resolved.yaml", "summary.json", "trajectory.npz", "report.html", "fig_maneuver.png",
            "fig_maneuver.pdf"} <= names
    assert (out / "report.html").read_text().count("data:image/png;base64,") == len(
        [n for n in names if n.endswith(".png")])


def test_compare_narrowed_to_direct_asks_each_question_once(monkeypatch, tmp_path):
    """compare of an impulsive maneuver: the solve refuses 'both' (the indirect method does not apply) and the
    CLI solves it by the direct method -- each method asked about once, by the solve, nothing read back."""
    out = tmp_path / "o"
    rc, calls, reads = run_counted(monkeypatch, tmp_path, ["compare", str(config("e1")), "--set", "horizon.N=40",
                                                           "--out", str(out), "--quiet", "--no-figures"])
    assert rc == 0
    assert calls == {"parse_maneuver": [None], "not_covered": ["both", "direct"], "necessary_conditions": [None],
                     "out_of_reach": [None]}
    assert reads == []
    assert sorted(p.name for p in out.iterdir()) == ["config.resolved.yaml", "direct.npz", "report.html",
                                                     "summary.json"]


def test_a_refusal_is_checked_once_and_writes_nothing(monkeypatch, tmp_path, capsys):
    """An accuracy out of reach: the solve's one check refuses it; one line naming --set and the field, exit 2,
    nothing written."""
    out = tmp_path / "deep" / "o"
    rc, calls, _ = run_counted(monkeypatch, tmp_path, ["solve", str(config("e3")), "--set", "solver.accuracy=1e-6",
                                                       "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("se3ocp: error: --set: solver.accuracy: accuracy 1e-06 is "
                                                           "out of reach")
    assert calls == {"parse_maneuver": [None], "not_covered": ["direct"], "necessary_conditions": [None],
                     "out_of_reach": [None]}
    assert list(tmp_path.iterdir()) == []


def test_a_method_that_does_not_apply_is_one_line(monkeypatch, tmp_path, capsys):
    """The indirect method of an impulsive maneuver: the solve's not_covered, once; the CLI's line names the file
    and control.kind, exit 2, nothing written."""
    out = tmp_path / "o"
    rc, calls, _ = run_counted(monkeypatch, tmp_path, ["solve", str(config("e1")), "--method", "indirect", "--out",
                                                       str(out), "--quiet"])
    err = capsys.readouterr().err.splitlines()
    assert rc == 2 and err == [f"se3ocp: error: {config('e1')}: control.kind: the indirect method applies to smooth "
                               f"maneuvers; impulsive maneuvers are solved by the direct method"]
    assert calls == {"parse_maneuver": [None], "not_covered": ["indirect"]}
    assert list(tmp_path.iterdir()) == []
