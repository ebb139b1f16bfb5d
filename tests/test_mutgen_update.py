"""The update mode of the generated mutants' report (``--only`` with ``--keep-killed``): the
listed mutants run again, every other mutant keeps its earlier record, the run history grows."""
from __future__ import annotations

import json
import types

import pytest

from ldaspark.mutants import mutgen


def _mutants():
    return mutgen.generate("claims/claims_general.py")


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
    mutgen.write_reports(recs, ["claims/claims_general.py"], {}, tmp_path, "second", 30.0, [], hist)
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
    assert "tests/test_mutation_quick.py" not in files           # it would recurse into the runner
    assert any(f.startswith("verification/") for f in files) and any(f.startswith("tests/") for f in files)


def test_a_coverage_run_in_two_shards_is_combined_with_its_contexts(tmp_path):
    """Two small test files, one per shard: the combined map has the node ids of both and the
    coverage report lists what no test executes."""
    files = ["theory/symmetry.py"]
    tests = ["verification/test_symmetry_23.py", "tests/test_kahan.py"]
    cmap, stats, rc, _, _ = mutgen.coverage_map(files, tests, tmp_path / "cov", jobs=2)
    assert rc == 0
    ids = {i for ls in cmap["theory/symmetry.py"].values() for i in ls}
    assert any(i.startswith("verification/test_symmetry_23.py::") for i in ids)
    lc, ln, bc, bn = stats["theory/symmetry.py"]
    assert 0 < lc <= ln and 0 <= bc <= bn
    assert not list(tmp_path.glob("cov.shard*"))                  # the shards' files are gone
    durations = json.loads((tmp_path / "cov.durations.json").read_text())["durations"]
    assert any(k.startswith("tests/test_kahan.py::") for k in durations)
    mutgen.write_coverage_report(files + ["verification/general_fixtures.py"], tmp_path / "cov", tmp_path, tests,
                                 {}, 1.0, "cmd")
    doc = json.loads((tmp_path / "coverage-checking.json").read_text())
    assert doc["modules"]["ldaspark/theory/symmetry.py"]["lines"] == [lc, ln]
    assert doc["modules"]["verification/general_fixtures.py"]["lines"][0] == 0
    md = (tmp_path / "coverage-checking.md").read_text()
    assert "| ldaspark/theory/symmetry.py |" in md and "2 test files" in md


def test_arcs_are_written_line_to_line_and_exits_named():
    assert mutgen._arc_text({12: [13, -10], 4: [7]}) == "4->7, 12->exit, 12->13"
    assert mutgen._arc_text({}) == ""
