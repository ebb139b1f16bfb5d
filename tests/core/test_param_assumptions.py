"""Parameter values that contradict the sympy assumptions the model was derived under are refused
(``system._check_assumptions``), naming the parameter, the value and the assumption."""
from __future__ import annotations

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import SystemDefinitionError

x, y, vx, vy = sympy.symbols("x y vx vy")

CASES = [
    (dict(positive=True), [-2, 0, "-1/2", -1e-300], [2, 0.5, "3"], "positive=True"),
    (dict(integer=True), [0.5, "1/2", 2.25], [2.0, 3, -4, "5"], "integer=True"),
    (dict(nonnegative=True), [-1e-300, -3], [0.0, 0, 1], "nonnegative=True"),
    (dict(negative=True), [0, 1], [-1, "-1/3"], "negative=True"),
    (dict(nonzero=True), [0, 0.0], [1e-300, -2], "nonzero=True"),
    (dict(even=True), [3, -1], [4.0, -2], "even=True"),
]


def _system(c, **kw):
    # sqrt(c**2) is c for c positive (the derivation used that): a negative value is a wrong model
    return ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - sympy.sqrt(c ** 2) * x ** 2 / 2, [vy - x * vx],
                                     [x, y], [vx, vy], **kw)


@pytest.mark.parametrize("assume, bad, good, named", CASES)
def test_contradicting_values_are_refused_on_every_path(assume, bad, good, named):
    c = sympy.Symbol("c", **assume)
    S = _system(c, params=[c])
    for val in bad:
        with pytest.raises(SystemDefinitionError) as err:
            S.with_params({c: val})
        msg = str(err.value)
        assert f"parameter c = {val}" in msg and named in msg and "\n" not in msg
        with pytest.raises(SystemDefinitionError, match=named):
            _system(c, params={c: val})
        with pytest.raises(SystemDefinitionError, match=named):
            ldaspark.integrate(S, "gauss-2", t_span=(0, 0.1), q0=[0.1, 0], v0=[0, 0], h=0.05, params={"c": val},
                               engine="generic")
    for val in good:                 # the control: values that satisfy the assumption are taken
        assert S.with_params({c: val}).param_values()[c] == (sympy.Rational(val) if isinstance(val, str) else val)


def test_the_refusal_matters_positive_symbol_simplified_abs():
    """Why: with c positive, sqrt(c**2) was derived as c; c = -2 would integrate the model with
    -2 where |c| = 2 belongs (a different, unstable system)."""
    c = sympy.Symbol("c", positive=True)
    assert sympy.sqrt(c ** 2) == c
    p = sympy.Symbol("p")
    r = ldaspark.integrate(_system(p, params={p: -2}), "gauss-2", t_span=(0, 0.2), q0=[0.1, 0], v0=[0, 0], h=0.05,
                           engine="generic")
    s = ldaspark.integrate(_system(c, params={c: 2}), "gauss-2", t_span=(0, 0.2), q0=[0.1, 0], v0=[0, 0], h=0.05,
                           engine="generic")
    assert np.abs(np.asarray(r.q) - np.asarray(s.q)).max() < 1e-12     # |p| = 2: the same as c = 2
