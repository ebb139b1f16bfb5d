"""Time dependence: Theorem 1, the underlying ODE (3a-b), the energy (8) and the order of
convergence on a system with explicit t in L (L_t != 0, grad^2_tv L != 0) and a rheonomic
constraint nonlinear in v (k_t != 0, K = k_v depending on t).

The paper's scenes are autonomous, so a wrong time argument (T_i = t0 + c_i h, t1 = t0 + h,
p0 at t0) or a dropped time derivative is invisible on them. Theorem 1 is stated for any
L(t, q, v), k(t, q, v): here both identities must hold to 1e-20 at 40 digits.
Cost: ~12 s."""
import functools

import mpmath
import numpy as np
import pytest
import sympy

from general_fixtures import general_tableau, rheonomic_initial, rheonomic_system, theorem1_tol
from ldaspark.core.backend import Backend
from ldaspark.core.families import get_method
from ldaspark.core.spark import integrate
from ldaspark.analysis.discrete import theorem1_residuals
from ldaspark.lab.claims.ledger import TOL_NEGATIVE, TOL_THEOREM1, negative_controls
from ldaspark.lab.theory.orders import ODEReference, estimate_order, floor_for

H = "0.1"


@functools.lru_cache(maxsize=None)
def _system():
    return rheonomic_system()


def _t1(tab, max_refine=4):
    t0, q0, v0 = rheonomic_initial(60)
    return theorem1_residuals(_system(), tab, t0, q0, v0, H, dps=40, max_refine=max_refine)


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-iiid-2", "general-2"])
def test_theorem1_time_dependent_L_and_rheonomic_k(name):
    tab = general_tableau() if name == "general-2" else get_method(name, exact=True)
    r = _t1(tab)
    assert r["fd_error"] < 1e-25, r
    assert r["theorem1-q0"] <= TOL_THEOREM1, r
    assert r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)
    assert r["without_forces_q0"] > 1e-6, r       # the forces f_d^{+/-} matter here


def test_theorem1_time_dependent_negative_control():
    tab, _ = negative_controls()[0]               # (22b) broken
    r = _t1(tab, max_refine=0)                   # a failing identity needs no refined FD
    assert max(r["theorem1-q0"], r["theorem1-q1"]) >= TOL_NEGATIVE, r


@functools.lru_cache(maxsize=None)
def _ode_parts():
    """(3a-b) and (8) derived here from L and k with sympy."""
    s = _system()
    t, q, v = s.t, list(s.q), list(s.v)
    L, k = s.L, sympy.Matrix(s.k)
    Lv = sympy.Matrix([sympy.diff(L, x) for x in v])
    a = sympy.symbols("a0:3")
    psi = sympy.symbols("psi0")
    K = k.jacobian(v)
    # (3a): L_vv a + K^T psi + L_tv + L_qv v - L_q, (3b): K a + k_t + k_q v
    r3a = Lv.jacobian(v) * sympy.Matrix(a) + K.T * sympy.Matrix([psi]) + Lv.diff(t) \
        + Lv.jacobian(q) * sympy.Matrix(v) - sympy.Matrix([sympy.diff(L, x) for x in q])
    r3b = K * sympy.Matrix(a) + k.diff(t) + k.jacobian(q) * sympy.Matrix(v)
    r3b_no_kt = K * sympy.Matrix(a) + k.jacobian(q) * sympy.Matrix(v)
    E = (Lv.T * sympy.Matrix(v))[0, 0] - L                                          # (8)
    args = [t] + q + v + list(a) + [psi]
    f = lambda e: sympy.lambdify(args, e, modules="mpmath")
    # energy balance along (1): dE/dt = -L_t - psi^T K v
    balance = lambda EE: (sympy.diff(EE, t) + sum(sympy.diff(EE, x) * y for x, y in zip(q, v))
                          + sum(sympy.diff(EE, x) * y for x, y in zip(v, a))
                          + sympy.diff(L, t) + psi * (K * sympy.Matrix(v))[0, 0])
    return {"3a": f(list(r3a)), "3b": f(list(r3b)), "3b_no_kt": f(list(r3b_no_kt)),
            "balance_lib": f(balance(s.energy_expr)), "balance_indep": f(balance(E)),
            "E_diff": sympy.simplify(s.energy_expr - E)}


