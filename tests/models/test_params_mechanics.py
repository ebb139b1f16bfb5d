"""Parameters without re-derivation, ensembles over parameters, the sympy.physics.mechanics
adapter (Chaplygin sleigh) and the rejection of dynamicsymbols by the plain constructor."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import LdasparkWarning, SystemDefinitionError

M, I = sympy.symbols("m I", positive=True)


def _skate_like(m, i, **kw):
    """A skate (8.2) pushed by a unit force along q1 (so that the mass matters) and a torsion
    spring on q3 (so that the inertia matters)."""
    q, v = sympy.symbols("q1:4"), sympy.symbols("v1:4")
    L = m * (v[0] ** 2 + v[1] ** 2) / 2 + i * v[2] ** 2 / 2 - q[0] - q[2] ** 2 / 2
    k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0]]
    return LagrangianSystem(L, k, q, v, name="skate-p", **kw)


def _param_skate():
    return _skate_like(M, I, params=[M, I])


def test_parameters_match_substituted_system_without_rederiving(monkeypatch):
    sysm = _param_skate()
    kw = dict(n_steps=10, h=0.1, q0=[0, 0, 0], v0=[0, 0, 1], engine="generic")
    first = ldaspark.integrate(sysm, "gauss-2", params={M: 2.0, "I": 3.0}, **kw)
    calls = []
    real_lambdify, real_derive = sympy.lambdify, LagrangianSystem._derive
    monkeypatch.setattr(sympy, "lambdify", lambda *a, **k: calls.append("lambdify") or real_lambdify(*a, **k))
    monkeypatch.setattr(LagrangianSystem, "_derive", lambda self: calls.append("derive") or real_derive(self))
    second = ldaspark.integrate(sysm, "gauss-2", params={"m": 5.0, "I": 0.5}, **kw)
    assert calls == []                                            # new values, nothing derived again
    monkeypatch.undo()
    for res, (m, i) in ((first, (2, 3)), (second, (5, sympy.Rational(1, 2)))):
        ref = ldaspark.integrate(_skate_like(sympy.sympify(m), sympy.sympify(i)), "gauss-2", **kw)
        assert np.abs(res.q - ref.q).max() < 1e-12 and np.abs(res.energy - ref.energy).max() < 1e-12
        assert res.params == {"m": float(m), "I": float(i)}
    assert np.abs(first.q - second.q).max() > 1e-3               # control: the parameter matters
    # the control that the counter sees derivations: building a system derives
    n0 = len(calls)
    monkeypatch.setattr(LagrangianSystem, "_derive", lambda self: calls.append("derive") or real_derive(self))
    _param_skate()
    assert len(calls) == n0 + 1


def test_missing_and_unknown_parameters():
    sysm = _param_skate()
    with pytest.raises(SystemDefinitionError, match="no value for parameter"):
        ldaspark.integrate(sysm, "gauss-2", n_steps=2, h=0.1, q0=[0, 0, 0], v0=[0, 0, 1], params={"m": 1})
    # a value for a symbol the model does not have is ignored with a note, not refused ...
    with pytest.warns(LdasparkWarning, match="g is not a parameter"):
        view = sysm.with_params({"g": 1, "m": 2})
    assert {str(p): v for p, v in view.param_values().items()} == {"m": 2}
    kw = dict(n_steps=2, h=0.1, q0=[0, 0, 0], v0=[0, 0, 1])
    with pytest.warns(LdasparkWarning, match="g is not a parameter"):
        noted = ldaspark.integrate(sysm, "gauss-2", params={"m": 1, "I": 1, "g": 9.81}, **kw)
    assert np.array_equal(noted.q, ldaspark.integrate(sysm, "gauss-2", params={"m": 1, "I": 1}, **kw).q)
    # ... and a misspelled name still fails, as the real parameter's missing value
    with pytest.warns(LdasparkWarning), pytest.raises(SystemDefinitionError, match="no value for parameter.*I"):
        ldaspark.integrate(sysm, "gauss-2", params={"m": 1, "i": 1}, **kw)
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    with pytest.raises(SystemDefinitionError, match="params"):
        LagrangianSystem(M * v[0] ** 2 / 2 + v[1] ** 2 / 2, [v[1] - q[0] * v[0]], q, v)


def test_ensemble_over_parameters():
    sysm = _param_skate()
    kw = dict(n_steps=5, h=0.1, q0=[0, 0, 0], v0=[0, 0, 1])
    ens = ldaspark.integrate(sysm, "gauss-2", params=[{"m": 1, "I": 1}, {"m": 2, "I": 1}], engine="generic", **kw)
    assert ens.batch == 2 and ens.q.shape == (2, 6, 3) and ens.success
    one = ldaspark.integrate(sysm, "gauss-2", params={"m": 2, "I": 1}, engine="generic", **kw)
    assert np.array_equal(ens.q[1], one.q)
    ref = ldaspark.integrate(_skate_like(1, 1), "gauss-2", engine="generic", **kw)
    assert np.abs(ens.q[0] - ref.q).max() < 1e-12


def test_plain_constructor_rejects_dynamicsymbols():
    from sympy.physics.mechanics import dynamicsymbols
    x, y = dynamicsymbols("x y")
    with pytest.raises(SystemDefinitionError) as err:
        LagrangianSystem(x.diff() ** 2 / 2 + y.diff() ** 2 / 2, [y.diff() - x * x.diff()], [x, y],
                         [x.diff(), y.diff()])
    assert "dynamicsymbols" in str(err.value) and "\n" not in str(err.value)


def _sleigh_mechanics():
    """Chaplygin sleigh: a rigid body of mass m, inertia I about its centre G at distance a along
    the blade from the contact point P = (x, y); the blade does not slip sideways."""
    import sympy.physics.mechanics as me
    x, y, th = me.dynamicsymbols("x y theta")
    m, i, a = sympy.symbols("m I a")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, P.pos_from(O).dt(N))
    G = P.locatenew("G", a * B.x)
    G.v2pt_theory(P, N, B)
    body = me.RigidBody("body", G, B, m, (me.inertia(B, 0, 0, i), G))
    lm = me.LagrangesMethod(me.Lagrangian(N, body), [x, y, th], nonhol_coneqs=[P.vel(N).dot(B.y)], frame=N)
    return LagrangianSystem.from_mechanics(lm, name="sleigh")


def _sleigh_by_hand():
    q = sympy.symbols("x y theta")
    v = sympy.symbols("vx vy vtheta")
    m, i, a = sympy.symbols("m I a")
    c, s = sympy.cos(q[2]), sympy.sin(q[2])
    vg = (v[0] - a * s * v[2], v[1] + a * c * v[2])          # velocity of G
    L = m * (vg[0] ** 2 + vg[1] ** 2) / 2 + i * v[2] ** 2 / 2
    return LagrangianSystem(L, [-s * v[0] + c * v[1]], q, v, name="sleigh-hand", params=[m, i, a])


def test_chaplygin_sleigh_from_mechanics_matches_hand_built():
    mech, hand = _sleigh_mechanics(), _sleigh_by_hand()
    assert [str(p) for p in mech.params] == ["I", "a", "m"]
    vals = {"m": 1.0, "I": 0.5, "a": 0.3}
    kw = dict(n_steps=100, h=0.05, q0=[0, 0, 0], v0=[1, 0, 0.8], params=vals, engine="generic")
    r1 = ldaspark.integrate(mech, "gauss-2", **kw)
    r2 = ldaspark.integrate(hand, "gauss-2", **kw)
    assert r1.success and r2.success
    assert np.abs(r1.q - r2.q).max() < 1e-12 and np.abs(r1.v - r2.v).max() < 1e-12
    assert np.abs(r1.constraint).max() < 1e-14                                 # (21f) at every step
    # control: a different centre offset gives a different trajectory
    r3 = ldaspark.integrate(hand, "gauss-2", **dict(kw, params=dict(vals, a=0.31)))
    assert np.abs(r3.q - r1.q).max() > 1e-4


def test_from_mechanics_plain_lagrangian_and_refusals():
    from sympy.physics.mechanics import dynamicsymbols
    x, y, z = dynamicsymbols("x y z")
    L = (x.diff() ** 2 + y.diff() ** 2 + z.diff() ** 2) / 2 - (x ** 2 + y ** 2)
    sysm = LagrangianSystem.from_mechanics(L, q=[x, y, z], constraints=[z.diff() - y * x.diff()])
    r = ldaspark.integrate(sysm, "gauss-2", n_steps=5, h=0.1, q0=[1, 0, 0], v0=[0, 1, 0], engine="generic")
    ref = ldaspark.integrate("particle", "gauss-2", n_steps=5, h=0.1, engine="generic")
    assert np.abs(r.q - ref.q).max() < 1e-14
    free = LagrangianSystem.from_mechanics(L, q=[x, y, z])   # no constraints: m = 0, a PRK method
    assert free.m == 0
    rf = ldaspark.integrate(free, "gauss-2", n_steps=5, h=0.1, q0=[1, 0, 0], v0=[0, 1, 0], engine="generic")
    assert np.abs(rf.q - r.q).max() > 1e-4    # the constraint changed the motion; without it z stays 0
    assert np.abs(rf.q[:, 2]).max() == 0.0
    with pytest.raises(SystemDefinitionError, match="second time derivatives"):
        LagrangianSystem.from_mechanics(L + x.diff().diff(), q=[x, y, z], constraints=[z.diff() - y * x.diff()])


# --- derived systems are independent of their source (no shared state) ---------------------------
def test_with_params_copies_are_independent_of_the_source_and_of_each_other():
    src = _param_skate()
    a = src.with_params(m=1.0, I=1.0)
    b = src.with_params({M: 2.0, "I": 1.0})
    c = a.with_params(m=3.0)                     # derived from a derived system
    assert src.param_values() == {}
    assert a.param_values() == {M: 1.0, I: 1.0} and b.param_values() == {M: 2.0, I: 1.0}
    assert c.param_values() == {M: 3.0, I: 1.0}
    for x in (a, b, c):                          # mutable containers are not shared
        assert x.q is not src.q and x.v is not src.v and x.psi is not src.psi
    a.q[0] = sympy.Symbol("zz")
    assert str(src.q[0]) == "q1" and str(b.q[0]) == "q1"
    a.q[0] = src.q[0]
    with pytest.raises(SystemDefinitionError, match="no value"):
        src.substituted()                        # the source still has no values
    # substituted() of each carries its own values
    assert a.substituted().L != b.substituted().L and not a.substituted().params
    assert sympy.simplify(a.substituted().L - _skate_like(1, 1).L) == 0


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_runs_of_derived_systems_do_not_see_each_others_values(engine):
    """a and b derived from one source, run interleaved (the compiled engine generates a model per
    set of values: the cached models must be keyed by the values, not the source system): each
    equals a system built by hand with its values (to 1e-12; the same method on the same data)."""
    src = _param_skate()
    kw = dict(n_steps=10, h=0.1, q0=[0, 0, 0], v0=[0, 0, 1], engine=engine)
    a, b = src.with_params(m=1, I=1), src.with_params(m=2, I=1)
    ra = ldaspark.integrate(a, "gauss-2", **kw)
    rb = ldaspark.integrate(b, "gauss-2", **kw)
    ra2 = ldaspark.integrate(a, "gauss-2", **kw)
    ref_a = ldaspark.integrate(_skate_like(1, 1), "gauss-2", **kw)
    ref_b = ldaspark.integrate(_skate_like(2, 1), "gauss-2", **kw)
    assert np.abs(ra.q - ref_a.q).max() < 1e-12 and np.abs(ra2.q - ref_a.q).max() < 1e-12
    assert np.abs(rb.q - ref_b.q).max() < 1e-12
    assert np.abs(ra.q - rb.q).max() > 1e-3                 # control: the values matter
    assert ra.engine == engine and rb.engine == engine
