"""Single shooting of the relaxed impulsive problem (``transcription: single_shooting``, the default): the six
unknowns p with exact first and second derivatives through the rollout, and Newton's method on the
constraint manifold (see :func:`relaxed_reduced`)."""
from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ...geometry.state import cayley_vectors
from ...compile import codegen
from ...geometry.state import NX, split_state, unpack_states
from ...dynamics.lgvi import CAYLEY_TOL, per_discretization
from ...options import DirectOptions
from ...ocp import Problem, orbit_conditions
from ...outcome import Iterate, Result
from .relaxed import relaxed_unknown_scales
from .sensitivity import P_ROWS_X
from .tpbvp import ImpulsiveSettings, simulate_momenta


@per_discretization
def _free_step_derivatives(disc, jit: bool) -> tuple:
    """Per-step derivative Functions of the free step F (u = 0) in ambient coordinates (R as 9 numbers).

    ``free_fwd``  (S[18x6], X[18], c0[3], h) -> dF/dX S           (forward sensitivity, 6 directions)
    ``free_adj``  (mu[18], X[18], c0[3], h)  -> dF/dX^T mu        (adjoint)
    ``free_hess`` (X[18], c0[3], h, mu[18], S[18x6]) -> S^T d2(mu^T F)/dX2 S (6 x 6)

    All differentiate ``disc.step_seeded`` at the step's Cayley root c0 (its first to third derivatives are the
    solved step's, lgvi.py); X_N(p) = F o ... o F (X_0(p)) with X_0 affine in p, so the ambient chain rule is exact.
    jit: compiled to C (codegen.compiled_libraries; interpreted while the background builds them).  Returns
    (fwd, adj, hess, the libraries still being built or None).
    """
    X, c0, h = ca.SX.sym("X", NX), ca.SX.sym("c0", 3), ca.SX.sym("h")
    mu, S, q = ca.SX.sym("mu", NX), ca.SX.sym("S", NX, 6), ca.SX.sym("q", 6)
    w0 = ca.DM.zeros(disc.nw)
    F = disc.step_seeded(X, w0, h, c0)
    fwd = ca.Function(f"{disc.scheme}_free_fwd", [S, X, c0, h], [ca.jtimes(F, X, S)], ["S", "X", "c0", "h"], ["S1"])
    adj = ca.Function(f"{disc.scheme}_free_adj", [mu, X, c0, h], [ca.jtimes(F, X, mu, True)],
                      ["mu", "X", "c0", "h"], ["mu0"])
    Hq = ca.hessian(ca.dot(mu, disc.step_seeded(X + ca.mtimes(S, q), w0, h, c0)), q)[0]
    hess = ca.Function(f"{disc.scheme}_free_hess", [X, c0, h, mu, S], [ca.substitute(Hq, q, ca.DM.zeros(6))],
                       ["X", "c0", "h", "mu", "S"], ["T"])
    libs = [codegen.Library(f.name(), (f,), cse=True) for f in (fwd, adj, hess)]
    if jit:   # one library each: -O1 when cached, else interpreted while the background builds them (codegen)
        (fwd,), (adj,), (hess,) = codegen.compiled_libraries(libs, quick=codegen.QUICK_CFLAGS)
    return fwd, adj, hess, (libs if jit and codegen.last_provisional else None)


@per_discretization
def _rollout_derivatives(disc, N: int, jit: bool) -> tuple[ca.Function, ca.Function]:
    """Sweeps over N free steps along given nodes X (18 x N, nodes 0..N-1) and Cayley roots (3 x N).

    ``sens`` (X, roots, h, S0[18x6]) -> S_N = dX_N/dX_0 S0
    ``hess`` (X, roots, h, S0, muN[18]) -> sum_k S_k^T d2(mu_{k+1}^T F)/dX2 S_k, with S_{k+1} = A_k S_k
             and mu_k = A_k^T mu_{k+1} (A_k = dF/dX at node k), mu_N = muN.
    """
    fwd, adj, hess, pending = _free_step_derivatives(disc, jit)
    sens, hfn = _sweeps(disc, N, fwd, adj, hess)
    if pending is None:
        return sens, hfn
    built: dict = {}    # the interpreted-first policy: both move to the compiled steps as they arrive

    def make(loaded, paths, i):   # one build per set of arrived libraries (codegen.Switch), shared by both
        if paths not in built:
            built[paths] = _sweeps(disc, N, *(f for (f,) in loaded))
        return built[paths][i]

    return tuple(codegen.Switch(f, pending, functools.partial(make, i=i)) for i, f in enumerate((sens, hfn)))


