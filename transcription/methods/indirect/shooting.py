"""The shooting Functions of the indirect method for one (Discretization, N): the residual z_N(lambda_0) and its
exact Jacobian, the rollout of states, costates and controls, and the free-final-time gradient."""
from __future__ import annotations

import functools

import casadi as ca
import numpy as np

from ...compile import codegen
from ...geometry.state import NU, NX, NZ, split_state, tangent_readback
from ...dynamics.lgvi import Discretization, per_discretization
from .conditions import costate_functions, node_law, terminal_residual_function
from .control import NB, control_matrix
from .coordinates import body_coordinates, initial_costate_function, terminal_costate_function
from .linearization import linearization_functions, terminal_residual_jacobian

#: nesting base of CasADi's mapaccum (default 10): the same evaluation, built ~10x faster at N = 1000
MAPACCUM_OPTS = {"base": 4}


class ShootingFunctions:
    """Shooting residual and its Jacobian for one (Discretization, N), built once.

    The unknown ``lam0`` is lambda_0 (first_order) or lambda_{-1} (lgvi, LGVI_CONDITIONS); bd the bound data
    (:func:`~.control.bound_data`; no bounds: u = v bit for bit); h[1 x N] the step sizes h_k (a scalar is broadcast:
    a uniform mesh; docs/mathematics.md §17), step k at h_k, the first control's law at h_0.  With a body-fixed force
    the recursion runs in the body-momentum coordinates of :mod:`.coordinates`, the outputs in z all the same (§15).

    shoot(lam0[12], X0[18], Xd[18], h[1 x N], Winv[6x6], bd[NB])
        -> (zN[12], X[18 x N] nodes 1..N, lam[12 x N] lambda_0..lambda_{N-1},
            U[6 x n_controls] (first_order u_1..u_N; lgvi u_0..u_N), res[1 x N] Cayley residuals,
            lam_res[1 x N] relative residuals of the costate solves, 0 for k = 0 in first_order)
    residual(lam0, X0, Xd, h, Winv, bd) -> (zN[12], lamN[12], res_max)  (line-search trials; lamN = lambda_{N-1} for
        the transversality conditions of free components; res_max the largest relative Cayley residual: a rollout
        above cayley_tol does not solve the discrete equations and is rejected)
    shoot_jac(lam0, X0, Xd, h, Winv, bd) -> (zN[12], Psi[12 x 12], dlamN[12 x 12]): Psi = dzN/dlam0 and dlamN =
        dlambda_{N-1}/dlam0 by the linearized recursion (:func:`~.linearization.linearization_functions`), equal to
        forward AD through the rollout (with bounds: the saturation's generalized derivative, semismooth Newton)
    terminal(...) -> (XN[18], lamN[12], res_max) and terminal_jac(...) -> (XN, lamN, dZ[12 x 12], dlamN[12 x 12]),
        dZ = dz_N/dlam0 at X_N: for terminal conditions other than a state's (:mod:`.orbit`); Xd is not read.
    rollout(...) -> (zN, lamN, res_max, S...) and jac_given(..., S...) -> (zN, Psi, dlamN): residual and shoot_jac,
        bit for bit, sharing the rollout's outputs S (:class:`RolloutCache`): no second rollout for the Jacobian.
    """

    def __init__(self, disc: Discretization, N: int, jit: bool = False):
        if N < 1:
            raise ValueError("N must be >= 1")
        self.disc, self.N, self.jit = disc, int(N), bool(jit)
        # the per-step maps take the model's numbers theta as data (their last input; here the constant
        # model.parameters, :meth:`_functions`): compiled once per structure, not per model
        self.costate_map, self.first_step = costate_functions(disc, True)
        self.costate_hessian, self.linearized_map = linearization_functions(disc)
        self.terminal_residual = terminal_residual_function()
        # with jit the three per-step Functions are compiled to C, one set per scheme and structure (independent of N,
        # the data and the model's numbers); a set not yet cached is interpreted while a background process compiles
        # it, and the N-step Functions move to it as it arrives (a codegen.Switch inside the shooting Functions)
        maps = (self.costate_map, self.costate_hessian, self.linearized_map)
        provisional, self.libraries, self.switches = False, [], []
        if self.jit:
            # in the order the background build compiles them: the costate map first (every rollout and every
            # line-search trial evaluates it), then the two of the Jacobian
            libs = [codegen.Library(maps[0].name(), (maps[0],), cse=True),
                    codegen.Library(maps[1].name(), (maps[1],)),
                    codegen.Library(maps[2].name(), (maps[2],), cflags=tuple(codegen.LOOP_CFLAGS), quick=False)]
            maps = tuple(f for (f,) in codegen.compiled_libraries(libs, cflags=codegen.QUICK_CFLAGS,
                                                                   quick=codegen.QUICK_CFLAGS))
            self.libraries = libs   # (codegen.ready(libraries, QUICK_CFLAGS): all compiled at their own flags)
            provisional = codegen.last_provisional
        self.compiled = self.jit and (provisional or all(f.class_name() == "External" for f in maps))
        n = self.N - 1 if disc.scheme == "first_order" else self.N   # the steps by the costate map
        steps = [self._n_steps(i, f, n) for i, f in enumerate(maps)] if n > 0 else [None] * 3
        if provisional and n > 0:
            self.switches = [codegen.Switch(f, [lib], functools.partial(self._switched, i=i, n=n),
                                            codegen.QUICK_CFLAGS, codegen.QUICK_CFLAGS)
                             for i, (f, lib) in enumerate(zip(steps, libs))]
            steps = self.switches   # (a Callback must outlive the Functions that call it: kept here)
        fns = self._functions(*steps)
        self.shoot, self.residual, self.shoot_jac = fns["shoot"], fns["residual"], fns["shoot_jac"]
        self.terminal, self.terminal_jac = fns["terminal"], fns["terminal_jac"]
        self.rollout, self.jac_given = fns["rollout"], fns["jac_given"]

    def _n_steps(self, i: int, fn: ca.Function, n: int) -> ca.Function:
        """The N-step Function of per-step map ``i`` (0 costate map, 1 its Hessian, 2 linearized map) ``fn`` over the
        n steps of the costate map: the accumulated rollout, the Hessians of all steps, the accumulated linearized
        recursion."""
        sch = self.disc.scheme
        if i == 1:
            return fn.map(f"{sch}_costate_hessian_map{n}", "serial", n, [5, 6, 7], [])
        return fn.mapaccum(f"{sch}_{'costate' if i == 0 else 'linearized'}_acc{n}", n, 2, MAPACCUM_OPTS)

    def _switched(self, loaded, paths, i: int, n: int) -> ca.Function:
        """The N-step Function ``i`` from its library's compiled map (:class:`codegen.Switch`)."""
        return self._n_steps(i, loaded[0][0], n)

    def _functions(self, acc, hess_n, lin_acc) -> dict:
        """shoot, residual, shoot_jac, terminal and terminal_jac (class docstring) from the N-step Functions
        (:meth:`_n_steps`; None for N = 1 in first_order), with the model's numbers theta = ``model.parameters`` as
        the maps' data."""
        disc, N, sch = self.disc, self.N, self.disc.scheme
        theta = ca.DM(disc.model.parameters)
        lam0 = ca.MX.sym("lam0", NZ)
        X0 = ca.MX.sym("X0", NX)
        Xd = ca.MX.sym("Xd", NX)
        h = ca.MX.sym("h", 1, N)   # the step sizes h_k (a scalar argument is broadcast: a uniform mesh)
        Winv = ca.MX.sym("Winv", NU, NU)
        bd = ca.MX.sym("bd", NB)
        # the rollout: steps k = k0 .. N-1 by the costate map from (X_k0, lambda_k0-1)
        n = N - 1 if sch == "first_order" else N   # the steps by the costate map (first_order: after step 0)
        h0, hr = h[0, 0], h[0, N - n:]   # step 0's size; those of the costate map's steps
        if sch == "first_order":   # step 0 from lambda_0 itself
            X1, u1, r1 = self.first_step(X0, lam0, h0, Winv, bd, theta)
            Xs, lams, Us, res, lres = [X1], [lam0], [u1], [r1], [ca.MX(0)]
            Xstart = X1
        else:
            Xs, lams, Us, res, lres = [], [], [], [], []
            Xstart = X0
        # the control lam0 determines (first_order u_1 at R_1, lgvi u_0 at R_0) and its saturation Jacobian
        u_first, D_first = node_law(disc, h0, Winv, bd)(lam0, split_state(Xstart)[2])
        if sch != "first_order":
            Us.append(u_first)
        steps = None
        if n > 0:
            steps = acc(Xstart, lam0, hr, ca.repmat(Winv, 1, n), ca.repmat(bd, 1, n), ca.repmat(theta, 1, n))
            for a, b in zip((Xs, lams, Us, res, lres), steps[:5]):
                a.append(b)
        Xs, lams, Us, res, lres = (ca.horzcat(*a) for a in (Xs, lams, Us, res, lres))
        zN, lamN = self.terminal_residual(Xs[:, -1], Xd), lams[:, -1]
        names_in = ["lam0", "X0", "Xd", "h", "Winv", "bd"]
        args = [lam0, X0, Xd, h, Winv, bd]
        shoot = ca.Function(
            f"{sch}_shoot{N}",
            args,
            [zN, Xs, lams, Us, res, lres],
            names_in,
            ["zN", "X", "lam", "U", "res", "lam_res"],
        )
        res_max = ca.mmax(res)
        residual = ca.Function(f"{sch}_shoot_residual{N}", args, [zN, lamN, res_max], names_in,
                               ["zN", "lamN", "res_max"])
        dZ, dlamN = self._linearization(hess_n, lin_acc, args, Xstart, D_first, steps, n)
        zL, JT = terminal_residual_jacobian()(Xs[:, -1], Xd)
        shoot_jac = ca.Function(f"{sch}_shoot_jac{N}", args, [zL, ca.mtimes(JT, dZ), dlamN], names_in,
                                ["zN", "Psi", "dlamN"])
        # the same residual and Jacobian in two calls that share one rollout (the Newton iteration asks for the
        # Jacobian where its line search accepted a residual): the rollout's outputs the linearization reads
        kept = (0, 1, 5, 6, 7, 8) if n > 0 else ()
        rollout = ca.Function(f"{sch}_shoot_rollout{N}", args, [zN, lamN, res_max, *(steps[i] for i in kept)])
        given = [ca.MX.sym(f"s{i}", steps[i].sparsity()) for i in kept]
        sym = [None] * 9
        for i, g in zip(kept, given):
            sym[i] = g
        dZg, dlamNg = self._linearization(hess_n, lin_acc, args, Xstart, D_first, sym if n > 0 else None, n)
        zLg, JTg = terminal_residual_jacobian()(sym[0][:, -1] if n > 0 else Xstart, Xd)
        jac_given = ca.Function(f"{sch}_shoot_jac_given{N}", args + given, [zLg, ca.mtimes(JTg, dZg), dlamNg])
        # the terminal state and lambda_{N-1}, with their derivatives by lam0, for terminal conditions other than a
        # state's (an orbit target, :mod:`.orbit`)
        terminal = ca.Function(f"{sch}_shoot_terminal{N}", args, [Xs[:, -1], lamN, res_max], names_in,
                               ["XN", "lamN", "res_max"])
        terminal_jac = ca.Function(f"{sch}_shoot_terminal_jac{N}", args, [Xs[:, -1], lamN, dZ, dlamN], names_in,
                                   ["XN", "lamN", "dZ", "dlamN"])
        return {"shoot": shoot, "residual": residual, "shoot_jac": shoot_jac, "terminal": terminal,
                "terminal_jac": terminal_jac, "rollout": rollout, "jac_given": jac_given}

    def _linearization(self, hess_n, lin_acc, args, Xstart, D_first, steps, n):
        """(dz_N, dlambda_{N-1}) by lam0 (12 x 12 each, tangent coordinates) by the linearized recursion along the
        rollout (:func:`~.linearization.linearization_functions`).  With a body-fixed force it runs in body-momentum
        coordinates (docs/mathematics.md §15): from dlambda' = T^-T (+ Qi dz'_1 in first_order, the unknown at X_1),
        mapped back at X_N by dlambda_{N-1} = T^T dlambda' + Q dz'_N, dz_N = T^-1 dz'_N."""
        disc, sch = self.disc, self.disc.scheme
        lam0, X0, _, h, Winv, bd = args
        h0, hr = h[0, 0], h[0, self.N - n:]   # step 0's size (the first control's law); the mapped steps'
        Bc = control_matrix(disc)(h0)
        body = body_coordinates(disc)
        dlam = ca.MX.eye(NZ)
        if body:
            Tit, Qi = initial_costate_function()(Xstart, lam0)
            dlam = Tit
        if sch == "first_order":   # first step: dz_1 = B du_1, du_1 = -(1/h) D_1 Winv B^T dlambda'_0
            G = -ca.mtimes(Winv, Bc.T) / h0
            dZ = ca.mtimes(Bc, ca.mtimes(D_first, ca.mtimes(G, dlam) if body else G))
            if body:               # lambda'_0 = T(X_1)^-T lambda_0 moves with X_1 (B^T Qi B = 0: dz_1 as above)
                dlam = dlam + ca.mtimes(Qi, dZ)
        else:
            dZ = ca.MX.zeros(NZ, NZ)
        dlamN, lam_last = dlam, (ca.mtimes(Tit, lam0) if body else lam0)
        if n > 0:
            Xr, Lr, Ar, Cr, Dr, LPr = (steps[i] for i in (0, 1, 5, 6, 7, 8))
            Xk = ca.horzcat(Xstart, Xr[:, :n - 1])         # X_k, lambda_{k-1}, lambda'_k of the steps
            Lprev = ca.horzcat(lam0, Lr[:, :n - 1])
            # D of the control each step's A_k is taken at (lgvi: u_k) and of the one it determines (u_{k+1})
            Dk = ca.horzcat(D_first, Dr[:, :NU * (n - 1)])
            Ws = ca.repmat(Winv, 1, n)
            Hk = hess_n(Xk, Lprev, LPr, Cr, hr, Winv, bd, ca.DM(self.disc.model.parameters))
            dZs, dlams = lin_acc(dZ, dlam, Ar, Hk, Dk, Dr, hr, Ws)
            dZ, dlamN, lam_last = dZs[:, -NZ:], dlams[:, -NZ:], LPr[:, -1]
        if body:   # dlambda_{N-1} = T^T dlambda' + Q dz'_N and dz_N = T^-1 dz'_N at X_N
            XN = Xr[:, -1] if n > 0 else Xstart
            _, Tt, Q, Tinv = terminal_costate_function()(XN, lam_last)
            dlamN, dZ = ca.mtimes(Tt, dlamN) + ca.mtimes(Q, dZ), ca.mtimes(Tinv, dZ)
        return dZ, dlamN


