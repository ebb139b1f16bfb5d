"""A frame oriented by a compound rotation in one step agrees with sympy's own equations
(issue 49: "a direction-cosine rate transposed in from_mechanics, only frames oriented in one
compound step see it").

A heavy asymmetric top about a fixed point, written the Kane way: B oriented from N in one step
(``orient_body_fixed(..., 'XYZ')`` or ``orient_space_fixed``), its angular velocity *set* in the
speeds u (so ``from_mechanics`` derives it from the direction cosines, ``_w_from_dcm``), its mass
centre at l B.z from the fixed point. The accelerations of the system (its ODE (3a-b)) mapped to
u' agree with those of sympy's KanesMethod (mass_matrix_full x' = forcing_full) at random states.
The negative control plants the transposition (C^T C' in place of C' C^T, which equals it for a
rotation about one axis) and the same check fails."""
import numpy as np
import pytest
import sympy
import sympy.physics.mechanics as me

import ldaspark.core.mechanics as mech
from ldaspark import LagrangianSystem
from ldaspark.core.backend import Backend
from ldaspark.core.errors import SystemDefinitionError

t = me.dynamicsymbols._t
P = {"m": 1.7, "l": 0.6, "g": 9.81, "Ixx": 0.9, "Iyy": 0.5, "Izz": 0.3, "Ixy": 0.07}
#: the accelerations are O(10-100); the two routes solve 3x3 systems of condition ~10 in
#: float64, so 1e-10 relative leaves a margin of 1e3 over round-off and is far below the
#: O(1) differences a wrong angular velocity makes
TOL = 1e-10


def _top(how):
    q = me.dynamicsymbols("q1:4")
    u = me.dynamicsymbols("u1:4")
    m, l, g, ixx, iyy, izz, ixy = sympy.symbols("m l g Ixx Iyy Izz Ixy")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    if how == "body_XYZ":
        B.orient_body_fixed(N, q, "XYZ")
    elif how == "space_ZXY":
        B.orient_space_fixed(N, q, "ZXY")
    else:                                  # three steps: each elementary (the rate is never transposed)
        A, C = me.ReferenceFrame("A"), me.ReferenceFrame("C")
        A.orient_axis(N, N.x, q[0])
        C.orient_axis(A, A.y, q[1])
        B.orient_axis(C, C.z, q[2])
    w = B.ang_vel_in(N)
    kd = [u[i] - w.dot(e) for i, e in enumerate((B.x, B.y, B.z))]
    B.set_ang_vel(N, u[0] * B.x + u[1] * B.y + u[2] * B.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", l * B.z)
    G.v2pt_theory(O, N, B)
    body = me.RigidBody("top", G, B, m, (me.inertia(B, ixx, iyy, izz, ixy), G))
    km = me.KanesMethod(N, q, u, kd, bodies=[body], forcelist=[(G, -m * g * N.z)])
    km.kanes_equations()
    return km, q, u, kd


def _max_rel_diff(how):
    """max over random states of |u'(ldaspark) - u'(sympy)| / (1 + |u'(sympy)|)."""
    km, q, u, kd = _top(how)
    s = LagrangianSystem.from_mechanics(km).with_params(P)
    pv = {sympy.Symbol(k): v for k, v in P.items()}
    states = list(q) + list(u)
    sym_f = sympy.lambdify([states], (km.mass_matrix_full.xreplace(pv), km.forcing_full.xreplace(pv)))
    qd = [x.diff(t) for x in q]
    # u as a function of (q, q') from the kinematic equations, and its time derivative given q''
    U = sympy.Matrix([sympy.solve(e, x)[0] for e, x in zip(kd, u)])
    qdd = sympy.symbols("a1:4")
    Ud = U.diff(t).xreplace({x.diff(t, 2): a for x, a in zip(q, qdd)})
    plain = {**{x.diff(t): sympy.Symbol(f"qd{i}") for i, x in enumerate(q)},
             **{x: sympy.Symbol(f"qq{i}") for i, x in enumerate(q)}}
    qq, qds = [plain[x] for x in q], [plain[x.diff(t)] for x in q]
    f_u = sympy.lambdify([qq, qds], U.xreplace(plain))
    f_ud = sympy.lambdify([qq, qds, list(qdd)], Ud.xreplace(plain))
    rng = np.random.default_rng(49)
    bk, worst = Backend(None), 0.0
    for _ in range(4):
        q0 = rng.uniform(-1.0, 1.0, 3)
        qdot = rng.uniform(-1.5, 1.5, 3)
        u0 = np.array(f_u(q0, qdot), float).ravel()
        M, F = sym_f(list(q0) + list(u0))
        xdot = np.linalg.solve(np.array(M, float), np.array(F, float).ravel())
        assert np.allclose(xdot[:3], qdot, rtol=1e-12, atol=1e-12)        # the same state, two ways
        vdot = np.asarray(s.ode_rhs(bk, 0.0, q0, qdot)[0], float)
        ud = np.array(f_ud(q0, qdot, vdot), float).ravel()
        worst = max(worst, float(np.max(np.abs(ud - xdot[3:]) / (1 + np.abs(xdot[3:])))))
    return worst


@pytest.mark.parametrize("how", ["body_XYZ", "space_ZXY", "three_steps"])
def test_compound_orientation_agrees_with_sympys_kane_equations(how):
    assert _max_rel_diff(how) <= TOL


def _transposed(a, b):
    """The planted fault: the rate C^T C' (the angular velocity's matrix in a's components) put
    where C' C^T (b's) belongs; the two agree for a rotation about one axis."""
    C = b.dcm(a)
    W = C.T * C.diff(t)
    w = [mech._trig_normal(W[7]), mech._trig_normal(W[2]), mech._trig_normal(W[3])]
    return sympy.physics.vector.Vector([(sympy.Matrix(w), b)])


@pytest.mark.parametrize("how", ["body_XYZ", "space_ZXY"])
def test_a_transposed_direction_cosine_rate_fails_the_check(how, monkeypatch):
    """Negative control: with the rate transposed, the model is refused (the set angular velocity
    no longer matches the derived one) or its accelerations disagree with sympy's."""
    monkeypatch.setattr(mech, "_w_from_dcm", _transposed)
    try:
        err = _max_rel_diff(how)
    except SystemDefinitionError as exc:
        assert "frame B" in str(exc)
        return
    assert err > 1e3 * TOL


def test_the_transposition_is_invisible_to_frames_oriented_one_axis_at_a_time(monkeypatch):
    """Why the compound step is needed: for elementary rotations the planted fault changes
    nothing (C^T C' = C' C^T), so only the tests above can see it."""
    monkeypatch.setattr(mech, "_w_from_dcm", _transposed)
    assert _max_rel_diff("three_steps") <= TOL
