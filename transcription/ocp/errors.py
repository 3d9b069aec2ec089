"""The error of an inconsistent Problem, and the checks of single values that raise it."""
from __future__ import annotations

import numpy as np

from ..geometry.so3 import unit_direction


class ProblemError(ValueError):
    """An inconsistent Problem: ``field`` names the offending attribute."""

    def __init__(self, fieldname: str, message: str):
        self.field = fieldname
        super().__init__(f"{fieldname}: {message}")


def unit(v, name: str) -> np.ndarray:
    """The unit direction of ``v`` (:func:`~transcription.geometry.so3.unit_direction`: 3 finite numbers of any magnitude,
    not all zero); ProblemError naming ``name`` otherwise."""
    u = unit_direction(v)
    if u is None:
        raise ProblemError(name, "expected a non-zero finite 3-vector")
    return u


def positive(value: float, name: str) -> None:
    """ProblemError naming ``name`` unless ``value`` is a positive finite number."""
    if not (np.isfinite(value) and value > 0):
        raise ProblemError(name, "expected a positive number")
