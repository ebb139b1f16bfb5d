"""Rules of ``ldaspark.analysis.conditions`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from ldaspark.analysis import conditions as cond
import pytest
import sympy
from ldaspark.analysis.conditions import check_22a, check_22b, check_23
from verification import general_fixtures as GF
from verification import strategies as ST
from system_fakes import _run, collect
from tableau_fakes import _lobatto2, _tab


# ==== audit: algebraic checks on small tableaux ===============================================


# ==== conditions (exact) ======================================================================
def test_conditions_exact_22_and_23_on_single_entries():
    t = _lobatto2()
    assert cond.check_22a(t) is cond.check_22b(t) is cond.check_23(t) is True
    assert False is cond.check_22a(_lobatto2(b_hat=["1/2", "3/5"]))
    assert False is cond.check_22b(_lobatto2(A_hat=[["1/2", 0], ["1/2", "1/10"]]))
    assert False is cond.check_22b(_lobatto2(A_hat=[["1/2", "1/10"], ["1/2", 0]]))
    assert False is cond.check_23(_lobatto2(c=["1/5", 1], A=[["1/5", 0], ["1/2", "1/2"]]))
    assert cond.check_23(_lobatto2(A_tilde=[[0, 0], ["1/2", "1/2"]])) is True       # IIIA is symmetric too
    assert False is cond.check_23(_lobatto2(A_tilde=[["1/2", 0], ["1/2", "1/10"]]))   # (23d) alone
    # b_tilde not symmetric while A_tilde_(s+1-i,s+1-j) + A_tilde_ij = b_tilde_j holds for every i, j
    assert False is cond.check_23(_lobatto2(b_tilde=["1/3", "2/3"], A_tilde=[["1/6", 0], ["2/3", "1/6"]]))
    rows = {r["method"]: r for r in cond.method_table(2)}
    assert rows["gauss-2"]["22"] and rows["gauss-2"]["23"] and rows["gauss-2"]["order"] == 4
    assert rows["euler-i"]["22"] and not rows["euler-i"]["23"] and "gauss-3" not in rows


def test_method_table_needs_both_halves_of_22(monkeypatch):
    tabs = {"ok": _lobatto2(), "no22b": _lobatto2(A_hat=[["1/2", 0], ["1/2", "1/10"]]),
            "no22a": _tab(b_hat=["11/10"], A_hat=[["11/20"]]),
            "no23": _lobatto2(A_tilde=[["1/2", 0], ["1/2", "1/10"]])}
    monkeypatch.setattr(cond, "builtin_method_names", lambda max_s: list(tabs))
    monkeypatch.setattr(cond, "get_method", lambda name, exact=False: tabs[name])
    rows = {r["method"]: (r["22"], r["23"], r["s"]) for r in cond.method_table()}
    assert rows == {"ok": (True, True, 2), "no22b": (False, False, 2), "no22a": (False, True, 1),
                    "no23": (True, False, 2)}


Q = sympy.Rational


def _den_ok(x, den):
    return sympy.Rational(x).q <= den




def _tab_expected(s, dA, db, dAt, dom):
    A = [[Q(ST.BASE_A[s][i][j]) + dA for j in range(s)] for i in range(s)]
    b = [Q(ST.BASE_B[s][i]) + db for i in range(s)]
    c = [sum(r) for r in A]
    At = [[Q(1, 2 * s) + dAt] * s for _ in range(s)]
    om = [[b[j] * c[j] ** i + dom for j in range(s)] for i in range(s - 1)]
    Ah = [[b[j] * (b[i] - A[j][i]) / b[i] for j in range(s)] for i in range(s)]
    return A, b, c, At, om, Ah


# --- tableaux ----------------------------------------------------------------------------------
def _exact(tab, name):
    return [[tab.exact[name][i, j] for j in range(tab.exact[name].cols)] for i in range(tab.exact[name].rows)]


def _col(tab, name):
    return [tab.exact[name][i, 0] for i in range(tab.s)]


def _check_random_tableau(tab, s_values):
    s = tab.s
    assert s in s_values
    A, Ah, At = _exact(tab, "A"), _exact(tab, "A_hat"), _exact(tab, "A_tilde")
    b, c = _col(tab, "b"), _col(tab, "c")
    assert _col(tab, "b_hat") == b and _col(tab, "b_tilde") == b
    assert check_22a(tab) and check_22b(tab)
    assert all(b[i] * Ah[i][j] + b[j] * A[j][i] == b[i] * b[j] for i in range(s) for j in range(s))
    assert c == [sum(r) for r in A]
    assert all(x != 0 for x in b) and sum(b) != 0
    for i in range(s):
        assert abs(b[i] - Q(ST.BASE_B[s][i])) <= Q(1, 20) and _den_ok(b[i] - Q(ST.BASE_B[s][i]), 50)
        for j in range(s):
            d = A[i][j] - Q(ST.BASE_A[s][i][j])
            assert abs(d) <= Q(1, 10) and _den_ok(d, 50), (i, j, d)
            assert abs(At[i][j] - Q(1, 2 * s)) <= Q(3, 10) and _den_ok(At[i][j] - Q(1, 2 * s), 50)
    if s > 1:
        om = _exact(tab, "omega")
        assert len(om) == s - 1 and all(len(r) == s for r in om)
        for i in range(s - 1):
            for j in range(s):
                d = om[i][j] - b[j] * c[j] ** i
                assert abs(d) <= Q(1, 10) and _den_ok(d, 20), (i, j, d)
    assert tab.name == f"random-{s}"


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
@pytest.mark.parametrize("policy, d", [("low", -1), ("high", 1), ("zero", 0)])
def test_spark_tableaux_corner_draws_are_the_documented_tableaux(monkeypatch, policy, d):
    """A = BASE_A +- 1/10, b = BASE_B +- 1/20, A_tilde = 1/(2s) +- 3/10, omega = b_j c_j^i +- 1/10
    at the corners (d = -1, +1) and at zero perturbation (the base tableau itself, sum b = 1)."""
    for s_values in ((1, 2, 3), (2,), (3, 1)):
        tab = _run(monkeypatch, ST.spark_tableaux(s_values=s_values), policy, perm=False)
        s = s_values[-1] if policy == "high" else s_values[0]
        A, b, c, At, om, Ah = _tab_expected(s, d * Q(1, 10), d * Q(1, 20), d * Q(3, 10), d * Q(1, 10))
        assert tab.s == s and tab.name == f"random-{s}"
        assert _exact(tab, "A") == A and _col(tab, "b") == b and _col(tab, "c") == c
        assert _exact(tab, "A_tilde") == At and _exact(tab, "A_hat") == Ah
        if s > 1:
            assert _exact(tab, "omega") == om
    for s_values in ((1, 2, 3), (2, 3)):
        tab = _run(monkeypatch, ST.spark_tableaux(s_values=s_values, symmetric=True), policy, perm=False)
        s = 2 if policy == "high" or s_values[0] == 2 else 1
        assert tab.s == s and check_23(tab) and check_22b(tab)
        if s == 2:
            a11, a12 = Q(1, 4) + d * Q(1, 10), d * Q(1, 10)
            want = [[a11, a12], [Q(1, 2) - a12, Q(1, 2) - a11]]
            assert _exact(tab, "A") == want and _exact(tab, "A_tilde") == want


def test_spark_tableaux_satisfy_22_in_the_documented_neighbourhood_and_cover_s_1_to_3():
    tabs = collect(ST.spark_tableaux(), 30)
    for t in tabs:
        _check_random_tableau(t, (1, 2, 3))
    assert {t.s for t in tabs} == {1, 2, 3}
    two = collect(ST.spark_tableaux(s_values=(2,)), 5)
    assert {t.s for t in two} == {2}
    for t in two:
        _check_random_tableau(t, (2,))


def test_symmetric_spark_tableaux_satisfy_23_and_cover_s_1_and_2():
    tabs = collect(ST.spark_tableaux(symmetric=True), 20)
    assert {t.s for t in tabs} == {1, 2}
    for t in tabs:
        assert check_22a(t) and check_22b(t) and check_23(t), t.name
        if t.s == 1:
            assert t.name == "random-sym-1" and _exact(t, "A") == [[Q(1, 2)]] and _exact(t, "A_tilde") == [[Q(1, 2)]]
            assert _col(t, "b") == [1]
        else:
            assert t.name == "random-sym-2" and _col(t, "b") == [Q(1, 2), Q(1, 2)]
            assert _exact(t, "omega") == [[Q(1, 2), Q(1, 2)]]
            for M in ("A", "A_tilde"):
                a = _exact(t, M)
                assert abs(a[0][0] - Q(1, 4)) <= Q(1, 10) and abs(a[0][1]) <= Q(1, 10), a
                assert a[1][0] == Q(1, 2) - a[0][1] and a[1][1] == Q(1, 2) - a[0][0]
    assert any(t.s == 2 and _exact(t, "A") != _exact(t, "A_tilde") for t in tabs)
    assert {t.s for t in collect(ST.spark_tableaux(symmetric=True, s_values=(1,)), 3)} == {1}
    assert {t.s for t in collect(ST.spark_tableaux(symmetric=True, s_values=(2, 3)), 5)} == {2}


def test_general_tableau_as_documented():
    tab = GF.general_tableau()
    A, Ah, At = _exact(tab, "A"), _exact(tab, "A_hat"), _exact(tab, "A_tilde")
    b, bh, bt, c = _col(tab, "b"), _col(tab, "b_hat"), _col(tab, "b_tilde"), _col(tab, "c")
    assert check_22a(tab) and check_22b(tab) and not check_23(tab)
    assert all(b[i] * Ah[i][j] + b[j] * A[j][i] == b[i] * b[j] for i in range(2) for j in range(2))
    assert c == [sum(r) for r in A] and c != b and bh == b and bt != bh and sum(bt) == 1 and sum(b) == 1
    assert At != Ah and _exact(tab, "omega") == [[Q(1, 3), Q(2, 3)]]
    # the fixture's data (docstring: A arbitrary, b_tilde != b): pinned, a change must be deliberate
    assert A == [[Q(1, 4), Q(-1, 20)], [Q(3, 4), Q(1, 4)]] and b == [Q(3, 5), Q(2, 5)]
    assert At == [[Q(1, 3), Q(1, 10)], [Q(2, 5), Q(1, 5)]] and bt == [Q(9, 20), Q(11, 20)]
    assert tab.name == "general-2"


def test_the_method_table_lists_the_builtin_methods_up_to_four_stages(monkeypatch):
    from ldaspark.analysis import conditions as cond
    asked = []
    monkeypatch.setattr(cond, "builtin_method_names", lambda max_s: asked.append(max_s) or [])
    assert cond.method_table() == [] and asked == [4]
