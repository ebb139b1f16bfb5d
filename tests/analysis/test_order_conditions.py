"""Trees, elementary weights, B/C/D and the stability function (ldaspark.analysis.order_conditions),
against textbook facts and independent sympy computations; each with a negative control."""
import pytest
import sympy
from hypothesis import given, strategies as st
from sympy import Rational as R

from ldaspark.analysis import order_conditions as oc
from ldaspark.core.tableau import SparkTableau
from ldaspark.core.families import get_method


def rk_tab(A, b, name="rk"):
    """Exact SparkTableau with A = A_hat = A_tilde (only A, b matter for these tests)."""
    s = len(b)
    A = sympy.Matrix(A)
    b = sympy.Matrix(s, 1, b)
    c = sympy.Matrix(s, 1, [sum(A.row(i)) for i in range(s)])
    om = sympy.Matrix(max(s - 1, 0), s, lambda i, j: b[j] * c[j] ** i) if s > 1 else sympy.zeros(0, 1)
    ex = {"c": c, "A": A, "A_hat": A, "A_tilde": A, "b": b, "b_hat": b, "b_tilde": b, "omega": om}
    return SparkTableau(name, s, exact=ex)


RK4 = ([[0, 0, 0, 0], [R(1, 2), 0, 0, 0], [0, R(1, 2), 0, 0], [0, 0, 1, 0]], [R(1, 6), R(1, 3), R(1, 3), R(1, 6)])


def test_tree_counts_match_oeis():
    assert [len(oc.trees(n)) for n in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]        # A000081
    assert [len(oc.trees(n, 2)) for n in range(1, 9)] == [2, 4, 14, 52, 214, 916, 4116, 18996]  # A038055
    assert [len(oc.trees(n, 3)) for n in range(1, 6)] == [3, 9, 45, 246, 1485]
    # canonical forms: no duplicates
    assert len(set(oc.trees(7, 2))) == 4116


def test_density_tall_and_bushy():
    tall = (0, ())
    for n in range(2, 9):
        tall = (0, (tall,))
        assert oc.density(tall) == sympy.factorial(n)
    for n in range(1, 9):
        bushy = (0, tuple([(0, ())] * (n - 1)))
        assert oc.density(bushy) == n


def test_rk4_order_4_and_perturbed_b_breaks_it():
    ar, e = oc.exact_arith(rk_tab(*RK4))
    assert oc.rk_order(ar, e["A"], e["b"]).order == 4
    A, b = RK4
    bad = oc.exact_arith(rk_tab(A, [R(1, 6), R(1, 3) + R(1, 100), R(1, 3) - R(1, 100), R(1, 6)]))
    r = oc.rk_order(bad[0], bad[1]["A"], bad[1]["b"])
    # c2 = c3 so sum b c^k is unchanged; b^T A c = 1/6 (tree o[o[o]]) is the first to fail
    assert r.order == 2 and r.failing == "o[o[o]]" and abs(r.residual - 1 / 400) < 1e-15


@pytest.mark.parametrize("s", [1, 2, 3])
def test_gauss_exact_order_2s_bcd(s):
    tab = get_method(f"gauss-{s}", exact=True)
    ar, e = oc.exact_arith(tab)
    assert ar.exact
    assert oc.rk_order(ar, e["A"], e["b"]).order == 2 * s
    sa = oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"])
    assert sa == {"B": 2 * s, "C": s, "D": s}
    st_ = oc.stability(ar, e["A"], e["b"])
    assert not st_.A_singular and st_.r_inf == (-1) ** s


@pytest.mark.parametrize("s", [2, 3])
def test_lobatto_pair_order_2s_minus_2(s):
    tab = get_method(f"lobatto-iiia-iiib-{s}", exact=True)
    ar, e = oc.exact_arith(tab)
    assert oc.pair_order(ar, e["A"], e["b"], e["A_hat"], e["b_hat"]).order == 2 * s - 2
    assert oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"])["C"] == s          # IIIA: C(s)
    assert oc.simplifying_assumptions(ar, e["A_hat"], e["b_hat"], e["c"])["D"] == s  # IIIB: D(s)
    st_ = oc.stability(ar, e["A"], e["b"])
    assert st_.A_singular and st_.r_inf == (-1) ** (s - 1)  # IIIA: first row zero


