"""Bounded, time-optimal and fuel-optimal maneuvers with path constraints, on rigid bodies
(docs/mathematics.md §10): the direct method against published optima and independent checks.

Published optima (continuous problems, the references cited in the configs):
* asymmetric body, configs/slew_time_optimal.yaml -- Betts, "Practical Methods for Optimal Control
  and Estimation Using Nonlinear Programming", 2nd ed. (SIAM 2010), sect. 6.8, from the data of
  Fleming, Sekhavat & Ross (AIAA 2008-7012): minimum time 28.6304077 s;
* symmetric body, configs/slew_time_optimal_symmetric.yaml -- Bilimoria & Wie, "Time-Optimal
  Three-Axis Reorientation of a Rigid Spacecraft", J. Guidance, Control, and Dynamics 16(3),
  1993: minimum time 3.2431 (the eigenaxis rotation takes 2 sqrt(pi) = 3.5449).
The discrete minimum times converge at second order in h (LGVI); a Richardson extrapolation of
N = 100 and 200 must agree with the published value to 0.1 %.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.ocp import fuel_cost, quadrature_weights
from support import ROOT, maneuver


@lru_cache(maxsize=None)
def solved(name: str, N: int | None = None, sets: tuple[str, ...] = (), method: str = "direct", **opts):
    return se3ocp.solve(maneuver(name, N, None, *sets), method, **opts)


# ------------------------------------------------------------------ time-optimal slews
@pytest.mark.parametrize("name, published", [("slew_time_optimal", 28.6304077), ("slew_time_optimal_symmetric", 3.2431)])
def test_time_optimal_slews_converge_to_the_published_minimum(name, published):
    T = {}
    for N in (50, 100, 200):
        s = solved(name, N)
        assert s.converged, s.message
        assert s.terminal_error <= 1e-10 and s.T == pytest.approx(s.cost, rel=1e-14)
        b = s.problem.control.moment_bound.b
        um = s.u_m
        assert np.abs(um).max() <= b.max() * (1 + 1e-7)                        # bounds respected
        # bang-bang on each axis up to the discretization: every component sits on its bound except
        # at the nodes next to a switch (at most 3 switches per axis)
        at = np.abs(um) >= b * (1 - 1e-5)
        assert np.all(at.sum(axis=0) >= len(um) - 6), at.sum(axis=0)
        assert np.abs(s.u_f).max() == 0.0                                       # the force is removed
        T[N] = s.cost
    # monotone, second-order convergence (from below here: the discrete problem is slightly optimistic)
    d1, d2 = T[100] - T[50], T[200] - T[100]
    assert d1 > 0 and d2 > 0 and 3.0 <= d1 / d2 <= 5.0, T
    extrapolated = T[200] + d2 / 3.0
    assert abs(extrapolated - published) <= 1e-3 * published, (extrapolated, published)


@pytest.mark.parametrize("name", [pytest.param("slew_time_optimal", marks=pytest.mark.slow),    # 22-30 s
                                  "slew_time_optimal_symmetric"])
def test_coarse_grid_starts_reach_the_fine_grid_minimum(name):
    """The time objective's starts are solved on max(25, N // 2) steps (recursively: 100 -> 50 -> 25) and the best is
    finished on N (TimeStrategy.coarse_min, coarse_factor): the same minimum as the starts solved on N steps."""
    from se3ocp.transcription.objectives.time import TimeStrategy, bracketing_times, estimate_times

    coarse = solved(name, 100)
    assert coarse.trace[0].label == "the best start on 50 steps, resampled"
    assert coarse.trace[0].parts[-1].label == "the best start on 25 steps, resampled"
    assert coarse.trace[0].prepared_on == "the coarse grid" and coarse.trace[0].total_iterations > coarse.trace[0].iterations
    assert coarse.stats["initial_guess"] == "from coarse"
    fine = se3ocp.solve(maneuver(name, 100), "direct", strategy=TimeStrategy(coarse_min=10 ** 6))   # the starts on N
    p100, ts = maneuver(name, 100).problem, TimeStrategy()
    starts = ts.starts + len(bracketing_times(p100)) + len(estimate_times(p100, ts.estimate_factors))  # seeds, Ts
    assert [a.prepared_on for a in fine.trace] == [""] * starts
    assert "resampled" not in fine.stats["initial_guess"]
    assert fine.converged and coarse.converged
    # the minimum time to solver tolerance (the controls may be a mirror image of each other: the slews
    # have symmetric pairs of minima of equal time, e.g. the asymmetric one's u_z reversed in sign and time)
    assert coarse.cost == pytest.approx(fine.cost, rel=1e-9, abs=0.0)


def test_failed_coarse_grid_start_falls_back_to_the_fine_grid_starts():
    """When the coarse-grid solve does not converge (here: one start within 1 iteration), the starts are solved on N
    steps as before; the coarse solve's iterations count."""
    from dataclasses import replace

    from se3ocp.transcription.objectives.time import TimeStrategy
    from se3ocp.transcription.strategy import starts
    from se3ocp.transcription.strategy.core import Solve

    class CoarseFails(TimeStrategy):
        def compose(self, problem, options, start=None):
            out = super().compose(problem, options, start)
            starved = replace(out.strategies[0], coarse=Solve(starts.interpolation, "interpolate", budget=1))
            return replace(out, strategies=(starved,) + out.strategies[1:])

    s = se3ocp.solve(maneuver("slew_time_optimal_symmetric", 50), "direct", strategy=CoarseFails())
    assert s.converged and len(s.trace) == 1 + TimeStrategy().starts
    first = s.trace[0]
    assert first.result is None and first.note == "not available (the coarse-grid problem did not converge)"
    assert first.total_iterations == 1                      # the coarse solve's iteration counts
    assert all(a.result is not None for a in s.trace[1:]) and "resampled" not in s.stats["initial_guess"]
    assert s.cost == pytest.approx(solved("slew_time_optimal_symmetric", 50).cost, rel=1e-9)


