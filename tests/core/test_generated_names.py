"""No user text in generated source (``ldaspark.core.gensource``): an undefined function is refused
by name at set-up on every engine, a symbol's name never reaches the source (it is printed as
``_s<i>``), and a name that means something else (pi, E, I, sin, sqrt, mpf, ...) changes no number.
"""
from __future__ import annotations

import builtins
import keyword
import re
import sys

import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core import gensource
from ldaspark.core.backend import Backend
from ldaspark.core.errors import LdasparkError, SystemDefinitionError
from ldaspark.core.gensource import ExpressionTooLargeError, UndefinedFunctionError

#: names that are Python code (each would set a marker attribute on builtins if executed), keywords,
#: dunders, names with spaces, quotes, newlines, and unicode names
_MARK = "_LDASPARK_NAME_EXECUTED"
HOSTILE = [
    f"__import__('builtins').setattr(__import__('builtins'), '{_MARK}', 1) or (lambda *a: 0)",
    f"(setattr(__import__('builtins'), '{_MARK}', 2), 0)[1]",
    "lambda", "import", "def", "__class__", "__import__", "__builtins__",
    "a b", "a'b", 'a"b', "a\nb", "x0", "_s0", "ñu", "变量", "x)+(1",
]


def _marked() -> bool:
    return hasattr(builtins, _MARK)


@pytest.fixture(autouse=True)
def _no_marker():
    if _marked():
        delattr(builtins, _MARK)
    yield
    assert not _marked(), "a user name was executed"


@pytest.fixture
def sources(monkeypatch):
    """Every source gensource checks (all of lambdify's), recorded."""
    seen = []
    real = gensource.check_source

    def record(src, *a, **kw):
        seen.append(src)
        return real(src, *a, **kw)
    monkeypatch.setattr(gensource, "check_source", record)
    return seen


def _xy():
    return sympy.symbols("x y vx vy")


def test_the_attack_is_real_without_the_gate():
    """The control: sympy.lambdify prints an undefined function's name as code, which runs."""
    f = sympy.Function(HOSTILE[0])
    x = sympy.Symbol("x")
    g = sympy.lambdify([x], [f(x)], modules="math")
    g(1.0)
    assert _marked()
    delattr(builtins, _MARK)


@pytest.mark.parametrize("where", ["L", "k", "nonideal", "mechanical"])
@pytest.mark.parametrize("name", HOSTILE + ["f"])
def test_an_undefined_function_is_refused_by_name_at_set_up(where, name):
    x, y, vx, vy = _xy()
    t = sympy.Symbol("t")
    f = sympy.Function(name)
    L = (vx ** 2 + vy ** 2) / 2 - x ** 2 / 2
    k = [vy - x * vx]
    kw = {}
    if where == "L":
        L = L + f(t)               # of t only: no derivative would mention it
    elif where == "k":
        k = [vy - x * vx + f(t) * 0 + f(t) - f(t) + f(t)]
    elif where == "nonideal":
        kw["nonideal"] = [f(t), 0]
    else:
        kw["mechanical"] = {"M": sympy.eye(2), "U": x ** 2 / 2 + f(x), "K": sympy.Matrix([[-x, 1]])}
    with pytest.raises(UndefinedFunctionError) as err:
        ldaspark.LagrangianSystem(L, k, [x, y], [vx, vy], **kw)
    msg = str(err.value)
    assert "\n" not in msg and "undefined function" in msg
    shown = name if name.isidentifier() and name.isascii() else repr(name[:60])
    assert shown in msg


def _hostile_system(name, pname):
    """A system whose coordinate x, parameter and nonideal term carry hostile names."""
    x = sympy.Symbol(name)
    y, vx, vy = sympy.symbols("y vx vy")
    c = sympy.Symbol(pname)
    L = (vx ** 2 + vy ** 2) / 2 - c * x ** 2 / 2
    return ldaspark.LagrangianSystem(L, [vy - x * vx], [x, y], [vx, vy], params={c: 2.0},
                                     nonideal=[-c * vx / 10, 0]), [x, y, vx, vy, c]


