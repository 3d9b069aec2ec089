"""The orders of the NLP decision vector: node-major (:class:`NLPLayout`, IPOPT) and stage-ordered
(:class:`StageLayout`, fatrop).  :meth:`NLPLayout.pack` and :meth:`NLPLayout.unpack` are the only routines
that know the order."""
from __future__ import annotations

import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.state import NU, NX
from .blocks import NC


class NLPLayout:
    """Order of the NLP decision vector: node-major blocks [X_k, u_k?, s_k?, c_k?], k = 0..N, then
    the global h.

    X_k (18) at every node; u_k (6) and the objective's own variables s_k (``n_slack``) at the control nodes; c_k (3)
    at nodes 0..N-1 when ``with_c``; h last when ``free_h``.  Shapes: X (18, N+1), U (6, n_controls), S (n_slack,
    n_controls), C (3, N); ``iX``, ``iU``, ``iS``, ``iC`` their index arrays, ``ih`` the index of h (or None);
    ``iUn`` the node controls the control-node rows use (here iU).
    """

    def __init__(self, N: int, control_nodes: list[int] | range, with_c: bool, n_slack: int = 0, free_h: bool = False):
        self.N = int(N)
        self.control_nodes = list(control_nodes)
        self.with_c = bool(with_c)
        self.n_slack = int(n_slack)
        has_u = np.zeros(self.N + 1, dtype=bool)
        has_u[self.control_nodes] = True
        iX = np.zeros((NX, self.N + 1), dtype=int)
        iU = np.zeros((NU, len(self.control_nodes)), dtype=int)
        iS = np.zeros((self.n_slack, len(self.control_nodes)), dtype=int)
        iC = np.zeros((NC, self.N if with_c else 0), dtype=int)
        pos, ju = 0, 0
        for k in range(self.N + 1):
            iX[:, k] = np.arange(pos, pos + NX)
            pos += NX
            if has_u[k]:
                iU[:, ju] = np.arange(pos, pos + NU)
                pos += NU
                iS[:, ju] = np.arange(pos, pos + self.n_slack)
                pos += self.n_slack
                ju += 1
            if with_c and k < self.N:
                iC[:, k] = np.arange(pos, pos + NC)
                pos += NC
        self.ih = pos if free_h else None
        self.n = pos + (1 if free_h else 0)
        self.iX, self.iU, self.iS, self.iC = iX, iU, iS, iC
        self.iUn = iU

    def stage_controls(self, disc) -> np.ndarray:
        """Indices (nw, N) of the stage controls w_k (first_order: u_{k+1}; lgvi: [u_k; u_{k+1}])."""
        return np.rint(np.asarray(disc.stage_controls(self.iU.astype(float)))).astype(np.int64)

    def unpack(self, w):
        """w (n,) -> (X (18, N+1), U (6, nU), C (3, N) or None) (NumPy)."""
        w = np.asarray(w, dtype=float).ravel()
        return w[self.iX], w[self.iU], (w[self.iC] if self.with_c else None)

    def pack(self, X, U, C=None, S=None, h=None) -> np.ndarray:
        """NumPy (X (18, N+1), U (6, nU), C (3, N), S (n_slack, nU), h) -> w (n,).  C required iff
        ``with_c``; S (the objective's own variables) iff ``n_slack``; h required iff the layout has it."""
        w = np.full(self.n, np.nan)
        w[self.iX] = np.asarray(X, dtype=float)
        U = np.asarray(U, dtype=float)
        w[self.iU] = U
        if self.n_slack:
            w[self.iS] = np.asarray(S, dtype=float)
        if self.with_c:
            if C is None:
                raise ValueError("this layout has Cayley variables: C (3, N) is required")
            w[self.iC] = np.asarray(C, dtype=float)
        if self.ih is not None:
            if h is None:
                raise ValueError("this layout has a free step size: h is required")
            w[self.ih] = float(h)
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


