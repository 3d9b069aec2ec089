"""Method-level problem statements: what the direct and indirect methods solve.

They carry numbers and a :class:`~transcription.lgvi.Discretization` only; the
YAML layer (``problems.maneuvers``) builds them.  All states are 18-vectors in the
layout of :mod:`transcription.layout` (momenta, not velocities).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .lgvi import Discretization


@dataclass(frozen=True)
class SmoothProblem:
    """SPEC §6: min sum (h/2)(u_f^T W_f u_f + u_m^T W_m u_m) s.t. the discrete
    dynamics, X_0 = X0 and X_N = Xd (x, gamma, Pi equal; R: vee log(Rd^T R_N) = 0).

    disc: the scheme (first_order: controls u_1..u_N; lgvi: u_0..u_N, trapezoidal
    weights h/2 at both ends of each step).  W_f, W_m: diagonal weights (3,).
    """

    disc: Discretization
    N: int
    T: float
    X0: np.ndarray
    Xd: np.ndarray
    W_f: np.ndarray
    W_m: np.ndarray
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def h(self) -> float:
        return self.T / self.N


@dataclass(frozen=True)
class OrbitTarget:
    """Relaxed terminal set of SPEC §5: circular orbit of radius r about unit normal e_n."""

    radius: float
    normal: np.ndarray


@dataclass(frozen=True)
class ImpulsiveProblem:
    """SPEC §5: impulses at t = 0 and t = T, free motion between (u = 0).

    terminal is either an 18-vector Xd (TPBVP: R_N, x_N given, gamma_N^+ and
    Pi_N^+ the momenta required after the terminal impulse) or an OrbitTarget.
    mu: gravitational parameter, needed for the circular velocity of the relaxed case.
    """

    disc: Discretization
    N: int
    T: float
    X0: np.ndarray
    terminal: np.ndarray | OrbitTarget
    mu: float
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def h(self) -> float:
        return self.T / self.N
