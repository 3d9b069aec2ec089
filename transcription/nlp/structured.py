"""The one NLP builder: a structured NLP assembled from small SX block Functions (docs/mathematics.md §7).

Every multiple-shooting NLP of the project is a sum of *blocks*: one SX Function of a few local variables,

    fn(v[nv], p[np]) -> (cost (1x1), rows (nr x 1)),

instantiated M times; instance k gathers its variables from the decision vector by ``idx[:, k]`` and gets its data
``data[:, k]`` (step size, scales, weights, targets: data, so one compiled Function serves every problem of the same
structure).  The NLP is

    min  sum_b sum_k cost_b(v_bk, p_bk)   s.t.  lbg <= rows_b(v_bk, p_bk) <= ubg,  lbx <= w <= ubx.

Each block's gradient, Jacobian and Hessian of (sigma cost + lam^T rows) are formed once on its small graph,
``map``-ped over its instances and scattered into the global sparse matrices by index maps fixed at build time
(duplicates summed): the exact Hessian, built and evaluated in time linear in the instances (SX-expanding the whole
NLP took ~10 s at N = 1000).  Blocks marked ``compile`` get their derivatives compiled to C (transcription.compile).
Rows are ordered block by block, instance-major inside a block (:meth:`StructuredNLP.rows`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..compile import codegen


class _Derivatives:
    """The gradient, Jacobian and Hessian Functions of one block Function (built once per Function)."""

    def __init__(self, fn: ca.Function, jit: bool):
        nv, npar = fn.size1_in(0), fn.size1_in(1)
        v, p = ca.SX.sym("v", nv), ca.SX.sym("p", npar)
        sigma = ca.SX.sym("sigma")
        cost, rows = fn(v, p)
        lam = ca.SX.sym("lam", rows.shape[0])
        Jv = ca.jacobian(rows, v)
        gv = ca.jacobian(cost, v)
        Hv = ca.triu(ca.hessian(sigma * cost + ca.dot(lam, rows), v)[0])
        name = fn.name()
        self.spJ, self.spg, self.spH = Jv.sparsity(), gv.sparsity(), Hv.sparsity()
        self.grad = ca.Function(f"{name}_grad", [v, p], [ca.vertcat(*gv.nonzeros()) if gv.nnz() else ca.SX(0, 1)],
                                ["v", "p"], ["gnz"])
        self.jac = ca.Function(f"{name}_jac", [v, p], [ca.vertcat(*Jv.nonzeros()) if Jv.nnz() else ca.SX(0, 1)],
                               ["v", "p"], ["jnz"])
        self.hess = ca.Function(f"{name}_hess", [v, p, sigma, lam],
                                [ca.vertcat(*Hv.nonzeros()) if Hv.nnz() else ca.SX(0, 1)], ["v", "p", "sigma", "lam"],
                                ["hnz"])
        self.compiled = self.provisional = False
        self.switches: list[codegen.Switch] = []
        if jit:
            self._libraries = (codegen.Library(self.jac.name(), (self.jac,), cse=True),
                               codegen.Library(self.hess.name(), (self.hess,), cse=True))
            self._compile()

    def _compile(self):
        """jac and hess compiled to C (one library each), by codegen's interpreted-first policy; ``provisional``
        until the -O1 build has arrived; ``compiled``: compiled code is in use or on its way."""
        (self.jac,), (self.hess,) = codegen.compiled_libraries(self._libraries, quick=codegen.QUICK_CFLAGS)
        self.provisional = codegen.last_provisional
        self.compiled = self.provisional or (self.jac.class_name() == "External"
                                             and self.hess.class_name() == "External")

    def refresh(self) -> "_Derivatives":
        """Load the -O1 build once it has arrived in the cache (between solves: an NLP keeps the Functions it got)."""
        if self.provisional and codegen.ready(self._libraries):
            self._compile()
        return self

    def mapped(self, which: str, M: int) -> ca.Function:
        """``which`` ('grad', 'jac' or 'hess') mapped over M instances; while provisional a :class:`codegen.Switch`
        that moves to the compiled library as it arrives, within a solve."""
        fn = getattr(self, which)
        if not self.provisional or which == "grad":
            return fn.map(M)
        lib = self._libraries[0 if which == "jac" else 1]
        switch = codegen.Switch(fn.map(M), [lib], lambda loaded, paths: loaded[0][0].map(M))
        self.switches.append(switch)   # a Callback must outlive the Functions that call it
        return switch


class BlockFunction:
    """A block's SX Function and its derivative Functions (:class:`_Derivatives`, one set per jit flag), built on
    first use and kept here, with their compiled code (the Discretization keeps the blocks of :mod:`.blocks`)."""

    def __init__(self, function: ca.Function):
        self.function = function
        self._derivatives: dict[bool, _Derivatives] = {}

    def derivatives(self, jit: bool) -> _Derivatives:
        if bool(jit) not in self._derivatives:
            self._derivatives[bool(jit)] = _Derivatives(self.function, bool(jit))
        return self._derivatives[bool(jit)].refresh()


@dataclass
class Block:
    """One kind of NLP term, instantiated M times.

    fn: SX Function (v[nv], p[np]) -> (cost (1x1), rows (nr x 1)), in scaled variables and rows, or a
    :class:`BlockFunction` of one (whose derivatives are kept with it); ``fn`` is then its Function.
    idx: (nv, M) global indices of v per instance.  data: (np, M) (or (np,) shared) constants.
    lbg, ubg: (nr, M) (or (nr,) shared, or scalars) row bounds.  compile: jit the derivatives.
    """

    name: str
    fn: ca.Function | BlockFunction
    idx: np.ndarray
    data: np.ndarray
    lbg: np.ndarray | float = 0.0
    ubg: np.ndarray | float = 0.0
    compile: bool = False
    block_function: BlockFunction = field(init=False, repr=False)

    def __post_init__(self):
        self.block_function = self.fn if isinstance(self.fn, BlockFunction) else BlockFunction(self.fn)
        self.fn = self.block_function.function
        self.idx = np.asarray(self.idx, dtype=np.int64)
        if self.idx.ndim == 1:
            self.idx = self.idx[:, None]
        nv, M = self.idx.shape
        data = np.asarray(self.data, dtype=float)
        self.data = np.repeat(data.reshape(-1, 1), M, axis=1) if data.ndim <= 1 else data
        if self.fn.size1_in(0) != nv or self.data.shape != (self.fn.size1_in(1), M):
            raise ValueError(f"block {self.name}: shapes of idx {self.idx.shape} / data {self.data.shape} do not match "
                             f"{self.fn.name()} (nv = {self.fn.size1_in(0)}, np = {self.fn.size1_in(1)})")
        nr = self.nr
        self.lbg = np.broadcast_to(np.asarray(self.lbg, dtype=float).reshape(-1, 1) if np.ndim(self.lbg) == 1
                                   else np.asarray(self.lbg, dtype=float), (nr, M)).copy()
        self.ubg = np.broadcast_to(np.asarray(self.ubg, dtype=float).reshape(-1, 1) if np.ndim(self.ubg) == 1
                                   else np.asarray(self.ubg, dtype=float), (nr, M)).copy()

    @property
    def M(self) -> int:
        return self.idx.shape[1]

    @property
    def nr(self) -> int:
        return self.fn.size1_out(1)


def assemble(nrow: int, ncol: int, rows, cols, vals):
    """Sparse (nrow x ncol) MX from triplets (rows, cols, vals (ntrip,) MX), duplicates summed: the nonzeros are
    one constant sparse product P @ vals (P: nnz x ntrip, 0/1)."""
    rows = np.asarray(rows, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    keys, mapping = np.unique(cols * nrow + rows, return_inverse=True)   # column-major = CasADi's nonzero order
    sp = ca.Sparsity.triplet(nrow, ncol, (keys % nrow).tolist(), (keys // nrow).tolist())
    ntrip = len(rows)
    if ntrip == 0:
        return ca.MX(nrow, ncol)
    if len(keys) == ntrip:            # no duplicates: a permutation
        perm = np.empty(ntrip, dtype=np.int64)
        perm[mapping] = np.arange(ntrip)
        nz = vals[perm.tolist()]
    else:
        P = ca.DM(ca.Sparsity.triplet(sp.nnz(), ntrip, mapping.tolist(), list(range(ntrip))), 1.0)
        nz = ca.mtimes(P, vals)
    return ca.sparsity_cast(nz, sp)


class StructuredNLP:
    """The NLP of a list of :class:`Block` over n decision variables.

    ``f``, ``g`` (MX of the symbol ``w``), ``lbg``, ``ubg``; :meth:`rows` gives a block's row
    indices in g; :meth:`derivative_functions` the nlpsol options 'grad_f', 'jac_g', 'hess_lag'
    (exact, assembled block by block).  ``compiled``: every block asked to compile did.
    """

    def __init__(self, n: int, blocks: list[Block], jit: bool = False):
        self.n = int(n)
        self.blocks = list(blocks)
        self.w = ca.MX.sym("w", self.n)
        self._offsets = {}
        off = 0
        for b in self.blocks:
            if b.name in self._offsets:
                raise ValueError(f"two blocks named {b.name}")
            if b.idx.size and (b.idx.min() < 0 or b.idx.max() >= self.n):
                raise ValueError(f"block {b.name}: variable index out of range")
            self._offsets[b.name] = off
            off += b.nr * b.M
        self.ng = off
        self.lbg = np.concatenate([b.lbg.ravel(order="F") for b in self.blocks]) if self.blocks else np.zeros(0)
        self.ubg = np.concatenate([b.ubg.ravel(order="F") for b in self.blocks]) if self.blocks else np.zeros(0)
        self._d = {b.name: b.block_function.derivatives(jit and b.compile) for b in self.blocks}
        self.compiled = all(self._d[b.name].compiled for b in self.blocks if b.compile) and jit
        self._V = {b.name: self._gather(b) for b in self.blocks}
        f = ca.MX(0)
        g = []
        for b in self.blocks:
            cost, rows = b.fn.map(b.M)(self._V[b.name], ca.DM(b.data))
            f = f + ca.sum2(cost)
            if b.nr:
                g.append(ca.vec(rows))
        self.f = f
        self.g = ca.vertcat(*g) if g else ca.MX(0, 1)

    @property
    def key(self) -> tuple:
        """The structure of this NLP (size; per block name, Function, rows, instances): NLPs with the same key order
        variables and rows alike, so the multipliers of one warm-start the other."""
        return (self.n, tuple((b.name, b.fn.name(), b.nr, b.M) for b in self.blocks))

    def _gather(self, b: Block):
        return ca.reshape(self.w[b.idx.ravel(order="F").tolist()], b.idx.shape[0], b.M)

    def rows(self, name: str) -> np.ndarray:
        """Row indices (nr, M) of block ``name`` in g."""
        b = next(b for b in self.blocks if b.name == name)
        return self._offsets[name] + np.arange(b.nr * b.M).reshape(b.M, b.nr).T

    def shared_rows(self, key: tuple, values: np.ndarray) -> np.ndarray:
        """(ng,) per-row ``values`` of the NLP whose :attr:`key` is ``key`` (its ng rows) on this NLP's rows: the
        blocks both have with the same name, rows and instances (the same constraints: dynamics, controls, path,
        terminal) copied, every other row 0 (e.g. the rows of another objective)."""
        theirs, off = {}, 0
        for name, _, nr, M in key[1]:
            theirs[name] = (off, nr, M)
            off += nr * M
        out = np.zeros(self.ng)
        for b in self.blocks:
            o = theirs.get(b.name)
            if b.nr and o is not None and o[1:] == (b.nr, b.M):
                n = np.arange(b.nr * b.M)              # both in g's order: instance-major, rows within
                out[self._offsets[b.name] + n] = np.asarray(values, float)[o[0] + n]
        return out

    def derivative_functions(self) -> dict[str, ca.Function]:
        """nlpsol options: grad_f (x, p) -> (f, grad_f_x), jac_g (x, p) -> (g, jac_g_x),
        hess_lag (x, p, lam_f, lam_g) -> triu_hess_gamma_x_x."""
        n, w = self.n, self.w
        lam_f = ca.MX.sym("lam_f")
        lam_g = ca.MX.sym("lam_g", self.ng)
        gr, gv, jr, jc, jv, hr, hc, hv = [], [], [], [], [], [], [], []
        for b in self.blocks:
            d, V, P, M = self._d[b.name], self._V[b.name], ca.DM(b.data), b.M
            ks = np.arange(M)
            if d.spg.nnz():
                _, gc = d.spg.get_triplet()                     # gradient: 1 x nv, columns are the variables
                gr.append(b.idx[np.asarray(gc), :].ravel(order="F"))
                gv.append(ca.vec(d.mapped("grad", M)(V, P)))
            if b.nr and d.spJ.nnz():
                r, c = (np.asarray(a) for a in d.spJ.get_triplet())
                jr.append((self._offsets[b.name] + ks[None, :] * b.nr + r[:, None]).ravel(order="F"))
                jc.append(b.idx[c, :].ravel(order="F"))
                jv.append(ca.vec(d.mapped("jac", M)(V, P)))
            if d.spH.nnz():
                r, c = (np.asarray(a) for a in d.spH.get_triplet())
                gi, gj = b.idx[r, :], b.idx[c, :]
                hr.append(np.minimum(gi, gj).ravel(order="F"))
                hc.append(np.maximum(gi, gj).ravel(order="F"))
                lam = ca.reshape(lam_g[self.rows(b.name).ravel(order="F").tolist()], b.nr, M) if b.nr \
                    else ca.MX(0, M)
                hv.append(ca.vec(d.mapped("hess", M)(V, P, ca.repmat(lam_f, 1, M), lam)))

        def cat(parts, empty):
            return np.concatenate(parts) if parts else empty

        none = np.zeros(0, dtype=np.int64)
        grad = assemble(n, 1, cat(gr, none), np.zeros(len(cat(gr, none)), dtype=np.int64),
                        ca.vertcat(*gv) if gv else ca.MX(0, 1))
        Jg = assemble(self.ng, n, cat(jr, none), cat(jc, none), ca.vertcat(*jv) if jv else ca.MX(0, 1))
        H = assemble(n, n, cat(hr, none), cat(hc, none), ca.vertcat(*hv) if hv else ca.MX(0, 1))
        p = ca.MX.sym("p", 0)
        return {
            "grad_f": ca.Function("nlp_grad_f", [w, p], [self.f, ca.densify(grad)], ["x", "p"], ["f", "grad_f_x"]),
            "jac_g": ca.Function("nlp_jac_g", [w, p], [self.g, Jg], ["x", "p"], ["g", "jac_g_x"]),
            "hess_lag": ca.Function("nlp_hess_l", [w, p, lam_f, lam_g], [H], ["x", "p", "lam_f", "lam_g"],
                                    ["triu_hess_gamma_x_x"]),
        }
