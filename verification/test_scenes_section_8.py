"""Section 8's scenes as stated: constraints, integrability, energy of the initial data.

Finding: the constraint printed in 8.4, v1 + sum_{i=m+2}^n q_i v_i = 0, is integrable
(k = d/dt (q1 + sum_{i>=m+2} q_i^2/2)), so the printed McLachlan-Perlmutter scene is holonomic.
The variant v1 + sum q_{i-m} v_i = 0 (scene mp-particles-nh) is genuinely nonholonomic. The test
for integrability is Frobenius: the distribution ker K(q) is involutive iff K [X, Y] = 0 for all
X, Y in it; the holonomic pendulum is the positive control, the particle (8.1) a negative one.
"""
import itertools

import pytest
import sympy

from ldaspark.models.scenes import get_scene, mp_particles


def is_involutive(system):
    """Frobenius for k = K(q) v: [X, Y] in ker K for a basis X, Y of ker K(q)."""
    K = system.k_v
    assert not K.free_symbols & set(system.v), "constraint must be linear in v"
    q = sympy.Matrix(system.q)
    basis = K.nullspace(simplify=True)
    for X, Y in itertools.combinations(basis, 2):
        bracket = Y.jacobian(q) * X - X.jacobian(q) * Y
        if any(sympy.simplify(e) != 0 for e in K * bracket):
            return False
    return True


@pytest.mark.parametrize("scene, holonomic", [("pendulum", True), ("mp-particles", True), ("particle", False),
                                              ("skate", False), ("robot", False), ("mp-particles-nh", False),
                                              ("rolling-disk", False)])
def test_section_8_constraint_integrability(scene, holonomic):
    assert is_involutive(get_scene(scene).system) is holonomic


def test_8_4_printed_constraint_is_a_time_derivative():
    sysm = mp_particles().system
    q, v = sysm.q, sysm.v
    g = q[0] + sum(x ** 2 for x in q[4:]) / 2
    assert sympy.simplify(sysm.k[0] - sum(sympy.diff(g, x) * y for x, y in zip(q, v))) == 0
    # the variant is not: the same candidate leaves a remainder
    nh = mp_particles(constraint="nonholonomic").system
    assert sympy.simplify(nh.k[0] - sum(sympy.diff(g, x) * y for x, y in zip(nh.q, nh.v))) != 0


@pytest.mark.parametrize("constraint", ["printed", "nonholonomic"])
def test_8_4_initial_data_energy_is_3_06(constraint):
    """E(q_j0, v_j0) = 3.06 exactly for j = 0..J, and the data are consistent."""
    for j in range(10):
        sc = mp_particles(J=9, j=j, constraint=constraint)
        sub = dict(zip(sc.system.q + sc.system.v, sc.q0 + sc.v0))
        assert sympy.nsimplify(sympy.simplify(sc.system.energy_expr.subs(sub))) == sympy.Rational(306, 100)
        assert sympy.simplify(sc.system.k[0].subs(sub)) == 0


def test_8_4_energy_check_has_teeth():
    sc = mp_particles(J=9, j=3)
    sub = dict(zip(sc.system.q + sc.system.v, [sc.q0[0] + sympy.Rational(1, 10)] + sc.q0[1:] + sc.v0))
    assert sympy.simplify(sc.system.energy_expr.subs(sub) - sympy.Rational(306, 100)) != 0
