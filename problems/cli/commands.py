"""The commands of ``se3ocp``, one function each: ``cmd_NAME(args) -> exit status``.  Bad input
raises ConfigError or ResultsDirError (exit 2, see :func:`se3ocp.problems.cli.main`); a run
writes its results directory as one transaction (complete, or absent)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..io import safe_name
from ..results_dir import results_transaction, results_update
from ..maneuvers import Maneuver, load_maneuver
from ..schema import ConfigError, blame_overrides
from .progress import Progress, ProgressBar, emit_summary, say, table
from .signals import Interrupt


def _load(args) -> Maneuver:
    return load_maneuver(args.config, args.overrides)


def _results(args, man: Maneuver):
    """The results directory of a run, as a transaction: written aside, swapped in whole when the
    block ends normally, absent (or the previous run, untouched) if it does not."""
    return results_transaction(args.out, Path("results") / safe_name(man.name), args.force)


def cmd_validate(args) -> int:
    """Exit 0 for a valid file; a file that is valid but asks what solve will refuse or cannot reach says so in a
    line beginning 'but' (a warning, still exit 0: the input is well-formed, the request is the problem)."""
    from ...transcription.strategy.refine import out_of_reach
    from ...transcription.ocp.feasibility import necessary_conditions
    from ..physical import thrust_warning

    man = _load(args)
    infeasible = necessary_conditions(man.problem)  # valid, but provably without a solution: said now
    unreachable = out_of_reach(man.problem, man.accuracy)   # solve's one-line answer to solver.accuracy, the same
    summary = {"config": man.source, "name": man.name, "valid": True, "control": man.control_kind,
               "discretization": man.discretization, "N": man.N, "T": man.T, "provably_infeasible": infeasible,
               "accuracy_out_of_reach": unreachable}
    say(args, f"{man.source}: valid ({man.name}: {man.control_kind or 'no control'}, "
               f"{man.discretization}, N = {man.N}, T = {man.T:g})")
    if infeasible:
        say(args, f"  but provably infeasible (solve will say so without iterating): {infeasible}")
    if unreachable:
        verb = "is out of reach" if "out of reach" in unreachable else "cannot apply"
        say(args, f"  but solver.{man.accuracy.tolerance_key} {verb} (solve refuses it, exit 2): {unreachable}")
    slip = thrust_warning(man)
    if slip:
        say(args, f"  but {slip}")
    emit_summary(args, summary)
    return 0


def cmd_simulate(args) -> int:
    from .. import api, store

    man = _load(args)
    with _results(args, man) as tx:
        sol = api.simulate(man)
        Interrupt.check()
        _write(args, tx.path, store.held_run(man, sol))
        Interrupt.check()  # a Ctrl-C that a library swallowed (see _Interrupt): do not commit
    out = tx.target
    st = sol.stats
    say(args, f"{man.name}: {man.discretization} free motion, N = {man.N}, h = {man.h:.3g}, {sol.solve_s:.2f} s")
    say(args, f"  max |R^T R - I|          {st['max_orthogonality_error']:.2e}")
    say(args, f"  max |det R - 1|          {st['max_determinant_error']:.2e}")
    say(args, f"  max relative energy err  {st['max_relative_energy_error']:.2e}")
    if sol.problem.terminal is not None:
        say(args, f"  miss at the target       {sol.terminal_error:.3e} (terminal error of the free motion)")
    say(args, f"  status                   {sol.result}: {sol.message}")
    say(args, f"  results in {out}/")
    emit_summary(args, store.summary(man, sol))
    return 0 if sol.converged else 1


def cmd_solve(args) -> int:
    """``solve`` and ``compare`` (``--method both``): validate, solve, write the run once.  The maneuver is
    validated once (here); which methods apply and whether solver.accuracy is within reach are decided once,
    by the solve (:func:`_solved`); the figures and report.html are drawn from the result held (:func:`_write`).
    0 if every method that applies converged, 1 if not (the run is still written and flagged)."""
    from ...transcription.outcome import Result
    from .. import store
    from ..physical import thrust_warning

    man = _load(args)
    if man.control_kind is None:
        raise ConfigError(man.source, "control/terminal",
                          "solving needs a 'control' block (kind smooth or impulsive) and a 'terminal' block")
    miss = "flown miss (of the maneuver)" if man.accuracy.of_maneuver else "continuous miss"
    with _results(args, man) as tx:
        say(args, f"{man.name}: {man.control_kind} maneuver, {man.discretization}, N = {man.N}, T = {man.T:g} "
                    f"-> {tx.target}/")
        problem = man.problem
        caution = problem.control.objective.caution(problem) if problem.kind == "smooth" else ""
        for said in (thrust_warning(man), caution):
            if said:
                say(args, f"warning: {said}")
        result = _solved(args, man, args.method)
        kept = _kept_level(result)
        if not kept:
            Interrupt.check()  # a solver may have swallowed Ctrl-C and returned
        sols = store.solutions_of(result)
        for m, sol in sols.items():
            if sol.result is Result.not_applicable:
                say(args, f"  {m}: {sol.result} ({sol.message})")
                continue
            say(args, f"  {m}: {sol.result} ({sol.message}); cost {sol.cost:.10g}, terminal error "
                       f"{sol.terminal_error:.2e}, {sol.iterations} iterations, build {sol.build_s:.2f} s, "
                       f"solve {sol.solve_s:.2f} s")
            for rec in sol.mesh:    # refinement to solver.accuracy: one line per mesh level
                say(args, f"    mesh level {rec['level']}: N = {rec['N']}, {miss} {rec['miss']:.2e}, path "
                          f"violation {rec['path_violation']:.1e}, {rec['iterations']} iterations, solve "
                          f"{rec['solve_s']:.2f} s, check {rec['check_s']:.2f} s ({rec['status']})"
                          + (f"; {rec['mesh']} mesh, steps {rec['h_min']:.3g} to {rec['h_max']:.3g}" if "mesh" in rec
                             else ""))
        _write(args, tx.path, store.held_run(man, result), figures=not kept)
        if kept:        # Ctrl-C during a refinement: its best level, a complete run, committed marked INCOMPLETE
            tx.commit(incomplete=kept)
            raise KeyboardInterrupt
        Interrupt.check()  # a Ctrl-C that a library swallowed (see _Interrupt): do not commit
    out = tx.target
    for line in table(sols.values()):
        say(args, line)
    if hasattr(result, "same_extremal"):
        say(args, f"comparison: {result.verdict}")
    say(args, f"results in {out}/")
    emit_summary(args, store.summary(man, result, with_history=False))
    if store.all_converged(result):
        return 0
    if args.quiet:  # quiet is not silent: a failure is still said, in one line
        failed = [f"{m}: {s.result} ({s.message})" for m, s in sols.items()
                  if not s.converged and s.result is not Result.not_applicable]
        print(" ".join(f"se3ocp: {man.name}: not converged: {' | '.join(failed) or 'no method applies'}; results in {out}/".split()),
              file=sys.stderr)
    return 1


def _kept_level(result) -> str:
    """'' or, when Ctrl-C came while a refinement to solver.accuracy ran (Interrupt.flag) and it returned a level
    that converged short of the tolerance (``stats['accuracy_met']`` false on every applicable Solution:
    transcription.strategy.refine.refine keeps the best level solved when a later one is interrupted or fails --
    a Ctrl-C inside a CasADi evaluation ends IPOPT as solver_failed, not interrupted), the reason the results
    directory of that level is committed with: a complete run of the level returned, marked INCOMPLETE because the
    refinement did not finish (as a sweep keeps its finished rows)."""
    from ...transcription.outcome import Result
    from .. import store

    if not Interrupt.flag:
        return ""
    sols = [s for s in store.solutions_of(result).values() if s.result is not Result.not_applicable]
    if not sols or not all(s.converged and s.mesh and s.stats.get("accuracy_met") is False for s in sols):
        return ""
    s = sols[0]
    last = s.mesh[-1]
    return (f"interrupted (Ctrl-C) during refinement to a tolerance: this is level {s.stats.get('accuracy_level')} "
            f"(N = {s.N}), the best level solved of {len(s.mesh)} (level {last['level']}, N = {last['N']}, ended "
            f"{last['status']}); the tolerance was not reached (figures not drawn: se3ocp plot DIR)")


def _solved(args, man: Maneuver, method: str):
    """``api.solve`` of the maneuver by ``method`` (with the central-body check of the path), the progress
    shown.  What the solve refuses before solving -- a method that cannot run on the problem (NotCovered) or a
    solver.accuracy out of reach (OutOfReach), each decided there, once -- is bad input: ConfigError naming
    the file (or --set) and the field.  'both', of a maneuver only the direct method solves, is solved by the
    direct method (its refusal, when the direct method cannot run either, is the same sentence)."""
    from ...transcription.solve import NotCovered, OutOfReach
    from .. import api

    say(args, f"solving by the {method} method{'s' if method == 'both' else ''} ...")
    try:
        return api.solve(man, method, progress=Progress(args))
    except NotCovered as e:
        if method == "both":                        # which methods solve which problems: decided there
            say(args, f"  not by both: {e}")
            return _solved(args, man, "direct")
        raise ConfigError(man.source, "control.kind", str(e)) from None
    except OutOfReach as e:  # the N it needs: named where it was given, the file or --set (of the accuracy,
        # the scheme, N or the cap)
        raise blame_overrides(ConfigError(man.source, f"solver.{man.accuracy.tolerance_key}", str(e),
                                          also=("discretization", "horizon.N", "solver.max_N")),
                              [o.split("=", 1)[0].strip() for o in args.overrides or ()]) from None


def _write(args, out: Path, run, figures: bool = True) -> None:
    """After simulate/solve/compare: write ``run`` (a :class:`problems.store.Run` held in memory:
    store.held_run) into ``out`` once -- the resolved configuration, the .npz files and summary.json, then the
    figures (unless --no-figures or not ``figures``), the animation (--animate) and report.html (always; with the
    figures just drawn embedded), all drawn from what the command holds: nothing is read back."""
    from .. import store
    from ..plots import draw_run, write_animation
    from ..report import write_run_report

    store.save_run(out, run)
    drawn: dict[str, bytes] = {}
    if figures and not args.no_figures:
        drawn = draw_run(out, run)
        if args.animate:
            write_animation(run.result, out / "maneuver.gif", frames=args.frames, fps=args.fps)
    write_run_report(out, run, list(drawn.items()))


def _results_dir(d: Path, flights: bool = False, plan: bool = True) -> int:
    """0 if d is a results directory (``flights``: or a flight directory of ``se3ocp fly``; ``plan``: holding a
    plan, not a run where no method applies), else the error printed and 2."""
    from ..flight.report import is_flight_dir
    from ..store import no_method_applies

    if flights and is_flight_dir(d):
        return 0
    if not (d / "summary.json").exists() or not (d / "config.resolved.yaml").exists():
        print(f"se3ocp: error: {d}: not a results directory (needs summary.json and config.resolved.yaml)", file=sys.stderr)
        return 2
    if not any((d / n).is_file() for n in ("direct.npz", "indirect.npz", "trajectory.npz")):
        try:
            summ = json.loads((d / "summary.json").read_text())
        except (OSError, ValueError):
            summ = None
        if not no_method_applies(summ):
            print(f"se3ocp: error: {d}: not a results directory (no direct.npz, indirect.npz or trajectory.npz)",
                  file=sys.stderr)
            return 2
        if plan:
            said = "; ".join(f"{m}: {b.get('message', '')}" for m, b in summ["methods"].items())
            print(f"se3ocp: error: {d}: the run holds no plan (no method applies: {said})", file=sys.stderr)
            return 2
    return 0


def _update_results(args, write, said, flights: bool = False, plan: bool = True) -> int:
    """``plot`` and ``report``: ``write(path)`` adds files to a copy of the complete results directory
    ``args.results`` (results_update: the copy is swapped in when it returns) and returns their names;
    ``said(d, written)`` is the line printed.  2 if the directory is not a results directory (``flights``:
    nor a flight directory; ``plan``: 2 for a run without a plan, where no method applies)."""
    d = Path(args.results)
    if _results_dir(d, flights, plan):
        return 2
    with results_update(d) as tx:
        written = [str(d / name) for name in write(tx.path)]
        Interrupt.check()
    say(args, said(d, written))
    if args.json:
        print(json.dumps(written))
    return 0


def cmd_plot(args) -> int:
    from ..plots import animate, draw_all
    from ..report import write_report

    def write(path: Path) -> list[str]:
        # --animate: the animation, and only the static figures that are missing or stale
        names = [p.name for p in draw_all(path, stale_only=args.animate)]
        if names or not (path / "report.html").exists():
            names.append(write_report(path, draw=False).name)
        if args.animate:
            names.append(animate(path, frames=args.frames, fps=args.fps).name)
        return names

    return _update_results(args, write, lambda d, written: f"wrote {len(written)} files in {d}/")


def cmd_export(args) -> int:
    """The plan of a results directory as CCSDS OEM/AEM, CSV, a GMAT thrust history (thf) or a GMAT script with
    its thrust history (gmat) (problems/export.py): into DIR/plan.<format> (the directory updated as a whole, as
    ``plot`` does), --out FILE (gmat: FILE and FILE's stem + .thf), or --out - (stdout: the first file).
    Everything is checked before anything is written; what cannot be exported is one line, exit 2."""
    from ..export import ExportError, files, plan_of
    from ..io import atomic_write_bytes

    d = Path(args.results)
    if _results_dir(d):
        return 2
    out = None if args.out in (None, "-") else Path(args.out)
    try:
        plan = plan_of(d, method=args.method, reference_radius=args.reference_radius, body=args.central_body,
                       mass_kg=args.mass, center=args.center)
        texts = files(plan, args.format, str(out.with_suffix("")) if out is not None else "plan",
                      time_system=args.time_system)
    except ExportError as e:
        print(f"se3ocp: error: {e}", file=sys.stderr)
        return 2
    main, *others = texts
    if args.out == "-":
        sys.stdout.write(texts[main])
        return 0
    if out is not None:
        written = [str(out)] + others
        for path, name in zip(written, texts):
            atomic_write_bytes(Path(path), texts[name].encode("utf-8"))
        say(args, f"wrote {', '.join(written)}")
        if args.json:
            print(json.dumps(written))
        return 0

    def write(path: Path) -> list[str]:
        for name, text in texts.items():
            atomic_write_bytes(path / name, text.encode("utf-8"))
        return list(texts)

    return _update_results(args, write, lambda _d, written: f"wrote {', '.join(written)}")


def cmd_report(args) -> int:
    from ..report import write_report

    return _update_results(args, lambda path: [write_report(path, draw=not args.no_figures).name],
                           lambda d, written: f"wrote {written[0]}", flights=True, plan=False)


def cmd_sweep(args) -> int:
    """``se3ocp sweep``: validate, connect, run, write.  Exit 0 if every point converged,
    1 if some did not (all rows are still written), ConfigError/ResultsDirError for bad
    input; on Ctrl-C the finished rows are written and KeyboardInterrupt propagates."""
    from ..sweep import load_sweep, make_executor, run_sweep, write_results

    tell = (lambda *m: None) if args.quiet else (lambda *m: print(*m, flush=True))  # noqa: E731

    def validating(done, total):  # long validations show life (at most once a second)
        if done < total:
            tell(f"validating the grid: {done}/{total} points checked ...")

    sw = load_sweep(args.sweep, progress=validating)
    cont = False if args.no_continuation else sw.continuation
    ex = make_executor(args.workers, args.scheduler)  # a bad --scheduler fails before anything is written
    try:
        with results_transaction(args.out, Path("results") / "sweeps" / safe_name(sw.name), args.force) as tx:
            n = len(sw.points())
            where = {"serial": "in-process", "local": f"local pool of {ex.workers} workers",
                     "dask": f"Dask cluster at {args.scheduler}"}[ex.kind]
            axc = sw.axes[sw.continuation_axis].name
            tell(f"{sw.name}: {n} points x {len(sw.row_methods())} method(s) = {n * len(sw.row_methods())} tasks on "
                 f"{where}; continuation {('along ' + axc) if cont and sw.control_kind != 'impulsive' else 'off'} "
                 f"-> {tx.target}/")
            bar = ProgressBar(quiet=args.quiet)
            try:
                res = run_sweep(sw, continuation=cont, progress=bar, check_interrupt=Interrupt.check, executor=ex)
            except KeyboardInterrupt as exc:
                bar.close()
                if getattr(exc, "partial", None) is not None:   # the finished rows, clearly marked incomplete
                    write_results(tx.path, exc.partial, figures=False)
                    tx.commit(incomplete=f"interrupted (Ctrl-C) after {len(exc.partial.rows)} of "
                                         f"{exc.partial.n_tasks} tasks")
                raise
            bar.close()
            write_results(tx.path, res)
            Interrupt.check()  # a Ctrl-C swallowed meanwhile: do not commit
        out = tx.target
    finally:
        ex.shutdown()
    s = res.summary()
    for m, b in s["by_method"].items():
        tell(f"  {m:<9} {b['converged']}/{b['points']} converged, {b['iterations_total']} iterations "
             f"({b['warm_started']} warm-started, {b['fallbacks_to_cold']} fell back to a cold start)")
    tell(f"  {res.wall_s:.1f} s wall; results in {out}/ (results.csv, results.jsonl, figures)")
    return 0 if res.all_converged else 1

