"""The error of an inconsistent Problem, and the checks of single values that raise it."""
from __future__ import annotations

import numpy as np


class ProblemError(ValueError):
    """An inconsistent Problem: ``field`` names the offending attribute."""

    def __init__(self, fieldname: str, message: str):
        self.field = fieldname
        super().__init__(f"{fieldname}: {message}")


def unit(v, name: str) -> np.ndarray:
    """``v`` (a non-zero finite 3-vector) normalized; ProblemError naming ``name`` otherwise."""
    v = np.asarray(v, dtype=float).reshape(-1)
    n = np.linalg.norm(v) if v.shape == (3,) and np.all(np.isfinite(v)) else 0.0
    if not n > 0:
        raise ProblemError(name, "expected a non-zero finite 3-vector")
    return v / n


def positive(value: float, name: str) -> None:
    """ProblemError naming ``name`` unless ``value`` is a positive finite number."""
    if not (np.isfinite(value) and value > 0):
        raise ProblemError(name, "expected a positive number")
