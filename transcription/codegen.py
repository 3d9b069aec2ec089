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
(``-O0``, the indirect method's straight-line per-step maps, and every first background stage) and
:data:`LOOP_CFLAGS` (``-O1``, small MX Functions whose C is loops).  On long straight-line functions
gcc's time at ``-O1`` goes into register allocation of one huge basic block; ``-O0`` compiles ~5x faster
(measured 1.0 s against 5.5 s for a 25k-instruction map; ~30 us per line of C on this machine, linear in the
length) and runs ~1.4x slower, which is what makes a compile on the first use affordable.
``-ffp-contract=off`` (every flag set) keeps the compiled arithmetic that of CasADi's interpreter (no fused
multiply-adds on targets that have them), so compiled and interpreted Functions agree bit for bit.

Compiled Functions evaluate values only; request derivatives from the original Function.

Compile little, once.  The cache key is the serialized Function, so what must not change with a problem's
numbers must not be a constant of the graph: the direct method's dynamics block and the indirect method's
per-step maps take the model's numbers (theta = mass, inertia, (2J)^-1, the potential's GM, J2, radius, sizes:
``BodyModel.parameters``; lgvi.Discretization.parametric / with_theta) as data like the step size, scales,
weights and bounds, so a model of a known structure (kind of body and gravity, scheme, controls, objective, free
time) loads its libraries from the cache and compiles nothing.

Interpreted first.  A structure never seen before is not waited for (:func:`compiled_libraries` with ``quick``):
its Functions come back interpreted while a detached background process (:func:`_spawn`, niced, with a
``.building`` lock beside the library that holds its process id, one of :data:`SLOTS` compilers at a time)
compiles the library at the ``quick`` flags (-O0, seconds) and then at its own into the cache, each atomically.
:class:`Switch` (a copy-free Callback) wraps what is built from those Functions -- the NLP's mapped block
derivatives, the indirect method's shooting Functions -- and moves to the compiled code when it lands, between
two evaluations of the same solve; the next build loads it directly (:func:`ready`).  :func:`settle` waits for
the builds under way, :func:`stop` ends them.

