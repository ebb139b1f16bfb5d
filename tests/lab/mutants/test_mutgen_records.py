"""``ldaspark mutants`` fed the malformed neighbours of each of its file arguments and selections
(issue 45, classes 3, 7 and 8): every one ends in one ``LdasparkError`` (CLI: one line, exit 2)
before any work starts; a FIFO or /dev/zero is never read; a module outside the package and an
empty selection are refused; a project copy never follows a link out of the tree."""
from __future__ import annotations

import contextlib
import io
import json
import os
import pathlib
import tempfile
from unittest import mock

import pytest
from hypothesis import given, strategies as st

from ldaspark import cli
from ldaspark.core.errors import LdasparkError
from ldaspark.lab.mutants import mutation, mutgen, records
from ldaspark.lab.mutants.records import sign_report

SMALL = "ldaspark/lab/mutants/mutant.py"          # two mutants: generated in milliseconds
REL = "lab/mutants/mutant.py"
KAHAN = "tests/compiled/test_kahan.py::test_neutral_direction_gains_most"


def _cli(*argv) -> tuple[int, str]:
    """``ldaspark mutants ...`` in this process; no mutant may run, no coverage may be measured."""
    err = io.StringIO()

    def no_work(*a, **k):
        raise AssertionError("a malformed argument reached the run")
    with mock.patch.object(mutgen, "coverage_map", no_work), mock.patch.object(mutgen, "run_catalogue", no_work), \
            mock.patch.object(mutation, "run_catalogue", no_work), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        rc = cli.main(["mutants", *argv])
    return rc, err.getvalue()


def _one_line_exit_2(rc, err):
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ldaspark: error:") and "Traceback" not in err, err


# --- the malformed neighbours of each file argument -------------------------------------------------
def _record(**change):
    ms = mutgen.generate(REL)
    return dict(mutgen._rec(ms[0], "killed", KAHAN, 1.0), **change)


WRONG_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=False, allow_infinity=False),
                         st.text(max_size=5), st.lists(st.integers(), max_size=2),
                         st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
RECORD_KEYS = ("mutant", "file", "description", "category", "killed", "status", "first_failing_test", "seconds")


