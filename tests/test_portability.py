"""Where there is no ``fcntl`` (Windows): the results-directory lock is POSIX, and it is kept out
of everything else.  Importing se3ocp, solving and drawing figures (also saving them, atomically)
work; a command that writes a results directory says in one line that it cannot lock it (exit 2,
nothing written).  Checked in a child process in which ``import fcntl`` fails."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

from support import config

NO_FCNTL = "import sys; sys.modules['fcntl'] = None  # import fcntl raises ImportError, as on Windows\n"


def _child(code: str, cwd):
    return subprocess.run([sys.executable, "-c", NO_FCNTL + textwrap.dedent(code)], cwd=cwd, capture_output=True,
                          text=True, timeout=600)


def test_figures_need_no_file_lock(tmp_path):
    r = _child(f"""
        import json, matplotlib
        matplotlib.use("Agg")
        import se3ocp
        from se3ocp.problems.io import save_figure
        m = se3ocp.load({str(config("e3"))!r}, ["horizon.N=10"])
        figs = se3ocp.plot(se3ocp.simulate(m))
        written = save_figure(figs["maneuver"], {str(tmp_path / "fig_maneuver")!r})
        print(json.dumps({{"fcntl": "fcntl" in sys.modules and sys.modules["fcntl"] is not None,
                          "figures": sorted(figs), "written": [p.name for p in written]}}))
    """, tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.splitlines()[-1])
    assert out["fcntl"] is False
    assert {"maneuver", "attitude", "velocity", "orbital_elements"} <= set(out["figures"])
    assert out["written"] == ["fig_maneuver.png", "fig_maneuver.pdf"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig_maneuver.pdf", "fig_maneuver.png"]


def test_results_directory_without_a_lock_is_one_line_exit_2(tmp_path):
    r = _child(f"""
        from se3ocp.problems import cli
        sys.exit(cli.main(["simulate", {str(config("e3"))!r}, "--set", "horizon.N=10", "--out", "out", "--quiet"]))
    """, tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stderr == ("se3ocp: error: out: cannot create the results directory (file locks (fcntl.flock) are not "
                        "available on this system)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