def test_resampled_solution_on_its_own_grid_is_the_solution():
    """A warm start fitted to the grid it lives on is itself; to a 4x finer grid (of the same scheme) its
    nodes 4k are the old nodes, the attitudes stay on SO(3) and its step size is T / N."""
    s = solved("slew_time_optimal_symmetric", 50)
    same, notes = s.warm.fit(50, s.scheme)
    assert same is s.warm and notes == ()
    assert np.array_equal(same.X, s.trajectory.X) and np.array_equal(same.U, s.controls)
    fine, notes = s.warm.fit(200, s.scheme)
    assert np.abs(fine.X[::4] - s.trajectory.X).max() <= 1e-12
    assert fine.h == pytest.approx(s.T / 200, rel=1e-15) and fine.T == s.T
    R = fine.X[:, 6:15].reshape(-1, 3, 3)
    assert np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max() <= 1e-13
    assert notes[0] == f"resampled from N = 50 ({s.scheme}) to N = 200 ({s.scheme}) on SE(3)"


def test_time_optimal_slew_is_not_the_eigenaxis_maneuver():
    """The eigenaxis (single-axis bang-bang) slew takes 2 sqrt(theta J_x / u) = 34.31 s; the optimum
    uses all three axes and is 17 % faster."""
    s = solved("slew_time_optimal", 100)
    eigenaxis = 2.0 * np.sqrt(np.radians(150.0) * 5621.0 / 50.0)
    assert s.cost < 0.85 * eigenaxis
    assert all(len(sw) >= 1 for sw in s.stats["bounds"]["moment"]["switch_times"])


