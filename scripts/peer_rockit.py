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
    """(X[18], u[6]) -> dX/dt as a CasADi Function (layout of transcription.layout)."""
    from se3ocp.transcription.layout import join_state, split_state
    from se3ocp.transcription.lie import hat

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
    from se3ocp.transcription.layout import unpack_states

    R = unpack_states(np.asarray(X)).R
    E = np.einsum("kji,kjl->kil", R, R) - np.eye(3)
    return float(np.linalg.norm(E, axis=(1, 2)).max()), float(np.abs(np.linalg.det(R) - 1).max())


def solve_peer(case: str, N: int, wall_cap: float = WALL_CAP_S) -> dict:
    """Build and solve the rockit version of E3/E4 with N intervals; returns a bench record."""
    from rockit import MultipleShooting, Ocp

    import se3ocp
    from se3ocp.transcription.guess import rollout_guess
    from se3ocp.transcription.layout import split_state
    from se3ocp.transcription.lie import log_so3
    from se3ocp.transcription.problem import terminal_error

    stem = {"e3": "e3_inclination_change", "e4": "e4_orbital_capture"}[case]
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
    guess = rollout_guess(prob.disc, prob.X0, N, prob.h)   # the same initial guess as ours
    ocp.set_initial(X, guess.X.T)
    ocp.set_initial(u, np.zeros((6, N)))
    ocp.method(MultipleShooting(N=N, M=1, intg="rk"))
    ocp.solver("ipopt", {"print_time": False, "expand": True,
                         "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10, "max_wall_time": float(wall_cap),
                                   "max_iter": 3000}})
    status, converged = "unknown", False
    marks: list[float] = []
    def mark(*_args):
        marks.append(time.perf_counter())   # IPOPT iteration 0 starts the solve clock

    ocp.callback(mark)
    try:
        sol = ocp.solve()
        stats = sol.stats
        status = str(stats.get("return_status"))
        converged = bool(stats.get("success"))
    except RuntimeError as exc:
        sol = ocp.non_converged_solution
        stats = ocp._method.opti.stats() if hasattr(ocp, "_method") else {}
        status = str(stats.get("return_status", str(exc).strip().splitlines()[-1][:200]))
    t_end = time.perf_counter()
    total = t_end - t0
    # build: Ocp set-up, transcription, nlpsol construction, up to IPOPT's iteration 0;
    # solve: IPOPT iteration 0 to the end (what rockit does not separate itself)
    solve_s = t_end - marks[0] if marks else total
    _, Xs = sol.sample(X, grid="control")
    _, Us = sol.sample(u, grid="control")
    Xs = np.asarray(Xs, float).reshape(N + 1, 18)
    U = np.asarray(Us, float).reshape(N + 1, 6)[:N].T
    cost = float(0.5 * prob.h * np.einsum("ik,ij,jk->", U, W, U))
    rec = {"method": "rockit", "solver": "rockit-ipopt (RK4 multiple shooting)", "build_s": total - solve_s,
           "solve_s": solve_s, "iterations": int(stats.get("iter_count", 0)), "converged": converged,
           "status": status, "cost": cost}
    nlp_orth, nlp_det = orthogonality(Xs)
    rec["nlp_terminal_error"] = terminal_error(Xs[-1], prob)
    rec["orthogonality_nodes"] = nlp_orth
    rec["det_error_nodes"] = nlp_det
    if np.all(np.isfinite(U)):
        Xr = resimulate(model, prob.X0, U, T)
        rec["terminal_error"] = terminal_error(Xr[-1], prob)
        rec["orthogonality_resim"], rec["det_error_resim"] = orthogonality(Xr)
    else:
        rec["terminal_error"] = float("inf")
    if not converged:
        rec["message"] = f"rockit/IPOPT did not converge: {status}"
    return rec


if __name__ == "__main__":
    import json

    case = sys.argv[1] if len(sys.argv) > 1 else "e3"
    N = int(sys.argv[2]) if len(sys.argv) > 2 else 250
    print(json.dumps(solve_peer(case, N), indent=1))
