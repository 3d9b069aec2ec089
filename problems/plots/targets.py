"""What the Problem asks for, as the figures show it (NumPy only): the target attitude, the
desired orbit and its elements, the controls a bound removes, and one line per path constraint."""
from __future__ import annotations

import numpy as np

from ...transcription.ocp import (KeepIn, KeepOut, MaxAngularRate, MinRadius, Problem, TargetOrbit, TargetRendezvous, TargetState)
from .orbits import _circle, _orbit_ellipse, osculating_elements


def _target_R(problem: Problem) -> np.ndarray | None:
    """R_d of a state target that fixes the attitude, else None."""
    term = problem.terminal
    if isinstance(term, TargetState) and "attitude" in term.fixed:
        return term.X[6:15].reshape(3, 3, order="F")
    if isinstance(term, TargetRendezvous):
        return term.R
    return None


def _target_orbit(problem: Problem) -> np.ndarray | None:
    """Points of the desired orbit (a TargetOrbit's circle, or the osculating orbit of a state
    target that fixes position and velocity), or None."""
    term, model = problem.terminal, problem.model
    if isinstance(term, (TargetOrbit, TargetRendezvous)):
        return _circle(term.radius, term.normal)
    if isinstance(term, TargetState) and {"position", "velocity"} <= set(term.fixed) and model.mu:
        return _orbit_ellipse(term.X[0:3], term.X[3:6] / model.mass, model.mu)
    return None


def _target_elements(problem: Problem) -> dict[str, float] | None:
    term, model = problem.terminal, problem.model
    if isinstance(term, (TargetOrbit, TargetRendezvous)):
        return {"radius": term.radius, "inclination": float(np.degrees(np.arccos(np.clip(term.normal[2], -1, 1)))),
                "eccentricity": 0.0}
    if isinstance(term, TargetState) and {"position", "velocity"} <= set(term.fixed) and model.mu:
        el = osculating_elements(term.X[0:3], term.X[3:6] / model.mass, model.mu)
        return {k: float(v[0]) for k, v in el.items()}
    return None


def removed(problem: Problem) -> set[str]:
    """The controls a norm bound of 0 removes: a subset of {"force", "moment"}."""
    rm = getattr(problem.control, "removed", (False, False))
    return {name for name, r in zip(("force", "moment"), rm) if r}


def _bound_of(problem: Problem, which: str):
    return getattr(problem.control, f"{which}_bound", None)


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in np.asarray(v, float) + 0.0) + ")"


def cone_direction_label(c) -> str:
    """A cone's direction in words: the fixed vector, or 'nadir −x/|x|', 'velocity v/|v|' (moving)."""
    return {"nadir": "nadir −x/|x|", "velocity": "velocity v/|v|"}.get(c.direction, None) if c.moving else _vec(c.direction)


def _describe(c) -> str:
    if isinstance(c, MinRadius):
        return f"min radius: |x| ≥ {c.radius:g}"
    if isinstance(c, (KeepOut, KeepIn)):
        rel = "≥" if isinstance(c, KeepOut) else "≤"
        return (f"{c.kind.replace('_', '-')}: angle(R b, s) {rel} {c.angle_deg:g}°, body axis b = {_vec(c.body_axis)}, "
                f"direction s = {cone_direction_label(c)}")
    if isinstance(c, MaxAngularRate):
        return f"max angular rate: |Ω| ≤ {c.value:g}"
    return c.kind
