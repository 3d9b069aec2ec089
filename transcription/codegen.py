"""Optional compilation of hot CasADi Functions to C (CasADi code generation + the system C compiler).

:func:`compiled` turns an SX :class:`casadi.Function` into an equivalent external Function
loaded from a shared library.  The library is cached on disk under a name that contains
the SHA-256 of the generated C source, so a Function is compiled once per machine (the
first build pays the compiler, e.g. ~6 s for the 80k-instruction linearized costate map at
``-O1``; later builds load it in milliseconds).  Whenever compilation is not possible (no
compiler, compiler error, unwritable cache, ``SE3OCP_NO_JIT=1``) the original Function is
returned unchanged, so callers never depend on a compiler: results are the same, only slower.

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
from typing import Callable

import casadi as ca

#: optimization level: -O1 compiles ~7x faster than -O2 on these straight-line functions
#: (5.6 s against 38 s for the linearized costate map) and runs within 25 % of it
CFLAGS = ["-O1", "-fPIC", "-shared"]

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


def compiled(fn: ca.Function, timeout: float = 600.0, cse: bool = True) -> ca.Function:
    """A compiled equivalent of ``fn`` (same name, inputs and outputs), or ``fn`` itself as fallback.

    The cache key is the SHA-256 of ``fn.serialize()`` (cheap: 0.2 s for the 230k-instruction LGVI
    linearized map, against ~1.5 s for common-subexpression elimination and C generation, which
    are only done on a cache miss), the flags and the CasADi version.
    """
    global last_error
    if not available():
        last_error = "no C compiler found (or SE3OCP_NO_JIT set)"
        return fn
    name = fn.name()
    try:
        key = hashlib.sha256(fn.serialize().encode() + " ".join(CFLAGS).encode() + ca.__version__.encode()).hexdigest()[:20]
        lib = cache_dir() / f"{name}_{key}.so"
        if not lib.exists():
            lib.parent.mkdir(parents=True, exist_ok=True)
            if notify is not None:
                notify(f"compiling {name} to C (once per machine; cached in {cache_dir()}; SE3OCP_NO_JIT=1 skips this)")
            if cse and fn.is_a("SXFunction"):
                ins = fn.sx_in()
                fn = ca.Function(name, ins, fn.call(ins), fn.name_in(), fn.name_out(), {"cse": True})
            with tempfile.TemporaryDirectory(dir=lib.parent) as tmp:
                cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
                cg.add(fn)
                cg.generate(tmp + os.sep)
                c = Path(tmp) / f"{name}.c"
                out = Path(tmp) / lib.name
                subprocess.run([compiler(), *CFLAGS, str(c), "-o", str(out), "-lm"], check=True, timeout=timeout,
                               capture_output=True)
                os.replace(out, lib)  # atomic: concurrent builders never see half a library
        ext = ca.external(name, str(lib))
        last_error = None
        return ext
    except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
        last_error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        return fn
