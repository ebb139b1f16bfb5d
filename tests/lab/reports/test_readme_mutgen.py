"""README's quotes of the generated mutants' report and of the checking code's coverage
(``summary.mutgen_values``, ``summary.coverage_values``): totals over modules, the lowest score and
coverage named with their module, the 90% line counted inclusively."""
from __future__ import annotations

from ldaspark.lab.reports import summary as S


def _mod(generated, killed, survived=0, timeout=0, equivalent=0, not_covered=0):
    judged = killed + survived + timeout
    return {"generated": generated, "killed": killed, "survived": survived, "timeout": timeout,
            "equivalent": equivalent, "not-covered": not_covered, "score": killed / judged if judged else None}


def test_mutgen_totals_and_the_lowest_score():
    d = {"modules": {"ldaspark/a.py": _mod(100, 38, 2, 0, 3, 10), "ldaspark/b.py": _mod(50, 20, 0, 1, 1, 0),
                     "ldaspark/c.py": _mod(7, 0, 0, 0, 0, 7)}}
    v = S.mutgen_values(d)
    assert v["mutgen.modules"] == "3" and v["mutgen.generated"] == "157"
    assert v["mutgen.run"] == "61" and v["mutgen.killed"] == "58"
    assert v["mutgen.surviving"] == "3" and v["mutgen.equivalent"] == "4" and v["mutgen.not_covered"] == "17"
    # a: 38/40 = 95.0%, b: 20/21 = 95.2%: the lowest is a's (c has no mutant run: no score)
    assert v["mutgen.min_score"] == "95.0% (ldaspark/a.py)"
    assert "mutgen.min_score" not in S.mutgen_values({"modules": {"x": _mod(3, 0)}})
    same = {"modules": {"ldaspark/a.py": _mod(10, 10), "ldaspark/b.py": _mod(5, 5)}}
    assert S.mutgen_values(same)["mutgen.min_score"] == "100.0% (every module)"


def test_coverage_the_lowest_module_and_the_ninety_percent_line():
    d = {"modules": {"ldaspark/a.py": {"lines": [9, 10], "branches": [9, 10]},
                     "ldaspark/b.py": {"lines": [5, 10], "branches": [89, 100]},
                     "ldaspark/c.py": {"lines": [3, 3], "branches": [0, 0]},
                     "ldaspark/d.py": {"lines": [10, 10], "branches": [20, 20]}}}
    v = S.coverage_values(d)
    assert v["coverage.at90"] == "2 of 3"               # 90% exactly counts; no branches: not counted
    assert v["coverage.min_branches"] == "89% (ldaspark/b.py)"
    assert v["coverage.modules"] == "4"
    assert S.coverage_values({"modules": {}}) == {}


def test_the_keys_name_their_report_files():
    assert S.SOURCE["mutgen"] == "mutation-generated.json" and S.SOURCE["coverage"] == "coverage-checking.json"
    assert S.quote_kind("mutgen.killed") == "exact" and S.quote_kind("coverage.at90") == "exact"
