"""The three tableau modules after the split of issue 46: ``core.numbers`` (the entry language,
its limits, ball arithmetic) is the lower layer and imports neither ``core.tableau`` nor
``core.tableau_file``; the names that moved out of ``core.tableau`` keep their old dotted names
(PEP 562 ``__getattr__``) as the very objects of their new modules, for code outside the package;
inside the repository nothing imports a moved name by its old path (that lookup is a lazy circle
tableau -> tableau_file -> tableau, kept for old callers only).

Negative controls: an unknown name is still an AttributeError / ImportError; the import scanner
finds the edge tableau_file -> tableau, and an old-path import in a synthetic source.
"""
from __future__ import annotations

import ast
import importlib
import pathlib
import subprocess
import sys

import pytest

import ldaspark.core.numbers as numbers
import ldaspark.core.tableau as tableau
import ldaspark.core.tableau_file as tableau_file

ROOT = pathlib.Path(__file__).resolve().parents[2]
CORE = ROOT / "ldaspark" / "core"

#: every public top-level name of ``ldaspark/core/tableau.py`` before the split
OLD_PUBLIC = ("NAMES", "MATRIX_NAMES", "VECTOR_NAMES", "guard_digits", "SparkTableau", "TableauArrays", "JsonNumber",
              "FLOAT64_REPR_DIGITS", "decimal_info", "decimal_radius", "LONG_DECIMAL", "omega_rank", "MAX_MAGNITUDE",
              "MAX_STAGES", "parse_exact_string", "parse_expression", "parse_number", "check_stages",
              "from_json_dict", "max_file_bytes", "load_tableau")
#: where each public name lives now (and the private names importers used)
HOME = {**dict.fromkeys(("JsonNumber", "FLOAT64_REPR_DIGITS", "decimal_info", "decimal_radius", "LONG_DECIMAL",
                         "MAX_MAGNITUDE", "MAX_STAGES", "parse_exact_string", "parse_expression", "parse_number",
                         "_parse_entry", "_BallEvaluator", "_sympy_ball"), numbers),
        **dict.fromkeys(("check_stages", "from_json_dict", "max_file_bytes", "load_tableau", "_json_number"),
                        tableau_file)}


def test_every_old_public_name_resolves_to_its_new_home():
    for name in OLD_PUBLIC:
        obj = getattr(tableau, name)
        home = HOME.get(name, tableau)
        assert obj is getattr(home, name), name
    for name, module in tableau._MOVED.items():
        assert getattr(tableau, name) is getattr(importlib.import_module(module, "ldaspark.core"), name)
    ns = {}
    exec("from ldaspark.core.tableau import load_tableau, parse_number, MAX_STAGES", ns)
    assert ns["load_tableau"] is tableau_file.load_tableau and ns["MAX_STAGES"] == 20


def test_an_unknown_name_is_still_an_error():
    with pytest.raises(AttributeError, match="no attribute 'load_tableaux'"):
        tableau.load_tableaux
    with pytest.raises(ImportError):
        exec("from ldaspark.core.tableau import no_such_name", {})


def _imported_modules(path: pathlib.Path, package: str = "ldaspark.core") -> set[str]:
    """The dotted modules a source file imports from (module level and inside functions)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            mod = ".".join(x for x in (base, node.module) if x)
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_numbers_is_the_lower_layer():
    mods = _imported_modules(CORE / "numbers.py")
    assert not mods & {"ldaspark.core.tableau", "ldaspark.core.tableau_file"}, mods
    # negative control: the scanner sees the loader's edge down to the tableau module
    assert "ldaspark.core.tableau" in _imported_modules(CORE / "tableau_file.py")
    assert "ldaspark.core.numbers" in _imported_modules(CORE / "tableau.py")
    # and at run time: importing numbers loads neither tableau module (a fresh interpreter)
    code = ("import sys, ldaspark.core.numbers; "
            "print(sorted(m for m in sys.modules if m.startswith('ldaspark.core.tableau')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def _old_path_imports(source: str, package: str) -> list[str]:
    """Moved names imported from ``ldaspark.core.tableau`` in ``source`` (a module of ``package``)."""
    moved = set(HOME)
    bad = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            base = package.rsplit(".", node.level - 1)[0] if node.level else ""
            mod = ".".join(x for x in (base, node.module) if x)
            if mod == "ldaspark.core.tableau":
                bad += [f"{a.name} (line {node.lineno})" for a in node.names if a.name in moved]
    return bad


def test_nothing_in_the_repository_imports_a_moved_name_by_its_old_path():
    bad = []
    for top in ("ldaspark", "tests", "verification", "benchmarks"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT)
            package = ".".join(rel.with_suffix("").parts[:-1])
            bad += [f"{rel}: {b}" for b in _old_path_imports(path.read_text(), package)]
    assert not bad, bad
    # negative controls: an absolute and a relative old-path import are both found
    assert _old_path_imports("from ldaspark.core.tableau import SparkTableau, load_tableau\n", "x") \
        == ["load_tableau (line 1)"]
    assert _old_path_imports("def f():\n    from ..core.tableau import parse_number\n", "ldaspark.models") \
        == ["parse_number (line 2)"]
