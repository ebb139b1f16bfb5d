"""The SPARK equations (21a-f), checked by an independent implementation.

The library solves (21) through its own derived expressions (``LagrangianSystem`` Jacobians,
the packed residual of ``SparkMethod`` and ``DiscreteBVP``). Here (21a-f) are re-evaluated
directly from the printed equations with L and k differentiated by sympy in this file, at 30
digits, on the solutions the library returns: the IVP step and the boundary-value solve of
Theorem 1. The system has explicit time in L and k, gyroscopic terms, and a constraint nonlinear
in v with K(t, q, v); the tableau has c != b, A_hat != A_tilde, b_tilde != b_hat and an omega
that is not b_j c_j^(i-1), and a variant with b_hat != b (the IVP step only: (21) does not need
(22)), so every coefficient and every argument of (21) is visible.

Also: the Newton matrix and the boundary-value sensitivities dG/dx, dG/dq0, dG/dq1 against
central differences of the residual (a Jacobian error would only slow Newton down, but it
enters dV/dq and hence f_d^{+/-} of Theorem 1). Each check has a negative control.
Cost: ~6 s."""
import functools

import mpmath
import numpy as np
import pytest
import sympy

from general_fixtures import general_tableau, rheonomic_initial, rheonomic_system
from ldaspark.core.backend import Backend
from ldaspark.core.families import get_method
from ldaspark.core.spark import SparkMethod
from ldaspark.analysis.discrete import DiscreteBVP, base_point, discrete_lagrangian

DPS = 30
H = "0.1"
TOL = mpmath.mpf(10) ** -25


@functools.lru_cache(maxsize=None)
def _system():
    return rheonomic_system()


@functools.lru_cache(maxsize=None)
def _tableau(name):
    if name == "general-2-bhat":
        # b_hat != b (breaks (22a), not (21)): b_hat of (21d) and b of (21c) become distinguishable
        return general_tableau().with_entry("b_hat", 0, None, "1/10")
    return general_tableau() if name == "general-2" else get_method(name, exact=True)


@functools.lru_cache(maxsize=None)
def _independent(sysm):
    """grad_v L, grad_q L, k and k_v straight from the user's L and k (not the library's)."""
    args = [sysm.t] + list(sysm.q) + list(sysm.v)
    Lv = [sympy.diff(sysm.L, x) for x in sysm.v]
    Lq = [sympy.diff(sysm.L, x) for x in sysm.q]
    k = list(sysm.k)
    kv = [[sympy.diff(e, x) for x in sysm.v] for e in k]
    return {name: sympy.lambdify(args, e, modules="mpmath") for name, e in
            (("Lv", Lv), ("Lq", Lq), ("k", k), ("kv", kv))}


def residual_21(sysm, tab, t0, q0, v0, h, V, Psi, q1, v1, swap=False):
    """max |residual| of (21a-f) as printed, at the given stage values (mpf).
    ``swap`` exchanges A_hat and A_tilde (negative control)."""
    f = _independent(sysm)
    s, n, m = tab.s, sysm.n, sysm.m
    a = tab.arrays(DPS)
    Ah, At = (a.A_tilde, a.A_hat) if swap else (a.A_hat, a.A_tilde)
    ev = lambda name, t, q, v: np.array(f[name](t, *q, *v), dtype=object)
    T = [t0 + a.c[i] * h for i in range(s)]
    Q = [q0 + h * sum(a.A[i, j] * V[j] for j in range(s)) for i in range(s)]            # (21a)
    P = [ev("Lv", T[i], Q[i], V[i]) for i in range(s)]
    F = [ev("Lq", T[i], Q[i], V[i]) for i in range(s)]
    R = [-ev("kv", T[i], Q[i], V[i]).reshape(m, n).T.dot(Psi[i]) for i in range(s)]
    Kst = [ev("k", T[i], Q[i], V[i]) for i in range(s)]
    t1 = t0 + h
    p0, p1 = ev("Lv", t0, q0, v0), ev("Lv", t1, q1, v1)
    res = []
    for i in range(s):                                                                  # (21b)
        res += list(P[i] - p0 - h * sum(Ah[i, j] * F[j] for j in range(s))
                    - h * sum(At[i, j] * R[j] for j in range(s)))
    res += list(q1 - q0 - h * sum(a.b[j] * V[j] for j in range(s)))                     # (21c)
    res += list(p1 - p0 - h * sum(a.b_hat[j] * F[j] for j in range(s))
                - h * sum(a.b_tilde[j] * R[j] for j in range(s)))                       # (21d)
    for i in range(s - 1):                                                              # (21e)
        res += list(sum(a.omega[i, j] * Kst[j] for j in range(s)))
    res += list(ev("k", t1, q1, v1))                                                    # (21f)
    return max(abs(x) for x in res)


