"""Peer comparison: E3/E4 written the way a user would otherwise write them, in rockit.

rockit (PyPI ``rockit-meco``, optional, not a runtime dependency of the project) with
``MultipleShooting(N=N, intg='rk')`` (one RK4 step per interval) on the continuous equations
(1)-(4) of docs/mathematics.md §1 with a rotation-matrix state (9 entries, no re-orthonormalization):

    dx/dt = gamma/m,  dgamma/dt = f + u_f,  dR/dt = R S(Omega),  dPi/dt = Pi x Omega + M + u_m,
    Omega = J^-1 Pi,

f, M from the same dumbbell potential by the same AD (``BodyModel.forces``), piecewise-constant
controls, cost integral (1/2)(u_f^T W_f u_f + u_m^T W_m u_m), X(0) = X0 and the same 12 terminal
conditions as ours (x, gamma, Pi and vee log(R_d^T R_N)).  Initial guess: the same as ours (the
free-motion rollout of our first-order scheme at the nodes, zero controls).  IPOPT (rockit's
default) with tol 1e-10 and a wall-time cap (``max_wall_time``, 120 s).

After the solve its controls are re-simulated with scipy's DOP853 (rtol = atol = 1e-12) on the
same equations, interval by interval; reported: terminal error of that re-simulation (docs/mathematics.md §8
measure), max |R^T R - I|_F and |det R - 1| of the peer's own node states and of the
re-simulation.  A peer that does not converge is reported with its last status.

    .venv/bin/python scripts/peer_rockit.py e3 1000

The constrained maneuvers of docs/mathematics.md §10, written the same way:

* ``slew`` / ``slew_sym`` (configs/slew_time_optimal.yaml, slew_time_optimal_symmetric.yaml): the
  time objective, ``Ocp(T=FreeTime(T_guess))`` with T within the maneuver's time bounds, cost ocp.T,
  the torque box as bounds on the control; no central body and no force, so the state is what a user
  would write for a slew: R (9) and Pi (3), the control u_m (3).  Guess: our first start (the screw
  interpolation with seed-0 symmetry-breaking controls, the first-order layout: one control per
  interval) and T_guess.
* ``e3_bounded`` (configs/e3_bounded.yaml): E3 with |u_f|^2 <= F^2 and |u_m,i| <= b_i; its start is ours,
  the solution without bounds (from E3's rollout it did not converge within 120 s at N = 100).

``--compare`` runs ours (se3ocp.solve, default settings, the direct method) and the peer at equal N,
each in fresh processes (``--runs``, medians), and prints the ratios (none where either side did not
converge: a time to no solution is not a speed) and both re-simulated terminal errors:

    .venv/bin/python scripts/peer_rockit.py --compare slew,slew_sym,e3_bounded --N 100,200 --runs 3
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

WALL_CAP_S = 120.0


def _rhs_functions(model):
    """(X[18], u[6]) -> dX/dt as a CasADi Function (layout of transcription.geometry.state)."""
    from se3ocp.transcription.geometry.state import join_state, split_state
    from se3ocp.transcription.geometry.so3 import hat

    X = ca.SX.sym("X", 18)
    u = ca.SX.sym("u", 6)
    x, g, R, P = split_state(X)
    f, M = model.forces(x, R)
    Om = ca.mtimes(ca.DM(np.linalg.inv(model.inertia)), P)
    dX = join_state(g / model.mass, f + u[0:3], ca.mtimes(R, hat(Om)), ca.cross(P, Om) + M + u[3:6])
    return ca.Function("rigid_body_rhs", [X, u], [dX], ["X", "u"], ["dX"])


def resimulate(model, X0, U, T, rtol=1e-12, atol=1e-12):
    """DOP853 re-simulation of (1)-(4) with piecewise-constant controls U (6, N) -> nodes (N+1, 18)."""
    from scipy.integrate import solve_ivp

    rhs = _rhs_functions(model)
    N = U.shape[1]
    h = T / N
    out = [np.asarray(X0, float)]
    Xk = out[0]
    for k in range(N):
        uk = U[:, k]
        sol = solve_ivp(lambda t, y: np.array(rhs(y, uk)).ravel(), (0.0, h), Xk, method="DOP853", rtol=rtol, atol=atol)
        Xk = sol.y[:, -1]
        out.append(Xk)
    return np.vstack(out)


def orthogonality(X):
    from se3ocp.transcription.geometry.state import unpack_states

    R = unpack_states(np.asarray(X)).R
    E = np.einsum("kji,kjl->kil", R, R) - np.eye(3)
    return float(np.linalg.norm(E, axis=(1, 2)).max()), float(np.abs(np.linalg.det(R) - 1).max())


def _run_ipopt(ocp, N: int, wall_cap: float, t0: float):
    """RK4 multiple shooting and IPOPT (tol 1e-10, a wall-time cap) on ``ocp``, solved; returns (solution,
    stats, status, converged, build_s, solve_s): build = Ocp set-up, transcription, nlpsol construction, up
    to IPOPT's iteration 0 (from t0); solve = IPOPT iteration 0 to the end (rockit does not separate them)."""
    from rockit import MultipleShooting

    ocp.method(MultipleShooting(N=N, M=1, intg="rk"))
    ocp.solver("ipopt", {"print_time": False, "expand": True,
                         "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10, "max_wall_time": float(wall_cap),
                                   "max_iter": 3000}})
    marks: list[float] = []
    ocp.callback(lambda *_a: marks.append(time.perf_counter()))   # iteration 0 starts the solve clock
    status, converged = "unknown", False
    try:
        sol = ocp.solve()
        stats = sol.stats
        status, converged = str(stats.get("return_status")), bool(stats.get("success"))
    except RuntimeError as exc:
        sol = ocp.non_converged_solution
        stats = ocp._method.opti.stats() if hasattr(ocp, "_method") else {}
        status = str(stats.get("return_status", str(exc).strip().splitlines()[-1][:200]))
    t_end = time.perf_counter()
    solve_s = t_end - marks[0] if marks else t_end - t0
    return sol, stats, status, converged, t_end - t0 - solve_s, solve_s


