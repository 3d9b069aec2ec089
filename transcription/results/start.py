"""Where a solve starts: one :class:`Start` -- node states, controls, their times, and what a solver can reuse of a
previous solve (NLP multipliers, costates, the shooting unknown) -- and its resampling onto another grid on SE(3).

Every Solution carries its Start (``sol.warm``; None when nothing is usable); ``solve(..., warm_start=sol)`` accepts it
whatever method, N and scheme produced it (:meth:`Start.fit` maps it onto the problem's grid).  The starts a strategy
makes (:mod:`transcription.strategy.starts`) are Starts too, their ``origin`` saying which.  Resampling
(docs/mathematics.md §4) is in normalized time s = k/N of the horizon: positions and momenta linear, attitudes along the
geodesic R_a exp(s log(R_a^T R_b)) (:func:`~transcription.geometry.so3.geodesic_interpolation`), controls at the new
control times (LGVI: nodes; first order: step midpoints), costates at the step midpoints.  The NLP multipliers are
reused only by an NLP of the same structure (``nlp_key``), the exact point only by the same NLP (``point``), ``lam0``
only on the same grid; elsewhere they are dropped and the notes say so.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..dynamics.lgvi import two_point
from ..geometry.so3 import exp_so3, geodesic_interpolation, log_so3_any
from ..geometry.state import NU, NX, NZ, X_ANG, X_MOM, X_POS, cayley_vectors, pack_state, unpack_states
from ..outcome import Code


class Origin(Code):
    """What a Start is: a solution of a solve (``solution``) or a start made from the problem's data."""

    solution = "solution"
    rollout = "rollout"
    interpolate = "interpolate"
    orbit = "orbit"
    aimed = "aimed"


