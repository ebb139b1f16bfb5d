"""One mechanical system, several statements (``core.system``): L and k as sympy expressions, the same
as text, ``LagrangianSystem.mechanical_form(M, U, K, b)`` and L, k with ``mechanical={...}``; with a
time-dependent potential U(t, q), a rheonomic constraint k = K(q) v + b(t) and a parameter. Each
statement is routed to the same form (the mechanical one for a constant M, the general one with a
gyroscopic term or M(q)) and gives the numbers of the 30-digit generic run on every engine.

Tolerance: 50 steps of h = 0.02, each solved to the round-off of states of size ~1 (2.2e-16),
amplified by the condition of the saddle matrix (4) (~10 for M with entries 1/2..2 and a unit row
K): 50 * 10 * 2.2e-16 ~ 1e-13; TOL = 1e-12. The multipliers are solved as Lambda = h Psi, so Psi
carries that error divided by h: TOL / h = 5e-11. Measured: q, v, E, k <= 6e-15, Psi <= 2e-13."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.compiled.runner import compile_system

H, STEPS = 0.02, 50
TOL = 1e-12
Q0, V0 = [0.3, -0.2, 0.4], [0.5, 0.3, 0.7]
ENGINES = {"generic": dict(engine="generic"), "compiled": dict(engine="compiled", newton="full"),
           "quasi": dict(engine="compiled", newton="quasi"), "auto": dict(engine="auto")}


def _statements(kind, shift=0):
    """{statement: system} of the mass with a heading: kind "mechanical" (M constant) or "general"
    (M(q) and a gyroscopic term); ``shift``: a potential changed by shift * x (the control)."""
    q, v, t, c = sympy.symbols("x y th"), sympy.symbols("vx vy vth"), sympy.Symbol("t"), sympy.Symbol("c")
    x, y, th = q
    V = sympy.Matrix(v)
    M = sympy.Matrix([[2, 0, sympy.Rational(1, 2)], [0, 2, 0], [sympy.Rational(1, 2), 0, 1]])
    if kind == "general":
        M = M + sympy.diag(0, 0, sympy.cos(x) ** 2 / 2)
    U = c * (x ** 2 + 2 * y ** 2) / 2 + sympy.cos(th) / 5 + x * sympy.sin(t) / 3 + shift * x
    K = sympy.Matrix([[sympy.sin(th), -sympy.cos(th), 0]])
    b = sympy.Matrix([sympy.cos(t) / 10])
    L = (V.T * M * V)[0, 0] / 2 - U + ((x * v[1] - y * v[0]) / 3 if kind == "general" else 0)
    k = list(K * V + b)
    out = {"sympy": LagrangianSystem(L, k, list(q), list(v), t=t, params=[c], name="sympy"),
           "text": LagrangianSystem(str(L), [str(e) for e in k], ["x", "y", "th"], ["vx", "vy", "vth"], t="t",
                                    params=["c"], name="text")}
    if kind == "mechanical":
        out["mechanical_form"] = LagrangianSystem.mechanical_form(M, U, K, b, q=list(q), v=list(v), params=[c],
                                                                  name="mechanical_form")
        out["mechanical="] = LagrangianSystem(L, k, list(q), list(v), t=t, params=[c], name="mechanical=",
                                              mechanical={"M": M, "U": U, "K": K, "b": b})
    return out


def _run(system, method, **kw):
    return ldaspark.integrate(system, method, t_span=(0, H * STEPS), q0=Q0, v0=V0, h=H, project=True,
                              params={"c": 0.7}, **kw)


def _gaps(run, ref):
    f = lambda a: np.asarray(a, float)       # noqa: E731
    return {key: np.abs(f(getattr(run, key)) - f(getattr(ref, key))).max()
            for key in ("q", "v", "energy", "constraint", "psi")}


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-3"])
@pytest.mark.parametrize("kind", ["mechanical", "general"])
def test_every_statement_gives_the_30_digit_numbers_on_every_engine(kind, method):
    systems = _statements(kind)
    ref = _run(systems["sympy"], method, engine="generic", dps=30)
    for name, system in systems.items():
        assert compile_system(system.with_params(c=0.7)).form == kind, name
        for engine, kw in ENGINES.items():
            run = _run(system, method, **kw)
            gaps = _gaps(run, ref)
            assert run.status == 0, (name, engine, run.message)
            assert max(gaps[key] for key in ("q", "v", "energy", "constraint")) < TOL, (name, engine, gaps)
            assert gaps["psi"] < TOL / H, (name, engine, gaps)


@pytest.mark.parametrize("kind", ["mechanical", "general"])
def test_a_statement_of_another_system_is_told_apart(kind):
    """Control: a potential changed by 1e-6 x moves the trajectory by far more than TOL on every statement."""
    ref = _run(_statements(kind)["sympy"], "gauss-2", engine="generic", dps=30)
    for name, system in _statements(kind, shift=sympy.Rational(1, 10 ** 6)).items():
        assert _gaps(_run(system, "gauss-2", engine="auto"), ref)["q"] > 1e3 * TOL, name
