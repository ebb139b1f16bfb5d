"""The mutation tools fed failing runs (issue 49, item 4): ``classify`` calls a mutant killed only
when pytest exits 1 (tests ran and failed) with a failing test named in its short summary; a
timeout, a collection error, a crash, a segfault and a run with no test are never kills. And the
reports count survivors and timeouts as surviving, never as killed."""
from __future__ import annotations

import json
import signal
import sys

import pytest

from ldaspark.lab.mutants import mutation, mutgen
from ldaspark.lab.mutants.mutation import classify, run_pytest

SUMMARY = "=========================== short test summary info ============================\n"

# pytest's own output for each kind of run (as `pytest -x -q -rfE` prints it), with its exit code
FAILED = ("F\n___ test_fail ___\n>       assert False\nE       assert False\n" + SUMMARY
          + "FAILED tests/test_a.py::test_fail - assert False\n!!!!!! stopping after 1 failures !!!!!!\n"
            "1 failed in 2.07s\n")
SETUP_ERROR = ("E\n___ ERROR at setup of test_x ___\n" + SUMMARY
               + "ERROR tests/test_a.py::test_x - RuntimeError: fixture\n1 error in 0.5s\n")
COLLECTION = ("___ ERROR collecting tests/test_b.py ___\nE   ModuleNotFoundError: No module named 'x'\n" + SUMMARY
              + "ERROR tests/test_b.py\n!!!!!!!!!!!!!!!!!!!! Interrupted: 1 error during collection !!!!!!!!!!!!!!!!!!!!\n"
                "1 error in 2.65s\n")
NO_TESTS = "\nno tests ran in 2.55s\n"
SEGFAULT = "Fatal Python error: Segmentation fault\n\nCurrent thread 0x7f (most recent call first):\n  File \"t.py\"\n"
# a test printing a verdict-shaped line and leaving by os._exit(1): no summary, no kill
FAKE_LINE = ".\nFAILED tests/test_a.py::test_fake - x\n"


@pytest.mark.parametrize("rc, output, status, first", [
    (1, FAILED, "killed", "tests/test_a.py::test_fail"),
    (1, SETUP_ERROR, "killed", "tests/test_a.py::test_x"),      # the mutant broke a fixture: tests failed
    (None, FAILED[:40], "timeout", None),                        # whatever it printed before the bound
    (None, "", "timeout", None),
    (2, COLLECTION, "invalid", None),                            # a collection error names a file, no test
    (1, COLLECTION, "invalid", None),                            # ... even with exit 1
    (5, NO_TESTS, "invalid", None),                              # no test ran
    (-signal.SIGSEGV, SEGFAULT, "invalid", None),                # a segfault
    (-signal.SIGSEGV, FAILED, "invalid", "tests/test_a.py::test_fail"),   # a crash after a failure
    (-signal.SIGKILL, "", "invalid", None),
    (1, FAKE_LINE, "invalid", None),                             # exit 1 but no summary: a crash
    (1, "", "invalid", None),
    (3, "INTERNALERROR> boom\n", "invalid", None),
    (4, "ERROR: file or directory not found: tests/x.py\n", "invalid", None),
    (0, FAILED, "survived", None),                               # the code says the tests passed
    (0, "1 passed in 0.1s\n", "survived", None),
])
def test_only_exit_1_with_a_failing_test_named_is_a_kill(rc, output, status, first):
    assert classify(rc, output) == (status, first)


def test_the_summary_is_read_after_its_header_only():
    # a test's own captured output shown in a failure report holds a FAILED-shaped line before the
    # summary: the test the summary names is the kill's
    out = ("----- Captured stdout call -----\nFAILED tests/test_z.py::test_other - printed\n" + SUMMARY
           + "FAILED tests/test_a.py::test_real - assert 0\n1 failed\n")
    assert classify(1, out) == ("killed", "tests/test_a.py::test_real")
    assert classify(1, out.replace(SUMMARY, "")) == ("invalid", None)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    root = tmp_path_factory.mktemp("proj")
    (root / "tests").mkdir()
    (root / "tests" / "test_a.py").write_text(
        "import os, signal\n\n\n"
        "def test_fail():\n    assert False\n\n\n"
        "def test_segfault():\n    os.kill(os.getpid(), signal.SIGSEGV)\n\n\n"
        "def test_exit():\n    print('FAILED tests/test_a.py::test_fake - x', flush=True)\n    os._exit(1)\n")
    (root / "tests" / "test_b.py").write_text("import no_such_module_anywhere\n\n\ndef test_x():\n    pass\n")
    (root / "tests" / "test_c.py").write_text("X = 1\n")
    (root / "tests" / "test_d.py").write_text("import time\n\n\ndef test_slow():\n    time.sleep(600)\n")
    return root


@pytest.mark.skipif(sys.platform == "win32", reason="signals")
@pytest.mark.parametrize("target, status", [("tests/test_a.py::test_segfault", "invalid"),
                                            ("tests/test_a.py::test_exit", "invalid")])
def test_real_crashes_are_not_kills(tiny, target, status):
    rc, out, _ = run_pytest(tiny, [target], timeout=300)
    assert rc != 0 and classify(rc, out) == (status, None)


