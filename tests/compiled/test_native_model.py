"""Native model functions (``ldaspark.compiled.native``): the generated model translated to LLVM
without numba computes what the source says, on every scene and both model forms; the kernels
run it with results bitwise equal to numba's compilation of the same source; what the translator
does not take goes to numba (nothing refused that ran before); a planted mistranslation is seen.

Tolerance of the per-function comparison with the source run as plain Python: the two evaluate
the same operations in the same order in IEEE double, except ``x**k`` (Python: libm's pow, one
rounding; native: square-and-multiply as numba, up to ~log2(k) roundings), so entries agree to a
few ulps of the largest term, amplified by the cancellations of a sum: 1e-11 * (1 + max |entry|)
over an output array leaves two orders of margin on the scenes' sizes (|terms| <= 1e2), and
a wrong operation (the control: sin read as cos) differs at O(1e-2) or more.
"""
import math

import numpy as np
import pytest
import sympy

from ldaspark.compiled import modeltypes as mt
from ldaspark.compiled import native
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.runner import _MODELS
from ldaspark.core.system import LagrangianSystem
from ldaspark.models.scenes import SCENES, get_scene

SCENE_NAMES = [s for s in SCENES if s != "bicycle"]
REL = 1e-11

numba = pytest.importorskip("numba")


# one caller per first-class signature, compiled once (the model functions are its arguments)
@numba.njit
def _call_vec(f, t, q, out):
    f(t, q, out)


@numba.njit
def _call_matx(f, t, q, v, out):
    f(t, q, v, out)


@numba.njit
def _call_u(f, t, q):
    return f(t, q)


@numba.njit
def _call_val(f, t, q, v, a, b, c, d):
    f(t, q, v, a, b, c, d)


@numba.njit
def _call_jac(f, t, q, v, lam, a, b, c, d, e, g):
    f(t, q, v, lam, a, b, c, d, e, g)


@numba.njit
def _call_e(f, t, q, v):
    return f(t, q, v)


@numba.njit
def _call_ni(f, t, q, v, psi, out):
    return f(t, q, v, psi, out)


@numba.njit
def _call_nij(f, t, q, v, psi, a, b, c):
    return f(t, q, v, psi, a, b, c)


def _outputs(fn_native, fn_python, sig, n, m, point):
    """[(name, native value, python value)] of one model function at ``point`` = (t, q, v, lam, psi)."""
    t, q, v, lam, psi = point
    z = lambda *shape: np.zeros(shape)  # noqa: E731
    res = []
    if sig is mt.VEC_SIG:
        for f, caller in ((fn_native, _call_vec), (fn_python, None)):
            out = z(n if fn_native.name != "b_of" else m)
            (caller(f, t, q, out) if caller else f(t, q, out))
            res.append([out])
    elif sig is mt.MAT_SIG:
        shape = (n, n) if fn_native.name == "hess_U" else (m, n)
        for f, caller in ((fn_native, _call_vec), (fn_python, None)):
            out = z(*shape)
            (caller(f, t, q, out) if caller else f(t, q, out))
            res.append([out])
    elif sig is mt.MATX_SIG:
        shape, x = ((m, n), v) if fn_native.name == "kq_of" else ((n, n), lam)
        for f, caller in ((fn_native, _call_matx), (fn_python, None)):
            out = z(*shape)
            (caller(f, t, q, x, out) if caller else f(t, q, x, out))
            res.append([out])
    elif sig is mt.U_SIG:
        res = [[np.array([_call_u(fn_native, t, q)])], [np.array([fn_python(t, q)])]]
    elif sig is mt.VAL_SIG:
        for f, caller in ((fn_native, _call_val), (fn_python, None)):
            outs = [z(n), z(n), z(m), z(m, n)]
            (caller(f, t, q, v, *outs) if caller else f(t, q, v, *outs))
            res.append(outs)
    elif sig is mt.JAC_SIG:
        for f, caller in ((fn_native, _call_jac), (fn_python, None)):
            outs = [z(n, n), z(n, n), z(n, n), z(m, n), z(n, n), z(n, n)]
            (caller(f, t, q, v, lam, *outs) if caller else f(t, q, v, lam, *outs))
            res.append(outs)
    elif sig is mt.E_SIG:
        res = [[np.array([_call_e(fn_native, t, q, v)])], [np.array([fn_python(t, q, v)])]]
    elif sig is mt.NI_SIG:
        for f, caller in ((fn_native, _call_ni), (fn_python, None)):
            out = z(n)
            flag = caller(f, t, q, v, psi, out) if caller else f(t, q, v, psi, out)
            res.append([out, np.array([float(flag)])])
    elif sig is mt.NIJ_SIG:
        for f, caller in ((fn_native, _call_nij), (fn_python, None)):
            outs = [z(n, n), z(n, n), z(n, m)]
            flag = caller(f, t, q, v, psi, *outs) if caller else f(t, q, v, psi, *outs)
            res.append(outs + [np.array([float(flag)])])
    else:
        raise AssertionError(sig)
    return res


