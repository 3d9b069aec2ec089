"""The arguments of ``se3ocp``: one subparser per command, its options, help and examples."""
from __future__ import annotations

import argparse

from ..flight.command import cmd_fly
from .commands import cmd_export, cmd_plot, cmd_report, cmd_simulate, cmd_solve, cmd_sweep, cmd_validate

EPILOG = """examples:
  se3ocp validate configs/e3_inclination_change.yaml
  se3ocp simulate configs/free_tumble.yaml --set horizon.N=2000
  se3ocp solve configs/e3_inclination_change.yaml --method both
  se3ocp compare configs/e4_orbital_capture.yaml --set solver.indirect.initial_costate=from_direct
  se3ocp plot results/e3_inclination_change
  se3ocp plot results/e3_inclination_change --animate --frames 150 --fps 25
  se3ocp report results/e3_inclination_change
  se3ocp export results/leo_raise_slew --format oem
  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T
  se3ocp fly configs/e3_inclination_change.yaml --flight configs/flights/e3_j2_thrust.yaml --runs 200

exit status:
  0  success (converged)
  1  a solver or the integrator did not converge, or the problem is provably infeasible
     (results written, summary.json flagged converged: false with a status and message)
  2  bad input: one line FILE (or --set): FIELD: expected ...; nothing written
  3  internal error (a defect): one line naming the file that holds the traceback
  130 interrupted (Ctrl-C): nothing half-written
"""


def _common(p: argparse.ArgumentParser, out=True):
    p.add_argument("config", help="maneuver YAML file")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a config value by dotted key, e.g. --set horizon.N=1000 (repeatable)")
    if out:
        p.add_argument("--out", default=None, metavar="DIR",
                       help="results directory (default results/<name>/; a fresh numbered sibling if that is not empty)")
        p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")


def _animation_options(p: argparse.ArgumentParser):
    p.add_argument("--animate", action="store_true",
                   help="also write maneuver.gif (every method, named; body frame, thrust arrow, target)")
    p.add_argument("--frames", type=_frames, default=100, metavar="K", help="frames of the animation (default 100)")
    p.add_argument("--fps", type=_positive_int, default=20, metavar="F", help="frames per second (default 20)")


def _executor_options(p: argparse.ArgumentParser):
    """Where a sweep's or a flight's tasks run: --workers (local pool) or --scheduler (a Dask cluster)."""
    p.add_argument("--workers", type=_positive_int, default=None, metavar="K",
                   help="local worker processes (default: one per core; 1 = in-process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the tasks on an existing dask.distributed cluster, e.g. tcp://host:8786")


def _output_options(p: argparse.ArgumentParser):
    p.add_argument("--no-figures", action="store_true", help="skip the PNG/PDF figures (report.html is still written)")
    _animation_options(p)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="se3ocp", description="Geometrically exact optimal control of a rigid body on SE(3).",
                                 epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"se3ocp {_version()}",
                    help="print the installed version and exit")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for add in (_validate_parser, _simulate_parser, _solve_parser, _plot_parser, _report_parser, _export_parser,
                _sweep_parser, _fly_parser):
        add(sub)
    return ap


def _validate_parser(sub) -> None:
    """The `validate` subcommand."""
    p = sub.add_parser("validate", help="check a maneuver file against the schema",
                       epilog="example:\n  se3ocp validate configs/e1_impulsive_tpbvp.yaml",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p, out=False)
    p.set_defaults(func=cmd_validate)


def _simulate_parser(sub) -> None:
    """The `simulate` subcommand."""
    p = sub.add_parser("simulate", help="uncontrolled motion from the initial state over the horizon",
                       epilog="example:\n  se3ocp simulate configs/free_tumble.yaml --out results/tumble",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p)
    _output_options(p)
    p.set_defaults(func=cmd_simulate)


