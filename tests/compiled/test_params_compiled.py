"""Parameters on the compiled engine: a system with ``params`` is generated and compiled once with
its parameters symbolic (``codegen.fill_params``; natively a pointer argument behind small
per-value wrappers, ``native.compile_model``), and every parameter value runs on it.

Tolerances: the compiled run with parameters evaluates the same generated expressions as the
compiled run of ``with_params(...).substituted()`` except that sympy may fold the substituted
numbers (2 * 9.81 -> 19.62) in another order; each such fold is one rounding (<= 2^-53 relative)
in a model evaluation, and over 500 gauss-2 steps of a bounded motion the difference stays at a
few hundred ulps of |q| <= 100: 1e-11 absolute. Against the generic engine (other code, the
same equations) the compiled runs agree to Newton's tolerance (~1e-14 per step): 1e-10 over
500 steps (measured: 1.4e-12)."""
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.compiled import codegen, native, runner
from ldaspark.compiled.fast import compile_system
from ldaspark.core.errors import InputError, SystemDefinitionError
from ldaspark.core.system import LagrangianSystem

x, y, th, vx, vy, vth = sympy.symbols("x y th vx vy vth")
m, I, g = sympy.symbols("m I g", positive=True)
Q0, V0 = [0.0, 0.0, 0.3], [float(np.cos(0.3)), float(np.sin(0.3)), 0.5]
KW = dict(t_span=(0, 5), h=0.01, q0=Q0, v0=V0)
P = {"m": 2.0, "I": 0.5, "g": 9.81}


def _skate(gyro=False):
    """A skate in a gravity field, mass and inertia as parameters (M depends on them); gyro: a
    magnetic term g*x*vy that makes it general form."""
    L = m * (vx ** 2 + vy ** 2) / 2 + I * vth ** 2 / 2 - m * g * y + (g * x * vy / 10 if gyro else 0)
    k = [sympy.sin(th) * vx - sympy.cos(th) * vy]
    return LagrangianSystem(L, k, [x, y, th], [vx, vy, vth], name="skate-params", params=[m, I, g])


@pytest.mark.parametrize("gyro,form", [(False, "mechanical"), (True, "general")])
def test_parameters_run_compiled_with_the_numbers_of_the_substituted_system(gyro, form):
    S = _skate(gyro)
    assert compile_system(S.with_params(P)).form == form
    r = ldaspark.integrate(S, "gauss-2", params=P, **KW)          # engine auto
    assert r.engine == "compiled" and r.success
    sub = ldaspark.integrate(S.with_params(P).substituted(), "gauss-2", engine="compiled", **KW)
    gen = ldaspark.integrate(S, "gauss-2", params=P, engine="generic", **KW)
    assert np.abs(r.q - sub.q).max() < 1e-11 and np.abs(r.v - sub.v).max() < 1e-11
    assert np.abs(r.q - gen.q).max() < 1e-10
    # control: the values reach the model (another g moves the skate by O(1))
    other = ldaspark.integrate(S, "gauss-2", params=dict(P, g=9.0), **KW)
    assert np.abs(other.q[-1] - r.q[-1]).max() > 1.0


def test_one_compilation_serves_every_value(monkeypatch, tmp_path):
    """Generated once and compiled natively once for 5 values; each value costs only its wrappers."""
    S = _skate()
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(codegen, "_SOURCES", {})
    monkeypatch.setattr(native, "_BASES", {})
    monkeypatch.setattr(runner, "_MODELS", {})
    gen, comp, bind = [], [], []
    orig_g, orig_c, orig_b = codegen._mechanical_source, native._compile_functions, native._bind
    monkeypatch.setattr(codegen, "_mechanical_source", lambda *a: (gen.append(1), orig_g(*a))[1])
    monkeypatch.setattr(native, "_compile_functions", lambda *a: (comp.append(1), orig_c(*a))[1])
    monkeypatch.setattr(native, "_bind", lambda *a: (bind.append(1), orig_b(*a))[1])
    ends = []
    for gv in (1.0, 2.0, 3.0, 4.0, 5.0):
        r = ldaspark.integrate(S, "gauss-2", params=dict(P, g=gv), **KW)
        assert r.engine == "compiled"
        ends.append(r.q[-1, 1])
    assert gen == [1] and comp == [1] and bind == [1] * 5
    assert len(set(ends)) == 5