def _points(sc, count=3, seed=0):
    t0, q0, v0 = sc.initial()
    rng = np.random.default_rng(seed)
    n, m = sc.system.n, sc.system.m
    for _ in range(count):
        yield (float(t0) + 0.3 * rng.random(), np.asarray(q0, float) + 1e-2 * rng.standard_normal(n),
               np.asarray(v0, float) + 1e-2 * rng.standard_normal(n), rng.standard_normal(m), rng.standard_normal(m))


def _worst(source, n, m, points):
    """max over functions, outputs and points of |native - python| / (1 + max |python|)."""
    model = native.compile_model(source)
    py = native.python_module(source)
    worst = 0.0
    for f in model[1:]:
        if not isinstance(f, native.NativeFunction):
            continue
        for p in points:
            got, ref = _outputs(f, getattr(py, f.name), f.signature(), n, m, p)
            for a, b in zip(got, ref):
                assert np.all(np.isfinite(b)), f"{f.name}: the reference is not finite at the test point"
                worst = max(worst, float(np.max(np.abs(a - b))) / (1.0 + float(np.max(np.abs(b)))))
    return worst


@pytest.mark.parametrize("form", ["auto", "general"])
@pytest.mark.parametrize("name", SCENE_NAMES)
def test_native_functions_compute_what_the_source_says(name, form):
    sc = get_scene(name)
    cs = compile_system(sc.system, form)
    assert _worst(cs.source, cs.n, cs.m, list(_points(sc))) <= REL


def test_a_mistranslated_function_is_seen(monkeypatch):
    """Negative control: sin translated as cos (one table entry) breaks the comparison above."""
    sc = get_scene("tilted-disk")
    cs = compile_system(sc.system, "general")
    assert "math.sin" in cs.source
    monkeypatch.setitem(native._INTRINSIC1, "sin", "llvm.cos")
    monkeypatch.setattr(native, "_BASES", {})              # translate again, not from this process's memory
    assert _worst(cs.source, cs.n, cs.m, list(_points(sc))) > 1e-3


def test_a_wrong_power_sequence_is_seen(monkeypatch):
    """Negative control: x**k computed as x**(k-1) for k >= 3 (a square-and-multiply off by one)."""
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - q[0] ** 5 / 5 - q[1] ** 4 / 4 - q[0] ** 2 * q[2] ** 3
    system = LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="powers")
    cs = compile_system(system, "general")
    pts = [(0.1, np.array([0.7, -1.3, 0.4]), np.array([0.2, 0.1, -0.5]), np.array([0.3]), np.array([0.0]))]
    assert _worst(cs.source, 3, 1, pts) <= REL
    orig = native._Function._int_exponent

    def off_by_one(self, node):
        k = orig(self, node)
        return k - 1 if (k is not None and k >= 3) else k
    monkeypatch.setattr(native._Function, "_int_exponent", off_by_one)
    monkeypatch.setattr(native, "_BASES", {})
    assert _worst(cs.source, 3, 1, pts) > 1e-3


@pytest.mark.parametrize("name,form", [("skate", "auto"), ("chaplygin-sphere", "general"),
                                       ("friction-skate", "general")])
