"""Rules of ``ldaspark.lab.theory.section7`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import numpy as np
import sympy


def test_section7_test_systems_are_the_documented_ones():
    from ldaspark.lab.theory import section7 as S7
    q = sympy.symbols("q1:4")
    R = sympy.Rational
    spec = {True: (sympy.diag(1, 2, 3), sympy.cos(q[0]) + q[1] ** 4 / 4 + q[0] * q[2], [1, -1, 2], R(1, 2)),
            False: (sympy.diag(1, 1, 2), q[0] ** 2 + q[1] ** 2 + sympy.cos(q[2]), [-q[1], 0, 1], q[0] / 4)}
    for constant_K, (M, U, K, b) in spec.items():
        sysm, q0, v0 = S7.affine_system(constant_K)
        mech = sysm.mechanical
        sub = dict(zip(sysm.q, q))
        assert sympy.simplify(sympy.Matrix(mech["M"]).subs(sub) - M) == sympy.zeros(3, 3)
        assert sympy.simplify(sympy.sympify(mech["U"]).subs(sub) - U) == 0
        assert sympy.simplify(sympy.Matrix(mech["K"]).subs(sub) - sympy.Matrix([K])) == sympy.zeros(1, 3)
        assert sympy.simplify(sympy.Matrix(mech["b"]).subs(sub)[0] - b) == 0
        # consistent data: K(q0) v0 + b(q0) = 0, with v0 not zero
        env = dict(zip(q, q0))
        kv = sum(sympy.sympify(Ki).subs(env) * vi for Ki, vi in zip(K, v0)) + sympy.sympify(b).subs(env)
        assert sympy.simplify(kv) == 0 and any(x != 0 for x in v0)
    # the data of the section 7 records (pinned: the recorded reductions are reproduced from them)
    assert S7.affine_system(True)[1:] == ([R(3, 10), R(-1, 5), R(1, 10)], [R(1, 2), 1, 0])
    assert S7.affine_system(False)[1:] == ([1, R(1, 5), 0], [0, 1, R(-1, 4)])


def test_section7_printed_solution_has_m_multipliers_and_solves_the_system():
    from ldaspark.lab.theory import section7 as S7
    sysm, q0, v0 = S7.affine_system(False)
    with mpmath.workdps(30):
        q0m = np.array([mpmath.mpf(x.p) / x.q if hasattr(x, "p") else mpmath.mpf(x) for x in map(sympy.Rational, q0)],
                       dtype=object)
        v0m = np.array([mpmath.mpf(x.p) / x.q for x in map(sympy.Rational, v0)], dtype=object)
        h = mpmath.mpf(1) / 10
        for kind in ("euler-i", "euler-ii", "midpoint"):
            pq, pv, pp = S7.solve_printed(kind, sysm, q0m, v0m, h, dps=30)
            assert len(pq) == sysm.n and len(pv) == sysm.n and len(pp) == sysm.m
            res = S7.printed_residual(kind, sysm, q0m, v0m, h, pq, pv, pp)
            assert len(res) == 2 * sysm.n + sysm.m
            assert max(abs(x) for x in res) < mpmath.mpf(10) ** -25
            assert abs(pp[0]) > 1e-3            # the multiplier is not trivially zero on this system
