"""Rules of ``ldaspark.lab.theory.energy_balance`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import math
import mpmath
import numpy as np
import pytest
import sympy
import ldaspark
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InputError, NonFiniteError
from ldaspark.lab.theory import energy_balance as EB


def _stub_f(table):
    """f(t, q, v) -> (E, E_t, E_q, E_v, L_t, K) of a 1-dof stub: E = 10 t + q, rows by t."""
    def f(t, q, v):
        et, lt, kk = table.get(float(t), (0, 0, 0))
        return (10 * t + q, mpmath.mpf(et), [mpmath.mpf(0)], [mpmath.mpf(0)], mpmath.mpf(lt), [[mpmath.mpf(kk)]])
    return f


# ---------------------------------------------------------------------------------------------
# energy_balance
def test_energy_system_names_and_predicted_order():
    with pytest.raises(InputError, match="unknown energy test system"):
        EB.energy_system("no-such")
    assert EB.predicted_mismatch_order(ldaspark.gauss(2)) == 5          # order 4 + 1
    assert EB.predicted_mismatch_order(ldaspark.gauss(1)) == 3
    assert EB.predicted_mismatch_order(ldaspark.euler_i()) == 2


def test_rhs_terms_signs():
    """(-psi^T K v, -L_t) from a stub f returning (E, E_t, E_q, E_v, L_t, K)."""
    f = lambda t, *qv: (0, 0, [0], [0], mpmath.mpf(3), [[2, 5]])
    ps, lt = EB.rhs_terms(f, 0, [0], [mpmath.mpf(1), mpmath.mpf(-1)], np.array([mpmath.mpf(2)], dtype=object))
    assert ps == -2 * (2 * 1 + 5 * (-1)) and lt == -3


# ---------------------------------------------------------------------------------------------
# energy_balance: the test systems as documented, and the balance bookkeeping on stubs
def test_energy_systems_are_the_documented_ones():
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    U = q[0] ** 2 + q[1] ** 2
    T = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2
    k0 = v[2] - q[1] * v[0]
    spec = {"time-L": (T - (1 + t / 2) * U, k0), "particle": (T - U, k0),
            "affine-b": (T - U, k0 + (q[0] + sympy.sin(t)) / 4), "nonlinear-k": (T - U, k0 + v[0] ** 2 / 4),
            "rheonomic-linear": (T - U, v[2] - (1 + t / 2) * q[1] * v[0])}
    assert set(spec) == set(EB.SYSTEMS)
    for name, (L, k) in spec.items():
        sysm, q0, v0 = EB.energy_system(name)
        sub = dict(zip(list(sysm.q) + list(sysm.v) + [sysm.t], q + v + [t]))
        assert sympy.simplify(sysm.L.subs(sub, simultaneous=True) - L) == 0, name
        assert sympy.simplify(sympy.Matrix(sysm.k).subs(sub, simultaneous=True)[0] - k) == 0, name
        with mpmath.workdps(50):
            qm, vm = [mpmath.mpf(x) for x in q0], [mpmath.mpf(x) for x in v0]
            assert qm == [1, mpmath.mpf(1) / 5, 0]
            env = dict(zip(q + v + [t], qm + vm + [0]))
            assert abs(mpmath.mpf(sympy.N(k.subs(env), 60))) < mpmath.mpf(10) ** -45      # consistent
            # the projection of (1/2, 1, 0) in the L_vv = I metric: v0 - v_ref parallel to k_v(v0)
            d = [vm[0] - mpmath.mpf(1) / 2, vm[1] - 1, vm[2]]
            g = [mpmath.mpf(sympy.N(sympy.diff(k, x).subs(env), 60)) for x in v]
            cross = [d[1] * g[2] - d[2] * g[1], d[2] * g[0] - d[0] * g[2], d[0] * g[1] - d[1] * g[0]]
            assert max(abs(c) for c in cross) < mpmath.mpf(10) ** -40 and max(abs(x) for x in d) > 1e-3


def test_exact_balance_rule_on_a_stub(monkeypatch):
    h = 0.5
    Ts = [0.1, 0.25, 0.4]
    # (E_t, L_t, K) per node; Psi and V per node below: ps = -Psi K V, lt = -L_t
    table = {0.1: (3.0, 1.0, 2.0), 0.25: (-0.5, 0.25, 1.0), 0.4: (1.5, -2.0, 0.5)}
    Psi, Vs = [1.0, -2.0, 4.0], [1.0, 1.0, 0.5]

    class Flow:
        s = 3

        def __init__(self, sysm, dps, stages):
            pass

        def ivp(self, t0, q0, v0, hh):
            nd = {"T": [mpmath.mpf(x) for x in Ts], "Q": [[mpmath.mpf(0)]] * 3,
                  "V": [[mpmath.mpf(x)] for x in Vs], "a": [[mpmath.mpf(0)]] * 3,
                  "Psi": [np.array([mpmath.mpf(p)], dtype=object) for p in Psi]}
            return np.array([mpmath.mpf(2)], dtype=object), np.array([mpmath.mpf(0)], dtype=object), nd

        def quad(self, vals, hh):
            return sum(vals) * hh / 3
    monkeypatch.setattr(EB, "ExactFlow", Flow)
    monkeypatch.setattr(EB, "_fns", lambda sysm: _stub_f(table))
    monkeypatch.setattr(EB, "energy_system", lambda name: (None, ["0"], ["0"]))
    out = EB.exact_balance("stub", h=str(h), dps=20, stages=3)
    rows = []
    for T, p, V in zip(Ts, Psi, Vs):
        et, lt, kk = table[T]
        rows.append((et, -p * kk * V, -lt))
    scale = max(1.0, max(abs(r[0]) for r in rows))          # 3: the largest |dE/dt|
    assert out["max_dEdt"] == pytest.approx(scale)
    assert out["pointwise"] == pytest.approx(max(abs(a - b - c) for a, b, c in rows) / scale)
    assert out["without_L_t"] == pytest.approx(max(abs(a - b) for a, b, c in rows) / scale)
    assert out["without_psi_term"] == pytest.approx(max(abs(a - c) for a, b, c in rows) / scale)
    E0, E1 = 0.0, 10 * h + 2
    assert out["delta_E"] == pytest.approx(abs(E1 - E0))
    assert out["integral"] == pytest.approx(abs(E1 - E0 - sum(b + c for a, b, c in rows) * h / 3) / scale)
    # a stub whose |dE/dt| stays below 1: the scale floor 1 is used
    small = {T: (0.25 * i, 0.0, 0.0) for i, T in enumerate(Ts)}
    monkeypatch.setattr(EB, "_fns", lambda sysm: _stub_f(small))
    out = EB.exact_balance("stub", h=str(h), dps=20, stages=3)
    assert out["max_dEdt"] == 1.0 and out["pointwise"] == pytest.approx(0.5)


def test_discrete_balance_rule_on_a_stub(monkeypatch):
    """One stage (b = 1, c = 1/2): Delta E = E(h, q1) - E(0, q0), quadrature h (ps + lt) at the
    stage, the control h ps; orders are log-log slopes over the last two h, None for a zero."""
    hs = ("0.5", "0.25", "0.125")            # binary fractions: the zero below is exact
    c = 0.5

    class Meth:
        def __init__(self, sysm, tab, dps):
            self.backend = Backend(20)
            self.tab = type("T", (), {"c": [mpmath.mpf(c)], "b": [mpmath.mpf(1)]})()

        def step(self, t0, q0, v0, h):
            r = type("R", (), {})()
            r.q1 = [q1_of[float(h)]]
            r.v1 = [mpmath.mpf(1)]
            r.Q, r.V = [[mpmath.mpf(0)]], [[mpmath.mpf(2)]]
            r.Psi = [np.array([mpmath.mpf(3)], dtype=object)]
            return r
    # stage rows at T = c h: (E_t, L_t, K): ps = -Psi K V = -6 K, lt = -L_t
    table = {0.25: (0, 0.5, 0.25), 0.125: (0, 0.125, 0.5), 0.0625: (0, 0.0, 1.0)}
    # at h = 1/8: Delta E = 10/8 + q1 = -3/4 = h ps (ps = -6): the control without L_t is exactly 0
    q1_of = {0.5: mpmath.mpf(-1), 0.25: mpmath.mpf("-0.5"), 0.125: mpmath.mpf(-2)}
    monkeypatch.setattr(EB, "SparkMethod", Meth)
    monkeypatch.setattr(EB, "_fns", lambda sysm: _stub_f(table))
    monkeypatch.setattr(EB, "energy_system", lambda name: (None, ["0"], ["0"]))
    tab = type("Tab", (), {"s": 1})()
    out = EB.discrete_balance("stub", tab, hs=hs, dps=20)
    dE, mm, mn = [], [], []
    for hh in (0.5, 0.25, 0.125):
        et, lt, kk = table[c * hh]
        ps, l = -3 * kk * 2, -lt
        d = 10 * hh + float(q1_of[hh])            # E = 10 t + q, E(0, 0) = 0
        dE.append(abs(d))
        mm.append(abs(d - hh * (ps + l)))
        mn.append(abs(d - hh * ps))
    assert out["h"] == [0.5, 0.25, 0.125]
    assert out["delta_E"] == pytest.approx(dE) and out["mismatch"] == pytest.approx(mm)
    assert out["mismatch_without_L_t"] == pytest.approx(mn)
    for key, e in (("delta_E", dE), ("mismatch", mm), ("mismatch_without_L_t", mn)):
        if e[-1] > 0 and e[-2] > 0:
            assert out["order_" + key] == pytest.approx(math.log(e[-2] / e[-1]) / math.log(2))
        else:
            assert out["order_" + key] is None
    assert dE[-1] > 0 and dE[-2] > 0 and mn[-1] == 0       # both branches of the order rule are taken


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- section 2.2, the energy balance (8) along the exact flow: worst node, floor 1 of the scale ----
def test_energy_balance_8_reports_the_worst_collocation_node(monkeypatch):
    from ldaspark.lab.theory import energy_balance as eb
    real, calls = eb.rhs_terms, []

    def planted(f, t, q, v, psi):
        # one node's -L_t off by 1e-3, another node's -psi^T K v off by 1e-4; the rest exact
        ps, lt = real(f, t, q, v, psi)
        i = len(calls)
        calls.append(i)
        return ps + (1e-4 if i == 1 else 0), lt + (1e-3 if i == 0 else 0)
    monkeypatch.setattr(eb, "rhs_terms", planted)
    out = eb.exact_balance("particle", dps=20, stages=3)
    assert len(calls) == 3
    # E is conserved on the particle: |dE/dt| << 1, so the scale is its floor 1
    assert out["max_dEdt"] == 1.0
    assert out["pointwise"] == _close(1e-3, rel=1e-3)       # node 0 (node 1: 1e-4, node 2: ~1e-21)
    assert out["without_L_t"] == _close(1e-4, rel=1e-3)     # node 1 (the others ~1e-21)
    assert out["without_psi_term"] == _close(1e-3, rel=1e-2)   # node 0 (the others |psi^T K v| < 1e-5)


def test_discrete_balance_measures_no_order_from_round_off():
    """Gauss-2 satisfies the discrete balance exactly on affine-b (L_t = 0, E quadratic): the
    mismatches at h = 0.2, 0.1, 0.05 are round-off of the 30-digit step (2.4e-31, 5.5e-32, 4.1e-31,
    measured), below the floor 1e3 eps max(1, |E|) = 1e-27. Their log-log slope (-2.90) is no order:
    order_mismatch is None and the floor is reported. Control: Lobatto IIIA-B 2, whose mismatch is
    not an identity, keeps its order (3)."""
    from ldaspark.core.families import get_method
    out = EB.discrete_balance("affine-b", get_method("gauss-2", exact=True))
    assert max(out["mismatch"]) <= out["floor"] <= 1e-26, out
    assert out["order_mismatch"] is None, out
    assert out["order_delta_E"] is not None          # Delta E itself is O(h), far above the floor
    ctl = EB.discrete_balance("affine-b", get_method("lobatto-iiia-iiib-2", exact=True))
    assert min(ctl["mismatch"]) > ctl["floor"] and abs(ctl["order_mismatch"] - 3) <= 0.4, ctl