def test_underlying_ode_3ab_with_time_derivatives():
    """ode_rhs solves (3a-b) including -grad^2_tv L and -k_t; the energy (8) obeys
    dE/dt = -L_t - psi^T K v along it (Lagrange-d'Alembert energy balance)."""
    s = _system()
    bk = Backend(40)
    p = _ode_parts()
    t0, q0, v0 = rheonomic_initial(40)
    with bk.context():
        a, psi = s.ode_rhs(bk, t0, bk.array(q0), bk.array(v0))
        args = [t0, *q0, *v0, *a, psi[0]]
        assert max(abs(x) for x in p["3a"](*args)) < 1e-35
        assert max(abs(x) for x in p["3b"](*args)) < 1e-35
        assert abs(p["balance_indep"](*args)) < 1e-35
        assert abs(p["balance_lib"](*args)) < 1e-35          # the library's energy expression
        # negative control: without k_t the constraint's time derivative is not matched
        assert max(abs(x) for x in p["3b_no_kt"](*args)) > 1e-3
    assert p["E_diff"] == 0


def test_order_2s_against_the_ode_reference():
    """Gauss s = 2 converges with order 4 in q and v to the Taylor solution of (3a-b) on the
    rheonomic system (stage times, t1 and every time derivative enter)."""
    s = _system()
    t0, q0, v0 = rheonomic_initial(20)
    ref = ODEReference(s, t0, q0, v0, dps=20)
    span = 0.4
    qr, vr, _ = ref(t0 + mpmath.mpf(span))
    tab = get_method("gauss-2")
    f0, fq, fv = rheonomic_initial(None)
    hs, eq, ev = [], [], []
    for N in (2, 4, 8):
        sol = integrate(s, tab, f0, fq, fv, span / N, n_steps=N)
        hs.append(span / N)
        eq.append(float(max(abs(float(x) - y) for x, y in zip(qr, sol.q[-1]))))
        ev.append(float(max(abs(float(x) - y) for x, y in zip(vr, sol.v[-1]))))
        assert np.abs(sol.constraint).max() < 1e-13
    for errs in (eq, ev):
        est = estimate_order(hs, errs, floor_for(None, 1.0))
        assert est.observed_order is not None and abs(est.observed_order - 4) < 0.3, errs


@pytest.mark.parametrize("engine", ["integrate", "solve"])
def test_reported_energy_8_and_k_at_the_step_times(engine):
    """The energy (8) and k that a run reports at (t_n, q_n, v_n) are E(t_n, q_n, v_n) and
    k(t_n, q_n, v_n), with E = L_v v - L and k from sympy here: on this system E depends on t
    (through -(1 + t/5)(x^2 + y^2)/2), so a time argument other than t_n is visible. Both entry
    points (``integrate`` of core.spark and ``ldaspark.integrate``) are checked. Tolerance:
    float64 evaluations of the same expressions, 1e3 eps relative to max(1, |E|).
    Control: E at t0 instead of t_n misses by > 1e-3."""
    s = _system()
    t, q, v = s.t, list(s.q), list(s.v)
    E = sum(sympy.diff(s.L, x) * x for x in v) - s.L
    Ef = sympy.lambdify([t] + q + v, E, modules="math")
    kf = sympy.lambdify([t] + q + v, s.k[0], modules="math")
    f0, fq, fv = rheonomic_initial(None)
    if engine == "integrate":
        sol = integrate(s, get_method("gauss-2"), f0, fq, fv, 0.1, n_steps=6)
        ts, qs, vs, Es, ks = sol.t, sol.q, sol.v, sol.energy, sol.constraint
    else:
        import ldaspark
        res = ldaspark.integrate(s, "gauss-2", t0=f0, q0=fq, v0=fv, h=0.1, n_steps=6, engine="generic")
        ts, qs, vs, Es, ks = res.t, res.q, res.v, res.energy, res.constraint
    eps = np.finfo(float).eps
    for i in range(len(ts)):
        e_ind = Ef(float(ts[i]), *map(float, qs[i]), *map(float, vs[i]))
        assert abs(float(Es[i]) - e_ind) <= 1e3 * eps * max(1.0, abs(e_ind)), (i, Es[i], e_ind)
        k_ind = kf(float(ts[i]), *map(float, qs[i]), *map(float, vs[i]))
        assert abs(float(np.ravel(ks[i])[0]) - k_ind) <= 1e3 * eps, (i, ks[i], k_ind)
    last = Ef(float(ts[0]), *map(float, qs[-1]), *map(float, vs[-1]))
    assert abs(float(Es[-1]) - last) > 1e-3                       # negative control
