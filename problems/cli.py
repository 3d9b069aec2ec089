"""``se3ocp``: the command-line tool.

Exit codes: 0 success / converged; 1 a solver or integrator did not converge
(results are still written and flagged); 2 bad input (config, options, results
directory); 130 interrupted.
"""
from __future__ import annotations

import os
import signal
import sys


def _interrupted_at_startup(signum, frame):  # pragma: no cover - timing dependent
    # Ctrl-C while the heavy modules load: nothing has been written yet.
    os.write(2, b"se3ocp: interrupted during start-up, before anything was written; nothing half-written was left\n")
    os._exit(130)


# Only when running as the program (python -m problems.cli, or the se3ocp script),
# never when merely imported: main() replaces it once the modules are loaded.
if __name__ == "__main__" or os.path.basename(sys.argv[0] if sys.argv else "") == "se3ocp":
    signal.signal(signal.SIGINT, _interrupted_at_startup)

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from .io import ResultsDirError, prepare_results_dir, write_json, write_npz, write_yaml  # noqa: E402
from .maneuvers import ConfigError, Maneuver, load_maneuver  # noqa: E402
from ..transcription.results import SolverOptionError  # noqa: E402

#: Cayley solves whose relative residual exceeds this are reported as failed.
CAYLEY_RESIDUAL_TOL = 1e-10

EPILOG = """examples:
  se3ocp validate configs/e3_inclination_change.yaml
  se3ocp simulate configs/free_tumble.yaml --set horizon.N=2000
  se3ocp solve configs/e3_inclination_change.yaml --method both
  se3ocp compare configs/e4_orbital_capture.yaml --set solver.indirect.initial_costate=from_direct
  se3ocp plot results/e3_inclination_change
  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T
"""

