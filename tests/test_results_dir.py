"""Results directories as transactions (problems/results_dir.py): a results directory is always one
complete run, the previous complete run, or absent -- after exceptions, Ctrl-C, SIGKILL,
concurrent runs, full or read-only disks -- and every fault is one ResultsDirError line."""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from se3ocp.problems import results_dir as rdir
from se3ocp.problems.io import ResultsDirError, atomic_output, atomic_write_bytes, write_json, write_npz, write_yaml
from se3ocp.problems.results_dir import INCOMPLETE_MARKER, results_transaction, results_update

import failure_cases as ft
from support import CONFIGS

#: how long a helper process may take to reach the point where the test acts on it (a bound
#: against hanging, not a timing assertion)
WAIT_S = 120


@pytest.fixture(params=["exchange", "two_renames"])
def swap(request, monkeypatch):
    """Run with the atomic exchange (Linux renameat2) and with the two-rename fallback."""
    if request.param == "exchange":
        if rdir._renameat2 is None:
            pytest.skip("renameat2 is not available here")
    else:
        monkeypatch.setattr(rdir, "_renameat2", None)
    return request.param


def old_run(d: Path, files=("summary.json", "indirect.npz", "fig_maneuver.png", "maneuver.gif")) -> dict:
    """A complete earlier run in ``d``; returns {name: bytes}."""
    d.mkdir(parents=True)
    content = {}
    for name in files:
        data = f"old run: {name}\n".encode()
        (d / name).write_bytes(data)
        content[name] = data
    return content


