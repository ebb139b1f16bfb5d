"""What the mutation tools read back is verified or refused (issue 45 class 4, issue 49 item 4):
the checkpoint fingerprint covers every file a verdict depends on (verification/ included), a
report or checkpoint record is a verdict only with its writer's signature, and a kill names a
test that exists in the project."""
from __future__ import annotations

import json
import types

import pytest

from ldaspark.core.errors import LdasparkError
from ldaspark.lab.checkpoint import Checkpoint, document_signed, sign_document
from ldaspark.lab.mutants import mutation, mutgen
from ldaspark.lab.mutants.records import (names_existing_test, read_previous, report_signed,
                                      sign_report)

KAHAN = "tests/compiled/test_kahan.py::test_neutral_direction_gains_most"      # a test that exists


# --- the fingerprint covers every file a verdict depends on --------------------------------------------
PROJECT_FILES = {
    "ldaspark/x.py": "X = 1\n", "ldaspark/data/tableaux/t.json": "{}", "tests/test_a.py": "def test_a(): pass\n",
    "tests/data/ref.json": "[1]", "verification/test_v.py": "def test_v(): pass\n",
    "verification/mutants_equivalent.json": "{}", "verification/strategies.py": "S = 1\n",
    "verification/fixtures/values.csv": "1,2\n", "examples/e.py": "E = 1\n", "reports/r.json": "{}",
    "docs/d.md": "# d\n", "benchmarks/b.py": "B = 1\n", "conftest.py": "C = 1\n", "pyproject.toml": "[x]\n",
    "README.md": "# r\n", "LICENSE": "MIT License\n", ".ci/run": "#!/bin/sh\n",
}


@pytest.fixture()
def fake_project(tmp_path, monkeypatch):
    root = tmp_path / "proj"
    for rel, text in PROJECT_FILES.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    monkeypatch.setattr(mutation, "PROJECT", root)
    return root


def test_every_copied_file_is_in_the_fingerprint(fake_project):
    # every top-level entry a mutant's run copies has a file here
    assert {rel.split("/")[0] for rel in PROJECT_FILES} == set(mutation.COPY)
    base = mutation.verdict_fingerprint("cfg")
    assert mutation.verdict_fingerprint("cfg") == base
    for rel in PROJECT_FILES:
        p = fake_project / rel
        old = p.read_text()
        p.write_text(old + " ")
        assert mutation.verdict_fingerprint("cfg") != base, rel
        p.write_text(old)
    assert mutation.verdict_fingerprint("cfg") == base
    # caches and checkpoints never enter (the control: they change as a run goes)
    (fake_project / "tests" / "__pycache__").mkdir()
    (fake_project / "tests" / "__pycache__" / "test_a.cpython-311.pyc").write_bytes(b"\0")
    (fake_project / "reports" / "mutation.partial.jsonl").write_text("{}\n")
    assert mutation.verdict_fingerprint("cfg") == base
    assert mutation.verdict_fingerprint("other") != base


def test_the_generated_runs_checkpoint_is_invalidated_by_a_change_under_verification(fake_project, monkeypatch,
                                                                                     tmp_path):
    """The records of an interrupted ``--generated`` run are not resumed once a file of
    verification/ (not only its *.py: the equivalents list, its data) changes."""
    rel = "lab/mutants/mutant.py"
    ms = mutgen.generate(rel)
    seen = []
    monkeypatch.setattr(mutgen, "coverage_map", lambda files, tests, datafile, timeout=3600, reuse=False, jobs=1:
                        ({rel: {m.line: [KAHAN] for m in ms}}, {rel: (1, 1, 1, 1)}, 0, 0.0, ""))
    monkeypatch.setattr(mutgen, "load_equivalent", lambda: {})

    def fake(todo, jobs, checkpoint=None, **kw):
        seen.append(checkpoint.fingerprint)
        return [mutgen._rec(m, "killed", KAHAN, 0.1) for m in todo]
    monkeypatch.setattr(mutgen, "run_catalogue", fake)
    args = types.SimpleNamespace(generated=[rel], outdir=str(tmp_path / "out"), tests="tests/compiled/test_kahan.py", jobs=1,
                                 only=None, keep_killed=None, sample=None, kinds=None, limit=None, fresh=False,
                                 mutant_timeout=None, coverage_only=False, scheduler=None)
    for change in (None, "verification/mutants_equivalent.json", "verification/fixtures/values.csv", "conftest.py",
                   None):
        if change:
            (fake_project / change).write_text((fake_project / change).read_text() + "\n")
        mutgen.run_generated(args)
    assert seen[4] == seen[3]                                               # nothing changed: same identity
    assert len(set(seen[:4])) == 4                                          # each change: a new identity
    # a record written under the first identity is not resumed under the second
    ck = Checkpoint(tmp_path / "c.partial.jsonl", seen[0])
    ck.open({})
    ck.add("u", {"v": 1})
    ck.close()
    assert Checkpoint(tmp_path / "c.partial.jsonl", seen[0], say=lambda m: None).load() == {"u": {"v": 1}}
    assert Checkpoint(tmp_path / "c.partial.jsonl", seen[1], say=lambda m: None).load() == {}


