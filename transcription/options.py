"""The options of each method: frozen dataclasses, validated when they are made.

``DirectOptions`` and ``IndirectOptions`` are the YAML blocks ``solver.direct`` and ``solver.indirect``;
:meth:`Options.from_mapping` builds one (unknown keys rejected), ``Options.replace(**changes)`` derives a variant.
Every check raises :class:`OptionError` naming the option, for a Python caller and a maneuver file alike.  Each
field's metadata (``_opt``) is the one place its type, range and default are written.
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar, Mapping

import casadi as ca

#: integer options are bounded (a typo such as 1e30 iterations must not overflow into 0)
MAX_INT_OPTION = 10**7
#: the largest C int: what the solvers' integer options hold
C_INT_MAX = 2**31 - 1


class OptionError(ValueError):
    """A bad option value: ``field`` names the option, ``detail`` says what was expected."""

    def __init__(self, fieldname: str, detail: str):
        self.field, self.detail = fieldname, detail
        super().__init__(f"{fieldname}: {detail}")


def shorten(v, limit: int = 60) -> str:
    """``v`` for a message: strings longer than ``limit`` are cut, huge integers summarized."""
    if isinstance(v, str) and len(v) > limit:
        return f"{v[:limit]}... ({len(v)} characters)"
    if isinstance(v, int) and not isinstance(v, bool) and v.bit_length() > 200:
        return f"{'-' if v < 0 else ''}<an integer of {int(abs(v).bit_length() * math.log10(2)) + 1} digits>"
    return v


def show(v) -> str:
    """repr(v) for a message, shortened (:func:`shorten`)."""
    s = shorten(v)
    return s if isinstance(v, int) and s is not v else repr(s)


def describe(v) -> str:
    """``v`` in a message: its kind and (shortened) value, always on one line."""
    if v is None:
        return "nothing (null)"
    if isinstance(v, bool):
        return f"a boolean ({v})"
    if isinstance(v, str):
        return f"the string {show(v)}"
    if isinstance(v, Mapping):
        return "a mapping"
    if isinstance(v, (list, tuple)):
        return f"a list of length {len(v)}"
    if isinstance(v, int):
        return f"int {shorten(v)}"
    text = repr(v)
    return f"{type(v).__name__} {shorten(text)}"


def _opt(default, kind: str, *, lo=None, hi=None, choices=(), lo_closed: bool = False, doc: str = ""):
    """A dataclass field with its check: kind in 'float', 'int', 'bool', 'choice', 'mapping', 'costate'.
    float: lo < v < hi (open bounds, None = unbounded; lo <= v with ``lo_closed``); int: lo <= v <= hi."""
    meta = {"kind": kind, "lo": lo, "hi": hi, "choices": tuple(choices), "doc": doc, "lo_closed": lo_closed}
    if isinstance(default, dict):
        return field(default_factory=lambda: dict(default), metadata=meta)
    return field(default=default, metadata=meta)


def _check(name: str, meta: dict, v):
    kind = meta["kind"]
    if kind == "bool":
        if not isinstance(v, bool):
            raise OptionError(name, f"expected true or false, got {describe(v)}")
        return v
    if kind == "choice":
        if not isinstance(v, str) or v not in meta["choices"]:
            raise OptionError(name, f"expected one of {', '.join(meta['choices'])}, got {describe(v)}")
        return v
    if kind == "mapping":
        if not isinstance(v, Mapping):
            raise OptionError(name, f"expected a mapping of option names to values, got {describe(v)}")
        for k, x in v.items():
            if not isinstance(k, str):
                raise OptionError(name, f"expected option names, got {describe(k)}")
            if x is None or not isinstance(x, (bool, int, float, str)) or (isinstance(x, float) and not math.isfinite(x)):
                raise OptionError(f"{name}.{k}", f"expected a number, a string or true/false, got {describe(x)}")
        return dict(v)
    if kind == "costate":
        if isinstance(v, str):
            if v not in ("zero", "from_direct"):
                raise OptionError(name, f"expected zero, from_direct or a list of 12 numbers, got {describe(v)}")
            return v
        if isinstance(v, (list, tuple)) or hasattr(v, "__array__"):
            vals = list(v.ravel()) if hasattr(v, "ravel") else list(v)
            if len(vals) == 12:
                return tuple(_number(f"{name}[{i}]", x, "float", None, None) for i, x in enumerate(vals))
        raise OptionError(name, f"expected zero, from_direct or a list of 12 numbers, got {describe(v)}")
    return _number(name, v, kind, meta["lo"], meta["hi"], meta["lo_closed"])


def _number(name, v, kind, lo, hi, lo_closed=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)) and not hasattr(v, "__float__"):
        raise OptionError(name, f"expected {'an integer' if kind == 'int' else 'a number'}, got {describe(v)}")
    x = float(v)
    if not math.isfinite(x):
        raise OptionError(name, f"expected a finite number, got {v!r}")
    if kind == "int":
        hi = MAX_INT_OPTION if hi is None else hi
        if not x.is_integer():
            raise OptionError(name, f"expected an integer, got {v!r}")
        if (lo is not None and x < lo) or x > hi:
            raise OptionError(name, f"expected an integer from {lo} to {hi}, got {v!r}")
        return int(x)
    if lo is not None and not (x >= lo if lo_closed else x > lo):
        raise OptionError(name, f"expected a number {'>=' if lo_closed else '>'} {lo:g}, got {v!r}")
    if hi is not None and not x < hi:
        raise OptionError(name, f"expected a number < {hi:g}, got {v!r}")
    return x


_CASADI_HINTS = {"is_double": "expected a number", "is_int": "expected an integer", "is_string": "expected a string",
                 "No such IPOPT option": "unknown IPOPT option", "option not supported": "unknown fatrop option"}


def raw_solver_value(v):
    """IPOPT and fatrop have no boolean options: YAML's true/false become 'yes'/'no'."""
    return ("yes" if v else "no") if isinstance(v, bool) else v