@pytest.mark.parametrize("engine, dps", [("generic", None), ("generic", 30), ("auto", None)])
def test_hostile_symbol_names_never_reach_the_source(engine, dps, sources):
    names = HOSTILE if (engine, dps) == ("generic", None) else [HOSTILE[0], "lambda", "a\nb", "_s0", "x0"]
    ref = None
    for i, nm in enumerate(names + ["x"]):
        S, syms = _hostile_system(nm, names[(i + 1) % len(names)] if nm != "x" else "c")
        r = ldaspark.integrate(S, "gauss-2", t_span=(0, 0.2), q0=[0.3, 0], v0=[0.1, 0.03], h=0.05,
                               engine=engine, dps=dps, project=True)
        assert r.status == 0
        q = np.asarray(r.q, dtype=float)
        if ref is None:
            ref = q
        # the same model under other names: the same numbers (only the names differ in the source)
        assert np.abs(q - ref).max() <= 1e-13 * (1 + np.abs(ref).max())
    assert sources, "gensource saw no source"
    for src in sources:
        words = set(re.findall(r"[^\W\d]\w*", src, re.UNICODE))
        for nm in names:
            if nm in ("_s0", "x0") or (keyword.iskeyword(nm) and nm != "lambda"):
                continue            # generated names and the source's own keywords (def, import) are ours
            assert (nm not in words) if nm.isidentifier() else (nm not in src), nm
        assert "lambda" not in words and "__import__" not in src


def test_hostile_names_on_the_compiled_engine(tmp_path, monkeypatch):
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path))
    from ldaspark.compiled import codegen
    S, _ = _hostile_system(HOSTILE[0], "lambda")
    src = codegen.general_source(S)
    assert HOSTILE[0] not in src and "lambda" not in src
    r = ldaspark.integrate(S, "gauss-2", t_span=(0, 0.2), q0=[0.3, 0], v0=[0.1, 0.03], h=0.05, engine="compiled")
    g = ldaspark.integrate(S, "gauss-2", t_span=(0, 0.2), q0=[0.3, 0], v0=[0.1, 0.03], h=0.05, engine="generic")
    assert r.engine == "compiled" and r.status == 0
    assert np.abs(np.asarray(r.q) - np.asarray(g.q)).max() <= 1e-12


def test_check_source_refuses_what_the_library_did_not_generate():
    ok = "def _lambdifygenerated(_s0, _s1):\n    x0 = sin(_s0)\n    return [x0 + _s1, abs(x0), float('nan')]\n"
    gensource.check_source(ok, {"sin": 0})
    for bad in ["def _lambdifygenerated(_s0):\n    return __import__('os')\n",
                "def _lambdifygenerated(_s0):\n    return evil(_s0)\n",
                "def _lambdifygenerated(_s0):\n    return sin('x')\n"]:
        with pytest.raises(gensource.GeneratedSourceError):
            gensource.check_source(bad, {"sin": 0})


def test_a_user_function_class_named_like_a_supported_one_is_refused():
    class sin(sympy.Function):       # noqa: N801 - the point: its name is "sin", it is not sympy.sin
        def _pythoncode(self, printer):
            return f"__import__('builtins').setattr(__import__('builtins'), '{_MARK}', 3)"
    x, y, vx, vy = _xy()
    with pytest.raises(SystemDefinitionError, match="contains the function sin"):
        ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - sin(x), [vy - x * vx], [x, y], [vx, vy])
    # the real sin passes
    ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - sympy.sin(x), [vy - x * vx], [x, y], [vx, vy])


# --- class 2: a name that means something else ------------------------------------------------
def _namespace_names() -> list[str]:
    """Every public name of mpmath and sympy (constants and functions), identifiers, sorted."""
    names = {n for n in dir(mpmath) + dir(sympy) + dir(builtins) + dir(sys.modules["math"])
             if n.isidentifier() and not n.startswith("_")}
    return sorted(names)


