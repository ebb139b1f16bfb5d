"""Section 7 for L = v^T M v / 2 - U(q), k = K(q) v + b(q) (nonconstant K and b, M != I):

* 7.1 Euler I: one SPARK step equals the printed q1/v1/Psi_1 system (q1 = q0 + h v1,
  M v1 = M v0 - h (grad U(q0) + K(q0)^T Psi_1), 0 = K(q1) v1 + b(q1)) solved on its own, and V_1 = v_1;
* 7.2 Euler II: equals its printed system (q1 = q0 + h v0, grad U and K at q1), V_1 = v_0;
* 7.3 the 1-stage Gauss SPARK method equals the printed midpoint system, Q_1 = (q0 + q1)/2,
  V_1 = (v0 + v1)/2;
* linear implicitness: one Newton iteration on (21) lands on the solution (|G| <= 1e-35) for
  Euler I with K, b constant from a generic start, and for Euler II from the integrator's own
  start V_1 = v_0 even with K(q), b(q).
Controls: Euler I's step does not solve Euler II's printed system; Lobatto IIIA-B 2 (also
symmetric, order 2) does not solve the midpoint system; Euler I with K(q) and the midpoint
rule need more than one Newton iteration. All at 40 digits. Cost ~6 s."""
import pytest

from ldaspark.lab.theory.section7 import one_newton_iteration, reduction

TOL = 1e-35
NEG = 1e-6


@pytest.mark.parametrize("kind,name", [("euler-i", "euler-i"), ("euler-ii", "euler-ii"), ("midpoint", "gauss-1")])
def test_section7_printed_systems(kind, name, exact_method):
    r = reduction(kind, exact_method(name), constant_K=False)
    assert r["diff"] < TOL and r["printed_residual"] < TOL, r
    assert r["stage"] < TOL, r


@pytest.mark.parametrize("kind,name", [("euler-ii", "euler-i"), ("midpoint", "lobatto-iiia-iiib-2")])
def test_section7_printed_systems_control(kind, name, exact_method):
    r = reduction(kind, exact_method(name), constant_K=False)
    assert r["diff"] > NEG and r["printed_residual"] > NEG, r


def test_linearly_implicit_7(exact_method):
    # Euler I, K and b constant: the system is linear in (V_1, Psi_1, v_1) -> one iteration, any start
    r = one_newton_iteration(exact_method("euler-i"), constant_K=True, guess="generic")
    assert r["after_one"] < TOL and r["before"] > 1, r
    # Euler II: V_1 = v_0 is explicit, the rest linear -> one iteration from V_1 = v_0, even with K(q)
    r = one_newton_iteration(exact_method("euler-ii"), constant_K=False, guess="default")
    assert r["after_one"] < TOL, r
    # controls: Euler I with K(q), and the midpoint rule, are nonlinear
    assert one_newton_iteration(exact_method("euler-i"), constant_K=False, guess="generic")["after_one"] > NEG
    assert one_newton_iteration(exact_method("gauss-1"), constant_K=True, guess="default")["after_one"] > 1e-12
