"""Lie group variational integrators on SE(3): the two discretizations of docs/mathematics.md §2-§3, built once per
(model, scheme) as named CasADi SX Functions:

* ``lgvi``        second-order LGVI, eqs. (7)-(11); stage control w_k = [u_k; u_{k+1}] in R^12.
* ``lgvi_kepler`` the second-order LGVI with the central body's Kepler motion flown exactly (§2a): kick by the
                  force less the point-mass term, the exact two-body drift (:mod:`.kepler`), kick; the attitude part
                  is the LGVI's.  Its error scales with the perturbation (thrust, J2, attitude coupling), not with
                  the orbit; stage control as ``lgvi``.  Needs the model's central body (``model.mu``).
* ``first_order`` the paper's modified first-order scheme, eqs. (21)-(25); stage control w_k = u_{k+1} in R^6.

The only implicit part is the Cayley equation (9)/(23), ``G(c) = g + g x c + (g^T c) c - 2 J c = 0``, F_k = cay(c),
solved by a fixed number of Newton iterations unrolled on the graph: the step stays a plain SX expression (mappable,
code-generatable) with the implicit function's derivatives.  Every solved step outputs |G(c)|/|g| (checked against
:data:`CAYLEY_TOL`).

    cayley_residual (c[3], g[3])            -> (G[3])
    cayley_solve    (g[3])                  -> (c[3], res_hist[K+1])   K Newton iterations from (2J)^-1 g
    step_given_c    (X[18], c[3], w[nw], h) -> (X1[18], G[3])          explicit step
    cayley_rhs      (X[18], w[nw], h)       -> (g[3])
    step            (X[18], w[nw], h)       -> (X1[18], res)           solved step
    variation       (X[18], w[nw], h)       -> (A[12x12], B[12xnw])    §4 eq. (18)
    step_seeded     (X, w, h, c0[3])        -> (X1)    two Newton iterations from c0 (derivatives)
    variation_seeded(X, w, h, c0[3])        -> (A, B)  from c0; with c0 the step's Cayley root, equal to variation
    rollout(N)      (X0[18], W[nw x N], h)  -> (X[18 x N], res[1 x N])  mapaccum

``parametric()`` gives them with the model's numbers theta = ``model.parameters`` as last input (one compile per
structure).
"""
from __future__ import annotations

import functools
import inspect
from typing import Any, Callable, Hashable

import casadi as ca
import numpy as np

from ..geometry.state import (NU, NX, NZ, U_FORCE, U_MOMENT, chart, join_state, split_state, tangent_readback,
                              unpack_states)
from ..geometry.so3 import cayley, hat, is_symbolic, step_cayley_vectors
from .kepler import kepler_drift, kepler_force
from .model import BodyModel

SCHEMES = ("lgvi", "lgvi_kepler", "first_order")

#: the order of each scheme's global error in h (the refinement's model, strategy.refine)
ORDER = {"lgvi": 2, "lgvi_kepler": 2, "first_order": 1}


def two_point(scheme: str) -> bool:
    """Whether the scheme's stage control is w_k = [u_k; u_{k+1}] (controls at the N+1 nodes: the LGVIs) rather
    than u_{k+1} alone (first_order)."""
    return scheme != "first_order"

#: the frame the force control u_f is given in: 'inertial' (the paper's case) or 'body' (engines fixed in
#: the body; the applied inertial force is R u_f at the node the control belongs to, docs/mathematics.md §14)
FORCE_FRAMES = ("inertial", "body")

#: unrolled Newton iterations in the Cayley solve: from (2J)^-1 g, s = h|Pi|/lambda_min(J) <= 0.999 needs at most 7
#: to reach |G|/|g| <= 1e-12 in every direction (tests/test_lgvi.py); at s >= 1 (the fold, docs/mathematics.md §2)
#: the residual output reports the failure
DEFAULT_NEWTON_ITERS = 8

#: a step whose Cayley equation is left with a relative residual |G|/|g| above this is not a step of
#: the scheme (the rotation per step is too large for h): every method and the simulator use this bound
CAYLEY_TOL = 1e-10


