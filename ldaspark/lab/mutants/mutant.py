"""One catalogued fault: the ``Mutant`` record and its ``_m`` builder. Apart from the catalogue
(``mutation_catalogue``), which collects the area modules (``catalogue/<area>.py``) that build
their mutants with ``_m``: the areas import this module, the catalogue imports the areas.
"""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Mutant:
    id: str
    file: str            # path relative to ldaspark/ ('a|b': alternatives, exactly one holds the snippet)
    snippet: str         # exact source text, occurring exactly once in the file
    replacement: str
    description: str
    category: str
    hint: tuple = field(default=())   # test files (or node ids) to run first


def _m(id, file, snippet, replacement, description, category, *hint):
    return Mutant(id, file, snippet, replacement, description, category, tuple(hint))
