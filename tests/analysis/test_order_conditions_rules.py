"""Rules of ``ldaspark.analysis.order_conditions`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import types
import mpmath
import pytest
import sympy
from ldaspark.core.families import gauss, get_method
from ldaspark.core.tableau_file import from_json_dict
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.analysis import order_conditions as oc
from tableau_fakes import _tab, approx


def mp_ar(tol=1e-10, dps=30):
    return oc.Arith("mp", dps=dps, tol=tol)


def mpv(v):
    with mpmath.workdps(30):
        return [mpv(x) for x in v] if isinstance(v, list) else mpmath.mpf(v)


# ==== audit: algebraic checks on small tableaux ===============================================


def _extab(c):
    """A one-stage exact tableau with c = [c] (expressions the file parser does not take)."""
    tab = get_method("gauss-1", exact=True)
    ex = dict(tab.exact)
    ex["c"] = sympy.Matrix([[c]])
    return type(tab)("x", 1, exact=ex)


def test_order_checks_facts_on_implicit_midpoint_and_euler():
    ar, e = oc.exact_arith(get_method("gauss-1", exact=True))
    C, f = ac.order_checks(ar, e)
    assert f["order:A"] == 2 and f["order:pair"] == 2 and f["order:forced-ode"] == 2
    assert f["R_inf:A"] == "-1" and f["BCD:A"] == {"B": 2, "C": 1, "D": 1}
    assert not f["order:forced-ode-capped"]
    names = {c.name: c for c in C}
    assert "first failing tree" in names["order:A"].detail and "A invertible" in names["stability:A"].detail
    ar, e = oc.exact_arith(_tab(c=[1], A=[[1]], A_hat=[[1]], A_tilde=[[1]]))     # implicit Euler
    C, f = ac.order_checks(ar, e)
    assert f["R_inf:A"] == "0" and "L-stable-type" in {c.name: c for c in C}["stability:A"].detail


# ==== order_conditions ========================================================================
def test_trees_counts_and_densities():
    assert oc.trees(0) == () and oc.trees(-1) == ()
    assert [len(oc.trees(n)) for n in range(1, 6)] == [1, 1, 2, 4, 9]
    assert [len(oc.trees(n, 2)) for n in range(1, 4)] == [2, 4, 14]
    assert sorted(oc.density(t) for t in oc.trees(3)) == [3, 6]
    assert sorted(oc.density(t) for t in oc.trees(4)) == [4, 8, 12, 24]
    t = (0, ((0, ()), (1, ())))
    assert oc.tree_str(t, ("q", "p")) == "q[q p]" and oc.tree_str(t) == "o[o o]"


def test_arith_mp_and_exact_helpers():
    ar = mp_ar(1e-10, dps=30)
    assert ar.to_str(mpmath.mpf(1) / 3).startswith("0.3333333333333333")
    assert ar.radius(mpmath.mpf(1)) == 1e-10 and ar.pow(mpmath.mpf(2), 3) == 8
    assert ar.is_zero(mpmath.mpf("1e-10")) and not ar.is_zero(mpmath.mpf("1.1e-10"))
    assert ar.num(1, 3) == ar.num(1, 3) and abs(ar.num(1, 3) * 3 - 1) < 1e-29
    ex, _ = oc.exact_arith(get_method("gauss-2", exact=True))
    assert ex.to_str(ex.K.from_sympy(sympy.sqrt(3) / 6)) in ("sqrt(3)/6", "sqrt(3)*(1/6)")
    assert ex.radius(ex.num(1)) == 0.0 and ex.prec == int(30 * 3.33) + 16


def test_to_str_survives_nsimplify_failure(monkeypatch):
    ex, _ = oc.exact_arith(get_method("gauss-2", exact=True))
    x = ex.K.from_sympy(sympy.sqrt(3) / 6)

    def boom(e):
        raise ValueError("no")
    monkeypatch.setattr(sympy, "nsimplify", boom)
    assert "sqrt(3)" in ex.to_str(x)


def test_exact_budget_reasons():
    flt = from_json_dict({"c": [0.5], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1.0],
                          "b_hat": [1.0], "b_tilde": [1.0]}, "f")
    assert oc.exact_budget(flt) == (False, "the entries are float64 numbers")
    ok, why = oc.exact_budget(_extab(sympy.E / 5))
    assert not ok and "involve E:" in why
    ok, why = oc.exact_budget(_tab(c=["pi/7"]))
    assert not ok and "involve pi:" in why
    ok, why = oc.exact_budget(_extab(sympy.sin(1) / 2 + sympy.pi / 10))
    assert not ok and "involve pi, sin:" in why
    ok, why = oc.exact_budget(get_method("gauss-3", exact=True))
    assert ok and why == "number field of degree <= 2"
    t = _tab(c=["sqrt(2)/4 + sqrt(3)/4 + sqrt(5)/8"])
    assert oc.exact_budget(t) == (True, "number field of degree <= 8")
    assert not oc.exact_budget(t, max_degree=4)[0] and oc.exact_budget(t, max_degree=None)[0]
    ok, why = oc.exact_budget(_tab(c=["sqrt(2)/4 + sqrt(3)/4 + sqrt(5)/8 + sqrt(7)/16"]))
    assert not ok and "4 distinct radicals: number field of degree up to 16 > 8" in why
    x = sympy.Symbol("x")
    r = sympy.CRootOf(x ** 3 - x - 1, 0)
    tab = get_method("gauss-1", exact=True)
    ex = dict(tab.exact)
    ex["c"] = sympy.Matrix([[r / 3]])
    t3 = type(tab)("cr", 1, exact=ex)
    assert oc.exact_budget(t3) == (True, "number field of degree <= 3")
    ex["c"] = sympy.Matrix([[r / 3 + sympy.sqrt(2) / 5 + sympy.sqrt(3) / 7]])
    assert oc.exact_budget(type(tab)("cr", 1, exact=ex))[0] is False          # 3 * 2 * 2 = 12 > 8


def test_arith_for_numerical_when_not_decidable(monkeypatch):
    assert oc.arith_for(get_method("gauss-1", exact=True))[0].exact
    monkeypatch.setattr(oc, "_decidable", lambda K: False)
    ar, e = oc.arith_for(get_method("gauss-1", exact=True))
    assert ar.ball and "not decidable exactly" in ar.label
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=None), 10) == 40
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=50), 30) == 70
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=10), 35) == 70


def test_additive_order_merges_identical_parts_and_caps_three_colours():
    Q = sympy.QQ
    ar = oc.Arith("exact", K=Q)
    A, b = [[Q(1, 2)]], [Q(1)]
    r = oc.additive_order(ar, [(A, b), (A, b), (A, b)], names=["q", "F", "R"])
    assert r.order == 2 and r.max_order == oc.MAX_ORDER and r.counts == {1: 1, 2: 1, 3: 2}
    # both trees of order 3 miss by 1/12 (+1/12 for o[o[o]], -1/12 for o[o o]): the first one is named
    assert r.failing == "o[o[o]]" and r.residual == approx(1 / 12)
    E, Ei = ([[Q(1)]], [Q(1)]), ([[Q(0)]], [Q(1)])
    r = oc.additive_order(ar, [E, Ei, E])
    assert r.order == 1 and r.max_order == oc.MAX_ORDER and r.counts[2] == 4   # two colours after the merge
    r = oc.additive_order(ar, [E, Ei, (A, b)])
    assert r.max_order == 6 and r.order == 1 and r.counts[2] == 9
    assert oc._same(ar, [[Q(1)]], [Q(1)], [[Q(1)]], [Q(1)])
    assert not oc._same(ar, [[Q(1)]], [Q(1)], [[Q(1)]], [Q(2)]) and not oc._same(ar, [[Q(1)]], [Q(1)], [[Q(0)]], [Q(1)])
    r = oc.pair_order(ar, *E, *Ei)
    assert r.order == 1 and "q" in r.failing and "p" in r.failing
    assert not r.complete and oc.OrderResult(8, 8).complete


def test_simplifying_assumptions_and_stability_exact():
    ar, e = oc.exact_arith(get_method("gauss-2", exact=True))
    sa = oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"])
    assert sa == {"B": 4, "C": 2, "D": 2}
    assert oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"], cap=1) == {"B": 1, "C": 1, "D": 1}
    ok, w = oc.check_B(ar, e["b"], e["c"], 5)
    assert not ok and w[1] == "k=5" and w[0] == approx(1 / 180)
    st = oc.stability(ar, e["A"], e["b"])
    assert st.r_inf == 1.0 and not st.A_singular
    Q = sympy.QQ
    ex = oc.Arith("exact", K=Q)
    st = oc.stability(ex, [[Q(0)]], [Q(1)])                 # explicit Euler: R = 1 + z
    assert st.r_inf == math.inf and st.r_inf_str == "inf" and st.A_singular and "singular" in st.note
    st = oc.stability(ex, [[Q(0), Q(0)], [Q(1, 2), Q(1, 2)]], [Q(1, 2), Q(1, 2)])   # trapezoid
    assert st.r_inf == -1.0 and st.A_singular
    assert oc.char_coeffs(ex, [[Q(1), Q(2)], [Q(3), Q(4)]]) == [Q(1), Q(-5), Q(-2)]
    assert oc.largest(lambda n: (n <= 3, None), 10) == 3 and oc.largest(lambda n: (True, None), 4) == 4


# ==== remaining branches ======================================================================
def test_decide_arith_undecidable_field_goes_to_balls(monkeypatch):
    monkeypatch.setattr(oc, "_decidable", lambda K: False)
    ar, e, why = au.decide_arith(_tab(), 30)
    assert ar.ball and why.startswith("sympy puts the entries in") and "not decidable exactly" in why


def test_decidable_domains():
    assert oc._decidable(sympy.QQ) and oc._decidable(sympy.ZZ)
    assert oc._decidable(sympy.QQ.algebraic_field(sympy.sqrt(3)))
    assert not oc._decidable(sympy.EX)


def test_additive_order_explicit_cap():
    Q = sympy.QQ
    ar = oc.Arith("exact", K=Q)
    E, Ei, M = ([[Q(1)]], [Q(1)]), ([[Q(0)]], [Q(1)]), ([[Q(1, 2)]], [Q(1)])
    r = oc.additive_order(ar, [M, M, M], max_order=2)
    assert r.order == 2 and r.max_order == 2 and r.complete and r.failing is None
    r = oc.additive_order(ar, [E, Ei, M], max_order=1)
    assert r.order == 1 and r.complete
    r = oc.spark_ode_order(ar, {"A": M[0], "b": M[1], "A_hat": M[0], "b_hat": M[1], "A_tilde": M[0], "b_tilde": M[1]})
    assert r.order == 2 and r.max_order == oc.MAX_ORDER


def test_ball_arith_helpers():
    import flint
    from ldaspark.core.errors import NonFiniteError
    ar = oc.Arith("ball", dps=30)
    assert ar.prec == int(30 * 3.33) + 16
    with ar.context():
        third = ar.num(1, 3)
        assert abs(float(third.mid()) - 1 / 3) < 1e-16 and float(third.rad()) < 1e-30
        x = flint.arb(0, 1e-3)                                  # a ball around 0
        assert ar.is_zero(x) and not ar.is_zero(flint.arb(1e-2, 1e-3))
        y = ar.pow(x, 3)
        assert y.is_finite() and ar.is_zero(y) and float(y.rad()) <= 1.01e-9
        assert float(ar.pow(flint.arb(2), 3).mid()) == 8.0 and float(ar.pow(flint.arb(5), 0).mid()) == 1.0
        assert ar.radius(flint.arb(1, 0.25)) == approx(0.25, rel=1e-6) and ar.to_float(flint.arb(0.75, 0.25)) == 0.75
        assert ar.to_str(ar.num(1, 4)) == "0.25" and ar.to_str(ar.num(1, 3)).startswith("0.33333333333333")
        with pytest.raises(NonFiniteError):
            ar.is_zero(flint.arb("nan"))


def test_simplifying_assumption_caps_when_everything_holds():
    ar = mp_ar(tol=10.0)                  # every residual is "zero": only the caps stop the search
    b, c, A = mpv([0.5, 0.5]), mpv([0.25, 0.75]), mpv([[0.25, 0.0], [0.5, 0.25]])
    assert oc.simplifying_assumptions(ar, A, b, c) == {"B": 5, "C": 3, "D": 3}
    assert oc.simplifying_assumptions(ar, A, b, c, cap=2) == {"B": 2, "C": 2, "D": 2}


def test_exact_budget_counts_only_radicals():
    ok, why = oc.exact_budget(_extab(sympy.sqrt(2) + sympy.sqrt(3) + sympy.sqrt(5) + sympy.sqrt(7)
                                     + 1 / (1 + sympy.sqrt(2))))
    assert not ok and why.startswith("4 distinct radicals: number field of degree up to 16")
    ok, why = oc.exact_budget(_extab(sympy.cbrt(2) / 3 + sympy.sqrt(3) / 5))
    assert ok and why == "number field of degree <= 6"
    ok, why = oc.exact_budget(_extab(sympy.cbrt(2) / 3 + sympy.sqrt(3) / 5 + sympy.sqrt(5) / 7))
    assert not ok and "degree up to 12 > 8" in why


def test_integer_tableau_is_lifted_to_a_field_and_mp_ball_arith():
    t = _tab(c=[1], A=[[1]], A_hat=[[0]], A_tilde=[[0]])          # integers only: sympy's ZZ
    ar, e = oc.exact_arith(t)
    assert ar.K.is_Field and ar.label == f"exact in {ar.K}"
    assert oc.rk_order(ar, e["A"], e["b"]).order == 1 and oc.rk_order(ar, e["A_hat"], e["b_hat"]).order == 1
    flt = from_json_dict({"c": [0.5, 0.5], "A": [[0.25, 0.25], [0.25, 0.25]], "A_hat": [[0.25, 0.25], [0.25, 0.25]],
                          "A_tilde": [[0.25, 0.25], [0.25, 0.25]], "b": [0.5, 0.5], "b_hat": [0.5, 0.5],
                          "b_tilde": [0.5, 0.5], "omega": [[1, -1]]}, "f")
    ar, e = oc.mp_arith(flt, 30)
    assert ar.tol == approx(1e-12 * 2) and e["b"] == [mpmath.mpf("0.5")] * 2 and e["c"] == [mpmath.mpf("0.5")] * 2
    ar, e = oc.mp_arith(get_method("gauss-1", exact=True), 20)
    assert ar.tol == approx(1e-17) and ar.dps == 20
    ar, _ = oc.ball_arith(flt, 40)
    assert ar.ball and ar.scope.startswith("the float64 precision") and ar.dps == 40
    ar, _ = oc.ball_arith(get_method("gauss-1", exact=True), 40, "R")
    assert ar.label.endswith("; not exact because R") and ar.scope.startswith("40 digits, numerically (exact")
    ar, _ = oc.ball_arith(flt, 40, "R")
    assert "not exact because" not in ar.label
    ar, _ = oc.ball_arith(_tab(c=["0.50"]), 40)
    assert ar.scope == "the 2 digits given"
    ar, _ = oc.ball_arith(gauss(2), 40)
    assert ar.scope == "40 digits, numerically"


def test_simplifying_assumptions_start_at_k_1():
    Q = sympy.QQ
    ex = oc.Arith("exact", K=Q)
    # implicit Euler: B(1), C(1) hold, D(1) (b_1 a_11 = b_1 (1 - c_1): 1 vs 0) does not
    assert oc.simplifying_assumptions(ex, [[Q(1)]], [Q(1)], [Q(1)]) == {"B": 1, "C": 1, "D": 0}
    ok, w = oc.check_D(ex, [[Q(1)]], [Q(1)], [Q(1)], 1)
    assert not ok and w == (1.0, "k=1, j=1")
    # sum b = 1/2: not even B(1); a_11 = 1/4 != c_1 = 1/2: not C(1) (C(2) alone would hold: 1/8 = 1/8)
    sa = oc.simplifying_assumptions(ex, [[Q(1, 4)]], [Q(1, 2)], [Q(1, 2)])
    assert sa["B"] == 0 and sa["C"] == 0
    assert oc.check_C(ex, [[Q(1, 4)]], [Q(1, 2)], 1) == (False, (0.25, "k=1, i=1"))
    assert oc.check_B(ex, [Q(1, 2)], [Q(1, 2)], 1) == (False, (0.5, "k=1"))


def test_an_exact_value_is_reported_as_the_nearest_double():
    """1.00000000000000011103 lies above the midpoint 1 + 2^-53 of 1 and 1 + 2^-52: the nearest
    double is 1 + 2^-52. Rounding to 20 digits first lands below the midpoint (1.0): a double rounding."""
    import sympy
    from sympy.polys.domains import QQ

    from ldaspark.analysis import order_conditions as oc
    ar = oc.Arith("exact", K=QQ)
    x = QQ(100000000000000011103, 10 ** 20)
    assert ar.to_float(x) == 1 + 2.0 ** -52
    assert ar.to_float(QQ(1, 3)) == 1 / 3
    alg = oc.Arith("exact", K=QQ.algebraic_field(sympy.sqrt(2)))
    assert alg.to_float(alg.K.from_sympy(sympy.sqrt(2))) == 2 ** 0.5
