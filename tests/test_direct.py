"""The direct method (transcription/methods/direct/): layouts, guesses, E3/E4, costates, fatrop, failures.

Tolerances are stated next to each check; small N in the default suite, N = 500 and the
order in h in the slow tests.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

import se3ocp
from se3ocp.transcription.nlp.layouts import NLPLayout, StageLayout
from se3ocp.transcription.strategy import starts
from se3ocp.transcription.geometry.state import NU, NX, unpack_states
from se3ocp.transcription.geometry.so3 import orthogonality_error
from se3ocp.transcription.options import DirectOptions, OptionError
from se3ocp.transcription.ocp import quadrature_weights
from support import maneuver, problem

SCHEMES = ("lgvi", "first_order")


@lru_cache(maxsize=None)
def solved(name: str, N: int, scheme: str, sets: tuple[str, ...] = (), **opts):
    """Solve once per configuration (tests share solutions)."""
    return se3ocp.solve(maneuver(name, N, scheme, *sets), "direct", **opts)


# ------------------------------------------------------------------------ layouts
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("with_c", [True, False])
def test_layout_roundtrip(scheme, with_c):
    N = 7
    nodes = range(0, N + 1) if scheme == "lgvi" else range(1, N + 1)
    lay = NLPLayout(N, nodes, with_c)
    idx = np.concatenate([lay.iX.ravel(), lay.iU.ravel(), lay.iC.ravel()])
    assert np.array_equal(np.sort(idx), np.arange(lay.n))            # every index used exactly once
    assert lay.n == NX * (N + 1) + NU * len(nodes) + (3 * N if with_c else 0)
    rng = np.random.default_rng(0)
    X, U = rng.normal(size=(NX, N + 1)), rng.normal(size=(NU, len(nodes)))
    C = rng.normal(size=(3, N)) if with_c else None
    X2, U2, C2 = lay.unpack(lay.pack(X, U, C))
    assert np.array_equal(X, X2) and np.array_equal(U, U2)
    if with_c:
        assert np.array_equal(C, C2)
    k = 3                                                              # node-major: X_k before u_k before c_k
    assert lay.iX[-1, k] < lay.iU[0, k - (0 if scheme == "lgvi" else 1)]


def test_layout_pack_rejects_missing_cayley():
    lay = NLPLayout(3, range(4), True)
    with pytest.raises(ValueError, match="Cayley"):
        lay.pack(np.zeros((NX, 4)), np.zeros((NU, 4)))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_stage_layout_order_and_lifting(scheme):
    N = 5
    lay = StageLayout(N, scheme)
    ns = NX + (NU if scheme == "lgvi" else 0)
    assert lay.ns == ns and lay.nq == NU + 3 and lay.n == N * (ns + lay.nq) + ns
    for k in range(N + 1):                                             # [s_0, q_0, s_1, ..., s_N]
        assert lay.iX[0, k] == k * (ns + lay.nq)
    idx = np.concatenate([lay.iX.ravel(), lay.iU.ravel(), lay.iC.ravel()] +
                         ([lay.iUp.ravel()] if lay.iUp is not None else []))
    assert np.array_equal(np.sort(idx), np.arange(lay.n))
    rng = np.random.default_rng(0)
    X, U, C = rng.normal(size=(NX, N + 1)), rng.normal(size=(NU, len(lay.control_nodes))), rng.normal(size=(3, N))
    X2, U2, C2 = lay.unpack(lay.pack(X, U, C))
    assert np.array_equal(X, X2) and np.array_equal(U, U2) and np.array_equal(C, C2)


# ------------------------------------------------------------------------ guesses
def test_rollout_guess_satisfies_dynamics():
    p = problem("e3", 50, "lgvi")
    g = starts.rollout(p)
    X1 = np.array(p.disc.step_given_c.map(p.N)(g.X[:-1].T, g.C.T, np.zeros((p.disc.nw, p.N)), p.h)[0]).T
    assert np.abs(X1 - g.X[1:]).max() <= 1e-13


@pytest.mark.parametrize("name", ["e3", "e4"])
def test_interpolation_guess_endpoints_orthogonality_and_arc(name):
    p = problem(name, 40, "lgvi")
    g = starts.interpolation(p)
    assert np.abs(g.X[0] - p.X0).max() <= 1e-12 and np.abs(g.X[-1] - p.Xd).max() <= 1e-12
    orth, det = orthogonality_error(unpack_states(g.X).R)
    assert orth.max() <= 1e-13 and det.max() <= 1e-13
    r = np.linalg.norm(unpack_states(g.X).x, axis=1)                  # an arc of radius 1, not the chord
    assert np.abs(r - 1.0).max() <= 1e-12


# --------------------------------------------------------------------- E3 / E4
def _check_solution(s, tol_err=1e-8):
    assert s.result is se3ocp.Result.converged and s.stats["solver_status"] == "Solve_Succeeded", s.message
    assert s.terminal_error <= tol_err, s.terminal_error
    orth = s.trajectory.orthogonality()
    assert orth["max_orthogonality_error"] <= 1e-12 and orth["max_determinant_error"] <= 1e-12
    assert np.isfinite(s.cost) and s.cost > 0
    assert s.controls.shape == (6, s.N + 1 if s.scheme == "lgvi" else s.N)
    assert s.costates.shape == (s.N, 12) and s.trajectory.X.shape == (s.N + 1, 18)
    assert s.stats["kkt_tol"] <= 1e-10


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_small_examples_converge(name, scheme):
    s = solved(name, 100, scheme)
    _check_solution(s)
    Xs, _ = s.problem.disc.simulate(s.trajectory.X[0], s.controls, s.h, s.N)   # the trajectory is the re-simulation
    assert np.array_equal(Xs, s.trajectory.X)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_costates_satisfy_discrete_necessary_conditions(scheme):
    """lambda_{k-1} = A_k^T lambda_k (eq. 28) and stationarity in the controls (eqs. 26-27), to 1e-9 relative."""
    s = solved("e4", 100, scheme)
    p = s.problem
    d, X, lam = p.disc, s.trajectory.X, s.costates
    A, B = (np.array(M) for M in d.variation.map(p.N)(X[:-1].T, d.stage_controls(s.controls), p.h))
    A, B = np.stack(np.split(A, p.N, axis=1)), np.stack(np.split(B, p.N, axis=1))
    adj = np.stack([A[k].T @ lam[k] for k in range(1, p.N)])
    assert np.abs(adj - lam[:-1]).max() <= 1e-9 * np.abs(lam).max()
    om = quadrature_weights(p.scheme, p.N, p.h)
    Wu = p.control.W @ s.controls * om[None, :]
    G = Wu.copy()
    for k in range(p.N):
        if scheme == "first_order":
            G[:, k] += B[k].T @ lam[k]
        else:
            G[:, k] += B[k][:, :6].T @ lam[k]
            G[:, k + 1] += B[k][:, 6:].T @ lam[k]
    assert np.abs(G).max() <= 1e-9 * np.abs(Wu).max()
    if scheme == "first_order":   # u_{k+1} = -W^-1 [lambda^2_k; lambda^4_k]
        u = -np.linalg.solve(p.control.W, np.r_[lam[:, 3:6].T, lam[:, 9:12].T])
        assert np.abs(u - s.controls).max() <= 1e-9 * np.abs(s.controls).max()


def test_interpolation_guess_reaches_same_optimum():
    a = solved("e3", 100, "lgvi")
    b = solved("e3", 100, "lgvi", initial_guess="interpolate")
    _check_solution(b)
    assert b.stats["initial_guess"] == "interpolate" and abs(a.cost - b.cost) <= 1e-9 * a.cost


def test_cayley_variables_off_gives_same_optimum():
    a = solved("e4", 30, "first_order")
    b = solved("e4", 30, "first_order", cayley_variables=False)
    _check_solution(a)
    _check_solution(b)
    assert not b.stats["cayley_variables"] and abs(a.cost - b.cost) <= 1e-9 * a.cost


def test_badly_scaled_weights_converge_small():
    """W_m = I instead of 1e4 I (docs/mathematics.md §9): Solve_Succeeded at tol 1e-8."""
    s = solved("e3", 100, "lgvi", ("control.weights.moment=1.0",), tol=1e-8)
    assert s.converged and s.stats["solver_status"] == "Solve_Succeeded", s.message
    assert s.terminal_error <= 1e-8 and s.trajectory.orthogonality()["max_orthogonality_error"] <= 1e-12


def test_progress_records_and_history():
    recs = []
    s = se3ocp.solve(maneuver("e4", 20, "first_order"), progress=recs.append)
    assert s.converged, s.message
    assert len(recs) >= s.iterations and {r.method for r in recs} == {"direct"}
    assert all(isinstance(r, se3ocp.Iterate) and np.isfinite(r.cost) and r.residual >= 0 for r in recs)
    assert len(s.history) == s.iterations + 1 and s.history[-1].residual <= 1e-9


def test_a_kept_solver_keeps_its_progress_callback():
    """Two solvers on one NLP (the same Problem, IPOPT options that differ), then the first reused: every solve
    converges to the same cost (1e-12 relative) and reports each of its iterations.  Each solver's callback is kept
    with the NLP: when one attribute held it, the second solver's replaced the first's, and the first, reused, stopped
    at its first iteration ("Callback object has been deleted")."""
    p = maneuver("e3", 20, "lgvi").problem
    runs = []
    for tol in (1e-10, 1e-9, 1e-10):
        recs = []
        s = se3ocp.solve(p, tol=tol, progress=recs.append)
        assert s.converged, s.message
        assert len(recs) >= s.iterations > 5
        runs.append(s.cost)
    assert max(runs) - min(runs) <= 1e-12 * abs(runs[0])


def test_failure_is_data():
    s = solved("e3", 20, "lgvi", max_iter=2)
    assert s.result is se3ocp.Result.max_iterations and not s.converged
    assert s.stats["solver_status"] == "Maximum_Iterations_Exceeded" and "did not converge" in s.message
    with pytest.raises(se3ocp.SolveError, match="max_iterations"):
        se3ocp.solve(maneuver("e3", 20, "lgvi"), max_iter=2, throw=True)


@pytest.mark.parametrize("change, field", [({"solver": "snopt"}, "solver"), ({"initial_guess": "nonsense"}, "initial_guess"),
                                           ({"max_iter": 1e30}, "max_iter"), ({"options": {"mu_init": None}}, "options.mu_init"),
                                           ({"options": {"linear_solver": "ma57"}}, "options.linear_solver"),
                                           ({"options": {"no_such_option": 1}}, "options.no_such_option")])
def test_bad_options_are_rejected_before_any_solve(change, field):
    """Options are checked when they are made (the same check for Python and maneuver files)."""
    with pytest.raises(OptionError) as e:
        DirectOptions().replace(**change)
    assert e.value.field == field


# ------------------------------------------------------------------------ fatrop
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_fatrop_equals_ipopt(name, scheme):
    """fatrop on the same blocks in stage order: cost to 1e-8, controls 1e-6, costates 1e-5 relative."""
    ip, fa = solved(name, 40, scheme), solved(name, 40, scheme, solver="fatrop")
    assert ip.converged and fa.converged, (ip.message, fa.message)
    assert fa.solver == "fatrop" and fa.stats["fatrop_fallback"] is False, fa.message
    assert abs(fa.cost - ip.cost) / ip.cost <= 1e-8
    assert np.abs(fa.controls - ip.controls).max() / np.abs(ip.controls).max() <= 1e-6
    assert np.abs(fa.costates - ip.costates).max() / np.abs(ip.costates).max() <= 1e-5
    assert fa.terminal_error <= 1e-9


def test_fatrop_failure_falls_back_to_ipopt():
    s = se3ocp.solve(maneuver("e3", 20, "first_order"), solver="fatrop", fatrop_options={"max_iter": 1})
    assert s.converged and s.solver == "ipopt"
    assert s.stats["fatrop_fallback"] is True and "fatrop did not converge" in s.message
    assert "IPOPT fallback" in s.message and s.stats["fatrop_status"] != "Solve_Succeeded"


# ------------------------------------------------------------------------- slow
@pytest.mark.slow
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_full_size_examples(name, scheme):
    _check_solution(solved(name, 500, scheme))


@pytest.mark.slow
def test_badly_scaled_weights_converge_full():
    s = solved("e3", 500, "lgvi", ("control.weights.moment=1.0",), tol=1e-8)
    assert s.converged and s.stats["solver_status"] == "Solve_Succeeded", s.message
    assert s.terminal_error <= 1e-8 and s.trajectory.orthogonality()["max_orthogonality_error"] <= 1e-12


def _slope(costs):
    return np.log2((costs[0] - costs[1]) / (costs[1] - costs[2]))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_cost_order_lgvi_is_two(name):
    """Fitted order of the optimal cost in h (N = 100, 200, 400): >= 1.8 (measured 1.998 / 2.002)."""
    assert _slope([solved(name, N, "lgvi").cost for N in (100, 200, 400)]) >= 1.8


@pytest.mark.slow
def test_cost_order_first_order_is_one():
    """E4 (tumbling start): slope ~1.  (E3 shows 2.0 for this scheme: its O(h) cost term cancels.)"""
    assert 0.8 <= _slope([solved("e4", N, "first_order").cost for N in (100, 200, 400)]) <= 1.4
