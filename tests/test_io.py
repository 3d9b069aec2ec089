"""Atomic result files (problems/io.py): complete or absent, ordinary modes, one-line errors."""
from __future__ import annotations

import errno
import os

import numpy as np
import pytest
import yaml

from se3ocp.problems import io as rio
from se3ocp.problems.io import (ResultsDirError, atomic_output, atomic_write_bytes, write_json, write_npz,
                                write_yaml)
from se3ocp.problems.schema import yaml_load


def error(fn, *args, **kw) -> str:
    with pytest.raises(ResultsDirError) as ei:
        fn(*args, **kw)
    msg = str(ei.value)
    assert "\n" not in msg and msg, msg
    return msg


def test_disk_full_is_one_line_and_leaves_no_temporary(tmp_path, monkeypatch):
    (tmp_path / "direct.npz").write_bytes(b"old")

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(rio.os, "write", full)
    msg = error(write_npz, tmp_path / "direct.npz", {"x": np.zeros(10)})
    monkeypatch.undo()
    assert msg == f"{tmp_path}/direct.npz: cannot write (No space left on device)"
    assert os.listdir(tmp_path) == ["direct.npz"] and (tmp_path / "direct.npz").read_bytes() == b"old"


@pytest.mark.parametrize("umask,fmode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_file_modes_follow_the_umask(tmp_path, umask, fmode):
    old = os.umask(umask)
    try:
        write_json(tmp_path / "summary.json", {})
        write_yaml(tmp_path / "config.resolved.yaml", {"a": 1})
        write_npz(tmp_path / "direct.npz", {"x": np.zeros(1)})
        with atomic_output(tmp_path / "maneuver.gif") as tmp:
            tmp.write_bytes(b"GIF89a")
    finally:
        os.umask(old)
    assert len(os.listdir(tmp_path)) == 4
    for p in tmp_path.iterdir():
        assert os.stat(p).st_mode & 0o777 == fmode, p


def test_interrupted_animation_leaves_no_temporary_file(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_output(tmp_path / "maneuver.gif") as tmp:
            assert tmp.suffix == ".gif" and tmp.parent == tmp_path
            tmp.write_bytes(b"GIF89a half")
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == []
    with atomic_output(tmp_path / "maneuver.gif") as tmp:
        tmp.write_bytes(b"GIF89a whole")
    assert os.listdir(tmp_path) == ["maneuver.gif"] and (tmp_path / "maneuver.gif").read_bytes() == b"GIF89a whole"


# ----------------------------------------------------------------------------- files
def test_write_yaml_reads_back_with_both_yaml_versions(tmp_path):
    obj = {"name": "yes", "tol": 1e-8, "N": 100, "code": "0o17", "flag": True, "none": None}
    write_yaml(tmp_path / "c.yaml", obj)
    text = (tmp_path / "c.yaml").read_text()
    assert yaml_load(text) == obj and yaml.safe_load(text) == obj


def test_atomic_write_into_a_missing_directory_does_not_create_it(tmp_path):
    msg = error(atomic_write_bytes, tmp_path / "gone" / "summary.json", b"{}")
    assert msg == f"{tmp_path}/gone/summary.json: cannot write (No such file or directory)"
    assert os.listdir(tmp_path) == []
