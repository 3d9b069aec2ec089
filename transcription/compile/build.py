"""The C side of :mod:`.codegen`: generating the C of CasADi Functions, and the background builds of its
interpreted-first policy -- one detached process per :func:`spawn` (``python -m`` this module), which compiles
libraries into the cache while the solve that started it runs on, interpreted.

Environment: ``SE3OCP_CACHE`` (cache directory, default ``~/.cache/se3ocp/codegen``), ``CC`` (compiler, default
``gcc`` then ``cc``).
"""
from __future__ import annotations

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
from typing import Callable

import casadi as ca

try:
    import fcntl
except ImportError:          # not POSIX: no slots (every build compiles at once)
    fcntl = None


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


def start_compiler(cc: str, c: Path, flags: list[str], out: Path, log=subprocess.DEVNULL) -> subprocess.Popen:
    """Start ``[cc, *flags, c, -o, out, -lm]``, output and errors to ``log``: the one command line of both builders
    (:func:`_compile` here, the in-process ``codegen._build``)."""
    return subprocess.Popen([cc, *flags, str(c), "-o", str(out), "-lm"], stdout=log, stderr=subprocess.STDOUT)


def generate(name: str, fns, cse: bool, tmp: str) -> Path:
    """The C file ``{tmp}/{name}.c`` of the Functions ``fns`` (SX ones through common-subexpression elimination if
    ``cse``), with :func:`lean_io`."""
    cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
    for f in fns:
        if cse and f.is_a("SXFunction"):
            ins = f.sx_in()
            f = ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out(), {"cse": True})
        cg.add(f)
    cg.generate(tmp + os.sep)
    path = Path(tmp) / f"{name}.c"
    path.write_text(lean_io(path.read_text()))
    return path


_BODY = re.compile(r"^(static int casadi_f\d+\(const casadi_real\*\* arg, casadi_real\*\* res, casadi_int\* iw, "
                   r"casadi_real\* w, int mem\) \{\n)(.*?)(^\}\n)", re.M | re.S)
_READ = re.compile(r"arg\[(\d+)\]\? arg\[\1\]\[(\d+)\] : 0")
_WRITE = re.compile(r"if \(res\[(\d+)\]!=0\) res\[\1\]\[(\d+)\]=")