def _solve3(A, b):
    """Solve a 3x3 system by the adjugate (exact SX expression, no pivoting)."""
    a = A
    cof = ca.vertcat(
        ca.horzcat(a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1], a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2], a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]),
        ca.horzcat(a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2], a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0], a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]),
        ca.horzcat(a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0], a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1], a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]),
    )
    det = a[0, 0] * cof[0, 0] + a[0, 1] * cof[1, 0] + a[0, 2] * cof[2, 0]
    return ca.mtimes(cof, b) / det


def per_discretization(build: Callable) -> Callable:
    """Decorator: ``build(disc, *args)`` is called once per Discretization and arguments (hashable: flags,
    sizes), its result kept on the Discretization (:meth:`Discretization.cached`), so that what is built for
    a scheme and a model lives exactly as long as they do."""
    signature = inspect.signature(build)

    @functools.wraps(build)
    def get(disc: "Discretization", *args, **kwargs):
        disc = getattr(disc, "base", disc)   # a WithTheta: what is kept is the Discretization's (numbers constant)
        bound = signature.bind(disc, *args, **kwargs)
        bound.apply_defaults()
        key = (build.__module__, build.__qualname__, *list(bound.arguments.values())[1:])
        return disc.cached(key, lambda: build(*bound.args, **bound.kwargs))

    return get