_KEY_NAMES = ["pi", "e", "E", "I", "oo", "sin", "sqrt", "exp", "cos", "mpf", "inf", "nan", "j", "math",
              "mpmath", "DiracDelta", "Heaviside", "range", "builtins", "abs", "x0", "x1"]


def _model(names):
    """A skate-like system (n = 2, m = 1) whose t, q, v and 6 parameters carry ``names`` (10),
    using pi, E, sin, cos, exp, sqrt, log: a shadowed constant or function changes its numbers."""
    t, q0, q1, v0, v1, *p = (sympy.Symbol(nm) for nm in names)
    L = (v0 ** 2 + (1 + p[0] / 10) * v1 ** 2) / 2 - p[1] * q0 ** 2 / 2 - sympy.pi * p[2] * sympy.cos(q1) / 10 \
        + sympy.E * p[3] * sympy.exp(-q0 ** 2) / 10 + sympy.sqrt(p[4]) * sympy.sin(q0 * q1) / 10 \
        - p[5] * sympy.log(2 + q1) * sympy.cos(t) / 50
    k = [v1 - q0 * v0 - p[0] * sympy.sin(t) / 10]
    vals = {s: sympy.Rational(i + 2, 7) for i, s in enumerate(p)}
    return ldaspark.LagrangianSystem(L, k, [q0, q1], [v0, v1], t=t, params=vals), (t, q0, q1, v0, v1)


_PLAIN = ["t", "q0", "q1", "v0", "v1", "c0", "c1", "c2", "c3", "c4", "c5"]


def _batches(names, size=11):
    return [names[i:i + size] for i in range(0, len(names) - size + 1, size)]


def _run_all(names):
    S, _ = _model(names)
    kw = dict(t_span=(0, 0.1), q0=[0.3, 0.2], v0=[0.1, 0.03 + 0.3 * 0.1 + (2 / 7) * 0], h=0.05, project=True)
    out = {"generic": np.asarray(ldaspark.integrate(S, "gauss-2", engine="generic", **kw).q, dtype=float),
           "dps": np.asarray(ldaspark.integrate(S, "gauss-2", engine="generic", dps=30, **kw).q, dtype=float)}
    for dps in (None, 30):
        bk = Backend(dps)
        with bk.context():
            St = S.with_params()
            e = St.energy(bk, bk.scalar(0.05), bk.array([0.3, 0.2]), bk.array([0.1, 0.4]))
            kk = St.constraint(bk, bk.scalar(0.05), bk.array([0.3, 0.2]), bk.array([0.1, 0.4]))
        out[f"E{dps}"] = float(e)
        out[f"k{dps}"] = np.asarray(kk, dtype=float)
    return out


def _compare(a, b):
    for key in a:
        x, y = np.asarray(a[key], float), np.asarray(b[key], float)
        # the same expressions under other names: sums may be printed in another order (the
        # stored order follows the names), a few ulps of the values' size
        assert np.abs(x - y).max() <= 1e-13 * (1 + np.abs(y).max()), key


def test_names_that_mean_something_else_change_no_number():
    ref = _run_all(_PLAIN)
    for batch in _batches(_KEY_NAMES):
        _compare(_run_all(batch), ref)


def test_the_named_constants_model_matches_the_compiled_engine(tmp_path, monkeypatch):
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path))
    S, _ = _model(_KEY_NAMES[:11])
    kw = dict(t_span=(0, 0.1), q0=[0.3, 0.2], v0=[0.1, 0.1], h=0.05, project=True)
    g = ldaspark.integrate(S, "gauss-2", engine="generic", **kw)
    c = ldaspark.integrate(S, "gauss-2", engine="compiled", **kw)
    assert c.engine == "compiled"
    assert np.abs(np.asarray(g.q) - np.asarray(c.q)).max() <= 1e-12


