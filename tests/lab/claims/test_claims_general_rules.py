"""Rules of ``ldaspark.lab.claims.claims_general`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
from types import SimpleNamespace
import numpy as np
import pytest
from ldaspark.lab.claims import claims_general as cg
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.lab.reports import peers, summary, systems
import types


def _tab(name="tab-x"):
    return SimpleNamespace(name=name)


def _scene(name="scene-x", L_q=(0, 0)):
    return SimpleNamespace(name=name, system=SimpleNamespace(L_q=list(L_q)))


def _t1_result(q0, q1):
    return {"theorem1-q0": q0, "theorem1-q1": q1, "fd_error": 1e-40, "without_forces_q0": 1e-3,
            "rank_deficiency": 0, "wellposed": "well-posed", "seconds": 2.0,
            "sigma_max": 1.0, "sigma_min_nonzero": 1e-3, "dps_fd": 60}


# ============================== claims_general ==============================================
def test_order_plan_switches_at_orders_2_and_4():
    # gauss-1 (order 2), gauss-2 (order 4), gauss-3 (order 6): each boundary on its own side
    assert cg.order_plan("gauss-1") == (None, [8, 16, 32, 64], "full")
    assert cg.order_plan("gauss-2") == (None, [4, 8, 16, 32], "full")
    assert cg.order_plan("gauss-3") == (25, [4, 8, 16], "mixed")
    assert cg.order_plan("lobatto-iiia-iiib-2") == (None, [8, 16, 32, 64], "full")


def test_general_theorem1_rule_thresholds_and_vacuous_control(monkeypatch):
    res = {}
    monkeypatch.setattr(cg, "theorem1_residuals", lambda *a, **k: res["r"])
    # the derived bound of these results: 10 x 1e-40 + 1e3 x 1e3 x 1e-60 = 1e-39 (below the 1e-20 cap)
    T, N = cg.theorem1_threshold(_t1_result(0.0, 0.0)), cg.TOL_NEGATIVE
    assert T == pytest.approx(1e-39, rel=1e-12)
    # expected pass: <= TOL (at the threshold passes, just above fails), each identity on its own
    res["r"] = _t1_result(T, T * 1.5)
    out = cg._theorem1_records(_scene(L_q=(1, 0)), _tab(), "pass", 0, [0], [0])
    assert [r["status"] for r in out] == ["pass", "fail"]
    assert [r["claim"] for r in out] == ["theorem1-general-q0", "theorem1-general-q1"]
    assert all(r["threshold"] == T for r in out) and out[0]["seconds"] == 1.0
    # control (expected fail): >= TOL_NEGATIVE is the failure the construction predicts
    res["r"] = _t1_result(N, N * 0.5)
    out = cg._theorem1_records(_scene(L_q=(0, 2)), _tab(), "fail", 0, [0], [0])
    assert [r["status"] for r in out] == ["fail", "pass"] and all(r["threshold"] == N for r in out)
    assert not out[0]["note"].startswith("vacuous")
    # vacuous only when EVERY component of grad_q L vanishes, and only for the control
    out = cg._theorem1_records(_scene(L_q=(0, 0)), _tab(), "fail", 0, [0], [0])
    assert [r["status"] for r in out] == ["not-applicable"] * 2
    assert out[0]["note"].startswith("vacuous control") and out[0]["threshold"] == N
    res["r"] = _t1_result(T * 2, 0.0)
    out = cg._theorem1_records(_scene(L_q=(0, 0)), _tab(), "pass", 0, [0], [0])
    assert [r["status"] for r in out] == ["fail", "pass"]


def test_general_record_failures_are_fail_records(monkeypatch):
    def boom(*a, **k):
        raise LdasparkError("no solution")

    def zero(*a, **k):
        raise ZeroDivisionError("pivot")
    monkeypatch.setattr(cg, "theorem1_residuals", boom)
    out = cg._theorem1_records(_scene(), _tab("t"), "pass", 0, [0], [0])
    assert [(r["claim"], r["status"], r["residual"], r["wellposed"], r["expected"]) for r in out] == [
        ("theorem1-general-q0", "fail", None, "singular", "pass"), ("theorem1-general-q1", "fail", None, "singular", "pass")]
    assert "no solution" in out[0]["note"] and 0 <= out[0]["seconds"] < 1e6        # elapsed, not time.time() + t
    monkeypatch.setattr(cg, "check_symmetry", zero)
    r = cg._symmetry_record(_scene(), _tab("t"), "fail", 0, [0], [0])
    assert (r["claim"], r["status"], r["residual"], r["expected"], r["threshold"]) == (
        "symmetry-general", "fail", None, "fail", cg.TOL_SYMMETRY)
    assert "pivot" in r["note"] and 0 <= r["seconds"] < 1e6        # elapsed, not time.time() + t
    monkeypatch.setattr(cg, "integrate", boom)
    scn = SimpleNamespace(name="s", system=None, initial=lambda: (0.0, [0.0], [0.0]))
    r = cg._constraint_record(scn, _tab("t"))
    assert (r["claim"], r["status"], r["residual"], r["point"]) == ("constraint-general", "fail", None, "ivp-5-steps")
    assert "integration failed" in r["note"] and 0 <= r["seconds"] < 1e6        # elapsed, not time.time() + t


def test_general_symmetry_takes_the_larger_of_the_two_identities(monkeypatch):
    T = cg.TOL_SYMMETRY
    for ld, phi, st in ((T * 10, 0.0, "fail"), (0.0, T * 10, "fail"), (T, T / 2, "pass"), (T / 2, T, "pass")):
        monkeypatch.setattr(cg, "check_symmetry", lambda *a, **k: {"symmetry-Ld": ld, "symmetry-Phi": phi,
                                                                   "wellposed": "well-posed", "seconds": 1.0})
        r = cg._symmetry_record(_scene(), _tab(), "pass", 0, [0], [0])
        assert r["status"] == st and r["residual"] == max(ld, phi)


def test_general_constraint_is_relative_to_one_plus_v_at_every_step(monkeypatch):
    eps = np.finfo(float).eps
    tol = 1e3 * eps
    # step 3: |k| = 2 tol with |v| = 1: relative 1 tol (pass at <=); step 5 alone exceeds
    cons = [np.zeros(2) for _ in range(6)]
    vs = [np.zeros(2) for _ in range(6)]
    cons[3][1], vs[3][0] = 2 * tol, -1.0
    sol = SimpleNamespace(constraint=cons, v=vs)
    monkeypatch.setattr(cg, "integrate", lambda *a, **k: sol)
    scn = SimpleNamespace(name="s", system=None, initial=lambda: (0.0, [0.0], [0.0]))
    r = cg._constraint_record(scn, _tab())
    assert r["status"] == "pass" and r["residual"] == pytest.approx(tol, rel=1e-12) and r["threshold"] == tol
    cons[5][0] = -1.5 * tol          # the last step counts (range(6)), with |v| = 0
    r = cg._constraint_record(scn, _tab())
    assert r["status"] == "fail" and r["residual"] == pytest.approx(1.5 * tol, rel=1e-12)


def test_general_order_record_within_tol_order_both_sides():
    base = {"claimed_order": 4, "pairwise_orders": [None, 3.9], "method": "m", "scene": "s", "dps": None,
            "variable": "q", "errors": [1e-3, 1e-6], "reference": "ref"}
    for o, st in ((4.3, "pass"), (3.7, "pass"), (4.31, "fail"), (3.69, "fail"), (None, "fail")):
        r = cg._order_record("c", dict(base, observed_order=o), 0.0)
        assert r["status"] == st, o
        assert r["residual"] == (None if o is None else pytest.approx(abs(o - 4)))
    assert "pairwise -, 3.90" in cg._order_record("c", dict(base, observed_order=4.0), 0.0)["note"]


def test_general_records_walks_the_pieces_and_reports_progress(monkeypatch):
    calls, seen = [], []
    monkeypatch.setattr(cg, "piece_records", lambda piece, quick: calls.append((piece, quick)) or [piece])
    out = cg.records(quick=True, progress=lambda *a: seen.append(a))
    ps = cg.pieces(True)
    assert out == ps and calls == [(p, True) for p in ps]
    n = len(cg.GENERAL_SCENES)
    # progress for orders pieces (1..n) and the nonideal piece (n+1), never for checks
    assert seen == [(i + 1, n + 1, "general", s) for i, s in enumerate(cg.GENERAL_SCENES)] + \
        [(n + 1, n + 1, "general", "friction-skate")]
    assert cg.records(quick=False) == ps          # no progress callable: no call


def test_general_piece_records_dispatch(monkeypatch):
    monkeypatch.setattr(cg, "_scene_checks", lambda name, quick: [("checks", name, quick)])
    monkeypatch.setattr(cg, "_nonideal_records", lambda quick: [("nonideal", quick)])
    recs = [{"variable": v, "observed_order": 2.0, "claimed_order": 2, "pairwise_orders": [2.0], "method": "m",
             "scene": "s", "dps": None, "errors": [1e-2, 1e-3], "reference": "r"} for v in ("q", "v", "psi")]
    asked = []
    monkeypatch.setattr(cg, "scene_orders", lambda name, methods, claimed=None: asked.append((methods, claimed)) or recs)
    assert cg.piece_records(("checks", "turntable"), True) == [("checks", "turntable", True)]
    assert cg.piece_records(("nonideal",), False) == [("nonideal", False)]
    out = cg.piece_records(("orders", "turntable"), True)
    assert [r["claim"] for r in out] == ["order-general-scenes"] * 2      # psi left out
    # the control runs with the others, measured against the claim it does not have
    assert asked[-1] == (cg._ord_methods(True) + ["euler-i"], {"euler-i": 2})
    ctl = [dict(r, method="euler-i", observed_order=1.0) for r in recs]
    monkeypatch.setattr(cg, "scene_orders", lambda name, methods, claimed=None: recs + ctl)
    out = cg.piece_records(("orders", "turntable"), True)
    assert [(r["method"], r["status"], r["expected"]) for r in out] == [("m", "pass", "pass")] * 2 + [
        ("euler-i (control: claimed 2)", "fail", "fail")] * 2
    ctl[0]["observed_order"] = 2.1          # a control that showed the claimed order is reported
    assert cg.piece_records(("orders", "turntable"), True)[2]["status"] == "pass"
    assert cg._ord_methods(False)[-1] == "gauss-3" and "gauss-3" not in cg._ord_methods(True)
    assert cg._t1_methods(True) == ["gauss-2", "lobatto-iiia-iiib-3"]
    assert cg.piece_cost(("nonideal",)) == 5.2 and cg.piece_cost(("orders", "nowhere")) == 1.0


def test_general_nonideal_control_stalls_below_order_one_half(monkeypatch):
    recs = [{"variable": v, "observed_order": 2.0, "claimed_order": 2, "pairwise_orders": [2.0], "method": "m",
             "scene": "friction-skate", "dps": None, "errors": [1e-2, 1e-3], "reference": "r"} for v in ("q", "psi")]
    monkeypatch.setattr(cg, "nonideal_orders", lambda methods: (recs, None))
    errs = {}
    monkeypatch.setattr(cg, "ideal_control_error", lambda ref: errs["e"])
    # stalls: no order, or an observed order below 1/2 (0.3 here); converges: 0.7 and 2
    for e, st in (([1e-2, 1e-2, 1e-2], "fail"), ([1e-2, 1e-2 / 2 ** 0.3, 1e-2 / 4 ** 0.3], "fail"),
                  ([1e-2, 1e-2 / 2 ** 0.7, 1e-2 / 4 ** 0.7], "pass"), ([1e-2, 2.5e-3, 6.25e-4], "pass")):
        errs["e"] = e
        out = cg._nonideal_records(True)
        assert [r["claim"] for r in out] == ["nonideal-3.3", "nonideal-3.3"] and out[-1]["status"] == st
        # the record carries what decided it: the observed order (None when none) against 0.5
        order = out[-1]["residual"]
        assert out[-1]["threshold"] == 0.5 and out[-1]["expected"] == "fail"
        assert (order is None or order < 0.5) == (st == "fail") and f"{e[-1]:.1e}" in out[-1]["note"]


def test_dop853_reference_failure_is_an_error(monkeypatch):
    monkeypatch.setattr(cg, "solve_ivp", lambda *a, **k: SimpleNamespace(success=False, message="step too small"))
    sys_ = SimpleNamespace(n=1)
    with pytest.raises(LdasparkError, match="step too small"):
        cg.DOP853Reference(sys_, 0.0, [1.0], [0.0], 1.0)


def test_dop853_reference_integrates_a_harmonic_oscillator():
    # q'' = -q: q(1) = cos 1, v(1) = -sin 1; psi passed through
    sys_ = SimpleNamespace(n=1, ode_rhs=lambda bk, t, q, v: (-np.asarray(q, float), "psi"))
    ref = cg.DOP853Reference(sys_, 0.0, [1.0], [0.0], 1.0)
    q, v, psi = ref(1.0)
    assert abs(q[0] - math.cos(1)) < 1e-10 and abs(v[0] + math.sin(1)) < 1e-10 and psi == "psi"
    assert ref.sol.t[-1] == 1.0


# ============================== claims_general: the measurement plumbing ===================
def test_scene_orders_passes_each_methods_plan(monkeypatch):
    scene = SimpleNamespace(name="sc")
    monkeypatch.setattr(cg, "get_scene", lambda name: scene)
    made = []
    monkeypatch.setattr(cg, "make_reference", lambda sc, dps: made.append(dps) or SimpleNamespace(kind="taylor"))
    calls = []
    monkeypatch.setattr(cg, "measure_errors", lambda meth, sc, ref, t_end, nl, dps=None, newton=None:
                        calls.append((meth, t_end, nl, dps, newton, ref.kind)) or {"m": meth})
    monkeypatch.setattr(cg, "order_records", lambda meth, name, p, m, dps, t_end, kind: [(meth, name, p, dps, kind)])
    out = cg.scene_orders("sc", ["gauss-1", "gauss-3"], t_end=0.5)
    assert made == [cg.REF_DPS] and out == [("gauss-1", "sc", 2, None, "taylor"), ("gauss-3", "sc", 6, 25, "taylor")]
    assert calls == [("gauss-1", 0.5, [8, 16, 32, 64], None, "full", "taylor"),
                     ("gauss-3", 0.5, [4, 8, 16], 25, "mixed", "taylor")]
    out = cg.scene_orders("sc", ["gauss-2"], reference=SimpleNamespace(kind="given"))
    assert made == [cg.REF_DPS] and out == [("gauss-2", "sc", 4, None, "given")] and calls[-1][1] == 1.0


def test_nonideal_orders_and_ideal_control(monkeypatch):
    scene = SimpleNamespace(name="friction-skate", system="S", initial=lambda: (0.5, [1.0, 2.0], [0.0, 0.0]))
    ideal = SimpleNamespace(system="ideal")
    monkeypatch.setattr(cg, "get_scene", lambda name: {"friction-skate": scene, "skate": ideal}[name])
    refs = []

    class Ref:
        kind = "dop"

        def __init__(self, system, t0, q0, v0, t_end):
            refs.append((system, t0, q0, v0, t_end))

        def __call__(self, t):
            return np.array([1.0, 2.0]), None, None
    monkeypatch.setattr(cg, "DOP853Reference", Ref)
    calls = []
    monkeypatch.setattr(cg, "measure_errors", lambda meth, sc, ref, t_end, nl: calls.append((meth, nl)) or {})
    monkeypatch.setattr(cg, "order_records", lambda meth, name, p, m, dps, t_end, kind: [(meth, p, dps, kind)])
    recs, ref = cg.nonideal_orders(("gauss-1", "euler-ii"), n_lists={"euler-ii": [8, 16]})
    assert refs == [("S", 0.5, [1.0, 2.0], [0.0, 0.0], 1.0)] and isinstance(ref, Ref)
    assert calls == [("gauss-1", [16, 32, 64, 128]), ("euler-ii", [8, 16])]
    assert recs == [("gauss-1", 2, None, "dop"), ("euler-ii", 1, None, "dop")]
    steps = []

    def integrate(system, tab, t0, q0, v0, h, n_steps):
        steps.append((system, tab.name, h, n_steps))
        # final q off the reference by (-3/N, +1/N): the error is the larger magnitude
        return SimpleNamespace(q=[None, [1.0 - 3.0 / n_steps, 2.0 + 1.0 / n_steps]])
    monkeypatch.setattr(cg, "integrate", integrate)
    errs = cg.ideal_control_error(Ref("S", 0, 0, 0, 0), n_list=(4, 8), t_end=2.0)
    assert errs == [pytest.approx(0.75), pytest.approx(0.375)]
    assert steps == [("ideal", "gauss-2", 1.5 / 4, 4), ("ideal", "gauss-2", 1.5 / 8, 8)]     # (t_end - t0) / N


def test_scene_checks_order_and_expectations(monkeypatch):
    scn = SimpleNamespace(name="turntable", initial=lambda dps: ("t0", "q0", "v0"))
    monkeypatch.setattr(cg, "get_scene", lambda name: scn)
    monkeypatch.setattr(cg, "_theorem1_records", lambda s, tab, exp, t0, q0, v0: [("t1", tab.name, exp, t0)])
    monkeypatch.setattr(cg, "_symmetry_record", lambda s, tab, exp, t0, q0, v0: ("sym", tab.name, exp))
    monkeypatch.setattr(cg, "_constraint_record", lambda s, tab: ("con", getattr(tab, "name", tab)))
    out = cg._scene_checks("turntable", True)
    assert out == [("t1", "gauss-2", "pass", "t0"), ("t1", "lobatto-iiia-iiib-3", "pass", "t0"),
                   ("t1", "negctl-gauss-2+dA_hat[0,1]", "fail", "t0"), ("sym", "gauss-2", "pass"),
                   ("sym", "euler-i", "fail"), ("con", "gauss-2"), ("con", "lobatto-iiia-iiib-iiid-3"),
                   ("con", "gauss-irk-2")]
    assert [x[1] for x in cg._scene_checks("turntable", False)[:3]] == [
        "gauss-2", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-2"]


def test_order_reference_is_the_closed_form_when_there_is_one(monkeypatch):
    import ldaspark.lab.claims.claims_general as cg
    import ldaspark.lab.theory.orders as orders
    monkeypatch.setattr(orders, "ExactReference", lambda sc, dps: ("exact", dps))
    monkeypatch.setattr(cg, "DOP853Reference", lambda system, t0, q0, v0, t_end: ("dop", t_end))
    assert systems._reference("x", SimpleNamespace(exact=object()), 1.0) == (("exact", 30), "closed form")
    sc = SimpleNamespace(exact=None, system=None, initial=lambda: (0.0, [], []))
    ref, kind = systems._reference("x", sc, 1.5)
    assert ref == ("dop", 1.5) and kind.startswith("DOP853")


# --- lab/claims/claims_general.py -------------------------------------------------------------------
def test_order_records_share_the_piece_time_per_record(monkeypatch):
    from ldaspark.lab.claims import claims_general as CG
    clock = iter([100.0, 106.0])
    monkeypatch.setattr(CG, "time", types.SimpleNamespace(time=lambda: next(clock)))

    def rec(var):
        return {"observed_order": 2.0, "claimed_order": 2, "pairwise_orders": [2.0], "method": "gauss-1",
                "scene": "s", "dps": None, "variable": var, "errors": [1e-3, 2.5e-4], "reference": "r"}
    monkeypatch.setattr(CG, "scene_orders", lambda name, methods, claimed=None: [rec("q"), rec("v"), rec("lambda")])
    out = CG.piece_records(("orders", "s"))
    assert [r["point"] for r in out] == ["order-q", "order-v"]
    assert [r["seconds"] for r in out] == [2.0, 2.0]


def test_an_order_record_quotes_the_first_and_last_errors():
    from ldaspark.lab.claims import claims_general as cg
    r = {"observed_order": 3.98, "claimed_order": 4, "pairwise_orders": [3.9, None], "method": "gauss-2",
         "scene": "particle", "dps": None, "variable": "q", "errors": [1e-2, 1e-3, 1e-4], "reference": "closed form"}
    rec = cg._order_record("order", r, 0.5)
    assert rec["status"] == "pass" and "errors 1.0e-02 .. 1.0e-04" in rec["note"] and "(pairwise 3.90, -)" in rec["note"]


def test_the_general_records_are_computed_and_reported_at_40_digits(monkeypatch):
    """README quotes the general Theorem 1 and symmetry records 'at 40 digits'."""
    from ldaspark.lab.claims import claims_general as cg
    asked = []

    def stop(*a, dps=None, **k):
        asked.append(dps)
        raise cg.LdasparkError("stop")
    monkeypatch.setattr(cg, "theorem1_residuals", stop)
    monkeypatch.setattr(cg, "check_symmetry", stop)
    import types
    scn = types.SimpleNamespace(name="sc", system=None)
    tab = types.SimpleNamespace(name="tab")
    recs = cg._theorem1_records(scn, tab, "pass", 0, [0], [0]) + [cg._symmetry_record(scn, tab, "pass", 0, [0], [0])]
    assert asked == [40, 40] and {r["dps"] for r in recs} == {40}


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


def test_a_general_symmetry_record_fails_when_either_identity_fails(monkeypatch):
    import types

    from ldaspark.lab.claims import claims_general as cg
    scn = types.SimpleNamespace(system=None, name="scene")
    tab = types.SimpleNamespace(name="tab")
    assert 1e-40 < cg.TOL_SYMMETRY < 1e-10                             # the inputs straddle the tolerance
    for ld, phi in ((1e-40, 1e-40), (1e-10, 1e-40), (1e-40, 1e-10)):
        monkeypatch.setattr(cg, "check_symmetry", lambda *a, ld=ld, phi=phi, **k: {
            "symmetry-Ld": ld, "symmetry-Phi": phi, "wellposed": "well-posed", "seconds": 0.1})
        rec = cg._symmetry_record(scn, tab, "pass", 0, [0], [0])
        assert rec["residual"] == _close(max(ld, phi))
        assert rec["status"] == ("pass" if max(ld, phi) <= cg.TOL_SYMMETRY else "fail")
