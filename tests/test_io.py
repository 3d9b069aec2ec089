"""Files written atomically (problems/io.py): complete or absent, never half written; a fault is
one ResultsDirError line naming the file; names made safe for the file system."""
from __future__ import annotations

import os

import pytest
import yaml

from se3ocp.problems.io import ResultsDirError, atomic_output, atomic_write_bytes, safe_name, write_yaml
from se3ocp.problems.schema import yaml_load


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


def test_write_yaml_reads_back_with_both_yaml_versions(tmp_path):
    obj = {"name": "yes", "tol": 1e-8, "N": 100, "code": "0o17", "flag": True, "none": None}
    write_yaml(tmp_path / "c.yaml", obj)
    text = (tmp_path / "c.yaml").read_text()
    assert yaml_load(text) == obj and yaml.safe_load(text) == obj


def test_atomic_write_into_a_missing_directory_does_not_create_it(tmp_path):
    with pytest.raises(ResultsDirError) as e:
        atomic_write_bytes(tmp_path / "gone" / "summary.json", b"{}")
    assert str(e.value) == f"{tmp_path}/gone/summary.json: cannot write (No such file or directory)"
    assert os.listdir(tmp_path) == []


def test_safe_name_keeps_letters_digits_dash_underscore_dot():
    """One sanitizer for the default results directory (maneuver and sweep names) and the sweep
    figures' file names (axis names): anything else becomes '_', one for one."""
    assert safe_name("e3_inclination-change.v2") == "e3_inclination-change.v2"
    assert safe_name("T sweep/../x: y*") == "T_sweep_.._x__y_"
    assert safe_name("Ω é") == "Ω_é"  # letters of any script are kept (str.isalnum)
