"""The exact flow of section 5 (``theory.exact_flow``) fed the terms its rules are about: on the
rheonomic system of ``verification.general_fixtures`` (L_vt != 0, L_qv != 0, k_t != 0, k
nonlinear in v), ExactFlow.rhs gives (a, psi) of (3a-b) as derived here independently from L
and k:  L_vv a + K^T psi = L_q - L_vq v - L_vt,  K a = -k_q v - k_t  (K = k_v). The check is
fed its failing value: (a, psi) without the L_vt term (or without k_t) differ from it by far
more than the tolerance, so an exact flow that dropped either term fails here."""
from __future__ import annotations

import mpmath
import sympy

from ldaspark.lab.theory.exact_flow import ExactFlow
from verification.general_fixtures import rheonomic_initial, rheonomic_system

DPS = 40


def _independent(system, t0, q0, v0, drop=None):
    t, q, v = system.t, list(system.q), list(system.v)
    L, k = system.L, sympy.Matrix(system.k)
    Lv = sympy.Matrix([L.diff(x) for x in v])
    Lvv, Lvq = Lv.jacobian(v), Lv.jacobian(q)
    Lvt = Lv.diff(t) if drop != "L_vt" else sympy.zeros(len(v), 1)
    Lq = sympy.Matrix([L.diff(x) for x in q])
    K, kq = k.jacobian(v), k.jacobian(q)
    kt = k.diff(t) if drop != "k_t" else sympy.zeros(k.rows, 1)
    vv = sympy.Matrix(v)
    n, m = len(q), k.rows
    S = sympy.zeros(n + m, n + m)
    S[:n, :n], S[:n, n:], S[n:, :n] = Lvv, K.T, K
    r = sympy.Matrix.vstack(Lq - Lvq * vv - Lvt, -kq * vv - kt)
    sub = {t: t0, **dict(zip(q, q0)), **dict(zip(v, v0))}
    with mpmath.workdps(DPS):
        Sm = mpmath.matrix([[mpmath.mpf(sympy.N(e.subs(sub), DPS + 10)) for e in S.row(i)] for i in range(n + m)])
        rm = mpmath.matrix([mpmath.mpf(sympy.N(e.subs(sub), DPS + 10)) for e in r])
        z = mpmath.lu_solve(Sm, rm)
        return [z[i] for i in range(n)], [z[n + i] for i in range(m)]


def test_exact_flow_rhs_has_the_L_vt_and_k_t_terms():
    system = rheonomic_system()
    t0, q0, v0 = rheonomic_initial(DPS)
    with mpmath.workdps(DPS):
        a, psi, _, _ = ExactFlow(system, dps=DPS, stages=2).rhs(t0, q0, v0, jacobian=False)
        a_ref, psi_ref = _independent(system, t0, q0, v0)
        tol = mpmath.mpf(10) ** (-DPS + 8)        # 40 digits, 8 lost to the solve and lambdify
        err = max(max(abs(x - y) for x, y in zip(a, a_ref)), max(abs(x - y) for x, y in zip(psi, psi_ref)))
        assert err <= tol, err
        for term in ("L_vt", "k_t"):              # the failing values: each term matters here
            a_bad, psi_bad = _independent(system, t0, q0, v0, drop=term)
            gap = max(max(abs(x - y) for x, y in zip(a, a_bad)), max(abs(x - y) for x, y in zip(psi, psi_bad)))
            assert gap > mpmath.mpf(10) ** -3, (term, gap)
