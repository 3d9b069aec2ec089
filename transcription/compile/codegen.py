"""Optional compilation of hot CasADi Functions to C (CasADi code generation + the system C compiler).

:func:`compiled` / :func:`compiled_many` turn SX Functions into equivalent external Functions loaded from one shared
library, cached on disk under the SHA-256 of the serialized Functions, the flags and the CasADi version (compiled once
per machine).  When compilation is not possible (no compiler, compiler error, unwritable cache, ``SE3OCP_NO_JIT=1``)
the original Functions are returned unchanged.  Compiled Functions evaluate values only.  Flag sets: :data:`CFLAGS`,
:data:`QUICK_CFLAGS`, :data:`LOOP_CFLAGS`; ``-ffp-contract=off`` everywhere keeps the compiled arithmetic the
interpreter's bit for bit.  The model's numbers are data of the compiled blocks, so a known structure compiles nothing.

Interpreted first (:func:`compiled_libraries` with ``quick``): a structure never seen comes back interpreted while a
detached background process (:func:`.build.spawn`) compiles it at the quick flags, then its own, into the cache;
:class:`Switch` moves what is built from them to the compiled code as it lands.  :func:`settle` waits for the builds
under way, :func:`stop` ends them.  Measurements: docs/performance.md.

Environment: ``SE3OCP_CACHE`` (cache directory, default ``~/.cache/se3ocp/codegen``), ``CC`` (compiler, default
``gcc`` then ``cc``), ``SE3OCP_NO_JIT`` (disable), ``SE3OCP_JIT_BACKGROUND=0`` (compile at once, in the foreground).
"""
from __future__ import annotations

import functools
import hashlib
import os
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca

from .build import building, cache_dir, compiler, generate, lean_io, spawn, start_compiler, stop

__all__ = ["CFLAGS", "QUICK_CFLAGS", "LOOP_CFLAGS", "last_error", "notify", "available", "compiled", "compiled_many",
           "Library", "compiled_libraries", "background", "candidates", "arrived", "load", "Switch", "ready", "settle",
           "last_provisional", "cache_dir", "compiler", "building", "stop", "lean_io"]

#: -O1 (the direct method's stage derivatives; docs/performance.md); -ffp-contract=off: the interpreter's arithmetic
CFLAGS = ["-O1", "-ffp-contract=off", "-fPIC", "-shared"]

#: -O0 for the indirect method's straight-line per-step maps and every first background stage (quicker to compile)
QUICK_CFLAGS = ["-O0", "-ffp-contract=off", "-fPIC", "-shared"]

#: for small MX Functions whose C is loops (matrix products, maps): cheap to compile at -O1, and at -O0
#: those loops run slower than CasADi's interpreter, which calls its own optimized kernels
LOOP_CFLAGS = ["-O1", "-ffp-contract=off", "-fPIC", "-shared"]

#: last failure reason (None when the last call compiled or loaded successfully); for reports
last_error: str | None = None

#: optional callable told (one line) before a cache miss is compiled, so that a front end can say why
#: the first run pauses; the CLI sets it, the library itself prints nothing
notify: Callable[[str], None] | None = None


def available() -> bool:
    """True if compilation can be attempted (a compiler exists and it is not disabled)."""
    return os.environ.get("SE3OCP_NO_JIT", "") not in ("1", "true", "yes") and compiler() is not None


def compiled(fn: ca.Function, timeout: float = 600.0, cse: bool = True, cflags: Sequence[str] = CFLAGS) -> ca.Function:
    """A compiled equivalent of ``fn`` (same name, inputs and outputs), or ``fn`` itself as fallback."""
    return compiled_many([fn], fn.name(), timeout=timeout, cse=cse, cflags=cflags)[0]


def compiled_many(fns: Sequence[ca.Function], name: str, timeout: float = 600.0, cse: bool = True,
                  cflags: Sequence[str] = CFLAGS) -> list[ca.Function]:
    """Compiled equivalents of ``fns`` from one shared library ``name``, or ``fns`` unchanged as fallback (all or
    nothing).  ``cse``: common-subexpression elimination of SX Functions before generating C."""
    return compiled_libraries([Library(name, tuple(fns), cse)], timeout=timeout, cflags=cflags)[0]


@dataclass(frozen=True)
class Library:
    """One shared library: its name (the cached file's prefix), its Functions, ``cse`` (common-subexpression
    elimination of SX Functions), its flags (None: the call's), and ``quick``: a background build compiles it at the
    quick flags first (not for C of loops, slower than the interpreter at -O0)."""

    name: str
    fns: tuple
    cse: bool = False
    cflags: tuple | None = None
    quick: bool = True

    @functools.cached_property
    def serialized(self) -> tuple[str, ...]:
        """The serialized Functions (the cache key's and the background build's; computed once)."""
        return tuple(f.serialize() for f in self.fns)

    @functools.cached_property
    def _digest(self) -> "hashlib._Hash":
        """SHA-256 of the serialized Functions, before the flags (:meth:`key` copies it per flag set)."""
        digest = hashlib.sha256()
        for text in self.serialized:
            digest.update(text.encode())
        return digest

    def key(self, flags: Sequence[str]) -> str:
        """The cache key of this library compiled with ``flags``: the serialized Functions, the flags, the CasADi
        version and whether common subexpressions are eliminated."""
        digest = self._digest.copy()
        digest.update(" ".join(flags).encode() + ca.__version__.encode() + (b"" if self.cse else b"nocse"))
        return digest.hexdigest()[:20]


