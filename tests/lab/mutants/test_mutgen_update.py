"""The update mode of the generated mutants' report (``--only`` with ``--keep-killed``): the
listed mutants run again, every other mutant keeps its earlier record, the run history grows."""
from __future__ import annotations

import json
import types

import pytest

from ldaspark.lab.mutants import mutgen
from ldaspark.lab.mutants.records import sign_report


def _mutants():
    return mutgen.generate("lab/claims/claims_general.py")


def test_only_ids_from_a_list_or_a_file_and_unknown_ids_refused(tmp_path):
    ms = _mutants()
    a, b = ms[0].id, ms[1].id
    assert mutgen._only_ids(types.SimpleNamespace(only=f"{a}, {b}"), ms) == {a, b}
    f = tmp_path / "ids.txt"
    f.write_text(f"{a}\n\n{b}\n")
    assert mutgen._only_ids(types.SimpleNamespace(only=f"@{f}"), ms) == {a, b}
    assert mutgen._only_ids(types.SimpleNamespace(only=None), ms) is None
    with pytest.raises(mutgen.MutgenError, match="not generated"):
        mutgen._only_ids(types.SimpleNamespace(only=a + "x"), ms)


def test_an_update_appends_its_run_and_lists_the_verdicts(tmp_path):
    prev = tmp_path / "prev.json"
    prev.write_text(json.dumps({"runs": [{"command": "first", "seconds": 60.0}], "modules_not_run": ["m"],
                                "mutants": []}))
    hist = mutgen._previous_runs(prev)
    assert hist == {"runs": [{"command": "first", "seconds": 60.0}], "modules_not_run": ["m"], "coverage": {}}
    m0, m1, m2 = _mutants()[:3]
    recs = [mutgen._rec(m0, "killed", "t::x", 1.0), mutgen._rec(m1, "survived", None, 1.0),
            mutgen._rec(m2, "equivalent", None, 0.0, "because")]
    mutgen.write_reports(recs, ["lab/claims/claims_general.py"], {}, tmp_path, "second", 30.0, [], hist)
    doc = json.loads((tmp_path / "mutation-generated.json").read_text())
    assert [r["command"] for r in doc["runs"]] == ["first", "second"]
    assert doc["surviving"] == [m1.id] and doc["equivalent"] == [m2.id] and doc["modules_not_run"] == ["m"]
    md = (tmp_path / "mutation-generated.md").read_text()
    assert "Not yet run: m." in md and "`first` (1.0 min)" in md
    # a one-run report is its own history
    one = tmp_path / "one.json"
    one.write_text(json.dumps({"command": "solo", "seconds": 5.0, "mutants": []}))
    assert mutgen._previous_runs(one)["runs"] == [{"command": "solo", "seconds": 5.0}]


# --- the verification helpers, the default suite's coverage, sharded coverage runs -------------
def test_verification_helpers_are_mutated_under_their_own_path(tmp_path):
    rel = mutgen.module_file("verification/systems_checks.py")
    assert rel == "verification/systems_checks.py" and mutgen.label(rel) == rel
    assert mutgen.label("core/validate.py") == "ldaspark/core/validate.py"
    ms = mutgen.generate(rel)
    assert ms and all(m.id.startswith(rel + "::") and m.file == rel for m in ms)
    # applied into a copy of the project, at verification/, not under ldaspark/
    (tmp_path / "verification").mkdir()
    (tmp_path / rel).write_text(mutgen.source_path(rel).read_text())
    path = ms[0].apply(tmp_path)
    assert path == tmp_path / rel and path.read_text() != mutgen.source_path(rel).read_text()
    # test files and conftest are not checking code to mutate; an absent helper is named
    for bad in ("verification/test_theorem1.py", "verification/conftest.py", "verification/nothere.py"):
        with pytest.raises(mutgen.MutgenError, match="no verification helper"):
            mutgen.module_file(bad)
    # the tests that import a helper by its bare name are its mapped tests
    mapped = mutgen.mapped_tests("verification/strategies.py")
    assert "verification/test_general_systems.py" in mapped
    assert "verification/test_theorem1.py" not in mapped or "strategies" in (
        mutgen.PROJECT / "verification/test_theorem1.py").read_text()
    # a report keys them by that path
    recs = [mutgen._rec(ms[0], "killed", "t::x", 1.0)]
    per = mutgen.summarize(recs, [rel])
    assert per[rel]["killed"] == 1 and per[rel]["generated"] == 1


