"""Results directories, written as one transaction: a run's directory is one complete run,
or absent.

A run writes its results through a :class:`ResultsTransaction`
(:func:`results_transaction`; :func:`results_update` for ``plot``)::

    with results_transaction(args.out, Path("results") / name, args.force) as tx:
        write_json(tx.path / "summary.json", summary)     # tx.path: a private directory
    # here tx.target is the complete new run

* The run writes into a fresh hidden sibling ``.NAME.tmp-PID-XXXXXXXX`` (same file system).
  Leaving the ``with`` block normally commits: the directory is renamed to ``NAME`` (if
  ``NAME`` exists -- an empty directory, or a results directory with ``force`` -- the two are
  exchanged atomically and the previous run is deleted).  The whole directory is replaced,
  so no file of an earlier run (a stale ``indirect.npz``, figure or GIF) survives.
* An exception (also KeyboardInterrupt) leaves ``NAME`` untouched and deletes the temporary
  directory.  To keep an interrupted or failed run, call ``tx.commit(incomplete=REASON)``
  before re-raising: the directory is committed with a file ``INCOMPLETE`` holding REASON.
* What a reader of ``NAME`` can observe: nothing until the first commit, then always one
  complete run -- the previous one until the instant of the swap, the new one after.  On
  Linux the swap is ``renameat2(RENAME_EXCHANGE)``, so the name always refers to a complete
  directory.  Where that call is unsupported (other systems, some network file systems) two
  renames are used: for the microseconds between them ``NAME`` is absent (a crash exactly
  there leaves the previous run at ``.NAME.old-PID-XXXXXXXX``, which the next transaction on
  ``NAME`` puts back).  A reader that opens several files one by one while a swap happens
  can get files of both runs; it can compare ``summary.json`` before and after, or open the
  directory once and read relative to that descriptor.
* Concurrency: a transaction holds an exclusive ``flock`` on ``.NAME.lock`` beside ``NAME``
  from start to commit; a second run on the same ``NAME`` fails at once with
  ``ResultsDirError("NAME: is being written by another se3ocp run (pid N); ...")``.  Without
  ``--out`` a busy or non-empty default ``results/NAME`` makes the run use the first free
  ``results/NAME.1``, ``NAME.2``, ... (chosen under the locks, so concurrent runs get
  different directories).  The lock file is removed when the transaction ends.
* Stale temporaries: a killed run (SIGKILL, power loss) can leave ``.NAME.tmp-*`` or
  ``.NAME.old-*`` behind.  Whoever holds ``NAME``'s lock is the only writer of these names,
  so every transaction on ``NAME`` deletes them when it starts (after restoring a
  ``.NAME.old-*`` if ``NAME`` is missing).
* ``force`` replaces only an empty directory or a results directory (one holding one of
  :data:`RESULTS_MARKERS`), and never the working directory or one of its parents: a typo
  such as ``--out . --force`` or ``--out ~ --force`` is refused instead of deleting files.
* The lock is ``fcntl.flock`` (POSIX), imported when a lock is taken: importing this module
  works anywhere, taking a lock where there is no fcntl is a one-line error.  The
  cross-platform ``filelock`` package was considered and not used: by design it leaves the lock
  file in place on release (this module removes it, safely, by checking on every acquisition
  that the file it locked is still the one under the name), it opens lock files read-write only
  (this module takes the lock on another user's lock file through a read-only descriptor), and
  the rest of the transaction (renameat2, directory fsync, renames over directories) is POSIX
  anyway.
"""
from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import signal
import stat
import sys
import threading
from pathlib import Path

from .io import ResultsDirError, _fs_error, _show, atomic_write_bytes
from .schema import ConfigError


#: the file an incomplete commit (``commit(incomplete=REASON)``) adds, holding REASON
INCOMPLETE_MARKER = "INCOMPLETE"
#: a directory holding one of these is a results directory, which ``force`` may replace
RESULTS_MARKERS = ("summary.json", "config.resolved.yaml", "sweep.resolved.yaml", INCOMPLETE_MARKER)
#: hidden names are ``.STEM.lock`` / ``.STEM.tmp-PID-XXXXXXXX``: a longer NAME is shortened to
#: STEM (a prefix and a hash) so that they fit in the file system's 255-byte names
_MAX_STEM_BYTES = 200
#: the most numbered siblings ``NAME.1``, ``NAME.2``, ... tried for a default directory
MAX_SIBLINGS = 10_000