# --- a signed document ------------------------------------------------------------------------------
def test_a_signature_covers_every_field_and_the_kind(tmp_path):
    key = b"k" * 32
    doc = sign_document("report", {"a": 1, "b": [1.5, "x"], "c": {"d": None}}, key=key)
    assert document_signed("report", doc, key=key)
    assert document_signed("report", json.loads(json.dumps(doc)), key=key)          # as read back
    assert not document_signed("other", doc, key=key)                                 # another kind
    assert not document_signed("report", doc, key=b"j" * 32)                          # another key
    for change in (dict(a=2), dict(b=[1.5, "y"]), dict(c={"d": 0}), dict(e=1)):
        assert not document_signed("report", dict(doc, **change), key=key), change
    assert not document_signed("report", {k: v for k, v in doc.items() if k != "a"}, key=key)
    assert not document_signed("report", {k: v for k, v in doc.items() if k != "signature"}, key=key)
    for sig in ("x", {"scheme": "hmac-sha256"}, {"scheme": "none", "mac": doc["signature"]["mac"]},
                {"scheme": "hmac-sha256", "mac": "0" * 64}):
        assert not document_signed("report", dict(doc, signature=sig), key=key)
    assert not document_signed("report", [doc], key=key)


def test_a_report_written_is_signed_and_an_edit_is_seen(tmp_path):
    rel = "lab/claims/claims_general.py"
    ms = mutgen.generate(rel, check=False)[:2]
    mutgen.write_reports([mutgen._rec(ms[0], "killed", KAHAN, 1.0), mutgen._rec(ms[1], "survived", None, 1.0)],
                         [rel], {}, tmp_path, "cmd", 1.0, [])
    path = tmp_path / "mutation-generated.json"
    prev = read_previous(path)
    assert prev.trusted and report_signed(json.loads(path.read_text()))
    doc = json.loads(path.read_text())
    doc["mutants"][1].update(status="killed", killed=True, first_failing_test=KAHAN)     # the forgery
    path.write_text(json.dumps(doc))
    assert not read_previous(path).trusted


# --- forged records never become kills ----------------------------------------------------------------
def _run(monkeypatch, tmp_path, keep, only=None, name="out"):
    rel = "lab/mutants/mutant.py"
    ms = mutgen.generate(rel)
    ran = {}
    monkeypatch.setattr(mutgen, "coverage_map", lambda files, tests, datafile, timeout=3600, reuse=False, jobs=1:
                        ({rel: {m.line: ["tests/compiled/test_kahan.py::test_compensated_roundoff_grows_like_sqrt_n"]
                                for m in ms}}, {rel: (1, 1, 1, 1)}, 0, 0.0, ""))
    monkeypatch.setattr(mutgen, "load_equivalent", lambda: {})

    def fake(todo, jobs, targets=None, **kw):
        for m in todo:
            ran[m.id] = targets[m.id]
        return [mutgen._rec(m, "survived", None, 0.1) for m in todo]     # what the mutants really do
    monkeypatch.setattr(mutgen, "run_catalogue", fake)
    args = types.SimpleNamespace(generated=[rel], outdir=str(tmp_path / name), tests="tests/compiled/test_kahan.py", jobs=1,
                                 only=only, keep_killed=keep, sample=None, kinds=None, limit=None, fresh=True,
                                 mutant_timeout=None, coverage_only=False, scheduler=None)
    code = mutgen.run_generated(args)
    doc = json.loads((tmp_path / name / "mutation-generated.json").read_text())
    return ms, ran, code, {r["mutant"]: r for r in doc["mutants"]}


def _report(ms, test=KAHAN):
    return {"mutants": [mutgen._rec(m, "killed", test, 1.0) for m in ms]}


