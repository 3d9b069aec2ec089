"""Convergence of the indirect method, like the paper's Fig. 3(b)/4(b).

Runs Newton-Armijo shooting (docs/mathematics.md §6) on E3 and E4 (first-order scheme) from
lambda_0 = 0 with eps_S = 0, i.e. down to the round-off floor, and plots the
terminal error |z_N|_2 (log scale) against every line-search trial, outer
iterations circled.  One panel per example.

    .venv/bin/python scripts/fig_convergence.py                   # N = 500, docs/figures/
    .venv/bin/python scripts/fig_convergence.py --N 100 --out /tmp/conv
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import se3ocp  # noqa: E402


def draw(ax, sol, title):
    """All trials of ``sol.history`` (one point each), accepted ones (outer iterations) circled."""
    err = np.array([r.residual for r in sol.history])
    err = np.where(err > 0, err, np.nan)
    ax.semilogy(np.arange(err.size), err, ".-", lw=1, ms=4, color="tab:red", label="line-search trials")
    acc = [i for i, r in enumerate(sol.history) if r.accepted]
    ax.semilogy(acc, err[acc], "o", mfc="none", ms=8, color="tab:red", label="outer iterations")
    ax.set_title(f"{title}: {sol.iterations} outer iterations, {sol.result}\n"
                 f"final |z_N| = {sol.stats['residual_norm']:.1e}, cost {sol.cost:.6g}", fontsize=9)
    ax.set_xlabel("line-search trial")
    ax.grid(alpha=0.3, which="both")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--N", type=int, default=500)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(9.6, 3.8), sharey=True)
    for ax, (name, stem) in zip(axes, (("E3", "e3_inclination_change"), ("E4", "e4_orbital_capture"))):
        man = se3ocp.load(ROOT / "configs" / f"{stem}.yaml", [f"horizon.N={a.N}", "discretization=first_order"])
        sol = se3ocp.solve(man, "indirect", eps_S=0.0, initial_costate="zero")
        errs = " ".join(f"{r.residual:.1e}" for r in sol.history if r.accepted)
        print(f"{name} N={a.N}: {sol.result}: {sol.message}\n  outer |z_N|: {errs}\n  "
              f"terminal error {sol.terminal_error:.2e}, cost {sol.cost:.10g}, C = {sol.stats['quadratic_C']}")
        draw(ax, sol, name)
    axes[0].set_ylabel("terminal error |z_N| (log scale)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    paths = [a.out / f"indirect_convergence_N{a.N}.{ext}" for ext in ("png", "pdf")]
    for p in paths:
        fig.savefig(p, dpi=150)
    print("wrote", *paths)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