def snapshot(d: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def hidden(parent: Path) -> list[str]:
    return sorted(n for n in os.listdir(parent) if n.startswith("."))


def error(fn, *args, **kw) -> str:
    with pytest.raises(ResultsDirError) as ei:
        fn(*args, **kw)
    msg = str(ei.value)
    assert "\n" not in msg and msg, msg
    return msg


def enter(*args, **kw):
    with results_transaction(*args, **kw) as tx:
        return tx


# ----------------------------------------------------------------------------- transactions
def test_directory_appears_whole_at_commit(tmp_path):
    out = tmp_path / "run"
    with results_transaction(out) as tx:
        assert tx.target == out and not out.exists()
        assert tx.path.parent == tmp_path and tx.path.name.startswith(".run.tmp-")
        write_json(tx.path / "summary.json", {"converged": True})
        write_npz(tx.path / "direct.npz", {"x": np.arange(3)})
        assert not out.exists()  # readers see nothing until the commit
        assert hidden(tmp_path) == sorted([".run.lock", tx.path.name])
    assert sorted(os.listdir(out)) == ["direct.npz", "summary.json"]
    assert json.loads((out / "summary.json").read_text()) == {"converged": True}
    assert os.listdir(tmp_path) == ["run"]  # no lock file, no temporary directory


@pytest.mark.parametrize("exc", [RuntimeError("solver crashed"), KeyboardInterrupt()], ids=["error", "ctrl_c"])
def test_exception_leaves_previous_run_untouched(tmp_path, exc, swap):
    out = tmp_path / "run"
    before = old_run(out)
    with pytest.raises(type(exc)):
        with results_transaction(out, force=True) as tx:
            write_json(tx.path / "summary.json", {"new": True})
            raise exc
    assert snapshot(out) == before
    assert os.listdir(tmp_path) == ["run"]
    assert tx.state == "aborted"


def test_exception_in_first_run_leaves_nothing(tmp_path):
    out = tmp_path / "deep" / "er" / "run"
    with pytest.raises(RuntimeError):
        with results_transaction(out) as tx:
            write_json(tx.path / "summary.json", {})
            raise RuntimeError
    assert os.listdir(tmp_path) == []  # also the parents this run created are gone


def test_force_replaces_the_whole_directory(tmp_path, swap):
    out = tmp_path / "run"
    old_run(out)
    with results_transaction(out, force=True) as tx:
        write_json(tx.path / "summary.json", {"run": 2})
        write_npz(tx.path / "direct.npz", {"x": np.zeros(2)})
    # indirect.npz, the figure and the GIF of the earlier run are gone with it
    assert sorted(os.listdir(out)) == ["direct.npz", "summary.json"]
    assert os.listdir(tmp_path) == ["run"]


def test_commit_into_an_existing_empty_directory(tmp_path, swap):
    out = tmp_path / "run"
    out.mkdir()
    with results_transaction(out) as tx:  # empty: no --force needed
        write_json(tx.path / "summary.json", {})
    assert os.listdir(out) == ["summary.json"]


def test_incomplete_commit_is_marked(tmp_path):
    out = tmp_path / "sweep"
    with pytest.raises(KeyboardInterrupt):
        with results_transaction(out) as tx:
            write_json(tx.path / "summary.json", {"interrupted": True})
            tx.commit(incomplete="interrupted (Ctrl-C)\nafter 3 of 8 tasks")
            raise KeyboardInterrupt
    assert sorted(os.listdir(out)) == [INCOMPLETE_MARKER, "summary.json"]
    assert (out / INCOMPLETE_MARKER).read_text() == "interrupted (Ctrl-C) after 3 of 8 tasks\n"
    assert tx.state == "committed" and os.listdir(tmp_path) == ["sweep"]


def test_ctrl_c_during_the_swap_waits_until_it_is_done(tmp_path, monkeypatch, swap):
    """SIGINT arriving between the renames is delivered after them: the new run is in place."""
    out = tmp_path / "run"
    old_run(out)
    real_rename = os.rename

    def rename_then_sigint(a, b):
        real_rename(a, b)
        os.kill(os.getpid(), signal.SIGINT)

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    monkeypatch.setattr(rdir.os, "rename", rename_then_sigint)
    if swap == "exchange":
        real_exchange = rdir._exchange
        monkeypatch.setattr(rdir, "_exchange", lambda a, b: (real_exchange(a, b), os.kill(os.getpid(), signal.SIGINT))[0])
    try:
        with pytest.raises(KeyboardInterrupt):
            with results_transaction(out, force=True) as tx:
                write_json(tx.path / "summary.json", {"run": 2})
    finally:
        signal.signal(signal.SIGINT, previous)
    monkeypatch.undo()
    assert tx.state == "committed" and snapshot(out) == {"summary.json": b'{\n  "run": 2\n}\n'}


def test_crash_between_the_two_renames_is_repaired_by_the_next_run(tmp_path):
    """The fallback swap killed after 'NAME -> .NAME.old-*': the next transaction puts it back."""
    before = old_run(tmp_path / ".run.old-999999-0123abcd")
    (tmp_path / ".run.tmp-999999-4567cdef").mkdir()  # the unfinished new run
    with results_transaction(None, tmp_path / "run") as tx:
        write_json(tx.path / "summary.json", {"run": 2})
    assert tx.target == tmp_path / "run.1"  # the restored previous run keeps its name
    assert snapshot(tmp_path / "run") == before
    assert sorted(os.listdir(tmp_path)) == ["run", "run.1"]


# ----------------------------------------------------------------------------- policy
def test_out_with_files_needs_force(tmp_path):
    out = tmp_path / "run"
    before = old_run(out)
    assert error(enter, out) == f"{out}: results directory already holds files; pass --force to overwrite, or choose another --out"
    assert snapshot(out) == before and os.listdir(tmp_path) == ["run"]


def test_out_is_a_file(tmp_path):
    (tmp_path / "run").write_text("x")
    assert error(enter, tmp_path / "run", force=True) == f"{tmp_path / 'run'}: exists and is not a directory"


def test_force_refuses_directories_that_are_not_results(tmp_path, monkeypatch):
    src = tmp_path / "src"
    src.mkdir()
    (src / "notes.txt").write_text("mine")
    msg = error(enter, src, force=True)
    assert msg.startswith(f"{src}: holds files but is not a results directory") and "--force" in msg
    assert (src / "notes.txt").read_text() == "mine"
    work = tmp_path / "work"
    old_run(work)
    monkeypatch.chdir(work)
    for out in (".", "..", ""):
        error(enter, out, force=True)
    msg = error(enter, str(work), force=True)  # the working directory itself, even a results one
    assert "is the working directory or one of its parents" in msg
    assert sorted(os.listdir(work)) == sorted(["summary.json", "indirect.npz", "fig_maneuver.png", "maneuver.gif"])


def test_default_goes_to_a_fresh_numbered_sibling(tmp_path):
    base = tmp_path / "results" / "e3"
    targets = []
    for i in range(3):
        with results_transaction(None, base) as tx:
            write_json(tx.path / "summary.json", {"run": i})
        targets.append(tx.target.name)
    assert targets == ["e3", "e3.1", "e3.2"]
    with results_transaction(None, base, force=True) as tx:  # --force without --out: the default itself
        write_json(tx.path / "summary.json", {"run": 3})
    assert tx.target == base and json.loads((base / "summary.json").read_text()) == {"run": 3}


def test_long_names_fit_the_hidden_names(tmp_path):
    out = tmp_path / ("n" * 250)
    with results_transaction(out) as tx:
        assert len(tx.path.name) < 255
        write_json(tx.path / "summary.json", {})
    assert os.listdir(out) == ["summary.json"] and os.listdir(tmp_path) == [out.name]


@pytest.mark.parametrize("out,expected", [
    ("", "--out: expected a directory name, got an empty string"),
    (".", ".: expected the name of a results directory, not '.', '..' or '/'"),
    ("..", "..: expected the name of a results directory, not '.', '..' or '/'"),
    ("/", "/: expected the name of a results directory, not '.', '..' or '/'"),
    ("a\0b", "'a\\x00b': a path cannot contain a NUL byte"),
    ("x" * 400, "x" * 400 + ": name too long (400 bytes; the file system allows 255)"),
])
def test_names_that_cannot_be_a_results_directory(out, expected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert error(enter, out) == expected
    assert os.listdir(tmp_path) == []


def test_out_under_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    msg = error(enter, tmp_path / "f" / "sub" / "run")
    assert msg == f"{tmp_path}/f/sub/run: cannot create the results directory (Not a directory; a part of the path is a file)"


def test_directory_created_by_someone_else_during_the_run(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(ResultsDirError) as ei:
        with results_transaction(out) as tx:
            write_json(tx.path / "summary.json", {})
            old_run(out, files=("theirs.txt",))
    assert str(ei.value) == f"{out}: was filled by another program during the run; nothing was written"
    assert os.listdir(out) == ["theirs.txt"] and os.listdir(tmp_path) == ["run"]


# ----------------------------------------------------------------------------- concurrency
def test_second_transaction_on_one_target_fails_fast(tmp_path):
    out = tmp_path / "run"
    with results_transaction(out) as tx:
        write_json(tx.path / "summary.json", {"winner": True})
        msg = error(enter, out, force=True)
        assert msg == (f"{out}: is being written by another se3ocp run (pid {os.getpid()}); "
                       f"try again or choose another --out")
        with results_transaction(None, out) as other:  # the default policy moves aside instead
            write_json(other.path / "summary.json", {"winner": False})
        assert other.target == tmp_path / "run.1"
    assert json.loads((out / "summary.json").read_text()) == {"winner": True}
    assert sorted(os.listdir(tmp_path)) == ["run", "run.1"]


def test_lock_on_a_file_removed_by_its_previous_holder_is_taken_again(tmp_path, monkeypatch):
    """B opened the lock file, A released the lock (removing the file), B's flock succeeds on
    the removed file: B must notice and lock the file now under the name, or a third run C
    could lock that one and run alongside B."""
    path = tmp_path / ".run.lock"
    a = rdir._Lock(path)
    assert a.try_acquire() is None
    stale = os.open(path, os.O_RDWR)  # B's open, before A releases
    a.release()
    c = rdir._Lock(path)
    assert c.try_acquire() is None  # C: a new file under the name
    opened = []
    real_open = os.open

    def b_open(p, flags, mode=0o777):
        opened.append(p)
        return stale if len(opened) == 1 else real_open(p, flags, mode)

    monkeypatch.setattr(rdir.os, "open", b_open)
    b = rdir._Lock(path)
    assert b.try_acquire() == os.getpid()  # B retried on C's file and found it held (by C's pid)
    assert len(opened) == 2
    monkeypatch.undo()
    c.release()
    assert not path.exists()


# SIGINT may be ignored in the test process and inherited so (a job started with `&` by a shell without job
# control): the holder and the in-process test restore Python's default handler, so that they test the
# transaction and not the disposition they were started with
HOLDER = textwrap.dedent("""
    import signal, sys, time
    signal.signal(signal.SIGINT, signal.default_int_handler)
    from pathlib import Path
    from se3ocp.problems.io import write_json
    from se3ocp.problems.results_dir import results_transaction
    out, ready, mode = sys.argv[1:4]
    with results_transaction(out, force=True) as tx:
        for i in range(10**9):
            write_json(tx.path / f"part{i % 50}.json", {"i": i, "pad": "x" * 4000})
            if i == 60:
                Path(ready).write_text(str(tx.path))
            if mode == "sleep" and i > 60:
                time.sleep(0.05)
""")


def start_holder(tmp_path, out: Path, mode="write"):
    (tmp_path.parent / f"{tmp_path.name}-ctl").mkdir(exist_ok=True)
    ready = tmp_path.parent / f"{tmp_path.name}-ctl" / f"ready-{time.monotonic_ns()}"
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(out), str(ready), mode], stderr=subprocess.PIPE)
    deadline = time.monotonic() + WAIT_S
    while not ready.exists():
        if p.poll() is not None or time.monotonic() > deadline:
            p.kill()
            pytest.fail(f"helper process did not start writing: {p.communicate()[1].decode()[-2000:]}")
        time.sleep(0.02)
    return p, Path(ready.read_text())


def test_concurrent_process_on_one_target(tmp_path):
    out = tmp_path / "results" / "run"
    p, tmp = start_holder(tmp_path, out, mode="sleep")
    try:
        assert error(enter, out, force=True) == (f"{out}: is being written by another se3ocp run (pid {p.pid}); "
                                                 f"try again or choose another --out")
        with results_transaction(None, out) as tx:
            write_json(tx.path / "summary.json", {})
        assert tx.target.name == "run.1"
    finally:
        p.kill()
        p.wait()
    assert not out.exists() and tmp.is_dir()  # the killed run left its temporary directory
    with results_transaction(out) as tx:  # the lock died with it; the stale directory is removed
        write_json(tx.path / "summary.json", {"after": True})
    assert sorted(os.listdir(out.parent)) == ["run", "run.1"]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["SIGKILL", "SIGINT"])