Environment: ``SE3OCP_CACHE`` (cache directory, default ``~/.cache/se3ocp/codegen``),
``CC`` (compiler, default ``gcc`` then ``cc``), ``SE3OCP_NO_JIT`` (disable), ``SE3OCP_JIT_BACKGROUND=0`` (compile
at the library's own flags at once instead of interpreting first and compiling in the background).
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import casadi as ca

try:
    import fcntl
except ImportError:          # not POSIX: no slots (every build compiles at once)
    fcntl = None

#: optimization level: -O1 compiles ~7x faster than -O2 on these straight-line functions
#: (5.6 s against 38 s for the linearized costate map) and runs within 25 % of it; -ffp-contract=off: the
#: interpreter's arithmetic (no fused multiply-adds), so that a solve that moves from the interpreter to the
#: compiled code (:class:`Switch`) gives the same bits wherever the move happens, on every target
CFLAGS = ["-O1", "-ffp-contract=off", "-fPIC", "-shared"]

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
    common-subexpression elimination before C generation, its compiler flags (None: the call's), and whether a
    background build compiles it with the quick flags first (:func:`compiled_libraries`; not for C of loops, which
    at -O0 runs slower than the interpreter)."""

    name: str
    fns: tuple
    cse: bool = False
    cflags: tuple | None = None
    quick: bool = True

    @functools.cached_property
    def serialized(self) -> tuple[str, ...]:
        """The serialized Functions (the cache key's and the background build's; computed once: ~0.1 s for a
        large map)."""
        return tuple(f.serialize() for f in self.fns)


def _key(lib: Library, flags: list[str]) -> str:
    memo = lib.__dict__.setdefault("_keys", {})   # (a frozen dataclass: its keys kept beside its cached_property)
    if tuple(flags) not in memo:
        digest = hashlib.sha256()
        for text in lib.serialized:
            digest.update(text.encode())
        # (for one Function with cse, the same key as before compiled_many existed: caches stay valid)
        digest.update(" ".join(flags).encode() + ca.__version__.encode() + (b"" if lib.cse else b"nocse"))
        memo[tuple(flags)] = digest.hexdigest()[:20]
    return memo[tuple(flags)]


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
    over all libraries: callers see either every Function compiled or none (without ``quick``; with it, each
    library is compiled or interpreted on its own).

    ``quick``: the interpreted-first policy.  A library not in the cache at its own flags is not waited for: it is
    loaded from its quick build (e.g. :data:`QUICK_CFLAGS`) if that is in the cache, else given back as the
    interpreted Function, while a background process (:func:`_spawn`) compiles it -- with the quick flags first
    (seconds), then with its own -- into the cache.  :data:`last_provisional` says whether any library is not yet
    at its own flags; :class:`Switch` evaluates a Function built from them and moves to the compiled code as it
    arrives, even within a solve (:func:`arrived`; same values: ``-ffp-contract=off`` keeps the compiled arithmetic
    the interpreter's).  ``SE3OCP_JIT_BACKGROUND=0`` compiles at the library's own flags now instead.
    """
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
            out = []
            for lib, path, fl in zip(libs, paths, flags):
                if path.exists():
                    out.append(_external(lib, path))
                    continue
                last_provisional = True
                stages = [(list(quick), _path(lib, list(quick)))] if lib.quick and list(quick) != fl else []
                _spawn(lib, [(f, p) for f, p in stages + [(fl, path)] if not p.exists()])
                have = [p for _, p in stages if p.exists()]
                out.append(_external(lib, have[0]) if have else list(lib.fns))
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


def arrived(paths: Sequence[Sequence[Path]]) -> tuple[tuple[Path, ...], bool] | None:
    """The best cached file of each library (``paths``: :func:`candidates`) and whether all are the best; None while
    some library has none in the cache (:func:`load` loads them)."""
    out, final = [], True
    for cands in paths:
        have = [p for p in cands if p.exists()]
        if not have:
            return None
        final = final and have[0] == cands[0]
        out.append(have[0])
    return tuple(out), final


def load(libs: Sequence[Library], paths: Sequence[Path]) -> list[list[ca.Function]]:
    """Every library's Functions from its shared library ``paths`` (:func:`arrived`)."""
    return [_external(lib, path) for lib, path in zip(libs, paths)]


def _external(lib: Library, path: Path) -> list[ca.Function]:
    """``lib``'s Functions loaded from its shared library ``path``."""
    return [ca.external(f.name(), str(path)) for f in lib.fns]


class Switch(ca.Callback):
    """A Function that evaluates ``fn`` (built from interpreted or quick-compiled Functions) until the compiled
    libraries ``libs`` arrive in the cache (:func:`arrived`, checked at every evaluation until they are all at their
    own flags), then ``make(loaded, final)``: the same Function built from the compiled ones (final: all at their own
    flags).  The interpreted-first
    policy's way to use compiled code as soon as it exists, within a solve (an NLP's derivative Functions, the
    indirect method's shooting Functions).  Values only, like the compiled Functions; the same values bit for bit
    (-ffp-contract=off), so where the switch happens does not show in the results."""

    def __init__(self, fn: ca.Function, libs: Sequence[Library], make: Callable[[list, bool], ca.Function],
                 cflags: Sequence[str] = CFLAGS, quick: Sequence[str] = QUICK_CFLAGS):
        ca.Callback.__init__(self)
        self.fn, self.libs, self.make = fn, tuple(libs), make
        self.candidates = candidates(libs, cflags, quick)
        self.final, self.paths, self._buffer = False, None, None
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
            got = arrived(self.candidates)
            if got is not None and got[0] != self.paths:
                self.fn, self.final, self.paths = self.make(load(self.libs, got[0]), got[1]), got[1], got[0]
                self._buffer = None
        if self._buffer is None:
            self._buffer = self.fn.buffer()
        buf, run = self._buffer
        for i, a in enumerate(arg):
            buf.set_arg(i, a)
        for i, r in enumerate(res):
            buf.set_res(i, r)
        run()
        return 0


def _path(lib: Library, flags: list[str]) -> Path:
    """The cached library of ``lib`` compiled with ``flags``."""
    return cache_dir() / f"{lib.name}_{_key(lib, flags)}.so"


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


def _spawn(lib: Library, stages: list[tuple[list[str], Path]]) -> None:
    """Start a detached process (:func:`_background`) that compiles ``lib`` with each stage's flags into its path in
    turn (the quick flags first, then the library's own), unless one is under way (a lock file beside the last
    path, ``.building``, holding the builder's process id, :func:`_alive`).  Tells :data:`notify` when it starts
    one."""
    if not stages:
        return
    cache_dir().mkdir(parents=True, exist_ok=True)
    lock = stages[-1][1].with_name(stages[-1][1].name + ".building")
    try:
        if _alive(lock):
            return
        lock.unlink(missing_ok=True)
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except OSError:              # another process took the lock first
        return
    if notify is not None:
        notify(f"compiling {lib.name} to C in the background (once per machine; cached in {cache_dir()}; "
               "interpreted until it arrives; SE3OCP_NO_JIT=1 skips this)")
    job = Path(tempfile.mkdtemp(dir=cache_dir(), prefix="background_"))
    (job / "job.json").write_text(json.dumps({"name": lib.name, "cse": lib.cse, "lock": str(lock),
                                              "stages": [[f, str(p)] for f, p in stages],
                                              "fns": list(lib.serialized)}))
    proc = subprocess.Popen([sys.executable, "-m", __name__, str(job)], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    lock.write_text(str(proc.pid))


def _alive(lock: Path) -> bool:
    """Whether the build behind ``lock`` is under way: its process (the id in the lock; a lock still empty is being
    written, for a minute at most) exists, and the lock is younger than :data:`BACKGROUND_TIMEOUT`."""
    try:
        age, text = time.time() - lock.stat().st_mtime, lock.read_text().strip()
    except OSError:
        return False
    if age >= BACKGROUND_TIMEOUT or not text:
        return age < 60.0
    try:
        os.kill(int(text), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError):
        return True
    return True


def building(cache: Path | None = None) -> list[Path]:
    """The locks of the background builds under way in the cache."""
    return [lock for lock in (cache_dir() if cache is None else cache).glob("*.building") if _alive(lock)]


def stop(cache: Path | None = None, timeout: float = 10.0) -> int:
    """End the background builds under way in the cache (their process groups: the builder and its compiler); each
    removes its job and its lock as it ends.  The number stopped.  For a caller that must not wait for them."""
    locks = building(cache)
    for lock in locks:
        try:
            os.killpg(int(lock.read_text().strip()), signal.SIGTERM)
        except (OSError, ValueError):
            pass
    t = time.monotonic()
    while any(lock.exists() for lock in locks) and time.monotonic() - t < timeout:
        time.sleep(0.1)
    return len(locks)


#: how many background builds compile at once (the others wait for a slot): cores, not one per library
SLOTS = max(1, os.cpu_count() or 1)


def _slot(first: bool) -> int | None:
    """Hold one of :data:`SLOTS` slots (an exclusive lock on ``.slotK`` in the cache, released when the descriptor
    is closed or the process ends); the descriptor (None without POSIX file locks).  A first stage (what a running
    solve waits for) may take any slot, a later one (-O1) only slot 0: the -O1 builds go one at a time and never
    hold up a quick one."""
    if fcntl is None:
        return None
    while True:
        for k in range(SLOTS if first else 1):
            fd = os.open(cache_dir() / f".slot{k}", os.O_CREAT | os.O_RDWR)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return fd
            except OSError:
                os.close(fd)
        time.sleep(0.2)


#: the niceness of a background build's first stage (what a running solve waits for) and of its later ones
FIRST_NICE, LATER_NICE = 5, 10


def _lower_priority(level: int) -> None:
    """Niceness ``level`` for this process and, where the kernel groups the processes of a session for scheduling
    (Linux autogroups: a process nices only against its own session, and :func:`_spawn` starts a new one), for its
    session's group too -- without it a niced build took a full share from the solve that started it."""
    os.nice(max(level - os.nice(0), 0))
    if os.getsid(0) != os.getpid():   # not the leader of a session of its own: the group is the caller's too
        return
    try:
        Path("/proc/self/autogroup").write_text(str(level))
    except OSError:
        pass


def _background(job: Path) -> None:
    """The background build of :func:`_spawn` (``python -m <this module> JOB``); each stage's library arrives in the
    cache atomically, or not at all; the lock goes last (also when ended by SIGTERM, :func:`stop`).  At lower
    priority, the solve that started it running on, interpreted, at its own: the first stage at :data:`FIRST_NICE`
    (measured: three builds at the caller's priority slowed a short first solve 1.6x at load 7; at nice 10 under
    load 4 the -O0 build of a 15k-line map took longer than the 7 s solve it was for), later ones at
    :data:`LATER_NICE`.
    Each stage waits for a slot (:func:`_slot`): a cold test suite starts dozens of builds."""
    spec = json.loads((job / "job.json").read_text())
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    try:
        _lower_priority(FIRST_NICE)
        lib = Library(spec["name"], tuple(ca.Function.deserialize(f) for f in spec["fns"]), spec["cse"])
        c = _generate(lib, str(job))
        for i, (flags, path) in enumerate(spec["stages"]):
            out = job / Path(path).name
            if i > 0:
                _lower_priority(LATER_NICE)
            fd = _slot(i == 0)
            try:
                subprocess.run([compiler(), *flags, str(c), "-o", str(out), "-lm"], check=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=BACKGROUND_TIMEOUT)
            finally:
                if fd is not None:
                    os.close(fd)
            os.replace(out, path)
    finally:
        shutil.rmtree(job, ignore_errors=True)
        Path(spec["lock"]).unlink(missing_ok=True)


if __name__ == "__main__":
    _background(Path(sys.argv[1]))
