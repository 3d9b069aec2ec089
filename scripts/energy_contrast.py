"""Energy and orthogonality over long free motion: LGVI vs classical RK4 (docs/mathematics.md §8).

The tumbling dumbbell on the reference orbit (x0 = (1,0,0), v0 = (0, 2 pi, 0),
R0 = I, Omega0 = (1, -2, 3) + 2 pi e3), free motion for ``--orbits`` orbits (period
1) at h = 1e-3 (``--h``), integrated by

* the second-order LGVI of docs/mathematics.md §2 (transcription.dynamics.lgvi, scheme 'lgvi');
* classical RK4 on the continuous equations (1)-(4) with R carried as 9 numbers,
  no re-orthonormalization.

Prints, for each: the max relative energy error |E/E0 - 1| over the first 10 and
the last 10 orbits, and the orthogonality |R^T R - I|_F and |det R - 1| at the end.

    python scripts/energy_contrast.py [--orbits 100] [--h 1e-3] [--plot energy.png]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from se3ocp.problems.models import Dumbbell  # noqa: E402
from se3ocp.transcription.geometry.state import NX, join_state, pack_state, split_state, unpack_states  # noqa: E402
from se3ocp.transcription.dynamics.lgvi import Discretization  # noqa: E402
from se3ocp.transcription.geometry.so3 import hat, orthogonality_error  # noqa: E402

H = 1e-3
CHUNK = 2000


def rk4_simulate(model, X0: np.ndarray, h: float, N: int) -> np.ndarray:
    """Classical RK4 of eqs. (1)-(4) with u = 0 on the 18-vector layout; returns (N+1, 18)."""
    X = ca.SX.sym("X", NX)
    x, gamma, R, Pi = split_state(X)
    f, M = model.forces(x, R)
    omega = ca.mtimes(ca.DM(np.linalg.inv(model.inertia)), Pi)
    Xdot = join_state(gamma / model.mass, f, ca.mtimes(R, hat(omega)), ca.cross(Pi, omega) + M)
    rhs = ca.Function("rhs", [X], [Xdot])
    k1 = rhs(X)
    k2 = rhs(X + h / 2 * k1)
    k3 = rhs(X + h / 2 * k2)
    k4 = rhs(X + h * k3)
    step = ca.Function("rk4_step", [X], [X + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)]).expand()
    out = [X0[None, :]]
    Xk = X0
    for s in range(0, N, CHUNK):
        n = min(CHUNK, N - s)
        Xs = np.array(step.mapaccum("rk4_acc", n)(Xk)).T
        out.append(Xs)
        Xk = Xs[-1]
    return np.vstack(out)


def summarize(model, X: np.ndarray, per_orbit: int) -> dict:
    E = np.array(model.energy().map(X.shape[0])(X.T)).ravel()
    rel = np.abs(E / E[0] - 1.0)
    orth, det = orthogonality_error(unpack_states(X[-1]).R)
    n10 = min(10 * per_orbit, X.shape[0] - 1)
    return {
        "rel": rel,
        "first10": rel[: n10 + 1].max(),
        "last10": rel[-(n10 + 1) :].max(),
        "orth": float(orth[0]),
        "det": float(det[0]),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--orbits", type=int, default=100, help="number of orbits (period 1), default 100")
    ap.add_argument("--h", type=float, default=H, help=f"step size, default {H:g} (the acceptance figure's)")
    ap.add_argument("--plot", type=Path, default=None, metavar="PATH", help="write a PNG of the energy error vs time")
    args = ap.parse_args(argv)
    if args.orbits < 10:
        ap.error("--orbits must be at least 10")
    per_orbit = int(round(1.0 / args.h))
    if not args.h > 0 or abs(per_orbit * args.h - 1.0) > 1e-12:
        ap.error("--h must divide the period 1 (e.g. 1e-3, 2e-3, 5e-3)")
    h = args.h

    db = Dumbbell()
    model = db.body_model()
    X0 = pack_state([1.0, 0.0, 0.0], [0.0, db.mass * 2 * np.pi, 0.0], np.eye(3), db.inertia @ np.array([1.0, -2.0, 3.0 + 2 * np.pi]))
    N = args.orbits * per_orbit

    runs = {}
    t0 = time.perf_counter()
    X_lgvi, res = Discretization(model, "lgvi").simulate(X0, None, h, N)
    runs["LGVI"] = (X_lgvi, time.perf_counter() - t0)
    t0 = time.perf_counter()
    runs["RK4"] = (rk4_simulate(model, X0, h, N), time.perf_counter() - t0)

    print(f"tumbling dumbbell, free motion, {args.orbits} orbits, h = {h:g} ({N} steps); "
          f"LGVI max Cayley residual {res.max():.1e}")
    print(f"| method | max rel. energy error, orbits 1-10 | orbits {args.orbits - 9}-{args.orbits} "
          f"| final ‖RᵀR − I‖ | final |det R − 1| | runtime |")
    print("|---|---|---|---|---|---|")
    stats = {}
    for name, (X, elapsed) in runs.items():
        s = stats[name] = summarize(model, X, per_orbit)
        print(f"| {name} | {s['first10']:.2e} | {s['last10']:.2e} | {s['orth']:.1e} | {s['det']:.1e} | {elapsed:.1f} s |")

    if args.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        t = np.arange(N + 1) * h
        stride = max(1, N // 20000)
        fig, ax = plt.subplots(figsize=(7, 4))
        for name, s in stats.items():
            ax.semilogy(t[::stride], np.maximum(s["rel"][::stride], 1e-17), lw=0.7, label=name)
        ax.set_xlabel("time (orbital periods)")
        ax.set_ylabel("relative energy error |E/E₀ − 1|")
        ax.set_title(f"Tumbling dumbbell, free motion, h = {h:g}")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"plot written to {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