class _StepFunctions:
    """The Cayley solve and the step Functions of one Discretization (module docstring), plus
    ``newton_map (c, g) -> c - (dG/dc)^-1 G``; from the model's numbers as constants, or (``parametric``) with
    theta = ``model.parameters`` as every Function's last input (names suffixed ``_p``)."""

    def __init__(self, disc: "Discretization", parametric: bool = False):
        model, scheme, sfx = disc.model, disc.scheme, "_p" if parametric else ""
        if parametric:
            th = ca.SX.sym("theta", model.parameters.size)
            m, J, inv2J, q = th[0], ca.reshape(th[1:10], 3, 3), ca.reshape(th[10:19], 3, 3), th[19:]
            pforces = model.parametric_forces()
            forces, extra = (lambda x, R: pforces(x, R, q)), [th]
        else:
            m, J, inv2J = model.mass, ca.DM(model.inertia), ca.DM(np.linalg.inv(2 * model.inertia))
            forces, extra = model.forces, []
        names = ["theta"] if parametric else []

        def fn(name, ins, outs, names_in, names_out):
            return ca.Function(name + sfx, ins + extra, outs, names_in + names, names_out)

        c, g = ca.SX.sym("c", 3), ca.SX.sym("g", 3)
        G = g + ca.cross(g, c) + ca.dot(g, c) * c - 2 * ca.mtimes(J, c)
        self.cayley_residual = fn("cayley_residual", [c, g], [G], ["c", "g"], ["G"])
        dG = hat(g) + ca.dot(g, c) * ca.DM.eye(3) + ca.mtimes(c, g.T) - 2 * J
        self.newton_map = fn("cayley_newton_map", [c, g], [c - _solve3(dG, G)], ["c", "g"], ["c1"])
        gnorm = ca.fmax(ca.norm_2(g), 1e-300)
        ck = ca.mtimes(inv2J, g)
        hist = [ca.norm_2(self.cayley_residual(ck, g, *extra)) / gnorm]
        for _ in range(disc.newton_iters):
            ck = self.newton_map(ck, g, *extra)
            hist.append(ca.norm_2(self.cayley_residual(ck, g, *extra)) / gnorm)
        self.cayley_solve = fn("cayley_solve", [g], [ck, ca.vertcat(*hist)], ["g"], ["c", "res_hist"])

        X, w, h = ca.SX.sym("X", NX), ca.SX.sym("w", disc.nw), ca.SX.sym("h")
        X1, gvec, kres = disc._step_expr(X, c, w, h, m, forces)
        self.step_given_c = fn(f"{scheme}_step_given_c", [X, c, w, h], [X1, self.cayley_residual(c, gvec, *extra)],
                               ["X", "c", "w", "h"], ["X1", "G"])
        self.cayley_rhs = fn(f"{scheme}_cayley_rhs", [X, w, h], [gvec], ["X", "w", "h"], ["g"])
        csol, hist = self.cayley_solve(gvec, *extra)
        X1s, _ = self.step_given_c(X, csol, w, h, *extra)
        # res: the Cayley residual, and the Kepler equation's where the drift solves one (lgvi_kepler)
        res = hist[-1] if kres is None else ca.fmax(hist[-1], kres)
        self.step = fn(f"{scheme}_step", [X, w, h], [X1s, res], ["X", "w", "h"], ["X1", "res"])
        self._later = (disc, fn, extra)
        if not parametric:
            self.variations()

    def variations(self) -> "_StepFunctions":
        """variation, step_seeded and variation_seeded (:class:`Discretization`) from the step, built on the first call
        (the direct method's block needs only the step)."""
        if hasattr(self, "variation"):
            return self
        disc, fn, extra = self._later
        scheme = disc.scheme
        X, w, h = ca.SX.sym("X", NX), ca.SX.sym("w", disc.nw), ca.SX.sym("h")
        X1s = self.step(X, w, h, *extra)[0]
        z = ca.SX.sym("z", NZ)
        X1z, _ = self.step(chart(X, z), w, h, *extra)
        dX1 = ca.substitute(ca.jacobian(X1z, ca.vertcat(z, w)), z, ca.DM.zeros(NZ))
        AB = tangent_readback(X1s, dX1)
        self.variation = fn(f"{scheme}_variation", [X, w, h], [AB[:, :NZ], AB[:, NZ:]], ["X", "w", "h"], ["A", "B"])

        # Seeded versions for derivatives: two Newton iterations from the unperturbed step's root c0 agree with
        # c(g) to O(|dg|^4), so values and first to third derivatives are exact with a ~5x smaller graph
        c0 = ca.SX.sym("c0", 3)
        gvec = self.cayley_rhs(X, w, h, *extra)
        c2 = self.newton_map(self.newton_map(c0, gvec, *extra), gvec, *extra)
        X1c, _ = self.step_given_c(X, c2, w, h, *extra)
        self.step_seeded = fn(f"{scheme}_step_seeded", [X, w, h, c0], [X1c], ["X", "w", "h", "c0"], ["X1"])
        X1zc = self.step_seeded(chart(X, z), w, h, c0, *extra)
        dX1c = ca.substitute(ca.jacobian(X1zc, ca.vertcat(z, w)), z, ca.DM.zeros(NZ))
        ABc = tangent_readback(X1c, dX1c)
        self.variation_seeded = fn(f"{scheme}_variation_seeded", [X, w, h, c0], [ABc[:, :NZ], ABc[:, NZ:]],
                                   ["X", "w", "h", "c0"], ["A", "B"])
        return self


#: the step Functions a :class:`WithTheta` gives with theta bound
STEP_FUNCTIONS = ("cayley_residual", "cayley_solve", "cayley_rhs", "step_given_c", "step", "variation", "step_seeded",
                  "variation_seeded")


class WithTheta:
    """A Discretization whose step Functions (:data:`STEP_FUNCTIONS`) are ``disc.parametric()``'s with the SX symbol
    ``theta`` bound as last input: the indirect method's per-step maps built from it take the model's numbers as
    data, so their compiled code serves every model of the same structure.  Everything else is ``base``'s."""

    def __init__(self, disc: "Discretization", theta):
        self.base, self.theta = disc, theta
        P = disc.parametric().variations()
        for name in STEP_FUNCTIONS:
            setattr(self, name, functools.partial(self._call, getattr(P, name)))

    def _call(self, f: ca.Function, *args):
        return f(*args, self.theta)

    def __getattr__(self, name: str):
        return getattr(self.base, name)


