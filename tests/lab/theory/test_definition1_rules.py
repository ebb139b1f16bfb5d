"""Rules of ``ldaspark.lab.theory.definition1`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import numpy as np
import pytest
from ldaspark.core.backend import Backend
from types import SimpleNamespace


# ---------------------------------------------------------------------------------------------
# section5: the residual bookkeeping on stubs (scales far from 1, so a residual multiplied
# instead of divided by its scale, or a force of the wrong side, shows)
def _ns(**kw):
    return type("NS", (), {k: staticmethod(v) if callable(v) else v for k, v in kw.items()})()


# ---------------------------------------------------------------------------------------------
# definition1: the aggregation of (15a), (15b) over a trajectory, on synthetic per-step data
def test_definition1_aggregates_the_right_neighbours(monkeypatch):
    from ldaspark.lab.theory import definition1 as D1
    N = 5
    rng = np.random.default_rng(7)
    tab = {key: rng.uniform(-1, 1, size=(N, 2)) for key in ("p0", "p1", "fm", "fp", "D2", "D4", "v0", "v1")}
    tab["p1"][:, 0] *= 3             # the scale max(|p1_{k-1}|, |p0_k|) picks different sides per k
    mu = rng.uniform(0, 1e-20, size=N)
    wp = ["well-posed", "gauge-deficient", "well-posed", "well-posed", "gauge-deficient"]

    class BVP:
        def __init__(self, *a):
            pass

        def unpack(self, xg):
            return None, None, np.array([xg[1], 0.0]), None      # v1 of the IVP step

    seen = {"v": [], "dps": set(), "delta": set()}

    def base_point(system, tableau, t, q, v, h, dps):
        k = int(round(q[0]))
        seen["v"].append(float(v[0]))
        seen["dps"].add(dps)
        return t + h, q + np.array([1.0, 0.5]), ("xg", 0.1 * (k + 1))

    def discrete_lagrangian(system, tableau, t, q, t1, q1, dps, x_guess):
        k = int(round(q[0]))
        r = type("R", (), {})()
        for key in ("p0", "p1", "v0", "v1"):
            setattr(r, key, tab[key][k])
        r.f_d_minus, r.f_d_plus, r.mu_norm, r.wellposed = tab["fm"][k], tab["fp"][k], mu[k], wp[k]
        return r

    def fd_gradient(bvp, r, t, q, t1, q1, delta):
        k = int(round(q[0]))
        seen["delta"].add(delta)
        return tab["D2"][k], tab["D4"][k]

    class Sys:
        @staticmethod
        def constraint(bk, t, q, v):
            return np.array([v[0] - 0.25 * q[1] + 0.125 * t])
    monkeypatch.setattr(D1, "DiscreteBVP", BVP)
    monkeypatch.setattr(D1, "base_point", base_point)
    monkeypatch.setattr(D1, "discrete_lagrangian", discrete_lagrangian)
    monkeypatch.setattr(D1, "_fd_gradient", fd_gradient)
    monkeypatch.setattr(D1, "Backend", lambda d: Backend(None))
    h = 0.5
    out = D1.definition1_residuals(Sys(), None, 0.0, [0.0, 0.0], [0.3, 0.0], h, n_steps=N, dps=30)
    nrm = lambda x: float(np.max(np.abs(x)))
    res, free = [], []
    for k in range(1, N):
        sc = max(nrm(tab["p1"][k - 1]), nrm(tab["p0"][k]))
        res.append(nrm(tab["D4"][k - 1] + tab["D2"][k] + tab["fp"][k - 1] + tab["fm"][k]) / sc)
        free.append(nrm(tab["D4"][k - 1] + tab["D2"][k]) / sc)
    assert out["15a_per_k"] == pytest.approx(res, rel=1e-12)
    assert out["15a"] == pytest.approx(max(res), rel=1e-12)
    assert out["15a_without_forces"] == pytest.approx(max(free), rel=1e-12)
    q = [np.array([k, 0.5 * k]) for k in range(N + 1)]
    t = [k * h for k in range(N + 1)]
    cons = lambda tt, qq, vv: abs(vv[0] - 0.25 * qq[1] + 0.125 * tt)
    assert out["15b"] == pytest.approx(max(cons(t[k + 1], q[k + 1], tab["v1"][k]) / (1 + nrm(tab["v1"][k]))
                                           for k in range(N)), rel=1e-12)
    assert out["15b_secant"] == pytest.approx(max(cons(t[k + 1], q[k + 1], (q[k + 1] - q[k]) / h)
                                                  for k in range(N)), rel=1e-12)
    assert out["15b_left_end"] == pytest.approx(max(cons(t[k], q[k], tab["v0"][k]) for k in range(N)), rel=1e-12)
    assert out["f_scale"] == pytest.approx(max(max(nrm(tab["fm"][k]), nrm(tab["fp"][k])) for k in range(N)))
    assert out["mu"] == max(mu) and out["wellposed"] == "gauge-deficient/well-posed"
    assert out["n_steps"] == N and out["dps"] == 30
    # each step starts from v1 of the previous IVP step; the differences run at dps + 20 digits
    # with delta = 10^-(dps/2 - 3)
    assert seen["v"] == pytest.approx([0.3] + [0.1 * k for k in range(1, N)])
    assert seen["dps"] == {50} and seen["delta"] == {mpmath.mpf(10) ** -12}


def test_definition1_fd_gradient_predicts_and_extrapolates(monkeypatch):
    """definition1's differences: each shifted solve starts from the first-order predictor
    x + dx/dq_k eps, and Richardson over delta, delta/2 is exact on quartic L_d."""
    from ldaspark.lab.theory import definition1 as D1
    starts = []

    class Solver:
        def __init__(self, bvp):
            pass

        def newton(self, t0, qa, t1, qb, x, gauge, fac=None):
            starts.append(x.copy())
            return x, None, 1, None
    with mpmath.workdps(40):
        coef = [mpmath.mpf(k + 2) / 5 for k in range(4)]
        bvp = _ns(size=3, n=2, L_d_only=lambda t0, qa, t1, qb, xs: sum(
            c * (z ** 4 - 2 * z ** 3 + z) for c, z in zip(coef, list(qa) + list(qb))))
        dxdq = np.array([[mpmath.mpf(i + 3 * j) for j in range(4)] for i in range(3)], dtype=object)
        res = _ns(x=np.array([mpmath.mpf(1), mpmath.mpf(2), mpmath.mpf(3)], dtype=object),
                  extra={"gauge": None, "fac": None, "dx_dq": dxdq})
        monkeypatch.setattr(D1, "_Solver", Solver)
        q0 = np.array([mpmath.mpf("0.3"), mpmath.mpf("-0.4")], dtype=object)
        q1 = np.array([mpmath.mpf("0.9"), mpmath.mpf("0.1")], dtype=object)
        delta = mpmath.mpf(10) ** -9
        g0, g1 = D1._fd_gradient(bvp, res, 0, q0, 1, q1, delta)
        exact = [c * (4 * z ** 3 - 6 * z ** 2 + 1) for c, z in zip(coef, list(q0) + list(q1))]
        assert max(abs(a - b) for a, b in zip(list(g0) + list(g1), exact)) < mpmath.mpf(10) ** -28
        assert len(starts) == 4 * 4
        for k in range(4):
            for j, e in enumerate((delta, -delta, delta / 2, -delta / 2)):
                want = res.x + dxdq[:, k] * e
                assert max(abs(a - b) for a, b in zip(starts[4 * k + j], want)) < mpmath.mpf(10) ** -38


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- Definition 1 (15a-b) along a trajectory: the reported residual is the worst k ----------------
def _v(x, y=0.0):
    return np.array([x, y], dtype=object)


#: per IVP step j: D2 L_d, D4 L_d, f_d^-, f_d^+, c(u = v1), c(secant), c(left end), |mu|
_DEF1_STEPS = [
    dict(D2=_v(0.0), D4=_v(1e-3), fm=_v(5.0), fp=_v(-1e-3), c=1e-3, c_sec=1e-12, c_left=1e-5, mu=4.0),
    dict(D2=_v(0.0), D4=_v(1e-9), fm=_v(0.0), fp=_v(1e-6), c=1e-12, c_sec=1e-4, c_left=0.0, mu=1.0),
    dict(D2=_v(0.0), D4=_v(0.0), fm=_v(0.0), fp=_v(2.0), c=1e-14, c_sec=1e-13, c_left=1e-14, mu=2.0),
]


def _fake_definition1(monkeypatch):
    from ldaspark.lab.theory import definition1 as d1
    state = {"step": -1, "calls": []}

    def base_point(system, tableau, t, q, v, h, dps):
        return t + h, q + v * h, v

    def discrete_lagrangian(system, tableau, t, q, t1, q1, dps, x_guess):
        state["step"] += 1
        st = _DEF1_STEPS[state["step"]]
        return SimpleNamespace(wellposed="well-posed", f_d_minus=st["fm"], f_d_plus=st["fp"], p0=_v(1.0), p1=_v(1.0),
                               v1=_v(0.0), v0=_v(0.0), mu_norm=st["mu"], step=st)

    def constraint(bk, t, q, v):
        st = _DEF1_STEPS[state["step"]]
        i = len(state["calls"]) % 3
        state["calls"].append(i)
        return np.array([st[("c", "c_sec", "c_left")[i]]], dtype=object)

    monkeypatch.setattr(d1, "base_point", base_point)
    monkeypatch.setattr(d1, "discrete_lagrangian", discrete_lagrangian)
    monkeypatch.setattr(d1, "_fd_gradient", lambda bvp, r, t, q, t1, q1, delta: (r.step["D2"], r.step["D4"]))
    monkeypatch.setattr(d1, "DiscreteBVP", lambda system, tableau, dps: SimpleNamespace(unpack=lambda x: (None, None, x)))
    system = SimpleNamespace(constraint=constraint)
    return d1.definition1_residuals(system, None, 0, [0.0, 0.0], [1.0, 0.0], "0.1", n_steps=3, dps=16)


def test_definition1_15a_15b_report_the_worst_interior_point(monkeypatch):
    out = _fake_definition1(monkeypatch)
    # (15a) at k = 1: D4 + D2 = 1e-3 cancelled by f_d^+ + f_d^- = -1e-3; at k = 2: 1e-9 + 1e-6
    assert out["15a_per_k"] == [0.0, _close(1e-9 + 1e-6)]
    assert out["15a"] == _close(1e-9 + 1e-6)
    assert out["15a_without_forces"] == _close(1e-3)
    # (15b): the worst c over the steps, with u = v1 and with the secant velocity
    assert out["15b"] == _close(1e-3)
    assert out["15b_secant"] == _close(1e-4)
    assert out["15b_left_end"] == _close(1e-5)
    # the force scale is the largest |f_d^-| or |f_d^+| of any step; mu the largest multiplier
    assert out["f_scale"] == _close(5.0)
    assert out["mu"] == 4.0
    assert out["wellposed"] == "well-posed"