def test_killed_mid_write_leaves_the_previous_run(tmp_path, sig):
    out = tmp_path / "run"
    before = old_run(out)
    p, tmp = start_holder(tmp_path, out)
    p.send_signal(sig)
    err = p.communicate(timeout=WAIT_S)[1].decode()
    assert p.returncode != 0
    assert snapshot(out) == before  # the previous complete run, untouched
    if sig == signal.SIGINT:  # Python unwinds: the temporary directory and the lock are removed
        assert "KeyboardInterrupt" in err and os.listdir(tmp_path) == ["run"]
    else:  # no unwinding: the temporary directory stays until the next run on this target
        assert tmp.is_dir() and len(os.listdir(tmp)) > 0
        with results_transaction(out, force=True) as tx:
            write_json(tx.path / "summary.json", {"run": 3})
        assert os.listdir(tmp_path) == ["run"] and os.listdir(out) == ["summary.json"]


# ----------------------------------------------------------------------------- file-system faults
def test_disk_full_is_one_line_and_writes_nothing(tmp_path, monkeypatch):
    out = tmp_path / "run"
    before = old_run(out)

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(ResultsDirError) as ei:
        with results_transaction(out, force=True) as tx:
            write_json(tx.path / "summary.json", {"ok": 1})
            monkeypatch.setattr(rdir.os, "write", full)
            write_npz(tx.path / "direct.npz", {"x": np.zeros(10)})
    monkeypatch.undo()
    # the message names the file in the results directory, not the hidden temporary one
    assert str(ei.value) == f"{out}/direct.npz: cannot write (No space left on device)"
    assert snapshot(out) == before and os.listdir(tmp_path) == ["run"]