#: case -> bundled maneuver file
STEMS = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture", "slew": "slew_time_optimal",
         "slew_sym": "slew_time_optimal_symmetric", "e3_bounded": "e3_bounded"}


def _attitude_rhs(model):
    """(Z[12] = [vec R (column-major); Pi], u_m[3]) -> dZ/dt of a body without a central body or force."""
    from se3ocp.transcription.geometry.so3 import hat

    Z = ca.SX.sym("Z", 12)
    um = ca.SX.sym("u_m", 3)
    R = ca.reshape(Z[0:9], 3, 3)
    P = Z[9:12]
    _, M = model.forces(ca.DM.zeros(3), R)
    Om = ca.mtimes(ca.DM(np.linalg.inv(model.inertia)), P)
    dZ = ca.vertcat(ca.vec(ca.mtimes(R, hat(Om))), ca.cross(P, Om) + M + um)
    return ca.Function("attitude_rhs", [Z, um], [dZ], ["Z", "u_m"], ["dZ"])


def _solve_constrained(case: str, N: int, wall_cap: float) -> dict:
    """The rockit version of a slew (time objective, FreeTime) or of the bounded E3."""
    from rockit import FreeTime, Ocp

    import se3ocp
    from se3ocp.transcription.strategy.starts import perturbed
    from se3ocp.transcription.geometry.state import X_ANG, X_ROT, split_state
    from se3ocp.transcription.geometry.so3 import log_so3

    prob = se3ocp.load(ROOT / "configs" / f"{STEMS[case]}.yaml", [f"horizon.N={N}", "discretization=first_order"]).problem
    model, c = prob.disc.model, prob.control
    slew = c.objective.free_time
    t0 = time.perf_counter()
    if slew:
        if not (c.removed[0] and model.mu is None):
            raise ValueError("the slew peer covers attitude-only problems (no central body, force removed)")
        ocp = Ocp(T=FreeTime(prob.T))
        Z = ocp.state(12)
        um = ocp.control(3)
        ocp.set_der(Z, _attitude_rhs(model)(Z, um))
        lo, hi = prob.time_bounds
        ocp.subject_to(lo <= (ocp.T <= hi))
        ocp.add_objective(ocp.T)
        b = c.moment_bound.b
        ocp.subject_to(-ca.DM(b) <= (um <= ca.DM(b)))
        Z0 = np.concatenate([prob.X0[X_ROT], prob.X0[X_ANG]])
        ocp.subject_to(ocp.at_t0(Z) == ca.DM(Z0))
        ZN = ocp.at_tf(Z)
        Rd, Pd = prob.Xd[X_ROT].reshape(3, 3, order="F"), prob.Xd[X_ANG]
        ocp.subject_to(ca.vertcat(log_so3(ca.mtimes(ca.DM(Rd).T, ca.reshape(ZN[0:9], 3, 3))), ZN[9:12] - Pd) == 0)
        size = np.concatenate([np.zeros(3), b])
        guess = perturbed(prob.replace(N=N), size, seed=0)
        ocp.set_initial(Z, np.hstack([guess.X[:, X_ROT], guess.X[:, X_ANG]]).T)
        ocp.set_initial(um, guess.U[3:6])
        ctrl = um
    else:
        ocp = Ocp(T=prob.T)
        X = ocp.state(18)
        u = ocp.control(6)
        ocp.set_der(X, _rhs_functions(model)(X, u))
        W = c.W
        ocp.add_objective(ocp.integral(0.5 * ca.bilin(ca.DM(W), u, u)))
        for sl, bound in ((slice(0, 3), c.force_bound), (slice(3, 6), c.moment_bound)):
            box = None if bound is None else bound.variable_box()
            if box is not None:
                ocp.subject_to(ca.DM(box[0]) <= (u[sl] <= ca.DM(box[1])))
            elif bound is not None:
                ocp.subject_to(ca.sumsqr(u[sl]) <= float(bound.radius) ** 2)
        ocp.subject_to(ocp.at_t0(X) == ca.DM(prob.X0))
        x, g, R, P = split_state(ocp.at_tf(X))
        xd, gd, Rd, Pd = split_state(ca.DM(prob.Xd))
        ocp.subject_to(ca.vertcat(x - xd, g - gd, log_so3(ca.mtimes(Rd.T, R)), P - Pd) == 0)
        # the same start as ours: the solution without bounds (our direct method's, not timed here; from
        # the rollout, as E3's peer starts, it ran into the 120 s wall-time cap at N = 100 after 1143 iterations)
        Xg, Ug = relaxed_start(prob)
        ocp.set_initial(X, Xg.T)
        ocp.set_initial(u, Ug)
        ctrl = u
    sol, stats, status, converged, build_s, solve_s = _run_ipopt(ocp, N, wall_cap, t0)
    _, Us = sol.sample(ctrl, grid="control")
    nu = 3 if slew else 6
    Uc = np.asarray(Us, float).reshape(N + 1, nu)[:N].T
    U = np.vstack([np.zeros((3, N)), Uc]) if slew else Uc
    T = float(sol.value(ocp.T)) if slew else prob.T
    cost = T if slew else float(0.5 * prob.h * np.einsum("ik,ij,jk->", U, c.W, U))
    rec = {"method": "rockit", "solver": "rockit-ipopt (RK4 multiple shooting)", "build_s": build_s,
           "solve_s": solve_s, "iterations": int(stats.get("iter_count", 0)), "converged": converged,
           "status": status, "cost": cost, "T": T}
    if slew:
        bmax = np.abs(Uc).max(axis=1)
        rec["bound_violation"] = float(max(0.0, (bmax - c.moment_bound.b).max()))
    return _resimulated(rec, prob, U, T)


