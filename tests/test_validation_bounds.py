"""Validation does bounded work (issue 15, acceptance): however large a maneuver or sweep file
(within the size limits), validating it accepts or rejects it with one line after a bounded
amount of work -- counted, not timed."""
from __future__ import annotations

import copy
import time

import pytest
import yaml

from support import CONFIGS
from test_cli import run


#: raw IPOPT options with values IPOPT accepts: the largest valid 'options' block is made of such names
#: (keys are unique, so the trials are at most the number of IPOPT's options, a few hundred)
_IPOPT_VALID = {"tol": 1e-9, "acceptable_tol": 1e-6, "mu_init": 0.1, "mu_strategy": "adaptive", "max_cpu_time": 100.0,
                "bound_push": 0.01, "bound_frac": 0.01, "nlp_scaling_method": "none", "hessian_approximation": "exact",
                "linear_solver": "mumps", "print_level": 5, "acceptable_iter": 5, "constr_viol_tol": 1e-6,
                "dual_inf_tol": 1.0, "compl_inf_tol": 1e-4, "mu_oracle": "quality-function", "warm_start_init_point": "no",
                "fixed_variable_treatment": "make_parameter", "alpha_for_y": "primal", "recalc_y": "no"}
#: what one validation may cost at most, whatever the file: numbers checked, elementary rotations,
#: path constraints, raw-option trials (each an nlpsol of one variable)
WORK_BOUNDS = {"numbers": 2_000, "rotations": 2 * 64, "constraints": 64 + 1, "trials": 2 * len(_IPOPT_VALID)}


def _counted_parse(doc, monkeypatch):
    """parse_maneuver(doc) with its expensive steps counted: {'numbers', 'rotations', 'constraints', 'trials'}."""
    import casadi
    from se3ocp.problems import maneuvers, schema
    from se3ocp.transcription import options

    work = dict.fromkeys(WORK_BOUNDS, 0)

    def counting(name, fn):
        def wrapped(*a, **k):
            work[name] += 1
            return fn(*a, **k)
        return wrapped

    monkeypatch.setattr(schema.Validator, "number", counting("numbers", schema.Validator.number))
    for axis in ("rot_x", "rot_y", "rot_z"):
        monkeypatch.setattr(schema, axis, counting("rotations", getattr(schema, axis)))
    monkeypatch.setattr(maneuvers, "MinRadius", counting("constraints", maneuvers.MinRadius))
    monkeypatch.setattr(casadi, "nlpsol", counting("trials", casadi.nlpsol))
    options._check_raw_option.cache_clear()  # every trial counts
    try:
        maneuvers.parse_maneuver(doc, "big.yaml")
        outcome = "valid"
    except schema.ConfigError as e:
        assert str(e).startswith("big.yaml: ") and "\n" not in str(e)
        outcome = "rejected"
    finally:
        monkeypatch.undo()
    return outcome, work


from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(n_con=st.integers(0, 5_000), n_rot=st.integers(1, 5_000), n_opt=st.integers(0, len(_IPOPT_VALID)),
       bogus=st.integers(0, 3), N=st.sampled_from([10, 10**7, 10**7 + 1, 10**9, 10**30]),
       T=st.sampled_from([0.5, 1e-300, 1e300]))