def _mount_tmpfs(where: Path, options: str):
    if os.geteuid() != 0:
        return False
    where.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True)
    return r.returncode == 0


@pytest.fixture
def tiny_disk(tmp_path):
    d = tmp_path / "disk"
    if not _mount_tmpfs(d, "size=256k"):
        pytest.skip("cannot mount a tmpfs here (needs root and CAP_SYS_ADMIN)")
    yield d
    subprocess.run(["umount", "-l", str(d)], check=False)


def test_really_full_disk(tiny_disk):
    out = tiny_disk / "run"
    before = old_run(out)
    with pytest.raises(ResultsDirError) as ei:
        with results_transaction(out, force=True) as tx:
            write_npz(tx.path / "direct.npz", {"x": np.random.default_rng(0).random(200_000)})  # 1.6 MB
    assert str(ei.value) == f"{out}/direct.npz: cannot write (No space left on device)"
    assert snapshot(out) == before and os.listdir(tiny_disk) == ["run"]


def test_read_only_file_system(tmp_path):
    ro = tmp_path / "ro"
    if os.geteuid() == 0:
        if not _mount_tmpfs(ro, "size=64k"):
            pytest.skip("cannot mount a tmpfs here")
        subprocess.run(["mount", "-o", "remount,ro", str(ro)], check=True)
        expected = "Read-only file system"
    else:
        ro.mkdir()
        ro.chmod(0o555)
        expected = "Permission denied"
    try:
        assert error(enter, ro / "run") == f"{ro}/run: cannot create the results directory ({expected})"
        assert error(enter, None, ro / "results" / "run") == \
            f"{ro}/results/run: cannot create the results directory ({expected})"
        assert os.listdir(ro) == []
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", "-l", str(ro)], check=False)
        else:
            ro.chmod(0o755)


