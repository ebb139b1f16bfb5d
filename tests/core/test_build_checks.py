"""Checks made when a LagrangianSystem is built: physical units are refused at once; velocities
along which L_vv vanishes identically are found and refused at the set-up of integrate (before
step 0), even where the saddle matrix (4) is regular."""
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LagrangianSystem
from ldaspark.core.errors import SingularSaddleError, SystemDefinitionError

x, y, th = sympy.symbols("x y th")
vx, vy, vth = sympy.symbols("vx vy vth")
Q0, V0 = [0.0, 0.0, 0.3], [1.0, float(np.sin(0.3)), 0.5]


def _toy(L):
    return LagrangianSystem(L, [vy - sympy.sin(th) * vx], [x, y, th], [vx, vy, vth], name="toy")


@pytest.mark.parametrize("engine", ["generic", "auto"])
def test_velocity_missing_from_L_is_named_at_set_up(engine, monkeypatch):
    """L without vy, K = (-sin th, 1, 0): (4) is regular, the stage equations are not solvable.
    The set-up names vy (one line); control: with the check switched off the run fails at step 0
    in Newton, and with vy in L it runs."""
    sysm = _toy((vx ** 2 + vth ** 2) / 2 - sympy.cos(th))
    assert "vy" in sysm.lvv_problem
    with pytest.raises(SingularSaddleError) as err:
        ldaspark.integrate(sysm, "gauss-2", n_steps=3, h=0.1, q0=Q0, v0=V0, engine=engine)
    msg = str(err.value)
    assert "L does not contain the velocities vy" in msg and "\n" not in msg
    monkeypatch.setattr(sysm, "lvv_problem", None)
    r = ldaspark.integrate(sysm, "gauss-2", n_steps=3, h=0.1, q0=Q0, v0=V0, engine="generic")
    assert r.status == -1 and "singular" in r.message and len(r.t) == 1
    ok = ldaspark.integrate(_toy((vx ** 2 + vy ** 2 + vth ** 2) / 2 - sympy.cos(th)), "gauss-2", n_steps=3, h=0.1,
                            q0=Q0, v0=V0, engine="generic")
    assert ok.success and ok.coordinate_names == ["x", "y", "th"]


def test_L_affine_in_a_velocity_is_named():
    """A gyroscopic term x vy makes L depend on vy, but only linearly: L_vv still vanishes along it."""
    sysm = _toy((vx ** 2 + vth ** 2) / 2 + x * vy)
    assert "L_vv vanishes along the velocities vy" in sysm.lvv_problem
    assert _toy((vx ** 2 + vth ** 2 + vy ** 2) / 2 + x * vy).lvv_problem is None


def test_physical_units_are_refused_at_build():
    from sympy.physics.units import kilogram, meter, second
    with pytest.raises(SystemDefinitionError) as err:
        _toy(kilogram * (vx ** 2 + vy ** 2 + vth ** 2) / 2 - 9.81 * meter / second ** 2 * x)
    msg = str(err.value)
    assert "physical units" in msg and "kilogram" in msg and "\n" not in msg
    with pytest.raises(SystemDefinitionError, match="physical units"):
        LagrangianSystem((vx ** 2 + vy ** 2 + vth ** 2) / 2, [vy - meter * vx], [x, y, th], [vx, vy, vth])
    assert _toy(2 * (vx ** 2 + vy ** 2 + vth ** 2) / 2 - x).lvv_problem is None     # control: numbers


_L2, _K2 = "(v0**2 + v1**2)/2 - q0", ["v1 - q0*v0"]
_q0, _v0, _v1 = sympy.symbols("q0 v0 v1")
_LS, _KS = (_v0 ** 2 + _v1 ** 2) / 2 - _q0, [_v1 - _q0 * _v0]        # sympy: no name to resolve in q
_BAD_ARGS = {
    "q None": lambda: LagrangianSystem(_LS, _KS, None, ["v0", "v1"]),
    "q a number": lambda: LagrangianSystem(_LS, _KS, 1, ["v0", "v1"]),
    "q a Symbol": lambda: LagrangianSystem(_LS, _KS, _q0, ["v0", "v1"]),
    "v an object": lambda: LagrangianSystem(_LS, _KS, ["q0", "q1"], object()),
    "t a list": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], t=[]),
    "t a number": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], t=1),
    "t bytes": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], t=b"t"),
    "t an array": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], t=np.array([])),
    "nonideal a number": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], nonideal=1),
    "nonideal bytes": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], nonideal=b"q0"),
    "nonideal nested": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], nonideal=[["q0"], [0]]),
    "psi a number": lambda: LagrangianSystem(_L2, _K2, ["q0", "q1"], ["v0", "v1"], nonideal=["psi1", 0], psi=1),
    "mechanical_form M None": lambda: LagrangianSystem.mechanical_form(None, "q0", [[1, 1]]),
    "mechanical_form M a number": lambda: LagrangianSystem.mechanical_form(1.5, "q0", [[1, 1]]),
    "mechanical_form M text": lambda: LagrangianSystem.mechanical_form("x", "q0", [[1, 1]]),
    "mechanical_form U None": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), None, [[1, 1]]),
    "mechanical_form U a dict": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), {}, [[1, 1]]),
    "mechanical_form U bytes": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), b"q0", [[1, 1]]),
    "mechanical_form U True": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), True, [[1, 1]]),
    "mechanical_form U an object": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), object(), [[1, 1]]),
    "mechanical_form q a number": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), "q0", [[1, 1]], q=1),
    "mechanical_form q an array": lambda: LagrangianSystem.mechanical_form(sympy.eye(2), "x", [[1, 1]],
                                                                         q=np.array([])),
}