class RolloutCache:
    """residual(lam0) and jacobian(lam0) of the Newton iteration on one ShootingFunctions (args: X0, Xd, h, Winv, bd):
    the Jacobian at the last residual's point reuses its rollout (``jac_given``): one rollout per accepted step, not
    two.  ``seed``: (lam0, outputs) of a rollout already done with these args (the start's check)."""

    def __init__(self, fns: ShootingFunctions, args: tuple, seed: tuple | None = None):
        self.fns, self.args, self.last, self.seed = fns, args, None, seed

    def residual(self, lam0):
        seeded = self.seed is not None and np.array_equal(self.seed[0], lam0)
        out = self.seed[1] if seeded else self.fns.rollout(lam0, *self.args)
        self.last = (np.array(lam0, dtype=float), out[3:])
        return out[:3]

    def jacobian(self, lam0):
        if self.last is not None and np.array_equal(self.last[0], lam0):
            return self.fns.jac_given(lam0, *self.args, *self.last[1])
        return self.fns.shoot_jac(lam0, *self.args)


@per_discretization
def shooting_functions(disc: Discretization, N: int, jit: bool = False) -> ShootingFunctions:
    """The :class:`ShootingFunctions` of ``disc`` and N, built once and kept on the Discretization."""
    return ShootingFunctions(disc, N, jit)


