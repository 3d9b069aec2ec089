"""Optional compilation of hot CasADi Functions to C (CasADi code generation + the system C compiler).

:func:`compiled` turns an SX :class:`casadi.Function` into an equivalent external Function
loaded from a shared library; :func:`compiled_many` does the same for several Functions with one
library (one C file, one compiler run, one cache entry).  The library is cached on disk under a name
that contains the SHA-256 of the serialized Functions, the flags and the CasADi version, so a
Function is compiled once per machine (the first build pays the compiler; later builds load it in
milliseconds).  Whenever compilation is not possible (no compiler, compiler error, unwritable cache,
``SE3OCP_NO_JIT=1``) the original Functions are returned unchanged, so callers never depend on a
compiler: results are the same, only slower.

Flag sets: :data:`CFLAGS` (``-O1``, the direct method's stage derivatives), :data:`QUICK_CFLAGS`
(``-O0``, the indirect method's straight-line per-step maps) and :data:`LOOP_CFLAGS` (``-O1``, small
MX Functions whose C is loops).  On long straight-line functions gcc's time at ``-O1`` goes into
register allocation of one huge basic block; ``-O0`` compiles ~5x faster (measured 1.0 s against
5.5 s for a 25k-instruction map; ~30 us per line of C on this machine, linear in the length) and
runs ~1.4x slower, which is what makes a compile on the first use affordable.
``-ffp-contract=off`` keeps the compiled arithmetic that of CasADi's interpreter (no fused
multiply-adds on targets that have them), so compiled and interpreted Functions agree bit for bit.

Compiled Functions evaluate values only; request derivatives from the original Function.

Compile little, once.  The cache key is the serialized Function, so what must not change with a problem's
numbers must not be a constant of the graph: the direct method's dynamics block takes the model's numbers
(theta = mass, inertia, (2J)^-1, the potential's GM, J2, radius, sizes: ``BodyModel.parameters``) as data
like its step size, scales, weights and bounds (transcription.nlp.blocks), so a model of a known structure
(kind of body and gravity, scheme, controls, objective, free time) loads its library from the cache and
compiles nothing.  A structure never seen before is compiled with ``quick`` flags (:func:`compiled_libraries`:
``-O0``, seconds, usable at once) while a detached background process (:func:`_spawn`, at low priority, with a
``.building`` lock beside the library) compiles the library at its own flags and moves it into the cache
atomically; the next build loads it (the NLP's block derivatives check :func:`ready` between solves).  The
indirect method's per-step maps are compiled at ``-O0`` only and still contain the model's numbers (one
compile per model; a few seconds).

Environment: ``SE3OCP_CACHE`` (cache directory, default ``~/.cache/se3ocp/codegen``),
``CC`` (compiler, default ``gcc`` then ``cc``), ``SE3OCP_NO_JIT`` (disable), ``SE3OCP_JIT_BACKGROUND=0`` (compile
at the library's own flags at once instead of ``quick`` now and the rest in the background).
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca

#: optimization level: -O1 compiles ~7x faster than -O2 on these straight-line functions
#: (5.6 s against 38 s for the linearized costate map) and runs within 25 % of it
CFLAGS = ["-O1", "-fPIC", "-shared"]

#: for Functions compiled on a first use (the indirect method's maps): see the module docstring
QUICK_CFLAGS = ["-O0", "-ffp-contract=off", "-fPIC", "-shared"]

#: for small MX Functions whose C is loops (matrix products, maps): cheap to compile at -O1, and at -O0
#: those loops run slower than CasADi's interpreter, which calls its own optimized kernels
LOOP_CFLAGS = ["-O1", "-ffp-contract=off", "-fPIC", "-shared"]

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
    return compiled_libraries([Library(name, tuple(fns), cse)], timeout=timeout, cflags=cflags)[0]


@dataclass(frozen=True)
class Library:
    """One shared library: its name (prefix of the cached file), its Functions, whether SX Functions go through
    common-subexpression elimination before C generation, and its compiler flags (None: the call's)."""

    name: str
    fns: tuple
    cse: bool = False
    cflags: tuple | None = None


def _key(lib: Library, flags: list[str]) -> str:
    digest = hashlib.sha256()
    for f in lib.fns:
        digest.update(f.serialize().encode())
    # (for one Function with cse, the same key as before compiled_many existed: caches stay valid)
    digest.update(" ".join(flags).encode() + ca.__version__.encode() + (b"" if lib.cse else b"nocse"))
    return digest.hexdigest()[:20]


def _generate(lib: Library, tmp: str) -> Path:
    cg = ca.CodeGenerator(f"{lib.name}.c", {"with_header": False})
    for f in lib.fns:
        if lib.cse and f.is_a("SXFunction"):
            ins = f.sx_in()
            f = ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out(), {"cse": True})
        cg.add(f)
    cg.generate(tmp + os.sep)
    path = Path(tmp) / f"{lib.name}.c"
    path.write_text(lean_io(path.read_text()))
    return path