# ---------------------------------------------------------------------- bounded effort
def test_bounded_effort_below_the_unbounded_peak():
    """configs/e3_bounded.yaml: E3 with the thrust norm bounded below the unbounded peak and a box
    on the body torque: converged, bounds respected to 1e-7, active where the unbounded control
    exceeded them, costlier than the unbounded optimum."""
    s, free = solved("e3_bounded"), solved("e3_inclination_change")
    assert s.converged and s.terminal_error <= 1e-10, s.message
    c = s.problem.control
    b_f, b_m = c.force_bound.b, c.moment_bound.b
    thrust, free_thrust = np.linalg.norm(s.u_f, axis=1), np.linalg.norm(free.u_f, axis=1)
    assert thrust.max() <= b_f * (1 + 1e-7) and np.all(np.abs(s.u_m) <= b_m * (1 + 1e-7))
    assert free_thrust.max() > b_f and np.any(np.abs(free.u_m) > b_m)
    # active where the unbounded thrust was far above the bound; inactive where far below
    assert np.all(thrust[free_thrust > 1.05 * b_f] >= b_f * (1 - 1e-6))
    assert np.all(thrust[free_thrust < 0.5 * b_f] < b_f * (1 - 1e-2))
    for i in range(3):
        over = np.abs(free.u_m[:, i]) > 1.1 * b_m[i]
        assert over.any() and np.all(np.abs(s.u_m[over, i]) >= b_m[i] * (1 - 1e-6)), i
    assert s.stats["bounds"]["force"]["at_bound_fraction"] > 0.1
    assert s.cost > free.cost


# ------------------------------------------------------------------------ path constraints
def test_keep_out_slew_stays_out_of_the_cone():
    s = solved("slew_keep_out")
    assert s.converged, s.message
    c = s.problem.constraints[0]
    assert c.margin(s.trajectory).min() >= -1e-8                      # degrees, on the re-simulation
    assert s.stats["constraints"][0]["min_margin"] == pytest.approx(c.margin(s.trajectory).min(), abs=0)
    assert s.stats["constraints"][0]["active_nodes"] >= 1 and s.stats["constraints"][0]["max_multiplier"] > 0
    free = se3ocp.solve(s.problem.replace(constraints=()), direct=maneuver("slew_keep_out").direct)
    assert free.converged and c.margin(free.trajectory).min() < -5.0   # the straight path enters the cone
    assert s.cost > free.cost


def test_min_radius_keeps_the_path_above_the_sphere():
    s = solved("e3_min_radius")
    assert s.converged, s.message
    r = np.linalg.norm(s.trajectory.x, axis=1)
    assert r.min() >= 0.995 - 1e-10
    free = se3ocp.solve(s.problem.replace(constraints=()), direct=maneuver("e3_min_radius").direct)
    assert np.linalg.norm(free.trajectory.x, axis=1).min() < 0.99 and s.cost > free.cost


# ------------------------------------------------------------------------------- fuel
def test_fuel_optimal_orbit_raise():
    """configs/orbit_raise_fuel.yaml: the fuel spent is below the effort solution's (same problem with
    the effort objective), the bounds hold, the thrust is on its bound or off over 97 % of the nodes
    (bang-off-bang), and the delta-v lies between the impulsive Hohmann transfer's -- the minimum of
    every coplanar transfer between circular orbits of radius ratio < 11.9 -- and 6 % above it."""
    from dataclasses import replace

    s = solved("orbit_raise_fuel")
    assert s.converged and s.terminal_error <= 1e-10, s.message
    p = s.problem
    om = quadrature_weights(p.scheme, p.N, s.h)
    assert s.cost == pytest.approx(fuel_cost(s.controls, p.control, om), rel=1e-14)
    effort = se3ocp.solve(p.replace(control=replace(p.control, objective=se3ocp.Effort())), "direct")
    assert effort.converged, effort.message
    assert s.cost < fuel_cost(effort.controls, p.control, om)
    b_f, b_m = p.control.force_bound.b, p.control.moment_bound.b
    thrust = np.linalg.norm(s.u_f, axis=1)
    assert thrust.max() <= b_f * (1 + 1e-7) and np.linalg.norm(s.u_m, axis=1).max() <= b_m * (1 + 1e-7)
    on_or_off = (thrust >= b_f * (1 - 1e-3)) | (thrust <= b_f * 1e-3)
    assert on_or_off.mean() >= 0.97
    mu, r1, r2 = p.model.mu, np.linalg.norm(p.X0[:3]), p.terminal.radius
    hohmann = np.sqrt(mu / r1) * (np.sqrt(2 * r2 / (r1 + r2)) - 1) + np.sqrt(mu / r2) * (1 - np.sqrt(2 * r1 / (r1 + r2)))
    delta_v = float(om @ thrust) / p.model.mass
    assert hohmann <= delta_v <= 1.06 * hohmann, (delta_v, hohmann)
    assert s.summary()["delta_v"] == pytest.approx(delta_v, rel=1e-12)


