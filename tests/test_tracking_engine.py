"""Issue 43, first and fourth bullets (docs/mathematics.md §12, *Input channels* and *The rate tracked*): the tracker
of a body-fixed engine steers the thrust by turning the body (its input is the engine's thrust T along the axis plus
the moment, on the step's own linearization, whose attitude columns carry d(R u_b)/dR), and it tracks the measured
rate Omega, not the truth's angular momentum."""
from __future__ import annotations

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.closedloop import tracking as tr
from se3ocp.transcription.closedloop.loop import TrackingLoop
from se3ocp.transcription.dynamics.flight import ClosedLoop, OpenLoop, fly
from se3ocp.transcription.geometry.state import U_FORCE, Z_ROT

from support import maneuver
from test_body_force import ENGINE_SLEW


def _engine_slew():
    sol = se3ocp.solve(maneuver("slew_keep_out", None, None, *ENGINE_SLEW))
    assert sol.converged, sol.message
    return sol


def test_the_attitude_columns_of_the_linearization_are_the_steps_own():
    """A body-frame engine plan (the engine slew, N = 40) at its step of largest thrust: the columns of A_k for the
    attitude against central differences of the discrete step on the manifold (R -> R Exp(+-eps e_i), eps = 1e-4,
    compared by log, tracking.tangent_error): equal to 1e-8 (measured 2.8e-11; A's entries are O(1)), and the force
    rows are not zero (0.017): the applied force R u_b turns with the body."""
    sol = _engine_slew()
    G, disc = tr.tracking_gains(sol), sol.problem.disc
    k = int(np.argmax(np.linalg.norm(sol.controls[U_FORCE], axis=0)))
    w, X, h = disc.stage_controls(sol.controls)[:, k], G.X[k], G.step(k)

    def step(Y):
        return np.asarray(disc.step(Y, w, h)[0]).ravel()

    X1, eps = step(X), 1e-4
    D = np.column_stack([(tr.tangent_error(step(tr.retract(X, eps * e)), X1)
                          - tr.tangent_error(step(tr.retract(X, -eps * e)), X1)) / (2 * eps) for e in np.eye(12)[Z_ROT]])
    assert np.abs(D - G.A[k][:, Z_ROT]).max() <= 1e-8
    assert np.abs(G.A[k][3:6, Z_ROT]).max() >= 1e-2


def test_the_engine_tracker_uses_only_the_engines_channels_and_beats_open_loop_under_a_thrust_error():
    """The engine slew flown on its own discrete step with every force delivered 2 % strong: the gains never ask for
    a force off the engine axis (K's force rows along the axis to 1e-14), every command is an engine command, and
    the terminal error falls by more than 5x against open loop (measured max |z_N| 2.0e-2 -> 2.0e-3); flown without
    an error the closed loop reproduces the plan to round-off (measured max |z| 1.5e-40, the commands the plan's to
    1e-15 of the thrust)."""
    sol = _engine_slew()
    G, disc, b = tr.tracking_gains(sol), sol.problem.disc, sol.problem.control.force_bound
    off = np.eye(3) - np.outer(b.axis, b.axis)
    assert np.abs(off @ G.K[:, U_FORCE, :]).max() <= 1e-14 * np.abs(G.K[:, U_FORCE, :]).max()

    def strong(w):
        w = np.array(w, float)
        w[:, U_FORCE] *= 1.02
        return w

    open_loop = tr.fly_discrete(G, disc, G.X[0], feedback=False, actuator=strong)
    closed = tr.fly_discrete(G, disc, G.X[0], actuator=strong)
    print(f"engine slew, 2 % thrust: max |z_N| open {np.abs(open_loop.z[-1]).max():.2e}, "
          f"closed {np.abs(closed.z[-1]).max():.2e}")
    assert np.abs(closed.z[-1]).max() <= 0.2 * np.abs(open_loop.z[-1]).max()
    uf = closed.commands[..., 0:3].reshape(-1, 3)
    assert np.max(b.off_axis(uf)) <= 1e-15 * b.max and b.thrust(uf).min() >= 0.0 and b.thrust(uf).max() <= b.max
    exact = tr.fly_discrete(G, disc, G.X[0])
    plan_rows = G.U[:, np.c_[:G.N, 1:G.N + 1]].transpose(1, 2, 0)          # (N, 2, 6): [u_k; u_{k+1}]
    assert np.abs(exact.z).max() <= 1e-12 and np.abs(exact.commands - plan_rows).max() <= 1e-15 * b.max


