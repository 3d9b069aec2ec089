"""``se3ocp``: the command-line tool.

Exit codes: 0 success / converged; 1 a solver or integrator did not converge
(results are still written and flagged); 2 bad input (config, options, results
directory); 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from .io import ResultsDirError, prepare_results_dir, write_json, write_npz, write_yaml
from .maneuvers import ConfigError, Maneuver, load_maneuver

#: Cayley solves whose relative residual exceeds this are reported as failed.
CAYLEY_RESIDUAL_TOL = 1e-10

EPILOG = """examples:
  se3ocp validate configs/e3_inclination_change.yaml
  se3ocp simulate configs/free_tumble.yaml --set horizon.N=2000
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


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="se3ocp", description="Geometrically exact optimal control of a rigid body on SE(3).",
                                 epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("validate", help="check a maneuver file against the schema",
                       epilog="example:\n  se3ocp validate configs/e1_impulsive_tpbvp.yaml",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p, out=False)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("simulate", help="uncontrolled motion from the initial state over the horizon",
                       epilog="example:\n  se3ocp simulate configs/free_tumble.yaml --out results/tumble",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(p)
    p.set_defaults(func=cmd_simulate)
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as e:
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    except ResultsDirError as e:
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("se3ocp: interrupted; files already written are complete, nothing half-written was left", file=sys.stderr)
        return 130


# ------------------------------------------------------------------ helpers
def _say(args, *msg):
    if not args.quiet and not args.json:
        print(*msg, flush=True)


def _load(args) -> Maneuver:
    return load_maneuver(args.config, args.overrides)


def _outdir(args, man: Maneuver) -> Path:
    safe = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in man.name)
    return prepare_results_dir(args.out, Path("results") / safe, args.force)


def _emit_summary(args, summary: dict):
    if args.json:
        print(json.dumps(summary, indent=2, default=float))


# ----------------------------------------------------------------- commands
def cmd_validate(args) -> int:
    man = _load(args)
    summary = {"config": man.source, "name": man.name, "valid": True, "control": man.control_kind,
               "discretization": man.discretization, "N": man.N, "T": man.T}
    _say(args, f"{man.source}: valid ({man.name}: {man.control_kind or 'no control'}, "
               f"{man.discretization}, N = {man.N}, T = {man.T:g})")
    _emit_summary(args, summary)
    return 0


def free_motion(man: Maneuver):
    """Simulate uncontrolled motion; returns (t, X (N+1,18), summary dict)."""
    from transcription.lie import orthogonality_error
    from transcription.layout import unpack_states

    t0 = time.perf_counter()
    disc = man.discretization_object()
    model = disc.model
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    X, res = disc.simulate(man.X0(), None, man.h, man.N)
    run_s = time.perf_counter() - t0
    E = np.array(model.energy().map(X.shape[0])(X.T)).ravel()
    rel = np.abs(E - E[0]) / abs(E[0])
    orth, det = orthogonality_error(unpack_states(X).R)
    worst = float(res.max()) if res.size else 0.0
    ok = bool(np.all(np.isfinite(X))) and worst <= CAYLEY_RESIDUAL_TOL
    if ok:
        status, message = "ok", "free motion simulated"
    else:
        k = int(np.nanargmax(np.where(np.isfinite(res), res, np.inf)))
        status = "cayley_not_converged"
        message = (f"the implicit Cayley equation was not solved at step {k} (relative residual {res[k]:.2e}): "
                   f"the rotation per step is too large; use a smaller step h = T/N (increase horizon.N)")
    summary = {
        "command": "simulate", "name": man.name, "status": status, "message": message, "converged": ok,
        "discretization": man.discretization, "N": man.N, "T": man.T, "h": man.h,
        "max_orthogonality_error": float(orth.max()), "max_determinant_error": float(det.max()),
        "energy_initial": float(E[0]), "max_relative_energy_error": float(rel.max()),
        "final_relative_energy_error": float(rel[-1]), "max_cayley_residual": worst,
        "build_s": build_s, "run_s": run_s,
    }
    return man.h * np.arange(man.N + 1), X, summary


def cmd_simulate(args) -> int:
    from transcription.layout import unpack_states

    man = _load(args)
    out = _outdir(args, man)
    t, X, summary = free_motion(man)
    s = unpack_states(X)
    write_yaml(out / "config.resolved.yaml", man.resolved)
    write_npz(out / "trajectory.npz", {"t": t, "x": s.x, "gamma": s.gamma, "Pi": s.Pi, "R": s.R})
    write_json(out / "summary.json", summary)
    _say(args, f"{man.name}: {man.discretization} free motion, N = {man.N}, h = {man.h:.3g}, "
               f"{summary['run_s']:.2f} s")
    _say(args, f"  max |R^T R - I|          {summary['max_orthogonality_error']:.2e}")
    _say(args, f"  max |det R - 1|          {summary['max_determinant_error']:.2e}")
    _say(args, f"  max relative energy err  {summary['max_relative_energy_error']:.2e}")
    _say(args, f"  status                   {summary['status']}: {summary['message']}")
    _say(args, f"  results in {out}/")
    _emit_summary(args, summary)
    return 0 if summary["converged"] else 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
