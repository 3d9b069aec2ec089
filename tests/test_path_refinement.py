"""Refinement for path constraints between the nodes, where the violation is made (issue 26; transcription/mesh.py
``path_density``, transcription/accuracy.py ``path_mesh``; docs/mathematics.md §16, "Path constraints between the
nodes").

Two cases: the keep-out slew (configs/slew_keep_out.yaml: the camera axis touches its 20 deg cone at t = 5 s) and a
rate-limited slew (the same body, 120 deg about (1, 2, 3), |Omega| <= 0.25 rad/s active on 2.3..7.6 s: RATE_SLEW, a
``--set`` variant).  Their between-node violation at N = 100 (9.9e-5 rad, 8.2e-6 rad/s) is almost all drift: the flown
path's error accumulated before the contact, not the chord between two nodes.  The plans are re-flown densely by the
test's own DOP853 (a unit quaternion, NumPy right-hand side; not our engine) and the margins computed here from the
flown states, not by the constraints' own code.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import se3ocp
from se3ocp.transcription.strategy import refine as accuracy
from se3ocp.transcription.strategy.mesh import drift_shares, margin_gradients
from se3ocp.transcription.ocp import MaxAngularRate

from support import maneuver
from test_flight import R_to_quat, quat_to_R

#: the keep-out slew turned into a rate-limited one (a variant of configs/slew_keep_out.yaml by --set)
RATE_SLEW = ("constraints=[{kind: max_angular_rate, value: 0.25}]", "terminal.attitude={axis_angle: [1, 2, 3, 120]}")
#: the keep-out slew's cone (configs/slew_keep_out.yaml)
SOURCE = np.array([0.7071067811865476, 0.7071067811865476, 0.2])
SAMPLES = 8


def dense_flight(sol, samples: int = SAMPLES):
    """(t, R, Omega) of ``sol``'s plan flown from its first node by DOP853 (rtol 1e-12) per node interval,
    J Omega' = J Omega x Omega + M(t), q' = q (x) (0, Omega) / 2, M linear from u_k to u_{k+1} (the LGVI's controls),
    sampled ``samples`` times per interval.  The slews have no force and no gravity."""
    tr, U, J = sol.trajectory, sol.controls, sol.problem.model.inertia
    Jinv = np.linalg.inv(J)

    def rhs(t, y, t0, h, a, b):
        q, Om = y[0:4], y[4:7]
        M = a + (t - t0) / h * (b - a)
        qd = 0.5 * np.array([-q[1:] @ Om, *(q[0] * Om + np.cross(q[1:], Om))])
        return np.concatenate([qd, Jinv @ (np.cross(J @ Om, Om) + M)])

    y = np.concatenate([R_to_quat(tr.R[0]), tr.Omega[0]])
    ts, Ys = [tr.t[:1]], [y[None, :]]
    for k in range(len(tr.t) - 1):
        t0, t1 = tr.t[k], tr.t[k + 1]
        te = t0 + (t1 - t0) * np.arange(1, samples + 1) / samples
        te[-1] = t1
        r = solve_ivp(rhs, (t0, t1), y, method="DOP853", rtol=1e-12, atol=1e-14, t_eval=te,
                      args=(t0, t1 - t0, U[3:6, k], U[3:6, k + 1]))
        assert r.success, r.message
        y = r.y[:, -1]
        ts.append(r.t)
        Ys.append(r.y.T)
    Y = np.vstack(Ys)
    return np.concatenate(ts), np.array([quat_to_R(q) for q in Y[:, 0:4]]), Y[:, 4:7]


def keep_out_violation(sol) -> float:
    """max(0, 20 deg - angle(R b, source)) (rad) over the dense flight, b = body x."""
    _, R, _ = dense_flight(sol)
    c = R[:, :, 0] @ (SOURCE / np.linalg.norm(SOURCE))
    return float(max(0.0, np.max(np.radians(20.0) - np.arccos(np.clip(c, -1.0, 1.0)))))


def rate_violation(sol) -> float:
    """max(0, |Omega| - 0.25) (rad/s) over the dense flight."""
    _, _, Om = dense_flight(sol)
    return float(max(0.0, np.max(np.linalg.norm(Om, axis=1) - 0.25)))


def mean_step(sol, a: float, b: float) -> float:
    t, h = sol.trajectory.t[:-1], sol.steps
    return float(h[(t >= a) & (t < b)].mean())


# ------------------------------------------------------------------------------------------------ the pieces
def test_drift_shares_are_the_local_errors_propagated_along_the_gradient():
    """S[i, k] = |w_i A_{j-1} ... A_{k+1} z_k| for k < j = nodes[i], 0 from j on: against the products formed here."""
    rng = np.random.default_rng(26)
    N, nodes = 7, np.array([7, 3, 1])
    A, z, w = rng.normal(size=(N, 12, 12)), rng.normal(size=(N, 12)), rng.normal(size=(3, 12))
    S = drift_shares(A, z, nodes, w)
    for i, j in enumerate(nodes):
        for k in range(N):
            P = np.eye(12)
            for m in range(k + 1, j):
                P = A[m] @ P
            want = abs(w[i] @ P @ z[k]) if k < j else 0.0
            assert S[i, k] == pytest.approx(want, rel=1e-12, abs=1e-12)


def test_margin_gradients_are_the_margins_derivatives_in_tangent_coordinates():
    """The rate limit's gradient is -J^-T Omega / |Omega| in dPi and 0 elsewhere; the keep-out cone's (rad) is the
    derivative of its angle along R exp(eps e_i^) computed here with the exact exponential: both to 1e-8."""
    from se3ocp.transcription.geometry.so3 import exp_so3

    prob = maneuver("slew_keep_out").problem
    J = prob.model.inertia
    R = exp_so3(np.array([0.3, -0.2, 0.9]))
    Pi = np.array([0.1, -0.05, 0.2])
    X = np.concatenate([np.zeros(6), R.ravel(order="F"), Pi])
    rate = MaxAngularRate(0.25)
    g = margin_gradients(rate, X, 1.0, 1.0, J)[0]
    Om = np.linalg.solve(J, Pi)
    assert np.allclose(g[9:12], -np.linalg.inv(J).T @ Om / np.linalg.norm(Om), atol=1e-8) and np.allclose(g[:9], 0)
    cone = prob.constraints[0]
    g = margin_gradients(cone, X, np.pi / 180.0, 1.0, J)[0]

    def angle(Rm):
        return np.arccos((Rm[:, 0] @ SOURCE) / np.linalg.norm(SOURCE))

    eps = 1e-6
    want = [(angle(R @ exp_so3(eps * e)) - angle(R @ exp_so3(-eps * e))) / (2 * eps) for e in np.eye(3)]
    assert np.allclose(g[6:9], want, atol=1e-8) and np.allclose(g[:6], 0) and np.allclose(g[9:], 0)


def test_the_chord_share_is_where_the_two_rules_need_the_fewest_steps():
    """chord_share's tol_c minimizes a / sqrt(tol_c) + b / sqrt(tol - tol_c) (p = 2; a, b as its docstring defines
    them, formed here): a grid of 10^5 splits finds no smaller total (to 1e-6 relative)."""
    from se3ocp.transcription.strategy.mesh import chord_share

    rng = np.random.default_rng(7)
    h = rng.uniform(0.05, 0.15, 40)
    chord = np.where(rng.uniform(size=40) < 0.2, rng.uniform(1e-6, 1e-4, 40), 0.0)
    shares = rng.uniform(1e-8, 1e-6, 25)
    tol = 1e-5
    tc = chord_share(h, chord, shares, 2, tol)
    a = np.sqrt(chord).sum()
    b = np.sqrt(h[:25].sum()) * (h[:25] * np.sqrt(shares / h[:25] ** 3)).sum()

    def total(x):
        return a / np.sqrt(x) + b / np.sqrt(tol - x)

    grid = np.linspace(0.05, 0.95, 100001) * tol
    assert 0.05 * tol < tc < 0.95 * tol and total(tc) <= total(grid).min() * (1 + 1e-6)


# ------------------------------------------------------------------------------- refinement on the violation
def test_keep_out_refined_on_its_violation_lands_within_it_with_the_steps_before_the_contact(monkeypatch):
    """The keep-out slew with the terminal miss taken as met (scaled_miss patched to 0), accuracy 1e-5: one refinement
    (100 -> N), the steps before the contact at t = 5 s (where the drift is made) finer than the ones after it, the
    violation re-flown densely by the test's DOP853 <= 1e-5 rad; a uniform mesh of the same N violates by more
    (its drift ~ h^2)."""
    monkeypatch.setattr(accuracy, "scaled_miss", lambda check, problem: 0.0)
    sol = se3ocp.solve(maneuver("slew_keep_out"), accuracy=1e-5)
    assert sol.converged and sol.stats["accuracy_met"] is True, sol.message
    assert [r["N"] for r in sol.mesh][0] == 100 and len(sol.mesh) == 2 and sol.mesh[0]["path_violation"] > 9e-5
    v = keep_out_violation(sol)
    print(f"keep-out 1e-5: N = {[r['N'] for r in sol.mesh]}, independent violation {v:.3e}")
    assert v <= 1e-5 and v == pytest.approx(sol.mesh[-1]["path_violation"], rel=0.05, abs=1e-8)
    assert mean_step(sol, 0.0, 4.5) < 0.6 * mean_step(sol, 5.5, 10.0)
    uniform = se3ocp.solve(maneuver("slew_keep_out", sol.N), continuous_check=True)
    assert keep_out_violation(uniform) > 1e-5


def test_rate_limit_refined_on_its_violation_lands_within_it(monkeypatch):
    """The rate-limited slew (RATE_SLEW) leaves |Omega| <= 0.25 by 8.2e-6 rad/s at the end of its active arc (t = 7.6
    s) at N = 100; refined on the violation alone (scaled_miss patched to 0) to 1e-6: one refinement, the dense
    DOP853 flight within 1e-6 rad/s, the steps after the violation (nothing drifts there) coarser than those before."""
    monkeypatch.setattr(accuracy, "scaled_miss", lambda check, problem: 0.0)
    sol = se3ocp.solve(maneuver("slew_keep_out", None, None, *RATE_SLEW), accuracy=1e-6)
    assert sol.converged and sol.stats["accuracy_met"] is True, sol.message
    assert len(sol.mesh) == 2 and sol.mesh[0]["path_violation"] > 8e-6
    v = rate_violation(sol)
    print(f"rate 1e-6: N = {[r['N'] for r in sol.mesh]}, independent violation {v:.3e}")
    assert v <= 1e-6
    assert mean_step(sol, 0.0, 7.5) < 0.6 * mean_step(sol, 8.0, 10.0)


def test_a_violation_below_the_tolerance_changes_no_mesh():
    """A path violation within the tolerance asks for nothing: the keep-out slew at 2e-3 (violation 9.9e-5 rad, miss
    4.3e-4) stops at N = 100."""
    sol = se3ocp.solve(maneuver("slew_keep_out"), accuracy=2e-3)
    assert sol.mesh[0]["path_violation"] < 2e-3 and sol.mesh[0]["miss"] < 2e-3 and len(sol.mesh) == 1


@pytest.mark.slow
@pytest.mark.parametrize("sets, violation", [((), keep_out_violation), (RATE_SLEW, rate_violation)],
                         ids=["keep_out", "rate_limit"])
def test_path_constrained_slews_refined_to_1e_6_land_and_stay_within_it(sets, violation):
    """Acceptance (issue 26): accuracy 1e-6 with the terminal miss and the path: both <= 1e-6 by the test's DOP853
    (the terminal miss by test_accuracy.independent_miss, the violation densely), on fewer steps than uniform
    refinement reaches (measured: keep-out 100 -> 2331 against 100 -> 2483; rate 100 -> 2564 -> 2972 against
    100 -> 3200; both driven by the terminal miss, whose error does not concentrate in these slews: the best uniform
    meshes, 2100 and 2950 steps, meet both too -- docs/mathematics.md §16)."""
    from test_accuracy import independent_miss

    sol = se3ocp.solve(maneuver("slew_keep_out", None, None, *sets), accuracy=1e-6)
    assert sol.converged and sol.stats["accuracy_met"] is True, sol.message
    miss, v = independent_miss(sol), violation(sol)
    uni = se3ocp.solve(maneuver("slew_keep_out", None, None, *sets, "solver.refinement=uniform"), accuracy=1e-6)
    print(f"{sets}: adaptive N = {[r['N'] for r in sol.mesh]}, uniform N = {[r['N'] for r in uni.mesh]}, "
          f"independent miss {max(miss.values()):.2e}, violation {v:.2e}")
    assert max(miss.values()) <= 1e-6 and v <= 1e-6
    assert uni.stats["accuracy_met"] is True and sol.N < uni.N