# ------------------------------------------------------------------------ free final time
@pytest.mark.parametrize("name, fixed_name, N", [("e3_free_time", "e3_inclination_change", None), ("e4", "e4", 100)])
def test_free_final_time_lowers_the_effort(name, fixed_name, N):
    """configs/e3_free_time.yaml, and E4 with T free by --set: T in [min, max], cost <= fixed T's."""
    fixed = solved(fixed_name, N)
    s = solved(name, N, () if name != "e4" else ("horizon.T={free: true, guess: 0.5, min: 0.4, max: 0.6}",))
    assert s.converged and s.terminal_error <= 1e-10, s.message
    assert 0.4 <= s.T <= 0.6 and s.stats["T"] == pytest.approx(s.T, rel=1e-14)
    assert s.cost <= fixed.cost * (1 + 1e-12)
    X, _ = s.problem.disc.simulate(s.problem.X0, s.controls, s.h, s.N)          # re-simulated with h = T / N
    np.testing.assert_array_equal(X, s.trajectory.X)


# ------------------------------------------------------------------------------ models
def test_maccullagh_potential_matches_the_dumbbell_far_away():
    """The second-order (MacCullagh) expansion differs from the exact dumbbell potential by
    O(mu m l^4 / r^5): at r = 1 and 2 the differences scale by 2^5 (to 2 %)."""
    import casadi as ca

    from se3ocp.problems.models import Dumbbell
    from se3ocp.transcription.geometry.so3 import exp_so3

    R = exp_so3(np.array([0.3, -0.5, 0.2]))
    exact, approx = Dumbbell().potential(), Dumbbell(gravity="gravity_gradient").potential()
    diffs = []
    for r in (1.0, 2.0):
        x = r * np.array([0.6, 0.8, 0.0])
        diffs.append(float(exact(x, R)) - float(approx(x, R)))
    assert diffs[0] / diffs[1] == pytest.approx(32.0, rel=0.02)
    del ca


def test_gravity_gradient_torque_formula():
    """The moment derived by AD from the MacCullagh potential is 3 mu / r^3 (rb x J rb), rb = R^T x / r."""
    from se3ocp.problems.models import Gravity, RigidBody
    from se3ocp.transcription.geometry.so3 import exp_so3

    J = np.diag([3.0, 2.0, 1.0])
    body = RigidBody(2.0, J, Gravity("point_mass", 5.0))
    model = body.body_model()
    x, R = np.array([1.0, 2.0, -0.5]), exp_so3(np.array([0.4, 0.1, -0.7]))
    f, M = (np.array(a).ravel() for a in model.forces(x, R))
    r = np.linalg.norm(x)
    rb = R.T @ x / r
    np.testing.assert_allclose(M, 3 * 5.0 / r**3 * np.cross(rb, J @ rb), rtol=1e-12, atol=1e-15)

    def U(y):       # the MacCullagh potential in closed form, independent of the CasADi model
        ry = np.linalg.norm(y)
        Ir = y @ R @ J @ R.T @ y / ry**2
        return -5.0 * 2.0 / ry - 5.0 / (2 * ry**3) * (np.trace(J) - 3 * Ir)

    e, d = np.eye(3), 1e-5
    f_fd = np.array([-(U(x + d * e[i]) - U(x - d * e[i])) / (2 * d) for i in range(3)])
    np.testing.assert_allclose(f, f_fd, rtol=1e-8)       # central differences: O(d^2) ~ 1e-10


