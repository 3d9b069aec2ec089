"""Test support: the bundled examples are defined once, in configs/, and the tests load them from there."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import se3ocp

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
#: short names of the bundled maneuver files
EXAMPLES = {"e1": "e1_impulsive_tpbvp", "e2": "e2_impulsive_relaxed", "e3": "e3_inclination_change",
            "e4": "e4_orbital_capture", "free": "free_tumble"}


def config(name: str) -> Path:
    """The path of a bundled maneuver file by its short name (e1..e4, free) or its stem."""
    return CONFIGS / f"{EXAMPLES.get(name, name)}.yaml"


@lru_cache(maxsize=None)
def _maneuver(name: str, sets: tuple[str, ...]):
    return se3ocp.load(config(name), sets)


def maneuver(name: str, N: int | None = None, scheme: str | None = None, *sets: str):
    """A bundled maneuver with N and the scheme overridden (cached: equal calls share the object)."""
    extra = ((f"horizon.N={N}",) if N is not None else ()) + ((f"discretization={scheme}",) if scheme else ())
    return _maneuver(name, extra + tuple(sets))


def problem(name: str, N: int | None = None, scheme: str | None = None, *sets: str):
    """The Problem of :func:`maneuver`."""
    return maneuver(name, N, scheme, *sets).problem
