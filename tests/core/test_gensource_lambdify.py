"""``ldaspark.core.gensource.lambdify`` keeps the shape of what it is given, as
``sympy.lambdify``: a single expression gives a function returning a number, a list a list
(cse with ``list=False``: with ``list=True`` the single expression came back as a list of one)."""
from __future__ import annotations

import math

import sympy

from ldaspark.core import gensource

x, y = sympy.symbols("x y")


def test_a_single_expression_gives_a_number_and_a_list_a_list():
    e = sympy.sin(x) + sympy.sin(x) ** 2 * y          # a common subexpression for cse
    want = math.sin(0.3) + math.sin(0.3) ** 2 * 0.7
    for module in ("math", "mpmath"):
        one = gensource.lambdify([x, y], e, module)(0.3, 0.7)
        assert not isinstance(one, (list, tuple)) and abs(float(one) - want) <= 1e-15, (module, one)
        many = gensource.lambdify([x, y], [e, sympy.sin(x)], module)(0.3, 0.7)
        assert isinstance(many, list) and len(many) == 2 and abs(float(many[0]) - want) <= 1e-15
    # without cse too
    assert abs(float(gensource.lambdify([x, y], e, "math", cse=False)(0.3, 0.7)) - want) <= 1e-15