@pytest.mark.parametrize("law", ["python", "loop"])
def test_the_rate_is_tracked_under_an_inertia_error(law):
    """E3 (LGVI, N = 100) flown on a truth whose principal inertias are 1 % off (x1.01, x0.99, x1.01), from the plan's
    attitude and rate.  Tracking the truth's angular momentum Pi (law_inertia None: the law reads Pi itself) ends
    with the rate off by 95 % of |(J_true^-1 J - I) Omega_N| (0.0589 of 0.0622 rad/TU: Pi matched, Omega not); the
    measured rate (law_inertia the plan's J) ends within 2 % of it (measured 3.3e-4, 0.5 %) and the position no
    worse.  Both the Tracker asked per interval and the loop in one call."""
    sol = se3ocp.solve(maneuver("e3", 100, "lgvi"), "direct")
    g, body, plan = tr.tracking_gains(sol), sol.problem.model, sol.trajectory
    truth = type(body)(mass=body.mass, inertia=body.inertia * np.array([1.01, 0.99, 1.01]), potential=body.potential,
                       forces=body.forces, mu=body.mu, markers=body.markers, name=body.name)
    X0 = plan.X[0].copy()
    X0[15:18] = truth.inertia @ np.linalg.solve(body.inertia, X0[15:18])          # the plan's Omega_0
    scale = np.linalg.norm((np.linalg.solve(truth.inertia, body.inertia) - np.eye(3)) @ plan.Omega[-1])

    def flown(J):
        if law == "loop":
            return fly(truth, X0, g.t, TrackingLoop.of_gains(g), law_inertia=J).trajectory()
        t = g.tracker()
        return fly(truth, X0, g.t, ClosedLoop(OpenLoop.of_controls("lgvi", g.U), lambda k, _, X: t.correction(k, X)),
                   law_inertia=J).trajectory()

    old, new = flown(None), flown(body.inertia)
    miss = [np.linalg.norm(f.Omega[-1] - plan.Omega[-1]) for f in (old, new)]
    pos = [np.linalg.norm(f.x[-1] - plan.x[-1]) for f in (old, new)]
    print(f"{law}: rate miss {miss[0]:.3e} -> {miss[1]:.3e} of {scale:.3e}; position {pos[0]:.2e} -> {pos[1]:.2e}")
    assert miss[0] >= 0.9 * scale and miss[1] <= 0.02 * scale and pos[1] <= pos[0]


@pytest.mark.slow
@pytest.mark.parametrize("config, sets", [("leo_body_engine", ()), ("leo/raise_engine", ()),
                                          ("leo/raise_engine_j2", ("gravity.kind=point_mass",))])
