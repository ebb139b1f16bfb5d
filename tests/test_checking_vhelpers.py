"""The theorem-checking suite's own helpers checked (issue #31): ``verification/strategies.py``
(hypothesis strategies), ``verification/systems_checks.py`` (the classic systems' checks) and
``verification/general_fixtures.py`` (fixed systems and a tableau). A helper that generates only
trivial systems, or a check that passes on a wrong input, would make the verification tests that
use it pass vacuously; each test here feeds a helper an input on which the documented rule and a
plausible neighbour differ (a bound hit exactly, one case wrong among several, a term dropped).

Expensive inner computations are replaced by small fakes (a recording LagrangianSystem for the
strategy's base point, a fake ``integrate`` for the run checks) so the file runs in seconds; one
test draws real systems to check the base point itself."""
import copy
import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
import sympy
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis.errors import NoSuchExample, Unsatisfiable

import ldaspark
import ldaspark.core.spark as spark_mod
import ldaspark.models.scenes as scenes_mod
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InconsistentInitialDataError, SingularSaddleError
from ldaspark.core.families import get_method
from ldaspark.core.system import LagrangianSystem
from ldaspark.analysis.conditions import check_22a, check_22b, check_23

from verification import general_fixtures as GF
from verification import strategies as ST
from verification import systems_checks as SC

EPS = 2.0 ** -52
Q = sympy.Rational


