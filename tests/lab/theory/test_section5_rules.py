"""Rules of ``ldaspark.lab.theory.section5`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import mpmath
import numpy as np
import pytest
import types


# ---------------------------------------------------------------------------------------------
# section5: the residual bookkeeping on stubs (scales far from 1, so a residual multiplied
# instead of divided by its scale, or a force of the wrong side, shows)
def _ns(**kw):
    return type("NS", (), {k: staticmethod(v) if callable(v) else v for k, v in kw.items()})()


def _section5_stubs(monkeypatch):
    from ldaspark.lab.theory import section5 as S5
    A = lambda *x: np.array(x, dtype=float)
    fw = _ns(p0=A(100.0, -3.0), p1=A(-50.0, 2.0), f_d_minus=A(0.5, 0.25), f_d_plus=A(-0.75, 0.5),
             k0=A(0.125), residual=1e-30, L_d=2.5, v0=A(1.0, 2.0), v1=A(3.0, -1.0),
             T=[0.0, 0.25], Q=[A(1.0, 0.0), A(2.0, 0.0)], V=[A(0.0, 1.0), A(0.0, 3.0)])
    rv = _ns(p0=A(1.0, 1.0), p1=A(1.0, 1.0), f_d_minus=A(0.7, -0.5), f_d_plus=A(-0.5, -0.25),
             k0=A(0.0), residual=0.0, L_d=-2.25, v0=A(3.0, -0.5), v1=A(1.0, 2.0), T=[], Q=[], V=[])
    seen = {"delta": [], "ivp": []}

    class Flow:
        s = 2
        bk = None
        system = _ns(constraint=lambda bk, t, q, v: np.array([q[0] * v[1] + t]))

        def __init__(self):
            pass

        def bvp(self, t0, q0, t1, q1):
            return fw if t1 > t0 else rv

        def ivp(self, t0, q0, v0, h):
            seen["ivp"].append(t0)
            return np.asarray(q0, dtype=float) + 1.0, np.asarray(v0, dtype=float) * 2, None
    fl = Flow()
    g = {"fw": (A(-99.0, 2.0), A(49.0, -1.0)), "rv": (A(-2.0, 0.5), A(0.25, 1.0))}

    def fd_gradient(flow, r, t0, q0, t1, q1, delta):
        seen["delta"].append(delta)
        return g["fw"] if r is fw else g["rv"]
    monkeypatch.setattr(S5, "flow_for", lambda name, dps=None, stages=None: fl)
    monkeypatch.setattr(S5, "get_scene", lambda name: _ns(initial=lambda dps: (0.0, [1.0, 2.0], [0.5, -0.5])))
    monkeypatch.setattr(S5, "fd_gradient", fd_gradient)
    monkeypatch.setattr(S5, "f_minus_17", lambda flow, r, h: r.f_d_minus + A(0.001, 0.0))
    monkeypatch.setattr(S5, "f_plus_19", lambda flow, r, h: r.f_d_plus + A(0.0, -0.002))
    monkeypatch.setattr(S5, "f_minus_20b_printed", lambda flow, r, h: -r.f_d_minus + A(0.004, 0.0))
    monkeypatch.setattr(S5, "f_minus_17_other_inner", lambda flow, r, h: r.f_d_minus + A(0.0, 0.25))
    monkeypatch.setattr(S5, "f_plus_19_other_inner", lambda flow, r, h: r.f_d_plus + A(-0.5, 0.0))
    return S5, fw, rv, g, seen


def test_section5_endpoints_and_identities_on_stubs(monkeypatch):
    S5, fw, rv, g, seen = _section5_stubs(monkeypatch)
    nrm = lambda x: float(np.max(np.abs(x)))
    with mpmath.workdps(20):
        t0, q0, t1, q1 = S5.endpoints("stub-a", "0.25", 20, 2, offset=("0.5", "-1"))
        assert t1 - t0 == mpmath.mpf("0.25")
        assert [float(x) for x in q1] == [1.0 + 1 + 0.5, 2.0 + 1 - 1]          # ivp q1 + offset
        assert [float(x) for x in S5.endpoints("stub-a", "0.25", 20, 2)[3]] == [2.0, 3.0]
    out = S5.exact_identities("stub-b", h="0.25")
    g0, g1 = g["fw"]
    scale = max(nrm(fw.p0), nrm(fw.p1), nrm(g0), nrm(g1))          # 100
    fscale = max(nrm(fw.f_d_minus), nrm(fw.f_d_plus))              # 0.75
    assert [float(d) for d in seen["delta"]] == [1e-12]
    assert out["16"] == pytest.approx(nrm(g0 + fw.p0 + fw.f_d_minus) / scale)
    assert out["18"] == pytest.approx(nrm(g1 - fw.p1 + fw.f_d_plus) / scale)
    assert out["16-without-force"] == pytest.approx(nrm(g0 + fw.p0) / scale)
    assert out["18-without-force"] == pytest.approx(nrm(g1 - fw.p1) / scale)
    assert out["17"] == pytest.approx(0.001 / fscale) and out["19"] == pytest.approx(0.002 / fscale)
    assert out["20b-printed"] == pytest.approx(nrm(-2 * fw.f_d_minus + np.array([0.004, 0])) / fscale)
    assert out["20b-corrected"] == pytest.approx(0.004 / fscale)
    # the controls of (17), (19): against the same side, relative to the same scale
    assert out["17-other-inner"] == pytest.approx(0.25 / fscale) and out["19-other-inner"] == pytest.approx(0.5 / fscale)
    assert out["f_d_minus"] == 0.5 and out["f_d_plus"] == 0.75 and out["k0"] == 0.125
    assert out["bvp_residual"] == 1e-30 and out["L_d"] == 2.5
    # k(T_i, Q_i, V_i) - k0: 0*1 + 0 - 1/8 and 2*3 + 1/4 - 1/8
    assert out["first_integral"] == pytest.approx(6.125)


def test_section5_del_and_antisymmetry_on_stubs(monkeypatch):
    S5, fw, rv, g, seen = _section5_stubs(monkeypatch)
    nrm = lambda x: float(np.max(np.abs(x)))
    out = S5.exact_del("stub-c", h="0.25")
    d4, d2 = g["fw"][1], g["fw"][0]            # both BVPs run forward (t1 > t0): the fw stubs
    f20a, f20bp = fw.f_d_plus + np.array([0, -0.002]), -fw.f_d_minus + np.array([0.004, 0])
    scale = max(nrm(fw.p1), nrm(d4), nrm(d2))                       # 99
    assert out["del"] == pytest.approx(nrm(d4 + d2 + f20a - f20bp) / scale)
    assert out["del-printed-20b"] == pytest.approx(nrm(d4 + d2 + f20a + f20bp) / scale)
    assert out["del-without-forces"] == pytest.approx(nrm(d4 + d2) / scale)
    assert out["momentum-continuity"] == pytest.approx(nrm(fw.p1 - fw.p0) / scale)
    assert seen["ivp"][:2] == [0.0, mpmath.mpf("0.25")]
    out = S5.antisymmetry("stub-d", h="0.25")
    fs = max(nrm(fw.f_d_minus), nrm(fw.f_d_plus))                   # 0.75
    assert out["L"] == pytest.approx(abs(fw.L_d + rv.L_d) / abs(fw.L_d))
    assert out["f_plus"] == pytest.approx(nrm(rv.f_d_plus + fw.f_d_minus) / fs)
    assert out["f_minus"] == pytest.approx(nrm(rv.f_d_minus + fw.f_d_plus) / fs)
    assert out["wrong-pairing"] == pytest.approx(nrm(rv.f_d_plus + fw.f_d_plus) / fs)
    assert out["v0-rev-is-v1"] == pytest.approx(nrm(rv.v0 - fw.v1))


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- section 5: (16), (18) relative to the largest covector; k a first integral at every node -----
def test_exact_identities_16_18_scale_and_the_first_integral_take_the_largest(monkeypatch):
    from ldaspark.lab.theory import section5 as s5
    real, rec = s5.fd_gradient, {}

    def recording(fl, r, *a, **k):
        g0, g1 = real(fl, r, *a, **k)
        rec.update(r=r, g0=g0, g1=g1)
        # plant a velocity error at the first collocation node only: k(T_1, Q_1, V_1) - k0 = O(1e-3)
        # there, O(1e-30) at the other nodes
        r.V[0] = r.V[0] + mpmath.mpf("1e-3")
        return g0, g1
    monkeypatch.setattr(s5, "fd_gradient", recording)
    out = s5.exact_identities.__wrapped__("particle", dps=20, stages=3)      # not memoized: planted
    r, g0, g1 = rec["r"], rec["g0"], rec["g1"]
    norms = [s5._nrm(x) for x in (r.p0, r.p1, g0, g1)]
    assert max(norms) > 1.005 * min(norms)          # the four sizes differ (by ~1% on the particle)
    with mpmath.workdps(40):
        assert out["16-without-force"] == _close(s5._nrm(g0 + r.p0) / max(norms))
        assert out["18-without-force"] == _close(s5._nrm(g1 - r.p1) / max(norms))
    assert 1e-4 < out["first_integral"] < 1e-2


def _fake_bvp(Ld, fm, fp):
    return types.SimpleNamespace(L_d=mpmath.mpf(Ld), f_d_minus=np.array([mpmath.mpf(x) for x in fm], dtype=object),
                                 f_d_plus=np.array([mpmath.mpf(x) for x in fp], dtype=object),
                                 v0=np.array([mpmath.mpf(0)], dtype=object), v1=np.array([mpmath.mpf(0)], dtype=object))


def _antisymmetry_on(monkeypatch, fw, rv):
    """section5.antisymmetry on a fake exact flow whose forward and reverse solves are given."""
    from ldaspark.lab.theory import section5
    monkeypatch.setattr(section5, "endpoints", lambda *a, **k: ("t0", "q0", "t1", "q1"))
    flow = types.SimpleNamespace(bvp=lambda t0, q0, t1, q1: fw if t0 == "t0" else rv)
    monkeypatch.setattr(section5, "flow_for", lambda *a, **k: flow)
    return section5.antisymmetry.__wrapped__("particle")


def test_the_antisymmetry_computation_pairs_each_side_with_the_other():
    """f^{E+}(rev) = -f^{E-}(fwd) and f^{E-}(rev) = -f^{E+}(fwd): a reverse solve that satisfies the
    first pair only fails the second (and vice versa); L^E(rev) = -L^E(fwd) on its own."""
    mp = pytest.MonkeyPatch()
    try:
        fw = _fake_bvp(2, ["1", "3"], ["5", "7"])
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-7"], ["-1", "-3"]))     # all hold
        assert r["L"] == 0 and r["f_plus"] == 0 and r["f_minus"] == 0
        assert r["wrong-pairing"] == pytest.approx(4 / 7)          # |f+(rev) + f+(fwd)| = |(-1+5, -3+7)| / 7
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-6"], ["-1", "-3"]))     # f^- (rev) off by 1
        assert r["f_plus"] == 0 and r["f_minus"] == pytest.approx(1 / 7) and r["L"] == 0
        r = _antisymmetry_on(mp, fw, _fake_bvp(-2, ["-5", "-7"], ["-1", "-2"]))     # f^+ (rev) off by 1
        assert r["f_minus"] == 0 and r["f_plus"] == pytest.approx(1 / 7)
        r = _antisymmetry_on(mp, fw, _fake_bvp(-1, ["-5", "-7"], ["-1", "-3"]))     # L_d(rev) off
        assert r["L"] == pytest.approx(0.5) and r["f_plus"] == 0 and r["f_minus"] == 0
    finally:
        mp.undo()


def _close_4(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


def test_the_holonomic_tangential_residual_is_the_worse_endpoint(monkeypatch):
    import types

    import numpy as np

    from ldaspark.lab.theory import section5
    # n = 2, m = 1, K = (1, 0): the tangential part of a covector is its second entry
    system = types.SimpleNamespace(n=2, saddle_matrix=lambda bk, t, q, v: np.array(
        [[1, 0, 1], [0, 1, 0], [1, 0, 0]], dtype=object))
    mp = mpmath.mpf
    for fm, fp, want in (((5, 0), (7, 2), 2), ((5, 3), (7, 0), 3)):
        r = types.SimpleNamespace(v0=None, v1=None, k0=np.array([mp(0)], dtype=object),
                                  f_d_minus=np.array([mp(x) for x in fm], dtype=object),
                                  f_d_plus=np.array([mp(x) for x in fp], dtype=object))
        monkeypatch.setattr(section5, "endpoints", lambda *a, **k: (0, None, 1, None))
        monkeypatch.setattr(section5, "flow_for", lambda *a, r=r, **k: types.SimpleNamespace(
            system=system, bvp=lambda *b: r))
        out = section5.holonomic_exact.__wrapped__("pendulum") if hasattr(section5.holonomic_exact, "__wrapped__") \
            else section5.holonomic_exact("pendulum")
        assert float(out["tangential"]) == _close_4(want) and float(out["full"]) == _close_4(7)
