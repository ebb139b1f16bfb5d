"""A constraint nonlinear in v: k = r - y u - (u^2 + w^2)/4, so K = k_v = (-y - u/2, -w/2, 1)
changes with the velocity. Theorem 1's forces use K_j = K(T_j, Q_j, V_j) at the stage
velocities; for k affine in v (every scene of the paper) K(q) does not see v at all, so a K taken
at the wrong velocity cannot be noticed there.

Checks: Theorem 1 (both identities <= 1e-20 at 40 digits) for a well-posed and a
gauge-deficient method, the symmetry under (23) of L_d and of the step, and k(t1, q1, v1) = 0
along a float64 run. Negative controls: without the forces the identity fails; a (22b)-breaking
tableau fails; the secant velocity violates k. Cost: ~6 s."""
import functools

import numpy as np
import pytest

from general_fixtures import nonlinear_constraint_system, nonlinear_initial, theorem1_tol
from ldaspark.core.families import get_method
from ldaspark.core.spark import integrate
from ldaspark.analysis.discrete import theorem1_residuals
from ldaspark.lab.claims.ledger import TOL_NEGATIVE, TOL_SYMMETRY, TOL_THEOREM1, negative_controls
from ldaspark.analysis.symmetry import check_symmetry

H = "0.1"


@functools.lru_cache(maxsize=None)
def _system():
    return nonlinear_constraint_system()


def _t1(tab, max_refine=4):
    t0, q0, v0 = nonlinear_initial(60)
    return theorem1_residuals(_system(), tab, t0, q0, v0, H, dps=40, max_refine=max_refine)


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-3"])
def test_theorem1_constraint_nonlinear_in_v(name):
    r = _t1(get_method(name, exact=True))
    assert r["fd_error"] < 1e-25, r
    assert r["theorem1-q0"] <= TOL_THEOREM1, r
    assert r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)
    assert r["without_forces_q0"] > 1e-6, r


def test_theorem1_nonlinear_negative_control():
    tab, _ = negative_controls()[0]
    r = _t1(tab, max_refine=0)                   # a failing identity needs no refined FD
    assert max(r["theorem1-q0"], r["theorem1-q1"]) >= TOL_NEGATIVE, r


def test_symmetry_23_constraint_nonlinear_in_v():
    t0, q0, v0 = nonlinear_initial(60)
    r = check_symmetry(_system(), get_method("gauss-2", exact=True), t0, q0, v0, H, dps=40)
    assert r["symmetry-Ld"] <= TOL_SYMMETRY and r["symmetry-Phi"] <= TOL_SYMMETRY, r
    assert r["symmetry-fd-plus"] <= TOL_SYMMETRY and r["symmetry-fd-minus"] <= TOL_SYMMETRY, r
    bad = check_symmetry(_system(), get_method("euler-i", exact=True), t0, q0, v0, H, dps=40)
    assert bad["symmetry-Phi"] > 1e-6                    # negative control: Euler I is not symmetric


def test_constraint_21f_along_a_run():
    t0, q0, v0 = nonlinear_initial(None)
    sol = integrate(_system(), get_method("gauss-3"), t0, q0, v0, 0.1, n_steps=10)
    assert np.abs(sol.constraint).max() < 1e-13
    sec = (sol.q[1:] - sol.q[:-1]) / 0.1
    ks = [abs(r - y * u - (u ** 2 + w ** 2) / 4) for (u, w, r), y in zip(sec, sol.q[1:, 1])]
    assert max(ks) > 1e-5                                # the secant velocity is not constrained