def _sweeps(disc, N: int, fwd, adj, hess) -> tuple[ca.Function, ca.Function]:
    """``sens`` and ``hess`` of :func:`_rollout_derivatives` from the per-step Functions."""
    X, roots, h = ca.MX.sym("X", NX, N), ca.MX.sym("roots", 3, N), ca.MX.sym("h")
    S0, muN = ca.MX.sym("S0", NX, 6), ca.MX.sym("muN", NX)
    H = ca.repmat(h, 1, N)
    S = fwd.mapaccum(f"{disc.scheme}_free_fwd_acc{N}", N)(S0, X, roots, H)        # S_1 .. S_N
    sens = ca.Function(f"{disc.scheme}_free_sens{N}", [X, roots, h, S0], [S[:, -6:]], ["X", "roots", "h", "S0"], ["SN"])
    rev = list(range(N - 1, -1, -1))
    mu = adj.mapaccum(f"{disc.scheme}_free_adj_acc{N}", N)(muN, X[:, rev], roots[:, rev], H)  # mu_{N-1} .. mu_0
    mu1 = ca.horzcat(mu[:, rev[1:]], muN)                                                     # mu_1 .. mu_N
    Sk = ca.horzcat(S0, S[:, : 6 * (N - 1)])                                                  # S_0 .. S_{N-1}
    T = hess.map(N)(X, roots, H, mu1, Sk)
    Tsum = ca.mtimes(T, ca.repmat(ca.DM.eye(6), N, 1))
    hfn = ca.Function(f"{disc.scheme}_free_hess{N}", [X, roots, h, S0, muN], [Tsum], ["X", "roots", "h", "S0", "muN"],
                      ["T"])
    return sens, hfn


