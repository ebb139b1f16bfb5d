"""The semi-implicit comparators of sections 7.5 and 8.4 (``core.comparators``) on the generic
engine against the compiled kernel and the SPARK method they rewrite, on systems whose mechanical
parts U(t, q), K(t, q), b(t, q) depend on the time (the form both engines detect)."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import InputError

SEMI_IMPLICIT = ("lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified-leapfrog", "mp-lobatto-iiib-a-2")
# 50 steps, each solved to the round-off of states of size ~1 (2.2e-16), through saddle matrices
# (4) of condition ~10 here: 50 * 10 * 2.2e-16 ~ 1e-13; measured 1e-16 to 7e-16
TOL = 1e-12


def _time_dependent(with_parts):
    """A mass on a plane with a heading (n = 3, m = 1): U(t, q) with a forcing sin(t) x / 3 and a
    constraint moving with b(t) = cos(t) / 10; stated as M, U, K, b or as L, k alone."""
    q = sympy.symbols("x y th")
    v = sympy.symbols("vx vy vth")
    t = sympy.Symbol("t")
    x, y, th = q
    M = sympy.Matrix([[2, 0, sympy.Rational(1, 2)], [0, 2, 0], [sympy.Rational(1, 2), 0, 1]])
    U = (x ** 2 + 2 * y ** 2) / 2 + x * sympy.sin(t) / 3
    K = sympy.Matrix([[sympy.sin(th), -sympy.cos(th), 0]])
    b = sympy.Matrix([sympy.cos(t) / 10])
    if with_parts:
        return LagrangianSystem.mechanical_form(M, U, K, b, q=list(q), v=list(v), name="forced")
    V = sympy.Matrix(v)
    return LagrangianSystem((V.T * M * V)[0, 0] / 2 - U, list(K * V + b), list(q), list(v), t=t, name="forced")


def _run(system, method, engine, t0=0.0):
    return ldaspark.integrate(system, method, t_span=(t0, t0 + 1), q0=[0.3, -0.2, 0.4], v0=[0.5, 0.3, 0.7],
                              h=0.02, project=True, engine=engine)


@pytest.mark.parametrize("with_parts", [True, False], ids=["mechanical_form", "L_and_k"])
@pytest.mark.parametrize("method", SEMI_IMPLICIT)
def test_the_generic_semi_implicit_comparators_take_the_time_of_U_K_and_b(method, with_parts):
    """The generic engine's comparators evaluated grad U, K and b as functions of q alone: a system
    stated by ``mechanical_form`` with t in U or b failed at the first step with "an expression
    contains symbols that are not arguments: t", and one stated by L and k was refused as not
    mechanical, while the compiled kernel ran both (U(t, q), K(t, q), b(t, q))."""
    system = _time_dependent(with_parts)
    gen, comp = _run(system, method, "generic"), _run(system, method, "compiled")
    assert gen.status == comp.status == 0
    for a, c in ((gen.q, comp.q), (gen.v, comp.v), (gen.energy, comp.energy)):
        assert np.abs(np.asarray(a, float) - np.asarray(c, float)).max() < TOL
    assert np.abs(np.asarray(gen.constraint, float)).max() < TOL
    # control: the same method with its clock shifted (the forcing and the constraint seen at
    # t + 0.5, a run that ignored t would agree with itself) differs far beyond TOL
    shifted = _run(system, method, "generic", t0=0.5)
    assert np.abs(np.asarray(shifted.q, float) - np.asarray(gen.q, float)).max() > 1e3 * TOL


@pytest.mark.parametrize("method", ["lobatto-iiia-iiib-2-leapfrog", "lobatto-iiia-iiib-2-modified-leapfrog"])
def test_the_leapfrog_forms_are_the_spark_methods_they_rewrite_on_a_time_dependent_system(method):
    """(25) is Lobatto IIIA-B-2 and its modified form the method of 8.4: on the generic engine the
    semi-implicit form gives the SPARK method's numbers with t in U and b too (control: the
    other of the two methods, 1.7e-6 apart on this system, is told apart)."""
    system = _time_dependent(True)
    spark = {"lobatto-iiia-iiib-2-leapfrog": "lobatto-iiia-iiib-2",
             "lobatto-iiia-iiib-2-modified-leapfrog": "lobatto-iiia-iiib-2-modified"}
    semi = _run(system, method, "generic")
    same = _run(system, spark[method], "generic")
    other = _run(system, spark[next(m for m in spark if m != method)], "generic")
    assert np.abs(np.asarray(semi.q, float) - np.asarray(same.q, float)).max() < TOL
    assert np.abs(np.asarray(semi.q, float) - np.asarray(other.q, float)).max() > 1e3 * TOL


def test_a_mass_matrix_depending_on_q_is_still_refused_by_the_semi_implicit_comparators():
    """Control of the widened form: M must stay constant (the semi-implicit steps solve with M)."""
    q = sympy.symbols("x y")
    v = sympy.symbols("vx vy")
    L = (1 + q[0] ** 2) * v[0] ** 2 / 2 + v[1] ** 2 / 2 - q[1] ** 2 / 2
    system = LagrangianSystem(L, [v[1] - q[0] * v[0]], list(q), list(v), name="varying-mass")
    for engine in ("generic", "compiled"):
        with pytest.raises(InputError, match="mechanical"):
            ldaspark.integrate(system, "mp-lobatto-iiib-a-2", t_span=(0, 0.1), q0=[0.1, 0.0], v0=[1.0, 0.1],
                               h=0.05, engine=engine)


@pytest.mark.parametrize("dps", [None, 30])
@pytest.mark.parametrize("method", SEMI_IMPLICIT)
def test_the_generic_semi_implicit_comparators_run_without_constraints(method, dps):
    """m = 0 (a system from ``mechanical_form`` with K 0 x n): the generic comparators indexed b's
    column, which m = 0 prints as [], and raised IndexError ("too many indices for array") at the
    first step, where the compiled kernel ran. Now both engines agree (TOL: see above), and the
    leapfrog form is Lobatto IIIA-B-2 (Stormer-Verlet at m = 0); control: McLachlan-Perlmutter's
    method (26) is another method, 1e-4 away on this oscillator."""
    x, y = sympy.symbols("x y")
    system = LagrangianSystem.mechanical_form(sympy.diag(1, 2), x ** 2 / 2 + y ** 2 + x ** 3 / 3,
                                              sympy.zeros(0, 2), q=[x, y], v=sympy.symbols("vx vy"))
    kw = dict(t_span=(0, 1), q0=[1.0, 0.2], v0=[0.0, 1.0], h=0.05)
    gen = ldaspark.integrate(system, method, engine="generic", dps=dps, **kw)
    comp = ldaspark.integrate(system, method, engine="compiled", **kw)
    spark = ldaspark.integrate(system, "lobatto-iiia-iiib-2", engine="generic", **kw)
    assert gen.status == comp.status == 0
    assert np.abs(np.asarray(gen.q, float) - comp.q).max() < TOL
    assert np.abs(np.asarray(gen.v, float) - comp.v).max() < TOL
    gap = np.abs(np.asarray(gen.q, float) - spark.q).max()
    assert gap < TOL if method != "mp-lobatto-iiib-a-2" else gap > 1e-6


_BASE = "(2*vx**2 + 2*vy**2 + vth**2 + vx*vth)/2 - (x**2 + 2*y**2)/2"


def _plane_with(extra):
    return LagrangianSystem(f"{_BASE} + {extra}", ["sin(th)*vx - cos(th)*vy"], ["x", "y", "th"], ["vx", "vy", "vth"],
                            name="plane")


@pytest.mark.parametrize("extra", ["vx*(log(exp(x)) - x)", "vy*(cos(x)**2 - (1 + cos(2*x))/2)"])
def test_the_generic_comparators_find_the_mechanical_form_where_the_compiled_engine_does(extra):
    """A term linear in v that vanishes identically but not by sympy.simplify (log(exp(x)) - x
    for real x): the compiled engine's detector (grad_v L - M v = 0 at random 40-digit points) took
    the system as mechanical and ran mp-lobatto-iiib-a-2, the generic engine's derive_mechanical
    (sympy.simplify of L - (v^T M v / 2 - U)) refused it as "not of the mechanical form". Both
    decide by the same test now and give the same numbers (TOL)."""
    system = _plane_with(extra)
    kw = dict(t_span=(0, 1), q0=[0.3, -0.2, 0.4], v0=[0.5, 0.5 * np.tan(0.4), 0.7], h=0.02)
    gen = ldaspark.integrate(system, "mp-lobatto-iiib-a-2", engine="generic", **kw)
    comp = ldaspark.integrate(system, "mp-lobatto-iiib-a-2", engine="compiled", **kw)
    assert gen.status == comp.status == 0
    assert np.abs(np.asarray(gen.q, float) - comp.q).max() < TOL


@pytest.mark.parametrize("extra", ["x*vy", "3*vy", "vx**4/10", "vx**2*(sin(x)**2 + cos(x)**2 - 1)"])
def test_terms_that_are_not_mechanical_are_refused_by_both_engines(extra):
    """Control: a gyroscopic term, a constant momentum shift, a quartic kinetic term and an L_vv
    depending on q as written are refused by the semi-implicit comparators on both engines."""
    system = _plane_with(extra)
    kw = dict(t_span=(0, 0.1), q0=[0.3, -0.2, 0.4], v0=[0.5, 0.5 * np.tan(0.4), 0.7], h=0.02)
    for engine in ("generic", "compiled"):
        with pytest.raises(InputError, match="mechanical form"):
            ldaspark.integrate(system, "mp-lobatto-iiib-a-2", engine=engine, **kw)


@pytest.mark.parametrize("as_text", [False, True], ids=["sympy", "text"])
def test_mechanical_parts_given_as_lists_run_the_generic_comparators_with_parameters(as_text):
    """``mechanical={"M": [[a, 0], [0, 1]], "K": [[1, -1]], ...}`` (lists of rows, as the docs allow)
    with a parameter a: the comparator engine substitutes the values (``substituted``), which
    called .subs on the lists: AttributeError "'list' object has no attribute 'subs'" on the
    generic engine, where the compiled one ran. Now the same numbers (TOL) on both; control: the
    system at a = 2 and a = 3 differs."""
    x, y, vx, vy, a = sympy.symbols("x y vx vy a")
    mech = ({"M": [["a", 0], [0, 1]], "U": "x**2/2", "K": [[1, "-1"]], "b": ["0"]} if as_text else
            {"M": [[a, 0], [0, 1]], "U": x ** 2 / 2, "K": [[1, -1]], "b": [0]})
    system = LagrangianSystem((a * vx ** 2 + vy ** 2) / 2 - x ** 2 / 2, [vx - vy], [x, y], [vx, vy], params=[a],
                              mechanical=mech)
    kw = dict(t_span=(0, 0.5), h=0.05, q0=[1.0, 0.0], v0=[0.3, 0.3])
    gen, comp, other = (ldaspark.integrate(system, "lobatto-iiia-iiib-2-leapfrog", engine=engine, params={"a": val},
                                           **kw) for engine, val in (("generic", 2), ("compiled", 2), ("generic", 3)))
    assert gen.status == comp.status == 0
    assert np.abs(np.asarray(gen.q, float) - comp.q).max() < TOL
    assert np.abs(np.asarray(gen.q, float) - np.asarray(other.q, float)).max() > 1e3 * TOL
