"""Each symbolic step of the potential search has a time bound (``core.bounded.call_bounded``)."""
from __future__ import annotations

import sympy

from ldaspark.core import bounded


def _forever():
    while True:
        pass


def test_a_step_that_never_ends_is_abandoned_at_its_bound():
    assert bounded.call_bounded(_forever, seconds=0.5) is bounded.TIMED_OUT


def test_a_step_that_ends_returns_its_value():
    x = sympy.Symbol("x")
    assert bounded.call_bounded(sympy.integrate, sympy.cos(x), x, seconds=60) == sympy.sin(x)


def test_a_step_that_raises_is_reported_as_not_done():
    assert bounded.call_bounded(int, "not a number", seconds=60) is bounded.TIMED_OUT


def _spring_model():
    """A particle on the skate-like constraint with a spring load -(q1 + q1**3) N.x: curl free and
    not constant, so from_mechanics looks for its potential (simplify, integrate)."""
    import sympy.physics.mechanics as me
    q1, q2 = me.dynamicsymbols("q1 q2")
    u1, u2 = me.dynamicsymbols("u1 u2")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q1 * N.x + q2 * N.y)
    P.set_vel(N, u1 * N.x + u2 * N.y)
    KM = me.KanesMethod(N, [q1, q2], [u1], kd_eqs=[q1.diff() - u1, q2.diff() - u2],
                        u_dependent=[u2], velocity_constraints=[u2 - q1 * u1])
    KM.kanes_equations([me.Particle("pa", P, 1)], [(P, -(q1 + q1 ** 3) * N.x)])
    return KM


def test_past_the_bound_the_load_enters_as_its_force_with_the_same_motion(monkeypatch):
    import numpy as np

    import ldaspark
    calls = []
    real = bounded.call_bounded

    def counting(fn, *args, **kw):
        calls.append(fn)
        return real(fn, *args, **kw)
    monkeypatch.setattr(bounded, "call_bounded", counting)
    found = ldaspark.LagrangianSystem.from_mechanics(_spring_model())
    assert calls and found.N is None                      # the potential was found, in bounded steps
    # every symbolic step past its bound (not timed: the bound's own test is the one above)
    monkeypatch.setattr(bounded, "call_bounded", lambda fn, *a, **kw: bounded.TIMED_OUT)
    forced = ldaspark.LagrangianSystem.from_mechanics(_spring_model())
    assert forced.N is not None                           # the load as its generalized force
    kw = dict(t_span=(0, 0.2), q0=[0.3, 0], v0=[0.5, 0.15], h=0.05, engine="generic")
    a = np.asarray(ldaspark.integrate(found, "gauss-2", **kw).q)
    b = np.asarray(ldaspark.integrate(forced, "gauss-2", **kw).q)
    assert np.abs(a - b).max() <= 1e-13 and np.abs(a[-1] - a[0]).max() > 1e-2