def relaxed_start(prob):
    """Node states (N+1, 18) and controls (6, N) of our direct solution of ``prob`` without its bounds (the
    first start of our bounded effort problems, transcription.strategy.plan.relaxation), first-order scheme."""
    from se3ocp.transcription.solve import solve_direct
    from se3ocp.transcription.strategy.plan import relaxation

    s = solve_direct(relaxation(prob))
    if not s.converged:
        raise RuntimeError(f"the relaxed problem did not converge: {s.message}")
    return np.asarray(s.trajectory.X, float), np.asarray(s.controls, float)


def run_ours(case: str, N: int) -> dict:
    """Our direct method with its default settings on the same maneuver (its own scheme, N steps)."""
    import se3ocp

    s = se3ocp.solve(se3ocp.load(ROOT / "configs" / f"{STEMS[case]}.yaml", [f"horizon.N={N}"]), "direct")
    return {"method": "se3ocp", "solver": f"direct ({s.problem.scheme})", "build_s": float(s.build_s),
            "solve_s": float(s.solve_s), "iterations": int(s.iterations), "converged": bool(s.converged),
            "status": s.result.value, "cost": float(s.cost), "T": float(s.T),
            "terminal_error": float(s.terminal_error)}


def solve_peer(case: str, N: int, wall_cap: float = WALL_CAP_S) -> dict:
    """Build and solve the rockit version of a case (e3, e4, slew, slew_sym, e3_bounded) with N
    intervals; returns a bench record."""
    from rockit import Ocp

    if case not in ("e3", "e4"):
        return _solve_constrained(case, N, wall_cap)

    import se3ocp
    from se3ocp.transcription.strategy.starts import rollout
    from se3ocp.transcription.geometry.state import split_state
    from se3ocp.transcription.geometry.so3 import log_so3
    from se3ocp.transcription.ocp import terminal_error

    stem = STEMS[case]
    prob = se3ocp.load(ROOT / "configs" / f"{stem}.yaml", [f"horizon.N={N}", "discretization=first_order"]).problem
    model, T = prob.disc.model, prob.T
    t0 = time.perf_counter()
    ocp = Ocp(T=T)
    X = ocp.state(18)
    u = ocp.control(6)
    rhs = _rhs_functions(model)
    ocp.set_der(X, rhs(X, u))
    W = prob.control.W
    ocp.add_objective(ocp.integral(0.5 * ca.bilin(ca.DM(W), u, u)))
    ocp.subject_to(ocp.at_t0(X) == ca.DM(prob.X0))
    XN = ocp.at_tf(X)
    x, g, R, P = split_state(XN)
    xd, gd, Rd, Pd = split_state(ca.DM(prob.Xd))
    ocp.subject_to(ca.vertcat(x - xd, g - gd, log_so3(ca.mtimes(Rd.T, R)), P - Pd) == 0)
    guess = rollout(prob.replace(N=N))   # the same initial guess as ours
    ocp.set_initial(X, guess.X.T)
    ocp.set_initial(u, np.zeros((6, N)))
    sol, stats, status, converged, build_s, solve_s = _run_ipopt(ocp, N, wall_cap, t0)
    _, Xs = sol.sample(X, grid="control")
    _, Us = sol.sample(u, grid="control")
    Xs = np.asarray(Xs, float).reshape(N + 1, 18)
    U = np.asarray(Us, float).reshape(N + 1, 6)[:N].T
    cost = float(0.5 * prob.h * np.einsum("ik,ij,jk->", U, W, U))
    rec = {"method": "rockit", "solver": "rockit-ipopt (RK4 multiple shooting)", "build_s": build_s,
           "solve_s": solve_s, "iterations": int(stats.get("iter_count", 0)), "converged": converged,
           "status": status, "cost": cost}
    nlp_orth, nlp_det = orthogonality(Xs)
    rec["nlp_terminal_error"] = terminal_error(Xs[-1], prob)
    rec["orthogonality_nodes"] = nlp_orth
    rec["det_error_nodes"] = nlp_det
    return _resimulated(rec, prob, U, T)


