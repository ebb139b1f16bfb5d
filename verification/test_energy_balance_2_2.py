"""Section 2.2: dE/dt = -psi^T K v - L_t (E = L_v v - L (8)), on test systems where energy is not
conserved (time-dependent L; affine rheonomic b(t, q); k nonlinear in v) and on the conservative
cases (the particle of 8.1: scleronomic, linear, autonomous; and a rheonomic but linear k).

Exact side (exact flow of ``exact_flow``, 28 digits, 8 Gauss nodes, h = 0.1): the balance holds
pointwise at the nodes (E_t + E_q v + E_v a) and integrated (E(t1) - E(t0) vs Gauss quadrature),
<= 1e-22; controls: dropping -L_t (time-dependent L) or the psi term (affine b) fails.
Discrete side (one SPARK step, h = 0.2, 0.1, 0.05, 30 digits): Delta E against the stage
quadrature h sum b_i (-Psi_i^T K_i V_i - L_t(T_i, Q_i, V_i)); the mismatch has order p + 1
(Gauss-1: 3, Gauss-2: 5, Lobatto IIIA-B 2: 3, Euler I: 2) while Delta E itself is O(h); on the
conservative particle Delta E is O(h^{p+1}). Gauss methods satisfy the discrete balance exactly
when L_t = 0 and E is quadratic (measured 1e-31). Cost ~8 s."""
import pytest

from ldaspark.lab.theory.energy_balance import discrete_balance, exact_balance, predicted_mismatch_order

TOL = 1e-22
NEG = 1e-6


@pytest.mark.parametrize("name,control", [("time-L", "without_L_t"), ("affine-b", "without_psi_term")])
def test_energy_balance_2_2_exact_nonconservative(name, control):
    r = exact_balance(name, dps=28, stages=8)
    assert r["pointwise"] < TOL and r["integral"] < TOL, r
    assert r["delta_E"] > 1e-3, r                  # energy is not conserved here ...
    assert r[control] > NEG, r                     # ... and the dropped term is what changes it


@pytest.mark.parametrize("name", ["particle", "rheonomic-linear"])
def test_energy_balance_2_2_exact_conserved(name):
    """Scleronomic linear k with autonomous L (the paper's case) conserves E; so does a rheonomic
    k linear in v (K v = k = 0): the paper's condition is sufficient, not necessary."""
    r = exact_balance(name, dps=28, stages=8)
    assert r["pointwise"] < TOL and r["delta_E"] < 1e-20, r


@pytest.mark.parametrize("method,p", [("gauss-1", 2), ("gauss-2", 4), ("lobatto-iiia-iiib-2", 2), ("euler-i", 1)])
def test_energy_balance_2_2_discrete_order(method, p, exact_method):
    r = discrete_balance("time-L", exact_method(method), hs=("0.1", "0.05", "0.025"))
    # two-sided, the finest pair decides (measured 2.96, 5.02, 3.0, 2.35: Euler I approaches 2 from
    # above, 2.51 at 0.2/0.1); tol 0.4 < 1/2, so a prediction off by one fails
    assert predicted_mismatch_order(exact_method(method)) == p + 1
    assert abs(r["order_mismatch"] - (p + 1)) <= 0.4, r
    assert 0.7 < r["order_delta_E"] < 1.3 and r["delta_E"][-1] > 1e-3, r     # not conserved: O(h)
    # control: the quadrature without -L_t misses by O(h)
    assert r["mismatch_without_L_t"][-1] > NEG and r["order_mismatch_without_L_t"] < 1.3, r
    c = discrete_balance("particle", exact_method(method))
    # one-sided on purpose: "conserved up to O(h^{p+1})" is an upper bound on the error (Gauss
    # does better on this quadratic energy: 5.2 for Gauss-1)
    assert c["order_delta_E"] > p + 1 - 0.3, c


def test_energy_balance_2_2_discrete_exact_for_gauss(exact_method):
    r = discrete_balance("affine-b", exact_method("gauss-2"))
    assert max(r["mismatch"]) < 1e-25 and r["delta_E"][-1] > 1e-3, r
    c = discrete_balance("affine-b", exact_method("lobatto-iiia-iiib-2"))
    assert c["mismatch"][-1] > NEG, c                # not an identity for every method


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", ["time-L", "affine-b", "nonlinear-k", "rheonomic-linear", "particle"])
@pytest.mark.parametrize("method", ["gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                                    "lobatto-iiia-iiib-iiid-3", "euler-i", "euler-ii"])
def test_energy_balance_exhaustive(name, method, exact_method):
    r = exact_balance(name)
    assert r["pointwise"] < 1e-25 and r["integral"] < 1e-25, r
    tab = exact_method(method)
    d = discrete_balance(name, tab, hs=("0.1", "0.05", "0.025"))
    p = tab.claimed_order
    # the finest mismatch at the round-off floor: the balance holds to working precision (no order)
    assert d["mismatch"][-1] <= d["floor"] or d["order_mismatch"] > p + 1 - 0.4, d


def test_discrete_order_is_the_finest_pair_of_a_pre_asymptotic_sweep(exact_method):
    """Distinguishing fixture: Euler I on time-L at h = 0.2 .. 0.025 is pre-asymptotic
    (pairwise slopes 2.63, 2.51, 2.35, measured): the reported order is the finest pair's, which
    differs from the coarsest by > 0.2."""
    import math
    r = discrete_balance("time-L", exact_method("euler-i"), hs=("0.2", "0.1", "0.05", "0.025"))
    e, h = r["mismatch"], r["h"]
    slopes = [math.log(e[i] / e[i + 1]) / math.log(h[i] / h[i + 1]) for i in range(3)]
    assert slopes[0] - slopes[-1] > 0.2, slopes
    assert r["order_mismatch"] == pytest.approx(slopes[-1], rel=1e-12)