def discretization(model: BodyModel, scheme: str = "lgvi", newton_iters: int = DEFAULT_NEWTON_ITERS,
                   force_frame: str = "inertial") -> "Discretization":
    """The :class:`Discretization` of ``model``, ``scheme`` and ``force_frame``, built once per model and kept
    on it (``model.discretizations``): every Problem of that model and scheme shares its Functions and
    everything cached on it (NLP blocks and their derivatives, shooting Functions, compiled code)."""
    key = (scheme, int(newton_iters), force_frame)
    if key not in model.discretizations:
        model.discretizations[key] = Discretization(model, scheme, newton_iters, force_frame)
    return model.discretizations[key]


class Discretization:
    """One discrete scheme ('lgvi' | 'lgvi_kepler' | 'first_order') for one body model, ``newton_iters`` unrolled
    Cayley iterations, ``force_frame`` 'inertial' | 'body' (the applied force of a control at node j is R_j u_{f,j},
    :meth:`applied_force`).  Every Function is built once here; what the methods build for it (NLP blocks, shooting
    Functions, rollouts) is kept here too (:meth:`cached`)."""

    def __init__(self, model: BodyModel, scheme: str = "lgvi", newton_iters: int = DEFAULT_NEWTON_ITERS,
                 force_frame: str = "inertial"):
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
        if force_frame not in FORCE_FRAMES:
            raise ValueError(f"force_frame must be one of {FORCE_FRAMES}, got {force_frame!r}")
        self.model = model
        self.scheme = scheme
        self.force_frame = force_frame
        self.newton_iters = int(newton_iters)
        self._built: dict[Hashable, Any] = {}
        #: stage control dimension
        self.nw = 2 * NU if two_point(scheme) else NU
        if scheme == "lgvi_kepler" and not model.mu:
            raise ValueError("the lgvi_kepler scheme flies a central body's Kepler motion exactly: the model needs "
                             "its gravitational parameter mu")
        J = model.inertia
        self.J = J
        self.Jd = 0.5 * np.trace(J) * np.eye(3) - J

        core = _StepFunctions(self)
        self.cayley_residual, self.cayley_solve = core.cayley_residual, core.cayley_solve
        self.step_given_c, self.cayley_rhs, self.step = core.step_given_c, core.cayley_rhs, core.step
        self.variation, self.step_seeded, self.variation_seeded = core.variation, core.step_seeded, core.variation_seeded

    # ------------------------------------------------------------------ steps
    def _step_expr(self, X, c, w, h, m, forces):
        """Symbolic step given the Cayley vector c, the mass m and forces(x, R) -> (f, M); returns (X_{k+1}, g_k,
        the Kepler residual or None).  The LGVIs' translation is kick, drift, kick: lgvi drifts freely (eq. 7-8),
        lgvi_kepler flies the two-body flow exactly between kicks by the force less its point-mass part (§2a, 7a)."""
        x, gamma, R, Pi = split_state(X)
        F = cayley(c)
        kres = None
        if two_point(self.scheme):
            uk, uk1 = w[0:NU], w[NU:]
            f0, M0 = forces(x, R)
            Fk0 = f0 + self.applied_force(R, uk[U_FORCE])
            Mk0 = M0 + uk[U_MOMENT]
            g = h * (Pi + (h / 2) * Mk0)                                       # (9)
            R1 = ca.mtimes(R, F)                                               # (10)
            if self.scheme == "lgvi_kepler":                                   # (7a)
                mu = float(self.model.mu)
                x1, v1, kres = kepler_drift(mu)(x, (gamma + (h / 2) * (Fk0 - kepler_force(mu, m, x))) / m, h)
                f1, M1 = forces(x1, R1)
                gamma1 = m * v1 + (h / 2) * (f1 - kepler_force(mu, m, x1) + self.applied_force(R1, uk1[U_FORCE]))
            else:   # written as the paper's (7)-(8), not as kick-drift-kick: the same numbers to the last bit
                x1 = x + (h / m) * gamma + (h**2 / (2 * m)) * Fk0                  # (7)
                f1, M1 = forces(x1, R1)
                gamma1 = gamma + (h / 2) * Fk0 + (h / 2) * (f1 + self.applied_force(R1, uk1[U_FORCE]))  # (8)
            Pi1 = ca.mtimes(F.T, Pi + (h / 2) * Mk0) + (h / 2) * (M1 + uk1[U_MOMENT])  # (11)
        else:
            u1 = w
            g = h * Pi                                                         # (23)
            x1 = x + (h / m) * gamma                                           # (21)
            R1 = ca.mtimes(R, F)                                               # (24)
            f1, M1 = forces(x1, R1)
            gamma1 = gamma + h * f1 + h * self.applied_force(R1, u1[U_FORCE])      # (22)
            Pi1 = ca.mtimes(F.T, Pi) + h * M1 + h * u1[U_MOMENT]                    # (25)
        return join_state(x1, gamma1, R1, Pi1), g, kres

    def applied_force(self, R, u_f):
        """The inertial force (3) a force control u_f (3) applies at a node of attitude R (3x3): u_f itself
        ('inertial') or R u_f ('body').  NumPy or CasADi; R and u_f may also be stacks (n,3,3), (n,3)."""
        if self.force_frame == "inertial":
            return u_f
        if is_symbolic(R) or is_symbolic(u_f):
            return ca.mtimes(R, u_f)
        return np.einsum("...ij,...j->...i", np.asarray(R, dtype=float), np.asarray(u_f, dtype=float))

    # --------------------------------------------------------------- controls
    def n_controls(self, N: int) -> int:
        """Number of control vectors over N steps: N+1 (lgvi, nodes 0..N) or N (first_order, u_1..u_N)."""
        return N + 1 if two_point(self.scheme) else N

    def stage_controls(self, U):
        """Controls (6 x n_controls(N)) -> stage controls W (nw x N); NumPy or CasADi."""
        if not two_point(self.scheme):
            return U
        if is_symbolic(U):
            return ca.vertcat(U[:, :-1], U[:, 1:])
        U = np.asarray(U, dtype=float)
        return np.vstack([U[:, :-1], U[:, 1:]])

    def with_theta(self, theta) -> "WithTheta":
        """This Discretization as builders of per-step Functions see it, with the model's numbers the SX symbol
        ``theta`` (:class:`WithTheta`)."""
        return WithTheta(self, theta)

    def parametric(self) -> "_StepFunctions":
        """The step Functions with theta = ``model.parameters`` as last input (equal to this Discretization's to
        round-off): what is compiled from them serves every model of the same structure.  Built on first use."""
        return self.cached("parametric", lambda: _StepFunctions(self, parametric=True))

    # ------------------------------------------------------------------ cache
    def __getstate__(self) -> dict:
        """Pickled without the cache of :meth:`cached` (what it holds is rebuilt on first use; some of it, the
        parametric step Functions' builders, are local closures that do not pickle), so a Problem or a Solution
        solved on this Discretization can go to another process."""
        return {**self.__dict__, "_built": {}}

    def cached(self, key: Hashable, build: Callable[[], Any]) -> Any:
        """What ``build()`` returns, built on the first call with ``key`` and kept on this Discretization
        (keys name what is built and its structural arguments, e.g. ('rollout', N))."""
        if key not in self._built:
            self._built[key] = build()
        return self._built[key]

    # ---------------------------------------------------------------- rollout
    def rollout(self, N: int) -> ca.Function:
        """(X0[18], W[nw x N], h) -> (X[18 x N] nodes 1..N, res[1 x N] Cayley residuals); built once per N."""
        return self.cached(("rollout", int(N)), lambda: self._rollout(int(N)))

    def _rollout(self, N: int) -> ca.Function:
        acc = self.step.mapaccum(f"{self.scheme}_acc{N}", N)
        X0 = ca.MX.sym("X0", NX)
        W = ca.MX.sym("W", self.nw, N)
        h = ca.MX.sym("h")
        Xs, res = acc(X0, W, ca.repmat(h, 1, N))
        return ca.Function(f"{self.scheme}_rollout{N}", [X0, W, h], [Xs, res], ["X0", "W", "h"], ["X", "res"])

    def rollout_steps(self, N: int) -> ca.Function:
        """(X0[18], W[nw x N], H[1 x N]) -> (X[18 x N], res[1 x N]): the rollout with step k of size H[k] (a
        non-uniform mesh, docs/mathematics.md §16); built once per N."""
        def build():
            acc = self.step.mapaccum(f"{self.scheme}_acc{N}", N)
            X0, W, H = ca.MX.sym("X0", NX), ca.MX.sym("W", self.nw, N), ca.MX.sym("H", 1, N)
            Xs, res = acc(X0, W, H)
            return ca.Function(f"{self.scheme}_rollout_steps{N}", [X0, W, H], [Xs, res], ["X0", "W", "H"],
                               ["X", "res"])
        return self.cached(("rollout_steps", int(N)), build)

    def implied_momenta(self, X: np.ndarray, U: np.ndarray, h) -> np.ndarray:
        """The angular momenta Pi_k (N, 3), k < N, that the attitudes of node states X (N+1, 18) imply on steps h (one
        size or N sizes) under the LGVIs' Cayley equation (9): with c_k = cay^-1(R_k^T R_{k+1}), G(c) = 0 is linear
        in g, (I - c^ + c c^T) g = 2 J c, and g = h (Pi_k + (h/2) M_k) with M_k = M(x_k, R_k) + u_{m,k}.  A start
        resampled onto another grid (its attitudes along geodesics, its momenta linear in time) is made to satisfy
        the Cayley rows of the NLP exactly with these (docs/mathematics.md §11, "The next mesh").  Two-point schemes
        only."""
        if not two_point(self.scheme):
            raise ValueError("implied_momenta: the LGVIs' Cayley equation (9) only")
        s = unpack_states(X)
        x, R = s.x, s.R
        c = step_cayley_vectors(R)
        N = len(c)
        hk = np.broadcast_to(np.asarray(h, dtype=float), (N,))
        J = np.asarray(self.J, dtype=float)
        Pi = np.empty((N, 3))
        for k in range(N):
            ck = c[k]
            g = np.linalg.solve(np.eye(3) - hat(ck) + np.outer(ck, ck), 2.0 * J @ ck)
            M = np.asarray(self.model.forces(x[k], R[k])[1], dtype=float).ravel() + U[U_MOMENT, k]
            Pi[k] = g / hk[k] - (hk[k] / 2.0) * M
        return Pi

    def simulate(self, X0, U, h, N: int, chunk: int = 2000):
        """Numeric rollout: X0 (18,), U (6 x n_controls(N)) or None for free motion; h one step size, or the N
        step sizes h_k of a non-uniform mesh (step k from node k to k+1 with its own h_k).

        Returns (X (N+1, 18) node-major, res (N,) Cayley residuals); evaluated in chunks of ``chunk`` steps.
        """
        hs = np.asarray(h, dtype=float)
        if hs.ndim and hs.size != N:
            raise ValueError(f"step sizes must be one number or {N} numbers, got {hs.size}")
        X0 = np.asarray(X0, dtype=float).reshape(NX)
        if U is None:
            W = np.zeros((self.nw, N))
        else:
            U = np.asarray(U, dtype=float)
            if U.shape != (NU, self.n_controls(N)):
                raise ValueError(f"controls must have shape (6, {self.n_controls(N)}), got {U.shape}")
            W = self.stage_controls(U)
        out = [X0[None, :]]
        res = []
        Xk = X0
        for s in range(0, N, chunk):
            n = min(chunk, N - s)
            if hs.ndim:
                Xs, r = self.rollout_steps(n)(Xk, W[:, s : s + n], hs[None, s : s + n])
            else:
                Xs, r = self.rollout(n)(Xk, W[:, s : s + n], h)
            Xs = Xs.full().T
            out.append(Xs)
            res.append(r.full().ravel())
            Xk = Xs[-1]
        return np.vstack(out), np.concatenate(res) if res else np.zeros(0)
