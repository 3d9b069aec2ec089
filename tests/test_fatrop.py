"""fatrop on the direct NLP (issue 6): same answers as IPOPT, stage structure, IPOPT fallback.

Small N (fast); the speed comparison is scripts/bench.py's job.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

import examples as ex
from se3ocp.transcription.direct import StageLayout, solve_direct
from se3ocp.transcription.layout import NU, NX

N = 40


@lru_cache(maxsize=None)
def solved(name: str, scheme: str, solver: str, **kw):
    return solve_direct(getattr(ex, name)(N=N, scheme=scheme, solver=solver, **kw))


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
@pytest.mark.parametrize("name", ["e3", "e4"])
def test_fatrop_equals_ipopt(name, scheme):
    ip, fa = solved(name, scheme, "ipopt"), solved(name, scheme, "fatrop")
    assert ip.converged and fa.converged, (ip.message, fa.message)
    assert fa.solver == "fatrop" and fa.extra["fatrop_fallback"] is False, fa.message
    rel = abs(fa.cost - ip.cost) / ip.cost
    u_rel = np.abs(fa.controls - ip.controls).max() / np.abs(ip.controls).max()
    lam_rel = np.abs(fa.costates - ip.costates).max() / np.abs(ip.costates).max()
    print(f"{name} {scheme}: cost rel {rel:.1e}, controls {u_rel:.1e}, costates {lam_rel:.1e}, "
          f"terminal error {fa.terminal_error:.1e}, iterations {fa.iterations} (IPOPT {ip.iterations})")
    assert rel <= 1e-8
    assert u_rel <= 1e-6 and lam_rel <= 1e-5
    assert fa.terminal_error <= 1e-9


@pytest.mark.parametrize("scheme", ["first_order", "lgvi"])
def test_stage_layout_order_and_lifting(scheme):
    lay = StageLayout(5, scheme)
    ns = NX + (NU if scheme == "lgvi" else 0)
    assert lay.ns == ns and lay.nq == NU + 3
    assert lay.n == (N_ := 5) * (ns + lay.nq) + ns
    # [s_0, q_0, s_1, q_1, ..., s_N]: state k starts at k (ns + nq)
    for k in range(N_ + 1):
        assert lay.iX[0, k] == k * (ns + lay.nq)
    idx = np.concatenate([lay.iX.ravel(), lay.iU.ravel(), lay.iC.ravel()] +
                         ([lay.iUp.ravel()] if lay.iUp is not None else []))
    assert np.array_equal(np.sort(idx), np.arange(lay.n))
    rng = np.random.default_rng(0)
    X, U, C = rng.normal(size=(NX, 6)), rng.normal(size=(NU, len(lay.control_nodes))), rng.normal(size=(3, 5))
    X2, U2, C2 = lay.unpack(lay.pack(X, U, C))
    assert np.array_equal(X, X2) and np.array_equal(U, U2) and np.array_equal(C, C2)


def test_fatrop_failure_falls_back_to_ipopt():
    s = solve_direct(ex.e3(N=20, scheme="first_order", solver="fatrop", fatrop_options={"max_iter": 1}))
    assert s.converged and s.solver == "ipopt"
    assert s.extra["fatrop_fallback"] is True and "fatrop did not converge" in s.message
    assert "IPOPT fallback" in s.message and s.extra["fatrop_status"] != "Solve_Succeeded"


def test_bad_fatrop_option_is_reported_in_the_fallback():
    s = solve_direct(ex.e3(N=20, scheme="first_order", solver="fatrop", fatrop_options={"no_such_option": 1}))
    assert s.converged and s.solver == "ipopt" and "no_such_option" in s.message