def test_numba_fallback_takes_the_values_too(monkeypatch):
    """LDASPARK_NATIVE=0: numba compiles the source with its values filled in; bitwise the same
    numbers as the native wrappers (the same IEEE operations)."""
    S = _skate()
    nat = ldaspark.integrate(S, "gauss-2", params=P, **KW)
    monkeypatch.setenv("LDASPARK_NATIVE", "0")
    monkeypatch.setattr(runner, "_MODELS", {})
    nb = ldaspark.integrate(S, "gauss-2", params=P, **KW)
    assert not compile_system(S.with_params(P)).is_native
    assert nb.engine == "compiled" and np.array_equal(nb.q, nat.q) and np.array_equal(nb.v, nat.v)


def test_a_parameter_ensemble_on_threads_equals_the_serial_run():
    """Members with different values run at once in one process (each has its own constant copy)."""
    S = _skate()
    plist = [dict(P, g=float(gv)) for gv in np.linspace(1, 10, 8)]
    serial = ldaspark.integrate(S, "gauss-2", params=plist, **KW)
    with ThreadPoolExecutor(2) as ex:
        par = ldaspark.integrate(S, "gauss-2", params=plist, executor=ex, **KW)
    assert np.array_equal(np.asarray(serial.q), np.asarray(par.q))
    finals = np.asarray(serial.q)[:, -1, 1]
    assert len(np.unique(finals)) == len(plist)


def test_fill_params_refuses_what_does_not_fit():
    S = _skate().with_params(P)
    src = compile_system(S).source
    assert "PARAMS = None" in src and "N_PARAMS = 3" in src
    assert "PARAMS = (2.0, 0.5, 9.81,)" in codegen.fill_params(src, (2.0, 0.5, 9.81))
    for bad in ((), (1.0, 2.0), (1.0, 2.0, float("nan"))):
        with pytest.raises(codegen.NotCompilableError):
            codegen.fill_params(src, bad)
    with pytest.raises(native.NotNativeError):
        native.compile_model(src, (1.0, 2.0))
    plain = compile_system(ldaspark.get_scene("skate").system).source
    with pytest.raises(codegen.NotCompilableError):
        codegen.fill_params(plain, (1.0,))
    assert codegen.fill_params(plain, ()) is plain


def _coupled(name):
    """M = [[a, 1], [1, 1]]: singular at a = 1 (no M^-1 for the mechanical kernels), regular at a = 2."""
    a = sympy.Symbol("a", positive=True)
    L = (a * vx ** 2 + 2 * vx * vy + vy ** 2) / 2 - x ** 2 / 2 - y ** 2
    return LagrangianSystem(L, [vx - vy], [x, y], [vx, vy], params=[a], name=name)


def test_the_compiled_form_of_a_parameter_value_does_not_depend_on_the_values_run_before():
    """The model of a system with parameters is generated once and shared by its values; the form
    was the one of the first value: M singular at a = 1 run first gave a = 2 the general form
    (another kernel: kernel "general" instead of "quasi"), and a = 2 first made a = 1 a refusal
    ("mass matrix M is singular") that the same value run first did not meet. Now each value has
    its form whatever ran before: a = 1 the general form, a = 2 the mechanical one, with the same
    bits (control: the two forms at a = 2 are different kernels)."""
    kw = dict(t_span=(0, 1), h=0.05, q0=[1.0, 0.5], v0=[0.3, 0.3], engine="compiled")
    forms, runs = {}, {}
    for order in ((1, 2), (2, 1)):
        system = _coupled(f"coupled-{order[0]}{order[1]}")
        for a in order:
            forms[order, a] = compile_system(system.with_params(a=a)).form
        runs[order] = ldaspark.integrate(system, "gauss-2", params={"a": 2}, **kw)
    assert forms[(1, 2), 1] == forms[(2, 1), 1] == "general"
    assert forms[(1, 2), 2] == forms[(2, 1), 2] == "mechanical"
    assert runs[(1, 2)].stats["kernel"] == runs[(2, 1)].stats["kernel"] == "quasi"
    assert np.array_equal(runs[(1, 2)].q, runs[(2, 1)].q) and np.array_equal(runs[(1, 2)].v, runs[(2, 1)].v)
    general = ldaspark.integrate(_coupled("coupled-general").with_params(a=2), "gauss-2",
                                 **dict(kw, newton="full"))
    assert general.stats["kernel"] != "quasi"