@dataclass(frozen=True)
class Point:
    """The exact point of one NLP: x and the multipliers lam_g, lam_x (None: not given) in its scaling, and ``key``,
    its identity (structure and scales): an NLP with the same key starts from it as it is."""

    key: tuple
    x: np.ndarray
    lam_g: np.ndarray | None = None
    lam_x: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Start:
    """Where a solve starts.  Primal: ``t`` (N+1,) node times, ``X`` (N+1, 18) node states (layout of
    transcription.geometry.state), ``U`` (6, n_controls) controls at the scheme's control nodes (lgvi u_0..u_N,
    first_order u_1..u_N), ``scheme``; T = t[-1], the mean step h = T / N (a free final time starts there).  ``origin``
    (:class:`Origin`) and ``source`` (the method that solved it, '' for a made start).  Dual: ``multipliers``, the
    direct method's NLP constraint multipliers in physical units, with ``nlp_key``, the structure of their NLP;
    ``point``, the exact primal-dual point of its NLP (:class:`Point`); ``costates`` (N, 12) lambda_0..lambda_{N-1};
    ``lam0`` (12,), the indirect method's shooting unknown (lambda_0; lgvi lambda_{-1}).  Absent parts are None.
    """

    t: np.ndarray
    X: np.ndarray
    U: np.ndarray
    scheme: str
    origin: Origin = Origin.solution
    source: str = ""
    multipliers: np.ndarray | None = None
    nlp_key: tuple | None = None
    point: Point | None = None
    costates: np.ndarray | None = None
    lam0: np.ndarray | None = None

    @property
    def N(self) -> int:
        return len(self.t) - 1

    @property
    def T(self) -> float:
        return float(self.t[-1])

    @property
    def h(self) -> float:
        return self.T / self.N

    @property
    def C(self) -> np.ndarray:
        """c_k = cay^-1(R_k^T R_{k+1}) (N, 3): the Cayley vectors of the steps, consistent with the attitudes."""
        return cayley_vectors(self.X)

    @property
    def finite(self) -> bool:
        return bool(np.all(np.isfinite(self.X)) and np.all(np.isfinite(self.U)))

    def __repr__(self) -> str:
        parts = [name for name, v in (("multipliers", self.multipliers), ("costates", self.costates),
                                      ("lambda_0", self.lam0)) if v is not None]
        return f"Start({self.describe()}, T = {self.T:.6g}; states, controls{''.join(', ' + p for p in parts)})"

    def describe(self) -> str:
        """'the direct solution (N = 100, first_order)', 'the rollout (N = 100, lgvi)'."""
        what = f"{self.source} solution" if self.origin is Origin.solution and self.source else str(self.origin)
        return f"the {what} (N = {self.N}, {self.scheme})"

    def fit(self, N: int, scheme: str, s: np.ndarray | None = None) -> tuple["Start", tuple[str, ...]]:
        """This start on N steps of ``scheme`` over its own T (module docstring), and notes on what was resampled and
        dropped.  ``s``: normalized node times (N+1,) of a non-uniform mesh (None: uniform).  The same object, no
        notes, when N, scheme and node times agree."""
        own = self.s
        sf = np.linspace(0.0, 1.0, N + 1) if s is None else np.asarray(s, dtype=float)
        if N == self.N and scheme == self.scheme and (s is None and self.uniform or
                                                      s is not None and np.allclose(sf, own, rtol=0, atol=1e-12)):
            return self, ()
        t = sf * self.T if s is not None else np.linspace(0.0, self.T, N + 1)
        X = resample_states(self.X, N, own, sf)
        U = resample_controls(self.U, self.scheme, scheme, N, own, sf)
        lam = None if self.costates is None else resample_costates(self.costates, N, own, sf)
        mesh = "" if s is None else " (a non-uniform mesh)"
        notes = [f"resampled from N = {self.N} ({self.scheme}) to N = {N}{mesh} ({scheme}) on SE(3)"]
        dropped = [what for what, part in (("the NLP multipliers", self.multipliers),
                                           ("the shooting unknown lambda_0", self.lam0)) if part is not None]
        if dropped:
            notes.append(f"{' and '.join(dropped)} not reused (they belong to the other grid)")
        return Start(t=t, X=X, U=U, scheme=scheme, origin=self.origin, source=self.source, costates=lam), tuple(notes)

    def primal(self) -> "Start":
        """This start without its dual parts (multipliers, point, costates, lambda_0)."""
        return replace(self, multipliers=None, nlp_key=None, point=None, costates=None, lam0=None)

    @property
    def uniform(self) -> bool:
        """Its node times are equally spaced (to round-off)."""
        d = np.diff(self.t)
        return bool(np.all(np.abs(d - d.mean()) <= 1e-9 * abs(d.mean())))

    @property
    def s(self) -> np.ndarray:
        """Its normalized node times (N+1,) in [0, 1]: k/N when uniform (exactly), else t / T."""
        return np.linspace(0.0, 1.0, self.N + 1) if self.uniform else self.t / self.T

    def tail(self, k: int) -> "Start":
        """The remaining horizon from node k (0 <= k < N), shifted to t = 0 (re-plans, docs/mathematics.md §12):
        X_k..X_N, the controls of steps k..N-1, lambda_k..lambda_{N-1}, and the remaining problem's shooting unknown
        lambda_{k-1} (lgvi; k = 0: own lam0) or lambda_k (first order).  The NLP multipliers are dropped."""
        if not 0 <= k < self.N:
            raise ValueError(f"tail: expected a node 0 <= k < {self.N}, got {k}")
        lam = self.costates
        if two_point(self.scheme):
            lam0 = self.lam0 if k == 0 else (None if lam is None else lam[k - 1])
        else:
            lam0 = self.lam0 if k == 0 and self.lam0 is not None else (None if lam is None else lam[k])
        return Start(t=self.t[k:] - self.t[k], X=self.X[k:], U=self.U[:, k:], scheme=self.scheme, origin=self.origin,
                     source=self.source, costates=None if lam is None else lam[k:],
                     lam0=None if lam0 is None else np.array(lam0, dtype=float))


def start_of(t: np.ndarray, X: np.ndarray, U: np.ndarray | None, scheme: str, source: str, **dual) -> Start | None:
    """The Start of a solution (node times t, states X (N+1, 18), controls U, its scheme and method; ``dual``:
    multipliers, nlp_key, point, costates, lam0), or None when there is nothing usable: no controls or non-finite
    states or controls (a dual part that is not finite is left out)."""
    if U is None or not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
        return None
    dual = {k: v for k, v in dual.items()
            if v is not None and (k in ("nlp_key", "point") or np.all(np.isfinite(np.asarray(v, float))))}
    if "multipliers" not in dual:
        dual.pop("nlp_key", None)
    arrays = {k: (np.array(v, dtype=float) if k not in ("nlp_key", "point") else v) for k, v in dual.items()}
    return Start(t=np.array(t, dtype=float), X=np.array(X, dtype=float), U=np.array(U, dtype=float), scheme=scheme,
                 source=source, **arrays)


