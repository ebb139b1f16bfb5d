"""The compiled model cache is keyed by the model's content (``codegen.model_key``), not by the
system's name: two systems with the same expressions (other names, other symbol names) share
one generated source and one compiled module, generated and compiled once, also across
processes; systems with different content never share one (the negative control); a stored
source is used only if its bytes are the recorded ones."""
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy

from ldaspark.compiled import cache, codegen, fast
from ldaspark.core.system import LagrangianSystem

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
x, y, z, vx, vy, vz = sympy.symbols("x y z vx vy vz")
L0 = (vx ** 2 + vy ** 2 + vz ** 2) / 2 - x ** 2 / 2 - sympy.cos(y) / 3
K0 = [vz - x * vy]


@pytest.fixture
def cdir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    monkeypatch.setenv("LDASPARK_NATIVE", "0")      # numba's path: the one that stores a module on disk
    monkeypatch.setattr(codegen, "_SOURCES", {})
    return d


def _count_generation(monkeypatch):
    calls = []
    for fn in ("_general_source", "_mechanical_source"):
        orig = getattr(codegen, fn)
        monkeypatch.setattr(codegen, fn, lambda *a, _o=orig, _f=fn: (calls.append(_f), _o(*a))[1])
    return calls


def _models(d):
    return sorted(n for n in os.listdir(d) if n.startswith("ldaspark_model_") and n.endswith(".py"))


def _sources(d):
    pyc = d / "__pycache__"
    return sorted(n for n in os.listdir(pyc) if n.startswith("ldaspark_sources.")) if pyc.is_dir() else []


def test_same_content_other_names_share_one_entry(cdir, monkeypatch):
    calls = _count_generation(monkeypatch)
    a = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz], name="first")
    b = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz], name="a renamed copy")
    ren = dict(zip([x, y, z, vx, vy, vz], sympy.symbols("p0 p1 p2 w0 w1 w2")))
    c = LagrangianSystem(L0.xreplace(ren), [e.xreplace(ren) for e in K0], [ren[s] for s in (x, y, z)],
                         [ren[s] for s in (vx, vy, vz)], name="other symbols")
    runs = []
    for s in (a, b, c):
        cs = fast.compile_system(s, form="general")
        runs.append(fast.run_compiled(cs, "gauss-2", 0.0, [0.1, 0.2, 0.0], [0.0, 0.1, 0.0], 0.05, 4))
    assert calls == ["_general_source"]                     # generated once
    assert len(_models(cdir)) == 1 and len(_sources(cdir)) == 1
    assert codegen.model_key(a, "general") == codegen.model_key(b, "general") == codegen.model_key(c, "general")
    for r in runs[1:]:
        assert np.array_equal(r.q, runs[0].q) and np.array_equal(r.v, runs[0].v)


def test_native_models_of_same_content_share_one_compilation(cdir, monkeypatch):
    """The default path (native model code): a renamed copy is generated and compiled once."""
    monkeypatch.setenv("LDASPARK_NATIVE", "1")
    from ldaspark.compiled import native, runner
    calls = _count_generation(monkeypatch)
    compiled = []
    monkeypatch.setattr(native, "compile_model", lambda *a, _o=native.compile_model: (compiled.append(1), _o(*a))[1])
    monkeypatch.setattr(runner, "_MODELS", {})
    L1 = L0 + x ** 4 / 7                                     # content no other test of this process compiles
    a = LagrangianSystem(L1, K0, [x, y, z], [vx, vy, vz], name="first")
    b = LagrangianSystem(L1, K0, [x, y, z], [vx, vy, vz], name="a renamed copy")
    runs = []
    for s in (a, b):
        cs = fast.compile_system(s, form="general")
        runs.append(fast.run_compiled(cs, "gauss-2", 0.0, [0.1, 0.2, 0.0], [0.0, 0.1, 0.0], 0.05, 4))
        assert cs.is_native
    assert calls == ["_general_source"] and compiled == [1]
    assert np.array_equal(runs[1].q, runs[0].q)


def test_different_content_never_shares_an_entry(cdir, monkeypatch):
    """Negative control: a changed coefficient, a changed constraint, a symbol with an assumption,
    another form of the same system: each its own key, source and module."""
    calls = _count_generation(monkeypatch)
    Q, V = [x, y, z], [vx, vy, vz]
    xr = sympy.Symbol("x", positive=True)
    systems = [LagrangianSystem(L0, K0, Q, V),
               LagrangianSystem(L0 + x ** 4 / 1000, K0, Q, V),
               LagrangianSystem(L0, [vz - x * vy - vx / 7], Q, V),
               LagrangianSystem(L0.subs(x, xr), [K0[0].subs(x, xr)], [xr, y, z], V)]
    keys = {codegen.model_key(s, "general") for s in systems}
    assert len(keys) == len(systems)
    srcs = {codegen.general_source(s) for s in systems}
    assert calls == ["_general_source"] * len(systems)
    assert len(srcs) >= 3            # (the positive x may print the same code: its own entry all the same)
    assert len(_sources(cdir)) == len(systems)
    mech = LagrangianSystem(L0, K0, Q, V, mechanical={"M": sympy.eye(3), "U": x ** 2 / 2 + sympy.cos(y) / 3,
                                                       "K": sympy.Matrix([[0, -x, 1]]), "b": None})
    assert codegen.model_key(mech, "mechanical", fast.mechanical_parts(mech)) not in keys
    assert codegen.model_key(mech, "general") not in keys          # its mechanical parts are part of the content