@pytest.mark.exhaustive
def test_every_mpmath_and_sympy_name_changes_no_number():
    ref = _run_all(_PLAIN)
    for batch in _batches(_namespace_names()):
        _compare(_run_all(batch), ref)


def test_the_namespace_name_batches_are_not_empty():
    names = _namespace_names()
    assert {"pi", "E", "I", "oo", "sin", "mpf", "sqrt"} <= set(names) and len(_batches(names)) > 50
    assert not any(keyword.iskeyword(n) for n in _KEY_NAMES)


# --- class 7: nonsmooth functions and deep expressions ----------------------------------------
@pytest.mark.parametrize("dps", [None, 30])
def test_sign_and_heaviside_in_a_load_run_with_their_derivative_zero_off_the_jump(dps):
    """N = -mu sign(vx) (Coulomb-like) and Heaviside(vx): on a run where vx > 0 throughout they
    are the constants -mu and 1, and the results equal those of that smooth model."""
    x, y, vx, vy = _xy()
    L = (vx ** 2 + vy ** 2) / 2 - x ** 2 / 2
    k = [vy - x * vx]
    kw = dict(t_span=(0, 0.1), q0=[0.1, 0], v0=[1.0, 0.1], h=0.02, engine="generic", dps=dps)
    rough = ldaspark.LagrangianSystem(L, k, [x, y], [vx, vy],
                                      nonideal=[-sympy.sign(vx) / 10 + sympy.Heaviside(vx) / 20, sympy.Max(vx, 0) / 30])
    smooth = ldaspark.LagrangianSystem(L, k, [x, y], [vx, vy], nonideal=[-sympy.S(1) / 10 + sympy.S(1) / 20, vx / 30])
    a, b = ldaspark.integrate(rough, "gauss-2", **kw), ldaspark.integrate(smooth, "gauss-2", **kw)
    assert a.status == 0 and b.status == 0
    qa, qb = np.asarray(a.q, float), np.asarray(b.q, float)
    assert np.abs(qa - qb).max() <= 1e-13
    # the control: the load acts (without it the path differs)
    free = ldaspark.LagrangianSystem(L, k, [x, y], [vx, vy])
    assert np.abs(np.asarray(ldaspark.integrate(free, "gauss-2", **kw).q, float) - qa).max() > 1e-5


def test_a_force_nested_400_deep_is_refused_at_set_up_naming_the_limit():
    x, y, vx, vy = _xy()
    F = x
    for i in range(400):
        F = sympy.sin(F) if i % 2 else (1 + F) * x
    with pytest.raises(ExpressionTooLargeError, match=r"nested more than 120 levels .*MAX_DEPTH"):
        ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2, [vy - x * vx], [x, y], [vx, vy], nonideal=[F, 0])
    # below the limit it is accepted (the bound is the depth, not the kind of node)
    G = x
    for i in range(40):
        G = sympy.sin(G) if i % 2 else (1 + G) * x / 2
    ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2, [vy - x * vx], [x, y], [vx, vy], nonideal=[G, 0])


def test_a_sum_beyond_the_compiler_is_rebalanced_not_a_recursion_error():
    xs = sympy.symbols("a0:7")
    terms = [sympy.Rational(i % 13 + 1, 7) * xs[i % 7] * xs[(i + 3) % 7] ** (i % 3) for i in range(4000)]
    e = sympy.Add(*terms, evaluate=False)
    old = sys.getrecursionlimit()
    try:
        sys.setrecursionlimit(400)      # the control: the chain as printed is beyond the compiler here
        src = "def f(a):\n    return " + " + ".join(f"a*{i}" for i in range(4000)) + "\n"
        with pytest.raises(RecursionError):
            compile(src, "<x>", "exec")
        f = gensource.lambdify(list(xs), [e], "math", cse=False)
    finally:
        sys.setrecursionlimit(old)
    pt = [0.1 * (i + 1) for i in range(7)]
    ref = float(e.subs(dict(zip(xs, pt))))
    assert abs(f(*pt)[0] - ref) <= 1e-12 * abs(ref)