def test_auto_checks_a_comparator_at_the_parameter_values_where_the_compiled_engine_cannot_run(monkeypatch):
    """engine="auto" with a comparator that the compiled engine cannot run asks the comparator
    whether it can (``require_mechanical``) before falling back: it asked with the parameters
    still symbols, and M = diag(m, m, I) was refused as "the semi-implicit comparators need a
    constant mass matrix M", a run that engine="generic" makes. Now asked at the values: auto
    falls back and gives the generic numbers (control: a mass matrix depending on q is still
    refused)."""
    from ldaspark.engines import ENGINES
    monkeypatch.setattr(type(ENGINES["compiled"]), "unavailable", lambda self, system, prob: "no compiler here")
    kw = dict(t_span=(0, 0.5), h=0.05, q0=Q0, v0=V0, params=P)
    auto = ldaspark.integrate(_skate(), "lobatto-iiia-iiib-2-leapfrog", engine="auto", **kw)
    generic = ldaspark.integrate(_skate(), "lobatto-iiia-iiib-2-leapfrog", engine="generic", **kw)
    assert auto.status == generic.status == 0
    assert np.array_equal(auto.q, generic.q)
    L = (1 + x ** 2) * vx ** 2 / 2 + m * (vy ** 2 + vth ** 2) / 2
    varying = LagrangianSystem(L, [sympy.sin(th) * vx - sympy.cos(th) * vy], [x, y, th], [vx, vy, vth], params=[m])
    with pytest.raises(InputError, match="with constant M"):
        ldaspark.integrate(varying, "lobatto-iiia-iiib-2-leapfrog", engine="auto", params={"m": 2.0},
                           **{k: v for k, v in kw.items() if k != "params"})


def test_a_float_parameter_value_passes_the_check_of_matching_mechanical_parts():
    """The mechanical parts are compared with L at 40 digits, with the parameters at their values:
    c = 0.7 (a Python float, 53 bits) bounded the precision of both sides, which sympy sums in
    different orders, and a matching U failed ("-0.0621196 vs -0.0621196"): the compiled engine
    refused the run ("compilation failed (SystemDefinitionError)"; auto fell back) that c = "0.7"
    or 0.5 ran. The value enters the check as the exact rational it is now. Control: a U off by
    1e-6 x is still refused."""
    c = sympy.Symbol("c")
    V = sympy.Matrix([vx, vy, vth])
    M = sympy.Matrix([[2, 0, sympy.Rational(1, 2)], [0, 2, 0], [sympy.Rational(1, 2), 0, 1]])
    U = c * (x ** 2 + 2 * y ** 2) / 2 + sympy.cos(th) / 5
    K = sympy.Matrix([[sympy.sin(th), -sympy.cos(th), 0]])

    def build(u):
        return LagrangianSystem((V.T * M * V)[0, 0] / 2 - U, list(K * V), [x, y, th], [vx, vy, vth], params=[c],
                                mechanical={"M": M, "U": u, "K": K})
    system = build(U)
    assert compile_system(system.with_params(c=0.7)).form == "mechanical"
    r = ldaspark.integrate(system, "gauss-2", engine="compiled", t_span=(0, 0.2), h=0.02, q0=[0.3, -0.2, 0.4],
                           v0=[0.5, 0.5 * np.tan(0.4), 0.7], params={"c": 0.7})
    assert r.status == 0 and r.stats["form"] == "mechanical"
    with pytest.raises(SystemDefinitionError, match="do not match"):
        build(U + x / 10 ** 6)