def _stem(name: str) -> str:
    if len(name.encode()) <= _MAX_STEM_BYTES:
        return name
    import hashlib

    head = name.encode()[:100].decode("utf-8", "ignore")
    return f"{head}~{hashlib.sha256(name.encode()).hexdigest()[:16]}"


def _name_max(parent: Path) -> int:
    p = parent
    while True:
        try:
            return os.pathconf(p, "PC_NAME_MAX")
        except (OSError, ValueError):
            if p.parent == p:
                return 255
            p = p.parent


def _checked_dir_path(p, what: str) -> Path:
    """``p`` as the path of a results directory, or ResultsDirError for names that cannot be one."""
    s = os.fspath(p)
    if s == "":
        raise ResultsDirError(f"{what}: expected a directory name, got an empty string")
    if "\0" in s:
        raise ResultsDirError(f"{_show(s)}: a path cannot contain a NUL byte")
    path = Path(s)
    if path.name in ("", ".", ".."):
        raise ResultsDirError(f"{_show(s)}: expected the name of a results directory, not '.', '..' or '/'")
    limit = _name_max(path.parent)
    n = len(path.name.encode("utf-8", "surrogateescape"))
    if n > limit:
        raise ResultsDirError(f"{_show(s)}: name too long ({n} bytes; the file system allows {limit})")
    if path.is_symlink() and path.is_dir():  # --out link-to-dir: the directory is replaced, not the link
        path = Path(os.path.realpath(path))
    return path


def _entries(d: Path) -> list[str]:
    try:
        return os.listdir(d)
    except FileNotFoundError:
        return []
    except OSError as e:
        raise _fs_error(d, e, "read the directory") from None


def _occupied(p: Path) -> bool:
    """A file, or a directory holding anything."""
    return os.path.lexists(p) and (not p.is_dir() or bool(_entries(p)))


def _inside_cwd_chain(p: Path) -> bool:
    try:
        here = Path.cwd().resolve()
        return p.resolve() in (here, *here.parents)
    except OSError:
        return False


class _Lock:
    """An exclusive, non-blocking ``flock`` on ``.STEM.lock``; the holder's pid is in the file.
    The holder removes the file when it releases the lock; whoever locks checks that the file
    it locked is still the one under the name (else it retries), so removal is safe."""

    def __init__(self, path: Path):
        self.path, self.fd = path, -1

    def try_acquire(self) -> int | None:
        """None when acquired, else the pid of the holder (0 if unknown).  OSError (ENOSYS) where
        there is no fcntl (not POSIX)."""
        try:
            import fcntl
        except ImportError:
            raise OSError(errno.ENOSYS, "file locks (fcntl.flock) are not available on this system") from None
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
            except PermissionError as e:  # another user's lock file: flock works on a read-only descriptor
                try:
                    fd = os.open(self.path, os.O_RDONLY | os.O_CLOEXEC)
                except OSError:
                    raise e from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                try:
                    text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
                finally:
                    os.close(fd)
                return int(text) if text.isdigit() else 0
            except BaseException:
                os.close(fd)
                raise
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                with contextlib.suppress(OSError):  # the pid is for messages only
                    os.ftruncate(fd, 0)
                    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                self.fd = fd
                return None
            os.close(fd)  # removed or replaced by its previous holder meanwhile: lock the new file

    def release(self) -> None:
        if self.fd >= 0:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
            os.close(self.fd)
            self.fd = -1