def _ivp(name):
    sysm, tab = _system(), _tableau(name)
    bk = Backend(DPS)
    t0, q0, v0 = rheonomic_initial(DPS)
    with bk.context():
        t0, q0, v0, h = bk.scalar(t0), bk.array(q0), bk.array(v0), bk.scalar(H)
        r = SparkMethod(sysm, tab, dps=DPS).step(t0, q0, v0, h)
    return sysm, tab, bk, t0, q0, v0, h, r


@pytest.mark.parametrize("name", ["general-2", "general-2-bhat", "gauss-3", "lobatto-iiia-iiib-iiid-3"])
def test_ivp_step_solves_21_as_printed(name):
    sysm, tab, bk, t0, q0, v0, h, r = _ivp(name)
    with bk.context():
        assert residual_21(sysm, tab, t0, q0, v0, h, r.V, r.Psi, r.q1, r.v1) <= TOL
        # negative control: the same check with A_hat and A_tilde exchanged sees the difference
        if name != "gauss-3":
            assert residual_21(sysm, tab, t0, q0, v0, h, r.V, r.Psi, r.q1, r.v1, swap=True) > 1e-6


@pytest.mark.parametrize("name", ["general-2", "general-2-bhat"])
def test_boundary_value_solve_solves_21_as_printed(name):
    """Theorem 1's implicit functions of (t0, q0, t1, q1): the BVP solution, with q1 moved off
    the IVP endpoint (v0 is then an output), satisfies (21a-f) with p0 = grad_v L(t0, q0, v0)."""
    sysm, tab = _system(), _tableau(name)
    bk = Backend(DPS)
    t0, q0, v0 = rheonomic_initial(DPS)
    with bk.context():
        t1, q1, xg = base_point(sysm, tab, t0, q0, v0, H, DPS)
        q1 = q1 + bk.array(["1e-3", "-2e-3", "1e-3"])
        res = discrete_lagrangian(sysm, tab, bk.scalar(t0), bk.array(q0), t1, q1, dps=DPS, x_guess=xg)
        assert res.wellposed == "well-posed"
        h = t1 - bk.scalar(t0)
        assert residual_21(sysm, tab, bk.scalar(t0), bk.array(q0), res.v0, h, res.V, res.Psi, q1, res.v1) <= TOL
        # negative control: the IVP's v0 is not the BVP's once q1 is moved
        assert residual_21(sysm, tab, bk.scalar(t0), bk.array(q0), bk.array(v0), h, res.V, res.Psi, q1,
                           res.v1) > 1e-6


@pytest.mark.parametrize("name", ["general-2", "lobatto-iiia-iiib-iiid-3"])
def test_discrete_lagrangian_13_as_printed(name):
    """The L_d that ``discrete_lagrangian`` returns (the value reported by symmetry-Ld, the
    variational order and the ledger; Theorem 1's finite differences use another function) is
    (13) as printed: h sum b_i L(t0 + c_i h, q0 + h sum_j a_ij V_j, V_i), with L from sympy here.
    The system has L_t != 0 at t0 = 3/10, so a time argument is visible (the paper's scenes and
    the rheonomic skate at t0 = 0, where L_t = 0, hide it). Control: L at t0 misses by > 1e-6."""
    sysm, tab = _system(), _tableau(name)
    bk = Backend(DPS)
    t0, q0, v0 = rheonomic_initial(DPS)
    Lfn = sympy.lambdify([sysm.t] + list(sysm.q) + list(sysm.v), sysm.L, modules="mpmath")
    with bk.context():
        t1, q1, xg = base_point(sysm, tab, t0, q0, v0, H, DPS)
        t0, q0 = bk.scalar(t0), bk.array(q0)
        res = discrete_lagrangian(sysm, tab, t0, q0, t1, q1, dps=DPS, x_guess=xg)
        a, h, s = tab.arrays(DPS), t1 - t0, tab.s
        Q = [q0 + h * sum(a.A[i, j] * res.V[j] for j in range(s)) for i in range(s)]
        L_d = lambda time: h * sum(a.b[i] * Lfn(time(i), *Q[i], *res.V[i]) for i in range(s))
        printed = L_d(lambda i: t0 + a.c[i] * h)
        assert abs(res.L_d - printed) <= TOL * max(abs(printed), 1), (res.L_d, printed)
        assert abs(res.L_d - L_d(lambda i: t0)) > 1e-6                 # negative control