def lean_io(source: str) -> str:
    """The generated C with every input and output pointer tested once per call instead of once per element.

    CasADi reads each input element as ``arg[i]? arg[i][k] : 0`` and writes each output under ``if (res[i]!=0)``:
    hundreds of branches that slow gcc.  Here a null input reads from a zero array and a null output writes to a
    scratch array (``ci0 = arg[0] ? arg[0] : zeros`` then ``ci0[k]``).  Bodies that use arg or res otherwise are
    left unchanged.
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


#: a background build older than this (s) is taken for dead and started again
BACKGROUND_TIMEOUT = 1800.0


def spawn(builds: list, notify: Callable[[str], None] | None = None) -> None:
    """Start one detached process (:func:`_background`) that compiles each library of ``builds`` (library, stages,
    waited: whether a solve waits for its first stage) stage by stage (quick flags first, then the library's own), in
    the order given, skipping those under way elsewhere (a ``.building`` lock beside the last path holding the
    builder's pid, :func:`_alive`).  One process for all libraries: one interpreter start.  Tells ``notify`` of each."""
    builds = [b for b in builds if b[1]]   # (library: a codegen.Library)
    if not builds:
        return
    cache_dir().mkdir(parents=True, exist_ok=True)
    taken = []
    for lib, stages, waited in builds:
        lock = stages[-1][1].with_name(stages[-1][1].name + ".building")
        try:
            if _alive(lock):
                continue
            lock.unlink(missing_ok=True)
            os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except OSError:          # another process took the lock first
            continue
        taken.append((lib, stages, lock, waited))
        if notify is not None:
            notify(f"compiling {lib.name} to C in the background (once per machine; cached in {cache_dir()}; "
                   "interpreted until it arrives; SE3OCP_NO_JIT=1 skips this)")
    if not taken:
        return
    job = Path(tempfile.mkdtemp(dir=cache_dir(), prefix="background_"))
    (job / "job.json").write_text(json.dumps([{"name": lib.name, "cse": lib.cse, "lock": str(lock),
                                               "stages": [[f, str(p)] for f, p in stages], "first": int(waited),
                                               "fns": list(lib.serialized)} for lib, stages, lock, waited in taken]))
    proc = subprocess.Popen([sys.executable, "-m", __name__, str(job)], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    for _, _, lock, _ in taken:
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
    stopped: set[Path] = set()
    t = time.monotonic()
    while time.monotonic() - t < timeout:
        # listed again each time: a build whose lock had no pid yet when first seen, or one started since, is
        # stopped too
        locks = building(cache)
        if not locks:
            break
        for lock in set(locks) - stopped:
            try:
                os.killpg(int(lock.read_text().strip()), signal.SIGTERM)
                stopped.add(lock)
            except (OSError, ValueError):
                pass
        for lock in stopped:
            _reap(lock)
        time.sleep(0.1)
    for lock in stopped:      # a builder ended before its SIGTERM handler was set (still starting) left its lock
        if lock.exists() and not _alive(lock):
            lock.unlink(missing_ok=True)
    if stopped:               # ... and its job, which it removes before its locks when it ends by its handler
        _remove_orphans(cache_dir() if cache is None else cache)
    return len(stopped)


def _remove_orphans(cache: Path) -> None:
    """Remove the jobs in ``cache`` whose builder is gone: none of their locks is held by a build under way
    (:func:`_alive`).  A builder removes its job before its last lock, so a job without a live lock is left over."""
    for spec in cache.glob("background_*/job.json"):
        try:
            locks = [Path(entry["lock"]) for entry in json.loads(spec.read_text())]
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if not any(_alive(lock) for lock in locks):
            shutil.rmtree(spec.parent, ignore_errors=True)


def _reap(lock: Path) -> None:
    """Collect the builder behind ``lock`` if it is this process's child and has ended: until then it is a zombie,
    which :func:`_alive` (a signal 0 to its id) takes for a build under way."""
    try:
        os.waitpid(int(lock.read_text().strip()), os.WNOHANG)
    except (OSError, ValueError):       # not our child, already collected, or the lock gone
        pass


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


#: the niceness of a background build's first stages (what a running solve waits for) and of its later ones: a
#: compromise between a short solve, which only pays the builder's share of a core, and a long one, which runs on
#: the libraries (measurements: docs/bench_notes.md, issue 27)
FIRST_NICE, LATER_NICE = 2, 10


def _lower_priority(level: int) -> None:
    """Niceness ``level`` for this process and, under Linux autogroups (nice orders only a session's own processes;
    :func:`spawn` starts a new session), for its session's group too."""
    os.nice(max(level - os.nice(0), 0))
    if os.getsid(0) != os.getpid():   # not the leader of a session of its own: the group is the caller's too
        return
    try:
        Path("/proc/self/autogroup").write_text(str(level))
    except OSError:
        pass


def _background(job: Path) -> None:
    """The background build of :func:`spawn` (``python -m <this module> JOB``).  Each stage's library arrives in the
    cache atomically or not at all; a library's lock goes when its last stage has arrived, every lock at the end (also
    on SIGTERM, :func:`stop`).  First stages at :data:`FIRST_NICE`, up to :data:`PARALLEL` compilers, the next C
    generated meanwhile (:func:`_first_stages`); then the later stages one at a time at :data:`LATER_NICE`.  Each
    compile waits for a slot (:func:`_slot`): a cold test suite starts dozens of builds."""
    spec = json.loads((job / "job.json").read_text())
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    try:
        _lower_priority(FIRST_NICE)
        sources = _first_stages(spec, job)
        _lower_priority(LATER_NICE)
        for i, (entry, c) in enumerate(zip(spec, sources)):
            for flags, path in entry["stages"][entry["first"]:]:
                _compile(c, flags, Path(path), job, first=False).wait_arrived()
            if i < len(spec) - 1:   # the last lock goes after the job's files (below): whoever waits for the locks
                Path(entry["lock"]).unlink(missing_ok=True)     # (codegen.settle) finds no job left behind
    finally:
        shutil.rmtree(job, ignore_errors=True)
        for entry in spec:
            Path(entry["lock"]).unlink(missing_ok=True)


#: how many compilers one background build runs at once for the first stages: the cores but one, which the solve
#: the build is for keeps (on two cores, one at a time: a second compiler would share the solve's core)
PARALLEL = max(1, (os.cpu_count() or 1) - 1)


def _first_stages(spec: list[dict], job: Path) -> list[Path]:
    """Generate each library's C and, if a solve waits for it (``first``), compile its first stage (at most
    :data:`PARALLEL` at once, in ``spec`` order; a library with one stage loses its lock as it arrives).  Returns the C
    files, for the later stages."""
    sources, running = [], []
    for i, entry in enumerate(spec):
        (job / str(i)).mkdir()
        fns = tuple(ca.Function.deserialize(f) for f in entry["fns"])
        sources.append(generate(entry["name"], fns, entry["cse"], str(job / str(i))))   # while the last one compiles
        if not entry["first"]:
            continue
        while len(running) >= PARALLEL:
            running.pop(0).wait_arrived()
        flags, path = entry["stages"][0]
        running.append(_compile(sources[-1], flags, Path(path), job, first=True,
                                lock=Path(entry["lock"]) if len(entry["stages"]) == 1 else None))
    for build in running:
        build.wait_arrived()
    return sources


@dataclass
class _Compile:
    """One compiler run of a background build: its process, the slot it holds, its output and where that goes."""

    proc: subprocess.Popen
    fd: int | None
    out: Path
    path: Path
    lock: Path | None = None

    def wait_arrived(self) -> None:
        """Wait for the compiler, release the slot, move the library into the cache (atomically), drop the lock if
        any.  A failed compile leaves nothing in the cache (that library stays interpreted)."""
        try:
            code = self.proc.wait(timeout=BACKGROUND_TIMEOUT)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        finally:
            if self.fd is not None:
                os.close(self.fd)
        if code == 0:
            os.replace(self.out, self.path)
        if self.lock is not None:
            self.lock.unlink(missing_ok=True)


def _compile(c: Path, flags: list[str], path: Path, job: Path, first: bool, lock: Path | None = None) -> _Compile:
    """Start compiling the C file ``c`` with ``flags`` for ``path`` once a slot is free (:func:`_slot`)."""
    fd = _slot(first)
    out = c.parent / path.name
    try:
        proc = start_compiler(compiler(), c, flags, out)
    except BaseException:
        if fd is not None:
            os.close(fd)
        raise
    return _Compile(proc, fd, out, path, lock)


if __name__ == "__main__":
    _background(Path(sys.argv[1]))