@per_discretization
def time_gradient_function(disc: Discretization, N: int) -> ca.Function:
    """``{scheme}_step_time_derivative{N}`` (X[18 x N], W[nw x N], lam[12 x N], h[1 x N]) -> g[1 x N]: the derivative
    of each step's constraint term of the Lagrangian by its step size at fixed states, controls and multipliers,

        g_k = lambda_k^T readback_{X_{k+1}}(d step(X_k, w_k, h_k) / dh_k)

    (X_k nodes 0..N-1, w_k the stage controls, lambda_k step k's multiplier; h: the h_k or one scalar), for the free
    final time (docs/mathematics.md §10; on a mesh dL/dh = J/h + sum_k r_k g_k, §17).  Forward AD through the step."""
    X, w, lam, h = ca.SX.sym("X", NX), ca.SX.sym("w", disc.nw), ca.SX.sym("lam", NZ), ca.SX.sym("h")
    X1 = disc.step(X, w, h)[0]
    g = ca.dot(lam, tangent_readback(X1, ca.jacobian(X1, h)))
    f = ca.Function(f"{disc.scheme}_step_time_derivative", [X, w, lam, h], [g], ["X", "w", "lam", "h"], ["g"])
    return f.map(f"{disc.scheme}_step_time_derivative{N}", "serial", N, [], [])
