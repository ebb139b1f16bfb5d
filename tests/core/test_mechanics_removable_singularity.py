"""``from_mechanics`` cancels the removable singularities that inverting the kinematic
differential equations creates, before code generation (issue 47, item 5).

A KanesMethod model with body-frame speeds and kinematics written q' = R(theta) u (the snakeboard
and the Chaplygin sleigh are written so) is mapped to (1) by solving the kinematics for u; the
solve divides by pivots such as cos(theta) + sin(theta)^2 / cos(theta), so k acquired denominators
like (-sin^2 - cos^2) cos(theta): 0/0 where the pivot's cosine (or sine) vanishes, NaN in float64
where it is exactly 0 (theta = 0 for a sine pivot). After the fix, k is the polynomial
u_dep(q, v) - a v_theta (u = R(theta)^T v) and its generated code is exact to round-off at and
around the removed singularity."""
import math

import mpmath
import numpy as np
import pytest
import sympy
import sympy.physics.mechanics as me

import ldaspark.core.mechanics as mech
from ldaspark import LagrangianSystem
from ldaspark.core.backend import Backend
from ldaspark.core.errors import LdasparkError


def _sleigh(dependent="u2", kinematics="rotated"):
    """The Chaplygin sleigh the Kane way: speeds u1, u2 along the body axes, u3 the yaw rate; the
    dependent speed (u2: the contact slides only along B.x; or u1) obeys u_dep - a u3 = 0."""
    t = me.dynamicsymbols._t
    x, y, th = me.dynamicsymbols('x y theta')
    u1, u2, u3 = me.dynamicsymbols('u1:4')
    m, inertia_z, a = sympy.symbols('m I a', positive=True)
    N, B = me.ReferenceFrame('N'), me.ReferenceFrame('B')
    B.orient_axis(N, N.z, th)
    B.set_ang_vel(N, u3 * N.z)
    O = me.Point('O')
    O.set_vel(N, 0)
    G = O.locatenew('G', x * N.x + y * N.y)
    G.set_vel(N, u1 * B.x + u2 * B.y)
    body = me.RigidBody('sleigh', G, B, m, (me.inertia(B, 0, 0, inertia_z), G))
    c, s = sympy.cos(th), sympy.sin(th)
    if kinematics == "rotated":          # q' = R(theta) u: solving for u divides by pivots
        kd = [x.diff(t) - (c * u1 - s * u2), y.diff(t) - (s * u1 + c * u2), th.diff(t) - u3]
    else:                                # u = R(theta)^T q': nothing to invert
        kd = [u1 - (c * x.diff(t) + s * y.diff(t)), u2 - (-s * x.diff(t) + c * y.diff(t)), u3 - th.diff(t)]
    dep, ind = (u2, u1) if dependent == "u2" else (u1, u2)
    return me.KanesMethod(N, [x, y, th], [ind, u3], kd, u_dependent=[dep], velocity_constraints=[dep - a * u3],
                          bodies=[body], forcelist=[])


P = {"m": 1.3, "I": 0.7, "a": 0.4}
V = (0.9, -1.7, 0.6)          # v_x, v_y, v_theta (k need not vanish to be evaluated)
#: dependent speed -> the angle where its solve's pivot vanishes
SINGULAR = {"u2": math.pi / 2, "u1": 0.0}


def _true_k(system, dependent):
    """sign * (u_dep(q, v) - a v_theta), the sign that makes it k identically (two-sided check)."""
    th = sympy.Symbol("theta")
    a = [p for p in system.params if str(p) == "a"][0]
    vx, vy, vt = system.v
    udep = {"u1": sympy.cos(th) * vx + sympy.sin(th) * vy, "u2": -sympy.sin(th) * vx + sympy.cos(th) * vy}[dependent]
    ref = udep - a * vt
    k = system.k[0]
    signs = [sg for sg in (1, -1) if sympy.expand(sympy.trigsimp(k - sg * ref)) == 0]
    assert len(signs) == 1, k
    return sympy.lambdify([th, vx, vy, vt, a], signs[0] * ref, "mpmath")


def _exact(f, theta):
    """The simplified k at (theta, V) at 50 digits (theta taken as the binary value)."""
    with mpmath.workdps(50):
        return float(f(mpmath.mpf(theta), *map(mpmath.mpf, V), mpmath.mpf(P["a"])))


def _thetas(th0):
    return [th0, th0 + 1e-9, th0 - 1e-9, math.nextafter(th0, 4), math.nextafter(th0, -4)]


def _k_value(system, theta):
    return float(system.with_params(P).constraint(Backend(None), 0.0, np.array([0.2, -0.3, theta]),
                                                  np.array(V))[0])


@pytest.mark.parametrize("kinematics", ["rotated", "inverse"])
@pytest.mark.parametrize("dependent", ["u2", "u1"])
def test_k_has_no_denominator_and_is_exact_near_the_removed_singularity(dependent, kinematics):
    s = LagrangianSystem.from_mechanics(_sleigh(dependent, kinematics))
    assert sympy.fraction(sympy.together(s.k[0]))[1].is_number, s.k[0]
    f = _true_k(s, dependent)
    for theta in _thetas(SINGULAR[dependent]):
        got = _k_value(s, theta)
        # |k| <= 3: the evaluation rounds a few terms of size <= 2, so 8 ulp of 4 is a strict bound
        assert abs(got - _exact(f, theta)) <= 8 * 4 * np.finfo(float).eps, (theta, got, _exact(f, theta))


def test_without_the_cancellation_k_keeps_the_pivot_and_fails_there(monkeypatch):
    """Negative control: with the solve's pivots kept (the cancellation made the identity) k has a
    trigonometric denominator, and at theta = 0, where the sine pivot is exactly 0 in float64, its
    generated code gives no finite value."""
    monkeypatch.setattr(mech, "_cancel_trig", lambda e, ops=0: e)
    s = LagrangianSystem.from_mechanics(_sleigh("u1"))
    assert not sympy.fraction(sympy.together(s.k[0]))[1].is_number
    try:
        with np.errstate(all="ignore"):
            val = _k_value(s, 0.0)
    except (LdasparkError, ZeroDivisionError, FloatingPointError):
        return
    assert not math.isfinite(val), val