def test_a_body_engine_leo_raise_flown_closed_loop(config, sets):
    """(slow: a LEO plan at N = 400-600 and four continuous flights, ~30 s.)  The bundled body-engine raises flown
    on their own point-mass truth (se3ocp.fly, one run, seed 0): with no error the LQR lands within 1e-2 of open
    loop (the plan's discretization error; measured leo_body_engine 8.8 m open, 6 mm closed; raise_engine 32 m,
    1.1 mm), and with a force scale error (sigma 2 %) within 1e-2 of open loop (measured 716 m -> 0.12 m, 1.3 km ->
    0.26 m); under 10 % of the steps saturated (measured 3.3 %, 2.5 %) and the delta-v delivered within 0.1 % of the
    plan's (measured at most 2.4e-4 relative).  Before issue 43: 8.8 m open, 560 m closed, 99.75 % saturated.  The 2 N
    raise of raise_engine_j2.yaml planned and flown about a point mass: 3.83 m open, 7.1 mm closed."""
    man = maneuver(config, None, None, *sets)
    sol = se3ocp.solve(man, "direct")
    assert sol.converged, sol.message
    for scale in (0.0, 0.02):
        flight = {"errors": {"force_scale": scale}, "feedback": "both", "runs": 1, "seed": 0}
        rows = {r["feedback"]: r for r in se3ocp.fly(sol, flight, maneuver=man).rows}
        assert rows["none"]["status"] == rows["lqr"]["status"] == "ok"
        if scale:
            assert rows["none"]["position_miss"] > 1e-3    # the draw gives the open loop something to miss
        o, c = rows["none"]["position_miss"], rows["lqr"]["position_miss"]
        print(f"{config}, force scale sigma {scale}: open {o:.3e}, closed {c:.3e}, saturated "
              f"{rows['lqr']['saturated_fraction']:.3f}, delta-v overhead {rows['lqr']['delta_v_overhead']:.2e}")
        assert c <= 1e-2 * o                           # issue 43: within 1e-2 of open loop, errors or none
        assert rows["lqr"]["saturated_fraction"] <= 0.1 and abs(rows["lqr"]["delta_v_overhead"]) <= 1e-3


@pytest.mark.slow
def test_a_leo_raise_planned_with_j2_flown_on_j2_with_errors_lands_within_a_hundredth_of_open_loop():
    """(slow: a LEO plan at N = 600 with J2, ~30 s, and 2 x 20 continuous flights, ~25 s.)  Issue 43's first line:
    configs/leo/raise_engine_j2.yaml (one 2 N body engine, planned with J2) flown with configs/flights/leo_engine_j2.yaml
    (the preset's J2 in the truth, 2 % thrust, 0.5 deg misalignment, initial dispersions 50 m, 5 cm/s, 0.5 deg,
    1e-4 rad/s; 20 of its runs): the LQR's p95 position miss within 1e-2 of open loop's and its p95 delta-v overhead
    within 5 % (measured with the file's 200 runs: p95 41.1 km open, 3.7 m closed; overhead p95 1.37 %).  A
    point-mass plan flown on J2 is worse closed loop than open (J2's pull is 7x the engine's: README, flights).
    Without the errors (the J2 truth only) within 1e-3 of open loop: the plan's local errors fed forward
    (docs/mathematics.md §12, *Known local errors*; measured 1.9 cm against 51.2 m open, 0.94 m before)."""
    import yaml
    from pathlib import Path

    man = maneuver("leo/raise_engine_j2")
    sol = se3ocp.solve(man, "direct")
    assert sol.converged, sol.message
    doc = yaml.safe_load((Path(__file__).parents[1] / "configs/flights/leo_engine_j2.yaml").read_text())["flight"]
    clean = {r["feedback"]: r["position_miss"]
             for r in se3ocp.fly(sol, {"truth": doc["truth"], "feedback": "both", "runs": 1, "seed": 0}, maneuver=man).rows}
    print(f"raise_engine_j2 on J2 without errors: open {clean['none']:.3e} km, closed {clean['lqr']:.3e} km")
    assert clean["lqr"] <= 1e-3 * clean["none"]
    rows = se3ocp.fly(sol, {**doc, "runs": 20}, maneuver=man).rows
    by = {f: [r for r in rows if r["feedback"] == f] for f in ("none", "lqr")}
    assert all(r["status"] == "ok" for r in rows)
    p95 = {f: float(np.percentile([r["position_miss"] for r in rs], 95)) for f, rs in by.items()}
    overhead = float(np.percentile([r["delta_v_overhead"] for r in by["lqr"]], 95))
    print(f"raise_engine_j2 on J2 with errors: p95 open {p95['none']:.3e} km, closed {p95['lqr']:.3e} km, "
          f"delta-v overhead p95 {overhead:.3%}")
    assert p95["none"] > 1.0                           # the errors give open loop kilometres to miss
    assert p95["lqr"] <= 1e-2 * p95["none"] and overhead <= 0.05
