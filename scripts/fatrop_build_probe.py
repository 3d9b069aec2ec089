"""How long CasADi's fatrop interface takes to *set up*, on a problem with nothing of ours in it.

    .venv/bin/python scripts/fatrop_build_probe.py            # N = 250, 500, 1000
    .venv/bin/python scripts/fatrop_build_probe.py 250 2000

A linear OCP with our stage sizes (18 states, 9 controls: u (6) and the Cayley variables c (3),
gap rows x_{k+1} - (A x_k + B u_k), 18 terminal rows), the structure stated
(``structure_detection: manual``), built with ``nlpsol(..., 'fatrop', ...)`` and the same NLP
with IPOPT for contrast.  Prints the setup time of each and the log-log slope in N.  This isolates
the quadratic setup of the interface (block-sparsity assembly inside CasADi's fatrop plugin) from
our transcription: see docs/bench_notes.md, section fatrop.
"""
from __future__ import annotations

import sys
import time

import casadi as ca
import numpy as np

NX, NU = 18, 9


def linear_ocp(N: int):
    """(x, f, g, structure options) of a random linear-quadratic OCP in fatrop's stage order."""
    rng = np.random.default_rng(0)
    A, B = ca.DM(rng.standard_normal((NX, NX)) * 0.1), ca.DM(rng.standard_normal((NX, NU)))
    xs = [ca.MX.sym(f"x{k}", NX) for k in range(N + 1)]
    us = [ca.MX.sym(f"u{k}", NU) for k in range(N)]
    w, g = [], []
    for k in range(N):
        w += [xs[k], us[k]]
        g.append(xs[k + 1] - (ca.mtimes(A, xs[k]) + ca.mtimes(B, us[k])))
    w.append(xs[N])
    g.append(xs[N])
    f = sum(ca.sumsqr(u) for u in us)
    G = ca.vertcat(*g)
    structure = {"structure_detection": "manual", "N": N, "nx": [NX] * (N + 1), "nu": [NU] * N + [0],
                 "ng": [0] * N + [NX], "equality": [True] * G.shape[0]}
    return ca.vertcat(*w), f, G, structure


def main(argv: list[str]) -> int:
    Ns = [int(a) for a in argv] or [250, 500, 1000]
    rows = []
    for N in Ns:
        x, f, g, structure = linear_ocp(N)
        t0 = time.perf_counter()
        ca.nlpsol("probe_fatrop", "fatrop", {"x": x, "f": f, "g": g}, {**structure, "fatrop": {"print_level": 0}})
        t_fat = time.perf_counter() - t0
        t0 = time.perf_counter()
        ca.nlpsol("probe_ipopt", "ipopt", {"x": x, "f": f, "g": g}, {"ipopt": {"print_level": 0}, "print_time": False})
        t_ip = time.perf_counter() - t0
        rows.append((N, t_fat, t_ip))
        print(f"N = {N:5d}: fatrop setup {t_fat:7.3f} s   IPOPT setup {t_ip:7.3f} s", flush=True)
    if len(rows) >= 2:
        lN = np.log([r[0] for r in rows])
        print(f"log-log slope in N: fatrop {np.polyfit(lN, np.log([r[1] for r in rows]), 1)[0]:.2f}, "
              f"IPOPT {np.polyfit(lN, np.log([r[2] for r in rows]), 1)[0]:.2f}  (casadi {ca.__version__})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