def test_kernels_give_the_same_bits_with_native_and_numba_models(name, form):
    """One kernel run of 30 steps, the model once native and once numba's compilation of the
    same source: every number equal (the same operations in the same order)."""
    sc = get_scene(name)
    cs = compile_system(sc.system, form)
    t0, q0, v0 = sc.initial()
    runs = {}
    saved = _MODELS.pop(cs.digest, None)
    try:
        for kind in ("native", "numba"):
            _MODELS.pop(cs.digest, None)
            if kind == "native":
                _MODELS[cs.digest] = native.compile_model(cs.source)
            else:
                from numba.core.types.function_type import CompileResultWAP
                mod = cs.module.MODEL
                _MODELS[cs.digest] = (mod[0],) + tuple(
                    f if isinstance(f, bool) else CompileResultWAP(f.overloads[f.signatures[0]]) for f in mod[1:])
            r = run_compiled(cs, "gauss-2", float(t0), [float(x) for x in q0], [float(x) for x in v0], 0.05, 30)
            runs[kind] = (np.asarray(r.q), np.asarray(r.v))
    finally:
        _MODELS.pop(cs.digest, None)
        if saved is not None:
            _MODELS[cs.digest] = saved
    assert np.array_equal(runs["native"][0], runs["numba"][0])
    assert np.array_equal(runs["native"][1], runs["numba"][1])
    assert np.all(np.isfinite(runs["native"][0]))


def test_the_compiled_engine_runs_native_where_it_can_and_numba_elsewhere():
    """A scene's model is native; a model with a function the translator does not take
    (erf) is compiled by numba and still agrees with the generic engine."""
    from ldaspark.core.spark import integrate
    from ldaspark.core.families import get_method
    sc = get_scene("skate")
    cs = compile_system(sc.system)
    if not native.enabled():
        pytest.skip("LDASPARK_NATIVE=0")
    assert cs.is_native
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2) / 2 * (2 + sympy.erf(q[2] / 3))
    system = LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="erf-particle")
    cg = compile_system(system)
    with pytest.raises(native.NotNativeError, match="math.erf"):
        native.compile_model(cg.source)
    assert not cg.is_native
    q0, v0 = [1.0, 0.0, 0.1], [0.0, 1.0, 0.0]
    fast = run_compiled(cg, "gauss-2", 0.0, q0, v0, 0.05, 20)
    ref = integrate(system, get_method("gauss-2"), 0.0, q0, v0, 0.05, n_steps=20)
    assert np.max(np.abs(np.asarray(fast.q) - np.asarray(ref.q, dtype=float))) < 1e-12