@pytest.mark.parametrize("case", sorted(_BAD_ARGS))
def test_arguments_of_the_wrong_type_are_one_system_definition_error(case):
    """Each argument of the wrong type (a number, None, bytes, an object where a list of symbols,
    a time symbol, a list of N components, a matrix or a scalar U belongs) is a
    SystemDefinitionError, not the TypeError, SympifyError or ValueError of the code below; bytes
    are not read as a list of small integers (nonideal=b"q0" was N = (113, 48)). Controls: the
    well-typed neighbours build."""
    with pytest.raises(SystemDefinitionError) as err:
        _BAD_ARGS[case]()
    assert "\n" not in str(err.value)
    assert LagrangianSystem(_L2, _K2, ("q0", "q1"), np.array(["v0", "v1"]), t="t",
                            nonideal=["psi1", 0], psi=("psi1",)).n == 2
    assert LagrangianSystem.mechanical_form(np.eye(2), 1, [[1, 1]], q=("x", "y")).m == 1


def _mech_off_box(U, c=1):
    """L = |v|^2/2 - sqrt(q0 - 1), k = v1 - sqrt(q0 - 1) v0 with the mechanical parts U and
    K = (-c sqrt(q0 - 1), 1): every test point in [0.3, 0.7] is outside the domain q0 >= 1 of L
    and k, so the identities L = v^T M v / 2 - U, k = K v must be decided elsewhere."""
    q0, q1, v0, v1 = sympy.symbols("q0 q1 v0 v1")
    r = sympy.sqrt(q0 - 1)
    return LagrangianSystem((v0 ** 2 + v1 ** 2) / 2 - r, [v1 - r * v0], [q0, q1], [v0, v1],
                            mechanical={"M": sympy.eye(2), "U": U(r) if callable(U) else U,
                                        "K": sympy.Matrix([[-c * r, 1]])})


@pytest.mark.parametrize("U, c", [
    (lambda r: 2 * r, 1),       # U twice L's: the compiled engine ran another system
    (sympy.nan, 1),
    (sympy.zoo, 1),
    (lambda r: r, 2),           # K v != k
])
def test_mechanical_parts_are_compared_outside_the_first_test_box(U, c):
    """The mechanical parts were compared with L and k only at points in [0.3, 0.7]; where L was
    complex at all of them no point was tested and any U (2 sqrt(q0 - 1) for sqrt(q0 - 1), nan)
    or K was accepted: with L = |v|^2/2 - sqrt(q0 - 1), k = v1 - v0 and U = 2 sqrt(q0 - 1), from
    q0 = (2, 0), v0 = (1, 1), h = 0.1, t = 1 gauss-2 ended at q0 = 2.890 on the generic engine (L)
    and 2.778 on the compiled one (U), energies 2.0 and 3.0, both status 0.
    Control: the matching parts are accepted."""
    with pytest.raises(SystemDefinitionError, match="mechanical parts do not match"):
        _mech_off_box(U, c)
    assert _mech_off_box(lambda r: r).mechanical is not None


def test_mechanical_form_text_may_use_the_time_t():
    """The system's time t is a declared name of the text of mechanical_form, as it is of
    LagrangianSystem's (U, K, b may depend on t: the compiled engine's U(t, q), b(t, q)):
    b = ["sin(t)"] was refused (unknown name 't') while b = [sin(t)] in sympy was taken."""
    t = sympy.Symbol("t")
    text = LagrangianSystem.mechanical_form(sympy.eye(2), "q0**2 * (1 + cos(t))", [[1, 1]], b=["sin(t)"])
    sym = LagrangianSystem.mechanical_form(sympy.eye(2), text.q[0] ** 2 * (1 + sympy.cos(t)), [[1, 1]],
                                           b=[sympy.sin(t)])
    assert text.L == sym.L and list(text.k) == list(sym.k) and text.t == sym.t == t