@pytest.mark.parametrize("name", ["euler-i", "euler-ii"])
def test_section7_euler_methods_as_printed_for_general_L(name):
    """7.1, 7.2 for a general L(t, q, v), k(t, q, v) (the rheonomic system here): Euler I is
    q1 = q0 + h V1, P1 = p0 + h (F1 + R1), p1 = P1, 0 = k(t1, q1, v1) with P1, F1, R1 at
    (t0, q0, V1); Euler II is q1 = q0 + h V1, P1 = p0, p1 = p0 + h (F1 + R1), 0 = k(t1, q1, v1)
    with P1, F1, R1 at (t1, q1, V1). The time argument is visible only here (test_section7's
    systems are autonomous): a node c of Euler I / II moved to the other end passes every other
    check (planted). Control: the other end's time misses by > 1e-6."""
    sysm, tab, bk, t0, q0, v0, h, r = _ivp(name)
    f = _independent(sysm)
    n, m = sysm.n, sysm.m
    ev = lambda nm, t, q, v: np.array(f[nm](t, *q, *v), dtype=object)
    V1, Psi1 = r.V[0], r.Psi[0]

    def residual(tq):
        tt, qq = tq
        P1, F1 = ev("Lv", tt, qq, V1), ev("Lq", tt, qq, V1)
        R1 = -ev("kv", tt, qq, V1).reshape(m, n).T.dot(Psi1)
        res = list(r.q1 - q0 - h * V1) + list(ev("k", t1, r.q1, r.v1))
        if name == "euler-i":
            res += list(P1 - p0 - h * (F1 + R1)) + list(p1 - P1)
        else:
            res += list(P1 - p0) + list(p1 - p0 - h * (F1 + R1))
        return max(abs(x) for x in res)

    with bk.context():                                  # DPS digits for every operation
        t1 = t0 + h
        p0, p1 = ev("Lv", t0, q0, v0), ev("Lv", t1, r.q1, r.v1)
        own, other = ((t0, q0), (t1, q0)) if name == "euler-i" else ((t1, r.q1), (t0, r.q1))
        assert residual(own) <= TOL
        assert residual(other) > 1e-6                               # negative control


def _fd_columns(fun, x, delta):
    cols = []
    for k in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[k] += delta
        xm[k] -= delta
        cols.append((fun(xp) - fun(xm)) / (2 * delta))
    return np.array(cols, dtype=object).T


def _rel(a, b):
    d = max(abs(x) for x in (np.asarray(a) - np.asarray(b)).reshape(-1))
    return d / max(max(abs(x) for x in np.asarray(b).reshape(-1)), 1)


@pytest.mark.parametrize("name", ["general-2", "gauss-2"])
def test_newton_matrix_is_the_derivative_of_21(name):
    sysm, tab, bk, t0, q0, v0, h, r = _ivp(name)
    meth = SparkMethod(sysm, tab, dps=DPS)
    with bk.context():
        p0 = sysm.momentum(bk, t0, q0, v0)
        x = r.x + bk.array(["1e-2"] * len(r.x))        # off the solution: every block is exercised
        _, J, _ = meth.residual(t0, q0, p0, h, x)
        fd = _fd_columns(lambda y: meth.residual(t0, q0, p0, h, y, jacobian=False)[0], x, mpmath.mpf("1e-10"))
        assert _rel(J, fd) < 1e-15
        # negative control: dropping the h b_k k_q(t1, q1, v1) block of the (21f) row is visible
        Jbad = J.copy()
        Jbad[-sysm.m:, :tab.s * sysm.n] = 0
        assert _rel(Jbad, fd) > 1e-4


@pytest.mark.parametrize("name", ["general-2", "general-2-bhat"])
def test_boundary_value_sensitivities_are_derivatives(name):
    """dG/dx, dG/dq0 and dG/dq1 of the BVP residual (they give dV/dq in f_d^{+/-}); b_hat != b
    too, so that b_hat's rows of dG/dq0 are seen."""
    sysm, tab = _system(), _tableau(name)
    bk = Backend(DPS)
    t0, q0, v0 = rheonomic_initial(DPS)
    bvp = DiscreteBVP(sysm, tab, DPS)
    d = mpmath.mpf("1e-10")
    with bk.context():
        t1, q1, xg = base_point(sysm, tab, t0, q0, v0, H, DPS)
        t0, q0 = bk.scalar(t0), bk.array(q0)
        x = xg + bk.array(["1e-2"] * len(xg))
        _, J, dq0, dq1 = bvp.evaluate(t0, q0, t1, q1, x)
        G = lambda y: bvp.evaluate(t0, q0, t1, q1, y, jacobian=False)[0]
        assert _rel(J, _fd_columns(G, x, d)) < 1e-15
        fd0 = _fd_columns(lambda qa: bvp.evaluate(t0, qa, t1, q1, x, jacobian=False)[0], q0, d)
        fd1 = _fd_columns(lambda qb: bvp.evaluate(t0, q0, t1, qb, x, jacobian=False)[0], q1, d)
        assert _rel(dq0, fd0) < 1e-15 and _rel(dq1, fd1) < 1e-15
        bad = dq0.copy()
        bad[bvp.r_f:bvp.r_c] = 0                       # negative control: (21f) row of dG/dq0
        assert _rel(bad, fd0) > 1e-4
