"""report.html (problems/report.py): self-contained, escaped, with the figures of merit of summary.json.

The slow test opens the page in a real headless browser (Debian's chromium; skipped when
/usr/bin/chromium is missing: ``apt-get install -y chromium``): no console message of any kind,
every embedded image decodes, the table and at least three figures are on the screenshot.
"""
from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

import se3ocp
from se3ocp.problems import plots, store
from se3ocp.problems.report import merit_rows, render, write_report
from se3ocp.transcription.ocp import BoxBound, KeepOut, MinRadius, NormBound, SmoothControl
from se3ocp.transcription.objectives import Effort
from support import maneuver, slew_comparison

CHROMIUM = Path("/usr/bin/chromium")


class Page(HTMLParser):
    """The parts of the page the tests look at: images, tables, scripts, external references, ids."""

    def __init__(self, text: str):
        super().__init__()
        self.imgs, self.tables, self.scripts, self.external, self.ids = [], 0, 0, [], set()
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        if tag == "table":
            self.tables += 1
        if tag == "script":
            self.scripts += 1
        for k in ("src", "href"):
            if a.get(k) and not a[k].startswith(("data:", "#")):
                self.external.append(a[k])


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    man = maneuver("e3", 30, "first_order")
    res = se3ocp.solve(man, "both")
    d = tmp_path_factory.mktemp("rep") / "e3"
    store.write_run(d, man, res)
    return d, res, write_report(d)


def test_report_is_self_contained_with_table_figures_history_and_config(compared):
    d, res, path = compared
    assert path == d / "report.html"
    text = path.read_text()
    page = Page(text)
    assert not page.external and page.scripts == 0                     # nothing loaded from elsewhere
    assert len(page.imgs) >= 10 and all(s.startswith("data:image/png;base64,") for s in page.imgs)
    assert {"summary", "verdict", "config", "figures", "fig-maneuver", "fig-attitude_error"} <= page.ids
    assert page.tables >= 3                                             # summary and one history per method
    assert "agree: same extremal" in text and "horizon:" in text and "NOT CONVERGED" not in text
    assert "url(" not in text and "@import" not in text


def test_report_numbers_are_those_of_summary_json(compared):
    d, res, path = compared
    text = path.read_text()
    s = json.loads((d / "summary.json").read_text())
    for m in ("direct", "indirect"):
        b = s["methods"][m]
        for key in ("delta_v", "angular_impulse", "peak_force", "peak_moment", "terminal_attitude_error_deg"):
            assert key in b, key
        assert f"{b['delta_v']:.6g}" in text and f"{b['peak_force']:.6g}" in text
        assert f"{b['cost']:.10g}" in text
    # delta-v is the quadrature of |u_f|/m (first order: u_1..u_N, weights h)
    d_ = res.direct
    assert s["methods"]["direct"]["delta_v"] == pytest.approx(d_.h * np.linalg.norm(d_.u_f, axis=1).sum(), rel=1e-12)


@pytest.fixture(scope="module")
def slew_report(tmp_path_factory):
    """The report of a keep-out slew: no central body, the force removed, the indirect method not
    applicable (support.slew_comparison), without figures."""
    man, res = slew_comparison()
    d = tmp_path_factory.mktemp("rep") / "slew"
    store.write_run(d, man, res)
    return d, res, write_report(d, draw=False).read_text()