def test_j2_force_at_the_pole_and_the_equator():
    """-grad of the J2 potential: at the pole |f| = mu/r^2 (1 - 3 J2 (Re/r)^2)... sign checks against
    the closed form f_r = -mu/r^2 [1 - 3/2 J2 (Re/r)^2 (3 sin^2(lat) - 1)]."""
    from se3ocp.problems.models import Gravity, RigidBody

    mu, J2, Re = 4.0, 1e-3, 0.9
    body = RigidBody(1.0, np.eye(3) * 1e-6, Gravity("j2", mu, J2, Re))
    model = body.body_model()
    for lat, x in ((0.0, np.array([1.2, 0.0, 0.0])), (90.0, np.array([0.0, 0.0, 1.2]))):
        f = np.array(model.forces(x, np.eye(3))[0]).ravel()
        r = 1.2
        fr = -mu / r**2 * (1 - 1.5 * J2 * (Re / r) ** 2 * (3 * np.sin(np.radians(lat)) ** 2 - 1))
        assert f @ x / r == pytest.approx(fr, rel=1e-9)


# ------------------------------------------------------------------------------- compare
def test_compare_says_what_the_indirect_method_does_not_cover():
    c = solved("slew_keep_out", method="both")
    assert c.direct.converged and c.indirect.result is se3ocp.Result.not_applicable
    assert "path constraints" in c.verdict and c.verdict.startswith("not comparable")
    assert c.direct.costates is not None and c.direct.costates.shape == (c.direct.N, 12)   # multiplier estimates


# ------------------------------------------------------------------ the indirect method on them
@pytest.mark.parametrize("N, scheme", [(None, None), (100, "lgvi")])
def test_direct_and_indirect_agree_on_bounded_effort(N, scheme):
    """configs/e3_bounded.yaml by both methods (the indirect one from lambda_0 = 0, by the bound
    continuation and semismooth Newton): cost to 1e-6 and controls to 1e-4 (relative; the gap is the
    direct method's interior-point tolerance, see the next test), the same nodes at the thrust bound."""
    m = maneuver("e3_bounded", N, scheme)
    d = solved("e3_bounded") if scheme is None else solved("e3_bounded", N, (f"discretization={scheme}",))
    i = se3ocp.solve(m, "indirect")
    assert d.converged and i.converged, (d.message, i.message)
    assert i.stats["initial_costate"] == "zero" and len(i.stats["bound_continuation"]) >= 2
    assert i.terminal_error <= 1e-10
    assert abs(i.cost - d.cost) <= 1e-6 * d.cost
    assert np.abs(i.controls - d.controls).max() <= 1e-4 * np.abs(d.controls).max()
    b = m.problem.control.force_bound.b
    ti, td = np.linalg.norm(i.u_f, axis=1), np.linalg.norm(d.u_f, axis=1)
    clear = np.abs(td - b) > 1e-3 * b                      # nodes not at the edge of the active set
    np.testing.assert_array_equal((ti >= b * (1 - 1e-9))[clear], (td >= b * (1 - 1e-6))[clear])
    assert (ti >= b * (1 - 1e-9)).any() and np.all(ti <= b * (1 + 1e-14))
    cmp = se3ocp.compare(d, i)
    assert cmp.same_extremal and cmp.verdict.startswith("agree")


def test_the_gap_on_bounded_effort_is_the_direct_tolerance():
    """With IPOPT's tolerance at 1e-12 instead of 1e-10 the direct solution of the bounded E3 (N = 100)
    moves onto the indirect one: cost to 1e-9, controls to 1e-7."""
    m = maneuver("e3_bounded", 100)
    i = se3ocp.solve(m, "indirect")
    d = se3ocp.solve(m, "direct", tol=1e-12)
    assert i.converged and d.converged
    assert abs(i.cost - d.cost) <= 1e-9 * i.cost
    assert np.abs(i.controls - d.controls).max() <= 1e-7 * np.abs(i.controls).max()