#: relative cost difference above which compare reports different extremals
MISMATCH_COST_RTOL = 1e-6


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
        p.add_argument("--no-figures", action="store_true", help="skip the PNG/PDF figures")
        p.add_argument("--animate", action="store_true", help="also write maneuver.gif")
        p.set_defaults(func=cmd_solve)
        if name == "compare":
            p.set_defaults(method="both")

    p = sub.add_parser("plot", help="(re)draw the figures of a results directory",
                       epilog="example:\n  se3ocp plot results/e3_inclination_change --animate",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", help="a results directory written by simulate, solve or compare")
    p.add_argument("--animate", action="store_true", help="also write maneuver.gif")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.add_argument("--json", action="store_true", help="print the list of files written as JSON")
    p.set_defaults(func=cmd_plot)

    p = sub.add_parser("sweep", help="trade study: solve a grid of parameter values (local pool or Dask cluster)",
                       epilog="examples:\n  se3ocp sweep configs/sweeps/e3_T.yaml --out results/e3_T\n"
                              "  se3ocp sweep configs/sweeps/e3_T_inclination.yaml --scheduler tcp://127.0.0.1:8786",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", help="sweep YAML file (base maneuver, axes, methods; see problems/sweep.py)")
    p.add_argument("--out", default=None, metavar="DIR", help="results directory (default results/sweeps/<name>/)")
    p.add_argument("--workers", type=_positive_int, default=None, metavar="K",
                   help="local worker processes (default: one per core; 1 = in-process)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the tasks on an existing dask.distributed cluster, e.g. tcp://host:8786")
    p.add_argument("--no-continuation", action="store_true", help="cold-start every point (ignore 'continuation')")
    p.add_argument("--force", action="store_true", help="write into a non-empty results directory")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=cmd_sweep)
    return ap


def _positive_int(text: str) -> int:
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return int(text)


class _Interrupt:
    """Ctrl-C policy.  The first SIGINT sets a flag and raises KeyboardInterrupt.
    Solvers may swallow that exception inside their own callbacks (IPOPT then stops
    with User_Requested_Stop, CasADi may turn it into another error), so the flag is
    what counts: it is checked after each solve, and any exception raised while it
    is set means "interrupted" (exit 130), never a traceback."""

    flag = False

    @classmethod
    def handler(cls, signum, frame):
        cls.flag = True
        raise KeyboardInterrupt

    @classmethod
    def check(cls):
        if cls.flag:
            raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    try:
        signal.signal(signal.SIGINT, _Interrupt.handler)
    except ValueError:  # not the main thread
        pass
    args = build_parser().parse_args(argv)
    from ..transcription import codegen

    codegen.notify = lambda msg: _say(args, f"  [jit] {msg}")
    try:
        return args.func(args)
    except (ConfigError, ResultsDirError) as e:
        if _Interrupt.flag:
            return _interrupted()
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except Exception:
        if _Interrupt.flag:  # an error caused by the interrupt inside a library
            return _interrupted()
        raise


def _interrupted() -> int:
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
    from ..transcription.lie import orthogonality_error
    from ..transcription.layout import unpack_states

    t0 = time.perf_counter()
    disc = man.discretization_object()
    model = disc.model
    build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    X, res = disc.simulate(man.X0(), None, man.h, man.N)
    _Interrupt.check()
    run_s = time.perf_counter() - t0
    E = np.array(model.energy().map(X.shape[0])(X.T)).ravel()
    rel = np.abs(E - E[0]) / abs(E[0])
    orth, det = orthogonality_error(unpack_states(X).R)
    worst = float(res.max()) if res.size else 0.0
    finite = np.all(np.isfinite(X), axis=1)
    ok = bool(finite.all()) and worst <= CAYLEY_RESIDUAL_TOL
    if ok:
        status, message = "ok", "free motion simulated"
    elif not finite.all() and (not np.isfinite(res).all() or res[np.isfinite(res)].max(initial=0) <= CAYLEY_RESIDUAL_TOL):
        k = int(np.argmin(finite))
        status = "nan"
        message = (f"the state became non-finite at node {k} (overflow or a singular potential: check the model "
                   f"parameters and that the body stays away from the central mass)")
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
    from ..transcription.layout import unpack_states

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


class Progress:
    """One line per Newton-Armijo outer iteration, and per block of NLP iterations
    (at most one line a second after the first ten), so long solves show life without flooding."""

    def __init__(self, args, label: str):
        self.args, self.label = args, label
        self.last = 0.0
        self.count = 0

    def __call__(self, rec: dict):
        _Interrupt.check()
        self.count += 1
        now = time.perf_counter()
        if self.count > 10 and now - self.last < 1.0 and "step" not in rec:
            return
        self.last = now
        if "iteration" in rec:  # Newton-Armijo
            _say(self.args, f"  [{self.label}] iter {rec['iteration']:3d}  |z_N| = {rec.get('error', float('nan')):.3e}"
                            f"  step = {rec.get('step', float('nan')):.3g}  halvings = {rec.get('halvings', 0)}")
        else:
            inf = rec.get("inf_pr", rec.get("inf_pr_scaled", float("nan")))
            _say(self.args, f"  [{self.label}] iter {rec.get('iter', self.count - 1):4d}  cost = {rec.get('objective', float('nan')):.8e}"
                            f"  infeasibility = {inf:.2e}")


def _run_method(args, man: Maneuver, method: str, lam0=None):
    """Build the problem for ``method`` and solve it; returns a Solution (failures are data)."""
    if man.control_kind == "impulsive":
        from ..transcription.impulsive import solve_impulsive

        return solve_impulsive(man.impulsive_problem(), progress=Progress(args, "impulsive"))
    if method == "direct":
        from ..transcription.direct import solve_direct

        return solve_direct(man.smooth_problem("direct"), progress=Progress(args, "direct"))
    from ..transcription.indirect import solve_indirect

    return solve_indirect(man.smooth_problem("indirect"), lam0=lam0, progress=Progress(args, "indirect"))


def compare_solutions(a, b) -> dict:
    """Cost and control differences between two solutions; flags different extremals."""
    out = {"cost_relative_difference": abs(a.cost - b.cost) / max(abs(a.cost), abs(b.cost), 1e-300)}
    if a.controls is not None and b.controls is not None and a.controls.shape == b.controls.shape:
        scale = max(np.abs(a.controls).max(), 1e-300)
        out["control_max_difference_relative"] = float(np.abs(a.controls - b.controls).max() / scale)
    both = a.converged and b.converged
    out["same_extremal"] = bool(both and out["cost_relative_difference"] <= MISMATCH_COST_RTOL)
    if not both:
        out["verdict"] = "not comparable: at least one method did not converge"
    elif out["same_extremal"]:
        out["verdict"] = "agree: same extremal"
    else:
        lo, hi = sorted([a, b], key=lambda s: s.cost)
        out["verdict"] = (f"MISMATCH: the methods reached different extremals ({lo.method} cost {lo.cost:.6g} vs "
                          f"{hi.method} cost {hi.cost:.6g}, ratio {hi.cost / lo.cost:.3g}); the higher one is not the "
                          f"optimum. Try solver.indirect.initial_costate=from_direct.")
    return out


def _table(sols) -> list[str]:
    head = f"{'method':<10} {'status':<20} {'cost':>14} {'term. err':>10} {'orth. err':>10} {'iters':>6} {'build s':>8} {'solve s':>8}"
    rows = [head, "-" * len(head)]
    for s in sols:
        o = s.trajectory.orthogonality()["max_orthogonality_error"]
        rows.append(f"{s.method:<10} {s.status[:20]:<20} {s.cost:>14.8g} {s.terminal_error:>10.2e} {o:>10.2e} "
                    f"{s.iterations:>6d} {s.build_s:>8.2f} {s.solve_s:>8.2f}")
    return rows


def _option_config_error(man: Maneuver, e: SolverOptionError) -> ConfigError:
    """A raw solver option the plugin rejected, as bad input naming solver.direct.options.NAME."""
    return ConfigError(man.source, "solver.direct.options" + (f".{e.option}" if e.option else ""), str(e))


def cmd_solve(args) -> int:
    from .plots import animate, draw_all

    man = _load(args)
    man.require_terminal()
    methods = ["direct", "indirect"] if args.method == "both" else [args.method]
    if man.control_kind == "impulsive":
        if "indirect" in methods and args.method != "both":
            raise ConfigError(man.source, "control.kind", "the indirect method applies to smooth maneuvers; "
                                                          "impulsive maneuvers are solved by --method direct")
        methods = ["direct"]
    from ..transcription.direct import check_solver_options

    try:  # before anything is written: bad raw solver options are bad input
        check_solver_options(man.direct.get("options") or {})
    except SolverOptionError as e:
        raise _option_config_error(man, e) from None
    out = _outdir(args, man)
    write_yaml(out / "config.resolved.yaml", man.resolved)
    _say(args, f"{man.name}: {man.control_kind} maneuver, {man.discretization}, N = {man.N}, T = {man.T:g} -> {out}/")
    sols = {}
    for method in methods:
        lam0 = None
        if method == "indirect" and man.indirect.get("initial_costate") == "from_direct" and "direct" in sols \
                and sols["direct"].costates is not None:
            from ..transcription.indirect import lam0_from_direct

            lam0 = lam0_from_direct(man.smooth_problem("indirect"), sols["direct"])  # reuse, don't re-solve
        _say(args, f"solving by the {method} method ...")
        try:
            sol = _run_method(args, man, method, lam0)
        except SolverOptionError as e:
            raise _option_config_error(man, e) from None
        _Interrupt.check()  # a solver may have swallowed Ctrl-C and returned
        sols[method] = sol
        write_npz(out / f"{method}.npz", sol.arrays())
        _say(args, f"  {method}: {sol.status} ({sol.message}); cost {sol.cost:.10g}, terminal error "
                   f"{sol.terminal_error:.2e}, {sol.iterations} iterations, build {sol.build_s:.2f} s, solve {sol.solve_s:.2f} s")
    summary = {"name": man.name, "config": man.source, "control": man.control_kind,
               "discretization": man.discretization, "N": man.N, "T": man.T,
               "converged": all(s.converged for s in sols.values()),
               "methods": {m: dict(s.summary(), history=s.history) for m, s in sols.items()}}
    if len(sols) == 2:
        summary["comparison"] = compare_solutions(sols["direct"], sols["indirect"])
    write_json(out / "summary.json", summary)
    if not args.no_figures:
        draw_all(out)
        if args.animate:
            animate(out)
    for line in _table(sols.values()):
        _say(args, line)
    if "comparison" in summary:
        _say(args, f"comparison: {summary['comparison']['verdict']}")
    _say(args, f"results in {out}/")
    _emit_summary(args, {k: v for k, v in summary.items() if k != "methods"} | {
        "methods": {m: s.summary() for m, s in sols.items()}})
    return 0 if summary["converged"] else 1


def cmd_plot(args) -> int:
    from .plots import animate, draw_all

    d = Path(args.results)
    if not (d / "summary.json").exists() or not (d / "config.resolved.yaml").exists():
        print(f"se3ocp: error: {d}: not a results directory (needs summary.json and config.resolved.yaml)", file=sys.stderr)
        return 2
    written = [str(p) for p in draw_all(d)]
    if args.animate:
        written.append(str(animate(d)))
    _say(args, f"wrote {len(written)} files in {d}/")
    if args.json:
        print(json.dumps(written))
    return 0


def cmd_sweep(args) -> int:
    from .sweep import cli_sweep

    return cli_sweep(args, check_interrupt=_Interrupt.check)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
