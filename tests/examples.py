"""The four examples of SPEC §7 as problem objects, built in Python (no YAML).

Velocities are given in SPEC §7; momenta follow: gamma = m v (inertial),
Pi = J Omega (body).  ``N`` defaults to the SPEC value and can be lowered for
fast tests (T is kept, so h = T/N grows).

    e1(N=800, scheme='lgvi')  -> ImpulsiveProblem, TPBVP (Xd an 18-vector)
    e2(N=800, scheme='lgvi')  -> ImpulsiveProblem, OrbitTarget(2, Rx(10) e3)
    e3(N=500, scheme='lgvi', W_m=1e4, **options) -> SmoothProblem
    e4(N=500, scheme='lgvi', W_m=1e4, **options) -> SmoothProblem
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from se3ocp.problems.dumbbell import Dumbbell
from se3ocp.transcription.layout import pack_state
from se3ocp.transcription.lgvi import Discretization
from se3ocp.transcription.lie import rot_x, rot_y, rot_z
from se3ocp.transcription.problem import ImpulsiveProblem, OrbitTarget, SmoothProblem

TWO_PI = 2.0 * np.pi
BODY = Dumbbell()
E3_VEC = np.array([0.0, 0.0, 1.0])


@lru_cache(maxsize=None)
def disc(scheme: str = "lgvi") -> Discretization:
    """One Discretization per scheme for the default dumbbell (Functions built once)."""
    return Discretization(BODY.body_model(), scheme)


def state(x, v, R, Omega) -> np.ndarray:
    """18-vector from position, inertial velocity, attitude and body angular velocity."""
    return pack_state(np.asarray(x, float), BODY.mass * np.asarray(v, float), np.asarray(R, float),
                      BODY.inertia @ np.asarray(Omega, float))


def x0_reference_orbit() -> np.ndarray:
    """Start on the reference orbit: x=(1,0,0), v=(0,2pi,0), R=I, Omega=(0,0,2pi)."""
    return state([1, 0, 0], [0, TWO_PI, 0], np.eye(3), [0, 0, TWO_PI])


def e1(N: int = 800, scheme: str = "lgvi", **options) -> ImpulsiveProblem:
    """E1: impulsive TPBVP, orbit radius 1 -> 2 at 150 deg, R_N = Rz(150) Ry(90), Omega_N+ = 0."""
    th = np.deg2rad(150.0)
    xN = 2.0 * np.array([np.cos(th), np.sin(th), 0.0])
    vN = np.sqrt(BODY.mu / 2.0) * np.cross(E3_VEC, xN / 2.0)
    Xd = state(xN, vN, rot_z(150) @ rot_y(90), np.zeros(3))
    return ImpulsiveProblem(disc=disc(scheme), N=N, T=0.8, X0=x0_reference_orbit(), terminal=Xd, mu=BODY.mu,
                            options=dict(options))


def e2(N: int = 800, scheme: str = "lgvi", **options) -> ImpulsiveProblem:
    """E2: impulsive, relaxed: circular orbit r_d = 2 with normal Rx(10) e3, axis along the normal."""
    target = OrbitTarget(radius=2.0, normal=rot_x(10) @ E3_VEC)
    return ImpulsiveProblem(disc=disc(scheme), N=N, T=0.8, X0=x0_reference_orbit(), terminal=target, mu=BODY.mu,
                            options=dict(options))


def e3(N: int = 500, scheme: str = "lgvi", W_m: float = 1e4, **options) -> SmoothProblem:
    """E3: smooth control, inclination change by 30 deg (T = 0.5, W_f = I, W_m = 1e4 I by default)."""
    Rd = rot_x(30) @ rot_z(180)
    Xd = state([-1, 0, 0], rot_x(30) @ np.array([0, -TWO_PI, 0]), Rd, Rd.T @ rot_x(30) @ np.array([0, 0, TWO_PI]))
    return SmoothProblem(disc=disc(scheme), N=N, T=0.5, X0=x0_reference_orbit(), Xd=Xd, W_f=np.ones(3),
                         W_m=W_m * np.ones(3), options=dict(options))


def e4(N: int = 500, scheme: str = "lgvi", W_m: float = 1e4, **options) -> SmoothProblem:
    """E4: smooth control, orbital capture from a fast tumbling start."""
    X0 = state([1, 0, 0], [0, 1.2 * TWO_PI, 0], np.eye(3), [1, -2, 3])
    Xd = state([-1, 0, 0], [0, -TWO_PI, 0], rot_z(180), [0, 0, TWO_PI])
    return SmoothProblem(disc=disc(scheme), N=N, T=0.5, X0=X0, Xd=Xd, W_f=np.ones(3), W_m=W_m * np.ones(3),
                         options=dict(options))