def test_shards_balance_the_test_files_and_keep_every_one():
    files = mutgen.all_test_files()
    for n in (1, 2, 3):
        groups = mutgen._shards(files, n)
        assert len(groups) == min(n, len(files))
        assert sorted(f for g in groups for f in g) == sorted(files)
        size = [sum((mutgen.PROJECT / f).stat().st_size for f in g) for g in groups]
        biggest = max((mutgen.PROJECT / f).stat().st_size for f in files)
        assert max(size) - min(size) <= biggest          # greedy: within one file of each other
    assert mutgen._shards(files[:1], 4) == [files[:1]]


@pytest.mark.parametrize("rcs, whole", [([0, 0], 0), ([0, 1], 1), ([1, 0], 1), ([5, 5], 5), ([0, 5], 0),
                                        ([1, 2], 2), ([3, 1], 3), ([5, 4], 4), ([], 0)])
def test_the_exit_status_of_the_shards_as_one(rcs, whole):
    assert mutgen._combined_rc(rcs) == whole


def test_the_suite_option_maps_every_default_test_file():
    assert mutgen.SUITE == "suite"
    files = mutgen.all_test_files()
    assert "tests/lab/mutants/test_mutation_quick.py" not in files           # it would recurse into the runner
    assert any(f.startswith("verification/") for f in files) and any(f.startswith("tests/") for f in files)


def test_a_coverage_run_in_two_shards_is_combined_with_its_contexts(tmp_path):
    """Two small test files, one per shard: the combined map has the node ids of both (each
    line with the tests that run it) and the coverage report lists what no test executes."""
    a, b = tmp_path / "test_a.py", tmp_path / "test_b.py"
    a.write_text("from ldaspark.analysis import memo\n\n\ndef test_outside():\n"
                 "    assert memo.cached('k', 1, 2, None, (1,), lambda: 5) == 5\n")
    b.write_text("import numpy as np\nfrom ldaspark.analysis import memo\n\n\ndef test_inside():\n"
                 "    with memo.memoized():\n"
                 "        assert memo.cached('k', 1, 2, None, (np.ones(2),), lambda: 5) == 5\n"
                 "        assert memo.cached('k', 1, 2, None, (np.ones(2),), lambda: 6) == 5\n")
    files = ["analysis/memo.py"]
    cmap, stats, rc, _, _ = mutgen.coverage_map(files, [str(a), str(b)], tmp_path / "cov", jobs=2)
    assert rc == 0
    src = (mutgen.PACKAGE / "analysis/memo.py").read_text().splitlines()
    line = lambda text: next(i + 1 for i, t in enumerate(src) if text in t)  # noqa: E731
    ran = lambda text: {i.split("::")[-1] for i in cmap["analysis/memo.py"].get(line(text), [])}  # noqa: E731
    assert ran("return compute()") == {"test_outside"}          # one shard's test
    assert ran("hit = _MEMO.get(k)") == {"test_inside"}          # the other's
    assert ran("return v._mpf_") == set()                        # no test
    lc, ln, bc, bn = stats["analysis/memo.py"]
    assert 0 < lc < ln and 0 < bc < bn
    assert not list(tmp_path.glob("cov.shard*"))                  # the shards' files are gone
    assert not list(tmp_path.glob("*.part"))                      # written by rename, none left half
    durations = json.loads((tmp_path / "cov.durations.json").read_text())["durations"]
    assert {k.split("::")[-1] for k in durations} == {"test_outside", "test_inside"}
    mutgen.write_coverage_report(files + ["verification/general_fixtures.py"], tmp_path / "cov", tmp_path,
                                 [str(a), str(b)], {}, 1.0, "cmd")
    doc = json.loads((tmp_path / "coverage-checking.json").read_text())
    assert doc["modules"]["ldaspark/analysis/memo.py"]["lines"] == [lc, ln]
    assert f"{line('isinstance(v, mpmath.mpf)')}->{line('return v._mpf_')}" in \
        doc["modules"]["ldaspark/analysis/memo.py"]["missed_branches"]
    assert doc["modules"]["verification/general_fixtures.py"]["lines"][0] == 0
    md = (tmp_path / "coverage-checking.md").read_text()
    assert "| ldaspark/analysis/memo.py |" in md and "2 test files" in md


