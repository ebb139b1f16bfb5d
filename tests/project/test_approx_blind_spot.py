"""A comparison that cannot fail is a defect: ``pytest.approx(x)`` allows an absolute error of
1e-12 by default, so for an expected value below ~1e-10 it accepts numbers off by more than 1%
(for 1e-26, anything in [-1e-12, 1e-12], zero included). Every such comparison in the suite states
its absolute tolerance (``abs=0`` for a relative check)."""
from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[2]
#: below this magnitude the default absolute tolerance (1e-12) exceeds 1% of the value
SMALL = 1e-10


def _literal(node):
    """The value of a constant numeric expression (1e3 * 2.0 ** -52, [1e-20, 2e-3]), else None."""
    try:
        return ast.literal_eval(node)
    except ValueError:
        pass
    if isinstance(node, ast.BinOp):
        a, b = _literal(node.left), _literal(node.right)
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            try:
                return {ast.Mult: lambda: a * b, ast.Div: lambda: a / b, ast.Pow: lambda: a ** b,
                        ast.Add: lambda: a + b, ast.Sub: lambda: a - b}[type(node.op)]()
            except (KeyError, ZeroDivisionError, OverflowError):
                return None
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        v = _literal(node.operand)
        return -v if isinstance(v, (int, float)) else None
    return None


def blind_comparisons(text: str) -> list[int]:
    """Lines of ``pytest.approx(x)`` calls with a literal expected value 0 < |x| < SMALL and no abs=."""
    out = []
    for node in ast.walk(ast.parse(text)):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "approx"
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "pytest" and node.args):
            continue
        if any(k.arg == "abs" for k in node.keywords):
            continue
        v = _literal(node.args[0])
        vals = v if isinstance(v, (list, tuple)) else [v]
        if any(isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < abs(x) < SMALL for x in vals):
            out.append(node.lineno)
    return out


def test_the_scan_sees_a_blind_comparison_and_passes_a_stated_one():
    assert blind_comparisons("import pytest\nassert f() == pytest.approx(1e3 * 1e-30 * 10)\n") == [2]
    assert blind_comparisons("assert f() == pytest.approx([1e-20, 2e-3])\n") == [1]
    assert blind_comparisons("assert f() == pytest.approx(-1e-15, rel=1e-9)\n") == [1]
    assert blind_comparisons("assert f() == pytest.approx(1e-26, rel=1e-12, abs=0)\n") == []
    assert blind_comparisons("assert f() == pytest.approx(2e-3)\nassert g() == pytest.approx(0.0)\n") == []


def test_no_comparison_in_the_suite_is_blind_below_1e_10():
    bad = [f"{p.relative_to(ROOT)}:{ln}" for d in ("tests", "verification") for p in sorted((ROOT / d).glob("*.py"))
           for ln in blind_comparisons(p.read_text())]
    assert not bad, "pytest.approx of a tiny value without abs= (accepts anything within 1e-12): " + ", ".join(bad)
