"""The names ``from_mechanics`` derives never capture a model's own symbols (issue 45, class 2).

q_i'(t) becomes the symbol v_<q_i> unless the model already has a symbol of that name (a constant
v_x, another coordinate v_x, a name equal to the fresh one): then the velocity gets a fresh name
(trailing underscores) and the model's symbol stays a parameter. A coordinate x(t) beside a
constant x would make both one symbol: refused in one line."""
import pytest
import sympy
import sympy.physics.mechanics as me

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import SystemDefinitionError

t = me.dynamicsymbols._t


def _by_name(syms):
    return {str(s): s for s in syms}


@pytest.mark.parametrize("const_names", [["v_x"], ["v_x", "v_x_"], ["_v_x"], ["u1"], ["v_x_", "v_x__"]])
def test_a_constant_named_like_a_derived_velocity_stays_a_constant(const_names):
    """L = m x'^2 / 2 - c x with c named v_x (and neighbours): c stays a parameter, the velocity of
    x is a fresh symbol, and the motion is x'' = -c / m (checked symbolically and by integrate)."""
    x = me.dynamicsymbols("x")
    m = sympy.Symbol("m", positive=True)
    consts = [sympy.Symbol(nm) for nm in const_names]
    c = consts[0]
    L = m * x.diff(t) ** 2 / 2 - c * x - sum(cc * x ** 2 for cc in consts[1:])
    s = LagrangianSystem.from_mechanics(L, q=[x])
    v = s.v[0]
    assert str(v) not in const_names and v not in consts
    assert set(consts) <= set(s.params)
    # two-sided: grad_v L is m v exactly (with the velocity captured by the constant it would not be)
    assert sympy.expand(s.L.diff(v) - m * v) == 0
    assert sympy.expand(s.L.diff(s.q[0]) - (-c - 2 * sum(consts[1:], sympy.S.Zero) * s.q[0])) == 0
    if len(consts) == 1:
        pv = {"m": 2.0, str(c): 3.0}
        r = ldaspark.integrate(s, "gauss-2", t_span=(0, 1.0), q0=[0.5], v0=[0.25], h=0.25, params=pv,
                               engine="generic")
        exact = 0.5 + 0.25 - 3.0 / 2.0 / 2                # x(1) = x0 + v0 - (c/m)/2; gauss-2 is exact on it
        assert abs(r.q[-1][0] - exact) <= 1e-13        # a quadratic: only round-off of 4 steps


def test_the_merged_reading_would_differ(monkeypatch):
    """Negative control: naming the velocity v_x whatever the model holds (the old reading, made
    here by a ``_final_names`` without the freshening) merges it with the constant, and grad_v L
    is no longer m v: the check above separates the two."""
    import ldaspark.core.mechanics as mech

    def plain(exprs, forces, qsym, vsym, tsym, added):
        ren = {x: sympy.Symbol(x.name) for x in list(qsym) + list(vsym)}
        return ([e.xreplace(ren) for e in exprs], forces, [ren[x] for x in qsym], [ren[x] for x in vsym], added)
    monkeypatch.setattr(mech, "_final_names", plain)
    x = me.dynamicsymbols("x")
    m, c = sympy.Symbol("m", positive=True), sympy.Symbol("v_x")
    s = LagrangianSystem.from_mechanics(m * x.diff(t) ** 2 / 2 - c * x, q=[x])
    assert str(s.v[0]) == "v_x" and sympy.expand(s.L.diff(s.v[0]) - m * s.v[0]) != 0


def test_coordinates_named_like_velocities_get_distinct_velocities():
    x, vx = me.dynamicsymbols("x v_x")
    L = (x.diff(t) ** 2 + 2 * vx.diff(t) ** 2) / 2 - x * vx
    s = LagrangianSystem.from_mechanics(L, q=[x, vx])
    names = [str(a) for a in list(s.q) + list(s.v)]
    assert len(set(names)) == 4 and names[:2] == ["x", "v_x"]
    assert sympy.expand(s.L.diff(s.v[0]) - s.v[0]) == 0 and sympy.expand(s.L.diff(s.v[1]) - 2 * s.v[1]) == 0


def test_kane_model_with_a_constant_named_like_a_velocity():
    """A particle x' = u1 under a constant force named v_x, with a constant named u1 besides the
    speed u1(t): both constants are parameters; the acceleration is v_x / m."""
    x = me.dynamicsymbols("x")
    u1 = me.dynamicsymbols("u1")
    m, fx, cu = sympy.symbols("m v_x u1")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x)
    P.set_vel(N, u1 * N.x)
    km = me.KanesMethod(N, [x], [u1], [x.diff(t) - u1], bodies=[me.Particle("p", P, m)],
                        forcelist=[(P, fx * cu * N.x)])
    s = LagrangianSystem.from_mechanics(km)
    assert {"v_x", "u1", "m"} <= set(_by_name(s.params)) and str(s.v[0]) not in {"v_x", "u1"}
    p = _by_name(s.params)
    # L = m v^2/2 + v_x u1 x (a constant force has a potential): grad_q L = v_x u1, two-sided
    assert sympy.expand(s.L.diff(s.q[0]) - p["v_x"] * p["u1"]) == 0
    assert sympy.expand(s.L.diff(s.v[0]) - p["m"] * s.v[0]) == 0


@pytest.mark.parametrize("clash", ["x", "t"])
def test_a_coordinate_named_like_a_model_symbol_is_refused(clash):
    x = me.dynamicsymbols(clash)
    other = t if clash == "t" else sympy.Symbol(clash)
    L = x.diff(t) ** 2 / 2 - other * x
    with pytest.raises(SystemDefinitionError) as ei:
        LagrangianSystem.from_mechanics(L, q=[x])
    msg = str(ei.value)
    assert "\n" not in msg and f"coordinate {clash}(t)" in msg


def test_an_added_coordinate_named_like_a_constant_is_renamed():
    """A speed in no kinematic equation (a wheel's spin) gets a coordinate q_<speed> of the
    adapter's; a model constant named q_u2 keeps its name and meaning, the added coordinate is
    renamed (and ``added_coordinates`` names it as renamed)."""
    x = me.dynamicsymbols("x")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m, J, Jt = sympy.symbols("m J Jt", positive=True)
    c = sympy.Symbol("q_u2")
    N, W = me.ReferenceFrame("N"), me.ReferenceFrame("W")
    W.set_ang_vel(N, u2 * N.y)
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x)
    P.set_vel(N, u1 * N.x)
    wheel = me.RigidBody("wheel", P, W, m, (me.inertia(N, Jt, J, Jt), P))
    km = me.KanesMethod(N, [x], [u1, u2], [x.diff(t) - u1], bodies=[wheel], forcelist=[(P, -c * N.x)])
    s = LagrangianSystem.from_mechanics(km)
    assert [str(a) for a in s.q] == ["x", "q_u2_"] and list(s.added_coordinates) == ["q_u2_"]
    assert c in set(s.params)
    # the constant is the force (grad_x L = -q_u2), the spin's velocity carries J: both two-sided
    assert sympy.expand(s.L.diff(s.q[0]) + c) == 0
    J = _by_name(s.params)["J"]
    assert sympy.expand(s.L.diff(s.v[1]) - J * s.v[1]) == 0 and s.L.diff(s.q[1]) == 0