def test_direct_multipliers_satisfy_the_saturated_control_law():
    """The discrete minimum principle read from the direct side: with the costates mapped from the direct
    method's multipliers, every control of the bounded E3 (first order, N = 100) minimizes the discrete
    Hamiltonian over the bounds, u_{k+1} = sat(-W^-1 [lambda^2_k; lambda^4_k]) -- the thrust projected on
    its norm ball, each torque component clipped to its box (written here in NumPy, independently of the
    method's saturate) -- to 1e-6 of the largest control."""
    d = se3ocp.solve(maneuver("e3_bounded", 100), "direct", tol=1e-12)
    c = d.problem.control
    lam = d.costates                                       # (N, 12): lambda_0 .. lambda_{N-1}
    v_f = -np.linalg.solve(c.W_f, lam[:, 3:6].T).T
    v_m = -np.linalg.solve(c.W_m, lam[:, 9:12].T).T
    n = np.linalg.norm(v_f, axis=1, keepdims=True)
    u_f = v_f * np.minimum(1.0, c.force_bound.b / n)
    u_m = np.clip(v_m, -c.moment_bound.b, c.moment_bound.b)
    assert np.abs(np.c_[u_f, u_m] - d.controls.T).max() <= 1e-6 * np.abs(d.controls).max()
    assert (n.ravel() > c.force_bound.b * 1.01).any()       # the law does saturate somewhere


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_semismooth_jacobian_equals_ad_through_the_saturated_rollout(scheme):
    """With bounds, Psi and dlambda_{N-1}/dlambda_0 by the linearized recursion (saturation Jacobians D_k)
    equal CasADi's forward AD through the saturated rollout (the same branches of min/max), to 1e-10, at a
    point where the thrust saturates."""
    import casadi as ca
    from se3ocp.transcription.methods.indirect.control import bound_data, weight_inverse
    from se3ocp.transcription.methods.indirect.shooting import shooting_functions

    p = maneuver("e3_bounded", 40, scheme).problem
    fns = shooting_functions(p.disc, 40)
    args = (p.X0, p.terminal.X, p.h, weight_inverse(p), bound_data(p))
    lam = se3ocp.solve(p, "indirect").warm.lam0 * 1.01
    U = np.array(fns.shoot(lam, *args)[3])
    assert (np.linalg.norm(U[:3], axis=0) >= p.control.force_bound.b * (1 - 1e-12)).any()
    l = ca.MX.sym("l", 12)
    z, lamN, _ = fns.residual(l, *args)
    ad = ca.Function("ad", [l], [ca.jacobian(z, l), ca.jacobian(lamN, l)])
    P_ad, L_ad = (np.array(a) for a in ad(lam))
    _, P, L = (np.array(a) for a in fns.shoot_jac(lam, *args))
    assert np.abs(P - P_ad).max() <= 1e-10 * np.abs(P_ad).max()
    assert np.abs(L - L_ad).max() <= 1e-10 * np.abs(L_ad).max()


@pytest.mark.parametrize("name, sets", [
    ("slew_keep_out", ("constraints=[]",)),                                 # position and velocity free
    ("e3_inclination_change", ("terminal={position: [-1.0, 0.0, 0.0], velocity: [0.0, -5.441398092702654, "
                               "-3.1415926535897927]}", "horizon.N=100")),  # attitude and its rate free
])
def test_free_terminal_components_by_transversality(name, sets):
    """Free terminal components: lambda_{N-1} = 0 on them (indirect) against the direct method, which
    simply leaves them out: cost to 1e-10, controls to 1e-9."""
    m = se3ocp.load(ROOT / "configs" / f"{name}.yaml", sets)
    assert m.problem.terminal.free
    d, i = se3ocp.solve(m, "direct"), se3ocp.solve(m, "indirect")
    assert d.converged and i.converged, i.message
    assert abs(i.cost - d.cost) <= 1e-10 * d.cost
    assert np.abs(i.controls - d.controls).max() <= 1e-9 * np.abs(d.controls).max()
    free = np.repeat([c in m.problem.terminal.free for c in ("position", "velocity", "attitude", "angular_velocity")], 3)
    assert np.abs(i.costates[-1][free]).max() <= 1e-12 * np.abs(i.costates).max()