def test_symplectic_euler_pair_is_order_1_but_each_part_alone_is_order_1_too():
    ar, e = oc.exact_arith(get_method("euler-i"))
    r = oc.pair_order(ar, e["A"], e["b"], e["A_hat"], e["b_hat"])
    assert r.order == 1 and r.failing in ("q[p]", "p[q]")
    # negative control: Stormer-Verlet = Lobatto IIIA-IIIB 2 reaches 2
    ar2, e2 = oc.exact_arith(get_method("lobatto-iiia-iiib-2", exact=True))
    assert oc.pair_order(ar2, e2["A"], e2["b"], e2["A_hat"], e2["b_hat"]).order == 2


def test_two_colours_with_equal_coefficients_reduce_to_one_colour():
    """The merge in additive_order is a shortcut: evaluating all bi-coloured trees with the same
    method in both colours gives the same order."""
    ar, e = oc.exact_arith(get_method("gauss-2", exact=True))
    full = oc._order_from_trees(ar, [e["A"], e["A"]], [e["b"], e["b"]], 2, 6, ("q", "p"))
    assert full.order == 4 == oc.rk_order(ar, e["A"], e["b"], 6).order


def test_iiid_forced_ode_order_uses_three_colours():
    ar, e = oc.exact_arith(get_method("lobatto-iiia-iiib-iiid-3", exact=True))
    r = oc.spark_ode_order(ar, e)
    assert r.order == 4 and r.counts[5] == 1485   # 3 colours really evaluated


def test_mp_arith_agrees_with_exact_and_has_a_tolerance():
    tab = get_method("gauss-3")  # builder only: mp path
    ar, e = oc.mp_arith(tab, 30)
    assert not ar.exact and ar.tol < 1e-25
    assert oc.rk_order(ar, e["A"], e["b"]).order == 6
    assert oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"]) == {"B": 6, "C": 3, "D": 3}
    # float-precision entries: tolerance follows the 15 source digits
    tabf = SparkTableau("f", 3, exact=get_method("gauss-3", exact=True).exact, source_digits=15)
    arf, _ = oc.mp_arith(tabf, 30)
    assert 1e-13 < arf.tol < 1e-10


def _direct_R(A, b, z):
    s = len(b)
    M = sympy.eye(s) - z * sympy.Matrix(A)
    return sympy.nsimplify(1 + z * (sympy.Matrix([b]) * M.inv() * sympy.ones(s, 1))[0])


@given(st.lists(st.fractions(min_value=-2, max_value=2, max_denominator=7), min_size=6, max_size=6))
def test_stability_polynomials_match_direct_formula(vals):
    A = [[R(vals[0].numerator, vals[0].denominator), R(vals[1].numerator, vals[1].denominator)],
         [R(vals[2].numerator, vals[2].denominator), R(vals[3].numerator, vals[3].denominator)]]
    b = [R(vals[4].numerator, vals[4].denominator), R(vals[5].numerator, vals[5].denominator)]
    ar, e = oc.exact_arith(rk_tab(A, b))
    stb = oc.stability(ar, e["A"], e["b"])
    for z in (R(1, 3), R(-2, 5)):
        if (sympy.eye(2) - z * sympy.Matrix(A)).det() == 0:
            continue
        P = sum(ar.K.to_sympy(c) * z ** k for k, c in enumerate(stb.P))
        Q = sum(ar.K.to_sympy(c) * z ** k for k, c in enumerate(stb.Q))
        assert sympy.simplify(P / Q - _direct_R(A, b, z)) == 0
    detA = sympy.Matrix(A).det()
    assert stb.A_singular == (detA == 0)
    if detA != 0:   # R(inf) = 1 - b^T A^{-1} 1
        rinf = 1 - (sympy.Matrix([b]) * sympy.Matrix(A).inv() * sympy.ones(2, 1))[0]
        assert abs(stb.r_inf - float(rinf)) < 1e-12