class StageLayout(NLPLayout):
    """Stage-ordered decision vector for fatrop: [s_0, q_0, s_1, q_1, ..., s_N].

    first_order: state s_k = X_k (18), stage control q_k = [u_{k+1} (6); c_k (3); S_{k+1} (n_slack)].
    lgvi: the step couples u_k and u_{k+1}, so u_k is lifted into the state: s_k = [X_k; v_k]
    (24, v_k = u_k) and q_k = [u'_{k+1}; c_k; S_{k+1}; S_0 (k = 0 only)] with the gap v_{k+1} - u'_{k+1} = 0,
    (u_{k+1} appears twice).  S_j (n_slack) sits beside the copy of u_j the node's rows use (:attr:`iUn`), so each
    node's rows are path rows of one stage (node j >= 1 of stage j - 1, node 0 of stage 0).  iU: the node controls
    (lgvi: the v_j); iUp (lgvi): the copies u'_{k+1}; iUn (6, n_controls); iS (n_slack, n_controls); ns, nq: state
    and stage-control sizes (``nu`` per stage: q_0 carries S_0 too); ``stage_of`` (n,): each variable's stage.
    """

    def __init__(self, N: int, scheme: str, n_slack: int = 0):
        self.N, self.scheme, self.with_c, self.n_slack, self.ih = int(N), scheme, True, int(n_slack), None
        lift = two_point(scheme)
        self.ns, self.nq = NX + (NU if lift else 0), NU + NC + self.n_slack
        self.control_nodes = list(range(N + 1)) if lift else list(range(1, N + 1))
        iX = np.zeros((NX, N + 1), dtype=int)
        iV = np.zeros((NU, N + 1), dtype=int)
        iQ = np.zeros((NU, N), dtype=int)
        iC = np.zeros((NC, N), dtype=int)
        iS = np.zeros((self.n_slack, len(self.control_nodes)), dtype=int)
        stage_of, pos, j0 = [], 0, 1 if lift else 0     # column of S_{k+1} in iS
        for k in range(N + 1):
            start = pos
            iX[:, k] = np.arange(pos, pos + NX)
            pos += NX
            if lift:
                iV[:, k] = np.arange(pos, pos + NU)
                pos += NU
            if k < N:
                iQ[:, k] = np.arange(pos, pos + NU)
                iC[:, k] = np.arange(pos + NU, pos + NU + NC)
                iS[:, k + j0] = np.arange(pos + NU + NC, pos + self.nq)
                pos += self.nq
                if lift and k == 0:
                    iS[:, 0] = np.arange(pos, pos + self.n_slack)
                    pos += self.n_slack
            stage_of += [k] * (pos - start)
        self.n = pos
        self.stage_of = np.array(stage_of, dtype=int)
        self.nu = [self.nq + (self.n_slack if lift else 0)] + [self.nq] * (N - 1) + [0]
        self.iX, self.iC, self.iS = iX, iC, iS
        self.iU = iV if lift else iQ
        self.iUp = iQ if lift else None
        self.iUn = np.hstack([iV[:, :1], iQ]) if lift else iQ

    def stage_controls(self, disc) -> np.ndarray:
        return np.vstack([self.iU[:, :-1], self.iUp]) if self.iUp is not None else self.iU

    def pack(self, X, U, C=None, S=None, h=None) -> np.ndarray:
        w = np.full(self.n, np.nan)
        U = np.asarray(U, dtype=float)
        w[self.iX] = np.asarray(X, dtype=float)
        w[self.iU] = U
        w[self.iC] = np.asarray(C, dtype=float)
        if self.iUp is not None:
            w[self.iUp] = U[:, 1:]
        if self.n_slack:
            w[self.iS] = np.asarray(S, dtype=float)
        if np.isnan(w).any():
            raise ValueError("pack: some entries were not filled (shape mismatch?)")
        return w


def control_nodes(disc, N: int) -> range:
    """Nodes carrying a control: 0..N (lgvi) or 1..N (first_order)."""
    return range(0, N + 1) if two_point(disc.scheme) else range(1, N + 1)