def secant(w0: Start, w1: Start, r: float) -> Start | None:
    """The secant predictor of a continuation, w1 + r (w1 - w0) for starts of one grid, on SE(3): attitudes
    R_1 Exp(r Log(R_0^T R_1)), everything else (multipliers only of one NLP structure) linearly.  None when their
    grids or schemes differ; a part only one carries is left out."""
    if (w0.N, w0.scheme, w0.U.shape) != (w1.N, w1.scheme, w1.U.shape):
        return None

    def lin(a, b):
        return None if a is None or b is None or np.shape(a) != np.shape(b) else b + r * (b - a)

    s0, s1 = unpack_states(w0.X), unpack_states(w1.X)
    R = np.array([R1 @ exp_so3(r * log_so3_any(R0.T @ R1)) for R0, R1 in zip(s0.R, s1.R)])
    X = pack_state(lin(s0.x, s1.x), lin(s0.gamma, s1.gamma), R, lin(s0.Pi, s1.Pi))
    same_nlp = w0.nlp_key is not None and w0.nlp_key == w1.nlp_key
    return Start(t=lin(w0.t, w1.t), X=X, U=lin(w0.U, w1.U), scheme=w1.scheme, source=w1.source,
                 multipliers=lin(w0.multipliers, w1.multipliers) if same_nlp else None,
                 nlp_key=w1.nlp_key if same_nlp else None, costates=lin(w0.costates, w1.costates),
                 lam0=lin(w0.lam0, w1.lam0))


def as_start(given) -> tuple[Start | None, str]:
    """The Start of what a caller passed as ``warm_start`` (a Start, a Solution or None), and a note when a Solution
    carries nothing usable."""
    if given is None or isinstance(given, Start):
        return given, ""
    warm = getattr(given, "warm", None)
    if isinstance(warm, Start):
        return warm, ""
    if hasattr(given, "result") and hasattr(given, "trajectory"):
        return None, f"the warm start given ({given.method}, {given.result}) carries nothing usable: solved cold"
    raise TypeError(f"warm_start: expected a Solution or a Start, got {type(given).__name__}")


# ------------------------------------------------------------------------------- resampling
def _nodes(N: int, s: np.ndarray | None) -> np.ndarray:
    """Normalized node times (N+1,) in [0, 1]: ``s`` itself, or the uniform k/N."""
    return np.linspace(0.0, 1.0, N + 1) if s is None else np.asarray(s, dtype=float)


def _midpoints(s: np.ndarray) -> np.ndarray:
    """The step midpoints (N,) of node times s (N+1,)."""
    return 0.5 * (s[:-1] + s[1:])


def resample_states(X: np.ndarray, N: int, sc: np.ndarray | None = None, sf: np.ndarray | None = None) -> np.ndarray:
    """Node states X (M+1, 18) at the N+1 nodes of the same horizon (module docstring): positions and momenta
    linear in time, attitudes by geodesic interpolation; the end nodes are copied exactly.  ``sc``, ``sf``: the
    normalized node times of the given and the new grid (None: uniform)."""
    M = X.shape[0] - 1
    sc, sf = _nodes(M, sc), _nodes(N, sf)
    Xf = np.empty((N + 1, NX))
    for sl in (X_POS, X_MOM, X_ANG):
        for i in range(sl.start, sl.stop):
            Xf[:, i] = np.interp(sf, sc, X[:, i])
    s = unpack_states(Xf)
    Xf = pack_state(s.x, s.gamma, geodesic_interpolation(unpack_states(X).R, sc, sf), s.Pi)
    Xf[0], Xf[-1] = X[0], X[-1]
    return Xf


def resample_controls(U: np.ndarray, scheme: str, new_scheme: str, N: int, sc: np.ndarray | None = None,
                      sf: np.ndarray | None = None) -> np.ndarray:
    """Controls U (6, n) of ``scheme`` at the control times of N steps of ``new_scheme``: linear in time
    between the control times (LGVI: nodes; first order: step midpoints), held beyond the first and last
    (``sc``, ``sf`` as in :func:`resample_states`)."""
    M = U.shape[1] - 1 if two_point(scheme) else U.shape[1]
    sc, sf = _nodes(M, sc), _nodes(N, sf)
    uc = sc if two_point(scheme) else _midpoints(sc)
    uf = sf if two_point(new_scheme) else _midpoints(sf)
    return np.vstack([np.interp(uf, uc, U[i]) for i in range(NU)])


def resample_costates(lam: np.ndarray, N: int, sc: np.ndarray | None = None, sf: np.ndarray | None = None) -> np.ndarray:
    """Costates lambda_k (M, 12) of the steps (at their midpoints) on N steps, linear in time (``sc``, ``sf`` as
    in :func:`resample_states`)."""
    mc, mf = _midpoints(_nodes(lam.shape[0], sc)), _midpoints(_nodes(N, sf))
    return np.column_stack([np.interp(mf, mc, lam[:, i]) for i in range(NZ)])
