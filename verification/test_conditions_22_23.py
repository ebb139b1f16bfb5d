"""(22a), (22b), (23a-d) checked exactly (sympy algebraic number field: rationals and radicals)
on every built-in family; the Euler methods satisfy (22) but not (23); perturbed tableaux fail.
The numeric builders the integrators run satisfy (22), (23) and omega_ij = b_j c_j^(i-1) up to the
rounding of their entries (tolerance derived below)."""
import pytest

from ldaspark.analysis.conditions import check_22a, check_22b, check_23
from ldaspark.lab.claims.ledger import negative_controls, proof_conditions

FAMILIES = ["gauss-%d" % s for s in range(1, 6)] + \
    ["lobatto-iiia-iiib-%d" % s for s in range(2, 6)] + \
    ["lobatto-iiia-iiib-iiid-%d" % s for s in range(2, 6)]


@pytest.mark.parametrize("name", FAMILIES)
def test_22a_22b_23_families(name, exact_method):
    tab = exact_method(name)
    assert tab.is_exact
    assert check_22a(tab), f"(22a) b_hat = b fails for {name}"
    assert check_22b(tab), f"(22b) fails for {name}"
    assert check_23(tab), f"(23a-d) symmetry fails for {name}"
    assert proof_conditions(tab) == (True, True)
    # (21e) with the coefficients of section 6, omega_ij = b_j c_j^(i-1), exactly
    K, e = tab.field_entries()
    assert all(e["omega"][i][j] == e["b"][j] * e["c"][j] ** i for i in range(tab.s - 1) for j in range(tab.s)), name


@pytest.mark.parametrize("name", ["euler-i", "euler-ii"])
def test_euler_satisfies_22_not_23(name, exact_method):
    tab = exact_method(name)
    assert check_22a(tab) and check_22b(tab)
    assert not check_23(tab)


def test_negative_controls_break_22():
    for tab, intended in negative_controls():
        assert ("pass" if check_22a(tab) else "fail") == intended["22a"], tab.name
        assert ("pass" if check_22b(tab) else "fail") == intended["22b"], tab.name
        c0, c1 = proof_conditions(tab)
        assert not c1                       # the q1 identity must break
        assert c0 == ("b_hat" in tab.name)  # b_hat != b leaves the q0 algebra intact


def test_22b_detects_tiny_exact_perturbation(exact_method):
    # exactness matters: a 1e-30 change is invisible in float64 but fails the exact check
    tab = exact_method("lobatto-iiia-iiib-3").with_entry("A_hat", 2, 2, "1e-30")
    assert check_22a(tab) and not check_22b(tab)
    tab = exact_method("gauss-2").with_entry("A_tilde", 0, 1, "1/7")
    assert check_22b(tab) and not check_23(tab)   # A_tilde is free in (22), not in (23d)


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", ["lobatto-iiia-iiib-6", "lobatto-iiia-iiib-iiid-6"])
def test_22_23_s6(name, exact_method):
    tab = exact_method(name)
    assert check_22a(tab) and check_22b(tab) and check_23(tab)


# Each of (23a), (23b), (23c), (23d) decides on its own: a symmetric tableau with one entry of
# exactly one of c, A, A_hat, A_tilde moved (by 1/7, exact) breaks (23) and nothing else of it.
# Lobatto IIIA-B-D 3 has three different matrices, so no perturbation hides behind an equal one.
@pytest.mark.parametrize("entry,i,j", [("c", 0, None), ("A", 0, 1), ("A_hat", 2, 0), ("A_tilde", 1, 2)])
def test_23_each_condition_decides(entry, i, j, exact_method):
    base = exact_method("lobatto-iiia-iiib-iiid-3")
    assert check_23(base)
    assert not check_23(base.with_entry(entry, i, j, "1/7")), entry
    # two-sided: the moved entry's mirror moved by the opposite amount keeps (23) (the check is
    # the printed pairing a_{s+1-i,s+1-j} + a_ij, c_{s+1-i} + c_i, not a stricter one)
    s = base.s
    ri, rj = s - 1 - i, (None if j is None else s - 1 - j)
    pair = base.with_entry(entry, i, j, "1/7").with_entry(entry, ri, rj, "-1/7")
    assert check_23(pair), entry


def _one_stage(b_hat, a_hat):
    from ldaspark.core.tableau_file import from_json_dict
    return from_json_dict({"c": ["1/2"], "A": [["1/2"]], "A_hat": [[a_hat]], "A_tilde": [["1/2"]],
                           "b": ["1"], "b_hat": [b_hat], "b_tilde": ["1"]}, name="b_hat-control")


def test_22b_uses_b_hat_where_printed():
    # (22b) b^_i a_ij + b_j a^_ji - b^_i b_j = 0 with a = 1/2, b = 1: a^ = b^/2. With b^ = 2,
    # a^ = 1 satisfies (22b) (not (22a)); a^ = 1/2 satisfies the b^ -> b variant b_i a_ij +
    # b_j a^_ji - b_i b_j = 0 but not (22b). Decides whether b_hat enters where the paper has it.
    assert check_22b(_one_stage("2", "1")) and not check_22a(_one_stage("2", "1"))
    assert not check_22b(_one_stage("2", "1/2"))


# The integrators run the numeric builders (``get_method(name)``, any precision), not the exact
# entries above: (22), (23) and omega_ij = b_j c_j^(i-1) (section 6) must hold for those too,
# up to the rounding of their entries. Entries correct to DPS_NUM digits carry a relative error
# <= eps = 2^(1-prec); each term of (22b), (23b-d) and omega is a product of at most s + 1
# entries of size <= M, so a residual of R terms is <= R (s + 2) eps M^(s+1) (rounding of the
# products included). tol is that bound; a fault in a builder leaves O(1).
DPS_NUM = 50


@pytest.mark.parametrize("name", ["gauss-2", "gauss-3", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-3",
                                  "lobatto-iiia-iiib-iiid-4"])
def test_22_23_omega_numeric_builders(name):
    import mpmath
    from ldaspark.core.families import get_method
    a = get_method(name).arrays(DPS_NUM)
    s = a.c.shape[0]
    with mpmath.workdps(DPS_NUM):
        ents = [abs(x) for k in ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde", "omega")
                for x in getattr(a, k).reshape(-1)]
        M = max(max(ents), 1)
        tol = 3 * (s + 2) * mpmath.mp.eps * M ** (s + 1)
        r = lambda i: s - 1 - i
        res = {"22a": max(abs(a.b_hat[i] - a.b[i]) for i in range(s)),
               "22b": max(abs(a.b_hat[i] * a.A[i, j] + a.b[j] * a.A_hat[j, i] - a.b_hat[i] * a.b[j])
                          for i in range(s) for j in range(s)),
               "23a": max(abs(a.c[r(i)] + a.c[i] - 1) for i in range(s))}
        for M_, bv in (("A", "b"), ("A_hat", "b_hat"), ("A_tilde", "b_tilde")):
            X, bb = getattr(a, M_), getattr(a, bv)
            res[M_] = max(max(abs(X[r(i), r(j)] + X[i, j] - bb[j]), abs(bb[r(j)] - bb[j]))
                          for i in range(s) for j in range(s))
        res["omega"] = max(abs(a.omega[i, j] - a.b[j] * a.c[j] ** i) for i in range(s - 1) for j in range(s))
        bad = {k: float(v) for k, v in res.items() if v > tol}
        assert not bad, (name, bad, float(tol))
        # the bound is not loose to the point of accepting anything: 1e-30 is far above it
        assert tol < mpmath.mpf(10) ** -40