def test_a_signed_report_keeps_its_kills_and_a_forged_one_is_rerun(monkeypatch, tmp_path):
    ms = mutgen.generate("lab/mutants/mutant.py")
    signed, forged = tmp_path / "signed.json", tmp_path / "forged.json"
    signed.write_text(json.dumps(sign_report(_report(ms))))
    # the control: this user's signed report keeps its kills, nothing runs
    _, ran, code, rec = _run(monkeypatch, tmp_path, str(signed), name="a")
    assert code == 0 and not ran and all(rec[m.id]["status"] == "killed" and rec[m.id]["previous_run"] for m in ms)
    for doc in (_report(ms),                                                  # unsigned
                dict(sign_report(_report(ms[:1])), mutants=_report(ms)["mutants"]),   # a kill added after signing
                sign_document("another kind", _report(ms))):                  # signed as something else
        forged.write_text(json.dumps(doc))
        _, ran, code, rec = _run(monkeypatch, tmp_path, str(forged), name="b")
        assert code == 1 and set(ran) == {m.id for m in ms}                   # every mutant ran again
        assert all(rec[m.id]["status"] == "survived" and not rec[m.id].get("previous_run") for m in ms)
        assert all(ran[m.id][0] == KAHAN for m in ms)                         # its named test first: a hint


def test_a_kill_must_name_a_test_that_exists(monkeypatch, tmp_path):
    ms = mutgen.generate("lab/mutants/mutant.py")
    for test in ("tests/compiled/test_kahan.py::test_no_such_test", "tests/test_no_such_file.py::test_x",
                 "tests/../tests/test_kahan.py::test_neutral_direction_gains_most", "/etc/passwd",
                 "ldaspark/core/errors.py::LdasparkError", "tests/compiled/test_kahan.py::pow2"):
        p = tmp_path / "r.json"
        p.write_text(json.dumps(sign_report(_report(ms, test))))
        _, ran, code, rec = _run(monkeypatch, tmp_path, str(p), name="c")
        assert code == 1 and set(ran) == {m.id for m in ms}, test
    # the control: a test that exists, with a parameter id
    p.write_text(json.dumps(sign_report(_report(ms, KAHAN + "[3]"))))
    _, ran, code, _ = _run(monkeypatch, tmp_path, str(p), name="d")
    assert code == 0 and not ran


def test_names_existing_test():
    root = mutgen.PROJECT
    assert names_existing_test(KAHAN, root) and names_existing_test(KAHAN + "[a-b]", root)
    assert names_existing_test("tests/compiled/test_kahan.py", root)
    assert names_existing_test("verification/test_theorem1.py", root)
    for bad in (None, "", 3, "tests/compiled/test_kahan.py::nope", "tests/kahan.py", "conftest.py", "README.md",
                "tests/../README.md", "/work/x/tests/test_kahan.py", "verification/strategies.py",
                "ldaspark/tests/test_x.py", "tests/compiled/test_kahan.py::" + "x" * 2000):
        assert not names_existing_test(bad, root), bad


def test_the_records_of_a_checkpoint_count_only_with_their_hmac(monkeypatch, tmp_path):
    ms = mutgen.generate("lab/mutants/mutant.py")
    path = tmp_path / "run.partial.jsonl"
    ck = Checkpoint(path, "a" * 64)
    ck.open({})
    ck.add(ms[0].id, mutgen._rec(ms[0], "killed", KAHAN, 1.0))
    ck.close()
    forged = dict(mutgen._rec(ms[1], "killed", KAHAN, 1.0))
    with open(path, "a") as fh:
        fh.write(json.dumps({"unit": ms[1].id, "value": forged, "mac": "0" * 64}) + "\n")
    notes = []
    prev = read_previous(path, say=notes.append)
    assert [r["mutant"] for r in prev.records] == [ms[0].id] and notes and "wrong HMAC" in notes[0]
    _, ran, code, rec = _run(monkeypatch, tmp_path, str(path), name="e")
    assert set(ran) == {ms[1].id} and rec[ms[0].id]["status"] == "killed" and rec[ms[1].id]["status"] == "survived"


def test_an_update_of_an_unsigned_report_is_refused(monkeypatch, tmp_path):
    ms = mutgen.generate("lab/mutants/mutant.py")
    p = tmp_path / "r.json"
    p.write_text(json.dumps(_report(ms)))
    with pytest.raises(LdasparkError, match="not signed"):
        _run(monkeypatch, tmp_path, str(p), only=ms[0].id)
    # the control: signed, the listed mutant a survivor there (it runs again), the other kept
    p.write_text(json.dumps(sign_report({"mutants": [mutgen._rec(ms[0], "survived", None, 1.0),
                                                      mutgen._rec(ms[1], "killed", KAHAN, 1.0)]})))
    _, ran, _, rec = _run(monkeypatch, tmp_path, str(p), only=ms[0].id)
    assert set(ran) == {ms[0].id} and rec[ms[1].id]["previous_run"]