def _solve_parser(sub) -> None:
    """The `solve and compare` subcommands."""
    for name, helptext, ex in (
        ("solve", "solve the optimal control problem (direct, indirect or both)",
         "examples:\n  se3ocp solve configs/e3_inclination_change.yaml --method direct\n"
         "  se3ocp solve configs/e1_impulsive_tpbvp.yaml --set horizon.N=200\n"
         "  se3ocp solve configs/e4_orbital_capture.yaml --method indirect --set solver.indirect.initial_costate=from_direct"),
        ("compare", "solve by both methods and compare them side by side",
         "example:\n  se3ocp compare configs/e3_inclination_change.yaml --set horizon.N=200"),
    ):
        p = sub.add_parser(name, help=helptext, epilog=ex, formatter_class=argparse.RawDescriptionHelpFormatter)
        _common(p)
        if name == "solve":
            p.add_argument("--method", choices=("direct", "indirect", "both"), default="direct",
                           help="direct (multiple shooting + NLP solver), indirect (Newton-Armijo shooting), "
                                "or both (default: direct)")
        _output_options(p)
        p.set_defaults(func=cmd_solve)
        if name == "compare":
            p.set_defaults(method="both")


def _plot_parser(sub) -> None:
    """The `plot` subcommand."""
    p = sub.add_parser("plot", help="(re)draw the figures, report.html and the animation of a results directory",
                       description="Without --animate: redraw every figure and report.html.  With --animate: write "
                                   "maneuver.gif, and draw only the figures that are missing or older than the run's "
                                   "summary.json (so a new animation does not redraw up-to-date figures).",
                       epilog="examples:\n  se3ocp plot results/e3_inclination_change\n"
                              "  se3ocp plot results/e3_inclination_change --animate --frames 150 --fps 25",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    _animation_options(p)
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the list of files written as JSON")
    p.set_defaults(func=cmd_plot)


def _report_parser(sub) -> None:
    """The `report` subcommand."""
    p = sub.add_parser("report", help="write report.html: a self-contained page (summary table, figures, history, config)",
                       epilog="example:\n  se3ocp report results/e3_inclination_change",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    p.add_argument("--no-figures", action="store_true", help="leave the figures out (no drawing)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the path written as JSON")
    p.set_defaults(func=cmd_report)


def _export_parser(sub) -> None:
    """The `export` subcommand."""
    p = sub.add_parser("export", help="the plan of a results directory as CCSDS OEM/AEM (GMAT, STK, Orekit), CSV or a "
                                      "GMAT thrust history",
                       description="OEM 2.0 (position km, velocity km/s, Hermite interpolation of degree 3, the mass in "
                                   "a comment), AEM 1.0 (quaternions: QUATERNION_TYPE LAST, ATTITUDE_DIR A2B from the "
                                   "inertial frame to the body), CSV (t, epoch, r, v, q, Ω, mass, thrust, torque, thrust "
                                   "in the body frame, throttle; units in the header), thf (a GMAT thrust history file), "
                                   "gmat (a GMAT script replaying plan.thf from the OEM's first epoch, and plan.thf).  "
                                   "Epochs: UTC = the maneuver's epoch (default J2000.0) + t, or in --time-system.  A "
                                   "maneuver in normalized units needs --reference-radius for OEM/AEM/thf/gmat.",
                       epilog="examples:\n  se3ocp export results/leo_raise_slew --format oem\n"
                              "  se3ocp export results/e3_inclination_change --format aem --reference-radius 6778.137\n"
                              "  se3ocp export results/leo_raise_slew --format csv --out leo.csv\n"
                              "  se3ocp export results/leo_raise_slew --format oem --time-system TAI\n"
                              "  se3ocp export results/leo_body_engine --format gmat   # plan.script + plan.thf",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    p.add_argument("--format", required=True, choices=("oem", "aem", "csv", "thf", "gmat"),
                   help="oem, aem, csv, thf (GMAT thrust history) or gmat (GMAT script + thrust history)")
    p.add_argument("--time-system", choices=("UTC", "TAI", "TT", "GPS"), default="UTC",
                   help="the epochs' time system (OEM, AEM, CSV): UTC (default), TAI, TT = TAI + 32.184 s, "
                        "GPS = TAI - 19 s")
    p.add_argument("--out", default=None, metavar="FILE",
                   help="where to write (default DIR/plan.<format>; - for standard output)")
    p.add_argument("--method", choices=("direct", "indirect", "simulate"), default=None,
                   help="which solution (default: direct, else the only one)")
    p.add_argument("--reference-radius", type=_positive_float, default=None, metavar="KM",
                   help="read normalized units as a circular orbit of this radius (km) about --central-body")
    p.add_argument("--central-body", default="earth", metavar="NAME", help="the preset body of --reference-radius (earth)")
    p.add_argument("--mass", type=_positive_float, default=None, metavar="KG",
                   help="kilograms per mass unit of a normalized file (the CSV's thrust and torque in N, N*m)")
    p.add_argument("--center", default=None, metavar="NAME", help="CENTER_NAME for a file without a preset central body")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the path written as JSON")
    p.set_defaults(func=cmd_export)


def _sweep_parser(sub) -> None:
    """The `sweep` subcommand."""
    p = sub.add_parser("sweep", help="trade study: solve a grid of parameter values (local pool or Dask cluster)",
                       epilog="examples:\n  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T\n"
                              "  se3ocp sweep configs/sweeps/e3_T_inclination.yaml --scheduler tcp://127.0.0.1:8786",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", help="sweep YAML file (base maneuver, axes, methods; see problems/sweep/)")
    p.add_argument("--out", default=None, metavar="DIR", help="results directory (default results/sweeps/<name>/)")
    _executor_options(p)
    p.add_argument("--no-continuation", action="store_true", help="cold-start every point (ignore 'continuation')")
    p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=cmd_sweep)


def _fly_parser(sub) -> None:
    p = sub.add_parser("fly", help="Monte Carlo flights of a plan: truth model, errors, open loop and LQR tracking",
                       epilog="examples:\n  se3ocp fly configs/e3_inclination_change.yaml --set horizon.N=400 "
                              "--set discretization=lgvi --flight configs/flights/e3_j2_thrust.yaml\n"
                              "  se3ocp fly results/slew_time_optimal --runs 500 --feedback lqr --workers 2\n"
                              "  se3ocp fly results/e3_inclination_change --scheduler tcp://127.0.0.1:8786",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("plan", metavar="CONFIG|RESULTS_DIR",
                   help="a maneuver file (solved first by the direct method) or a results directory holding the plan")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a value of the maneuver file by dotted key (repeatable)")
    p.add_argument("--flight", default=None, metavar="FILE",
                   help="a YAML file holding a 'flight:' block (default: the maneuver's own, else the defaults)")
    p.add_argument("--runs", type=_positive_int, default=None, metavar="K", help="number of runs (default: the block's)")
    p.add_argument("--feedback", choices=("none", "lqr", "mpc", "both", "all"), default=None,
                   help="open loop, the LQR tracker, re-planning (MPC), open loop and LQR side by side (both), or "
                        "all three (default: the block's, else both)")
    _executor_options(p)
    p.add_argument("--save-runs", type=_nonneg_int, default=0, metavar="K",
                   help="write runs/NNNN.npz (errors, applied controls, truth trajectory) of the first K runs")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="results directory (default results/flights/<name>/; a fresh numbered sibling if not empty)")
    p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=cmd_fly)


def _version() -> str:
    """The installed distribution's version (package metadata), so it cannot drift from pyproject.toml."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("se3ocp")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


def _positive_int(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return int(text)


def _positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not (x > 0 and x < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return x


def _nonneg_int(text: str) -> int:
    if not text.isdigit():
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return int(text)


def _frames(text: str) -> int:
    if not text.isdigit() or int(text) < 2:
        raise argparse.ArgumentTypeError(f"expected an integer >= 2, got {text!r}")
    return int(text)