def check_raw_options(solver: str, raw: Mapping, name: str) -> None:
    """Raise OptionError ``name.KEY`` for a raw option the solver plugin rejects or cannot honour: each is tried
    alone on a one-variable problem (unknown names and types fail when the solver is made, unavailable choices when
    it runs: 'Invalid_Option')."""
    for k, v in raw.items():
        _check_raw_option(solver, k, v, name)


#: raw options naming files: checked for their type only, never tried (a trial would create or read the file)
_FILE_OPTIONS = {"output_file": "a file name", "option_file_name": None}


@lru_cache(maxsize=4096)
def _check_raw_option(solver: str, k: str, v, name: str) -> None:
    """One raw option (cached: a sweep checks the same options at every point); the trial prints nothing."""

    if k in _FILE_OPTIONS:
        if _FILE_OPTIONS[k] is None:
            raise OptionError(f"{name}.{k}", "not supported: give the solver's options in this block instead of an "
                                             "option file")
        if not isinstance(v, str) or not v.strip() or "\0" in v:
            raise OptionError(f"{name}.{k}", f"expected {_FILE_OPTIONS[k]}, got {describe(v)}")
        why = _unwritable(v)
        if why:
            raise OptionError(f"{name}.{k}", f"expected a file that can be written ({solver} cannot start otherwise), "
                                             f"got {v!r}: {why}")
        return
    if isinstance(v, (int, float)) and not isinstance(v, bool) and _option_kind(solver, k) == "int":
        # CasADi passes an integer option as a C int, silently truncated or wrapped: refuse what does not convert
        if not (float(v).is_integer() and -C_INT_MAX - 1 <= v <= C_INT_MAX):
            raise OptionError(f"{name}.{k}", f"expected an integer from {-C_INT_MAX - 1} to {C_INT_MAX} ({solver}'s "
                                             f"int), got {show(v)}")
    x = ca.SX.sym("x")
    quiet = {"ipopt": {"print_level": 0, "sb": "yes"}, "fatrop": {"print_level": 0}}[solver]
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # CasADi prints the solver's output through sys.stdout
            nlp = ca.nlpsol("option_check", solver, {"x": x, "f": (x - 1) ** 2},
                            {solver: {**quiet, k: raw_solver_value(v)}, "print_time": False})
            nlp(x0=0.0)
        status = str(nlp.stats().get("return_status", ""))
    except RuntimeError as exc:
        text = str(exc)
        hint = next((h for key, h in _CASADI_HINTS.items() if key in text), None)
        last = text.strip().splitlines()[-1] if text.strip() else "unknown reason"
        raise OptionError(f"{name}.{k}", f"{hint or 'rejected by ' + solver + ': ' + last} (value {v!r})") from None
    if status == "Invalid_Option":
        raise OptionError(f"{name}.{k}", f"{solver} cannot use the value {v!r} here (Invalid_Option: e.g. a linear "
                                         "solver that is not installed)")


