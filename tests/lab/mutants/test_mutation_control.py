"""``mutation.run_mutant``: a kill the rest of the suite finds (after the hint files) counts only
when that test passes on the unmutated copy. A test that fails there too (the copy lacks a file,
the test depends on the machine) is deselected and the run goes on; more than MAX_CONTROL such
tests make the record "invalid", never a kill. Also: the copy holds LICENSE (tests read it)."""
from __future__ import annotations

import pathlib

import pytest

from ldaspark.lab.mutants import mutation
from ldaspark.lab.mutants.mutant import Mutant

SUMMARY = "=========================== short test summary info ============================\n"


def _failed(node):
    return f"F\n{SUMMARY}FAILED {node} - assert False\n1 failed in 1.0s\n"


@pytest.fixture
def fake(monkeypatch, tmp_path):
    """run_mutant with the copy, the mutation and pytest replaced: ``fails[root kind]`` is the set
    of test ids that fail on the mutated copy ("mutant") and on the unmutated one ("control");
    every call is logged."""
    calls, fails = [], {"mutant": set(), "control": set()}

    def copy(dest, project=None):
        dest = pathlib.Path(dest)
        dest.mkdir(parents=True)
        (dest / "ldaspark").mkdir()
        return dest

    def apply(root, m):
        p = pathlib.Path(root) / "ldaspark" / "m.py"
        p.write_text("x = 1\n")
        return p

    def targets(m, root, hints_only=False, exclude=()):
        return ["tests/hint.py"] if hints_only else ["tests/hint.py", "tests/a.py::t_env", "tests/b.py::t_real"]

    def run(root, tgts, timeout, cache=None, python=None):
        kind = "control" if pathlib.Path(root).name == "control" else "mutant"
        calls.append((kind, list(tgts)))
        desel = {t.split("=", 1)[1] for t in tgts if t.startswith("--deselect=")}
        for t in tgts:
            if not t.startswith("--") and t in fails[kind] and t not in desel:
                return 1, _failed(t if "::" in t else t + "::t_h"), 0.1
        return 0, "1 passed\n", 0.1
    monkeypatch.setattr(mutation, "copy_project", copy)
    monkeypatch.setattr(mutation, "apply_mutant", apply)
    monkeypatch.setattr(mutation, "ordered_targets", targets)
    monkeypatch.setattr(mutation, "run_pytest", run)
    return calls, fails


M = Mutant("m1", "m.py", "x", "y", "a fault", "paths", ("tests/hint.py",))


def test_a_kill_confirmed_on_the_unmutated_copy_counts(fake):
    calls, fails = fake
    fails["mutant"] |= {"tests/b.py::t_real"}
    rec = mutation.run_mutant(M)
    assert rec["status"] == "killed" and rec["first_failing_test"] == "tests/b.py::t_real"
    assert ("control", ["tests/b.py::t_real"]) in calls


def test_a_test_failing_without_the_mutant_is_no_kill(fake):
    calls, fails = fake
    fails["mutant"] |= {"tests/a.py::t_env"}
    fails["control"] |= {"tests/a.py::t_env"}
    rec = mutation.run_mutant(M)
    # the environment's failure is deselected; the rest passes: the mutant survived
    assert rec["status"] == "survived" and not rec["killed"]
    assert "deselected" in rec["output_tail"] and "tests/a.py::t_env" in rec["output_tail"]
    # and behind it a real kill is still found
    fails["mutant"] |= {"tests/b.py::t_real"}
    rec = mutation.run_mutant(M)
    assert rec["status"] == "killed" and rec["first_failing_test"] == "tests/b.py::t_real"


def test_a_hint_kill_needs_no_control(fake):
    calls, fails = fake
    fails["mutant"] |= {"tests/hint.py"}
    rec = mutation.run_mutant(M)
    assert rec["status"] == "killed" and not any(k == "control" for k, _ in calls)


def test_too_many_environment_failures_make_the_record_invalid(fake, monkeypatch):
    calls, fails = fake
    monkeypatch.setattr(mutation, "MAX_CONTROL", 0)
    fails["mutant"] |= {"tests/a.py::t_env"}
    fails["control"] |= {"tests/a.py::t_env"}
    rec = mutation.run_mutant(M)
    assert rec["status"] == "invalid" and not rec["killed"] and "unmutated copy" in rec["output_tail"]


def test_the_copy_holds_what_the_tests_read(tmp_path):
    # tests/io/test_result_files.py::test_packaging reads LICENSE at the project root
    root = mutation.copy_project(tmp_path / "p")
    assert (root / "LICENSE").read_text().startswith("MIT License")
