"""The weighted sum of effort and time (transcription/objectives/effort_time.py): min effort + rho T over the final
time in its bounds, checked against the effort objective at fixed final times (an independent formulation: the
fixed-T NLP has no time variable and no time cost)."""
from __future__ import annotations

import pytest

import se3ocp
from se3ocp.transcription.objectives import OBJECTIVES, named
from se3ocp.transcription.objectives.effort_time import EffortTime
from se3ocp.transcription.ocp import ProblemError
from support import maneuver

#: configs/e3_free_time.yaml (T in [0.4, 0.6]) on 40 steps
SETS = ("horizon.N=40",)
RHO = 100.0


def _fixed(T: float) -> float:
    """The effort optimum of the file at the fixed final time T."""
    sol = se3ocp.solve(maneuver("e3_free_time", None, None, *SETS, f"horizon.T={T!r}"))
    assert sol.converged, sol.message
    return sol.cost


def test_the_objective_is_named_and_checked():
    """The registry names it; a negative rho is a ProblemError naming the field; a maneuver file takes it as
    {kind: effort_time, rho: ...}."""
    assert OBJECTIVES["effort_time"] is EffortTime and named("effort_time", rho=2.0) == EffortTime(rho=2.0)
    with pytest.raises(ProblemError, match="rho"):
        EffortTime(rho=-1.0)
    man = maneuver("e3_free_time", None, None, *SETS, f"control.objective={{kind: effort_time, rho: {RHO}}}")
    assert man.problem.control.objective == EffortTime(rho=RHO)


def test_the_optimum_is_where_the_effort_falls_at_the_rate_rho():
    """With rho = 100 the optimum T* is inside (0.4, 0.6), its cost is the fixed-T effort optimum at T* plus rho T*
    (1e-8 relative: the same discrete problem), and the fixed-T optimum's slope there is -rho (central difference,
    dT = 1e-3 T*: 1e-4 relative to rho) -- the stationarity of effort + rho T in T; the costs at T* +- dT are above
    the optimum's (a minimum, not a maximum)."""
    man = maneuver("e3_free_time", None, None, *SETS, f"control.objective={{kind: effort_time, rho: {RHO}}}")
    sol = se3ocp.solve(man)
    assert sol.converged, sol.message
    T = sol.T
    lo, hi = man.problem.time_bounds
    assert lo * (1 + 1e-3) < T < hi * (1 - 1e-3)
    effort = _fixed(T)
    assert sol.cost == pytest.approx(effort + RHO * T, rel=1e-8)
    dT = 1e-3 * T
    up, down = _fixed(T + dT), _fixed(T - dT)
    slope = (up - down) / (2 * dT)
    assert slope == pytest.approx(-RHO, rel=1e-4)
    assert min(up + RHO * (T + dT), down + RHO * (T - dT)) > sol.cost