def test_mechanical_form_takes_parameters_and_the_time_symbol():
    """mechanical_form had neither ``params`` nor ``t``: M = diag(a, 1) was refused with "declare them
    with params=[...]", and params=[a] was a TypeError (not an LdasparkError); a time symbol with
    assumptions (Symbol("t", real=True)) in U was refused as a second 't' that could not be
    renamed. Both are taken now, as by LagrangianSystem: the same L, k and parameters as the
    system built from L and k, the same numbers from integrate (generic engine, 20 steps: equal to
    the last bit, the same derived expressions). Control: an undeclared symbol is still refused."""
    a = sympy.Symbol("a", positive=True)
    t = sympy.Symbol("t", real=True)
    M, U, K = sympy.diag(a, 1, 1), a * x ** 2 / 2 + sympy.sin(t) * y, [[-sympy.sin(th), 1, 0]]
    mech = LagrangianSystem.mechanical_form(M, U, K, q=[x, y, th], v=[vx, vy, vth], params=[a], t=t)
    text = LagrangianSystem.mechanical_form([["a", 0, 0], [0, 1, 0], [0, 0, 1]], "a*x**2/2 + sin(t)*y",
                                            [["-sin(th)", 1, 0]], q=["x", "y", "th"], v=["vx", "vy", "vth"],
                                            params=[a], t=t)
    V = sympy.Matrix([vx, vy, vth])
    direct = LagrangianSystem((V.T * M * V)[0, 0] / 2 - U, [vy - sympy.sin(th) * vx], [x, y, th], [vx, vy, vth],
                              t=t, params=[a])
    assert mech.params == text.params == direct.params == (a,) and mech.t is t and text.t is t
    assert sympy.expand(mech.L - direct.L) == 0 and sympy.expand(text.L - direct.L) == 0
    assert list(mech.k) == list(direct.k)
    runs = [ldaspark.integrate(s, "gauss-2", t_span=(0, 0.4), q0=Q0, v0=V0, h=0.02, params={"a": 1.5},
                               engine="generic") for s in (mech, direct)]
    assert runs[0].status == runs[1].status == 0
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].v, runs[1].v)
    with pytest.raises(SystemDefinitionError, match="params"):
        LagrangianSystem.mechanical_form(M, U, K, q=[x, y, th], v=[vx, vy, vth], t=t)
    with pytest.raises(SystemDefinitionError, match="'t'"):
        LagrangianSystem.mechanical_form(M, U, K, q=[x, y, th], v=[vx, vy, vth], params=[a])


def _plane(mech):
    """The toy's kinetic part with a heading constraint, with the mechanical parts ``mech`` (the
    value 0 of M or K: the system's own)."""
    V = sympy.Matrix([vx, vy, vth])
    M, K = sympy.diag(2, 2, 1), sympy.Matrix([[-sympy.sin(th), 1, 0]])
    return LagrangianSystem((V.T * M * V)[0, 0] / 2, list(K * V), [x, y, th], [vx, vy, vth], name="plane",
                            mechanical={key: {"M": M, "K": K}[key] if val == 0 and key in "MK" else val
                                                for key, val in mech.items()})


@pytest.mark.parametrize("mech, why", [({"M": 0}, "has no K"), ({"M": 0, "U": 0, "K": None}, "has no K"),
                                       ({"M": 0, "K": 0, "B": [0]}, r"keys \['B'\]")])
def test_mechanical_parts_without_K_or_with_an_unknown_key_are_refused_at_build(mech, why):
    """A mechanical dict without K (or K None), or with a key it does not know ("B" for b), was
    built; then the compiled engine failed with "compilation failed (KeyError)" and fell back,
    and the generic semi-implicit comparators raised a bare KeyError 'K' (or 'b', where the
    compiled kernel had taken b = 0). Refused at build now, naming the key. Control: M and K
    alone (U and b omitted, both 0) run every engine with the same numbers."""
    with pytest.raises(SystemDefinitionError, match=why):
        _plane(mech)
    system = _plane({"M": 0, "K": 0})
    runs = [ldaspark.integrate(system, "lobatto-iiia-iiib-2-leapfrog", t_span=(0, 0.2), q0=Q0, v0=V0, h=0.02,
                               engine=engine) for engine in ("generic", "compiled")]
    assert runs[0].status == runs[1].status == 0
    # 10 steps solved to round-off (2.2e-16) of states ~1, saddle matrices (4) of condition ~2: 1e-13
    assert np.abs(np.asarray(runs[0].q, float) - runs[1].q).max() < 1e-13


@pytest.mark.parametrize("U", [x, sympy.Max(0, x)])
def test_mechanical_parts_equal_to_L_on_the_test_box_only_are_refused(U):
    """L = |v|^2/2 - Abs(x) with the mechanical part U = x: equal on [0.3, 0.7], where the parts were
    compared with L, and not for x < 0, where the compiled engine (U) and the generic one (L)
    integrate different systems. Compared at points of every sign too now (``signed_points``).
    Control: U = Abs(x), and Max(x, -x) (the same function spelt otherwise), are built."""
    def build(u):
        return LagrangianSystem((vx ** 2 + vy ** 2 + vth ** 2) / 2 - sympy.Abs(x), [vth - sympy.sin(x) * vy],
                                [x, y, th], [vx, vy, vth],
                                mechanical={"M": sympy.eye(3), "U": u, "K": [[0, -sympy.sin(x), 1]]})
    with pytest.raises(SystemDefinitionError, match="do not match L and k"):
        build(U)
    assert build(sympy.Abs(x)).mechanical is not None and build(sympy.Max(x, -x)).mechanical is not None