def _unwritable(path: str) -> str:
    """Why ``path`` cannot be opened for writing ('' if it can); a new file is created and removed again."""
    if os.path.isdir(path):
        return "it is a directory"
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        return "" if os.access(path, os.W_OK) else "no permission to write it"
    except OSError as e:
        return e.strerror or str(e)
    os.close(fd)
    os.unlink(path)
    return ""


@lru_cache(maxsize=4096)
def _option_kind(solver: str, k: str) -> str:
    """'int', 'float' or 'other': the type the solver declares for option ``k`` (given a word, CasADi names the
    type it expected: is_int / is_double)."""
    import contextlib
    import io

    import casadi as ca

    try:
        with contextlib.redirect_stdout(io.StringIO()):  # IPOPT lists a string option's settings on stdout
            ca.nlpsol("option_kind", solver, {"x": ca.SX.sym("x"), "f": ca.SX(0)},
                      {solver: {"print_level": 0, **({"sb": "yes"} if solver == "ipopt" else {}), k: "?"},
                       "print_time": False})
    except RuntimeError as exc:
        text = str(exc)
        return "int" if "is_int" in text else "float" if "is_double" in text else "other"
    return "other"


class Options:
    """Behaviour shared by the method option classes (they are frozen dataclasses)."""

    def __post_init__(self):
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _check(f.name, f.metadata, getattr(self, f.name)))

    @classmethod
    def from_mapping(cls, d: Mapping[str, Any] | None):
        """An instance from a mapping (a YAML block); unknown keys raise OptionError."""
        d = dict(d or {})
        names = [f.name for f in dataclasses.fields(cls)]
        for k in d:
            if k not in names:
                raise OptionError(str(k), f"unknown option; allowed here: {', '.join(sorted(names))}")
        return cls(**d)

    def replace(self, **changes):
        """A copy with some options changed (validated)."""
        names = [f.name for f in dataclasses.fields(self)]
        for k in changes:
            if k not in names:
                raise OptionError(k, f"unknown option; allowed here: {', '.join(sorted(names))}")
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """Plain values (for the resolved config and summaries)."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = dict(v) if isinstance(v, Mapping) else list(v) if isinstance(v, tuple) else v
        return out


@dataclass(frozen=True)
class DirectOptions(Options):
    """Options of the direct method (YAML ``solver.direct``)."""

    solver: str = _opt("ipopt", "choice", choices=("ipopt", "fatrop"), doc="NLP solver (fatrop: fixed-time effort problems; IPOPT is its fallback)")
    tol: float = _opt(1e-10, "float", lo=0.0, doc="the NLP solver's KKT tolerance")
    max_iter: int = _opt(3000, "int", lo=1, doc="iteration limit of the NLP solver (and of the impulsive TPBVP's Newton, at most 50)")
    initial_guess: str = _opt("auto", "choice", choices=("auto", "rollout", "interpolate", "orbit"),
                              doc="rollout: free motion of the scheme; interpolate: the SE(3) screw motion to the target; "
                                  "orbit: that screw motion in the frame turning with the orbit (a central body); "
                                  "auto: the objective's strategy of starts (docs/mathematics.md §10, Initial guesses); "
                                  "every guess tried is reported in the message and the trace")
    options: Mapping = _opt({}, "mapping", doc="raw IPOPT options, checked before anything runs")
    cayley_variables: bool = _opt(True, "bool", doc="the Cayley vectors as unknowns (every defect explicit)")
    terminal_tol: float = _opt(1e-6, "float", lo=0.0, doc="re-simulated terminal error above which a solve is not converged")
    fatrop_options: Mapping = _opt({}, "mapping", doc="raw fatrop options")
    fatrop_expand: bool = _opt(False, "bool", doc="fatrop: SX-expand the whole NLP")
    jit: bool = _opt(True, "bool", doc="compile the stage derivatives to C (cached on disk; interpreter without a compiler)")
    transcription: str = _opt("single_shooting", "choice", choices=("single_shooting", "multiple_shooting"),
                              doc="impulsive maneuvers to an orbit: the six initial momenta as unknowns, or every node state")

    def __post_init__(self):
        super().__post_init__()
        if self.options:
            check_raw_options("ipopt", self.options, "options")
        if self.fatrop_options:
            check_raw_options("fatrop", self.fatrop_options, "fatrop_options")


@dataclass(frozen=True)
class IndirectOptions(Options):
    """Options of the indirect method (YAML ``solver.indirect``)."""

    alpha: float = _opt(1e-4, "float", lo=0.0, hi=1.0, doc="Armijo constant")
    eps_S: float = _opt(1e-12, "float", lo=0.0, lo_closed=True, doc="tolerance on |z_N|_2 (0: run to the round-off floor)")
    max_iter: int = _opt(50, "int", lo=1, doc="Newton iterations")
    max_halvings: int = _opt(30, "int", lo=0, hi=200, doc="line-search halvings per iteration")
    initial_costate: Any = _opt("zero", "costate", doc="zero, from_direct (the direct solution's multipliers) or 12 numbers")
    fallback: bool = _opt(True, "bool", doc="when the start of initial_costate (zero or 12 numbers) fails, start again "
                                            "from the direct solution (from_direct, with its T for a free final time)")
    floor_factor: float = _opt(10.0, "float", lo=1.0, doc="round-off floor: |z_N| within this factor of the measured noise")
    floor_accept: float = _opt(1e-8, "float", lo=0.0, doc="a round-off floor above this is not accepted as convergence")
    cayley_tol: float = _opt(1e-10, "float", lo=0.0, doc="trials whose rollout leaves a larger Cayley residual are rejected")
    jit: bool = _opt(True, "bool", doc="compile the per-step maps to C (cached on disk; the first build takes ~1-2 s; "
                                      "the interpreter without a compiler)")


#: the environment variable that switches the default continuous check off (``0``, ``false``, ``no``, ``off``; for
#: test runs); an explicit ``continuous_check`` always wins
CHECK_ENV = "SE3OCP_CONTINUOUS_CHECK"


def _default_check() -> bool:
    return os.environ.get(CHECK_ENV, "1").strip().lower() not in ("0", "false", "no", "off")


@dataclass(frozen=True)
class AccuracyOptions(Options):
    """The ``solver`` block's own keys (YAML ``solver.continuous_check``, ``solver.accuracy``, ...): the continuous
    check and refinement to a tolerance (transcription/strategy/refine.py)."""

    KEYS: ClassVar[tuple[str, ...]] = ("continuous_check", "accuracy", "maneuver_accuracy", "constraints_tolerance",
                                       "max_N", "max_levels", "refinement")

    continuous_check: bool = _opt(True, "bool", doc="fly every successful smooth-control Solution through the continuous "
                                                     "equations and report how it lands (Solution.continuous)")
    accuracy: float | None = field(default=None, metadata={
        **_opt(1.0, "float", lo=0.0, doc="refine the mesh until the continuous-time terminal miss (scaled_miss) and the "
                                          "path constraints' violation between the nodes are at most this; absent or "
                                          "null: the given N, no refinement").metadata, "optional": True})
    maneuver_accuracy: float | None = field(default=None, metadata={
        **_opt(0.5, "float", lo=0.0, hi=1.0, doc="refine the mesh until the continuous-time terminal miss as a fraction "
                                                  "of what the maneuver changes (ContinuousCheck.maneuver_fraction: "
                                                  "0.01 = 1 %) and the path constraints' violation between the nodes "
                                                  "are at most this; not with accuracy; absent or null: no "
                                                  "refinement").metadata, "optional": True})
    constraints_tolerance: float | None = field(default=None, metadata={
        **_opt(1e-5, "float", lo=0.0, doc="the path constraints' violation between the nodes (the continuous flight's "
                                           "margins) the status accepts, in the units of accuracy: rad for a cone, a "
                                           "fraction of the orbit radius L for a radius, rad per time unit for a "
                                           "rate; given, the mesh is refined until the violation is at most this "
                                           "(with accuracy: the miss within accuracy too; alone: the violation "
                                           "only); absent or null: the status judges by "
                                           "transcription.results.check.PATH_MARGIN_TOL (1e-5) and only accuracy "
                                           "refines").metadata, "optional": True})
    max_N: int = _opt(50000, "int", lo=1, doc="the largest N refinement may solve on; an accuracy that needs more is "
                                               "refused before solving (or the refinement stops) with the N it needs")
    max_levels: int = _opt(8, "int", lo=1, hi=50, doc="the most mesh levels (solves) of one refinement")
    refinement: str = _opt("adaptive", "choice", choices=("adaptive", "uniform"),
                           doc="adaptive: non-uniform steps equidistributing the estimated error (where every method "
                               "solved takes a mesh; else uniform); uniform: N steps of one size per level")

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (f.metadata.get("optional") and v is None):
                object.__setattr__(self, f.name, _check(f.name, f.metadata, v))
        if self.accuracy is not None and self.maneuver_accuracy is not None:
            raise OptionError("maneuver_accuracy", f"expected either accuracy (a scaled miss) or maneuver_accuracy (a "
                                                   f"fraction of the maneuver), not both: got accuracy "
                                                   f"{self.accuracy:g} and maneuver_accuracy "
                                                   f"{self.maneuver_accuracy:g}")

    @property
    def tolerance(self) -> float | None:
        """What refinement drives the miss below: ``accuracy`` or ``maneuver_accuracy`` (None: no refinement)."""
        return self.accuracy if self.accuracy is not None else self.maneuver_accuracy

    @property
    def refines(self) -> bool:
        """True when a mesh refinement is asked for: ``accuracy``, ``maneuver_accuracy`` or ``constraints_tolerance``."""
        return self.tolerance is not None or self.constraints_tolerance is not None

    @property
    def path_tolerance(self) -> float | None:
        """What refinement drives the path constraints' violation below: ``constraints_tolerance``, else
        :attr:`tolerance` (None: no refinement)."""
        return self.constraints_tolerance if self.constraints_tolerance is not None else self.tolerance

    @property
    def of_maneuver(self) -> bool:
        """True when the miss refined is the flown miss as a fraction of the maneuver (``maneuver_accuracy``)."""
        return self.maneuver_accuracy is not None

    @property
    def tolerance_key(self) -> str:
        """The ``solver`` key that gave :attr:`tolerance` (for messages naming the field): ``constraints_tolerance``
        when it is the only one."""
        if self.tolerance is None and self.constraints_tolerance is not None:
            return "constraints_tolerance"
        return "maneuver_accuracy" if self.of_maneuver else "accuracy"

    @classmethod
    def from_mapping(cls, d=None) -> "AccuracyOptions":
        """The defaults (:meth:`default`) changed by a mapping (the solver block's own keys); unknown keys raise."""
        return cls.default().replace(**dict(d or {}))

    def given(self, d) -> dict[str, Any]:
        """The options among the keys of ``d`` (the resolved file keeps what the file gave)."""
        return {k: x for k, x in self.as_dict().items() if k in d}

    @classmethod
    def default(cls) -> "AccuracyOptions":
        """The defaults, with the continuous check as the environment says (:data:`CHECK_ENV`)."""
        return cls(continuous_check=_default_check())