def test_explicit_and_implicit_euler_r_inf():
    ar, e = oc.exact_arith(rk_tab([[0]], [1]))
    assert oc.stability(ar, e["A"], e["b"]).r_inf == float("inf")
    ar, e = oc.exact_arith(rk_tab([[1]], [1]))
    assert oc.stability(ar, e["A"], e["b"]).r_inf == 0.0


def seven_array_tableau():
    """Distinguishing fixture: the seven coefficient arrays pairwise different, c not
    symmetric (c = (1/5, 1/2, 1)), every row sum = c, built so that each coefficient set has its
    own order, derived by hand:
    (A, b): B(3) (b c^k = 1/(k+1), k < 3) and b^T A c = 1/6, b c^3 = 4/15 != 1/4: order 3;
    (A_hat, b_hat): b_hat = b + (5/72, -1/9, 1/24), b_hat c = 1/2, b_hat c^2 = 7/20 != 1/3: order 2;
    (A_tilde, b_tilde): b_tilde = (1/3, 1/3, 1/3), b_tilde c = 17/30 != 1/2: order 1.
    So the pair (A; A_hat) has order 2 and the forced ODE (A; A_hat, A_tilde) order 1; with b_hat
    in place of b_tilde it would be 2 (and the order of A_tilde alone 2)."""
    from ldaspark.core.tableau_file import from_json_dict
    d = {"c": ["1/5", "1/2", "1"],
         "A": [["1/5", "0", "0"], ["1/4", "1/4", "0"], ["1/2", "12/25", "1/50"]],
         "A_hat": [["0", "1/5", "0"], ["1/2", "0", "0"], ["1/3", "1/3", "1/3"]],
         "A_tilde": [["1/10", "1/10", "0"], ["0", "1/4", "1/4"], ["1/4", "1/4", "1/2"]],
         "b": ["25/72", "4/9", "5/24"], "b_hat": ["5/12", "1/3", "1/4"], "b_tilde": ["1/3", "1/3", "1/3"],
         "omega": [["1/3", "1/3", "1/3"], ["1/5", "2/5", "2/5"]]}
    return from_json_dict(d, name="seven-arrays-3")


def test_seven_array_tableau_orders_see_which_weights_belong_to_which_matrix():
    tab = seven_array_tableau()
    ar, e = oc.exact_arith(tab)
    keys = ("c", "b", "b_hat", "b_tilde", "A", "A_hat", "A_tilde")
    assert all(e[x] != e[y] for i, x in enumerate(keys) for y in keys[i + 1:]), "arrays not pairwise different"
    assert e["c"][0] + e["c"][2] != 1                                  # c not symmetric
    assert oc.rk_order(ar, e["A"], e["b"]).order == 3
    assert oc.rk_order(ar, e["A_hat"], e["b_hat"]).order == 2
    assert oc.rk_order(ar, e["A_tilde"], e["b_tilde"]).order == 1
    assert oc.pair_order(ar, e["A"], e["b"], e["A_hat"], e["b_hat"]).order == 2
    r = oc.spark_ode_order(ar, e)
    assert r.order == 1 and "R" in r.failing, r                       # an R-rooted tree of order 2 fails
    # negative controls: the plausible neighbours give other orders on this fixture
    assert oc.additive_order(ar, [(e["A"], e["b"]), (e["A_hat"], e["b_hat"]), (e["A_tilde"], e["b_hat"])]).order == 2
    assert oc.rk_order(ar, e["A_tilde"], e["b_hat"]).order == 2
    # the mpmath arithmetic (tableaux known only numerically) agrees
    ar2, e2 = oc.mp_arith(tab, 30)
    assert [oc.spark_ode_order(ar2, e2).order, oc.pair_order(ar2, e2["A"], e2["b"], e2["A_hat"], e2["b_hat"]).order] \
        == [1, 2]