def test_arcs_are_written_line_to_line_and_exits_named():
    assert mutgen._arc_text({12: [13, -10], 4: [7]}) == "4->7, 12->exit, 12->13"
    assert mutgen._arc_text({}) == ""


def _args(rel, outdir, tests, only=None, keep_killed=None, sample=None):
    """The parsed command line of ``ldaspark mutants --generated REL`` as ``run_generated`` takes it."""
    return types.SimpleNamespace(generated=[rel], outdir=outdir, tests=tests, jobs=1, only=only,
                                 keep_killed=keep_killed, sample=sample, kinds=None, limit=None, fresh=True,
                                 mutant_timeout=None, coverage_only=False, scheduler=None)


def _fake_run(monkeypatch, tmp_path, cmap, tests, ran):
    """run_generated with the coverage run and the mutant runs replaced: ``ran`` gets the
    targets of each mutant run; every mutant run is reported killed by its first target."""
    def fake_map(files, test_files, datafile, timeout=3600, reuse=False, jobs=1):
        return cmap, {f: (1, 1, 1, 1) for f in files}, 0, 0.0, ""

    def fake_catalogue(todo, jobs, progress=None, where=None, checkpoint=None, targets=None, timeout=None):
        out = []
        for m in todo:
            ran[m.id] = targets[m.id]
            out.append(mutgen._rec(m, "killed", targets[m.id][0], 0.1))
        return out
    monkeypatch.setattr(mutgen, "coverage_map", fake_map)
    monkeypatch.setattr(mutgen, "run_catalogue", fake_catalogue)
    monkeypatch.setattr(mutgen, "load_equivalent", lambda: {})


def test_a_module_constant_executed_at_import_is_run_against_the_files_importing_it(monkeypatch, tmp_path):
    rel = "lab/claims/claims_general.py"
    ms = mutgen.generate(rel, check=False)
    const = next(m for m in ms if m.id.split("::")[1] == "<module>")
    deftime = mutgen.definition_time_lines(rel)
    inner = next(m for m in ms if m.id.split("::")[1] != "<module>" and m.line not in deftime)
    mapped = [f for f in mutgen.mapped_tests(rel) if f not in mutgen.ALWAYS_MAPPED]
    assert mapped
    # the constant's line ran at import only (no test context); the other line in one test
    cmap = {rel: {const.line: [], inner.line: ["tests/test_x.py::test_y"]}}
    ran = {}
    _fake_run(monkeypatch, tmp_path, cmap, mapped, ran)
    args = _args(rel, str(tmp_path), ",".join(mapped), only=f"{const.id},{inner.id}")
    assert mutgen.run_generated(args) == 0
    files_run = [t for t in ran[const.id] if not t.startswith("--deselect")]
    assert set(mapped) <= set(files_run)                       # the importing files, run whole
    # ... first, then the kill files (every one of them, once): a constant the kill files do not
    # read reaches its own test before the timeout
    kill_files = [f for f in mutgen.ALWAYS_MAPPED if (mutgen.PROJECT / f).is_file()]
    assert set(files_run[:len(mapped)]) == set(mapped) and set(kill_files) <= set(files_run)
    assert len(files_run) == len(set(files_run))
    assert [t for t in ran[inner.id] if not t.startswith("--")] == ["tests/test_x.py::test_y"]
    doc = json.loads((tmp_path / "mutation-generated.json").read_text())
    status = {r["mutant"]: r["status"] for r in doc["mutants"]}
    assert status[const.id] == status[inner.id] == "killed"
    # a default value on a def line runs at import too: the importing files decide it
    default = next((m for m in ms if m.id.split("::")[1] != "<module>" and m.line in deftime
                    and m.line != const.line), None)
    assert default is not None
    cmap[rel][default.line] = []
    ran.clear()
    args.only, args.outdir = default.id, str(tmp_path / "d")
    assert mutgen.run_generated(args) == 0
    assert set(mapped) <= set(ran[default.id])
    # a line that never ran is not covered, at module level too
    other = next(m for m in ms if m.id.split("::")[1] == "<module>" and m.line != const.line)
    assert status[other.id] == "not-covered"


