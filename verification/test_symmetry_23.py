"""Symmetry under (23): L_d(t1,q1,t0,q0) = -L_d(t0,q0,t1,q1), f_d^+(t1,q1,t0,q0) =
-f_d^-(t0,q0,t1,q1) and its twin, Phi_{-h}(Phi_h(y)) = y; all <= 1e-25 at 40 digits for the
symmetric built-ins, and the Euler methods fail.

Finding: the f_d identities hold for variations tangent to the discrete constraint manifold
C_d (consistent v0); as covectors on all of R^n they fail (off C_d the forward BVP leaves v0
inconsistent while the reversed one imposes k = 0 there), which the last test shows."""
import pytest

from ldaspark.analysis.discrete import SINGULAR
from ldaspark.analysis.symmetry import check_symmetry
from ldaspark.lab.claims.ledger import TOL_SYMMETRY, perturbed_initial

H = "0.1"


def _sym(scene, tab, perturbed=True):
    t0, q0, v0 = perturbed_initial(scene, 60) if perturbed else scene.initial(60)
    return check_symmetry(scene.system, tab, t0, q0, v0, H, dps=40)


@pytest.mark.parametrize("name", ["gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2",
                                  "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-2"])
@pytest.mark.parametrize("scn", ["particle", "skate"])
def test_symmetry_symmetric_methods(name, scn, exact_method, scene):
    r = _sym(scene(scn), exact_method(name))
    assert r["symmetry-Ld"] <= TOL_SYMMETRY, r
    assert r["symmetry-Phi"] <= TOL_SYMMETRY, r
    if r["wellposed"] != SINGULAR:     # f_d of a singular BVP depend on the pin
        assert r["symmetry-fd-plus"] <= TOL_SYMMETRY, r
        assert r["symmetry-fd-minus"] <= TOL_SYMMETRY, r
        assert min(r["tangent_dim"]) >= 1


@pytest.mark.parametrize("name", ["euler-i", "euler-ii"])
@pytest.mark.parametrize("scn", ["particle", "skate"])
def test_symmetry_fails_for_euler(name, scn, exact_method, scene):
    r = _sym(scene(scn), exact_method(name))
    assert r["symmetry-Ld"] > 1e-6, r
    assert r["symmetry-Phi"] > 1e-6, r
    # the f_d identities' own control: Euler II, the closer of the two, misses them by
    # >= 1.4e-5 on C_d at h = 0.1 (measured), 20 orders above TOL_SYMMETRY
    assert r["symmetry-fd-plus"] > 1e-7, r
    assert r["symmetry-fd-minus"] > 1e-7, r


def test_symmetry_fails_for_perturbed_A_tilde(exact_method, scene):
    # (22) still holds (A_tilde is free there) but (23d) does not: Phi_-h o Phi_h != id
    tab = exact_method("gauss-2").with_entry("A_tilde", 0, 1, "1/10")
    r = _sym(scene("particle"), tab)
    assert r["symmetry-Phi"] > 1e-8, r
    # the f_d identities (23) fail with it, on C_d (measured 5e-5, 4e-5)
    assert min(r["symmetry-fd-plus"], r["symmetry-fd-minus"]) > 1e-7, r


def _lobatto3_own_b_tilde(b_tilde):
    """Lobatto IIIA-IIIB 3 with A_tilde = IIIB + (w - b) / 2 in every row, w = (1/4, 1/2, 1/4):
    (23d) a~_(s+1-i,s+1-j) + a~_ij = w_j holds, so with b_tilde = w the tableau satisfies (23)
    with b_tilde != b_hat (the built-ins have b_tilde = b_hat = b, where a (23d) read with b_hat
    and a (21d) run with b_hat on the constraint forces are invisible); with b_tilde = b_hat it
    does not. (22) holds for both (A_tilde and b_tilde are free there)."""
    from ldaspark.core.tableau_file import from_json_dict
    d = {"c": ["0", "1/2", "1"],
         "A": [["0", "0", "0"], ["5/24", "1/3", "-1/24"], ["1/6", "2/3", "1/6"]],
         "A_hat": [["1/6", "-1/6", "0"], ["1/6", "1/3", "0"], ["1/6", "5/6", "0"]],
         "A_tilde": [["5/24", "-1/4", "1/24"], ["5/24", "1/4", "1/24"], ["5/24", "3/4", "1/24"]],
         "b": ["1/6", "2/3", "1/6"], "b_hat": ["1/6", "2/3", "1/6"], "b_tilde": list(b_tilde),
         "omega": [["1/6", "2/3", "1/6"], ["0", "1/3", "1/6"]]}
    return from_json_dict(d, name="lobatto3-b_tilde=" + "/".join(b_tilde))


@pytest.mark.parametrize("scn", ["particle", "skate"])
def test_23d_with_b_tilde_decides_the_symmetry(scn, scene):
    """(23) is a statement about b_tilde, not b_hat: the tableau with b_tilde = (1/4, 1/2, 1/4)
    != b_hat satisfies (23) and its step is symmetric (Phi_-h o Phi_h - id measured 1.4e-42,
    1.0e-42 at 40 digits); the same A_tilde with b_tilde = b_hat breaks (23d) and misses the
    round trip by 1.4e-5, 8.8e-6 (control, >= TOL_NEGATIVE 1e-6). The BVP is singular here (f_d
    depend on the pin), so the round trip Phi decides. Planted (23d) checked with b_hat
    (analysis/conditions.py, mutant teeth-conditions-23d-bhat): 55 tests of the verification
    files that call check_23 passed it (the built-ins and the random tableaux have b_tilde =
    b_hat); this test fails on it (check_23 rejects the symmetric tableau)."""
    from ldaspark.analysis.conditions import check_22a, check_22b, check_23
    from ldaspark.lab.claims.ledger import TOL_NEGATIVE
    good, bad = _lobatto3_own_b_tilde(("1/4", "1/2", "1/4")), _lobatto3_own_b_tilde(("1/6", "2/3", "1/6"))
    assert all(check_22a(t) and check_22b(t) for t in (good, bad))
    assert check_23(good) and not check_23(bad)
    assert _sym(scene(scn), good)["symmetry-Phi"] <= TOL_SYMMETRY
    assert _sym(scene(scn), bad)["symmetry-Phi"] >= TOL_NEGATIVE


def test_fd_symmetry_only_on_C_d(exact_method, scene):
    r = _sym(scene("particle"), exact_method("gauss-2"))
    assert r["symmetry-fd-plus"] <= TOL_SYMMETRY
    assert min(r["symmetry-fd-unrestricted"]) > 1e-3, r


def test_symmetry_robot(exact_method, scene):
    r = _sym(scene("robot"), exact_method("lobatto-iiia-iiib-2"))
    assert max(r["symmetry-Ld"], r["symmetry-Phi"], r["symmetry-fd-plus"], r["symmetry-fd-minus"]) <= TOL_SYMMETRY, r


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", ["gauss-4", "lobatto-iiia-iiib-4", "lobatto-iiia-iiib-iiid-4",
                                  "gauss-6", "lobatto-iiia-iiib-6"])
@pytest.mark.parametrize("scn", ["particle", "skate", "robot", "mp-particles"])
def test_symmetry_exhaustive(name, scn, scene):
    from ldaspark.core.families import get_method
    r = _sym(scene(scn), get_method(name))
    assert r["symmetry-Ld"] <= TOL_SYMMETRY and r["symmetry-Phi"] <= TOL_SYMMETRY, r