def test_every_refusal_is_one_line_and_an_ldaspark_error():
    x, y, vx, vy = _xy()
    for bad in [sympy.Function("g")(x), sympy.zeta(x), sympy.Integral(x, x), sympy.floor(x)]:
        with pytest.raises(LdasparkError) as err:
            ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 + bad, [vy - x * vx], [x, y], [vx, vy])
        assert "\n" not in str(err.value) and re.search(r"L contains", str(err.value))


def test_nonsmooth_loads_through_from_mechanics_run_on_the_generic_engine():
    """A load -sign(u)/5 (was NameError: DiracDelta at integrate) equals -Heaviside(u)/5 and the
    constant -1/5 while u > 0; -Piecewise((u, u > 0), (0, True))/5 equals -Max(u, 0)/5."""
    import sympy.physics.mechanics as me

    def run(force, dps=None):
        q1, q2 = me.dynamicsymbols("q1 q2")
        u1, u2 = me.dynamicsymbols("u1 u2")
        N = me.ReferenceFrame("N")
        O = me.Point("O")
        O.set_vel(N, 0)
        P = O.locatenew("P", q1 * N.x + q2 * N.y)
        P.set_vel(N, u1 * N.x + u2 * N.y)
        KM = me.KanesMethod(N, [q1, q2], [u1], kd_eqs=[q1.diff() - u1, q2.diff() - u2],
                            u_dependent=[u2], velocity_constraints=[u2 - q1 * u1])
        KM.kanes_equations([me.Particle("pa", P, 1)], [(P, force(u1) * N.x)])
        S = ldaspark.LagrangianSystem.from_mechanics(KM)
        r = ldaspark.integrate(S, "gauss-2", (0, 0.2), [0.1, 0], [1.0, 0.1], h=0.05, engine="generic", dps=dps)
        assert r.status == 0
        return np.asarray(r.q, float)

    const = run(lambda u: -sympy.S(1) / 5)
    for f in (lambda u: -sympy.sign(u) / 5, lambda u: -sympy.Heaviside(u) / 5):
        assert np.abs(run(f) - const).max() <= 1e-14
    assert np.abs(run(lambda u: -sympy.sign(u) / 5, dps=30) - const).max() <= 1e-14
    ramp = run(lambda u: -sympy.Max(u, 0) / 5)
    assert np.abs(run(lambda u: -sympy.Piecewise((u, u > 0), (0, True)) / 5) - ramp).max() <= 1e-14
    assert np.abs(ramp - const).max() > 1e-5           # the control: the two loads differ (8e-5 here)


def test_the_model_module_is_checked_generated_or_read_back(tmp_path, monkeypatch):
    """codegen's model source passes the same identifier check (``codegen._checked_model``) when it
    is generated and when it is read back from the cache; a source holding anything else is refused."""
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path))
    from ldaspark.compiled import cache, codegen
    S, _ = _hostile_system("x", "c")
    src = codegen.general_source(S)
    assert codegen._checked_model(src) == src
    key = codegen.model_key(S, "general")
    assert "_q0" in src and "_v0" in src
    for bad in (src.replace("_v0", "__import__", 1), src + "\nopen('x', 'w')\n", src.replace("_q0", "x", 1)):
        with pytest.raises(codegen.NotCompilableError, match="the model module"):
            codegen._checked_model(bad)
    # a tampered source under the key (as if read back): refused before anything runs, and the
    # model generated again (tests/compiled/test_content_key.py: the record is replaced)
    monkeypatch.setattr(codegen, "_SOURCES", {})
    monkeypatch.setattr(cache, "stored_source", lambda k: src + "\nopen('x', 'w')\n" if k == key else None)
    monkeypatch.setattr(cache, "store_source", lambda k, s: None)
    assert codegen.general_source(S) == src