def test_kills_of_several_earlier_reports_are_kept_outside_the_sample(monkeypatch, tmp_path):
    rel = "analysis/symmetry.py"
    ms = mutgen.generate(rel, check=False)
    cmap = {rel: {m.line: ["tests/compiled/test_kahan.py::test_x"] for m in ms}}
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    kahan = "tests/compiled/test_kahan.py::test_neutral_direction_gains_most"      # a test that exists
    # reports as this user's runs write them: signed (an unsigned one is tests/test_mutgen_records.py's)
    a.write_text(json.dumps(sign_report({"runs": [{"command": "first", "seconds": 1.0}],
                             "modules_not_run": ["theory (symmetry.py, variational.py)", "models (bicycle.py)"],
                             "mutants": [
        dict(mutgen._rec(ms[-1], "killed", kahan, 1.0))]})))
    b.write_text(json.dumps(sign_report({"mutants": [dict(mutgen._rec(ms[-2], "killed", kahan, 1.0)),
                                         dict(mutgen._rec(ms[-3], "killed", "tests/no_such_file.py::t", 1.0))]})))
    ran = {}
    _fake_run(monkeypatch, tmp_path, cmap, ["tests/compiled/test_kahan.py"], ran)
    args = _args(rel, str(tmp_path / "out"), "tests/compiled/test_kahan.py", keep_killed=f"{a},{b}", sample=2)
    assert mutgen.run_generated(args) == 0
    doc = json.loads((tmp_path / "out" / "mutation-generated.json").read_text())
    rec = {r["mutant"]: r for r in doc["mutants"]}
    # both files' kills kept (outside the sample of 2 too), not run again; a kill whose test is gone is not
    assert rec[ms[-1].id].get("previous_run") and rec[ms[-2].id].get("previous_run")
    assert ms[-1].id not in ran and ms[-2].id not in ran
    assert rec[ms[-3].id]["status"] in ("not-run", "killed") and not rec[ms[-3].id].get("previous_run")
    assert len(ran) == 2                                          # the sample ran
    # each ran its covering test first, then every kill file (newer tests than the map), once
    kill_files = [f for f in mutgen.ALWAYS_MAPPED if (mutgen.PROJECT / f).is_file()]
    for targets in ran.values():
        files = [t for t in targets if not t.startswith("--")]
        assert files[0] == "tests/compiled/test_kahan.py::test_x" and set(kill_files) <= set(files[1:])
        assert len(files) == len(set(files))
    assert [r["command"] for r in doc["runs"]][0] == "first"      # the history is the first file's
    assert doc["modules_not_run"] == ["models (bicycle.py)"]       # symmetry.py ran: no longer listed
    assert "--sample 2" in doc["command"] and "--tests tests/compiled/test_kahan.py" in doc["command"]