@pytest.mark.exhaustive
@pytest.mark.parametrize("target, timeout, status, first", [
    ("tests/test_a.py::test_fail", 300, "killed", "tests/test_a.py::test_fail"),   # the control
    ("tests/test_b.py", 300, "invalid", None),
    ("tests/test_c.py", 300, "invalid", None),
    ("tests/test_d.py::test_slow", 5, "timeout", None),
])
def test_real_runs_of_each_kind(tiny, target, timeout, status, first):
    rc, out, _ = run_pytest(tiny, [target], timeout=timeout)
    assert classify(rc, out) == (status, first)


def test_a_mutant_run_that_times_out_is_recorded_as_a_timeout_not_a_kill(monkeypatch):
    m = mutation.by_id(mutation.QUICK[0])
    monkeypatch.setattr(mutation, "copy_project", lambda dest, project=None: __import__("pathlib").Path(dest))
    monkeypatch.setattr(mutation, "apply_mutant", lambda root, mutant: _touch(root))
    calls = []

    def fake_pytest(root, targets, timeout, cache=None):
        calls.append(targets)
        return None, FAILED, timeout              # a test had failed when the bound passed
    monkeypatch.setattr(mutation, "run_pytest", fake_pytest)
    rec = mutation.run_mutant(m, targets=["tests/test_a.py"], timeout=5)
    assert rec["status"] == "timeout" and rec["killed"] is False and rec["first_failing_test"] is None
    assert mutation.check_record(m.id, rec)
    monkeypatch.setattr(mutation, "run_pytest", lambda root, targets, timeout, cache=None: (1, FAILED, 1.0))
    assert mutation.run_mutant(m, targets=["tests/test_a.py"], timeout=5)["killed"] is True   # the control


def _touch(root):
    import pathlib
    p = pathlib.Path(root) / "ldaspark" / "x.py"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text("X = 1\n")
    return p


# --- the reports' counts ------------------------------------------------------------------------------
def test_the_generated_report_counts_timeouts_with_the_survivors(tmp_path):
    rel = "lab/claims/claims_general.py"
    ms = mutgen.generate(rel, check=False)[:9]
    statuses = ["killed", "killed", "killed", "survived", "timeout", "timeout", "invalid", "not-covered",
                "equivalent"]
    recs = [mutgen._rec(m, st, "tests/test_x.py::test_y" if st == "killed" else None, 1.0,
                        "because" if st == "equivalent" else None) for m, st in zip(ms, statuses)]
    mutgen.write_reports(recs, [rel], {rel: (1, 2, 3, 4)}, tmp_path, "cmd", 1.0, [])
    doc = json.loads((tmp_path / "mutation-generated.json").read_text())
    c = doc["modules"]["ldaspark/" + rel]
    assert (c["killed"], c["survived"], c["timeout"], c["invalid"], c["not-covered"], c["equivalent"]) == \
        (3, 1, 2, 1, 1, 1)
    # score = killed / (killed + survived + timeout) = 3 / 6, not 3 / 4 (timeouts left out) nor 5 / 6
    assert c["score"] == 0.5
    assert doc["surviving"] == [ms[3].id, ms[4].id, ms[5].id]
    row = next(line for line in (tmp_path / "mutation-generated.md").read_text().splitlines()
               if line.startswith("| ldaspark/" + rel))
    cells = [x.strip() for x in row.strip("|").split("|")]
    # generated, run, killed, equivalent, surviving, not covered, invalid, not run, score
    assert cells[1:10] == ["9", "7", "3", "1", "3", "1", "1", "0", "50.0%"]


def test_the_catalogue_report_counts_a_timeout_as_not_killed(tmp_path):
    ms = [mutation.by_id(x) for x in mutation.QUICK[:3]]
    recs = [mutation._record(ms[0], "killed", "tests/t.py::a", 1.0), mutation._record(ms[1], "timeout", None, 9.0),
            mutation._record(ms[2], "invalid", None, 1.0)]
    mutation.write_reports(recs, tmp_path, "cmd", 60.0)
    md = (tmp_path / "mutation.md").read_text()
    assert "**1 of 3 mutants killed** (33%)" in md
    assert "**NO (timeout)**" in md and "**NO (invalid)**" in md
    assert [r["killed"] for r in json.loads((tmp_path / "mutation.json").read_text())] == [True, False, False]


def test_a_generated_run_with_a_timeout_exits_1(monkeypatch, tmp_path):
    """The command's exit code: a timeout is a surviving mutant (1), like a survivor."""
    import types
    rel = "lab/mutants/mutant.py"
    ms = mutgen.generate(rel)
    assert ms
    monkeypatch.setattr(mutgen, "coverage_map", lambda files, tests, datafile, timeout=3600, reuse=False, jobs=1:
                        ({rel: {m.line: ["tests/compiled/test_kahan.py::test_x"] for m in ms}}, {rel: (1, 1, 1, 1)}, 0, 0.0, ""))
    monkeypatch.setattr(mutgen, "load_equivalent", lambda: {})
    for status, code in (("timeout", 1), ("killed", 0), ("survived", 1)):
        monkeypatch.setattr(mutgen, "run_catalogue", lambda todo, jobs, status=status, **kw: [
            mutgen._rec(m, status, "tests/compiled/test_kahan.py::test_x" if status == "killed" else None, 0.1) for m in todo])
        args = types.SimpleNamespace(generated=[rel], outdir=str(tmp_path / status), tests="tests/compiled/test_kahan.py",
                                     jobs=1, only=None, keep_killed=None, sample=None, kinds=None, limit=None,
                                     fresh=True, mutant_timeout=None, coverage_only=False, scheduler=None)
        assert mutgen.run_generated(args) == code, status
