"""(22a), (22b), (23a-d) checked exactly (sympy algebraic number field: rationals and radicals)
on every built-in family; the Euler methods satisfy (22) but not (23); perturbed tableaux fail."""
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
