"""Rules of ``ldaspark.core.backend`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import ldaspark
from ldaspark.core.backend import Backend
from ldaspark.analysis import discrete as D
from verification import strategies as ST
from system_fakes import collect


def test_perturbed_initial_is_consistent_and_generic():
    """q0 + scale (k + 1)/n (distinct shifts per coordinate: no symmetry of the scene's data
    survives), v0 shifted by scale (-1)^k (k + 2)/n and projected onto k = 0."""
    sc = ldaspark.get_scene("skate")
    bk = Backend(30)
    with bk.context():
        t0, q0s, v0s = sc.initial(30)
        for scale, sval in (("1/20", mpmath.mpf(1) / 20), ("0.1", mpmath.mpf("0.1"))):
            t, q, v = D.perturbed_initial(sc, 30, scale)
            n = len(q)
            assert t == t0
            for k in range(n):
                assert abs(q[k] - q0s[k] - sval * (k + 1) / n) < mpmath.mpf(10) ** -28
            assert abs(sc.system.constraint(bk, t, bk.array(q), bk.array(v))[0]) < mpmath.mpf(10) ** -25
            # v is the projection of the shifted velocity: projecting again moves nothing, and
            # it is not the scene's own v0
            shifted = [v0s[k] + sval * (-1) ** k * (k + 2) / n for k in range(n)]
            again = sc.system.project_velocity(bk, t, q, shifted)
            assert max(abs(a - b) for a, b in zip(v, again)) < mpmath.mpf(10) ** -25
            assert max(abs(a - b) for a, b in zip(v, v0s)) > sval / 10


def test_general_systems_real_base_point_satisfies_k_and_the_saddle_condition():
    """Real systems: k(t0, q0, v0) = 0 at 60 digits, (4) nonsingular, |v0| < 3."""
    for c in collect(ST.general_systems(n_range=(2, 2)), 2):
        S, bk = c.system, Backend(60)
        with bk.context():
            k = S.constraint(bk, c.t0, c.q0, c.v0)
            assert bk.norm_inf(k) <= mpmath.mpf(10) ** -50, k
            assert S.check_saddle(bk, c.t0, c.q0, c.v0, rcond=1e-6) > 1e-6
            assert bk.norm_inf(bk.array(c.v0)) < 3


def test_numpy_floats_are_read_by_value_at_mpmath_precision():
    """A NumPy float32 / float16 (scalar, 0-d array or array entry) is the binary number it holds,
    as the float64 engines read it: 0.100000001490116... for np.float32(0.1), not the decimal 0.1
    of its shortest repr (the mpmath run then stepped with h off by 1.5e-8 relative, float16 by
    2.4e-4, and started from other q0, v0 than the float64 runs)."""
    import numpy as np
    bk = Backend(30)
    with bk.context():
        for x in (np.float32(0.1), np.float16(0.1), np.array(0.1, dtype=np.float32), np.longdouble(0.1)):
            num, den = np.asarray(x)[()].as_integer_ratio()
            exact = mpmath.mpf(num) / den                       # den a power of 2: exact
            assert bk.scalar(x) == exact, (repr(x), bk.scalar(x), exact)
            assert bk.array(np.array([x, x]))[0] == exact
        assert bk.scalar("0.1") == mpmath.mpf("0.1")          # decimal text keeps its digits
        assert bk.scalar(np.int64(3)) == 3
    r = ldaspark.integrate("pendulum", "gauss-2", n_steps=1, h=np.float32(0.1), dps=30, guard=False)
    with mpmath.workdps(30):
        assert r.t[1] == mpmath.mpf(float(np.float32(0.1)))   # float32 -> float64 is exact


def test_exact_sympy_numbers_in_arrays_are_read_at_mpmath_precision():
    """q0 = [sqrt(2)/2, sqrt(2)/2] (exact sympy numbers) ran on the float64 engines and was refused
    at dps ("t0, q0 and v0 must be numbers: invalid literal for int() ... 'sqrt(2)'"): the array
    conversion read them by str(), which mpmath does not parse; ``Backend.scalar`` evaluated them
    (h = pi/30 ran). Both now evaluate them at the working precision."""
    import sympy as sp
    with mpmath.workdps(60):              # the references, rounded once to 30 digits below
        refs = (mpmath.sqrt(2) / 2, mpmath.cos(mpmath.mpf(1) / 3), mpmath.pi / 30)
    bk = Backend(30)
    with bk.context():
        got = list(bk.array([sp.sqrt(2) / 2, sp.cos(sp.Rational(1, 3))])) + [bk.scalar(sp.pi / 30)]
        assert all(mpmath.almosteq(g, r, rel_eps=mpmath.mpf(10) ** -29) for g, r in zip(got, refs)), got
    s2 = sp.sqrt(2) / 2
    r = ldaspark.integrate("pendulum", "gauss-2", q0=[s2, s2], v0=[-s2 / 2, s2 / 2], n_steps=2, h=0.1, dps=30,
                           guard=False)
    with mpmath.workdps(30):
        assert r.status == 0 and mpmath.almosteq(r.q[0][0], refs[0], rel_eps=mpmath.mpf(10) ** -29)