def test_a_new_process_serves_the_stored_source(cdir, monkeypatch):
    a = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz], name="a")
    src = codegen.general_source(a)
    code = ("import sympy\nfrom ldaspark.compiled import codegen\nfrom ldaspark.core.system import LagrangianSystem\n"
            "x, y, z, vx, vy, vz = sympy.symbols('x y z vx vy vz')\n"
            "s = LagrangianSystem((vx**2 + vy**2 + vz**2)/2 - x**2/2 - sympy.cos(y)/3, [vz - x*vy], [x, y, z],"
            " [vx, vy, vz], name='renamed')\n"
            "def refuse(*a): raise SystemExit('generated again')\n"
            "codegen._general_source = refuse\n"
            "print(len(codegen.general_source(s)))\n")
    env = dict(os.environ, PYTHONPATH=REPO, LDASPARK_CACHE_DIR=str(cdir))
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-500:]
    assert p.stdout.strip() == str(len(src))


def test_a_stored_source_is_used_only_as_recorded(cdir, monkeypatch):
    """A source file changed on disk (or planted under a key never recorded) is not returned and is
    deleted: the model is generated again, never loaded from what is there."""
    a = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz])
    key = codegen.model_key(a, "general")
    src = codegen.general_source(a)
    assert cache.stored_source(key) == src
    path = cdir / "__pycache__" / f"ldaspark_sources.{key}.py"
    path.write_text(src + "\nimport os  # planted\n")
    assert cache.stored_source(key) is None and not path.exists()
    other = "0" * 64
    (cdir / "__pycache__" / f"ldaspark_sources.{other}.py").write_text("raise SystemExit('planted')\n")
    assert cache.stored_source(other) is None
    assert cache.stored_source("../../etc/passwd") is None
    calls = _count_generation(monkeypatch)
    monkeypatch.setattr(codegen, "_SOURCES", {})
    assert codegen.general_source(a) == src and calls == ["_general_source"]
    assert cache.stored_source(key) == src                  # recorded again


def test_a_recorded_source_the_checks_refuse_is_generated_again(cdir, monkeypatch):
    """A stored source, recorded by this user, that this version's source check refuses (written by
    a version whose ``gensource.check_source`` was laxer: the checker is not in the key) made every
    later compilation of that model fail ("the model module: ...") until the cache was cleared.
    Now it is generated again and the record replaced; control: a recorded source that passes is
    served without generating."""
    a = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz])
    key = codegen.model_key(a, "general")
    src = codegen.general_source(a)
    cache.store_source(key, src.replace("N_CON = 1\n", "N_CON = 1\nUNKNOWN_NAME = 0\n", 1))
    assert "UNKNOWN_NAME" in cache.stored_source(key)              # recorded: the store serves it
    calls = _count_generation(monkeypatch)
    monkeypatch.setattr(codegen, "_SOURCES", {})
    assert codegen.general_source(a) == src and calls == ["_general_source"]
    assert cache.stored_source(key) == src
    monkeypatch.setattr(codegen, "_SOURCES", {})
    assert codegen.general_source(a) == src and calls == ["_general_source"]     # served, not generated


def test_the_generated_module_carries_no_name():
    a = LagrangianSystem(L0, K0, [x, y, z], [vx, vy, vz], name="a very particular name")
    src = codegen.general_source(a)
    assert "particular" not in src
    head = codegen.header(None, "general", 3, 1)
    compile(head, "h", "exec")
    assert head.count('"""') == 2 and "system" not in head.splitlines()[0]


def test_key_ignores_the_order_sympy_gives_renamed_terms():
    """Names whose sort order is reversed make sympy order the terms of L and k differently; the
    key hashes a sum's terms as a multiset, so the renamed copy still shares it."""
    Q, V = [x, y, z], [vx, vy, vz]
    ren = dict(zip(Q + V, sympy.symbols("z9 y9 x9 c b a")))
    a = LagrangianSystem(L0, K0, Q, V)
    b = LagrangianSystem(L0.xreplace(ren), [e.xreplace(ren) for e in K0], [ren[s] for s in Q], [ren[s] for s in V])
    assert [str(t) for t in sympy.Add.make_args(b.L)] != [str(t.xreplace(ren)) for t in sympy.Add.make_args(a.L)]
    assert codegen.model_key(a, "general") == codegen.model_key(b, "general")


def test_key_sees_every_digit_and_the_kind_of_a_number():
    """Negative control: a Float one unit in the last place away, a Float instead of the equal
    Rational, a symbol's position swapped: each its own key."""
    Q, V = [x, y, z], [vx, vy, vz]
    base = L0 + sympy.Float(0.1) * x ** 3
    ulp = L0 + sympy.Float(float(np.nextafter(0.1, 1.0))) * x ** 3
    rat = L0 + sympy.Rational(1, 2) * x ** 3
    flo = L0 + sympy.Float(0.5) * x ** 3
    swapped = LagrangianSystem(L0, K0, [y, x, z], [vy, vx, vz])
    systems = [LagrangianSystem(e, K0, Q, V) for e in (base, ulp, rat, flo)] + [swapped]
    assert len({codegen.model_key(s, "general") for s in systems}) == len(systems)
