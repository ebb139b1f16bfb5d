"""Without constraints (m = 0) the SPARK method (21) has no multipliers: (21a-c) are the
partitioned Runge-Kutta method (A, A_hat) applied to the Euler-Lagrange equations, and under
(22a) it is symplectic. Checked on an anharmonic oscillator (n = 2, nonlinear, no closed form):
the orders 2s (Gauss) and 2s - 2 (Lobatto IIIA-B), two-sided; symplecticity of the step map
in (q, p) by central differences, with a (22a)-breaking tableau as the negative control; the
engines agree; psi has m = 0 columns."""
import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.families import get_method
from ldaspark.lab.theory.orders import estimate_order

q1, q2, v1, v2 = sympy.symbols("q1 q2 v1 v2")
R2 = q1 ** 2 + q2 ** 2
#: L = T - U with U = |q|^2 / 2 + |q|^4 / 4: p = v, a nonlinear force, no constraint
SYSTEM = ldaspark.LagrangianSystem((v1 ** 2 + v2 ** 2) / 2 - R2 / 2 - R2 ** 2 / 4, [], [q1, q2], [v1, v2],
                                   name="anharmonic")
Q0, V0, T_END = [0.8, 0.1], [0.0, 0.9], 1.0
HS = [1 / 4, 1 / 8, 1 / 16, 1 / 32]


@pytest.fixture(scope="module")
def reference():
    # gauss-5 (order 10) at h = 1/64 in 30 digits: error ~ (1/64)^10 ~ 1e-18, far below the
    # smallest error measured below (~1e-11: gauss-3 at h = 1/32)
    res = ldaspark.integrate(SYSTEM, "gauss-5", t_span=(0, T_END), h=1 / 64, q0=Q0, v0=V0, dps=30)
    return np.array([float(x) for x in res.q[-1]]), np.array([float(x) for x in res.v[-1]])


@pytest.mark.parametrize("method, order", [("gauss-1", 2), ("gauss-2", 4), ("gauss-3", 6),
                                           ("lobatto-iiia-iiib-2", 2), ("lobatto-iiia-iiib-3", 4),
                                           ("lobatto-iiia-iiib-4", 6)])
def test_orders_2s_and_2s_minus_2_without_constraints(reference, method, order):
    qr, vr = reference
    errs = {"q": [], "v": []}
    for h in HS:
        res = ldaspark.integrate(SYSTEM, method, t_span=(0, T_END), h=h, q0=Q0, v0=V0)
        assert res.status == 0 and res.constraint.shape == (len(res.t), 0)
        errs["q"].append(np.abs(res.q[-1] - qr).max())
        errs["v"].append(np.abs(res.v[-1] - vr).max())
    for var, e in errs.items():
        # floor: float64 round-off over 128 steps of O(1) values, 1e-13; the window excludes it
        est = estimate_order(HS, e, 1e-13)
        # two-sided: an order 0.3 above or below the claim fails (pre-asymptotic drift measured
        # here is < 0.15)
        assert est.observed_order is not None and abs(est.observed_order - order) <= 0.3, (var, est)


def _step_map_jacobian(tableau, x, h=0.3, d=1e-5):
    """The Jacobian of (q0, p0) -> (q1, p1) of one step (p = v here) by central differences
    at 30 digits, so that the difference error (~d^2 |x'''| ~ 1e-10) and not rounding limits it."""
    def step(z):
        r = ldaspark.integrate(SYSTEM, tableau, t_span=(0, h), h=h, q0=z[:2], v0=z[2:], dps=30)
        return np.array([float(c) for c in list(r.q[-1]) + list(r.v[-1])])
    J = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = d
        J[:, j] = (step(x + e) - step(x - e)) / (2 * d)
    return J


OMEGA = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])


def _symplecticity_defect(tableau):
    J = _step_map_jacobian(tableau, np.array(Q0 + V0))
    return np.abs(J.T @ OMEGA @ J - OMEGA).max()


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-3", "euler-i"])
def test_symplectic_under_22a(method):
    # central differences with d = 1e-5 at 30 digits: J is exact to ~1e-10, so the defect of a
    # symplectic map is ~1e-10; a tableau breaking (22a) by 1/10 at h = 0.3 gives ~1e-2
    assert _symplecticity_defect(get_method(method)) < 1e-8


def test_symplecticity_negative_control_breaks_22a():
    broken = get_method("gauss-2", exact=True).with_entry("A_hat", 0, 1, "1/10")
    assert _symplecticity_defect(broken) > 1e-4


def test_engines_agree_without_constraints():
    kw = dict(t_span=(0, 2), h=0.1, q0=Q0, v0=V0)
    gen = ldaspark.integrate(SYSTEM, "gauss-3", engine="generic", **kw)
    com = ldaspark.integrate(SYSTEM, "gauss-3", engine="compiled", **kw)
    assert com.engine == "compiled"
    # the engines solve the same equations to the Newton tolerance: 1e-13 after 20 steps
    assert np.abs(com.q - gen.q).max() < 1e-12 and np.abs(com.v - gen.v).max() < 1e-12
    assert gen.psi.shape == (20, 3, 0) and com.psi.shape == (20, 3, 0)
    mp = ldaspark.integrate(SYSTEM, "gauss-3", dps=30, **kw)
    assert max(abs(float(a) - b) for a, b in zip(mp.q[-1], gen.q[-1])) < 1e-12


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-3"])
def test_theorem1_without_constraints_is_a_type_I_generating_function(method):
    """Theorem 1 at m = 0: f_d^+- vanish (no multipliers), so dL_d/dq0 = -p0 and dL_d/dq1 = p1:
    the discrete Lagrangian (13) generates the step map (the discrete analogue of section 5's
    statement for L_d^E). Residuals at 40 digits, the finite differences at 60: 1e-30 leaves
    ~20 digits of room above the measured 3e-52 and fails the control's 7e-3."""
    r = ldaspark.theorem1_residuals(SYSTEM, get_method(method), 0, Q0, V0, "1/10")
    assert r["f_d_minus_norm"] == 0 and r["f_d_plus_norm"] == 0
    assert r["theorem1-q0"] < 1e-30 and r["theorem1-q1"] < 1e-30


def test_theorem1_without_constraints_negative_control():
    broken = get_method("gauss-2", exact=True).with_entry("A_hat", 0, 1, "1/10")      # breaks (22a)
    r = ldaspark.theorem1_residuals(SYSTEM, broken, 0, Q0, V0, "1/10")
    assert min(r["theorem1-q0"], r["theorem1-q1"]) > 1e-4


def test_block_solver_without_constraints():
    """At n = 40 the compiled engine factors by blocks (the Schur complement of the multipliers
    is empty at m = 0); same steps as the generic engine to the Newton tolerance."""
    n = 40
    q, v = sympy.symbols(f"q0:{n}"), sympy.symbols(f"v0:{n}")
    L = (sum(x ** 2 for x in v) / 2 - sum((q[i + 1] - q[i]) ** 2 for i in range(n - 1)) / 2
         - sum(x ** 4 for x in q) / 4)
    chain = ldaspark.LagrangianSystem(L, [], list(q), list(v), name="chain")
    kw = dict(t_span=(0, 0.5), h=0.1, q0=np.sin(np.arange(n)), v0=np.zeros(n))
    com = ldaspark.integrate(chain, "gauss-2", engine="compiled", **kw)
    gen = ldaspark.integrate(chain, "gauss-2", engine="generic", **kw)
    assert com.stats["linear_solver"] == "sparse"
    assert np.abs(com.q - gen.q).max() < 1e-12 and np.abs(com.v - gen.v).max() < 1e-12
