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