def _rows(text: str) -> dict[str, list[str]]:
    """The summary table as {quantity: [unit, cell, ...]} (cells as text, tags stripped)."""
    body = text.split('<table id="summary">', 1)[1].split("</table>", 1)[0]
    out = {}
    for tr in re.findall(r"<tr>(.*?)</tr>", body, re.S):
        cells = [re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
        if cells:
            out[cells[0]] = cells[1:]
    return out


def test_units_in_the_header_and_the_table(compared, slew_report):
    _, _, path = compared
    text = path.read_text()
    assert "T = 0.5 orbital periods" in text and "units: normalized orbit units" in text
    assert _rows(text)["Δv = Σ ω |u_f| / m"][0] == "radii/period"
    assert _rows(text)["final time T"][0] == "periods"
    _, _, text = slew_report
    assert "period" not in text.split("<h2>Resolved configuration</h2>")[0] and "radii" not in text
    assert "T = 10 ·" in text and "units: those of the configuration file" in text
    rows = _rows(text)
    assert rows["∫ |u_m| dt"][0] == "mass·length²/time" and rows["peak |u_m|"][0] == "mass·length²/time²"
    assert rows["final time T"][0] == "time" and rows["minimum margin: keep out"][0] == "deg"


def test_a_removed_force_is_not_reported_at_its_bound(slew_report):
    d, _, text = slew_report
    assert "time with the force at its bound" not in _rows(text)
    assert "force_time_at_bound" not in json.loads((d / "summary.json").read_text())["methods"]["direct"]


def test_a_method_not_applicable_is_a_neutral_card_with_its_message(slew_report):
    """The indirect method on a path-constrained problem: summary.json keeps its status and message
    (and no figures of merit: it solved nothing); the page shows it as a grey card of its own, not
    as a failure and not left out, and the verdict 'not comparable' in grey."""
    d, res, text = slew_report
    block = json.loads((d / "summary.json").read_text())["methods"]["indirect"]
    assert block["status"] == "not_applicable" and "does not cover path constraints" in block["message"]
    assert not [k for k in block if k.startswith("min_margin") or k in ("terminal_attitude_error_deg", "delta_v")]
    assert not (d / "indirect.npz").exists()
    cards = re.findall(r'<div class="card([^"]*)">\s*<div class="head">([^<]*)</div>\s*<div class="msg">([^<]*)</div>', text)
    assert [(c.strip(), h) for c, h, _ in cards] == [("", "direct: converged"), ("na", "indirect: not applicable")]
    assert cards[1][2].startswith("not applicable: the indirect method does not cover path constraints")
    assert "card failed" not in text and "NOT CONVERGED" not in text
    assert '<div class="verdict na" id="verdict">' in text and "<b>not comparable: the indirect method" in text
    assert "<code>se3ocp compare</code>" in text
    assert _rows(text)["status"] == ["", "converged"]                  # the table: the applicable method only


def test_a_round_off_margin_is_not_a_violation(slew_report):
    """A margin of -5e-11 deg is round-off: red only when it exceeds the tolerance, which is the
    maneuver's solver.direct.terminal_tol (the direct method's own threshold), stated in the note."""
    _, res, text = slew_report
    assert "violated by more than 1e-06" in text                         # the file's terminal_tol (the default)
    d = res.direct
    c = d.problem.constraints[0]
    worst = float(np.min(c.angles_deg(d.trajectory)))
    edge = KeepOut(c.body_axis, c.direction, worst + 5e-11)              # the path grazes the cone: margin -5e-11
    sol = dataclasses.replace(d, problem=d.problem.replace(constraints=(edge,)))
    assert -1e-10 < sol.summary()["min_margin_keep_out"] < 0
    cell = {r["label"]: r for r in merit_rows({"direct": sol})}["minimum margin: keep out"]["cells"][0]
    assert cell["bad"] is False                                          # default tolerance 1e-8
    cell = {r["label"]: r for r in merit_rows({"direct": sol}, tol=1e-12)}["minimum margin: keep out"]["cells"][0]
    assert cell["bad"] is True
    for tol, shaded in ((None, False), (1e-12, True)):                   # the figure shades by the same rule
        fig = plots.figures(sol, ("constraints",), constraint_tol=tol)["constraints"]
        assert bool([a for a in fig.findobj() if getattr(a, "get_gid", lambda: None)() == "bound-active"]) is shaded
        plt.close(fig)
    assert store.path_tolerance(maneuver("e3", 30, None, "solver.direct.terminal_tol=1e-12")) == 1e-12
    assert store.path_tolerance(None) == store.DEFAULT_PATH_TOL == 1e-8


def test_bounds_and_constraints_read_as_words(slew_report):
    _, _, text = slew_report
    assert "force: removed (a norm bound of 0)" in text and "|u| ≤ 0" not in text
    assert "body axis b = (1, 0, 0), direction s = (0.693, 0.693, 0.196)" in text


def test_wide_figures_span_the_page(slew_report, tmp_path):
    """A wide figure (a slew's frames side by side, the maneuver with a zoom panel) spans both
    columns, so that its text is not shrunk to half the size of the others'."""
    from PIL import Image

    from se3ocp.problems.report import _wide

    def png(w, h):
        import io

        buf = io.BytesIO()
        Image.new("RGB", (w, h), "white").save(buf, format="PNG")
        return buf.getvalue()

    figs = [("maneuver", png(1200, 300)), ("attitude", png(700, 620)), ("control_norms", png(750, 330)),
            ("moment", png(750, 600))]
    assert _wide(figs) == [True, False, False, False]                 # short is not wide
    d, _, _ = slew_report
    text = render(store.read_run(d), figs)
    assert '<figure id="fig-maneuver" class="wide">' in text and '<figure id="fig-control_norms">' in text


def test_user_text_is_escaped(compared, tmp_path):
    d, res, _ = compared
    evil = '<img src=x onerror=alert(1)>&"'
    man = maneuver("e3", 30, "first_order", f"name={json.dumps(evil)}")
    bad = dataclasses.replace(res.direct, verdict=evil, notes=())
    store.write_run(tmp_path, man, bad)
    text = write_report(tmp_path, draw=False).read_text()
    assert evil not in text and "onerror=alert(1)&gt;" in text and "&lt;img src=x" in text
    assert Page(text).imgs == []                                        # draw=False and no PNGs: no figures


def test_failed_run_is_red_and_named(tmp_path):
    man = maneuver("e4", 30, None, "solver.direct.max_iter=2")
    sol = se3ocp.solve(man)
    store.write_run(tmp_path, man, sol)
    text = write_report(tmp_path, draw=False).read_text()
    assert 'class="card failed"' in text and "direct: NOT CONVERGED — max_iterations" in text
    assert '<span class="bad">max_iterations</span>' in text


def test_bounds_and_constraint_margins_in_the_table():
    man = maneuver("e3", 30, "first_order")
    sol = se3ocp.solve(man)
    prob = sol.problem
    b = 0.5 * np.linalg.norm(sol.u_f, axis=1).max()
    pb = prob.replace(control=SmoothControl(prob.control.W_f, prob.control.W_m, objective=Effort(), force_bound=NormBound(b),
                                            moment_bound=BoxBound([1e-3, 1e-3, 1e-3])),
                      constraints=(KeepOut([1, 0, 0], [0, 1, 0], 40.0), MinRadius(0.9)))
    sim = se3ocp.simulate(pb, sol.controls)                  # the unbounded optimum violates both
    rows = {r["label"]: r for r in merit_rows({"simulate": sim})}
    assert {"time with the force at its bound", "time with the moment at its bound",
            "minimum margin: keep out", "minimum margin: min radius"} <= set(rows)
    assert rows["minimum margin: keep out"]["cells"][0]["bad"] is True          # violated: flagged
    assert rows["minimum margin: min radius"]["cells"][0]["bad"] is False
    assert rows["minimum margin: keep out"]["unit"] == "deg"
    run = store.Run(man, {"simulate": sim}, store.summary(man, sim))
    text = render(run, [])
    assert "force: |u| ≤" in text and "keep-out" in text and "td class=\"num bad\"" in text


# ------------------------------------------------------------------------- a real browser
def _chromium(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                           "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
                           f"--user-data-dir={tmp / 'profile'}", "--enable-logging=stderr", "--v=0",
                           "--virtual-time-budget=5000", *args], capture_output=True, text=True, timeout=180)


