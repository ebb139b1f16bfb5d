"""Parameter values through every path (probe t14): the same values given substituted into the
expressions, as ``params={...}``, through ``with_params``, as a params list (ensemble) and through
``run_many`` give the same numbers; one parameter given two different values is refused.

A system with three parameters: m a mass in M, c in L only (the potential), b in k only.
Tolerances: the same engine on the same values runs the same IEEE operations (the compiled model
takes the values at run time, the generic one as trailing arguments): bit for bit. Across engines
(generic vs compiled, other code for the same equations), each step agrees to Newton's tolerance
(~1e-14 relative on |q| <= 1): 10 steps of gauss-2, 1e-12 absolute (measured 1.1e-16)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import SystemDefinitionError
from ldaspark.core.system import LagrangianSystem
from ldaspark.ensemble import RunSpec, run_many

x, y, th, vx, vy, vth = sympy.symbols("x y th vx vy vth")
m = sympy.Symbol("m", positive=True)
c, b = sympy.symbols("c b")
P = {"m": 2, "c": 0.7, "b": 0.25}
Q0, V0 = [0.1, 0.2, 0.0], [1.0, 0.125, 0.5]          # k = -vy + b vth = 0 exactly at th = 0
KW = dict(t_span=(0, 0.5), h=0.05, q0=Q0, v0=V0)


def _system(name="probe-t14"):
    L = m * (vx ** 2 + vy ** 2) / 2 + vth ** 2 / 2 - c * (x ** 2 + y ** 2) / 2
    return LagrangianSystem(L, [sympy.sin(th) * vx - sympy.cos(th) * vy + b * vth], [x, y, th], [vx, vy, vth],
                            params=[m, c, b], name=name)


@pytest.mark.parametrize("engine, extra", [("generic", {}), ("compiled", {}), ("compiled", {"newton": "quasi"})])
def test_every_path_gives_the_same_numbers(engine, extra):
    S = _system()
    kw = dict(KW, engine=engine, **extra)
    given = ldaspark.integrate(S, "gauss-2", params=P, **kw)
    sub = ldaspark.integrate(S.with_params(P).substituted(), "gauss-2", **kw)
    view = ldaspark.integrate(S.with_params(P), "gauss-2", **kw)
    other = dict(P, m=3, c=1.1)
    members = ldaspark.integrate(S, "gauss-2", params=[P, other, P], **kw)
    for r in (sub, view):
        assert np.array_equal(r.q, given.q) and np.array_equal(r.v, given.v)
    mq = np.asarray(members.q)
    assert np.array_equal(mq[0], given.q) and np.array_equal(mq[2], given.q)
    assert np.abs(mq[1] - mq[0]).max() > 1e-3              # control: the other values reach the model
    assert given.params == {"m": 2, "c": 0.7, "b": 0.25}
    assert members.params == {"members": [P, other, P]}
    many = run_many([RunSpec(S.with_params(P), "gauss-2", 0.0, [Q0], [V0], 0.05, 10)])[0]
    tol = 0.0 if engine == "compiled" else 1e-12
    assert np.abs(np.asarray(many.q)[0] - given.q).max() <= tol


def test_one_parameter_given_two_different_values_is_refused():
    """{"m": 2, Symbol("m"): 3} named m twice: the last value ran (m = 3) and the other was
    dropped without a word. Now refused, naming the parameter; the same value twice still runs
    (control), with the numbers of the value given once."""
    S = _system()
    with pytest.raises(SystemDefinitionError, match="parameter m is given twice"):
        S.with_params({"m": 2, sympy.Symbol("m"): 3})
    with pytest.raises(SystemDefinitionError, match="parameter m is given twice"):
        S.with_params({m: 3}, m=2)
    with pytest.raises(SystemDefinitionError, match="parameter m is given twice"):
        ldaspark.integrate(S, "gauss-2", params={"m": 2, sympy.Symbol("m"): 3, "c": 0.7, "b": 0.25}, **KW)
    once = ldaspark.integrate(S, "gauss-2", params=P, **KW)
    twice = ldaspark.integrate(S, "gauss-2", params={**P, m: 2.0}, **KW)
    assert np.array_equal(once.q, twice.q)
