"""``from_mechanics`` refuses a non-symmetric inertia dyadic (issue 45, class 8): sympy stores
any dyadic it is given, and T = w . I . w / 2 would silently use only its symmetric part."""
import pytest
import sympy
import sympy.physics.mechanics as me

from ldaspark import LagrangianSystem
from ldaspark.core.errors import SystemDefinitionError

t = me.dynamicsymbols._t


def _top(extra):
    """A body turning about N.z (angle q, speed u) whose central inertia is inertia(...) + extra(B)."""
    q, u = me.dynamicsymbols("q u")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_axis(N, N.z, q)
    O = me.Point("O")
    O.set_vel(N, 0)
    m, a, b, c = sympy.symbols("m a b c", positive=True)
    inertia = me.inertia(B, a, b, c) + extra(B)
    body = me.RigidBody("rotor", O, B, m, (inertia, O))
    return me.KanesMethod(N, [q], [u], [q.diff(t) - u], bodies=[body], forcelist=[])


@pytest.mark.parametrize("extra", [
    lambda B: sympy.Rational(1, 2) * (B.x | B.y),                 # a number in one product
    lambda B: sympy.Symbol("d") * (B.z | B.x),                    # a symbol
    lambda B: 0.25 * ((B.y | B.z) - (B.z | B.y)),                 # an antisymmetric part alone
], ids=["number", "symbol", "antisymmetric"])
def test_a_non_symmetric_inertia_is_refused_naming_the_body(extra):
    with pytest.raises(SystemDefinitionError) as ei:
        LagrangianSystem.from_mechanics(_top(extra))
    msg = str(ei.value)
    assert "\n" not in msg and "rotor" in msg and "not symmetric" in msg and "inertia(" in msg


@pytest.mark.parametrize("extra", [
    lambda B: 0 * (B.x | B.x),
    lambda B: sympy.Symbol("d") * ((B.x | B.z) + (B.z | B.x)),    # products of inertia, symmetric
], ids=["diagonal", "products"])
def test_a_symmetric_inertia_is_accepted(extra):
    """Negative control: the same bodies with symmetric inertia are read, T = I_zz q'^2 / 2."""
    s = LagrangianSystem.from_mechanics(_top(extra))
    c = [p for p in s.params if str(p) == "c"][0]
    assert sympy.expand(s.L - c * s.v[0] ** 2 / 2) == 0