def _console(stderr: str) -> list[str]:
    """Every console message the page produced (Chromium logs them as ...:CONSOLE:<line>] "text")."""
    return [ln for ln in stderr.splitlines() if re.search(r":CONSOLE[:(]", ln) or "Uncaught" in ln]


PROBE = """<script>window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  console.log("SE3OCP-PROBE images=" + imgs.length + " decoded=" + ok + " tables=" + document.querySelectorAll("table").length);
});</script>"""


@pytest.mark.slow
@pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium (apt-get install -y chromium)")
def test_report_in_a_headless_browser(tmp_path):
    from PIL import Image

    from se3ocp.problems.plots import draw_all

    man = maneuver("e3", 30, "first_order")
    d = tmp_path / "e3"
    store.write_run(d, man, se3ocp.solve(man, "both"))
    draw_all(d)
    report = write_report(d)
    # the detector works: a page with a script error is caught
    bad = tmp_path / "bad.html"
    bad.write_text("<!DOCTYPE html><html><body><p>x</p><script>undefined_function();</script></body></html>")
    assert any("Uncaught ReferenceError" in ln for ln in _console(_chromium(tmp_path, "--dump-dom", bad.as_uri()).stderr))
    # the report itself: no console message at all, the table and the figures in the DOM
    r = _chromium(tmp_path, "--dump-dom", report.as_uri())
    assert r.returncode == 0, r.stderr[-2000:]
    assert _console(r.stderr) == []
    dom = Page(r.stdout)
    assert "summary" in dom.ids and dom.tables >= 1
    assert sum(s.startswith("data:image/png;base64,") for s in dom.imgs) >= 3
    # every embedded image decodes (probe appended to a copy: the report has no script of its own)
    probe = tmp_path / "probe.html"
    probe.write_text(report.read_text().replace("</body>", PROBE + "</body>"))
    msgs = _console(_chromium(tmp_path, "--dump-dom", probe.as_uri()).stderr)
    m = [re.search(r"SE3OCP-PROBE images=(\d+) decoded=(\d+) tables=(\d+)", ln) for ln in msgs]
    m = [x for x in m if x]
    assert len(m) == 1 and len(msgs) == 1, msgs
    n, ok, tables = map(int, m[0].groups())
    assert n == ok >= 3 and tables >= 1
    # the screenshot is a page, not a blank: table and figures drawn
    shot = tmp_path / "shot.png"
    r = _chromium(tmp_path, f"--screenshot={shot}", "--window-size=1280,4000", report.as_uri())
    assert shot.is_file(), r.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    assert img.shape[:2] == (4000, 1280)
    ink = (img.sum(axis=2) < 600)                                       # anything darker than near-white
    assert ink.mean() > 0.03
    rows_with_ink = ink.any(axis=1)
    assert rows_with_ink[:600].mean() > 0.2                             # the header, status and table at the top
    figure_band = img[1300:3900]
    colours = len(np.unique(figure_band.reshape(-1, 3)[::7], axis=0))
    assert colours > 200                                                # plotted figures, not text on white
    shutil.rmtree(tmp_path / "profile", ignore_errors=True)
