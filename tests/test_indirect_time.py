"""The indirect method for the time objective (transcription/methods/indirect/objectives.py; docs/mathematics.md,
"The indirect method for the time objective"): the two time-optimal slews (configs/slew_time_optimal.yaml, Betts'
reorientation; configs/slew_time_optimal_symmetric.yaml, Bilimoria & Wie) by both methods on the same grid.

Default run: N = 40 (each solve a few seconds); the acceptance sizes N = 100 and 200 are marked slow.  The direct
method runs at tol 1e-12 so that its T is good to ~1e-11: the indirect T is asserted equal to 1e-9 relative
(measured 1.6e-11 .. 8e-11; the issue asks 1e-6).  Numbers measured are printed (run with -s).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.geometry.state import NU, U_FORCE, U_MOMENT, tangent_readback
from se3ocp.transcription.methods.indirect.control import FUEL_EPS, bound_data, saturation, weight_inverse
from se3ocp.transcription.methods.indirect.objectives import switching_function
from se3ocp.transcription.methods.indirect.solve import not_covered
from se3ocp.transcription.options import DirectOptions
from se3ocp.transcription.ocp import BoxBound, NormBound, SmoothControl, quadrature_weights
from se3ocp.transcription.objectives import Time
import support

SLEWS = ("slew_time_optimal", "slew_time_optimal_symmetric")


def both(name: str, N: int):
    """compare (solve 'both') with the direct method at tol 1e-12: the indirect method's cold start fails at once
    (a zero costate turns nothing) and it falls back to the direct solution."""
    return se3ocp.solve(support.maneuver(name, N), "both", direct=DirectOptions(tol=1e-12))


@pytest.fixture(scope="module", params=SLEWS)
def compared(request):
    return request.param, both(request.param, 40)


def relative_T(cmp) -> float:
    d, i = cmp.direct, cmp.indirect
    return abs(i.cost - d.cost) / d.cost


# --------------------------------------------------------------------------------------------- agreement
def check_agreement(name, cmp, rtol=1e-9):
    d, i = cmp.direct, cmp.indirect
    print(f"{name} N = {d.problem.N}: direct T = {d.cost:.14g}, indirect T = {i.cost:.14g}, relative "
          f"{relative_T(cmp):.1e}; {i.stats['time_homotopy']['message']}")
    assert d.converged and i.converged, i.message
    assert np.isclose(i.cost, i.trajectory.t[-1], rtol=1e-15, atol=0)     # the cost is T = N h
    assert relative_T(cmp) <= rtol
    assert cmp.verdict.startswith("agree")
    assert i.stats["fallback"] == "from_direct" and i.stats["time_homotopy"]["settled"]


def test_indirect_T_equals_direct_T(compared):
    check_agreement(*compared)


@pytest.mark.slow
@pytest.mark.parametrize("N", [100, 200])
@pytest.mark.parametrize("name", SLEWS)
def test_indirect_T_equals_direct_T_at_the_acceptance_sizes(name, N):
    check_agreement(name, both(name, N))


# --------------------------------------------------------------------------------------------- the control law
def sigma_of(sol, h: float | None = None) -> np.ndarray:
    """sigma (6 x n_controls) from the indirect Solution's costates (lgvi: its shooting unknown lambda_{-1} first), at
    the (mean) step size h (default: the first step's, t_1)."""
    p, lams = sol.problem, sol.costates.T
    if p.scheme == "lgvi":
        lams = np.column_stack([sol.warm.lam0, lams])
    return switching_function(p, lams, sol.trajectory.t[1] if h is None else h)


def law(sigma: np.ndarray, problem, e: float, eps_fuel: float = 0.0) -> np.ndarray:
    """The method's one control law (indirect/control.py ``saturate``) of the switching function sigma (6 x n): the
    time objective's eps-law sat(-W^-1 sigma / e) (e = 1: the effort law; ``eps_fuel`` > 0: the fuel objective's on/off
    law of switching.on_off on its norm-bounded blocks)."""
    bd = bound_data(problem)
    bd[FUEL_EPS] = eps_fuel
    Winv, sat = weight_inverse(problem), saturation()
    return np.column_stack([np.array(sat(-Winv @ s / e, bd)[0]).ravel() for s in np.asarray(sigma, float).T])


def test_the_switching_function_decides_the_control(compared):
    """The controls are the method's eps-law of sigma at the final e (to 1e-9 of the bound, measured 1.4e-16; sigma
    from the Solution's costates); u_i = -b_i sign(sigma_i) wherever the control is at its bound (the Hamiltonian's
    minimizer); inside the bound (the switching nodes) sigma is within the eps-law's band |sigma_i| <= e W_ii b_i, and
    there is at most one such node per switch: the discrete eps = 0 structure."""
    _, cmp = compared
    i = cmp.indirect
    full = sigma_of(i)
    U, sigma, b = i.controls[U_MOMENT], full[U_MOMENT], i.problem.control.moment_bound.b[:, None]
    e, Wm = i.stats["time_homotopy"]["e"], np.diag(i.problem.control.W_m)[:, None]
    assert np.abs(law(full, i.problem, e) - i.controls).max() <= 1e-9 * b.max()
    at = np.abs(U) >= b * (1 - 1e-12)
    assert np.all(U[at] == -np.broadcast_to(b, U.shape)[at] * np.sign(sigma[at]))
    band = np.broadcast_to(e * Wm * b, sigma.shape)
    assert np.all(np.abs(sigma[~at]) <= band[~at] * (1 + 1e-9))
    for k in range(3):       # between two interior nodes of a component the sign changes: one node per switch
        inside = np.flatnonzero(~at[k])
        assert np.all(np.diff(inside) > 1)
    print(f"interior nodes per component: {(~at).sum(axis=1)}, smallest |sigma| at a bang node "
          f"{np.abs(sigma[at]).min():.2e} (band {float(e * Wm.max() * b.max()):.2e})")
    assert np.all(i.controls[U_FORCE] == 0.0)


def test_the_switch_structure_is_the_direct_solutions(compared):
    """Away from the switching nodes both methods' torques are at the same bound, and they switch at the same
    nodes."""
    _, cmp = compared
    d, i = cmp.direct.controls[U_MOMENT], cmp.indirect.controls[U_MOMENT]
    b = cmp.direct.problem.control.moment_bound.b[:, None]
    at_d, at_i = np.abs(d) >= b * (1 - 1e-6), np.abs(i) >= b * (1 - 1e-12)
    assert np.array_equal(at_d, at_i)
    assert np.array_equal(np.sign(d[at_d]), np.sign(i[at_i]))
    assert np.abs(d - i).max() <= 1e-5 * b.max()


def test_the_free_final_time_condition_holds(compared):
    """dL/dh = N + e J_effort / h + sum_k lambda_k^T readback(d step_k / dh) = 0, with d step / dh by central
    differences of disc.step (not the AD of the method), and the eps = 0 condition N + sum_k ... within e J / h."""
    _, cmp = compared
    i = cmp.indirect
    p, h, X, U = i.problem, i.trajectory.t[1], i.trajectory.X, i.controls
    disc = p.disc
    W = disc.stage_controls(U)
    dh = 1e-6 * h
    terms = []
    for k in range(p.N):
        Xp, Xm = (np.array(disc.step(X[k], W[:, k], h + s)[0]).ravel() for s in (dh, -dh))
        X1 = np.array(disc.step(X[k], W[:, k], h)[0]).ravel()
        t = np.array(tangent_readback(X1, (Xp - Xm)[:, None] / (2 * dh))).ravel()
        terms.append(i.costates[k] @ t)
    e = i.stats["time_homotopy"]["e"]
    omega = np.full(U.shape[1], 1.0)
    if p.scheme == "lgvi":
        omega[[0, -1]] = 0.5
    effort_per_h = 0.5 * float(np.einsum("k,ik,ij,jk->", omega, U, p.control.W, U))
    g = p.N + e * effort_per_h + np.sum(terms)
    print(f"dL/dh / N = {g / p.N:.1e}; eps = 0 part {(g - e * effort_per_h) / p.N:.1e} (e J/(h N) = "
          f"{e * effort_per_h / p.N:.1e})")
    assert abs(g) / p.N <= 1e-7
    assert abs(g - e * effort_per_h) / p.N <= 1.01 * e * effort_per_h / p.N + 1e-7


# --------------------------------------------------------------------------------------------- the law itself
def test_the_laws_at_their_limits_are_the_hamiltonians_minimizer():
    """The method's one law (``saturate``) at its limits minimizes the discrete Hamiltonian's control part over the
    bounds: the time objective's eps-law at e -> 0 (1e-12) is bang-bang per component of a box and along -sigma in a
    norm ball, 0 where sigma = 0 (a switching node, not decided by the minimizer); the fuel objective's on/off law
    (switching.on_off) at eps -> 0 is full thrust along -sigma where |sigma| > w and off below (the threshold w = 1 of
    W_f = w I); a removed control (norm bound 0) is 0."""
    sigma = np.array([[3.0, -0.1], [4.0, 0.2], [0.0, 0.0], [1.0, -2.0], [-1.0, 0.0], [2.0, 3.0]])
    box = SmoothControl(objective=Time(), force_bound=NormBound(2.0), moment_bound=BoxBound([1.0, 2.0, 3.0]))
    u = law(sigma, dataclasses.replace(support.problem("slew_time_optimal", 20), control=box), 1e-12)
    assert u.shape == (NU, 2)
    assert np.allclose(u[U_FORCE, 0], [-1.2, -1.6, 0.0], rtol=1e-14) and np.all(u[U_MOMENT, 0] == [-1.0, 2.0, -3.0])
    assert np.all(u[U_MOMENT, 1] == [1.0, 0.0, -3.0])                  # sigma = 0: a switching node, 0
    fuel = dataclasses.replace(box, objective=se3ocp.Fuel())
    on_off = law(sigma, dataclasses.replace(support.problem("slew_time_optimal", 20), control=fuel), 1.0, 1e-12)
    assert np.allclose(on_off[U_FORCE, 0], [-1.2, -1.6, 0.0], rtol=1e-14) and np.all(on_off[U_FORCE, 1] == 0.0)
    removed = SmoothControl(objective=Time(), force_bound=NormBound(0.0), moment_bound=BoxBound([1.0, 1.0, 1.0]))
    p = dataclasses.replace(support.problem("slew_time_optimal", 20), control=removed)
    assert np.all(law(sigma, p, 1e-12)[U_FORCE] == 0.0)


def test_coverage_names_what_is_left():
    p = support.problem("slew_time_optimal", 20)
    assert not_covered(p) == ""
    assert not_covered(p, ("effort",)) == "the time objective"     # MPC's re-plan (the effort Newton step)
    body = support.problem("slew_time_optimal", 20, None, "control.force_frame=body")
    assert not_covered(body) == "the time objective with a body-fixed force"
    mesh = dataclasses.replace(p, mesh=np.linspace(0.5, 1.5, 20))
    assert not_covered(mesh) == ""                                  # the mesh: below, docs/mathematics.md §18


@pytest.mark.slow
def test_the_homotopy_from_the_direct_costates_reaches_the_same_T(monkeypatch):
    """Without the structure start (the path taken when it fails): from the direct lambda_0 and T at eps = 1e-2,
    eps halved along the path's tangent until T settles -- Betts' slew at N = 100 (measured: 5 stages, 1 retried)."""
    from se3ocp.transcription.methods.indirect import objectives
    from se3ocp.transcription.methods.indirect.laws import TimeLaw

    cmp = both("slew_time_optimal", 100)
    monkeypatch.setattr(objectives, "structure_start", lambda *args: None)
    again = se3ocp.solve(support.maneuver("slew_time_optimal", 100), "indirect", warm_start=cmp.direct)
    stages = again.stats["time_homotopy"]["stages"]
    print(again.stats["time_homotopy"]["message"])
    assert again.converged and stages[0]["eps"] == TimeLaw().eps_start
    assert abs(again.cost - cmp.indirect.cost) <= 1e-12 * cmp.indirect.cost


# --------------------------------------------------------------------------------------------- on a non-uniform mesh
def on_mesh(name: str, N: int, scheme: str | None = None):
    """The slew on the irregular mesh r_k = 1.5 + sin(2.3 k) (steps 0.5 to 2.5 times the mean; tests/test_indirect_mesh.py)."""
    return support.problem(name, N, scheme).replace(mesh=1.5 + np.sin(2.3 * np.arange(N)))


@pytest.fixture(scope="module", params=[None, "first_order"])
def meshed(request):
    """Betts' slew on the mesh, N = 40, by both methods (the direct method at tol 1e-12)."""
    p = on_mesh("slew_time_optimal", 40, request.param)
    return p, se3ocp.solve(p, "both", direct=DirectOptions(tol=1e-12))


def test_indirect_T_equals_direct_T_on_a_non_uniform_mesh(meshed):
    """Betts' slew, N = 40, on the mesh (free T: every step scales with the mean step h, h_k = r_k h): the indirect T
    equals the direct T to 1e-9 relative (issue 26 asks 1e-8; measured 1.6e-11 LGVI, 1.5e-11 first order, as on a
    uniform grid), the first stage from the direct solution's switching structure on the mesh's node times (2 and 4
    stages in all); the mesh is felt (the uniform grid's T differs by 6e-4 and 9e-4)."""
    p, cmp = meshed
    check_agreement(f"Betts' slew ({p.scheme}) on the mesh", cmp)
    i = cmp.indirect
    assert not i.uniform and np.allclose(np.diff(i.trajectory.t) / i.h, p.mesh, rtol=1e-12, atol=0)
    stages = i.stats["time_homotopy"]["stages"]
    assert i.stats["time_homotopy"]["structure_start"] and stages[0]["result"] in ("converged", "round_off_floor")
    uniform = se3ocp.solve(support.problem("slew_time_optimal", 40, p.scheme), "direct", direct=DirectOptions(tol=1e-12))
    assert abs(uniform.cost - cmp.direct.cost) >= 1e-4 * cmp.direct.cost


def test_on_a_mesh_the_switching_function_and_the_free_final_time_condition(meshed):
    """On the mesh: the torque is at its bound with the sign of -sigma_j (sigma_j at the step size h_j of its node)
    wherever it is at a bound; dL/dh = N + e J_effort / h + sum_k r_k lambda_k^T readback(d step_k / dh_k) = 0 with
    d step_k / dh_k by central differences of disc.step at h_k (not the method's AD): |g| / N <= 1e-7; with the
    steps' terms unweighted by r_k it is far from 0 (the weighting is what the solution satisfies)."""
    p, cmp = meshed
    i = cmp.indirect
    sigma = sigma_of(i, i.h)[U_MOMENT]
    U, b = i.controls[U_MOMENT], np.broadcast_to(p.control.moment_bound.b[:, None], i.controls[U_MOMENT].shape)
    at = np.abs(U) >= b * (1 - 1e-12)
    assert at.mean() > 0.8 and np.all(U[at] == -b[at] * np.sign(sigma[at]))
    X, W, hk = i.trajectory.X, p.disc.stage_controls(i.controls), np.diff(i.trajectory.t)
    terms = []
    for k in range(p.N):
        dh = 1e-6 * hk[k]
        Xp, Xm = (np.array(p.disc.step(X[k], W[:, k], hk[k] + d)[0]).ravel() for d in (dh, -dh))
        X1 = np.array(p.disc.step(X[k], W[:, k], hk[k])[0]).ravel()
        terms.append(i.costates[k] @ np.array(tangent_readback(X1, (Xp - Xm)[:, None] / (2 * dh))).ravel())
    e, terms = i.stats["time_homotopy"]["e"], np.array(terms)
    omega = quadrature_weights(p.scheme, p.N, p.mesh)          # per unit mean step
    effort_per_h = 0.5 * float(np.einsum("k,ik,ij,jk->", omega, i.controls, p.control.W, i.controls))
    g, unweighted = p.N + e * effort_per_h + p.mesh @ terms, p.N + e * effort_per_h + terms.sum()
    print(f"{p.scheme} on the mesh: dL/dh / N = {g / p.N:.1e} (unweighted by r_k: {unweighted / p.N:.1e})")
    assert abs(g) / p.N <= 1e-7 and abs(unweighted) / p.N >= 1e-3