# ----------------------------------------------------------------------------- modes
@pytest.mark.parametrize("umask,dmode,fmode", [(0o022, 0o755, 0o644), (0o077, 0o700, 0o600), (0o002, 0o775, 0o664)])
def test_modes_follow_the_umask(tmp_path, umask, dmode, fmode):
    old = os.umask(umask)
    try:
        with results_transaction(None, tmp_path / "results" / "run") as tx:
            write_json(tx.path / "summary.json", {})
            write_yaml(tx.path / "config.resolved.yaml", {"a": 1})
            write_npz(tx.path / "direct.npz", {"x": np.zeros(1)})
            with atomic_output(tx.path / "maneuver.gif") as tmp:
                tmp.write_bytes(b"GIF89a")
            tx.commit(incomplete="test")
        atomic_write_bytes(tmp_path / "loose.txt", b"x")
    finally:
        os.umask(old)
    out = tmp_path / "results" / "run"
    assert os.stat(out).st_mode & 0o777 == dmode
    assert os.stat(tmp_path / "results").st_mode & 0o777 == dmode
    for p in [*out.iterdir(), tmp_path / "loose.txt"]:
        assert os.stat(p).st_mode & 0o777 == fmode, p


# ----------------------------------------------------------------------------- plot: updates
def test_update_changes_files_of_a_complete_directory(tmp_path, swap):
    d = tmp_path / "run"
    before = old_run(d)
    with results_update(d) as tx:
        assert snapshot(tx.path) == before  # starts from the existing run
        atomic_write_bytes(tx.path / "fig_maneuver.png", b"new figure")
        assert (d / "fig_maneuver.png").read_bytes() == before["fig_maneuver.png"]  # not yet visible
    assert snapshot(d) == dict(before, **{"fig_maneuver.png": b"new figure"})
    assert os.listdir(tmp_path) == ["run"]


