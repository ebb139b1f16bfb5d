"""Rules of ``ldaspark.models.bicycle_benchmark`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import pytest


def test_benchmark_unknown_parameter_and_max_real_part():
    from ldaspark.models import bicycle_benchmark as bb
    with pytest.raises(KeyError, match="unknown benchmark parameter 'cc'"):
        bb.matrices(15, cc="1")
    # at 5 m/s (between the weave and capsize speeds) all real parts are negative; the largest is
    # the capsize eigenvalue -0.3229 of Table 2, not the most negative -14.08
    m5 = bb.max_real_part(5, 20)
    assert float(m5) == pytest.approx(float(bb.PUBLISHED["eig_v5"][3]), abs=1e-10)
    # at rest the bicycle falls over: the largest real eigenvalue is +5.53
    assert float(bb.max_real_part(0, 20)) == pytest.approx(float(bb.PUBLISHED["eig_v0"][3]), abs=1e-10)


def test_benchmark_total_mass_is_the_sum_of_the_four_bodies():
    """mT enters M, K0, K2, C1 only through mT xT and mT zT (the centre of mass times the mass), so
    a wrong sign in the sum shows only where it makes mT vanish: with mF = mR + mB + mH = 91 kg the
    sum is 182 kg and the matrices are finite, and equal to those with the mass moment written out."""
    import mpmath
    from ldaspark.models import bicycle_benchmark as bb
    with mpmath.workdps(25):
        M, C1, K0, K2, g = bb.matrices(15, mF="91")
        # K0[0, 0] = mT zT = -rR mR + zB mB + zH mH - rF mF (Table 1 values, mF = 91)
        want = -mpmath.mpf("0.3") * 2 + mpmath.mpf("-0.9") * 85 + mpmath.mpf("-0.7") * 4 - mpmath.mpf("0.35") * 91
        assert abs(K0[0, 0] - want) < mpmath.mpf(10) ** -20
        assert all(mpmath.isfinite(x) for A in (M, C1, K0, K2) for x in A)
