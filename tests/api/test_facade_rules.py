"""Rules of ``ldaspark`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
from fractions import Fraction
import mpmath
import numpy as np
import pytest
import sympy
import ldaspark
from verification import general_fixtures as GF
from verification import strategies as ST
from verification import systems_checks as SC
from ldaspark import LdasparkError
from ldaspark.core.errors import InputError
import os
import subprocess
import sys
from ldaspark.core.errors import InputError, SystemDefinitionError
from system_fakes import _documented_defaults, _one_line, _run, collect, fake_system  # noqa: F401 (pytest fixtures)


EPS = 2.0 ** -52


Q = sympy.Rational


def _den_ok(x, den):
    return sympy.Rational(x).q <= den


def _at0(e, syms):
    return e.subs({s: 0 for s in syms})


def lagrangian_parts(S):
    """The coefficients of the documented form of L read off by derivatives at 0 (module docstring
    of strategies.py), and L rebuilt from them."""
    q, v, t = S.q, S.v, S.t
    n = len(q)
    allv = list(q) + list(v) + [t]
    L = S.L
    beta = 8 * _at0(sympy.diff(L, v[0], 3), allv)
    alpha = _at0(sympy.diff(L, v[-1], 4), allv) / 6
    H = sympy.Matrix(n, n, lambda i, j: _at0(sympy.diff(L, v[i], v[j]), allv))
    M = H.copy()
    M[0, 0] -= beta / 4
    G = sympy.Matrix(n, n, lambda i, j: sympy.diff(L, q[i], v[j]).subs({x: 0 for x in list(q) + list(v)}).subs(t, sympy.pi / 2))
    T = sympy.Matrix(n, n, lambda i, j: _at0(sympy.diff(L, q[i], v[j]), allv)) - G
    sigma = _at0(sympy.diff(L, t, q[0], q[0]), allv)
    w = [-_at0(sympy.diff(L, q[i], 2), allv) for i in range(n)]
    c3 = -_at0(sympy.diff(L, q[0], 3), allv) / 2
    vv = sympy.Matrix(v)
    Lr = ((vv.T * M * vv)[0, 0] / 2 + alpha * sum(x ** 2 for x in v) ** 2 / 4 + beta * sympy.exp(v[0] / 2)
          + sum(G[i, j] * q[i] * v[j] for i in range(n) for j in range(n))
          + sympy.cos(t) * sum(T[i, j] * q[i] * v[j] for i in range(n) for j in range(n))
          + sigma * t * q[0] ** 2 / 2 - (sum(w[i] * q[i] ** 2 for i in range(n)) / 2 + c3 * q[0] ** 3 / 3))
    return dict(alpha=alpha, beta=beta, M=M, G=G, T=T, sigma=sigma, w=w, c3=c3, rebuilt=Lr)


def constraint_parts(S, r):
    q, v, t = S.q, S.v, S.t
    n = len(q)
    k = S.k[r]
    allv = list(q) + list(v) + [t]
    b = k.subs({x: 0 for x in v})
    rho = _at0(b, allv)
    beta_r = _at0(sympy.diff(b, t), allv)
    hs = [i for i in range(n) if _at0(sympy.diff(b, q[i]), allv) != 0]
    lin = [_at0(sympy.diff(k, v[j]), allv) for j in range(n)]
    Kq = sympy.Matrix(n, n, lambda i, j: _at0(sympy.diff(k, q[i], v[j]), allv))
    nu = [_at0(sympy.diff(k, v[j], 2), allv) / 2 for j in range(n)]
    piv = [j for j in range(n) if lin[j] != 0]
    rebuilt = (sum(lin[j] * v[j] for j in range(n)) + sum(Kq[i, j] * q[i] * v[j] for i in range(n) for j in range(n))
               + sum(nu[j] * v[j] ** 2 for j in range(n))
               + (beta_r * sympy.sin(t + q[hs[0]]) if len(hs) == 1 else sympy.nan) + rho)
    return dict(rho=rho, beta_r=beta_r, hs=hs, lin=lin, Kq=Kq, nu=nu, piv=piv, rebuilt=rebuilt)


def _check_general_case(case, n_range, m_max):
    S = case.system
    n, m = S.n, S.m
    assert n_range[0] <= n <= n_range[1] and len(S.v) == n
    assert 1 <= m <= min(m_max, n - 1), (n, m)
    assert S.name == f"random-n{n}-m{m}" and str(S.t) == "t"
    P = lagrangian_parts(S)
    assert sympy.expand(S.L - P["rebuilt"]) == 0, (S.L, P["rebuilt"])
    M = P["M"]
    assert M == M.T
    for i in range(n):
        assert 1 <= M[i, i] <= 2 and _den_ok(M[i, i] - 1, 4), M
    off = [(i, j) for i in range(n) for j in range(n) if i != j and M[i, j] != 0]
    assert len(off) in (0, 2), M
    assert all(abs(M[i, j]) <= Q(1, 5) and _den_ok(M[i, j], 10) for i, j in off), M
    assert Q(1, 20) <= P["alpha"] <= Q(1, 5) and Q(1, 20) <= P["beta"] <= Q(1, 5), P
    assert _den_ok(P["alpha"], 20) and _den_ok(P["beta"], 20)
    g = [P["G"][i, j] for i in range(n) for j in range(n) if P["G"][i, j] != 0]
    assert len(g) <= 1 and all(abs(x) <= Q(1, 2) and _den_ok(x, 20) for x in g), P["G"]
    tt = [P["T"][i, j] for i in range(n) for j in range(n) if P["T"][i, j] != 0]
    assert len(tt) == 1 and Q(1, 10) <= tt[0] <= Q(1, 2) and _den_ok(tt[0], 20), P["T"]
    assert Q(1, 10) <= P["sigma"] <= Q(1, 2) and _den_ok(P["sigma"], 20)
    assert all(1 <= x <= 2 and _den_ok(x - 1, 4) for x in P["w"]), P["w"]
    assert abs(P["c3"]) <= Q(1, 5) and _den_ok(P["c3"], 20)
    pivots = []
    for r in range(m):
        K = constraint_parts(S, r)
        assert sympy.expand(S.k[r] - K["rebuilt"]) == 0, (S.k[r], K["rebuilt"])
        assert len(K["piv"]) == 1 and K["lin"][K["piv"][0]] == 1, K["lin"]
        pivots.append(K["piv"][0])
        kq = [x for x in K["Kq"] if x != 0]
        assert len(kq) <= 1 and all(abs(x) <= Q(1, 2) and _den_ok(x, 20) for x in kq)
        nus = [x for x in K["nu"] if x != 0]
        assert len(nus) == 1 and Q(1, 20) <= nus[0] <= Q(1, 2) and _den_ok(nus[0], 20), K["nu"]
        assert Q(1, 20) <= K["beta_r"] <= Q(1, 2) and _den_ok(K["beta_r"], 20)
        assert abs(K["rho"]) <= Q(1, 5) and _den_ok(K["rho"], 20)
    assert len(set(pivots)) == m, pivots
    assert case.dps == 60
    with mpmath.workdps(case.dps):
        for x, lo, hi in [(case.t0, 0, 0.5)] + [(y, -0.5, 0.5) for y in case.q0]:
            assert isinstance(x, mpmath.mpf) and lo <= x <= hi
            # a rational with denominator <= 10: an integer multiple of 1/2520
            assert abs(x * 2520 - mpmath.nint(x * 2520)) < mpmath.mpf(10) ** (-case.dps + 5), x
    assert case.description.startswith(f"n={n}, m={m}, L={S.L}, k=")
    assert repr(case) == f"GeneralCase({case.description})"
    return n, m, P, pivots




def _lowest_case(monkeypatch, **kw):
    return _run(monkeypatch, ST.general_systems(**kw), "low")


class _Osc:
    """A fake system: dv/dt = sa * q, psi = exact psi + dpsi, k = v - exact v + dk."""

    def __init__(self, sa=-1, dpsi=(0, 0), dk=(0, 0)):
        self.sa, self.dpsi, self.dk = sa, dpsi, dk

    def ode_rhs(self, bk, t, q, v):
        assert mpmath.mp.dps == 30
        return self.sa * q, np.array([mpmath.cos(t) + self.dpsi[0], mpmath.sin(t) + self.dpsi[1]], dtype=object)

    def constraint(self, bk, t, q, v):
        return np.array([v[0] - mpmath.cos(t) + self.dk[0], v[1] + mpmath.sin(t) + self.dk[1]], dtype=object)


class _OscScene:
    """q = (sin t, cos t), psi = (cos t, sin t): a solution of the _Osc system with sa = -1."""

    def __init__(self):
        self.system, self.calls = _Osc(), []

    def exact_solution(self, t, dps=None):
        self.calls.append((t, dps, mpmath.mp.dps))
        q = np.array([mpmath.sin(t), mpmath.cos(t)], dtype=object)
        v = np.array([mpmath.cos(t), -mpmath.sin(t)], dtype=object)
        return q, v, np.array([mpmath.cos(t), mpmath.sin(t)], dtype=object)


def _res(q, v, **kw):
    return type("Res", (), dict(q=np.asarray(q, float), v=np.asarray(v, float), **kw))()


class _ODE:
    """A fake float system for rk4_constraint_drift: (a, k) given as functions."""

    def __init__(self, n, acc, kf):
        self.n, self.acc, self.kf = n, acc, kf

    def ode_rhs(self, bk, t, q, v):
        assert len(q) == len(v) == self.n
        return np.asarray(self.acc(t, q, v), float), None

    def constraint(self, bk, t, q, v):
        assert len(q) == len(v) == self.n
        return np.asarray(self.kf(t, q, v), float)


def _scene(system, t0, q0, v0):
    return type("Sc", (), {"system": system, "initial": lambda self: (t0, q0, v0)})()


class _InvScene:
    def __init__(self, x):
        self.x = x

    def invariant_values(self, t, q, v):
        return {"E": np.asarray(self.x, float)}


def _fake_run(monkeypatch, n=16):
    log = []

    def fake_integrate(scene, method, t_span, h, q0=None, v0=None, engine=None):
        log.append((scene, method, tuple(t_span), h, q0, v0, engine))
        t = np.linspace(t_span[0], t_span[1], n)
        return type("Res", (), dict(t=t, q=np.zeros((n, 1)), v=np.zeros((n, 1))))()
    monkeypatch.setattr(ldaspark, "integrate", fake_integrate)
    return log


def _kval(f, t, q, v):
    return f(t, *q, *v)


# =================================================================================================
# strategies.py: small, _R, GeneralCase
# =================================================================================================
def test_small_is_a_bounded_fraction_strategy_with_the_given_denominator():
    assert repr(ST.small()) == ("fractions(min_value=Fraction(-1, 5), max_value=Fraction(1, 5), "
                               "max_denominator=20)")
    for x in collect(ST.small("0", "1", 4), 25):
        assert isinstance(x, Fraction) and 0 <= x <= 1 and x.denominator <= 4, x
    assert ST._R(Fraction(-3, 7)) == Q(-3, 7)


def test_general_systems_draws_the_documented_form_in_the_documented_ranges(fake_system):
    """Every drawn system has the documented L and k (rebuilt from coefficients read off by
    derivatives, equal as expressions) with each coefficient in its range; the default draws
    cover n = 2 and 3, m = 1 and 2, an off-diagonal mass entry, a gyroscopic term and a
    non-identity pivot choice."""
    cases = collect(ST.general_systems(), 9)
    seen, offdiag, gyro = set(), False, False
    for c in cases:
        n, m, P, piv = _check_general_case(c, (2, 3), 2)
        seen.add((n, m))
        offdiag |= any(P["M"][i, j] != 0 for i in range(n) for j in range(n) if i != j)
        gyro |= any(x != 0 for x in P["G"])
        with mpmath.workdps(60):   # unprojected by the fake: v0 is the drawn point
            assert all(-0.5 <= x <= 0.5 and abs(x * 2520 - mpmath.nint(x * 2520)) < 1e-50 for x in c.v0)
    assert {(2, 1), (3, 1), (3, 2)} <= seen, seen
    assert offdiag and gyro


def test_general_systems_bounds_m_by_m_max_and_n_minus_1(fake_system):
    """n = 4: m stays <= m_max = 2 (not n - 1 = 3) and reaches 2; n = 2: m = 1 only; m_max = 3
    with n = 4 reaches 3; the base point is at the requested dps."""
    c4 = collect(ST.general_systems(n_range=(4, 4)), 8)
    ms4 = {c.system.m for c in c4}
    assert all(c.system.n == 4 and len(c.q0) == 4 for c in c4)
    assert ms4 == {1, 2}, ms4
    ms2 = {_check_general_case(c, (2, 2), 2)[1] for c in collect(ST.general_systems(n_range=(2, 2)), 4)}
    assert ms2 == {1}
    ms43 = {c.system.m for c in collect(ST.general_systems(n_range=(4, 4), m_max=3, dps=20), 10)}
    assert 3 in ms43 and max(ms43) == 3, ms43
    c = collect(ST.general_systems(n_range=(2, 2), dps=20), 1)[0]
    assert c.dps == 20 and mpmath.mpf(c.t0).context.dps >= 15


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
def test_general_systems_lowest_draw_is_the_documented_lower_corner(fake_system, monkeypatch):
    """Every draw at its lower end: n = 2, m = 1, M = I, alpha = beta = 1/20, gamma = -1/2 on
    q1 v1, tau = sigma = 1/10, w = 1, U's cubic -1/5, k = v1 - q1 v1 / 2 + v1^2 / 20
    + sin(t + q1) / 20 - 1/5; base point t0 = 0, q0 = v0 = -1/2."""
    c = _lowest_case(monkeypatch)
    S = c.system
    q1, q2 = S.q
    v1, v2 = S.v
    t = S.t
    L = ((v1 ** 2 + v2 ** 2) / 2 + (v1 ** 2 + v2 ** 2) ** 2 / 80 + sympy.exp(v1 / 2) / 20 - q1 * v1 / 2
         + sympy.cos(t) * q1 * v1 / 10 + t * q1 ** 2 / 20 - ((q1 ** 2 + q2 ** 2) / 2 - q1 ** 3 / 15))
    assert sympy.expand(S.L - L) == 0, S.L
    k = v1 - q1 * v1 / 2 + v1 ** 2 / 20 + sympy.sin(t + q1) / 20 - Q(1, 5)
    assert S.m == 1 and sympy.expand(S.k[0] - k) == 0, S.k
    with mpmath.workdps(60):
        assert c.t0 == 0 and list(c.q0) == [-0.5, -0.5] and list(c.v0) == [-0.5, -0.5]
    c = _lowest_case(monkeypatch, n_range=(4, 4), m_max=3, dps=20)
    assert (c.system.n, c.system.m, c.dps) == (4, 1, 20)


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
def test_general_systems_highest_draw_is_the_documented_upper_corner(fake_system, monkeypatch):
    """Every draw at its upper end (permutations reversed): n = 3, m = 2, M = 2 I, alpha = beta
    = 1/5, gamma = tau = sigma = 1/2 on q3 v3, w = 2, cubic 1/5; k_r = v_{3-r} + q3 v3 / 2
    + v3^2 / 2 + sin(t + q3) / 2 + 1/5 with pivots v3, v2; base point t0 = 1/2, q0 = v0 = 1/2."""
    c = _run(monkeypatch, ST.general_systems(), "high")
    S = c.system
    q1, q2, q3 = S.q
    v1, v2, v3 = S.v
    t = S.t
    V2 = v1 ** 2 + v2 ** 2 + v3 ** 2
    L = (V2 + V2 ** 2 / 20 + sympy.exp(v1 / 2) / 5 + q3 * v3 / 2 + sympy.cos(t) * q3 * v3 / 2 + t * q1 ** 2 / 4
         - (q1 ** 2 + q2 ** 2 + q3 ** 2 + q1 ** 3 / 15))
    assert sympy.expand(S.L - L) == 0, S.L
    rest = q3 * v3 / 2 + v3 ** 2 / 2 + sympy.sin(t + q3) / 2 + Q(1, 5)
    assert S.m == 2 and sympy.expand(S.k[0] - (v3 + rest)) == 0 and sympy.expand(S.k[1] - (v2 + rest)) == 0, S.k
    with mpmath.workdps(60):
        assert c.t0 == 0.5 and list(c.q0) == [0.5] * 3 and list(c.v0) == [0.5] * 3


def test_builtin_tableaux_sample_every_family_member_exactly(monkeypatch):
    calls = []
    monkeypatch.setattr(ST, "get_method", lambda nm, exact=False: calls.append(exact) or nm)
    want = {3: {"gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3"},
            2: {"gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-2"}}
    assert set(collect(ST.builtin_tableaux(), 60)) == want[3]
    assert set(collect(ST.builtin_tableaux(max_s=2), 40)) == want[2]
    assert calls and all(calls)


def test_ode_residual_resolves_each_part_at_30_digits():
    sc = _OscScene()
    acc, psi, k = SC.ode_residual(sc)
    assert acc < SC.RESIDUAL_TOL and psi == 0 and k == 0
    assert acc > 0      # the FD truncation d^2 |v'''| / 6 ~ 1e-21 is resolved, not 0
    assert {round(float(t), 6) for t, _, _ in sc.calls} == {0.7} and all(d == 30 and p == 30 for _, d, p in sc.calls)
    assert sum(abs(float(t) - 0.7) < 1e-15 for t, _, _ in sc.calls) == 1 and len(sc.calls) == 3
    # wrong system: a = +q: |v' - a| = 2 max(|sin 0.7|, |cos 0.7|) = 2 cos 0.7
    acc, psi, k = SC.ode_residual(sc, _Osc(sa=1, dpsi=(0.25, -0.5), dk=(0.125, -0.0625)))
    assert abs(acc - 2 * math.cos(0.7)) < 1e-12 and abs(psi - 0.5) < 1e-15 and abs(k - 0.125) < 1e-15, (acc, psi, k)
    assert SC.ode_residual(sc, t="0.2")[0] < 1e-15


def test_orders_hold_is_two_sided_and_needs_every_order():
    ok = {"a": (4, {"q": 4.5, "v": 3.5}, None), "b": (2, {"q": 2.0}, None)}
    assert SC.orders_hold(ok, tol=0.5)
    assert not SC.orders_hold(ok, tol=0.49)
    assert SC.orders_hold({"a": (4, {"q": 4.2, "v": 3.8}, None)})
    assert not SC.orders_hold({"a": (4, {"q": 4.2, "v": 3.6}, None)})       # one variable off
    assert not SC.orders_hold({"a": (4, {"q": 4.0}, None), "b": (2, {"q": 2.4}, None)})   # one method off
    assert not SC.orders_hold({"a": (4, {"q": None, "v": 4.0}, None)})
    assert not SC.orders_hold({"a": (4, {"q": -4.0}, None)})


def test_with_system_copies():
    sc = type("Sc", (), {})()
    sc.system, sc.x = "a", 1
    c = SC._with_system(sc, "b")
    assert c.system == "b" and c.x == 1 and sc.system == "a"


def test_constraint_bound_value():
    r = _res([[1.0, -3.0], [0.5, 2.0]], [[0.25, 0.5], [-2.0, 1.0]])
    assert SC.constraint_bound(r) == 100 * 4 * 3 * EPS            # exact: powers of two times integers


def test_rk4_constraint_drift_is_classical_rk4():
    # two oscillators (frequencies 1, 2): one RK4 step is the matrix series of exp(h A) to 4th order
    S = _ODE(2, lambda t, q, v: [-q[0], -4 * q[1]],
             lambda t, q, v: [q[0] ** 2 + v[0] ** 2 - 1, 4 * q[1] ** 2 + v[1] ** 2 - 4])
    h, N = 0.1, 20
    for q0, v0, scq, scv in (([0.6, 1.0], [0.8, 0.0], None, None), ([0.6, 1.0], [0.8, 0.0], [1.0, 0.0], [0.0, 2.0])):
        got = SC.rk4_constraint_drift(_scene(S, 0.0, q0, v0), h, N, q0=scq, v0=scv)
        want = 0.0
        y = np.array((scq or q0) + (scv or v0), float)
        A = np.zeros((4, 4))
        A[0, 2] = A[1, 3] = 1
        A[2, 0], A[3, 1] = -1, -4
        hA = h * A
        P = np.eye(4) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
        for _ in range(N):
            y = P @ y
            want = max(want, abs(y[0] ** 2 + y[2] ** 2 - 1), abs(4 * y[1] ** 2 + y[3] ** 2 - 4))
        assert want > 1e-9 and abs(got - want) <= 1e-6 * want, (got, want)
    # time dependence: v' = cos t is integrated by Simpson's rule; k = v - sin t at t_n = t0 + n h
    t0 = 0.3
    S = _ODE(1, lambda t, q, v: [math.cos(t)], lambda t, q, v: [v[0] - math.sin(t) + 0 * q[0]])
    got = SC.rk4_constraint_drift(_scene(S, t0, [0.0], [math.sin(t0)]), 0.25, 6)
    v, want = math.sin(t0), 0.0
    for j in range(6):
        t = t0 + j * 0.25
        v += 0.25 / 6 * (math.cos(t) + 4 * math.cos(t + 0.125) + math.cos(t + 0.25))
        want = max(want, abs(v - math.sin(t + 0.25)))
    assert want > 1e-9 and abs(got - want) <= 1e-6 * want, (got, want)


def test_long_run_roundoff_bounded_and_drift_verdicts(monkeypatch):
    """16 points: round-off bound 100 eps sqrt(16) (1 + |I0|); quarters [0:5], .., [12:17]."""
    log = _fake_run(monkeypatch)
    I0 = -3.0                                   # bound = 100 eps 4 * 4 = 1600 eps
    at = np.full(16, I0)
    at[-1] = I0 + 1600 * EPS
    res, rec = SC.long_run(_InvScene(at), "m", 10.0, 0.5, q0=[1.0], v0=[2.0], engine="generic")
    assert rec["E"]["roundoff"] and rec["E"]["bounded"] and not rec["E"]["drift"], rec
    assert log[-1][1:] == ("m", (0, 10.0), 0.5, [1.0], [2.0], "generic") and len(res.t) == 16
    above = at.copy()
    above[-1] = I0 + 1602 * EPS                 # first quarter 0: ratio inf
    rec = SC.long_run(_InvScene(above), "m", 10.0, 0.5)[1]["E"]
    assert not rec["roundoff"] and not rec["bounded"] and rec["drift"], rec
    assert log[-1][-1] == "compiled"

    def series(first, last):
        e = np.zeros(16)
        e[2], e[14] = first, last
        return e
    for first, last, bounded, drift in ((0.5, 0.75, True, False), (0.5, 1.0, False, True),
                                        (0.5, 0.875, False, False), (0.5, 0.5, True, False), (-0.5, -1.0, False, True)):
        rec = SC.long_run(_InvScene(series(first, last)), "m", 10.0, 0.5)[1]["E"]
        assert not rec["roundoff"] and rec["bounded"] == bounded and rec["drift"] == drift, (first, last, rec)
    # observables: errors as given (no I0: scale 1), bound 100 eps 4 = 400 eps
    obs = {"r": lambda t, q, v: series(0.0, 400 * EPS), "s": lambda t, q, v: series(0.0, 402 * EPS)}
    rec = SC.long_run(_InvScene(np.zeros(16)), "m", 10.0, 0.5, observables=obs)[1]
    assert set(rec) == {"r", "s"} and rec["r"]["roundoff"] and not rec["s"]["roundoff"] and rec["s"]["drift"]


def test_finite():
    assert SC.finite(1.0) and SC.finite(0) and not SC.finite(None)
    assert not SC.finite(float("nan")) and not SC.finite(float("inf")) and not SC.finite(-float("inf"))


# =================================================================================================
# general_fixtures.py
# =================================================================================================
def test_rheonomic_system_is_the_documented_one():
    S = GF.rheonomic_system()
    x, y, z = S.q
    u, w, r = S.v
    t = S.t
    L = (u ** 2 + w ** 2 + r ** 2) / 2 + u ** 4 / 12 + (1 + sympy.sin(t)) / 4 * (x * w - y * u) \
        - (1 + t / 5) * (x ** 2 + y ** 2) / 2 - z ** 2 / 4
    assert sympy.expand(S.L - L) == 0, S.L
    assert len(S.k) == 1 and sympy.expand(S.k[0] - (r - (y + t / 4) * u - w ** 3 / 10 - sympy.sin(t) / 5)) == 0
    assert [str(s) for s in S.q + S.v] == ["x", "y", "z", "u", "w", "r"] and S.name == "rheonomic-general"


def test_rheonomic_initial_is_consistent_and_as_documented():
    S = GF.rheonomic_system()
    kf = sympy.lambdify([S.t] + list(S.q) + list(S.v), S.k[0], "mpmath")
    t0, q0, v0 = GF.rheonomic_initial()
    assert (t0, q0, v0[:2]) == (0.3, [1.0, 0.5, 0.0], [0.5, 1.0]) and all(type(x) is float for x in [t0] + q0 + v0)
    assert abs(float(_kval(kf, t0, q0, v0))) < 1e-15
    r0 = (0.5 + 0.3 / 4) * 0.5 + 0.1 + math.sin(0.3) / 5
    assert abs(v0[2] - r0) < 1e-16
    for dps in (20, 40):
        t0, q0, v0 = GF.rheonomic_initial(dps)
        assert mpmath.mp.dps == 15                          # workdps: the global precision untouched
        with mpmath.workdps(dps + 20):
            assert all(isinstance(x, mpmath.mpf) for x in [t0] + q0 + v0)
            assert t0 == mpmath.mpf("0.3") or abs(t0 - mpmath.mpf(3) / 10) < mpmath.mpf(2) ** (-3.32 * dps)
            assert abs(_kval(kf, t0, q0, v0)) < mpmath.mpf(10) ** (-dps + 1)
            exact_r0 = (mpmath.mpf(1) / 2 + mpmath.mpf(3) / 40) / 2 + mpmath.mpf(1) / 10 + mpmath.sin(mpmath.mpf(3) / 10) / 5
            assert abs(v0[2] - exact_r0) <= abs(exact_r0) * mpmath.mpf(2) ** (-mpmath.mpf(3.32) * dps)   # correctly rounded


def test_nonlinear_constraint_system_and_initial_as_documented():
    S = GF.nonlinear_constraint_system()
    x, y, z = S.q
    u, w, r = S.v
    assert sympy.expand(S.L - ((u ** 2 + w ** 2 + r ** 2) / 2 + u ** 4 / 12 - (x ** 2 + y ** 2) / 2)) == 0
    assert len(S.k) == 1 and sympy.expand(S.k[0] - (r - y * u - (u ** 2 + w ** 2) / 4)) == 0
    assert S.name == "nonlinear-constraint" and S.t == GF.T
    t0, q0, v0 = GF.nonlinear_initial()
    assert (t0, q0, v0) == (0.0, [1.0, 0.5, 0.0], [0.5, 1.0, 0.25 + 0.3125])
    t0, q0, v0 = GF.nonlinear_initial(30)
    with mpmath.workdps(50):
        assert all(isinstance(x, mpmath.mpf) for x in [t0] + q0 + v0)
        assert v0[2] == mpmath.mpf("0.5625") and t0 == 0


def _point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- the mechanical form: one system for every engine, shapes checked -------------------------
def _mech(**kw):
    import sympy
    x, y, vx, vy = sympy.symbols("x y vx vy")
    d = dict(M=sympy.Matrix([[1, 0], [0, 2]]), U=y, K=sympy.Matrix([[1, -x]]))
    d.update(kw)
    return ldaspark.LagrangianSystem(vx ** 2 / 2 + vy ** 2 - y, [vx - x * vy], [x, y], [vx, vy], mechanical=d)


# --- valid input refused: an event's value and direction of any real number type --------------
@pytest.mark.parametrize("engine", ["generic", "compiled"])
@pytest.mark.parametrize("kind", [mpmath.mpf, Fraction, np.float32])
def test_event_values_of_every_real_number_type(engine, kind):
    def g(t, q, v):
        return kind(t) - kind("0.05") if kind is not Fraction else Fraction(t) - Fraction(1, 20)
    g.direction = Fraction(1)
    r = ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine=engine, events=g)
    # the event g = t - 0.05 crosses zero once, inside the first step (its root to the event
    # solver's tolerance, far below the step 0.1)
    assert len(r.t_events[0]) == 1 and abs(float(r.t_events[0][0]) - 0.05) < 1e-6


@pytest.mark.parametrize("bad", ["0.5", b"1", 1j, True, np.array([0.5]), float("nan")])
def test_event_values_that_are_not_real_numbers_are_refused(bad):
    with pytest.raises(InputError, match="event 0"):
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, engine="generic", events=lambda t, q, v: bad)


# --- error messages stay one line when the value is an array ----------------------------------
def test_an_array_in_a_message_is_one_line():
    with pytest.raises(InputError) as exc:
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, tangent=np.zeros((3, 3)))
    assert "\n" not in str(exc.value)
    # valid neighbour: a 2n x r tangent
    assert ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, tangent=np.eye(6)[:, :2],
                                  select=[0, 1]).full.shape == (6, 6)


def test_classify_wellposedness_takes_numpy_precisions():
    q0, v0 = _point()
    ldaspark.classify_wellposedness("skate", "gauss-1", 0, q0, v0, "0.1", dps=(np.int64(16), np.int32(20)))


# --- silent numbers: flow_jacobian's t0 with a scene, dependent without coords / rates ---------
def test_flow_jacobian_uses_the_t0_it_is_given():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, t0=1e17)
    assert ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, t0=1.0).full.shape == (6, 6)


def test_flow_jacobian_dependent_needs_coords_or_rates():
    with pytest.raises(InputError, match="dependent"):
        ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, dependent=[0])
    fj = ldaspark.flow_jacobian("skate", "gauss-1", None, None, 0.1, coords=[0])
    assert fj.J.shape[1] == 1


def test_all_errors_derive_from_ldasparkerror():
    assert issubclass(InputError, LdasparkError)


def test_theory_checks_use_the_t0_they_are_given_with_a_scene():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.check_symmetry("skate", "gauss-1", 1e17, None, None, 1, dps=16)
    assert isinstance(ldaspark.check_symmetry("skate", "gauss-1", 1.0, None, None, "0.1", dps=16), dict)


def test_fast_integrate_refuses_steps_that_do_not_advance_t():
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.fast_integrate("skate", "gauss-2", t0=1e17, h=1.0, n_steps=3)
    # valid neighbour: 32 is twice the spacing of the float64 numbers near 1e17
    assert len(set(ldaspark.fast_integrate("skate", "gauss-2", t0=1e17, h=32.0, n_steps=3).t.tolist())) == 4


@pytest.mark.parametrize("part", ["U", "K", "b", "Uv"])
def test_mechanical_parts_must_match_L_and_k(part):
    import sympy
    x, y, vx = sympy.symbols("x y vx")
    bad = {"U": dict(U=2 * y), "K": dict(K=sympy.Matrix([[1, -2 * x]])), "b": dict(b=sympy.Matrix([1])),
           "Uv": dict(U=y + vx)}[part]
    with pytest.raises(LdasparkError, match="mechanical"):
        _mech(**bad)
    assert _mech().mechanical is not None          # the matching parts are accepted


@pytest.mark.parametrize("args", [
    dict(M=[[1, 0, 0], [0, 2, 0]], U="q1", K=[[1, "-q0"]]),          # M not square
    dict(M=[[1, 0], [0, 2]], U="q1", K=[[1, "-q0", 3]]),              # K of the wrong width
    dict(M=[[1, 0], [0, 2]], U="q1", K=[[1, "-q0"]], b=[1, 2]),       # b of the wrong height
    dict(M=[[1, 0], [0, 2]], U=["q1", "q1"], K=[[1, "-q0"]]),         # U not a scalar
])
def test_mechanical_form_checks_shapes(args):
    with pytest.raises(LdasparkError):
        ldaspark.LagrangianSystem.mechanical_form(**args)
    ldaspark.LagrangianSystem.mechanical_form([[1, 0], [0, 2]], "q1", [[1, "-q0"]], b=["q0"])


def test_with_params_takes_a_dict():
    import sympy
    s = ldaspark.LagrangianSystem("vx**2/2 + vy**2/2 - a*y", ["vx - x*vy"], ["x", "y"], ["vx", "vy"], params=["a"])
    for bad in ([1], "a", 3):
        with pytest.raises(LdasparkError, match="dict"):
            s.with_params(bad)
    assert s.with_params({"a": 1}).param_values() == {sympy.Symbol("a"): 1}


# --- the last neighbours: a misspelt option, the user's own event code, a flag's type, an
# executor that was shut down, a URL's trailing slash -----------------------------------------
def test_a_misspelt_integrate_option_is_one_line_naming_the_closest():
    with pytest.raises(InputError, match=r"unknown option 'tole' \(did you mean tol\?\)") as ei:
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, tole=1e-10)
    assert "\n" not in str(ei.value)
    r = ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, tol=1e-10)     # the neighbour
    assert r.status == 0


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_an_event_that_raises_is_named_with_its_error_kept_as_cause(engine):
    def g(t, q, v):
        raise ZeroDivisionError("inside the user's event")
    with pytest.raises(InputError, match=r"event 0 raised ZeroDivisionError at t = 0: inside the user's event") as ei:
        ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine=engine, events=g)
    assert isinstance(ei.value.__cause__, ZeroDivisionError)


@pytest.mark.parametrize("bad", ["yes", "no", 1, 0.0, None])
def test_get_method_exact_must_be_a_bool(bad):
    with pytest.raises(LdasparkError, match="exact must be True or False"):
        ldaspark.get_method("gauss-2", exact=bad)
    assert ldaspark.get_method("gauss-2", exact=np.True_).exact is not None
    assert ldaspark.get_method("gauss-2", exact=False).s == 2


ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _skate_point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


# --- root 3: exported functions outside the validation layer ------------------------------------
def _fj(**kw):
    h = kw.pop("h", 0.1)
    return ldaspark.flow_jacobian("skate", "gauss-2", None, None, h, **kw)


# --- root 4: silent wrong numbers --------------------------------------------------------------
X, Y, VX, VY = sympy.symbols("x y vx vy")


@pytest.mark.parametrize("h", ["abc", 1j, True, 0, float("nan"), float("inf"), None, [0.1]])
def test_flow_jacobian_refuses_a_bad_step(h):
    with pytest.raises(InputError) as ei:
        _fj(h=h)
    assert "h" in _one_line(ei)


def test_flow_jacobian_valid_neighbours():
    full = _fj()
    assert np.all(np.isfinite(full.J)) and full.J.shape == (6, 6)
    assert np.allclose(_fj(h="0.1").J, full.J)             # a decimal string is a number
    B = np.eye(6)[:, :2]
    r = _fj(tangent=B, select=[0, 1])
    assert np.allclose(r.J, full.full[[0, 1]][:, [0, 1]])
    assert _fj(coords=[0, 1]).J.shape == (2, 2)


def test_flow_jacobian_refuses_nan_t0_and_tangent():
    with pytest.raises(InputError, match="t0"):
        _fj(t0=float("nan"))
    B = np.eye(6)[:, :2]
    B[0, 0] = np.nan
    with pytest.raises(InputError, match="tangent"):
        _fj(tangent=B, select=[0, 1])


@pytest.mark.parametrize("select", [[0, 99], [0, -1], [0, 1.5], [0, 0], [0, True], "01"])
def test_flow_jacobian_refuses_bad_select(select):
    with pytest.raises(InputError, match="select"):
        _fj(tangent=np.eye(6)[:, :2], select=select)


def test_flow_jacobian_refuses_duplicate_coordinates():
    with pytest.raises(InputError, match="twice"):
        _fj(coords=[0, 0])
    with pytest.raises(InputError, match="twice"):
        _fj(coords=["q1", 0])
    assert _fj(coords=["q1"]).J.shape == (1, 1)


@pytest.mark.parametrize("name,ic", [(["skate"], None), (3, None), ("mp-particles", True), ("mp-particles", "3"),
                                     ("mp-particles", 2.5), ("mp-particles", -1), ("skate", 1)])
def test_get_scene_refuses_bad_name_and_ic(name, ic):
    with pytest.raises(InputError):
        ldaspark.get_scene(name, ic)


def test_get_scene_valid_neighbours():
    a = ldaspark.get_scene("mp-particles", 2)
    b = ldaspark.get_scene("mp-particles", np.int64(2))
    assert a is b and a.params["j"] == 2


def test_mechanical_form_refuses_a_non_symmetric_mass_matrix():
    with pytest.raises(SystemDefinitionError, match="not symmetric") as ei:
        ldaspark.LagrangianSystem.mechanical_form([[1, 0.5], [0, 1]], "x**2/2 + y**2/2", [[1, 1]],
                                                  q=[X, Y], v=[VX, VY])
    _one_line(ei)
    ok = ldaspark.LagrangianSystem.mechanical_form([[1, 0.25], [0.25, 1]], "x**2/2 + y**2/2", [[1, 1]],
                                                   q=[X, Y], v=[VX, VY])
    assert ok.L_vv == sympy.Matrix(ok.mechanical["M"])
    res = ldaspark.integrate(ok, "gauss-1", q0=[0.1, 0.2], v0=[0.5, -0.5], h=0.1, n_steps=3, engine="generic")
    assert res.status == 0


def test_string_l_names_must_be_nfkc_normal():
    mu_micro, mu_greek = sympy.Symbol("\u00b5"), sympy.Symbol("\u03bc")
    with pytest.raises(SystemDefinitionError, match="NFKC"):
        ldaspark.LagrangianSystem("\u00b5*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY], params=[mu_greek])
    with pytest.raises(SystemDefinitionError, match="NFKC"):
        ldaspark.LagrangianSystem("\uff58*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY])
    with pytest.raises(SystemDefinitionError, match="NFKC normalisation"):
        ldaspark.LagrangianSystem(mu_micro * VX ** 2 / 2 + mu_greek * VY ** 2, [VX - VY], [X, Y], [VX, VY],
                                  params=[mu_micro, mu_greek])
    ok = ldaspark.LagrangianSystem("\u03bc*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY], params=[mu_greek])
    assert ok.L.free_symbols == {mu_greek, VX, VY}


@pytest.mark.parametrize("span", [{0: 0, 1: 1}, {0, 1}, "01", 1.0])
def test_t_span_must_be_a_pair(span):
    with pytest.raises(InputError, match="t_span"):
        ldaspark.integrate("skate", "gauss-1", t_span=span, h=0.5, engine="generic")


def test_t_span_valid_neighbours():
    for span in ((0, 1), [0, 1], np.array([0.0, 1.0])):
        assert len(ldaspark.integrate("skate", "gauss-1", t_span=span, h=0.5, engine="generic").t) == 3


def test_ensemble_members_terminal_events_are_on_the_batched_result():
    def at_015(t, q, v):
        return t - 0.15
    at_015.terminal = True
    q0, v0 = _skate_point()
    res = ldaspark.integrate("skate", "gauss-1", q0=[q0, q0], v0=[v0, v0], h=0.1, n_steps=4, events=at_015,
                             engine="generic")
    assert list(res.status) == [1, 1]
    assert len(res.t_events) == 1 and len(res.t_events[0]) == 2
    for k, m in enumerate(res.members):
        assert np.array_equal(res.t_events[0][k], m.t_events[0]) and np.allclose(m.t_events[0], [0.15])
        assert np.array_equal(res.q_events[0][k], m.q_events[0])
    plain = ldaspark.integrate("skate", "gauss-1", q0=[q0, q0], v0=[v0, v0], h=0.1, n_steps=2, engine="generic")
    assert plain.t_events == [] and list(plain.status) == [0, 0]


# --- root 5: functions the engines cannot translate; two symbols with one name ----------------
@pytest.mark.parametrize("f,name", [(sympy.besselj(0, X), "besselj"), (sympy.polygamma(0, X + 3), "polygamma"),
                                    (sympy.LambertW(X), "LambertW"), (sympy.zeta(X + 3), "zeta"),
                                    (sympy.conjugate(X), "conjugate"), (sympy.floor(X) * X, "floor"),
                                    (sympy.gamma(X + 3), "gamma"), (sympy.Function("f")(X), "f"),
                                    (sympy.Derivative(sympy.sin(X * Y), X), "erivative")])
def test_untranslatable_functions_refused_at_build(f, name):
    with pytest.raises(SystemDefinitionError) as ei:
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - f, [VX - VY], [X, Y], [VX, VY])
    assert name in _one_line(ei)


def test_untranslatable_function_in_k_is_named_with_where():
    with pytest.raises(SystemDefinitionError, match=r"k\[0\] contains the function zeta"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2, [VX - sympy.zeta(X + 3) * VY], [X, Y], [VX, VY])


@pytest.mark.parametrize("dps", [None, 20])
def test_translated_functions_still_run(dps):
    U = sympy.sin(X) + sympy.Abs(Y) + sympy.Piecewise((X ** 2, X > 0), (0, True)) + sympy.atan2(X, Y + 3) \
        + sympy.erf(X) + sympy.Heaviside(X) * X ** 2
    sysm = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - U, [VX - VY / 2], [X, Y], [VX, VY])
    res = ldaspark.integrate(sysm, "gauss-1", q0=[0.5, 0.5], v0=[0.5, 1], h=0.1, n_steps=2, engine="generic",
                             dps=dps)
    assert res.status == 0


def test_two_symbols_with_one_name_refused_at_build():
    x_real = sympy.Symbol("x", real=True)
    with pytest.raises(SystemDefinitionError, match="same name") as ei:
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - x_real ** 2, [VX - VY], [X, Y], [VX, VY])
    assert "'x'" in _one_line(ei)
    with pytest.raises(SystemDefinitionError, match="same name"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - sympy.Dummy("y") ** 2, [VX - VY], [X, Y], [VX, VY])
    lam0 = sympy.Symbol("lam0")                   # the name of the first multiplier
    with pytest.raises(SystemDefinitionError, match="multipliers"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2, [VX - VY], [lam0, Y], [VX, VY])
    ok = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - X ** 2, [VX - VY], [X, Y], [VX, VY])
    assert ldaspark.integrate(ok, "gauss-1", q0=[0.5, 0.5], v0=[1, 1], h=0.1, n_steps=1, engine="generic").status == 0


@pytest.mark.parametrize("argv", [["report", "--scheduler", "tcp://[::1"], ["verify", "--scheduler", "x://y"],
                                  ["mutants", "--scheduler", "tcp://"]])
def test_cli_scheduler_one_line_no_traceback_at_exit(argv, tmp_path):
    p = subprocess.run([sys.executable, "-m", "ldaspark", *argv, "--outdir", str(tmp_path)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": ROOT})
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "malformed" in lines[0], p.stderr      # no "Exception ignored in ..." after it


def test_dense_output_of_a_dps_run_at_its_own_times():
    res = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=2, dps=20, dense_output=True, engine="generic")
    assert isinstance(res.t[1], mpmath.mpf)
    q, _ = res.sol(res.t[1])
    assert np.allclose(q, [float(x) for x in res.q[1]], atol=1e-12)


def test_numpy_integers_wherever_ints_are_taken():
    a = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=np.int64(2), max_stages=np.int64(3),
                           save_every=np.int32(1), engine="generic")
    b = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=2, max_stages=3, engine="generic")
    assert np.array_equal(a.q, b.q)
    assert ldaspark.get_method("gauss-3", max_stages=np.int64(3)).s == 3
    assert ldaspark.gauss(np.int64(2)).s == 2
    with pytest.raises(LdasparkError, match="max_stages"):
        ldaspark.get_method("gauss-3", max_stages=np.float64(3))
    with pytest.raises(LdasparkError, match="max_stages"):
        ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=1, max_stages=np.bool_(True))


# --- found by the harness's sweeps ------------------------------------------------------------
def test_check_symmetry_at_rest_and_at_a_huge_step():
    at_rest = ldaspark.check_symmetry("skate", "gauss-1", 0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], "0.1", dps=16)
    assert at_rest["symmetry-fd-unrestricted"] == (0.0, 0.0)      # was a ZeroDivisionError
    big = ldaspark.check_symmetry("skate", "gauss-1", 0, None, None, 6932, dps=16)   # was a broadcast ValueError
    assert all(np.isfinite(big[k]) for k in ("symmetry-Ld", "symmetry-Phi"))


def test_theory_checks_at_steps_beyond_range_are_errors_not_numbers():
    q0, _ = _skate_point()
    with pytest.raises(LdasparkError, match="not finite"):
        ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, -1.2e146, dps=16, max_refine=0)
    with pytest.raises(LdasparkError, match="float64 range"):
        ldaspark.discrete_lagrangian("skate", "gauss-1", 5e165, q0, "0.1", q0, dps=16)
    ok = ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, "1/10", dps=16, max_refine=0)
    assert ok["theorem1-q0"] < 1e-10


# --- documented defaults and the precision the ledger reports ------------------------------------


def test_the_documented_default_parser():
    doc = "Parameters\n----------\nh : float\n    Step.\ndps : int, optional\n    Working digits (default 40).\n" \
          "h_factors : tuple\n    Factors (default (1, \"1/2\")).\nx : int\n    Bound (default 20; more is slow).\n"
    assert _documented_defaults(doc) == {"dps": "40", "h_factors": "(1, \"1/2\")", "x": "20"}


