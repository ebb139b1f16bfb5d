"""Rules of ``ldaspark.lab.claims.claims_index`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from ldaspark.lab.claims import claims_index as ci


# ============================== claims_index / claims_paper ================================
def test_equations_in_ranges_and_single_labels():
    assert ci.equations_in("(21a)-(21c), (7)") == {"(21a)", "(21b)", "(21c)", "(7)"}
    assert ci.equations_in("(21a)-(21a)") == {"(21a)"}
    # a range across numbers is not expanded: the part is kept as it is
    assert ci.equations_in("(21a)-(22b)") == {"(21a)-(22b)"}
    assert ci.equations_in("Theorem 1, (9b)") == {"(9b)"}
    # not a parenthesised range: no expansion
    assert ci.equations_in("(3)-x") == {"(3)-x"}
    # split at the first hyphen only: a second one leaves the part as it is
    assert ci.equations_in("(21a)-(21c)-(21d)") == {"(21a)-(21c)-(21d)"}


def test_claims_index_markdown_counts_and_escapes(monkeypatch):
    claims = (("(1)", "2", "a|b", ("f.py::t",), ci.CHECKED, ""),
              ("(2)", "3", "c", (), ci.NOT_CHECKED, "x\ny"),
              ("(3)", "3", "d", ("g.py::u", "h.py::v"), ci.NOT_CHECKABLE, "n"))
    monkeypatch.setattr(ci, "CLAIMS", claims)
    md = ci.claims_index_markdown()
    assert "3 entries: 1 checked, 1 not checkable, 1 not checked." in md
    assert "| a\\|b |" in md and "| - | " + ci.NOT_CHECKED + " | x y |" in md
    assert "`g.py::u`<br>`h.py::v`" in md and "| f.py::t" not in md and "| - |\n" in md