def _generate(lib: Library, tmp: str) -> Path:
    """The C file of ``lib`` in the directory ``tmp`` (:func:`.build.generate`)."""
    return generate(lib.name, lib.fns, lib.cse, tmp)


def compiled_libraries(libs: Sequence[Library], timeout: float = 600.0, cflags: Sequence[str] = CFLAGS,
                       quick: Sequence[str] | None = None) -> list[list[ca.Function]]:
    """Compiled equivalents of every library's Functions, or all of them unchanged as fallback.  Each library is its
    own C file and compiler process; cache misses compile concurrently.  Without ``quick``, all or nothing.  With
    ``quick`` (interpreted first) each library on its own: one not cached at its own flags is loaded from its quick
    build if cached, else returned interpreted while the background compiles it (quick flags, then its own, in the
    order of ``libs``); :data:`last_provisional` says whether any library is not yet at its own flags."""
    global last_error, last_provisional
    originals = [list(lib.fns) for lib in libs]
    last_provisional = False
    if not available():
        last_error = "no C compiler found (or SE3OCP_NO_JIT set)"
        return originals
    flags = [_flags(lib, cflags) for lib in libs]
    try:
        paths = [_path(lib, fl) for lib, fl in zip(libs, flags)]
        if quick is not None and background():
            out, builds = [], []
            for lib, path, fl in zip(libs, paths, flags):
                if path.exists():
                    out.append(_external(lib, path))
                    continue
                last_provisional = True
                stages = [(list(quick), _path(lib, list(quick)))] if lib.quick and list(quick) != fl else []
                have = [p for _, p in stages if p.exists()]
                builds.append((lib, [(f, p) for f, p in stages + [(fl, path)] if not p.exists()], not have))
                out.append(_external(lib, have[0]) if have else list(lib.fns))
            spawn(builds, notify)
            last_error = None
            return out
        _build([(lib, path, fl) for lib, path, fl in zip(libs, paths, flags) if not path.exists()], timeout)
        exts = load(libs, paths)
        last_error = None
        return exts
    except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
        last_error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        last_provisional = False
        return originals


def background() -> bool:
    """Whether cache misses are compiled in the background (the interpreted-first policy; ``SE3OCP_JIT_BACKGROUND``)."""
    return os.environ.get("SE3OCP_JIT_BACKGROUND", "1") not in ("0", "false", "no")


def _flags(lib: Library, cflags: Sequence[str] = CFLAGS) -> list[str]:
    return list(lib.cflags) if lib.cflags is not None else list(cflags)


def candidates(libs: Sequence[Library], cflags: Sequence[str] = CFLAGS,
               quick: Sequence[str] = ()) -> list[list[Path]]:
    """Per library, the cached files it may be loaded from, best first: at its own flags, then (``quick``, if the
    library has a quick build) at the quick flags.  (The names hash the serialized Functions: computed once.)"""
    return [[_path(lib, _flags(lib, cflags))] + ([_path(lib, list(quick))] if quick and lib.quick else [])
            for lib in libs]


def arrived(paths: Sequence[Sequence[Path]]) -> tuple[tuple[Path | None, ...], bool]:
    """The best cached file of each library (``paths``: :func:`candidates`; None for a library with none in the cache
    yet, which stays interpreted) and whether all are the best (:func:`load` loads them)."""
    out, final = [], True
    for cands in paths:
        have = [p for p in cands if p.exists()]
        final = final and bool(have) and have[0] == cands[0]
        out.append(have[0] if have else None)
    return tuple(out), final


def load(libs: Sequence[Library], paths: Sequence[Path | None]) -> list[list[ca.Function]]:
    """Every library's Functions from its shared library ``paths`` (:func:`arrived`); a library without one (None)
    as its interpreted Functions."""
    return [_external(lib, path) if path is not None else list(lib.fns) for lib, path in zip(libs, paths)]


def _external(lib: Library, path: Path) -> list[ca.Function]:
    """``lib``'s Functions loaded from its shared library ``path``."""
    return [ca.external(f.name(), str(path)) for f in lib.fns]


