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
