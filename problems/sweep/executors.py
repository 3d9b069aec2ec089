"""Where tasks run: in-process, on a local process pool or on a Dask cluster, all behind one
small interface, :class:`Executor`, so that sweeps and Monte Carlo runs share them.

A task is ``fn(arg)`` with ``fn`` a module-level function and ``arg`` plain data (both are
pickled for a pool or a cluster).  The driver submits tasks, waits for the first to complete
(also while it keeps submitting new ones, as continuation chains do) and shuts the executor
down, cancelling what is still running on Ctrl-C::

    ex = make_executor(workers, scheduler)
    pending = {ex.submit(solve_point, task): task for task in tasks}
    try:
        while pending:
            for fut in ex.wait_first(pending):
                handle(pending.pop(fut), fut.result())
    except KeyboardInterrupt:
        ex.shutdown(cancel=True)
        raise
    ex.shutdown()
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
from typing import Any, Callable, Iterable, Protocol

from ..schema import ConfigError


class Executor(Protocol):
    """What the sweep driver (and the Monte Carlo runs) need of an executor."""

    #: "serial" (in-process), "local" (process pool) or "dask" (a cluster)
    kind: str
    #: worker processes (1 in-process; None on a cluster: the cluster's)
    workers: int | None

    def submit(self, fn: Callable[[Any], Any], arg: Any) -> cf.Future:
        """Start ``fn(arg)``; its Future completes with the result, or with the exception of a
        task (or worker) that failed."""

    def wait_first(self, pending: Iterable[cf.Future]) -> set[cf.Future]:
        """Block until at least one of ``pending`` is done; return those that are."""

    def shutdown(self, cancel: bool = False) -> None:
        """Release the workers (idempotent).  ``cancel``: do not wait for running tasks, stop them."""


def _first_done(pending: Iterable[cf.Future]) -> set[cf.Future]:
    return cf.wait(list(pending), return_when=cf.FIRST_COMPLETED).done


def _ignore_sigint():  # pool workers: Ctrl-C is the driver's to handle
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class SerialExecutor:
    """In-process execution (``workers=1``): a task runs when it is submitted."""

    kind = "serial"
    workers = 1

    def submit(self, fn, arg) -> cf.Future:
        f = cf.Future()
        try:
            f.set_result(fn(arg))
        except Exception as exc:
            f.set_exception(exc)
        return f

    def wait_first(self, pending) -> set[cf.Future]:
        return _first_done(pending)

    def shutdown(self, cancel: bool = False) -> None:
        pass


class PoolExecutor:
    """A local ProcessPoolExecutor (forkserver context where available, else spawn: CasADi is not
    fork-safe once threads exist); its workers ignore Ctrl-C, which is the driver's to handle."""

    kind = "local"

    def __init__(self, workers: int):
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
        self.workers = workers
        self.pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_ignore_sigint)
        self._closed = False

    def submit(self, fn, arg) -> cf.Future:
        return self.pool.submit(fn, arg)

    def wait_first(self, pending) -> set[cf.Future]:
        return _first_done(pending)

    def shutdown(self, cancel: bool = False) -> None:
        if self._closed:
            return
        self._closed = True
        if cancel:  # do not wait for running solves: stop the workers
            procs = list((getattr(self.pool, "_processes", None) or {}).values())
            self.pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()
            for p in procs:
                p.join(5)
            # then let the executor's manager thread see the dead workers and release its queues' semaphores: a
            # process that exits with them held makes multiprocessing's resource tracker warn of "leaked semaphore
            # objects" on stderr after the CLI's last line (seen on a loaded machine in test_cli_ctrl_c_writes_finished_rows)
            self.pool.shutdown(wait=True)
        else:
            self.pool.shutdown(wait=True)


class DaskExecutor:
    """Tasks submitted to an existing dask.distributed cluster (``Client(address)``; its workers
    need this package installed).  A missing Dask or an unreachable scheduler is a ConfigError
    naming ``--scheduler``."""

    kind = "dask"
    workers = None

    def __init__(self, address: str, timeout: float = 10.0):
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError("--scheduler", address, "dask.distributed is not installed; "
                                                      "pip install 'dask[distributed]' (or se3ocp[sweep])") from None
        try:
            self.client = Client(address, timeout=timeout, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as e:
            raise ConfigError("--scheduler", address, f"cannot connect to a Dask scheduler there ({e})") from None
        self._futures: dict = {}
        self._closed = False

    def submit(self, fn, arg) -> cf.Future:
        """A concurrent.futures.Future completed from the Dask future's done callback,
        so that the driver waits on every executor the same way (cf.wait)."""
        dfut = self.client.submit(fn, arg, pure=False)
        fut = cf.Future()

        def done(d):
            try:
                fut.set_result(d.result())
            except BaseException as exc:  # noqa: BLE001 - handed to the driver, which records it
                fut.set_exception(exc)

        dfut.add_done_callback(done)
        self._futures[fut] = dfut
        return fut

    def wait_first(self, pending) -> set[cf.Future]:
        done = _first_done(pending)
        for f in done:
            self._futures.pop(f, None)
        return done

    def shutdown(self, cancel: bool = False) -> None:
        if self._closed:
            return
        self._closed = True
        if cancel and self._futures:
            self.client.cancel(list(self._futures.values()))
        self.client.close()


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def make_executor(workers: int | None = None, scheduler: str | None = None) -> Executor:
    """A DaskExecutor on ``scheduler`` if given, else in-process for workers == 1, else a local
    pool (default: one worker per available core)."""
    if scheduler:
        return DaskExecutor(scheduler)
    workers = workers or default_workers()
    return SerialExecutor() if workers == 1 else PoolExecutor(workers)