class Switch(ca.Callback):
    """A Function that evaluates ``fn`` (built from interpreted or quick-compiled Functions) and moves to compiled
    code library by library as it arrives in the cache (:func:`arrived`, checked at every evaluation until all are at
    their own flags): on each arrival ``make(loaded, paths)`` rebuilds the Function from ``loaded`` (per library, its
    compiled or interpreted Functions); ``paths`` (None: interpreted) identifies the build, so Switches of one build
    can share it.  Values only, the same bits (-ffp-contract=off): where the switch happens does not show."""

    def __init__(self, fn: ca.Function, libs: Sequence[Library], make: Callable[[list, tuple], ca.Function],
                 cflags: Sequence[str] = CFLAGS, quick: Sequence[str] = QUICK_CFLAGS):
        ca.Callback.__init__(self)
        self.fn, self.libs, self.make = fn, tuple(libs), make
        self.candidates = candidates(libs, cflags, quick)
        # fn is taken to be the interpreted one (one already on a quick build is rebuilt from it at the first call)
        self.final, self.paths, self._buffer, self._spares = False, (None,) * len(self.libs), None, {}
        self.construct(f"{fn.name()}_switch", {})

    def get_n_in(self):
        return self.fn.n_in()

    def get_n_out(self):
        return self.fn.n_out()

    def get_name_in(self, i):
        return self.fn.name_in(i)

    def get_name_out(self, i):
        return self.fn.name_out(i)

    def get_sparsity_in(self, i):
        return self.fn.sparsity_in(i)

    def get_sparsity_out(self, i):
        return self.fn.sparsity_out(i)

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        """Evaluate on the caller's buffers, without copies (a FunctionBuffer of the current Function)."""
        if not self.final:
            paths, final = arrived(self.candidates)
            if paths != self.paths:
                self.fn, self.final, self.paths = self.make(load(self.libs, paths), paths), final, paths
                self._buffer = None
        if self._buffer is None:
            self._buffer = self.fn.buffer()
        buf, run = self._buffer
        for i, a in enumerate(arg):
            buf.set_arg(i, a if a is not None else self._spare("in", i))
        for i, r in enumerate(res):   # (an output the calling graph does not read comes as None)
            buf.set_res(i, r if r is not None else self._spare("out", i))
        run()
        return 0

    def _spare(self, kind: str, i: int) -> memoryview:
        """Zeros for an absent input ``i`` (kind 'in'), a scratch array for an output ``i`` nobody reads ('out')."""
        key = (kind, i)
        if key not in self._spares:
            sp = self.fn.sparsity_in(i) if kind == "in" else self.fn.sparsity_out(i)
            self._spares[key] = memoryview(bytearray(8 * max(sp.nnz(), 1))).cast("d")
        return self._spares[key]


def _path(lib: Library, flags: list[str]) -> Path:
    """The cached library of ``lib`` compiled with ``flags``."""
    return cache_dir() / f"{lib.name}_{lib.key(flags)}.so"


def ready(libs: Sequence[Library], cflags: Sequence[str] = CFLAGS) -> bool:
    """Whether every library is in the cache at its own flags (a background build has arrived)."""
    return available() and all(_path(lib, _flags(lib, cflags)).exists() for lib in libs)


def settle(timeout: float = 1800.0, cache: Path | None = None) -> float:
    """Wait until no background build is under way in the cache (:func:`building`); the seconds waited.  For
    whoever must leave no compiler running (a test session, a benchmark that wants the warm case)."""
    t = time.monotonic()
    while time.monotonic() - t < timeout and building(cache):
        time.sleep(0.2)
    return time.monotonic() - t


def _build(missing: list[tuple[Library, Path, list[str]]], timeout: float) -> None:
    """Compile the libraries ``missing`` (library, cache path, flags) concurrently; each arrives atomically."""
    if not missing:
        return
    procs: list[subprocess.Popen] = []
    tmps: list[tempfile.TemporaryDirectory] = []
    cache_dir().mkdir(parents=True, exist_ok=True)
    if notify is not None:
        what = ", ".join(lib.name for lib, _, _ in missing)
        notify(f"compiling {what} to C (once per machine; cached in {cache_dir()}; SE3OCP_NO_JIT=1 skips this)")
    try:
        outs = []
        for lib, path, fl in missing:
            tmp = tempfile.TemporaryDirectory(dir=cache_dir())
            tmps.append(tmp)
            c = _generate(lib, tmp.name)
            out = Path(tmp.name) / path.name
            with open(Path(tmp.name) / "cc.log", "wb") as log:  # a file, not a pipe: nothing can block
                procs.append(start_compiler(compiler(), c, fl, out, log))
            outs.append(out)
        deadline = time.monotonic() + timeout
        for proc, (lib, path, _), out in zip(procs, missing, outs):
            proc.wait(timeout=max(deadline - time.monotonic(), 0.0))
            if proc.returncode != 0:
                raise subprocess.CalledProcessError(proc.returncode, proc.args,
                                                    output=(out.parent / "cc.log").read_text(errors="replace"))
            os.replace(out, path)  # atomic: concurrent builders never see half a library
    finally:
        for proc in procs:  # only after a failure can one still run
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for tmp in tmps:
            tmp.cleanup()


#: whether the last :func:`compiled_libraries` loaded any library from a quick build (its own build pending)
last_provisional: bool = False

