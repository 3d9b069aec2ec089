"""Optional compilation of hot CasADi Functions to C (CasADi code generation + the system C compiler).

:func:`compiled` turns an SX :class:`casadi.Function` into an equivalent external Function
loaded from a shared library; :func:`compiled_many` does the same for several Functions with one
library (one C file, one compiler run, one cache entry).  The library is cached on disk under a name
that contains the SHA-256 of the serialized Functions, the flags and the CasADi version, so a
Function is compiled once per machine (the first build pays the compiler; later builds load it in
milliseconds).  Whenever compilation is not possible (no compiler, compiler error, unwritable cache,
``SE3OCP_NO_JIT=1``) the original Functions are returned unchanged, so callers never depend on a
compiler: results are the same, only slower.

Two flag sets: :data:`CFLAGS` (``-O1``, the direct method's stage derivatives) and
:data:`QUICK_CFLAGS` (``-O0``, the indirect method's per-step maps).  On these long straight-line
functions gcc's time at ``-O1`` goes into register allocation of one huge basic block; ``-O0``
compiles ~5x faster (1.0 s against 5.5 s for the 25k-instruction first-order linearized costate
map) and runs ~1.4x slower, which is what makes a compile on the first use affordable.
``-ffp-contract=off`` keeps the compiled arithmetic that of CasADi's interpreter (no fused
multiply-adds on targets that have them), so compiled and interpreted Functions agree bit for bit.

Compiled Functions evaluate values only; request derivatives from the original Function.

Environment: ``SE3OCP_CACHE`` (cache directory, default ``~/.cache/se3ocp/codegen``),
``CC`` (compiler, default ``gcc`` then ``cc``), ``SE3OCP_NO_JIT`` (disable).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca

#: optimization level: -O1 compiles ~7x faster than -O2 on these straight-line functions
#: (5.6 s against 38 s for the linearized costate map) and runs within 25 % of it
CFLAGS = ["-O1", "-fPIC", "-shared"]

#: for Functions compiled on a first use (the indirect method's maps): see the module docstring
QUICK_CFLAGS = ["-O0", "-ffp-contract=off", "-fPIC", "-shared"]

#: last failure reason (None when the last call compiled or loaded successfully); for reports
last_error: str | None = None

#: optional callable told (one line) before a cache miss is compiled, so that a front end can say why
#: the first run pauses; the CLI sets it, the library itself prints nothing
notify: Callable[[str], None] | None = None


def cache_dir() -> Path:
    return Path(os.environ.get("SE3OCP_CACHE", Path.home() / ".cache" / "se3ocp" / "codegen"))


def compiler() -> str | None:
    """The C compiler to use, or None."""
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    for name in ("gcc", "cc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def available() -> bool:
    """True if compilation can be attempted (a compiler exists and it is not disabled)."""
    return os.environ.get("SE3OCP_NO_JIT", "") not in ("1", "true", "yes") and compiler() is not None


def compiled(fn: ca.Function, timeout: float = 600.0, cse: bool = True, cflags: Sequence[str] = CFLAGS) -> ca.Function:
    """A compiled equivalent of ``fn`` (same name, inputs and outputs), or ``fn`` itself as fallback.

    The cache key is the SHA-256 of ``fn.serialize()`` (cheap: 0.2 s for the 230k-instruction LGVI
    linearized map, against ~1.5 s for common-subexpression elimination and C generation, which
    are only done on a cache miss), the flags and the CasADi version.
    """
    return compiled_many([fn], fn.name(), timeout=timeout, cse=cse, cflags=cflags)[0]


def compiled_many(fns: Sequence[ca.Function], name: str, timeout: float = 600.0, cse: bool = True,
                  cflags: Sequence[str] = CFLAGS) -> list[ca.Function]:
    """Compiled equivalents of ``fns`` from one shared library ``name``, or ``fns`` unchanged as fallback.

    All or nothing: either every Function is loaded from the library or the originals are returned.
    ``cse``: common-subexpression elimination of SX Functions before generating C (fewer lines for
    the compiler and faster code, at the cost of the elimination itself, paid on a cache miss only).
    """
    global last_error
    fns = list(fns)
    if not available():
        last_error = "no C compiler found (or SE3OCP_NO_JIT set)"
        return fns
    flags = list(cflags)
    try:
        digest = hashlib.sha256()
        for f in fns:
            digest.update(f.serialize().encode())
        # (for one Function with cse, the same key as before compiled_many existed: caches stay valid)
        digest.update(" ".join(flags).encode() + ca.__version__.encode() + (b"" if cse else b"nocse"))
        key = digest.hexdigest()[:20]
        lib = cache_dir() / f"{name}_{key}.so"
        if not lib.exists():
            lib.parent.mkdir(parents=True, exist_ok=True)
            if notify is not None:
                what = name if len(fns) == 1 else f"{name} ({', '.join(f.name() for f in fns)})"
                notify(f"compiling {what} to C (once per machine; cached in {cache_dir()}; SE3OCP_NO_JIT=1 skips this)")
            with tempfile.TemporaryDirectory(dir=lib.parent) as tmp:
                cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
                for f in fns:
                    if cse and f.is_a("SXFunction"):
                        ins = f.sx_in()
                        f = ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out(), {"cse": True})
                    cg.add(f)
                cg.generate(tmp + os.sep)
                c = Path(tmp) / f"{name}.c"
                out = Path(tmp) / lib.name
                subprocess.run([compiler(), *flags, str(c), "-o", str(out), "-lm"], check=True, timeout=timeout,
                               capture_output=True)
                os.replace(out, lib)  # atomic: concurrent builders never see half a library
        exts = [ca.external(f.name(), str(lib)) for f in fns]
        last_error = None
        return exts
    except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
        last_error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        return fns
