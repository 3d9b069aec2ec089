"""The objective of a smooth-control problem, as a class; each objective's module (:mod:`transcription.objectives`)
brings its NLP blocks, indirect conditions and default strategy.  The layers below ask ``problem.control.objective``,
never its name."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from .controls import SmoothControl
    from .problem import Problem


class Objective:
    """The cost of a smooth-control problem (docs/mathematics.md §6, §10).

    ``name``: what files and messages call it; ``free_time``: it minimizes the final time (the problem needs
    time_bounds); ``indirect``: its indirect conditions (None: not covered).  A subclass is a frozen dataclass (its
    parameters are fields) implementing the methods below."""

    name: ClassVar[str] = ""
    free_time: ClassVar[bool] = False
    #: its necessary conditions in the indirect method (transcription.methods.indirect.laws; None: not covered)
    indirect: ClassVar[Any] = None
    #: why fatrop's stage-ordered NLP is not used for it ('' when it is: transcription.methods.direct.fatrop)
    fatrop: ClassVar[str] = "fatrop is used for the effort objective"

    def __str__(self) -> str:
        return self.name

    # ------------------------------------------------------------------ the problem
    def check(self, control: "SmoothControl") -> None:
        """Raise ProblemError when ``control`` (its weights, its bounds) does not suit this objective."""

    def value(self, problem: "Problem", U: np.ndarray, h: float) -> float:
        """The cost of controls U (6, n_controls) on ``problem``'s grid at the (mean) step size h."""
        raise NotImplementedError

    def unit_weights(self, force: float, moment: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(W_f, W_m) that measure each control in units of its size ``force``, ``moment`` (a file's default weights
        in the actuators' terms: :func:`~transcription.ocp.estimate.control_sizes`); None: this objective keeps the
        given weights."""
        return None

    def with_weights(self, control: "SmoothControl") -> "Objective":
        """This objective for ``control``'s weights (an objective keeping derived data of them refreshes it)."""
        return self

    # ------------------------------------------------------------------ the direct method's NLP
    def scales(self, problem: "Problem", sU: np.ndarray) -> tuple[np.ndarray, float]:
        """The control scales (6,) the NLP uses (``sU`` from the boundary data and the bounds, raised where the
        objective balances them) and the objective's scale."""
        raise NotImplementedError

    def slacks(self, tr: Any) -> int:
        """How many variables of its own this objective adds at each control node of the NLP ``tr``."""
        return 0

    def blocks(self, tr: Any) -> list:
        """The NLP blocks of this objective on ``tr`` (a SmoothTranscription: its layout, scales and data), as
        (Block, row scales) pairs: its running cost at the control nodes, its rows, a cost of the final time."""
        return []

    def slack_bounds(self, tr: Any, lbx: np.ndarray, ubx: np.ndarray) -> None:
        """Bound this objective's variables in lbx, ubx (scaled, in place)."""

    def slack_values(self, tr: Any, U: np.ndarray) -> np.ndarray | None:
        """Initial values (n_slack, n_controls) of this objective's variables for controls U (None: none)."""
        return None

    def slack_scales(self, tr: Any) -> np.ndarray:
        """The scales (n_slack,) of this objective's variables."""
        return np.zeros(0)

    # ------------------------------------------------------------------ methods and strategies
    def failure_tip(self, problem: "Problem") -> str:
        """What to try with this objective after its default strategy failed on ``problem``, in ``--set`` terms
        ('' when it has nothing to add to transcription.strategy.hints.failure_hint's tips)."""
        return ""

    def caution(self, problem: "Problem") -> str:
        """One line said before solving ``problem`` when this objective is known to converge slowly or not at all on
        problems of its kind, with what to try ('' otherwise)."""
        return ""

    def via_lgvi(self, problem: "Problem") -> bool:
        """Whether on the Kepler-split LGVI its default strategy starts from its optimum on the LGVI
        (:func:`transcription.strategy.core.default_strategy`); False where its own strategy reaches that scheme
        otherwise."""
        return True

    def strategy(self, problem: "Problem", options: Any) -> Any:
        """This objective's default strategy for ``problem`` with the direct method's ``options``
        (:mod:`transcription.strategy`)."""
        raise NotImplementedError
