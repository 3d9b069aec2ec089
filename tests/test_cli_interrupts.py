"""Ctrl-C through the real CLI at random moments (issue 15): whatever the moment, exit 130 (or
0 if the run had finished) with one stderr line, and a results directory that is the previous
complete run, one complete new run or (a sweep) the finished rows marked INCOMPLETE; and the
stderr filter that drops CasADi's own warning about the interrupt.  The Ctrl-C cases of the
catalogue (tests/failure_cases.py) are in test_failures.py."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import failure_cases as ft
from support import CONFIGS


def test_casadi_interrupt_warning_is_dropped_and_nothing_else():
    """The CLI's stderr filter drops CasADi's KeyboardInterruptException warning, whole, however it
    is split into writes, and passes every other text through unchanged."""
    import io

    from se3ocp.problems.cli.signals import DropInterruptWarnings

    warning = 'CasADi - 2026-12-02 09:40:32 WARNING("KeyboardInterruptException") [.../ipopt_nlp.cpp:132]\n'
    other = "CasADi - 2026-12-02 09:40:32 WARNING(\"something else\") [x.cpp:1]\nplain text\nC"
    for cut in range(0, len(warning) + len(other), 7):
        buf = io.StringIO()
        f = DropInterruptWarnings(buf)
        text = warning + other
        f.write(text[:cut])
        f.write(text[cut:])
        f.flush()
        assert buf.getvalue() == other, cut


# --------------------------------------------- Ctrl-C at random moments, concurrent runs (issue 15)
#: interrupts per command in test_ctrl_c_at_random_moments (the issue asks for 20; the environment
#: variable SE3OCP_N_INTERRUPTS changes it for a quick look)
N_INTERRUPTS = int(os.environ.get("SE3OCP_N_INTERRUPTS", "20"))
#: a small sweep: base E3, N = 20, direct, in-process (``{values}`` is the horizon.T axis)
SWEEP_TEXT = ("name: rnd\nbase: {base}\nset: {{horizon.N: 20}}\naxes: {{horizon.T: {values}}}\n"
              "methods: [direct]\n")


def _files(d: Path) -> dict[str, tuple[str, int]]:
    """name (relative) -> (sha256, mtime_ns) of every file under d."""
    import hashlib

    return {str(f.relative_to(d)): (hashlib.sha256(f.read_bytes()).hexdigest(), f.stat().st_mtime_ns)
            for f in sorted(d.rglob("*")) if f.is_file()}


class _Scenario:
    """One command run repeatedly over a results directory ``out`` that holds a complete earlier
    run (made by ``old_argv``); ``new_argv`` is interrupted.  :meth:`verdict` says which state the
    directory is in afterwards -- 'previous' (every file as before), 'new' (one complete run of
    new_argv) or 'new, marked INCOMPLETE' -- or raises AssertionError naming the offending file."""

    def __init__(self, name, old_argv, new_argv, work: Path, kind: str):
        self.name, self.old_argv, self.new_argv, self.work, self.kind = name, old_argv, new_argv, work, kind
        self.out = work / "out"

    def run(self, argv, **kw):
        return subprocess.run([sys.executable, "-m", "se3ocp.problems.cli", *map(str, argv)], cwd=self.work,
                              capture_output=True, text=True, timeout=900, **kw)

    def prepare(self):
        """The earlier run (and, once, a reference run of new_argv: its file names and duration)."""
        import shutil

        if not hasattr(self, "reference"):
            shutil.rmtree(self.out, ignore_errors=True)
            if self.kind == "plot":
                assert self.run(self.old_argv).returncode == 0
            t0 = time.monotonic()
            r = self.run(self.new_argv)
            self.duration = time.monotonic() - t0
            assert r.returncode == 0, r.stderr
            self.reference = set(_files(self.out))
        shutil.rmtree(self.out, ignore_errors=True)
        r = self.run(self.old_argv)
        assert r.returncode == 0, r.stderr
        self.before = _files(self.out)

    def verdict(self, t_start_ns: int) -> str:
        d = self.out
        left = sorted(p.name for p in self.work.iterdir() if p.name.startswith(".out."))
        assert not left, f"temporaries left beside the results directory: {left}"
        assert d.is_dir(), "the previous complete run is gone"
        bad = ft.incomplete_files(d)
        assert not bad, f"incomplete files: {bad}"
        now = _files(d)
        if now == self.before:
            return "previous"
        old = {n for n, (h, m) in now.items() if n in self.before and self.before[n][0] == h and m < t_start_ns}
        new = {n for n, (h, m) in now.items() if m >= t_start_ns}
        assert set(now) == old | new, f"files neither of the previous run nor of this one: {sorted(set(now) - old - new)}"
        if self.kind == "plot":  # an update: the earlier files untouched, the animation added whole
            assert set(now) == set(self.before) | {"maneuver.gif"} and old == set(self.before), \
                f"plot changed {sorted(set(now) ^ set(self.before))}"
            return "new"
        assert not old, f"files of the previous run mixed into the new one: {sorted(old)}"
        if "INCOMPLETE" in now:
            assert self.kind == "sweep", "only a sweep commits an interrupted run (marked INCOMPLETE)"
            assert {"results.csv", "summary.json", "INCOMPLETE"} <= set(now), sorted(now)
            assert json.loads((d / "summary.json").read_text())["interrupted"] is True
            return "new, marked INCOMPLETE"
        assert set(now) == self.reference, f"not the files of a complete run: {sorted(set(now) ^ self.reference)}"
        self.consistent(d)
        return "new"

    def consistent(self, d: Path):
        """Every data file of a new run is of that run (its N or its grid), not of the previous one."""
        if self.kind == "sweep":
            doc = yaml.safe_load((d / "sweep.resolved.yaml").read_text())
            rows = (d / "results.csv").read_text().splitlines()
            summ = json.loads((d / "summary.json").read_text())
            assert len(rows) - 1 == len(doc["axes"]["horizon.T"]) == summ["tasks"] == summ["finished"]
            assert summ["axes"]["horizon.T"] == doc["axes"]["horizon.T"]
            return
        n = json.loads((d / "summary.json").read_text())["N"]
        assert yaml.safe_load((d / "config.resolved.yaml").read_text())["horizon"]["N"] == n
        for f in d.glob("*.npz"):
            with np.load(f) as z:
                assert z["t"].shape == (n + 1,), f.name


def _scenarios(tmp: Path) -> list[_Scenario]:
    e3 = CONFIGS / "e3_inclination_change.yaml"
    out = ["--out", "out", "--force"]
    sweeps = tmp / "sweeps"
    sweeps.mkdir()
    (sweeps / "old.yaml").write_text(SWEEP_TEXT.format(base=e3, values="[0.5, 0.55]"))
    (sweeps / "new.yaml").write_text(SWEEP_TEXT.format(base=e3, values="[0.45, 0.5, 0.55, 0.6]"))
    return [
        _Scenario("solve", ["solve", e3, "--set", "horizon.N=30", *out], ["solve", e3, "--set", "horizon.N=40", *out],
                  tmp / "solve", "solve"),
        _Scenario("compare", ["compare", e3, "--set", "horizon.N=30", *out],
                  ["compare", e3, "--set", "horizon.N=40", *out], tmp / "compare", "compare"),
        _Scenario("plot --animate", ["solve", e3, "--set", "horizon.N=30", *out],
                  ["plot", "out", "--animate", "--frames", "30"], tmp / "plot", "plot"),
        _Scenario("sweep", ["sweep", sweeps / "old.yaml", "--workers", "1", *out],
                  ["sweep", sweeps / "new.yaml", "--workers", "1", "--quiet", *out], tmp / "sweep", "sweep"),
    ]


@pytest.mark.slow
def test_ctrl_c_at_random_moments(tmp_path):
    """Ctrl-C at N_INTERRUPTS random moments (seeded; spread over a reference run's duration) of
    solve, compare, plot --animate and sweep, each over a directory holding a complete earlier run:
    every time exit 130 (or 0/1 if the run had finished) without a traceback, one stderr line when
    interrupted, and the directory checked file by file is the previous run, one complete new run,
    or (sweep only) the finished rows marked INCOMPLETE -- never a mixture, never a temporary.

    The child starts with SIGINT blocked (as the catalogue's start-up case): a Ctrl-C in the first
    ~50 ms, while the interpreter itself starts (site imports, before any line of se3ocp runs, where
    only Python's own handler exists), is delivered when the CLI installs its handler.  Without
    that, such an early Ctrl-C gets Python's KeyboardInterrupt traceback -- outside the program."""
    import random

    rng = random.Random(15)
    tally = {}
    problems = []
    for sc in _scenarios(tmp_path):
        sc.work.mkdir()
        counts = {}
        for i in range(N_INTERRUPTS):
            sc.prepare()
            delay = rng.uniform(0.0, sc.duration)
            t0 = time.time_ns()
            p = subprocess.Popen([sys.executable, "-m", "se3ocp.problems.cli", *map(str, sc.new_argv)], cwd=sc.work,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                 preexec_fn=ft._block_sigint)
            time.sleep(delay)
            p.send_signal(signal.SIGINT)
            _, err = p.communicate(timeout=900)
            what = f"{sc.name} #{i} (SIGINT after {delay:.2f} s): exit {p.returncode}"
            try:
                assert "Traceback" not in err, "traceback"
                assert p.returncode in (0, 130), "exit code"
                if p.returncode == 130:
                    lines = [ln for ln in err.splitlines() if ln.strip()]
                    assert len(lines) == 1 and "interrupted" in lines[0], f"{len(lines)} stderr lines"
                state = sc.verdict(t0)
            except AssertionError as e:
                problems.append(f"{what}: {e}\n{err[-800:]}")
                continue
            counts[(p.returncode, state)] = counts.get((p.returncode, state), 0) + 1
        tally[sc.name] = counts
    print("\ninterrupt outcomes (exit code, directory state): count")
    for name, counts in tally.items():
        print(f"  {name}: " + ", ".join(f"exit {rc} {st}: {n}" for (rc, st), n in sorted(counts.items())))
    assert not problems, "\n".join(problems)