class ReducedRelaxed:
    """The relaxed problem in the six unknowns p only (single shooting), in scaled variables y = p / s_y.

    f(y) = (|p_gamma - gamma_0| + |p_Pi - Pi_0| + |gamma_N^+(x_N) - gamma_N| + |Pi_N|) / s_f,
    c(y) = C(X_N(p)) / (r_d, r_d, 1, 1), X_N(p) the free rollout from X_0^+.  Exact derivatives: S_k = dX_k/dy
    (18 x 6, ambient) by S_{k+1} = A_k S_k, S_0 = the momentum columns (S_N in tangent coordinates is
    Phi[:, (gamma_0, Pi_0)] diag(s_y)).  The Hessian of L = f + lam^T c is the second-order adjoint
    S_N^T d2l/dX_N2 S_N + sum_k S_k^T d2(mu_{k+1}^T F)/dX2 S_k + d2f_0/dy2 with mu_N = dl/dX_N
    and mu_k = A_k^T mu_{k+1} (l = the X_N-dependent part of L; f_0 the initial-impulse part).
    """

    def __init__(self, problem: Problem, jit: bool = True):
        self.problem = problem
        disc, N = problem.disc, problem.N
        self.sy = relaxed_unknown_scales(problem)
        self.sf = float(self.sy[0])
        rd = float(problem.terminal.radius)
        self.sc = np.array([rd, rd, 1.0, 1.0])
        a0 = unpack_states(problem.X0)
        XN, y, lam = ca.SX.sym("XN", NX), ca.SX.sym("y", 6), ca.SX.sym("lam", 4)
        C, gp, Pp = orbit_conditions(XN, problem.terminal, problem.model.mass, problem.model.mu)
        _, gN, _, PN = split_state(XN)
        p = y * ca.DM(self.sy)
        f0 = (ca.norm_2(p[:3] - ca.DM(a0.gamma[0])) + ca.norm_2(p[3:] - ca.DM(a0.Pi[0]))) / self.sf
        fN = (ca.norm_2(gp - gN) + ca.norm_2(Pp - PN)) / self.sf
        c = C / ca.DM(self.sc)
        ell = fN + ca.dot(lam, c)
        self.value_fn = ca.Function("reduced_value", [XN, y], [f0 + fN, c])
        self.first_fn = ca.Function("reduced_first", [XN, y], [ca.gradient(fN, XN), ca.jacobian(c, XN),
                                                              ca.gradient(f0, y)])
        self.second_fn = ca.Function("reduced_second", [XN, y, lam], [ca.hessian(ell, XN)[0], ca.hessian(f0, y)[0]])
        self.sens_fn, self.hess_fn = _rollout_derivatives(disc, N, jit)
        self.S0 = np.zeros((NX, 6))
        self.S0[P_ROWS_X, np.arange(6)] = self.sy

    def p(self, y: np.ndarray) -> np.ndarray:
        return self.sy * y

    def rollout(self, y: np.ndarray) -> np.ndarray:
        """Node states (N+1, 18); NaN if a Cayley solve failed."""
        X, res = simulate_momenta(self.problem, self.p(y))
        return X if res <= CAYLEY_TOL else np.full_like(X, np.nan)

    def value(self, X: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
        f, c = self.value_fn(X[-1], y)
        return float(f), np.array(c).ravel()

    def first(self, X: np.ndarray, y: np.ndarray) -> dict:
        """grad f (6,), Jacobian of c (4 x 6), S_N = dX_N/dy (18 x 6) and the Cayley roots."""
        roots = cayley_vectors(X).T
        SN = np.array(self.sens_fn(X[:-1].T, roots, self.problem.h, self.S0))
        dfN, dc, df0 = (np.array(v) for v in self.first_fn(X[-1], y))
        return {"g": SN.T @ dfN.ravel() + df0.ravel(), "Jc": dc @ SN, "SN": SN, "roots": roots,
                "dfN": dfN.ravel(), "dc": dc}

    def hessian(self, X: np.ndarray, y: np.ndarray, lam: np.ndarray, d1: dict) -> np.ndarray:
        """Exact Hessian of L = f + lam^T c in y (6 x 6), the second-order adjoint of the class docstring."""
        SN = d1["SN"]
        muN = d1["dfN"] + d1["dc"].T @ lam
        HX, H0 = (np.array(v) for v in self.second_fn(X[-1], y, lam))
        T = np.array(self.hess_fn(X[:-1].T, d1["roots"], self.problem.h, self.S0, muN))
        H = SN.T @ HX @ SN + H0 + T
        return 0.5 * (H + H.T)


def _null_space(Jc: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the null space of a full-row-rank Jc (m x n) -> (n x (n - m))."""
    Q, _ = np.linalg.qr(Jc.T, mode="complete")
    return Q[:, Jc.shape[0]:]


class _Point:
    """A point y of the reduced problem with its rollout, values and (lazily) first derivatives."""

    def __init__(self, red: ReducedRelaxed, y: np.ndarray, X: np.ndarray | None = None):
        self.red, self.y = red, y
        self.X = red.rollout(y) if X is None else X
        self.f, self.c = red.value(self.X, y)
        self._d1 = None

    @property
    def ok(self) -> bool:
        return bool(np.isfinite(self.f) and np.all(np.isfinite(self.c)))

    @property
    def d1(self) -> dict:
        if self._d1 is None:
            self._d1 = self.red.first(self.X, self.y)
        return self._d1


def _project(pt: _Point, tol: float, max_iter: int, damped: bool) -> tuple[_Point, int, bool]:
    """Minimum-norm Newton onto c(y) = 0: y <- y - Jc^T (Jc Jc^T)^-1 c(y), Jc fresh at every iterate.  damped:
    Armijo backtracking on |c|_2 (from afar); otherwise an iterate must halve |c|_2 or the projection fails.
    Returns (point, rollouts, success)."""
    n = 0
    for _ in range(max_iter + 1):
        if not pt.ok:
            return pt, n, False
        e = float(np.linalg.norm(pt.c))
        if np.abs(pt.c).max() <= tol:
            return pt, n, True
        Jc = pt.d1["Jc"]
        dy = -Jc.T @ np.linalg.solve(Jc @ Jc.T, pt.c)
        a = 1.0
        while True:
            trial = _Point(pt.red, pt.y + a * dy)
            n += 1
            et = float(np.linalg.norm(trial.c)) if trial.ok else np.inf
            if et <= (1.0 - 1e-4 * a) * e if damped else et <= 0.5 * e:
                break
            if not damped or a < 1e-6:
                return trial, n, False
            a *= 0.5
        pt = trial
    return pt, n, bool(pt.ok and np.abs(pt.c).max() <= tol)


@dataclass
class ReducedResult:
    """The outcome of :func:`relaxed_reduced`: the momenta p, the result, iterations, history, rollouts, build and
    solve time, the least-squares multipliers of the conditions (physical units; None if never computed) and the
    final rollout's terminal state."""

    p: np.ndarray
    result: Result
    iterations: int
    history: list[Iterate]
    rollouts: int
    build_s: float
    solve_s: float
    multipliers: list | None
    XN: np.ndarray


def _reduced_newton_direction(red: ReducedRelaxed, pt: _Point, lam: np.ndarray, Z: np.ndarray, rg: np.ndarray,
                              max_step: float) -> np.ndarray:
    """d = -Z (Z^T H Z + delta I)^-1 Z^T g, Z^T H Z shifted to positive definite if it is not, capped at max_step."""
    Hr = Z.T @ red.hessian(pt.X, pt.y, lam, pt.d1) @ Z
    ev = np.linalg.eigvalsh(Hr)
    delta = 0.0 if ev[0] > 1e-12 * max(1.0, ev[-1]) else -ev[0] + 1e-4 * max(1.0, abs(ev[-1]))
    d = -Z @ np.linalg.solve(Hr + delta * np.eye(Hr.shape[0]), rg)
    return d * min(1.0, max_step / max(np.abs(d).max(), 1e-300))


def _line_search(red: ReducedRelaxed, pt: _Point, d: np.ndarray, lam: np.ndarray,
                 s: ImpulsiveSettings) -> tuple[_Point, float, bool, int]:
    """Halve alpha until the projected trial y + alpha d decreases f + lam^T c by Armijo's rule on g^T d (s.armijo;
    the projection's s.projection_*): (trial, alpha, accepted, rollouts)."""
    D = float(pt.d1["g"] @ d)
    alpha, rollouts, trial = 1.0, 0, pt
    while alpha >= 1e-8:
        trial, n, ok = _project(_Point(red, pt.y + alpha * d), s.projection_tol, s.projection_max_iter, damped=False)
        rollouts += n + 1
        # compare f + lam^T c (the trial and pt satisfy c = 0 only to projection_tol, which moves f by
        # lam^T c, more than the last Newton steps gain); allow 10 ulp of |f| for round-off
        slack = 10 * np.finfo(float).eps * abs(pt.f)
        if ok and trial.f + lam @ trial.c <= pt.f + lam @ pt.c + s.armijo * alpha * D + slack:
            return trial, alpha, True, rollouts
        alpha *= 0.5
    return trial, alpha, False, rollouts


def relaxed_reduced(problem: Problem, p0: np.ndarray, options: DirectOptions, progress,
                    s: ImpulsiveSettings) -> ReducedResult:
    """Single shooting of the relaxed case in the six unknowns p from p0: Newton's method on the constraint manifold
    c(y) = 0 (a feasible-point SQP; the terminal conditions are too curved in p for a plain l1-merit SQP).

    At a feasible y: d = -Z (Z^T H Z)^-1 Z^T g, Z an orthonormal basis of null(Jc), H the exact Hessian of the
    Lagrangian at the least-squares multipliers (:class:`ReducedRelaxed`; shifted to positive definite if it is not),
    capped at s.max_step (scaled); a trial y + alpha d is projected back onto c = 0 (:func:`_project`) and accepted
    by Armijo on g^T d, else alpha is halved.  A start off the constraint set is projected first.  Converged when
    |g + Jc^T lambda|_inf <= tol (the scaled reduced gradient) at |c|_inf <= 1e-12.  Returns a :class:`ReducedResult`.
    """
    t_build = time.perf_counter()
    red = ReducedRelaxed(problem, jit=bool(options.jit))
    build_s = time.perf_counter() - t_build
    t0 = time.perf_counter()
    tol, max_iter = float(options.tol), int(options.max_iter)
    history: list[Iterate] = []
    pt = _Point(red, np.asarray(p0, dtype=float) / red.sy)
    pt, rollouts, ok = _project(pt, s.projection_tol, 50, damped=True)
    rollouts += 1
    result = Result.max_iterations if ok else Result.infeasible
    for it in range(max_iter + 1 if ok else 0):
        g, Jc = pt.d1["g"], pt.d1["Jc"]
        lam = np.linalg.lstsq(Jc.T, -g, rcond=None)[0]
        Z = _null_space(Jc)
        inf_du = float(np.abs(g + Jc.T @ lam).max())
        rec = Iterate(iteration=it, cost=pt.f * red.sf, residual=float(np.abs(pt.c).max()), dual=inf_du, phase="sqp",
                      elapsed_s=time.perf_counter() - t0)
        if inf_du <= tol or it == max_iter:
            result = Result.converged if inf_du <= tol else result
            history.append(rec)
            if progress and inf_du <= tol:
                progress(rec)
            break
        d = _reduced_newton_direction(red, pt, lam, Z, Z.T @ g, s.max_step)
        trial, alpha, accepted, n = _line_search(red, pt, d, lam, s)
        rollouts += n
        rec = dataclasses.replace(rec, step=alpha)
        history.append(rec)
        if progress:
            progress(rec)
        if not accepted:
            result = Result.line_search_failed
            break
        pt = trial
    multipliers = None
    if pt._d1 is not None:
        lam = np.linalg.lstsq(pt.d1["Jc"].T, -pt.d1["g"], rcond=None)[0]
        multipliers = (lam * red.sf / red.sc).tolist()
    return ReducedResult(red.p(pt.y), result, max(len(history) - 1, 0), history, rollouts, build_s,
                         time.perf_counter() - t0, multipliers, pt.X[-1])