def _resimulated(rec: dict, prob, U: np.ndarray, T: float) -> dict:
    """``rec`` with the terminal error (docs/mathematics.md §8) and the orthogonality of the DOP853
    re-simulation of the peer's controls U (6, N) over [0, T], and a message if it did not converge."""
    from se3ocp.transcription.ocp import terminal_error

    if np.all(np.isfinite(U)) and np.isfinite(T):
        Xr = resimulate(prob.disc.model, prob.X0, U, T)
        rec["terminal_error"] = terminal_error(Xr[-1], prob)
        rec["orthogonality_resim"], rec["det_error_resim"] = orthogonality(Xr)
    else:
        rec["terminal_error"] = float("inf")
    if not rec["converged"]:
        rec["message"] = f"rockit/IPOPT did not converge: {rec['status']}"
    return rec


def compare(cases: list[str], Ns: list[int], runs: int, timeout: float) -> list[dict]:
    """Ours and the peer, fresh processes, round-robin (benchkit.round_robin); per (case, N): medians and
    the ratios peer / ours."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from benchkit import round_robin

    def line(r, k, rec):
        print(f"  run {r + 1} {k[0]:10s} N={k[1]:4d} {k[2]:5s} {rec.get('status', '?')!s:18s} it "
              f"{rec.get('iterations', '-')!s:>5} build {rec.get('build_s', float('nan')):7.2f} s solve "
              f"{rec.get('solve_s', float('nan')):7.2f} s cost {rec.get('cost', float('nan')):.10g} "
              f"terminal error {rec.get('terminal_error', float('nan')):.1e}", flush=True)

    out = round_robin(Path(__file__).resolve(), cases, Ns, runs, timeout, ("cost", "T", "terminal_error"), line)
    print(f"\nmedians of {runs} fresh-process run(s) each; ratio = peer / ours")
    print("| maneuver | N | ours: it / build s / solve s | peer: it / build s / solve s | solve ratio | "
          "build+solve ratio | cost ours / peer | terminal error ours / peer (DOP853) |")
    print("|---|---|---|---|---|---|---|---|")

    def ratio(x):
        return "-" if x is None else f"{x:.1f}x"

    def cost(rec):
        return f"{rec['cost']:.8g}" if rec.get("converged") else "-"

    for r in out:
        if "ours" not in r:
            print(f"| {r['case']} | {r['N']} | {r['status']} |")
            continue
        o, p = r["ours"], r["peer"]
        print(f"| {r['case']} | {r['N']} | {o['iterations']} / {o['build_s']:.2f} / {o['solve_s']:.2f} | "
              f"{p['iterations']} / {p['build_s']:.2f} / {p['solve_s']:.2f}{'' if p['converged'] else ' (' + p['status'] + ')'} | "
              f"{ratio(r['solve_ratio'])} | {ratio(r['total_ratio'])} | {cost(o)} / {cost(p)} | "
              f"{o['terminal_error']:.1e} / {p['terminal_error']:.1e} |")
    return out


if __name__ == "__main__":
    import argparse
    import json

    ap = argparse.ArgumentParser(description="the rockit peer (see the module docstring)")
    ap.add_argument("case", nargs="?", default="e3", choices=sorted(STEMS))
    ap.add_argument("N", nargs="?", type=int, default=250)
    ap.add_argument("--compare", default=None, help="comma separated cases: ours against the peer, fresh processes")
    ap.add_argument("--N", dest="Ns", default="100,200", help="with --compare: comma separated N")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--json", default=None, help="with --compare: write the records to this file")
    ap.add_argument("--one", nargs=3, metavar=("CASE", "N", "WHO"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        case, N, who = a.one[0], int(a.one[1]), a.one[2]
        print(json.dumps(run_ours(case, N) if who == "ours" else solve_peer(case, N)))
    elif a.compare:
        recs = compare([c for c in a.compare.split(",") if c], [int(n) for n in a.Ns.split(",")], a.runs, a.timeout)
        if a.json:
            Path(a.json).write_text(json.dumps(recs, indent=1))
    else:
        print(json.dumps(solve_peer(a.case, a.N), indent=1))