_BODY = re.compile(r"^(static int casadi_f\d+\(const casadi_real\*\* arg, casadi_real\*\* res, casadi_int\* iw, "
                   r"casadi_real\* w, int mem\) \{\n)(.*?)(^\}\n)", re.M | re.S)
_READ = re.compile(r"arg\[(\d+)\]\? arg\[\1\]\[(\d+)\] : 0")
_WRITE = re.compile(r"if \(res\[(\d+)\]!=0\) res\[\1\]\[(\d+)\]=")


def lean_io(source: str) -> str:
    """The generated C with every input and output pointer tested once per call instead of once per element.

    CasADi's straight-line code reads each input element as ``arg[i]? arg[i][k] : 0`` and writes each output
    element under ``if (res[i]!=0)``: hundreds of branches in one huge function, which cost gcc a third of
    its time on the linearized map.  Here a null input reads from a zero array and a null output writes to
    a scratch array on the stack, with the same values: ``ci0 = arg[0] ? arg[0] : zeros`` then ``ci0[k]``.
    Function bodies in which anything else refers to arg or res are left unchanged.
    """
    def body(m: re.Match) -> str:
        head, text, tail = m.groups()
        reads = [(int(i), int(k)) for i, k in _READ.findall(text)]
        writes = [(int(i), int(k)) for i, k in _WRITE.findall(text)]
        rest = _WRITE.sub("", _READ.sub("", text))
        if not (reads or writes) or re.search(r"\b(arg|res)\b", rest):
            return m.group(0)
        decl = []
        if reads:
            ins = sorted({i for i, _ in reads})
            decl.append(f"  static const casadi_real casadi_zeros_in[{max(k for _, k in reads) + 1}] = {{0}};\n")
            decl += [f"  const casadi_real* ci{i} = arg[{i}] ? arg[{i}] : casadi_zeros_in;\n" for i in ins]
        if writes:
            outs = sorted({i for i, _ in writes})
            decl.append(f"  casadi_real casadi_scratch_out[{max(k for _, k in writes) + 1}];\n")
            decl += [f"  casadi_real* co{i} = res[{i}] ? res[{i}] : casadi_scratch_out;\n" for i in outs]
        text = _READ.sub(lambda r: f"ci{r.group(1)}[{r.group(2)}]", text)
        text = _WRITE.sub(lambda w: f"co{w.group(1)}[{w.group(2)}]=", text)
        return head + "".join(decl) + text + tail

    return _BODY.sub(body, source)