def test_free_final_time_by_both_methods():
    """configs/e3_free_time.yaml: the indirect method's free-final-time condition dL/dh = 0 (a secant
    iteration over fixed-T shootings) finds the direct method's T to 1e-9 and its cost to 1e-12; with the
    interval's upper end below that optimum both stop at the bound."""
    m = maneuver("e3_free_time")
    d, i = solved("e3_free_time"), se3ocp.solve(m, "indirect")
    assert d.converged and i.converged, i.message
    assert abs(i.T - d.T) <= 1e-9 * d.T and abs(i.cost - d.cost) <= 1e-12 * d.cost
    assert i.stats["free_time"]["converged"] and abs(i.stats["free_time"]["dL_dh"]) * i.h <= 1e-9 * i.cost
    capped = maneuver("e3_free_time", 200, None, "horizon.T={free: true, guess: 0.45, min: 0.4, max: 0.5}")
    d, i = se3ocp.solve(capped, "direct"), se3ocp.solve(capped, "indirect")
    assert d.converged and i.converged
    assert i.T == pytest.approx(0.5, rel=1e-15) and d.T == pytest.approx(0.5, rel=1e-9)
    assert i.stats["free_time"]["dL_dh"] < 0 and abs(i.cost - d.cost) <= 1e-9 * d.cost


def test_free_time_condition_is_the_derivative_of_the_optimal_cost():
    """Envelope theorem: dL/dh at the fixed-T optimum (the first evaluation of the free-time iteration, at
    the guess T = 0.5) equals dJ*/dh by central differences of fixed-T indirect solves, to 1e-6 (step
    1e-5: truncation ~2e-8, the solves' round-off ~4e-8 of dJ/dh)."""
    N, T, dT = 200, 0.5, 1e-5
    m = maneuver("e3_free_time", N)
    g = se3ocp.solve(m, "indirect").stats["free_time"]["evaluations"][0]
    assert g[0] == pytest.approx(T, rel=1e-15)
    J = [se3ocp.solve(maneuver("e3", N, None, f"horizon.T={t!r}"), "indirect").cost for t in (T - dT, T + dT)]
    fd = (J[1] - J[0]) / (2 * dT / N)
    assert g[1] == pytest.approx(fd, rel=1e-6)


@pytest.mark.parametrize("gravity", ["none", "point_mass"])
def test_full_inertia_tensor_is_a_rotated_principal_body(gravity):
    """A body given by a full inertia tensor J' = Q D Q^T is the principal body D seen in body axes turned
    by Q: from R'_0 = R_0 Q^T, Omega'_0 = Q Omega_0 the free motion (LGVI, no gravity or point-mass gravity
    with the MacCullagh term) is R'_k = R_k Q^T, Omega'_k = Q Omega_k -- to 1e-11 (relative) over 400 steps."""
    from se3ocp.transcription.geometry.so3 import exp_so3

    D = np.array([1.0, 1.5, 2.0]) * 1e-3          # a body small against its orbit (MacCullagh's expansion)
    Q = exp_so3(np.array([0.3, -0.5, 0.8]))
    R0, W0 = exp_so3(np.array([0.2, 0.1, -0.4])), np.array([0.7, -1.1, 0.4])
    Jf = Q @ np.diag(D) @ Q.T

    def run(J, R, W):
        sets = [f"gravity={{kind: {gravity}}}", "horizon={N: 400, T: 1.0}",
                f"model={{kind: rigid_body, mass: 1.0, inertia: {np.asarray(J).tolist()}}}",
                f"initial={{position: [1.0, 0, 0], velocity: [0, 6.283185307179586, 0], "
                f"attitude: {{matrix: {R.tolist()}}}, angular_velocity: {W.tolist()}}}"]
        return se3ocp.simulate(se3ocp.load(ROOT / "configs" / "free_tumble.yaml", sets)).trajectory

    a, b = run(D.tolist(), R0, W0), run(Jf, R0 @ Q.T, Q @ W0)
    np.testing.assert_allclose(b.R, a.R @ Q.T, rtol=0, atol=1e-11)
    np.testing.assert_allclose(b.Omega, a.Omega @ Q.T, rtol=0, atol=1e-11 * np.abs(a.Omega).max())
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-11 * np.abs(a.x).max())
    assert np.abs(a.R[-1] - a.R[0]).max() > 0.5 and np.abs(a.x).max() <= 7.0       # it did turn; no escape