def test_validation_work_is_bounded_whatever_the_sizes(n_con, n_rot, n_opt, bogus, N, T, monkeypatch):
    """The inputs that drive the work of validating a maneuver -- the number of path constraints,
    of elementary rotations in an attitude, of raw solver options, N and T -- can be made as large as
    a 1 MB file allows; validation either accepts the file or rejects it with one line, and the work
    it does (numbers checked, rotations multiplied, constraints built, option trials run) stays within
    WORK_BOUNDS.  Counted, not timed, so that it cannot flake on a loaded machine."""
    from se3ocp.problems.maneuvers import MAX_CONSTRAINTS, MAX_N
    from se3ocp.problems.schema import MAX_ROTATIONS

    from se3ocp.problems.schema import yaml_load

    doc = yaml_load((CONFIGS / "e3_inclination_change.yaml").read_text())
    doc["horizon"] = {"N": N, "T": T}
    doc["constraints"] = [{"kind": "max_angular_rate", "value": 100.0 + i} for i in range(n_con)]
    doc["initial"]["attitude"] = {"rotations": [["x", 1.0], ["z", -1.0]] * (n_rot // 2) + [["y", 0.0]] * (n_rot % 2)}
    opts = dict(list(_IPOPT_VALID.items())[:n_opt])
    opts.update({f"not_an_option_{i}": 1 for i in range(bogus)})
    doc["solver"] = {"direct": {"options": opts}}
    outcome, work = _counted_parse(doc, monkeypatch)
    for k, bound in WORK_BOUNDS.items():
        assert work[k] <= bound, (k, work[k], bound)
    fits = n_con <= MAX_CONSTRAINTS and n_rot <= MAX_ROTATIONS and not bogus and N <= MAX_N and 1e-150 <= T / N <= 1e150
    assert outcome == ("valid" if fits else "rejected"), (outcome, work)


def test_sweep_grid_validation_is_bounded_and_shows_progress(tmp_path):
    """A sweep file cannot ask for more than MAX_GRID_POINTS validations (one line, exit 2, before any
    work per point), and a grid at the limit reports its validation progress (load_sweep's callback:
    a call at most once a second and one at the end, with the count of points checked)."""
    from se3ocp.problems import sweep as sw

    base = CONFIGS / "e3_inclination_change.yaml"
    over = tmp_path / "over.yaml"
    over.write_text(f"base: {base}\naxes:\n  horizon.T: {{linspace: [0.45, 0.63, 101]}}\n"
                    f"  model.length: {{linspace: [0.05, 0.15, {sw.MAX_GRID_POINTS // 100 + 1}]}}\n")
    r = run("sweep", over, "--out", tmp_path / "o")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and f"at most {sw.MAX_GRID_POINTS} grid points" in r.stderr
    assert not (tmp_path / "o").exists()
    calls = []
    small = tmp_path / "small.yaml"
    small.write_text(f"base: {base}\naxes:\n  horizon.T: {{linspace: [0.45, 0.63, 7]}}\n")
    sw.load_sweep(small, progress=lambda done, total: calls.append((done, total)))
    assert calls[-1] == (7, 7) and all(d <= t == 7 for d, t in calls)


@pytest.mark.slow
def test_worst_files_validate_end_to_end(tmp_path):
    """End to end, once: the largest files of each kind that validation accepts or must read to
    reject (1 MB of values at the node limit, an alias bomb up to the limit, 64 constraints and 64
    rotations, every option of _IPOPT_VALID, N = 10^7) -> `se3ocp validate` accepts the valid one and
    rejects each other with one line naming the file.  The work is bounded by the counted test above;
    the time each takes is printed (the benchmarks measure speed, not the tests)."""
    from se3ocp.problems.schema import MAX_FILE_BYTES, MAX_NODES, yaml_load

    e3 = yaml_load((CONFIGS / "e3_inclination_change.yaml").read_text())
    files = {}
    doc = copy.deepcopy(e3)
    doc["horizon"]["N"] = 10**7
    doc["constraints"] = [{"kind": "max_angular_rate", "value": 100.0 + i} for i in range(64)]
    doc["initial"]["attitude"] = {"rotations": [["x", 1.0], ["z", -1.0]] * 32}
    doc["solver"] = {"direct": {"options": _IPOPT_VALID}}
    files["largest_valid"] = yaml.safe_dump(doc)
    files["node_limit"] = "name: x\nhorizon: {T: 1, N: 1}\nnoise: [" + ",".join(["0"] * (MAX_NODES - 10)) + "]\n"
    files["alias_bomb"] = "a0: &a0 [" + ",".join(["0"] * 100) + "]\n" + "".join(
        f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 10) + "]\n" for i in range(1, 6))
    files["one_megabyte"] = "name: x\n#" + "y" * (MAX_FILE_BYTES - 20) + "\n"
    for name, text in files.items():
        assert len(text.encode()) <= MAX_FILE_BYTES, name
        p = tmp_path / f"{name}.yaml"
        p.write_text(text)
        t0 = time.monotonic()
        r = run("validate", p)
        secs = time.monotonic() - t0
        if name == "largest_valid":
            assert r.returncode == 0 and r.stderr == "", r.stderr
        else:
            assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith(f"se3ocp: error: {p}: "), \
                (name, r.stderr)
        print(f"{name}: exit {r.returncode} in {secs:.2f} s")
