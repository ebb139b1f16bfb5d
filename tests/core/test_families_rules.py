"""Rules of ``ldaspark.core.families`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from fractions import Fraction
import numpy as np
import sympy
from ldaspark.core.families import get_method
from verification import strategies as ST
from verification import systems_checks as SC
import mpmath
import pytest
from ldaspark.lab.theory import audit as au


Q = sympy.Rational


# --- tableaux ----------------------------------------------------------------------------------
def _exact(tab, name):
    return [[tab.exact[name][i, j] for j in range(tab.exact[name].cols)] for i in range(tab.exact[name].rows)]


def _col(tab, name):
    return [tab.exact[name][i, 0] for i in range(tab.s)]


def test_base_tableaux_are_the_documented_ones():
    """BASE_A/B: the midpoint rule (Gauss 1), near Gauss 2 with its weights, Lobatto IIIA 3."""
    for s, meth in ((1, "gauss-1"), (3, "lobatto-iiia-iiib-3")):
        ref = get_method(meth, exact=True)
        assert [[Q(x) for x in r] for r in ST.BASE_A[s]] == _exact(ref, "A"), s
        assert [Q(x) for x in ST.BASE_B[s]] == _col(ref, "b"), s
    g2 = get_method("gauss-2", exact=True)
    assert [Q(x) for x in ST.BASE_B[2]] == _col(g2, "b")
    A2 = _exact(g2, "A")
    assert max(abs(float(Q(ST.BASE_A[2][i][j]) - A2[i][j])) for i in range(2) for j in range(2)) < 0.3
    # the data as defined (comment of BASE_A): diagonal of Gauss 2, rational off-diagonal 1/4, 3/4
    assert ST.BASE_A[2] == [[Fraction(1, 4), Fraction(1, 4)], [Fraction(3, 4), Fraction(1, 4)]]
    assert sorted(ST.BASE_A) == sorted(ST.BASE_B) == [1, 2, 3]


# =================================================================================================
# systems_checks.py
# =================================================================================================
def test_constants_as_documented():
    assert SC.EPS == np.finfo(float).eps and SC.RESIDUAL_TOL == 1e-15 and SC.ORDER_TOL == 0.3
    for plan in (SC.ORDER_PLAN, SC.EXHAUSTIVE_PLAN):
        for meth, nl in plan:
            assert get_method(meth).claimed_order is not None
            assert len(nl) == 4 and all(b == 2 * a for a, b in zip(nl, nl[1:])) and nl[0] in (4, 8), (meth, nl)
    assert [m for m, _ in SC.ORDER_PLAN] == ["gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3"]
    # the s = 1 / 2-stage second-order methods start at N = 8, the others at 4 (errors above 1e3 eps)
    assert [nl[0] for _, nl in SC.ORDER_PLAN] == [8, 4, 8, 4]


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- section 7.3: the midpoint statement needs both V_1 and Q_1 at the midpoint -------------------
def test_section7_3_midpoint_stage_statement_is_the_worse_of_V1_and_Q1(monkeypatch):
    import dataclasses

    from ldaspark.core.families import get_method
    from ldaspark.lab.theory import section7 as s7
    real = s7.spark_step

    def planted(*a, **k):
        r = real(*a, **k)            # Gauss-1 is the midpoint rule: V_1, Q_1 at the midpoint to ~1e-40
        return dataclasses.replace(r, Q=np.array([r.Q[0] + mpmath.mpf("1e-3")] + list(r.Q[1:]), dtype=object))
    monkeypatch.setattr(s7, "spark_step", planted)
    out = s7.reduction("midpoint", get_method("gauss-1", exact=True))
    assert out["stage"] == _close(1e-3, rel=1e-6)
    assert out["diff"] < 1e-30


def test_the_discrete_bvp_works_at_40_digits_unless_told():
    from ldaspark.core.families import get_method
    from ldaspark.models.scenes import particle
    from ldaspark.analysis.discrete import DiscreteBVP
    sysm = particle().system
    bvp = DiscreteBVP(sysm, get_method("gauss-2", exact=True))
    assert bvp.dps == 40 and bvp.method.backend.dps == 40
    assert DiscreteBVP(sysm, get_method("gauss-2", exact=True), dps=None).dps is None


def test_the_classical_order_is_searched_up_to_eight():
    """Gauss with 5 stages has order 10: the tree conditions hold through order 8, the cap
    (MAX_ORDER), so the reported order is 8, not more."""
    import mpmath

    from ldaspark.core.families import get_method
    from ldaspark.analysis import order_conditions as oc
    tab = get_method("gauss-5")
    with mpmath.workdps(30):
        e = tab.mp_entries(30)
        ar = oc.Arith("mp", dps=30, tol=1e-20)
        r = oc.rk_order(ar, e["A"], e["b"])
    assert oc.MAX_ORDER == 8 and r.order == 8


# --- exact conditions, pairs of covectors, skipped caches: one item of many -------------------------------
def test_the_exact_conditions_need_every_index():
    from ldaspark.core.families import get_method
    from ldaspark.analysis import conditions as cd
    g2, g3 = get_method("gauss-2", exact=True), get_method("gauss-3", exact=True)
    assert cd.check_22a(g2) and cd.check_22b(g2) and cd.check_23(g3)
    assert not cd.check_22a(g2.with_entry("b_hat", 1, None, "1/10"))      # b_hat_1 = b_1 still holds
    assert not cd.check_22b(g2.with_entry("A_hat", 0, 1, "1/10"))
    # c_2 + c_2 = 1 still holds, c_1 + c_3 does not
    assert not cd.check_23(g3.with_entry("c", 0, None, "1/10"))


def test_a_section7_reduction_difference_is_the_worst_of_q_v_and_psi():
    from ldaspark.core.families import get_method
    from ldaspark.lab.theory.section7 import reduction
    r = reduction("euler-ii", get_method("euler-i", exact=True), constant_K=False)     # the control: differs
    parts = [r["q1"], r["v1"], r["Psi1"]]
    assert len(set(parts)) > 1 and r["diff"] == max(parts)


def test_mp_arithmetic_asked_for_is_used_even_for_exact_entries():
    from ldaspark.core.families import get_method
    ar, _, _ = au.decide_arith(get_method("gauss-2", exact=True), 30, "mp")
    assert not ar.exact
    ar, _, _ = au.decide_arith(get_method("gauss-2", exact=True), 30, "auto")
    assert ar.exact


@pytest.mark.parametrize("s", ["3", 2.5, None, np.float64(3.0)])
def test_lobatto_coefficients_refuses_a_stage_count_that_is_not_an_integer(s):
    """lobatto_coefficients("3") was a TypeError ('<' between str and int), 2.5 a sympy
    PolynomialError; the families' own check now applies (TableauError)."""
    from ldaspark.core.errors import TableauError
    from ldaspark.core.families import lobatto_coefficients
    with pytest.raises(TableauError, match="integer"):
        lobatto_coefficients(s)
    assert lobatto_coefficients(np.int64(3))["IIIA"].shape == (3, 3)      # valid neighbour
