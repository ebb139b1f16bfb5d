"""The Python form of a generated model (``native.python_module``, used by the set-up checks)
compiles at any size: long sums and products are rebalanced, not nested n deep (CPython's
compiler refused a 1001-coordinate model with a RecursionError from ``ldaspark.integrate``)."""
from __future__ import annotations

import ast
import math
import sys

import numpy as np
import pytest

from ldaspark.compiled import native
from ldaspark.core import gensource


def _source(n_terms: int) -> str:
    signs = ["+" if i % 3 else "-" for i in range(n_terms)]
    body = "x[0]" + "".join(f" {sg} {i + 1}.0*x[{i % 7}]*x[{(i + 1) % 7}]" for i, sg in enumerate(signs))
    prod = " * ".join(f"(1.0 + x[{i % 7}]/{1000 + i})" for i in range(n_terms))
    return f"def s(x):\n    return {body}\n\ndef p(x):\n    return {prod}\n"


def test_a_sum_and_a_product_of_2000_terms_compile_and_keep_their_value():
    N = 2000
    src = _source(N)
    tree, balanced = ast.parse(src), ast.fix_missing_locations(gensource.BalancedSums().visit(ast.parse(src)))
    old = sys.getrecursionlimit()
    try:
        # CPython's compiler allows a nesting of a few times the recursion limit, minus the frames
        # in use: deep inside integrate the 1001-coordinate model's sums were beyond it
        sys.setrecursionlimit(500)
        with pytest.raises(RecursionError):      # the control: the chain as printed
            compile(tree, "<model>", "exec")
        compile(balanced, "<model>", "exec")
    finally:
        sys.setrecursionlimit(old)
    mod = native.python_module(src)
    x = np.linspace(0.1, 0.7, 7)
    signs = [1.0 if i % 3 else -1.0 for i in range(N)]
    ref_s = math.fsum([x[0]] + [sg * (i + 1) * x[i % 7] * x[(i + 1) % 7] for i, sg in enumerate(signs)])
    ref_p = math.prod(1.0 + x[i % 7] / (1000 + i) for i in range(N))
    # a different order of 2000 additions of terms up to ~1e3: a few hundred ulps of the sum's scale
    scale = math.fsum(abs((i + 1) * x[i % 7] * x[(i + 1) % 7]) for i in range(N))
    assert abs(mod.s(x) - ref_s) <= 1e-12 * scale
    assert abs(mod.p(x) - ref_p) <= 1e-12 * abs(ref_p)
    assert abs(ref_s) > 1.0 and abs(mod.s(x) - ref_s) < 1e-6 * abs(ref_s)    # the signs were kept


def test_short_chains_are_left_as_printed():
    src = "def f(x):\n    return x[0] + x[1] - x[2] * x[3]\n"
    tree = gensource.BalancedSums().visit(ast.parse(src))
    assert ast.unparse(tree).strip().endswith("return x[0] + x[1] - x[2] * x[3]")


def test_a_source_beyond_the_parser_is_one_error_not_a_crash():
    with pytest.raises(native.NotNativeError, match="does not parse"):
        native.python_module(_source(8000))


@pytest.mark.exhaustive
def test_integrate_runs_a_new_1001_coordinate_system_on_the_compiled_engine(tmp_path, monkeypatch):
    """The user's path (LagrangianSystem, then ldaspark.integrate) at n = 1001: was a raw
    RecursionError from the set-up checks' Python form of the model."""
    import sympy

    import ldaspark
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path))
    n = 1001
    m = (n - 1) // 2
    q, v = list(sympy.symbols(f"q0:{n}")), list(sympy.symbols(f"v0:{n}"))
    U = (sum(x ** 2 for x in q) + q[m + 1] ** 2 * q[m + 2] ** 2 + sum(q[i] ** 2 * q[m + i] ** 2 for i in range(1, m + 1))) / 2
    L = sum(x ** 2 for x in v) / 2 - U
    k = [v[0] + sum(q[i - 1 - m] * v[i - 1] for i in range(m + 2, n + 1))]
    q0 = [1.0] + [2 * (m - i) / 10 for i in range(m)] + [1.0] * m
    r = ldaspark.integrate(ldaspark.LagrangianSystem(L, k, q, v, name="mp-1001"), "gauss-2", t_span=(0, 0.002),
                           q0=q0, v0=[0.0] * n, h=0.001)
    assert r.engine == "compiled" and r.status == 0 and np.isfinite(r.q).all()