def compiled_libraries(libs: Sequence[Library], timeout: float = 600.0, cflags: Sequence[str] = CFLAGS,
                       quick: Sequence[str] | None = None) -> list[list[ca.Function]]:
    """Compiled equivalents of every library's Functions, or all of them unchanged as fallback.

    Each library is its own C file and compiler process; the cache misses are compiled concurrently
    (the C of the next library is generated while the compiler works on the previous ones), so the
    first build takes about the longest single compile on a machine with free cores.  All or nothing
    over all libraries: callers see either every Function compiled or none.

    ``quick``: flags for a first use (e.g. :data:`QUICK_CFLAGS`).  A library not in the cache at its own flags is
    then loaded from (or compiled now with) the quick flags, and compiled with its own flags by a background
    process (:func:`_spawn`) that puts it into the cache for later builds; :data:`last_provisional` says whether
    any library came from a quick build (:func:`ready` tells when its own build has arrived).
    ``SE3OCP_JIT_BACKGROUND=0`` compiles at the library's own flags now instead.
    """
    global last_error, last_provisional
    originals = [list(lib.fns) for lib in libs]
    last_provisional = False
    if not available():
        last_error = "no C compiler found (or SE3OCP_NO_JIT set)"
        return originals
    flags = [list(lib.cflags) if lib.cflags is not None else list(cflags) for lib in libs]
    try:
        paths = [_path(lib, fl) for lib, fl in zip(libs, flags)]
        if quick is not None and os.environ.get("SE3OCP_JIT_BACKGROUND", "1") not in ("0", "false", "no"):
            for i, (lib, fl) in enumerate(zip(libs, flags)):
                if not paths[i].exists() and list(quick) != fl:
                    _spawn(lib, paths[i], fl)
                    paths[i], flags[i], last_provisional = _path(lib, list(quick)), list(quick), True
        _build([(lib, path, fl) for lib, path, fl in zip(libs, paths, flags) if not path.exists()], timeout)
        exts = [[ca.external(f.name(), str(path)) for f in lib.fns] for lib, path in zip(libs, paths)]
        last_error = None
        return exts
    except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
        last_error = f"{type(exc).__name__}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else ''}"
        last_provisional = False
        return originals


def _path(lib: Library, flags: list[str]) -> Path:
    """The cached library of ``lib`` compiled with ``flags``."""
    return cache_dir() / f"{lib.name}_{_key(lib, flags)}.so"


def ready(libs: Sequence[Library], cflags: Sequence[str] = CFLAGS) -> bool:
    """Whether every library is in the cache at its own flags (a background build has arrived)."""
    return available() and all(_path(lib, list(lib.cflags) if lib.cflags is not None else list(cflags)).exists()
                               for lib in libs)


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
                procs.append(subprocess.Popen([compiler(), *fl, str(c), "-o", str(out), "-lm"],
                                              stdout=log, stderr=subprocess.STDOUT))
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

#: a background build older than this (s) is taken for dead and started again
BACKGROUND_TIMEOUT = 1800.0


def _spawn(lib: Library, path: Path, flags: list[str]) -> None:
    """Start a detached process (:func:`_background`) that compiles ``lib`` with ``flags`` into ``path``, unless
    one is under way (a lock file ``path.building`` younger than :data:`BACKGROUND_TIMEOUT`)."""
    cache_dir().mkdir(parents=True, exist_ok=True)
    lock = path.with_name(path.name + ".building")
    try:
        if lock.exists() and time.time() - lock.stat().st_mtime < BACKGROUND_TIMEOUT:
            return
        lock.unlink(missing_ok=True)
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except OSError:              # another process took the lock first
        return
    job = Path(tempfile.mkdtemp(dir=cache_dir(), prefix="background_"))
    (job / "job.json").write_text(json.dumps({"name": lib.name, "cse": lib.cse, "flags": flags, "path": str(path),
                                              "fns": [f.serialize() for f in lib.fns]}))
    subprocess.Popen([sys.executable, "-m", __name__, str(job)], stdin=subprocess.DEVNULL,
                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def _background(job: Path) -> None:
    """The background build of :func:`_spawn` (``python -m <this module> JOB``), at low priority; the library
    arrives in the cache atomically, or not at all."""
    spec = json.loads((job / "job.json").read_text())
    path = Path(spec["path"])
    try:
        os.nice(10)
        lib = Library(spec["name"], tuple(ca.Function.deserialize(f) for f in spec["fns"]), spec["cse"])
        c = _generate(lib, str(job))
        out = job / path.name
        subprocess.run([compiler(), *spec["flags"], str(c), "-o", str(out), "-lm"], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=BACKGROUND_TIMEOUT)
        os.replace(out, path)
    finally:
        shutil.rmtree(job, ignore_errors=True)
        path.with_name(path.name + ".building").unlink(missing_ok=True)


if __name__ == "__main__":
    _background(Path(sys.argv[1]))