def collect(strategy, n):
    """n examples of ``strategy`` (derandomized by the ci profile), no shrinking."""
    out = []

    @settings(max_examples=n, database=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(x):
        out.append(x)
    run()
    return out


def _den_ok(x, den):
    return sympy.Rational(x).q <= den


# =================================================================================================
# strategies.py: small, _R, GeneralCase
# =================================================================================================
def test_small_is_a_bounded_fraction_strategy_with_the_given_denominator():
    assert repr(ST.small()) == ("fractions(min_value=Fraction(-1, 5), max_value=Fraction(1, 5), "
                               "max_denominator=20)")
    for x in collect(ST.small("0", "1", 4), 25):
        assert isinstance(x, Fraction) and 0 <= x <= 1 and x.denominator <= 4, x
    assert ST._R(Fraction(-3, 7)) == Q(-3, 7)


class FakeSystem:
    """Stands for LagrangianSystem inside ``general_systems``: records L and k; the base point's
    behaviour is set per test through ``FakeSystem.mode``."""
    mode = {}

    def __init__(self, L, k, q, v, t=None, name="system"):
        self.L, self.k, self.q, self.v, self.t, self.name = L, list(k), list(q), list(v), t, name
        self.n, self.m = len(self.q), len(self.k)

    def project_velocity(self, bk, t, q, v):
        if self.mode.get("raise"):
            raise InconsistentInitialDataError("fake: no projection")
        if "v" in self.mode:
            return bk.array(self.mode["v"][:self.n] + [0] * max(0, self.n - len(self.mode["v"])))
        return bk.array(v)

    def check_saddle(self, bk, t, q, v, rcond=None):
        rc = self.mode.get("rc", 1.0)          # the reciprocal condition of this fake's matrix (4)
        if rc <= rcond:
            raise SingularSaddleError("fake: singular")
        return rc


@pytest.fixture
def fake_system(monkeypatch):
    monkeypatch.setattr(ST, "LagrangianSystem", FakeSystem)
    monkeypatch.setattr(FakeSystem, "mode", {})
    return FakeSystem


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


class _St:
    """Stands for ``hypothesis.strategies`` inside the strategies' definitions, driven by ``_draw``:
    each strategy is a tuple that the fake draw resolves by a policy (module attribute)."""
    integers = staticmethod(lambda lo, hi: ("i", lo, hi))
    fractions = staticmethod(lambda min_value, max_value, max_denominator: ("f", min_value, max_value))
    permutations = staticmethod(lambda x: ("p", list(x), list(x)))
    sampled_from = staticmethod(lambda x: ("p", list(x), list(x)))


def _draw(policy):
    """low: every draw at its lower end (a list: its first element, a permutation: the identity);
    high: the upper end (last element, reversed); zero: 0 where the range holds it, else low."""
    def draw(s):
        kind, a, b = s
        if kind == "p":
            return (a if policy != "high" else a[::-1]) if _PERM[0] else (a[0] if policy != "high" else a[-1])
        if policy == "zero" and a <= 0 <= b:
            return type(a)(0)
        return b if policy == "high" else a
    return draw


_PERM = [True]


def _run(monkeypatch, strategy, policy, perm=True):
    """The composite's definition run once with the fake draws (``perm``: "p" strategies are
    permutations, else sampled_from)."""
    w = strategy.wrapped_strategy
    monkeypatch.setattr(ST, "st", _St)
    _PERM[0] = perm
    return w.definition(_draw(policy), *w.args, **w.kwargs)


def _lowest_case(monkeypatch, **kw):
    return _run(monkeypatch, ST.general_systems(**kw), "low")


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
def test_general_systems_rejects_bad_base_points(fake_system, monkeypatch):
    """The base point is kept only when the projection converges, the saddle matrix (4) passes
    with rcond = 1e-6 and |v0|_inf < 3 (strict)."""
    from hypothesis.errors import UnsatisfiedAssumption
    for mode, accepted in ((dict(raise_=True), False), (dict(rc=1e-7), False), (dict(rc=1e-6), False),
                           (dict(rc=1e-5), True), (dict(v=[3, 0]), False), (dict(v=[-3.5, 0]), False),
                           (dict(v=[2.9, -1]), True), (dict(v=[0, -2.99]), True)):
        FakeSystem.mode = {("raise" if k == "raise_" else k): x for k, x in mode.items()}
        if accepted:
            c = _lowest_case(monkeypatch, n_range=(2, 2))
            assert c.dps == 60 and c.system.n == 2
            if "v" in mode:
                assert [float(x) for x in c.v0] == [float(x) for x in mode["v"]]
        else:
            with pytest.raises(UnsatisfiedAssumption):
                _lowest_case(monkeypatch, n_range=(2, 2))


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


def _tab_expected(s, dA, db, dAt, dom):
    A = [[Q(ST.BASE_A[s][i][j]) + dA for j in range(s)] for i in range(s)]
    b = [Q(ST.BASE_B[s][i]) + db for i in range(s)]
    c = [sum(r) for r in A]
    At = [[Q(1, 2 * s) + dAt] * s for _ in range(s)]
    om = [[b[j] * c[j] ** i + dom for j in range(s)] for i in range(s - 1)]
    Ah = [[b[j] * (b[i] - A[j][i]) / b[i] for j in range(s)] for i in range(s)]
    return A, b, c, At, om, Ah


@pytest.mark.filterwarnings("ignore:Using `assume` outside")
@pytest.mark.parametrize("policy, d", [("low", -1), ("high", 1), ("zero", 0)])
def test_spark_tableaux_corner_draws_are_the_documented_tableaux(monkeypatch, policy, d):
    """A = BASE_A +- 1/10, b = BASE_B +- 1/20, A_tilde = 1/(2s) +- 3/10, omega = b_j c_j^i +- 1/10
    at the corners (d = -1, +1) and at zero perturbation (the base tableau itself, sum b = 1)."""
    for s_values in ((1, 2, 3), (2,), (3, 1)):
        tab = _run(monkeypatch, ST.spark_tableaux(s_values=s_values), policy, perm=False)
        s = s_values[-1] if policy == "high" else s_values[0]
        A, b, c, At, om, Ah = _tab_expected(s, d * Q(1, 10), d * Q(1, 20), d * Q(3, 10), d * Q(1, 10))
        assert tab.s == s and tab.name == f"random-{s}"
        assert _exact(tab, "A") == A and _col(tab, "b") == b and _col(tab, "c") == c
        assert _exact(tab, "A_tilde") == At and _exact(tab, "A_hat") == Ah
        if s > 1:
            assert _exact(tab, "omega") == om
    for s_values in ((1, 2, 3), (2, 3)):
        tab = _run(monkeypatch, ST.spark_tableaux(s_values=s_values, symmetric=True), policy, perm=False)
        s = 2 if policy == "high" or s_values[0] == 2 else 1
        assert tab.s == s and check_23(tab) and check_22b(tab)
        if s == 2:
            a11, a12 = Q(1, 4) + d * Q(1, 10), d * Q(1, 10)
            want = [[a11, a12], [Q(1, 2) - a12, Q(1, 2) - a11]]
            assert _exact(tab, "A") == want and _exact(tab, "A_tilde") == want


def test_general_systems_real_base_point_satisfies_k_and_the_saddle_condition():
    """Real systems: k(t0, q0, v0) = 0 at 60 digits, (4) nonsingular, |v0| < 3."""
    for c in collect(ST.general_systems(n_range=(2, 2)), 2):
        S, bk = c.system, Backend(60)
        with bk.context():
            k = S.constraint(bk, c.t0, c.q0, c.v0)
            assert bk.norm_inf(k) <= mpmath.mpf(10) ** -50, k
            assert S.check_saddle(bk, c.t0, c.q0, c.v0, rcond=1e-6) > 1e-6
            assert bk.norm_inf(bk.array(c.v0)) < 3


# --- tableaux ----------------------------------------------------------------------------------
def _exact(tab, name):
    return [[tab.exact[name][i, j] for j in range(tab.exact[name].cols)] for i in range(tab.exact[name].rows)]


def _col(tab, name):
    return [tab.exact[name][i, 0] for i in range(tab.s)]


def test_base_tableaux_are_the_documented_ones():
    """BASE_A/B: the midpoint rule (Gauss 1), near Gauss 2 with its weights, Lobatto IIIA 3."""
    for s, meth in ((1, "gauss-1"), (3, "lobatto-iiia-iiib-3")):
        ref = get_method(meth, exact=True)
        assert [[Q(x) for x in r] for r in ST.BASE_A[s]] == _exact(ref, "A"), s
        assert [Q(x) for x in ST.BASE_B[s]] == _col(ref, "b"), s
    g2 = get_method("gauss-2", exact=True)
    assert [Q(x) for x in ST.BASE_B[2]] == _col(g2, "b")
    A2 = _exact(g2, "A")
    assert max(abs(float(Q(ST.BASE_A[2][i][j]) - A2[i][j])) for i in range(2) for j in range(2)) < 0.3
    # the data as defined (comment of BASE_A): diagonal of Gauss 2, rational off-diagonal 1/4, 3/4
    assert ST.BASE_A[2] == [[Fraction(1, 4), Fraction(1, 4)], [Fraction(3, 4), Fraction(1, 4)]]
    assert sorted(ST.BASE_A) == sorted(ST.BASE_B) == [1, 2, 3]


def _check_random_tableau(tab, s_values):
    s = tab.s
    assert s in s_values
    A, Ah, At = _exact(tab, "A"), _exact(tab, "A_hat"), _exact(tab, "A_tilde")
    b, c = _col(tab, "b"), _col(tab, "c")
    assert _col(tab, "b_hat") == b and _col(tab, "b_tilde") == b
    assert check_22a(tab) and check_22b(tab)
    assert all(b[i] * Ah[i][j] + b[j] * A[j][i] == b[i] * b[j] for i in range(s) for j in range(s))
    assert c == [sum(r) for r in A]
    assert all(x != 0 for x in b) and sum(b) != 0
    for i in range(s):
        assert abs(b[i] - Q(ST.BASE_B[s][i])) <= Q(1, 20) and _den_ok(b[i] - Q(ST.BASE_B[s][i]), 50)
        for j in range(s):
            d = A[i][j] - Q(ST.BASE_A[s][i][j])
            assert abs(d) <= Q(1, 10) and _den_ok(d, 50), (i, j, d)
            assert abs(At[i][j] - Q(1, 2 * s)) <= Q(3, 10) and _den_ok(At[i][j] - Q(1, 2 * s), 50)
    if s > 1:
        om = _exact(tab, "omega")
        assert len(om) == s - 1 and all(len(r) == s for r in om)
        for i in range(s - 1):
            for j in range(s):
                d = om[i][j] - b[j] * c[j] ** i
                assert abs(d) <= Q(1, 10) and _den_ok(d, 20), (i, j, d)
    assert tab.name == f"random-{s}"


def test_spark_tableaux_satisfy_22_in_the_documented_neighbourhood_and_cover_s_1_to_3():
    tabs = collect(ST.spark_tableaux(), 30)
    for t in tabs:
        _check_random_tableau(t, (1, 2, 3))
    assert {t.s for t in tabs} == {1, 2, 3}
    two = collect(ST.spark_tableaux(s_values=(2,)), 5)
    assert {t.s for t in two} == {2}
    for t in two:
        _check_random_tableau(t, (2,))


def test_symmetric_spark_tableaux_satisfy_23_and_cover_s_1_and_2():
    tabs = collect(ST.spark_tableaux(symmetric=True), 20)
    assert {t.s for t in tabs} == {1, 2}
    for t in tabs:
        assert check_22a(t) and check_22b(t) and check_23(t), t.name
        if t.s == 1:
            assert t.name == "random-sym-1" and _exact(t, "A") == [[Q(1, 2)]] and _exact(t, "A_tilde") == [[Q(1, 2)]]
            assert _col(t, "b") == [1]
        else:
            assert t.name == "random-sym-2" and _col(t, "b") == [Q(1, 2), Q(1, 2)]
            assert _exact(t, "omega") == [[Q(1, 2), Q(1, 2)]]
            for M in ("A", "A_tilde"):
                a = _exact(t, M)
                assert abs(a[0][0] - Q(1, 4)) <= Q(1, 10) and abs(a[0][1]) <= Q(1, 10), a
                assert a[1][0] == Q(1, 2) - a[0][1] and a[1][1] == Q(1, 2) - a[0][0]
    assert any(t.s == 2 and _exact(t, "A") != _exact(t, "A_tilde") for t in tabs)
    assert {t.s for t in collect(ST.spark_tableaux(symmetric=True, s_values=(1,)), 3)} == {1}
    assert {t.s for t in collect(ST.spark_tableaux(symmetric=True, s_values=(2, 3)), 5)} == {2}


def test_builtin_tableaux_sample_every_family_member_exactly(monkeypatch):
    calls = []
    monkeypatch.setattr(ST, "get_method", lambda nm, exact=False: calls.append(exact) or nm)
    want = {3: {"gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3"},
            2: {"gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-2"}}
    assert set(collect(ST.builtin_tableaux(), 60)) == want[3]
    assert set(collect(ST.builtin_tableaux(max_s=2), 40)) == want[2]
    assert calls and all(calls)


# =================================================================================================
# systems_checks.py
# =================================================================================================
def test_constants_as_documented():
    assert SC.EPS == np.finfo(float).eps and SC.RESIDUAL_TOL == 1e-15 and SC.ORDER_TOL == 0.3
    for plan in (SC.ORDER_PLAN, SC.EXHAUSTIVE_PLAN):
        for meth, nl in plan:
            assert get_method(meth).claimed_order is not None
            assert len(nl) == 4 and all(b == 2 * a for a, b in zip(nl, nl[1:])) and nl[0] in (4, 8), (meth, nl)
    assert [m for m, _ in SC.ORDER_PLAN] == ["gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3"]
    # the s = 1 / 2-stage second-order methods start at N = 8, the others at 4 (errors above 1e3 eps)
    assert [nl[0] for _, nl in SC.ORDER_PLAN] == [8, 4, 8, 4]


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


def test_observed_orders_of_q_v_and_of_a_quantity(monkeypatch):
    seen = []

    def fake_measure(meth, sc, reference, t_end, nl):
        seen.append((meth, sc.system, reference, t_end, list(nl)))
        p = get_method(meth).claimed_order
        h = [1.0 / N for N in nl]
        return {"h": h, "q": [x ** p for x in h], "v": [3 * x ** (p - 1) for x in h], "scale": {"q": 1.0, "v": 1.0}}
    monkeypatch.setattr(SC, "measure_errors", fake_measure)
    plan = (("gauss-1", [8, 16, 32, 64]), ("gauss-2", [4, 8, 16, 32]))
    sc = type("Sc", (), {})()
    sc.system = "own"
    ref = object()
    out = SC.observed_orders(sc, ref, plan=plan)
    assert set(out) == {"gauss-1", "gauss-2"}
    for meth, p in (("gauss-1", 2), ("gauss-2", 4)):
        claimed, obs, errs = out[meth]
        assert claimed == p and abs(obs["q"] - p) < 1e-9 and abs(obs["v"] - (p - 1)) < 1e-9, out
        assert errs["q"][0] == (1.0 / plan[[m for m, _ in plan].index(meth)][1][0]) ** p
    assert seen[0] == ("gauss-1", "own", ref, 1.0, [8, 16, 32, 64])
    out = SC.observed_orders(sc, ref, t_end=2.0, plan=plan[:1], system="wrong")
    assert seen[-1][1] == "wrong" and seen[-1][3] == 2.0 and sc.system == "own"

    # a derived quantity: integrate faked, error 0.5 h^p from an exact quantity 1
    calls = []

    def fake_integrate(S, tab, t0, q0, v0, h, n_steps=None, newton=None):
        calls.append((S, tab.name, t0, h, n_steps))
        e = 0.5 * h ** tab.claimed_order
        # the last step is the one measured: earlier rows are far off
        return type("Sol", (), {"q": [np.array([9.0]), np.array([7.0]), np.array([1.0 + e])],
                                "v": [None, np.array([5.0]), np.array([-e])]})()
    monkeypatch.setattr(spark_mod, "integrate", fake_integrate)
    hs_seen, real_estimate = [], SC.estimate_order
    monkeypatch.setattr(SC, "estimate_order", lambda hs, errs, floor: hs_seen.append(list(hs)) or real_estimate(hs, errs, floor))
    sc2 = type("Sc", (), {"system": "own", "initial": lambda self: (0.25, [0.0], [0.0])})()
    refq = lambda t: np.array([1.0, 0.0]) if t == 1.0 else np.array([np.nan, np.nan])
    out = SC.observed_orders(sc2, refq, plan=plan, quantity=lambda q, v: np.array([q[0], v[0]]))
    for meth, p in (("gauss-1", 2), ("gauss-2", 4)):
        claimed, obs, errs = out[meth]
        assert claimed == p and abs(obs["quantity"] - p) < 1e-9, out
    assert all(S == "own" and abs(h * N - 0.75) < 1e-15 for S, _, _, h, N in calls)
    assert [N for *_, N in calls] == [8, 16, 32, 64, 4, 8, 16, 32]
    # the step sizes the order is fitted on are those of the runs, (t_end - t0) / N
    assert hs_seen == [[0.75 / N for N in nl] for _, nl in plan], hs_seen
    SC.observed_orders(sc2, refq, plan=plan[:1], quantity=lambda q, v: np.array([q[0], v[0]]), system="wrong")
    assert calls[-1][0] == "wrong"


def test_with_system_copies():
    sc = type("Sc", (), {})()
    sc.system, sc.x = "a", 1
    c = SC._with_system(sc, "b")
    assert c.system == "b" and c.x == 1 and sc.system == "a"


def _res(q, v, **kw):
    return type("Res", (), dict(q=np.asarray(q, float), v=np.asarray(v, float), **kw))()


def test_constraint_bound_value():
    r = _res([[1.0, -3.0], [0.5, 2.0]], [[0.25, 0.5], [-2.0, 1.0]])
    assert SC.constraint_bound(r) == 100 * 4 * 3 * EPS            # exact: powers of two times integers


def _fake_runs(monkeypatch, kmax=1.0, engine="compiled", success=True, dq=0.0, drift=11.0):
    """The compiled run: q = (t - 2, -2 t), v = (1, 1/2) on [0, 200] (bound 100 eps 401 * 2);
    constraint = kmax * bound; the generic run's q(2) off by dq; RK4 drift = drift * bound."""
    bound = 100 * EPS * 401 * 2
    log = []

    def fake_integrate(name, method, t_span, h, engine=None, **kw):
        log.append((name, method, tuple(t_span), h, engine))
        N = int(round((t_span[1] - t_span[0]) / h))
        t = t_span[0] + h * np.arange(N + 1)
        q = np.stack([t - 2.0, -2 * t], axis=1)
        if engine == "generic":
            q[-1, 0] += dq
            return type("Res", (), dict(q=q, engine="generic", success=True))()
        v = np.tile([1.0, 0.5], (N + 1, 1))
        k = np.zeros(N + 1)
        k[N // 2] = -kmax * bound
        return type("Res", (), dict(q=q, v=v, t=t, constraint=k, engine=engine_out, success=success))()
    engine_out = engine
    monkeypatch.setattr(ldaspark, "integrate", fake_integrate)
    monkeypatch.setattr(scenes_mod, "get_scene", lambda name: ("scene", name))
    monkeypatch.setattr(SC, "rk4_constraint_drift", lambda sc, h, n: log.append(("rk4", sc, h, n)) or drift * bound)
    return log


@pytest.mark.parametrize("kw, ok", [
    ({}, True), (dict(kmax=1.0, dq=0.99e-12, drift=10 * (1 + 1e-9)), True),
    (dict(kmax=1 + 1e-12), False), (dict(engine="generic"), False), (dict(success=False), False),
    (dict(dq=1e-12), False), (dict(dq=-2e-12), False), (dict(drift=10.0), False), (dict(drift=5.0), False)])
def test_check_constraint_roundoff_and_engines_verdict(monkeypatch, kw, ok):
    log = _fake_runs(monkeypatch, **kw)
    if ok:
        SC.check_constraint_roundoff_and_engines("scn")
        assert log == [("scn", "gauss-2", (0, 200), 0.1, None), ("scn", "gauss-2", (0, 2), 0.1, "generic"),
                       ("rk4", ("scene", "scn"), 0.1, 20)], log
    else:
        with pytest.raises(AssertionError):
            SC.check_constraint_roundoff_and_engines("scn")


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


def _toy():
    x, y, u, w, t = sympy.symbols("x y u w t")
    return LagrangianSystem((u ** 2 + w ** 2) / 2 + x * w - y ** 2 / 2, [w - x * u], [x, y], [u, w], t=t, name="toy"), \
        (x, y, u, w)


def test_wrong_sign_flips_the_symbol_where_asked():
    S, (x, y, u, w) = _toy()
    a = SC.wrong_sign(S, "L", "x")
    assert sympy.expand(a.L - ((u ** 2 + w ** 2) / 2 - x * w - y ** 2 / 2)) == 0 and list(a.k) == list(S.k)
    assert a.name == "toy-wrong-L"
    b = SC.wrong_sign(S, "k", "u", name="kk")
    assert sympy.expand(b.k[0] - (w + x * u)) == 0 and b.L == S.L and b.name == "kk"
    assert b.q == S.q and b.v == S.v and b.t == S.t
    with pytest.raises(AssertionError, match="changed nothing"):
        SC.wrong_sign(S, "L", "u")          # L is even in u
    with pytest.raises(AssertionError, match="changed nothing"):
        SC.wrong_sign(S, "k", "y")          # k has no y


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


def _kval(f, t, q, v):
    return f(t, *q, *v)


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


def test_general_tableau_as_documented():
    tab = GF.general_tableau()
    A, Ah, At = _exact(tab, "A"), _exact(tab, "A_hat"), _exact(tab, "A_tilde")
    b, bh, bt, c = _col(tab, "b"), _col(tab, "b_hat"), _col(tab, "b_tilde"), _col(tab, "c")
    assert check_22a(tab) and check_22b(tab) and not check_23(tab)
    assert all(b[i] * Ah[i][j] + b[j] * A[j][i] == b[i] * b[j] for i in range(2) for j in range(2))
    assert c == [sum(r) for r in A] and c != b and bh == b and bt != bh and sum(bt) == 1 and sum(b) == 1
    assert At != Ah and _exact(tab, "omega") == [[Q(1, 3), Q(2, 3)]]
    # the fixture's data (docstring: A arbitrary, b_tilde != b): pinned, a change must be deliberate
    assert A == [[Q(1, 4), Q(-1, 20)], [Q(3, 4), Q(1, 4)]] and b == [Q(3, 5), Q(2, 5)]
    assert At == [[Q(1, 3), Q(1, 10)], [Q(2, 5), Q(1, 5)]] and bt == [Q(9, 20), Q(11, 20)]
    assert tab.name == "general-2"
