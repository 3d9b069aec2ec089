"""Saddles of the NLP (docs/mathematics.md §10, "Saddles"): the second-order check of a converged point
(transcription/nlp/curvature.py) and the strategy that leaves a saddle (transcription/strategy/saddle.py), on the
normalized one-engine raise (configs/one_engine_raise.yaml): a start that keeps the body's initial roll turns it
about its largest principal axis and ends at a saddle; the optimum rolls the body about its engine first.  Also, on
the same turning body, the warm start resampled onto another LGVI grid keeps the Cayley rows (implied momenta)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl

from se3ocp.problems.api import load, solve
from se3ocp.transcription.geometry.so3 import log_so3_any
from se3ocp.transcription.geometry.state import pack_state, unpack_states
from se3ocp.transcription.methods.direct.solve import Direct, transcription
from se3ocp.transcription.objectives.effort import EffortStrategy
from se3ocp.transcription.outcome import Result
from se3ocp.transcription.results.start import Origin, Start
from se3ocp.transcription.strategy import starts
from se3ocp.transcription.strategy.core import Composed

from test_kepler import flown_miss

CONFIG = "configs/one_engine_raise.yaml"
NORMAL = np.array([0.0, 0.0, 1.0])          # the orbit normal of the raise


def small(N=40):
    """The raise on the LGVI at N steps: the saddle appears there too, and the solves take about a second."""
    return load(CONFIG, ["discretization=lgvi", f"horizon.N={N}"])


class RelaxedOnly(Composed):
    """The effort strategy's first start alone (the aimed relaxed solution), with ``escape`` its Escape's fields."""

    def __init__(self, **escape):
        self.escape = escape

    def compose(self, problem, options, start=None):
        return EffortStrategy(escape=self.escape).compose(problem, options, start).strategies[0]


def independent_start(man, axis_on_normal: int) -> Start:
    """A start made here, not by the strategy: the orbit-following interpolation's path, the engine (body x) along
    the velocity, body axis ``axis_on_normal`` (1: y, 2: z) on the orbit normal, the thrust 10 everywhere."""
    p = man.problem
    g = starts.make("orbit", p)
    s = unpack_states(g.X)
    v = s.gamma / np.linalg.norm(s.gamma, axis=1)[:, None]
    n = np.repeat(NORMAL[None], len(v), 0)
    R = (np.stack([v, n, np.cross(v, n)], axis=2) if axis_on_normal == 1 else
         np.stack([v, np.cross(n, v), n], axis=2))
    J = np.asarray(p.disc.J)
    Om = np.array([log_so3_any(R[k].T @ R[k + 1]) / p.h for k in range(len(R) - 1)])
    Pi = np.vstack([Om @ J.T, (Om @ J.T)[-1:]])
    U = g.U.copy()
    U[0] = 10.0
    return Start(t=g.t, X=pack_state(s.x, s.gamma, R, Pi), U=U, scheme=g.scheme, origin=Origin.interpolate)


def dense_least_curvature(tr, x, lam_g, tol=1e-7):
    """The least eigenvalue of Z^T H Z, Z an orthonormal basis of the active constraints' null space, by dense
    linear algebra (scipy.linalg.null_space): the independent formulation of the sparse projected Lanczos."""
    fns = tr.nlp.derivative_functions()
    g, Jg = fns["jac_g"](x, [])
    g, Jg = np.asarray(g).ravel(), np.asarray(Jg.full())
    Hu = np.asarray(fns["hess_lag"](x, [], 1.0, lam_g).full())
    H = Hu + np.triu(Hu, 1).T
    lbg, ubg = np.asarray(tr.nlp.lbg, float), np.asarray(tr.nlp.ubg, float)
    lbx, ubx = np.asarray(tr.lbx, float), np.asarray(tr.ubx, float)

    def near(v, b):
        with np.errstate(invalid="ignore"):
            return np.isfinite(b) & (np.abs(v - b) <= tol * (1 + np.abs(b)))

    rows = near(g, lbg) | near(g, ubg)
    free = ~(near(x, lbx) | near(x, ubx))
    Z = sl.null_space(Jg[rows][:, free])
    return float(np.linalg.eigvalsh(Z.T @ H[np.ix_(free, free)] @ Z)[0])


def test_least_curvature_is_the_dense_reduced_hessians_least_eigenvalue():
    """At the aimed relaxed start's end (N = 40, the escape off): IPOPT's Hessian was regularized at its last
    iterations, the sparse check's least curvature is negative and equals the dense reduced Hessian's least
    eigenvalue to 1e-6 (Lanczos' tolerance); at the optimum the escape reaches, it is >= -1e-9 of the largest."""
    man = small()
    saddle = solve(man, strategy=RelaxedOnly(rounds=0), continuous_check=False)
    assert saddle.result in (Result.acceptable, Result.converged)
    assert saddle.history[-1].regularization > 0
    method = Direct(man.direct)
    tr, _ = transcription(saddle.problem, man.direct)
    for sol, negative in ((saddle, True), (solve(man, continuous_check=False), False)):
        c = method.curvature(sol.problem, sol)
        pt = sol.warm.point
        dense = dense_least_curvature(tr, pt.x, pt.lam_g)
        print(sol.cost, c.least, dense, c.largest)
        assert c.saddle(1e-6) == negative
        if negative:
            assert c.least == pytest.approx(dense, rel=1e-6)
            assert np.linalg.norm(c.direction) == pytest.approx(1.0, rel=1e-12)
        else:
            assert c.least >= -1e-9 * c.largest and dense >= -1e-9 * c.largest


def test_a_saddle_is_left_for_the_optimum_an_independent_start_finds():
    """N = 40 on the LGVI: the default strategy leaves the saddle its aimed start ends at (the trace names the solve
    from it, the message says so) and converges to the cost an independent start finds (body y on the orbit normal
    from the start; 38.5982582139) to 1e-9; the same start with body z on the normal converges first to another
    saddle (40.98), which the strategy also leaves for that cost.  The optimum rolls the body until it turns about y
    (0.03), on the orbit normal in the middle half of the raise; the saddle turns it about z (0.04)."""
    man = small()
    sol = solve(man, continuous_check=False)
    assert sol.result is Result.converged
    assert any(a.label.startswith("from the saddle") for a in sol.trace)
    assert "left a saddle of the NLP" in sol.message
    indep = solve(man, warm_start=independent_start(man, 1), continuous_check=False)
    assert indep.result is Result.converged
    assert sol.cost == pytest.approx(indep.cost, rel=1e-9)
    other = solve(man, warm_start=independent_start(man, 2), continuous_check=False)
    assert other.result is Result.converged and other.cost == pytest.approx(indep.cost, rel=1e-9)
    assert other.trace[0].cost > 1.05 * indep.cost                        # the first solve's saddle, 40.98
    assert len(sol.stats["saddle_escapes"]) >= 1
    R = unpack_states(sol.trajectory.X).R
    on_normal = np.abs(np.einsum("kij,i->kj", R, NORMAL))                # |n . body axis j| at each node
    mid = slice(len(R) // 4, 3 * len(R) // 4)
    print(on_normal[mid].mean(axis=0), on_normal.max(axis=0))
    assert on_normal[mid, 1].mean() > 0.8 and on_normal[mid, 2].mean() < 0.5 and on_normal[:, 1].max() > 0.99


@pytest.mark.slow
def test_one_engine_raise_converges_by_default_at_the_optimum_direct_equals_indirect():
    """The bundled file as written (lgvi_kepler, N = 200), both methods: converged (not acceptable), direct =
    indirect to 1e-8, the cost the independent start reaches to 1e-9 (39.2705432), and flown by the test's own
    integrator within 1 % of the maneuver."""
    man = load(CONFIG)
    out = solve(man, "both")
    d, i = out.direct, out.indirect
    assert d.result is Result.converged and i.result is Result.converged
    assert d.cost == pytest.approx(i.cost, rel=1e-8)
    indep = solve(man, warm_start=independent_start(man, 1), continuous_check=False)
    assert indep.result is Result.converged and d.cost == pytest.approx(indep.cost, rel=1e-9)
    dx, dv, frac = flown_miss(man, d)
    print(d.cost, i.cost, indep.cost, dx, dv, frac)
    assert frac <= 0.01


def test_a_start_resampled_onto_another_lgvi_grid_keeps_the_cayley_rows():
    """A solution fitted onto another number of steps (attitudes along geodesics, momenta linear) breaks the LGVI's
    Cayley equation (9) where the body turns fast; on_grid gives it the angular momenta its attitudes imply
    (Discretization.implied_momenta), so G(c_k) = 0 at every step to round-off (1e-12 of |g|), against more than
    1e-4 for the linear momenta (the one-engine raise, N = 40 -> 97)."""
    from se3ocp.transcription.geometry.so3 import step_cayley_vectors
    from se3ocp.transcription.geometry.state import U_MOMENT
    from se3ocp.transcription.methods.direct.solve import on_grid

    sol = solve(small(), continuous_check=False)
    fine = sol.problem.replace(N=97)
    d, h = fine.disc, fine.h

    def worst(start):
        s = unpack_states(start.X)
        c = step_cayley_vectors(s.R)
        out = 0.0
        for k in range(fine.N):
            M = np.asarray(d.model.forces(s.x[k], s.R[k])[1]).ravel() + start.U[U_MOMENT, k]
            g = h * (s.Pi[k] + h / 2 * M)
            G = np.asarray(d.cayley_residual(c[k], g)).ravel()
            out = max(out, np.linalg.norm(G) / max(np.linalg.norm(g), 1e-300))
        return out

    plain = sol.warm.fit(fine.N, fine.scheme, fine.fractions)[0]
    assert worst(on_grid(fine, sol.warm)) <= 1e-12 < 1e-4 < worst(plain)