def test_audit_order_facts_and_22_on_the_seven_array_tableau():
    """The audit's per-matrix orders, the forced-ODE prediction and (22a), (22b) read the right
    arrays: the expected residuals are computed here from the definitions."""
    from fractions import Fraction as Fr

    from ldaspark.lab.theory import audit_checks as ac
    from ldaspark.analysis.conditions import check_22a, check_22b
    tab = seven_array_tableau()
    ar, e = oc.exact_arith(tab)
    _, facts = ac.order_checks(ar, e)
    assert (facts["order:A"], facts["order:A_hat"], facts["order:A_tilde"], facts["order:pair"],
            facts["order:forced-ode"]) == (3, 2, 1, 2, 1)
    b = [Fr(25, 72), Fr(4, 9), Fr(5, 24)]
    bh = [Fr(5, 12), Fr(1, 3), Fr(1, 4)]
    A = [[Fr(1, 5), 0, 0], [Fr(1, 4), Fr(1, 4), 0], [Fr(1, 2), Fr(12, 25), Fr(1, 50)]]
    Ah = [[0, Fr(1, 5), 0], [Fr(1, 2), 0, 0], [Fr(1, 3), Fr(1, 3), Fr(1, 3)]]
    w22a = max(abs(x - y) for x, y in zip(bh, b))
    w22b = max(abs(bh[i] * A[i][j] + b[j] * Ah[j][i] - bh[i] * b[j]) for i in range(3) for j in range(3))
    c22a, c22b = ac.check_22a(ar, e), ac.check_22b(ar, e)
    assert c22a.status == ac.FAIL and c22a.residual == pytest.approx(float(w22a), rel=1e-12)
    assert c22b.status == ac.FAIL and c22b.residual == pytest.approx(float(w22b), rel=1e-12)
    assert not check_22a(tab) and not check_22b(tab)


def _lobatto3_with_own_tilde(b_tilde, a_from=None):
    """Lobatto IIIA-IIIB 3 with A_tilde_ij = w_j / 2 (w = ``a_from``, default b_tilde), which
    satisfies (23d) with respect to b_tilde = w for any symmetric w: a symmetric method with
    b_tilde != b_hat."""
    from ldaspark.core.tableau_file import from_json_dict
    bt = [sympy.Rational(x) for x in b_tilde]
    w = [sympy.Rational(x) for x in (a_from or b_tilde)]
    d = {"c": ["0", "1/2", "1"],
         "A": [["0", "0", "0"], ["5/24", "1/3", "-1/24"], ["1/6", "2/3", "1/6"]],
         "A_hat": [["1/6", "-1/6", "0"], ["1/6", "1/3", "0"], ["1/6", "5/6", "0"]],
         "A_tilde": [[str(x / 2) for x in w] for _ in range(3)],
         "b": ["1/6", "2/3", "1/6"], "b_hat": ["1/6", "2/3", "1/6"], "b_tilde": [str(x) for x in bt],
         "omega": [["1/6", "2/3", "1/6"], ["0", "1/3", "1/6"]]}
    return from_json_dict(d, name="lobatto3-own-tilde")


def test_23d_reads_b_tilde_not_b_hat():
    """(23d) A_tilde_(s+1-i,s+1-j) + A_tilde_ij = b_tilde_j holds here with b_tilde = (1/4, 1/2, 1/4)
    != b_hat; checked with b_hat it would fail (control: the same A_tilde with b_tilde = b_hat)."""
    from ldaspark.lab.theory import audit_checks as ac
    from ldaspark.analysis.conditions import check_22a, check_22b, check_23
    tab = _lobatto3_with_own_tilde(["1/4", "1/2", "1/4"])
    ar, e = oc.exact_arith(tab)
    assert e["b_tilde"] != e["b_hat"] and e["A_tilde"] != e["A_hat"]
    assert check_22a(tab) and check_22b(tab) and check_23(tab)
    assert {c.name: c.status for c in ac.check_23(ar, e)} == {"23a": ac.PASS, "23b": ac.PASS, "23c": ac.PASS,
                                                             "23d": ac.PASS}
    # control: the same A_tilde with b_tilde = b_hat (the neighbour a wrong check would read)
    bad = _lobatto3_with_own_tilde(["1/6", "2/3", "1/6"], a_from=["1/4", "1/2", "1/4"])
    ar2, e2 = oc.exact_arith(bad)
    assert not check_23(bad)
    assert {c.name: c.status for c in ac.check_23(ar2, e2)}["23d"] == ac.INFO