def test_update_of_a_directory_removed_meanwhile_recreates_nothing(tmp_path):
    d = tmp_path / "run"
    old_run(d)
    with pytest.raises(ResultsDirError) as ei:
        with results_update(d) as tx:
            atomic_write_bytes(tx.path / "fig_maneuver.png", b"new figure")
            for p in d.iterdir():
                p.unlink()
            d.rmdir()
    assert str(ei.value) == f"{d}: was removed during the run; nothing was written"
    assert os.listdir(tmp_path) == []


def test_update_needs_an_existing_directory_and_the_lock(tmp_path):
    assert error(enter_update, tmp_path / "none") == f"{tmp_path}/none: not a directory"
    d = tmp_path / "run"
    old_run(d)
    with results_transaction(d, force=True):
        assert error(enter_update, d) == (f"{d}: is being written by another se3ocp run (pid {os.getpid()}); "
                                          f"try again when it has finished")
    assert os.listdir(tmp_path) == ["run"]


def enter_update(d):
    with results_update(d) as tx:
        return tx


# ----------------------------------------------------------------------------- through the CLI
@pytest.mark.slow
@pytest.mark.parametrize("force", [True, False], ids=["force", "no-force"])
def test_concurrent_runs_on_one_out(tmp_path, force):
    """Three solves of different N started together on one --out (three rounds): each exits 0, or 2
    with one line saying another run holds the directory (or, without --force, that it holds
    files); at least one succeeds; afterwards the directory is one complete run, file by file (its
    summary, config and every npz of one N), with no temporary or lock left."""
    e3 = CONFIGS / "e3_inclination_change.yaml"
    for rnd in range(3):
        work = tmp_path / f"round{rnd}"
        work.mkdir()
        procs = [subprocess.Popen([sys.executable, "-m", "se3ocp.problems.cli", "solve", str(e3), "--set",
                                   f"horizon.N={n}", "--out", "out", "--quiet", *(["--force"] if force else [])],
                                  cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                 for n in (30, 35, 40)]
        outs = [p.communicate(timeout=900) for p in procs]
        codes = [p.returncode for p in procs]
        for (o, e), rc in zip(outs, codes):
            assert "Traceback" not in e and rc in (0, 2), (rc, e)
            if rc == 2:
                assert len(e.strip().splitlines()) == 1
                assert "is being written by another se3ocp run" in e or (not force and "already holds files" in e), e
        assert 0 in codes
        d = work / "out"
        assert not ft.incomplete_files(d)
        assert sorted(p.name for p in work.iterdir()) == ["out"], "temporaries or a lock left"
        n = json.loads((d / "summary.json").read_text())["N"]
        assert n in (30, 35, 40) and codes[(30, 35, 40).index(n)] == 0
        assert yaml.safe_load((d / "config.resolved.yaml").read_text())["horizon"]["N"] == n
        with np.load(d / "direct.npz") as z:
            assert z["t"].shape == (n + 1,)
        for f in d.iterdir():  # figures and report of the same run: written after its start, before its end
            assert f.stat().st_mtime_ns >= (d / "config.resolved.yaml").stat().st_mtime_ns - 10**9, f.name
