"""Accuracy on demand (issue 26, docs/mathematics.md §11): every smooth-control Solution of ``solve`` is flown
in continuous time (the continuous check, on by default), and with ``solver.accuracy`` the mesh is refined
until that flight lands within the tolerance.

:class:`AccuracyOptions` are the ``solver`` block's own keys (beside ``direct`` and ``indirect``):
``continuous_check`` (default true), ``accuracy`` (absent or null: today's fixed N), ``max_N`` and
``max_levels``.  :func:`attach_checks` stores a :class:`~transcription.flight.check.ContinuousCheck` on every
successful smooth-control Solution (``sol.continuous``); failed solves skip it.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .options import Options, _check, _opt
from .results import Solution

if TYPE_CHECKING:  # pragma: no cover
    from .solve import Comparison

#: the environment variable that switches the default continuous check off (``0``, ``false``, ``no``, ``off``):
#: for test runs of code that does not test the check; an explicit ``continuous_check`` always wins
CHECK_ENV = "SE3OCP_CONTINUOUS_CHECK"


def _default_check() -> bool:
    return os.environ.get(CHECK_ENV, "1").strip().lower() not in ("0", "false", "no", "off")


@dataclass(frozen=True)
class AccuracyOptions(Options):
    """The ``solver`` block's own keys (YAML ``solver.continuous_check``, ``solver.accuracy``, ...)."""

    continuous_check: bool = _opt(True, "bool", doc="fly every successful smooth-control Solution through the continuous "
                                                     "equations and report how it lands (Solution.continuous)")

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (f.metadata.get("optional") and v is None):
                object.__setattr__(self, f.name, _check(f.name, f.metadata, v))

    @classmethod
    def default(cls) -> "AccuracyOptions":
        """The defaults, with the continuous check as the environment says (:data:`CHECK_ENV`)."""
        return cls(continuous_check=_default_check())


def _solutions(out: "Solution | Comparison") -> list[Solution]:
    return list(out.solutions.values()) if hasattr(out, "solutions") else [out]


def attach_checks(out: "Solution | Comparison") -> "Solution | Comparison":
    """Fly every successful smooth-control Solution of ``out`` (:func:`~transcription.flight.check.continuous_check`)
    and store the check as ``sol.continuous`` (a check already there is kept).  Failed solves, impulsive plans
    and simulations are left alone.  Returns ``out``."""
    from .flight.check import continuous_check

    for s in _solutions(out):
        if s.continuous is None and s.converged and s.problem is not None and s.problem.kind == "smooth" \
                and s.controls is not None:
            s.continuous = continuous_check(s)
    return out