def test_the_sample_is_drawn_from_every_mutant_whatever_the_coverage(monkeypatch, tmp_path):
    rel = "analysis/symmetry.py"
    ms = mutgen.generate(rel, check=False)
    picked = [m.id for m in mutgen.sample(ms, [rel], 6)]
    assert len(picked) == 6 and len(set(picked)) == 6
    runs = []
    for covered_lines in ({m.line for m in ms}, {m.line for m in ms[: len(ms) // 2]}):
        cmap = {rel: {ln: ["tests/compiled/test_kahan.py::test_x"] for ln in covered_lines}}
        ran = {}
        _fake_run(monkeypatch, tmp_path, cmap, ["tests/compiled/test_kahan.py"], ran)
        args = _args(rel, str(tmp_path / f"o{len(runs)}"), "tests/compiled/test_kahan.py", sample=6)
        mutgen.run_generated(args)
        doc = json.loads((tmp_path / f"o{len(runs)}" / "mutation-generated.json").read_text())
        runs.append((set(ran), {r["mutant"] for r in doc["mutants"] if r["status"] == "not-covered"}))
    assert runs[0][0] == set(picked)                               # all covered: the whole sample runs
    part = {m.id for m in ms if m.line in {x.line for x in ms[: len(ms) // 2]}}
    assert runs[1][0] == set(picked) & part and runs[1][0] < runs[0][0]   # the same sample, its covered part


def test_definition_time_lines_are_those_import_evaluates(tmp_path, monkeypatch):
    src = ('"""doc."""\nimport math\nX = 3\n\n\n@decor(2)\ndef f(a, b=0.5, *, c=[1,\n      2], d: int = 4) -> "T":\n'
           '    y = a + 1\n    return y\n\n\nclass K:\n    Z = 7\n\n    def g(self, e=9):\n        return e\n')
    (tmp_path / "verification").mkdir()
    (tmp_path / "verification" / "mod.py").write_text(src)
    monkeypatch.setattr(mutgen, "PROJECT", tmp_path)
    lines = mutgen.definition_time_lines("verification/mod.py")
    assert {1, 2, 3, 6, 7, 8, 14, 16} <= lines            # module code, decorator, defaults, class body
    assert not {9, 10, 17} & lines                         # function bodies run when called


def test_a_default_value_is_decided_by_the_importing_files_even_when_a_test_imported_it(monkeypatch, tmp_path):
    """A test that imports the module inside its body records the def line in its context; that
    test alone need not call the function with its default."""
    rel = "lab/theory/bicycle_flow.py"
    ms = mutgen.generate(rel, check=False)
    m = next(x for x in ms if x.id == "lab/theory/bicycle_flow.py::spark_eigenvalues::constant::0.01->0.0#1")
    assert m.line in mutgen.definition_time_lines(rel)
    mapped = [f for f in mutgen.mapped_tests(rel) if f not in mutgen.ALWAYS_MAPPED]
    cmap = {rel: {m.line: ["tests/test_x.py::test_imports_it"]}}
    ran = {}
    _fake_run(monkeypatch, tmp_path, cmap, mapped, ran)
    args = _args(rel, str(tmp_path), ",".join(mapped), only=m.id)
    mutgen.run_generated(args)
    assert "tests/test_x.py::test_imports_it" in ran[m.id] and set(mapped) <= set(ran[m.id])


def test_whole_test_files_are_ordered_by_their_tests_total_time():
    d = {"tests/a.py::t1": 5.0, "tests/a.py::t2": 6.0, "tests/b.py::t": 2.0, "tests/c.py::x": 0.5}
    ids = ["tests/a.py", "tests/b.py", "tests/c.py::x", "tests/new.py", "tests/c.py::y"]
    assert mutgen._order_tests(ids, d) == ["tests/c.py::x", "tests/b.py", "tests/a.py", "tests/c.py::y", "tests/new.py"]
    assert mutgen._file_costs(d) == {"tests/a.py": 11.0, "tests/b.py": 2.0, "tests/c.py": 0.5}


def test_a_continuation_line_is_looked_up_at_its_statements_first_line(monkeypatch, tmp_path):
    """coverage.py records a multi-line statement at its first line: a mutant on its second line
    runs the tests of the first (it was reported not covered)."""
    rel = "lab/reports/summary.py"
    st = mutgen.statement_lines(rel)
    ms = mutgen.generate(rel, check=False)
    m = next(x for x in ms if x.id.startswith("lab/reports/summary.py::_us::") and st[x.line] != x.line)
    cmap = {rel: {st[m.line]: ["tests/test_x.py::test_us"]}}
    ran = {}
    _fake_run(monkeypatch, tmp_path, cmap, ["tests/project/test_readme.py"], ran)
    args = _args(rel, str(tmp_path), "tests/project/test_readme.py", only=m.id)
    mutgen.run_generated(args)
    assert ran[m.id][0] == "tests/test_x.py::test_us"


def test_a_mutant_in_a_numba_compiled_body_is_run_against_the_layers_tests_not_called_not_covered(monkeypatch, tmp_path):
    """numba compiles a kernel from its bytecode: coverage records no context for its lines, and
    every mutant of compiled/kernels_quasi.py was reported "not covered" and never run (probe
    t24). Such a mutant now runs the files that import the module and the compiled layer's tests
    (tests/compiled/, e.g. test_kahan.py, which reaches the kernel through the public path only).
    Control: with the compiled bodies unknown (the rule before) the same mutant is not run."""
    rel = "compiled/kernels_quasi.py"
    jitted = mutgen.compiled_body_lines(rel)
    ms = mutgen.generate(rel, check=False)
    inner = next(m for m in ms if m.id.split("::")[1] == "quasi_steps" and m.line in jitted)
    mapped = [f for f in mutgen.mapped_tests(rel) if f not in mutgen.ALWAYS_MAPPED]
    assert "tests/compiled/test_kahan.py" in mapped and "tests/compiled/test_kernels_quasi.py" in mapped
    gen = mutgen.generate
    # the run's syntax check of ~1000 mutated copies of the module (8 s) decides nothing here
    monkeypatch.setattr(mutgen, "generate", lambda rel, text=None, check=True: gen(rel, text, check=False))
    for rule in (True, False):
        if not rule:
            monkeypatch.setattr(mutgen, "compiled_body_lines", lambda rel: set())
        ran = {}
        _fake_run(monkeypatch, tmp_path, {rel: {}}, mapped, ran)
        args = _args(rel, str(tmp_path / str(rule)), ",".join(mapped), only=inner.id)
        mutgen.run_generated(args)
        if rule:
            assert set(mapped) <= set(ran[inner.id])
        else:
            assert inner.id not in ran                               # "not covered", never run


def test_compiled_body_lines_are_the_bodies_of_jitted_functions(monkeypatch, tmp_path):
    src = ('import numba\n\n\n@numba.njit(cache=True, _nrt=False)\ndef k(x):\n    return x + 1\n\n\n'
           '@_jit(nogil=True)\ndef g(x):\n    y = x\n    return y\n\n\ndef p(x):\n    return x - 1\n')
    (tmp_path / "verification").mkdir()
    (tmp_path / "verification" / "kmod.py").write_text(src)
    monkeypatch.setattr(mutgen, "PROJECT", tmp_path)
    assert mutgen.compiled_body_lines("verification/kmod.py") == {6, 11, 12}


def test_a_helper_mutant_keeps_the_kernels_digest_record_true(tmp_path):
    """A mutant of a kernel's helper (newton.py) changed the digest kernels.py records, and the
    record's test killed it for that alone. ``refresh_helper_digests`` recomputes every kernel's
    digest in the copy, kernels_quasi's (which hashes kernels.py, digest line included) after
    kernels.py's. Control: without the refresh the record is stale."""
    import hashlib
    import re
    import shutil
    from ldaspark.lab.mutants.mutation import refresh_helper_digests
    src = mutgen.PROJECT / "ldaspark" / "compiled"
    dst = tmp_path / "ldaspark" / "compiled"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))

    def stale():
        out = []
        for p in sorted(dst.glob("kernels*.py")):
            text = p.read_text()
            m = re.search(r"^HELPERS = \((.*?)\)\n", text, re.S | re.M)
            if m is None:
                continue
            h = hashlib.sha256()
            for name in re.findall(r'"([^"]+)"', m.group(1)):
                h.update((dst / name).read_bytes())
            if f'HELPERS_SHA256 = "{h.hexdigest()}"' not in text:
                out.append(p.name)
        return out
    assert stale() == [] and refresh_helper_digests(tmp_path) == []
    (dst / "newton.py").write_text((dst / "newton.py").read_text().replace("theta", "theta_", 1))
    assert {"kernels.py", "kernels_quasi.py", "kernels_quasi_general.py"} <= set(stale())
    changed = refresh_helper_digests(tmp_path)
    assert stale() == [] and "kernels.py" in changed and "kernels_quasi.py" in changed