_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_renameat2 = None
if sys.platform.startswith("linux"):  # pragma: no branch - Linux with glibc >= 2.28
    try:
        _renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
        _renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    except (AttributeError, OSError):  # pragma: no cover
        _renameat2 = None


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap the names ``a`` and ``b`` (both must exist); False if unsupported here."""
    if _renameat2 is None:
        return False
    if _renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EPERM):
        return False  # the file system or the kernel cannot: fall back to two renames
    raise OSError(err, os.strerror(err), str(b))


def _fsync_dir(d: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(d, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_tree(d: Path) -> None:
    """Flush every file (also those written by other means than atomic_write_bytes) and directory."""
    for root, dirs, files in os.walk(d):
        for f in files:
            p = os.path.join(root, f)
            if not stat.S_ISREG(os.lstat(p).st_mode):  # links, and FIFOs that would block an open
                continue
            fd = os.open(p, os.O_RDONLY | os.O_CLOEXEC)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        _fsync_dir(Path(root))


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT/SIGTERM/SIGHUP wait until the block ends (the swap and its bookkeeping are one
    step); then they get their handlers as usual.  Python-level, because a signal may reach any
    thread (BLAS, CasADi), and Python runs the handler in the main thread wherever it arrived.
    Outside the main thread there is nothing to do: handlers do not run there."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    old = {}
    try:
        for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            old[s] = signal.signal(s, lambda signum, frame: pending.append(signum))
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        for s in pending:  # as if they arrived now
            h = old[s]
            if callable(h):
                h(s, None)
            elif h == signal.SIG_DFL:
                signal.raise_signal(s)


class ResultsTransaction:
    """One run's results directory, written as a whole: see the module docstring.

    Use as a context manager (the directory is chosen, locked and created on entry).
    ``target``: the final directory; ``path``: where to write until the commit.
    Leaving the block normally commits; an exception aborts (nothing changes under
    ``target``).  :meth:`commit` may be called inside the block, e.g. with
    ``incomplete=REASON`` on Ctrl-C before re-raising.
    """

    #: (target, incomplete reason or None) of every commit in this process, in order (the CLI says what
    #: an interrupted run left)
    committed: list = []

    def __init__(self, out: str | os.PathLike | None, default: str | os.PathLike | None = None,
                 force: bool = False, *, update: bool = False):
        if out is None and default is None:
            raise ValueError("results_transaction needs out or default")
        self._out, self._default, self.force, self.update = out, default, bool(force), update
        self.target: Path | None = None
        self.path: Path | None = None
        self.state = "new"  # -> open -> committed | aborted
        self._lock: _Lock | None = None
        self._made: list[Path] = []

    # ---------------------------------------------------------------- entering
    def __enter__(self) -> "ResultsTransaction":
        try:
            self._begin()
        except BaseException:
            self._cleanup()
            raise
        self.state = "open"
        return self

    def _begin(self) -> None:
        if self._out is not None:
            target = _checked_dir_path(self._out, "results directory" if self.update else "--out")
            if self.update:
                if not target.is_dir():
                    raise ResultsDirError(f"{_show(target)}: not a directory")
            else:
                self._make_parent(target)
            self._lock_or_fail(target)
            self._check_target(target)
        else:
            target = self._pick_default(_checked_dir_path(self._default, "results directory"))
        self.target = target
        self.path = self._make_tmp()
        if self.update:
            self._seed()

    def _make_parent(self, target: Path) -> None:
        missing = []
        p = target.parent
        while not os.path.lexists(p) and p.parent != p:
            missing.append(p)
            p = p.parent
        for d in reversed(missing):
            try:
                os.mkdir(d, 0o777)
            except FileExistsError:
                continue
            except (OSError, ValueError) as e:
                raise _fs_error(target, e, "create the results directory") from None
            self._made.append(d)
        if not target.parent.is_dir():
            raise ResultsDirError(f"{_show(target)}: cannot create the results directory ({_show(target.parent)} "
                                  f"is not a directory)")

    def _lock_for(self, target: Path) -> int | None:
        lock = _Lock(target.parent / f".{_stem(target.name)}.lock")
        try:
            holder = lock.try_acquire()
        except (OSError, ValueError) as e:
            raise _fs_error(target, e, "create the results directory") from None
        if holder is None:
            self._lock = lock
            self._clean_stale(target)  # before anything looks at target: this may put a run back
        return holder

    def _lock_or_fail(self, target: Path) -> None:
        holder = self._lock_for(target)
        if holder is not None:
            raise self._busy(target, holder)

    def _busy(self, target: Path, holder: int) -> ResultsDirError:
        who = f"pid {holder}" if holder else "pid unknown"
        hint = "try again when it has finished" if self.update else "try again or choose another --out"
        return ResultsDirError(f"{_show(target)}: is being written by another se3ocp run ({who}); {hint}")

    def _check_target(self, target: Path) -> None:
        if self.update:
            if not target.is_dir():
                raise ResultsDirError(f"{_show(target)}: not a directory")
            return
        if os.path.lexists(target) and not target.is_dir():
            raise ResultsDirError(f"{_show(target)}: exists and is not a directory")
        if _occupied(target):
            if not self.force:
                raise ResultsDirError(f"{_show(target)}: results directory already holds files; pass --force to "
                                      f"overwrite, or choose another --out")
            self._check_replaceable(target)

    @staticmethod
    def _check_replaceable(target: Path) -> None:
        if _inside_cwd_chain(target):
            raise ResultsDirError(f"{_show(target)}: is the working directory or one of its parents; --force "
                                  f"replaces the whole directory, so choose another --out")
        names = set(_entries(target))
        if not names & set(RESULTS_MARKERS):
            raise ResultsDirError(f"{_show(target)}: holds files but is not a results directory (no "
                                  f"{' or '.join(RESULTS_MARKERS[:2])}); --force replaces only results "
                                  f"directories, so choose another --out")

    def _pick_default(self, base: Path) -> Path:
        self._make_parent(base)
        for i in range(MAX_SIBLINGS + 1):
            cand = base if i == 0 else base.with_name(f"{base.name}.{i}")
            if i and len(cand.name.encode()) > _name_max(cand.parent):
                raise ResultsDirError(f"{_show(cand)}: name too long for a numbered results directory")
            replace = i == 0 and self.force
            if _occupied(cand) and not replace:
                continue
            holder = self._lock_for(cand)
            if holder is not None:
                if replace:  # --force names this directory: do not silently go elsewhere
                    raise self._busy(cand, holder)
                continue
            if _occupied(cand) and not replace:  # filled while we were locking it
                self._release()
                continue
            self._check_target(cand)
            return cand
        raise ResultsDirError(f"{_show(base)}: {MAX_SIBLINGS} numbered results directories exist; "
                              f"remove some or pass --out")

    @staticmethod
    def _clean_stale(t: Path) -> None:
        """Under the lock of ``t``: remove the temporaries of earlier runs on it that were
        killed, after putting back a previous run a crash left aside (see the module docstring)."""
        rx = re.compile(rf"\.{re.escape(_stem(t.name))}\.(tmp|old)-[0-9]+-[0-9a-f]{{8}}")
        for name in sorted(_entries(t.parent), key=lambda n: ".old-" not in n):  # .old- first
            m = rx.fullmatch(name)
            if not m:
                continue
            p = t.parent / name
            if m.group(1) == "old" and not os.path.lexists(t):
                try:  # a crash between the two renames of a swap: put the previous run back
                    os.rename(p, t)
                except OSError:
                    pass  # keep it rather than delete the only copy of a run
                continue
            shutil.rmtree(p, ignore_errors=True)

    def _hidden(self, kind: str) -> Path:
        return self.target.parent / f".{_stem(self.target.name)}.{kind}-{os.getpid()}-{secrets.token_hex(4)}"

    def _make_tmp(self) -> Path:
        while True:
            p = self._hidden("tmp")
            try:
                os.mkdir(p, 0o777)  # mode 0777 minus the umask, like any new directory
                return p
            except FileExistsError:
                continue
            except (OSError, ValueError) as e:
                raise _fs_error(self.target, e, "create the results directory") from None

    def _seed(self) -> None:
        """An update starts from a copy of the existing directory (reflinked where the file
        system can); files are then replaced in the copy, never changed in the original."""
        try:
            shutil.copytree(self.target, self.path, symlinks=True, dirs_exist_ok=True)
        except shutil.Error as e:  # a list of (source, destination, reason), one per file
            why = e.args[0][0][2] if e.args and e.args[0] else "copy failed"
            raise ResultsDirError(f"{_show(self.target)}: cannot copy the results directory ({why})") from None
        except OSError as e:
            raise _fs_error(self.target, e, "copy the results directory") from None

    # ---------------------------------------------------------------- leaving
    def commit(self, *, incomplete: str | None = None) -> Path:
        """Put the written directory in place of ``target`` (see the module docstring); with
        ``incomplete``, first add the file ``INCOMPLETE`` holding that reason.  Returns ``target``."""
        if self.state != "open":
            raise RuntimeError(f"commit of a results transaction that is {self.state}")
        old = None
        try:
            if incomplete is not None:
                atomic_write_bytes(self.path / INCOMPLETE_MARKER, (" ".join(str(incomplete).split()) + "\n").encode())
            _fsync_tree(self.path)
            with _signals_deferred():
                old = self._swap()
                self.state = "committed"
        except OSError as e:
            self.abort()
            raise _fs_error(self.target, e, "commit the results directory") from None
        except BaseException:
            if self.state != "committed":
                self.abort()
            raise
        finally:
            if self.state == "committed":
                self._release()
                ResultsTransaction.committed.append((self.target, incomplete))
        if old is not None:  # the previous run, now under the temporary name: removed before a Ctrl-C acts
            with _signals_deferred():
                shutil.rmtree(old, ignore_errors=True)
        return self.target

    def _swap(self) -> Path | None:
        t, new = self.target, self.path
        exists = os.path.lexists(t)
        if self.update and not (exists and t.is_dir()):
            raise ResultsDirError(f"{_show(t)}: was removed during the run; nothing was written")
        if not exists:
            try:
                os.rename(new, t)  # atomic; also onto an empty directory created meanwhile
            except OSError as e:
                if e.errno in (errno.EEXIST, errno.ENOTEMPTY, errno.ENOTDIR, errno.EISDIR):
                    raise ResultsDirError(f"{_show(t)}: was created by another program during the run; "
                                          f"nothing was written") from None
                raise
            _fsync_dir(t.parent)
            return None
        if not t.is_dir():
            raise ResultsDirError(f"{_show(t)}: was replaced by a file during the run; nothing was written")
        if not (self.force or self.update) and _entries(t):
            raise ResultsDirError(f"{_show(t)}: was filled by another program during the run; nothing was written")
        if _exchange(new, t):
            old = new  # the temporary name now holds the previous run
        else:
            old = self._hidden("old")
            os.rename(t, old)
            try:
                os.rename(new, t)
            except BaseException:
                os.rename(old, t)
                raise
        _fsync_dir(t.parent)
        return old

    def abort(self) -> None:
        """Delete the temporary directory; ``target`` is left as it was."""
        if self.state in ("committed", "aborted"):
            return
        self.state = "aborted"
        self._cleanup()

    def _cleanup(self) -> None:
        if self.path is not None:
            shutil.rmtree(self.path, ignore_errors=True)
        self._release()
        for d in reversed(self._made):  # parents this transaction created, if still empty
            with contextlib.suppress(OSError):
                os.rmdir(d)
        self._made = []

    def _release(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self.state != "open":
            self._release()
            return False
        if exc_type is None:
            self.commit()
            return False
        self.abort()
        if isinstance(exc, (ResultsDirError, ConfigError)) and self.path is not None and self.target is not None:
            # a message about a file of the private copy names the file the user knows
            exc.args = tuple(str(a).replace(str(self.path), str(self.target)) for a in exc.args)
            if isinstance(exc, ConfigError):
                exc.source = str(exc.source).replace(str(self.path), str(self.target))
        return False


def results_transaction(out: str | os.PathLike | None, default: str | os.PathLike | None = None,
                        force: bool = False) -> ResultsTransaction:
    """A transaction on the results directory of a run (policy of ``--out``/``--force``):

    * ``out`` given: that directory.  If it holds files, only with ``force``, and only if it
      is a results directory (:data:`RESULTS_MARKERS`); then the new run replaces it whole.
    * ``out`` None: ``default``; if it holds files (and not ``force``) or another run is
      writing it, the first free numbered sibling ``default.1``, ``default.2``, ...
    """
    return ResultsTransaction(out, default, force)


def results_update(directory: str | os.PathLike) -> ResultsTransaction:
    """A transaction that changes files of an existing complete results directory (``plot``):
    ``tx.path`` starts as a copy of it; the commit replaces it whole, and fails with
    ResultsDirError (writing nothing) if the directory was removed meanwhile."""
    return ResultsTransaction(directory, None, True, update=True)