@st.composite
def malformed(draw, kind):
    """(what to make at the path, its bytes): a neighbour of a valid ``kind`` file."""
    shape = draw(st.sampled_from(["missing", "directory", "fifo", "devzero", "dangling", "not-utf8", "too-big",
                                  "deep", "truncated", "not-finite", "wrong-shape", "wrong-record"]))
    if shape in ("missing", "directory", "fifo", "devzero", "dangling"):
        return shape, b""
    if kind == "only":
        # any text: ids that are not generated from the module, or none at all
        if shape == "not-utf8":
            return "file", b"ok\n\xff\xfe" + draw(st.binary(max_size=8))
        if shape == "too-big":
            return "big", b"x" * 64
        return "file", draw(st.sampled_from(["", "\n\n", " , ", "no::such::id#1\n", "[]", "{}"])).encode()
    if kind == "checkpoint":
        # the header names the run; without one the file is refused as a whole
        head = draw(st.sampled_from([b"", b"{}\n", b"[]\n", b'{"fingerprint": 3}\n', b'{"fingerprint": "ab"}\n',
                                     b"\xff\xfe\n", b"[" * 5000 + b"\n", b'{"fingerprint": NaN}\n']))
        return ("big" if shape == "too-big" else "file"), head + b'{"unit": "u", "value": 1, "mac": "0"}\n'
    valid = {"mutants": [_record()], "runs": [{"command": "c", "seconds": 1.0}], "modules_not_run": []} \
        if kind == "report" else {"some::id#1": "an argument"}
    text = json.dumps(valid)
    if shape == "not-utf8":
        cut = draw(st.integers(0, len(text)))
        return "file", text[:cut].encode() + b"\xff" + text[cut:].encode()
    if shape == "too-big":
        return "big", text.encode()
    if shape == "deep":
        depth = draw(st.sampled_from([records.MAX_DEPTH + 1, 1000, 10 ** 5]))
        return "file", (b"[" * depth + b"]" * depth) if draw(st.booleans()) else \
            json.dumps({"mutants": []})[:-2].encode() + b"[" * depth + b"]" * depth + b"}"
    if shape == "truncated":
        return "file", text[:draw(st.integers(0, len(text) - 1))].encode()
    if shape == "not-finite":
        return "file", text.replace("1.0", draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999"]))).encode() \
            if kind == "report" else b'{"a": NaN}'
    if shape == "wrong-shape":
        other = draw(st.sampled_from([[], [valid], "text", 3, None, True]))
        if kind == "report":
            other = draw(st.sampled_from([other, {"mutants": {"a": 1}}, {"mutants": "x"}, {"runs": "x", "mutants": []},
                                          {"mutants": [], "modules_not_run": [1]}, {"mutants": [], "modules": []}]))
        return "file", json.dumps(other).encode()
    # records of the wrong type: one field of one record replaced by a value of another type
    if kind == "equivalent":
        return "file", json.dumps({"id": draw(st.one_of(st.just(""), st.integers(), st.none(), st.lists(st.text())))}).encode()
    key = draw(st.sampled_from(RECORD_KEYS + ("extra",)))
    value = draw(WRONG_VALUES)
    rec = _record(**{key: value})
    try:
        records.check_generated_record(rec)
        rec = dict(rec, seconds=-1.0)          # the drawn value happened to be valid: make the record invalid
    except LdasparkError:
        pass
    return "file", json.dumps(dict(valid, mutants=[_record(), rec])).encode()


def _make(path: pathlib.Path, how, data):
    if how == "directory":
        path.mkdir()
    elif how == "fifo":
        os.mkfifo(path)
    elif how == "devzero":
        path.symlink_to("/dev/zero")
    elif how == "dangling":
        path.symlink_to(path.parent / "nowhere")
    elif how in ("file", "big"):
        path.write_bytes(data)


def _bounded(how):
    """A small reader's bound for "big": the file is past it (the real bounds are megabytes)."""
    if how != "big":
        return contextlib.nullcontext()
    stack = contextlib.ExitStack()
    for name in ("MAX_REPORT_BYTES", "MAX_LIST_BYTES"):
        stack.enter_context(mock.patch.object(records, name, 16))
    return stack


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
@given(st.sampled_from(["only", "report", "checkpoint"]).flatmap(lambda k: st.tuples(st.just(k), malformed(k))))
def test_every_malformed_file_argument_is_one_line_exit_2(case):
    kind, (how, data) = case
    with tempfile.TemporaryDirectory() as tmp:
        name = {"only": "ids.txt", "report": "prev.json", "checkpoint": "run.partial.jsonl"}[kind]
        path = pathlib.Path(tmp) / name
        _make(path, how, data)
        arg = ["--only", f"@{path}"] if kind == "only" else ["--keep-killed", str(path)]
        with _bounded(how):
            rc, err = _cli("--generated", SMALL, "--tests", "tests/compiled/test_kahan.py", "--outdir", str(pathlib.Path(tmp) / "o"),
                           *arg)
    _one_line_exit_2(rc, err)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
@given(malformed("equivalent"))
def test_every_malformed_equivalents_list_is_one_error(case):
    how, data = case
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "eq.json"
        _make(path, how, data)
        if how == "missing":
            assert mutgen.load_equivalent(path) == {}       # no list: no equivalents
            return
        with _bounded(how), pytest.raises(LdasparkError):
            mutgen.load_equivalent(path)


def test_the_controls_are_accepted(tmp_path):
    """The valid neighbours: the same arguments, well formed, are read (so each refusal above is the
    malformation's)."""
    ms = mutgen.generate(REL)
    ids = tmp_path / "ids.txt"
    ids.write_text(ms[0].id + "\n")
    import types
    assert mutgen._only_ids(types.SimpleNamespace(only=f"@{ids}"), ms) == {ms[0].id}
    rep = tmp_path / "prev.json"
    rep.write_text(json.dumps(sign_report({"mutants": [_record()], "runs": [{"command": "c", "seconds": 1.0}]})))
    prev = records.read_previous(rep)
    assert prev.trusted and len(prev.records) == 1
    eq = tmp_path / "eq.json"
    eq.write_text(json.dumps({"some::id#1": "an argument"}))
    assert mutgen.load_equivalent(eq) == {"some::id#1": "an argument"}


def test_a_fifo_argument_is_refused_without_blocking(tmp_path):
    """Opened without blocking and refused (a blocking open would hang this test for ever)."""
    fifo = tmp_path / "ids.txt"
    os.mkfifo(fifo)
    for arg in (["--only", f"@{fifo}"], ["--keep-killed", str(fifo)], ["--keep-killed", str(fifo) + ".partial.jsonl"]):
        if arg[1].endswith(".jsonl"):
            os.mkfifo(arg[1])
        rc, err = _cli("--generated", SMALL, "--tests", "tests/compiled/test_kahan.py", "--outdir", str(tmp_path / "o"), *arg)
        _one_line_exit_2(rc, err)
        assert "not a regular file" in err, err


# --- modules and selections -----------------------------------------------------------------------------
@pytest.mark.parametrize("module", ["ldaspark/../../x.py", "ldaspark/../conftest.py", "../ldaspark/core/validate.py",
                                    "/etc/passwd.py", "ldaspark/core/../../tests/test_kahan.py", "", " ",
                                    "ldaspark", "ldaspark.", "os.path", "ldaspark/core", "verification/test_theorem1.py",
                                    "verification/../ldaspark/core/validate.py", "x\0.py"])
def test_a_module_outside_the_package_is_refused(module):
    with pytest.raises(LdasparkError):
        mutgen.module_file(module)


def test_a_link_out_of_the_package_is_refused(tmp_path, monkeypatch):
    pkg = tmp_path / "ldaspark"
    (pkg / "core").mkdir(parents=True)
    (pkg / "core" / "inside.py").write_text("X = 1\n")
    (tmp_path / "outside.py").write_text("Y = 1\n")
    (pkg / "core" / "link.py").symlink_to(tmp_path / "outside.py")
    (pkg / "core" / "fifo.py").parent.mkdir(exist_ok=True)
    os.mkfifo(pkg / "core" / "fifo.py")
    monkeypatch.setattr(mutgen, "PACKAGE", pkg)
    assert mutgen.module_file("ldaspark/core/inside.py") == "core/inside.py"         # the control
    for bad in ("ldaspark/core/link.py", "ldaspark.core.link", "ldaspark/core/fifo.py"):
        with pytest.raises(LdasparkError):
            mutgen.module_file(bad)


@pytest.mark.parametrize("argv, words", [
    (["--generated", SMALL, "--only", ","], "selects no mutant"),
    (["--generated", SMALL, "--only", " "], "selects no mutant"),
    (["--generated", SMALL, "--only", ""], "selects no mutant"),
    (["--generated", SMALL, "--kinds", ","], "no kind"),
    (["--generated", SMALL, "--kinds", "nonsense"], "unknown kind"),
    (["--generated", SMALL, "--keep-killed", ","], "names no file"),
    (["--generated", SMALL, "--tests", ","], "names no test file"),
    (["--generated", SMALL, "--tests", "tests/../README.md"], "not a test file"),
    (["--generated", SMALL, "--tests", "/dev/zero"], "not a test file"),
    (["--generated", "ldaspark/../../x.py"], "not a module"),
    (["--generated", SMALL, "--tests", "tests/compiled/test_kahan.py", "--outdir", "/dev/null/x"], "--outdir"),
    (["--only", ","], "selects no mutant"),
    (["--only", ""], "selects no mutant"),
])
def test_empty_selections_and_bad_arguments_are_refused_in_one_line(argv, words):
    rc, err = _cli(*argv)
    _one_line_exit_2(rc, err)
    assert words in err, err


# --- project copies ---------------------------------------------------------------------------------------
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
def test_a_project_copy_never_follows_a_link_out_of_the_tree_nor_opens_a_special_file(tmp_path):
    proj = tmp_path / "proj"
    (proj / "ldaspark" / "sub").mkdir(parents=True)
    (proj / "tests").mkdir()
    (proj / "ldaspark" / "a.py").write_text("A = 1\n")
    (proj / "ldaspark" / "sub" / "b.py").write_text("B = 1\n")
    (proj / "tests" / "test_a.py").write_text("def test_a(): pass\n")
    (tmp_path / "secret.txt").write_text("outside\n")
    (proj / "ldaspark" / "zero.bin").symlink_to("/dev/zero")                      # would fill the disk
    (proj / "ldaspark" / "out.txt").symlink_to(tmp_path / "secret.txt")           # out of the tree
    (proj / "ldaspark" / "up.txt").symlink_to("../../secret.txt")                 # out, relative
    (proj / "ldaspark" / "outdir").symlink_to(tmp_path)                           # a directory out of it
    os.mkfifo(proj / "tests" / "test_fifo.py")                                    # would block
    (proj / "tests" / "same.py").symlink_to("../ldaspark/a.py")                   # inside: kept as a link
    (proj / "README.md").symlink_to("/dev/zero")
    dest = mutation.copy_project(tmp_path / "copy", proj)
    got = sorted(str(p.relative_to(dest)) for p in dest.rglob("*"))
    assert got == ["ldaspark", "ldaspark/a.py", "ldaspark/sub", "ldaspark/sub/b.py", "tests", "tests/same.py",
                   "tests/test_a.py"]
    assert (dest / "tests" / "same.py").is_symlink() and (dest / "tests" / "same.py").read_text() == "A = 1\n"
    assert (dest / "ldaspark" / "sub" / "b.py").read_text() == "B = 1\n"
    # and the copy's test files never list the FIFO, the fingerprint never opens it
    assert mutation.all_test_files(proj) == ["tests/test_a.py"]
    assert mutation.verdict_fingerprint("x", project=proj)