def test_threads_binding_parameter_values_each_get_their_own(monkeypatch):
    """compile_model binds each set of parameter values to wrappers in one shared LLVM engine,
    named by the count of wrapper modules made so far: two threads inside it at once took the
    same name and one got the other's wrappers, i.e. its parameter values (integrate(params=...)
    in 12 threads: 10-11 of 12 runs wrong by up to 0.4, status 0). Here two threads are held
    together inside the bind whenever both can be there at once (after the name is chosen, and
    before the addresses are looked up); each model's U must then be its own value's, bit for bit
    as a bind made alone (the control: the two values give different U)."""
    import threading
    if not native.enabled():
        pytest.skip("LDASPARK_NATIVE=0")
    x, y, vx, vy, c = sympy.symbols("x y vx vy c")
    system = LagrangianSystem((vx ** 2 + vy ** 2) / 2 - c * x ** 2 / 2 - sympy.cos(y) / 2, [vy - x * vx], [x, y],
                              [vx, vy], params={c: 1.0}, name="bind-threads")
    src = compile_system(system).source
    U_AT = 7                                           # MODEL = (n, grad_U, ..., KTlam_q, U_of)
    point = np.array([1.0, 0.0])
    native.compile_model(src, (1.0,))                  # the base model and the wrappers' engine
    # bounds for a serialised bind (the other thread is then not inside), not timings
    named, added = threading.Barrier(2, timeout=1.5), threading.Barrier(2, timeout=1.5)
    waited = threading.local()

    def meet(barrier):
        try:
            barrier.wait()
        except threading.BrokenBarrierError:
            pass
    real_init = native._init_llvm

    def init():
        meet(named)
        real_init()

    class Engine:                                      # the shared engine, the first lookup held
        def __init__(self, engine):
            self.engine = engine

        def add_module(self, mod):
            return self.engine.add_module(mod)

        def finalize_object(self):
            return self.engine.finalize_object()

        def get_function_address(self, name):
            if not getattr(waited, "done", False):
                waited.done = True
                meet(added)
            return self.engine.get_function_address(name)
    got = {}

    def bind(value):
        got[value] = native.compile_model(src, (value,))
    monkeypatch.setattr(native, "_init_llvm", init)
    engine = native._WRAPPERS[0]
    native._WRAPPERS[0] = Engine(engine)
    try:
        threads = [threading.Thread(target=bind, args=(value,)) for value in (3.0, 5.0)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        native._WRAPPERS[0] = engine
        monkeypatch.undo()
    alone = {value: _call_u(native.compile_model(src, (value,))[U_AT], 0.0, point) for value in (3.0, 5.0)}
    assert alone[3.0] != alone[5.0]
    assert {value: _call_u(got[value][U_AT], 0.0, point) for value in (3.0, 5.0)} == alone


@pytest.mark.parametrize("text,why", [
    ("import os", "neither a function"),
    ("def f(t, q):\n    return os.system('x')", "not a generated model function"),
    ("@_jit(_mt.U_SIG)\ndef f(t, q):\n    return os.system(1.0)", "call of os.system"),
    ("@_jit(_mt.U_SIG)\ndef f(t, q):\n    while True:\n        pass", "statement While"),
    ("@_jit(_mt.U_SIG)\ndef f(t, q):\n    return q[-1]", "index"),
])
def test_the_translator_takes_only_its_whitelist(text, why):
    src = "MODEL = (1, f)\n" + text
    with pytest.raises(native.NotNativeError, match=why):
        native.compile_model(src)


def test_a_source_with_a_foreign_call_is_refused_before_any_code_is_built():
    sc = get_scene("skate")
    cs = compile_system(sc.system, "general")
    bad = cs.source.replace("math.sin(", "os.system(", 1) if "math.sin(" in cs.source else \
        cs.source.replace("return ", "return os.getpid() + ", 1)
    with pytest.raises(native.NotNativeError):
        native.compile_model(bad)


def test_a_thousand_term_sum_is_translated_without_recursion():
    """A left-nested sum of 1200 terms (what codegen prints for a long L) is walked iteratively:
    the source is written here, so the test costs the translation only, not a 1200-dof derivation."""
    n = 1200
    body = "\n".join(f"    _q{i} = q[{i}]" for i in range(n))
    expr = " + ".join(f"((1.0/2.0))*_q{i}**2" for i in range(n))
    src = ("import math\nfrom ldaspark.compiled import modeltypes as _mt\n"
           "from ldaspark.compiled.cache import model_jit as _jit\n\n"
           f"@_jit(_mt.U_SIG, nogil=True, _nrt=False)\ndef U_of(t, q):\n{body}\n    return {expr}\n\n"
           f"N_DOF = {n}\nMODEL = (N_DOF, U_of)\n")
    model = native.compile_model(src)
    U = next(f for f in model[1:] if f.name == "U_of")
    qq = np.linspace(-1, 1, n)
    assert math.isclose(_call_u(U, 0.0, qq), float(np.sum(qq ** 2) / 2), rel_tol=1e-13)



@pytest.mark.parametrize("form", ["mechanical", "general"])
@pytest.mark.parametrize("newton", ["quasi", "auto"])
def test_a_division_by_zero_in_a_numba_model_is_seen_as_in_a_native_one(newton, form, monkeypatch, capfd):
    """U = q1^2 + q2^2 + q1 / (1000 (t - 1)) has a pole at t = 1, a stage time of
    lobatto-iiia-iiib-2 with h = 0.25 (step 3): grad U is inf / nan there. The native model
    computes inf / nan and the run stops at that step (status -3, residual nan). numba's model
    (LDASPARK_NATIVE=0, or a model the translator refuses) raised ZeroDivisionError inside the
    first-class call, which a kernel cannot propagate: numba printed "Exception ignored" 30 times,
    the entry kept its previous value and the run reported t_end reached with q1 = -0.887 (measured
    before the generated functions took error_model="numpy"). Both kinds of model must now give
    the same result and print nothing. Control: started after the pole, both run to the end.
    The general form's model (k = v3 - q2 v1 + v1^2 / 10, not affine in v) likewise: its functions
    come from the same emitter, its steps from other kernels."""
    import ldaspark
    from ldaspark.compiled.fast import compile_system as compile_
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    U = q[0] ** 2 + q[1] ** 2 + q[0] / (1000 * (t - 1))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - U
    results = {}
    for kind in ("native", "numba"):
        monkeypatch.setenv("LDASPARK_NATIVE", "1" if kind == "native" else "0")
        k = v[2] - q[1] * v[0] + (v[0] ** 2 / 10 if form == "general" else 0)
        system = LagrangianSystem(L, [k], q, v, t=t, name=f"pole-particle-{form}-{kind}")
        cs = compile_(system)
        assert cs.form == form
        _MODELS.pop(cs.model_id, None)                      # the model built on this path
        for t0 in (0.0, 1.1):
            r = ldaspark.integrate(system, "lobatto-iiia-iiib-2", t0=t0, q0=[1.0, 0.0, 0.1], v0=[0.0, 1.0, 0.0],
                                   h=0.25, n_steps=8, engine="compiled", newton=newton)
            results[kind, t0] = (r.status, r.message.split(":")[0], np.asarray(r.q))
        assert cs.is_native == (kind == "native")
        _MODELS.pop(cs.model_id, None)
    err = capfd.readouterr().err
    assert "Exception ignored" not in err, err[:300]
    assert results["native", 0.0][0] < 0                     # the pole is seen
    for t0 in (0.0, 1.1):
        a, b = results["native", t0], results["numba", t0]
        assert a[:2] == b[:2], (a[:2], b[:2])
        assert np.array_equal(a[2], b[2])
    assert results["native", 1.1][0] == 0 and np.all(np.isfinite(results["native", 1.1][2]))


@pytest.mark.parametrize("name,form", [("skate", "auto"), ("chaplygin-sleigh", "auto"), ("rolling-disk", "auto"),
                                       ("skate", "general")])
def test_a_model_with_the_sine_and_cosine_of_one_value_is_built_at_O2_with_the_bits_of_O0(name, form, monkeypatch):
    """A model that takes sin and cos of one value is compiled at -O2 (libm's sincos for the pair,
    ``native._O2_SIN_COS_UP_TO``) however few its operations per coordinate; every output of every
    function equal bit for bit to the -O0 build (no fast-math: LLVM keeps the order of the
    operations, and glibc's sincos is its sin and cos). Control: with the rule off, -O0."""
    sc = get_scene(name)
    cs = compile_system(sc.system, form)
    levels = []
    jit = native._jit
    monkeypatch.setattr(native, "_jit", lambda module, opt: (levels.append(opt), jit(module, opt))[1])
    py = native.python_module(cs.source)
    outs = {}
    for rule in (True, False):
        monkeypatch.setattr(native, "_O2_SIN_COS_UP_TO", 4000 if rule else 0)
        monkeypatch.setattr(native, "_BASES", {})           # translate again, not from this process's memory
        model = native.compile_model(cs.source)
        outs[rule] = [_outputs(f, getattr(py, f.name), f.signature(), cs.n, cs.m, p)[0]
                      for f in model[1:] if isinstance(f, native.NativeFunction) for p in _points(sc)]
    assert levels == [2, 0]
    assert len(outs[True]) == len(outs[False]) > 0
    for a, b in zip(outs[True], outs[False]):
        for x, y in zip(a, b):
            assert np.array_equal(np.asarray(x), np.asarray(y))