class _SelfPrinting(sympy.core.numbers.NumberSymbol):
    """A constant whose own printer hooks return source text (as sympy lets any class do)."""
    is_real = is_positive = is_irrational = is_number = True
    __slots__ = ()

    def _as_mpf_val(self, prec):
        return mpmath.mpf(9.81)._mpf_

    def _pythoncode(self, printer, *args, **kw):
        return "0\nbuiltins.abs = builtins.float\ndef _x99():\n    return 0"
    _numpycode = _mpmathcode = _lambdacode = _pythoncode


def test_a_node_class_defined_outside_sympy_never_prints_into_the_source():
    """sympy's printers call a node's own _pythoncode before _print_Symbol: a NumberSymbol subclass
    put statements into the compiled ODE module (not checked) and the generic engine's function
    (builtins.abs replaced process-wide). Refused at set-up now, by class; the generated source is
    ASCII and one function definition of name-only assignments (U+FE33 folded by the compiler into
    "_" passed the token check). Control: sympy's own NumberSymbols (pi, E) run."""
    a, b, va, vb = sympy.symbols("a b va vb")
    with pytest.raises(SystemDefinitionError, match="outside sympy"):
        ldaspark.LagrangianSystem((va**2 + vb**2) / 2 - _SelfPrinting() * sympy.cos(a), [vb - a * va], [a, b],
                                  [va, vb])
    assert abs(-5) == 5
    ok = ldaspark.LagrangianSystem((va**2 + vb**2) / 2 - sympy.pi * sympy.cos(a) / sympy.E, [vb - a * va], [a, b],
                                   [va, vb])
    assert ldaspark.integrate(ok, "gauss-2", n_steps=2, h=0.1, q0=[0.1, 0], v0=[0, 0], engine="generic").status == 0
    from sympy.utilities.lambdify import _get_namespace
    with pytest.raises(gensource.GeneratedSourceError, match="outside ASCII"):
        gensource.check_source("def _lambdifygenerated(_s0):\n    return e\ufe33\ufe33(_s0)\n", _get_namespace("math"))
    for src in ("def _lambdifygenerated(_s0):\n    builtins.abs = builtins.float\n    return 0\n",
                "x0 = 1\ndef _lambdifygenerated(_s0):\n    return 0\n",
                "def _lambdifygenerated(_s0):\n    import os\n    return 0\n"):
        with pytest.raises(gensource.GeneratedSourceError):
            gensource._one_function(src)
    gensource._one_function("def _lambdifygenerated(_s0):\n    x0 = _s0\n    return builtins.float('nan') + x0\n")


def test_an_expression_whose_tree_is_exponential_in_its_graph_is_refused_at_set_up():
    """e = sin(e) + cos(e) twenty times: 41 distinct nodes, 2e6 written out, which sympy's
    free_symbols, the derivatives and the printers walk (LagrangianSystem took 65 s, the first
    step minutes). Refused at set-up by its tree size, counted on the graph; control: eight times
    (1021 nodes) runs."""
    a, b, va, vb = sympy.symbols("a b va vb")

    def nested(k):
        e = a
        for _ in range(k):
            e = sympy.sin(e) + sympy.cos(e)
        return e
    assert gensource.tree_nodes(nested(20), gensource.MAX_TREE_NODES) > gensource.MAX_TREE_NODES
    with pytest.raises(ExpressionTooLargeError, match="nodes written out"):
        ldaspark.LagrangianSystem((va**2 + vb**2) / 2 - nested(20) / 10**20, [vb - a * va], [a, b], [va, vb])
    assert gensource.tree_nodes(nested(8), 10**9) == 1021      # 2^(k+2) - 3
    ok = ldaspark.LagrangianSystem((va**2 + vb**2) / 2 - nested(8) / 10**8, [vb - a * va], [a, b], [va, vb])
    assert ldaspark.integrate(ok, "gauss-2", n_steps=2, h=0.01, q0=[0.1, 0], v0=[0.1, 0.01],
                              engine="generic").status == 0
