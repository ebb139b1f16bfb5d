"""Issue #31: the verdict rules and fault paths of executors.py, lab/claims/ledger.py,
lab/claims/claims_general.py, lab/claims/claims_index.py and lab/claims/claims_paper.py on inputs where
the right rule and its plausible neighbours (<= vs <, all vs any, min vs max, one side of a
pair, a field left out of a fingerprint) give different answers. The expensive inner
computations (BVP solves, integrations) are replaced by synthetic results: what is checked is
the rule that turns a measurement into a verdict, and the paths a failure takes."""
from __future__ import annotations

import concurrent.futures as cf
import json
import math
import os
import stat
from types import SimpleNamespace

import mpmath
import numpy as np
import pytest

from ldaspark.lab.claims import claims_general as cg
from ldaspark.lab.claims import claims_index as ci
from ldaspark.lab.claims import claims_paper as cp
from ldaspark.lab.claims import ledger
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark import executors as workers
from ldaspark.executors import Checkpoint, InlineExecutor, Unit


def _tab(name="tab-x"):
    return SimpleNamespace(name=name)


def _scene(name="scene-x", L_q=(0, 0)):
    return SimpleNamespace(name=name, system=SimpleNamespace(L_q=list(L_q)))


# ============================== claims_general ==============================================
def test_order_plan_switches_at_orders_2_and_4():
    # gauss-1 (order 2), gauss-2 (order 4), gauss-3 (order 6): each boundary on its own side
    assert cg.order_plan("gauss-1") == (None, [8, 16, 32, 64], "full")
    assert cg.order_plan("gauss-2") == (None, [4, 8, 16, 32], "full")
    assert cg.order_plan("gauss-3") == (25, [4, 8, 16], "mixed")
    assert cg.order_plan("lobatto-iiia-iiib-2") == (None, [8, 16, 32, 64], "full")


def _t1_result(q0, q1):
    return {"theorem1-q0": q0, "theorem1-q1": q1, "fd_error": 1e-40, "without_forces_q0": 1e-3,
            "rank_deficiency": 0, "wellposed": "well-posed", "seconds": 2.0}


def test_general_theorem1_rule_thresholds_and_vacuous_control(monkeypatch):
    res = {}
    monkeypatch.setattr(cg, "theorem1_residuals", lambda *a, **k: res["r"])
    T, N = cg.TOL_THEOREM1, cg.TOL_NEGATIVE
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
    monkeypatch.setattr(cg, "scene_orders", lambda name, methods: recs)
    assert cg.piece_records(("checks", "turntable"), True) == [("checks", "turntable", True)]
    assert cg.piece_records(("nonideal",), False) == [("nonideal", False)]
    out = cg.piece_records(("orders", "turntable"), True)
    assert [r["claim"] for r in out] == ["order-general-scenes"] * 2      # psi left out
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
        assert out[-1]["residual"] == e[-1] and out[-1]["expected"] == "fail"


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


# ============================== claims_index / claims_paper ================================
def test_equations_in_ranges_and_single_labels():
    assert ci.equations_in("(21a)-(21c), (7)") == {"(21a)", "(21b)", "(21c)", "(7)"}
    assert ci.equations_in("(21a)-(21a)") == {"(21a)"}
    # a range across numbers is not expanded: the part is kept as it is
    assert ci.equations_in("(21a)-(22b)") == {"(21a)-(22b)"}
    assert ci.equations_in("Theorem 1, (9b)") == {"(9b)"}
    # not a parenthesised range: no expansion
    assert ci.equations_in("(3)-x") == {"(3)-x"}
    # split at the first hyphen only: a second one leaves the part as it is
    assert ci.equations_in("(21a)-(21c)-(21d)") == {"(21a)-(21c)-(21d)"}


def test_claims_index_markdown_counts_and_escapes(monkeypatch):
    claims = (("(1)", "2", "a|b", ("f.py::t",), ci.CHECKED, ""),
              ("(2)", "3", "c", (), ci.NOT_CHECKED, "x\ny"),
              ("(3)", "3", "d", ("g.py::u", "h.py::v"), ci.NOT_CHECKABLE, "n"))
    monkeypatch.setattr(ci, "CLAIMS", claims)
    md = ci.claims_index_markdown()
    assert "3 entries: 1 checked, 1 not checkable, 1 not checked." in md
    assert "| a\\|b |" in md and "| - | " + ci.NOT_CHECKED + " | x y |" in md
    assert "`g.py::u`<br>`h.py::v`" in md and "| f.py::t" not in md and "| - |\n" in md


def test_claims_paper_pieces_and_records(monkeypatch):
    calls, seen = [], []
    parts = tuple((label, (lambda lab: (lambda quick: calls.append((lab, quick)) or [lab]))(label))
                  for label, _ in cp._PARTS)
    monkeypatch.setattr(cp, "_PARTS", parts)
    assert cp.records(quick=True, progress=lambda *a: seen.append(a)) == [p for p, _ in parts]
    assert seen == [(i, len(parts), "paper claims", p) for i, (p, _) in enumerate(parts, 1)]
    assert cp.piece_records("section-7", quick=False) == ["section-7"] and calls[-1] == ("section-7", False)
    assert cp.pieces() == [p for p, _ in parts]
    assert cp.piece_cost("energy-2.2") == 0.8 and cp.piece_cost("nothing") == 5.0


# ============================== ledger =====================================================
def test_record_normalises_the_residual():
    assert ledger.record("c", "m", "s", "pass", mpmath.mpf("0.25"), "pass")["residual"] == 0.25
    assert type(ledger.record("c", "m", "s", "pass", mpmath.mpf(2), "pass")["residual"]) is float
    for bad in (float("inf"), float("nan"), mpmath.inf):
        assert ledger.record("c", "m", "s", "fail", bad, "pass")["residual"] is None
    assert ledger.record("c", "m", "s", "pass", 3, "pass", seconds=1.23456)["seconds"] == 1.235
    assert ledger.record("c", "m", "s", "pass", 1e300, "pass")["residual"] == 1e300


def test_status_is_inclusive_and_none_fails():
    assert ledger._status(1e-20, 1e-20) == "pass" and ledger._status(1.0000001e-20, 1e-20) == "fail"
    assert ledger._status(None, 1.0) == "fail" and ledger._status(0.0, 0.0) == "pass"


def test_check_unit_records_schema():
    good = ledger.record("c", "m", "s", "pass", 0.5, "pass", dps=40, seconds=1.0, threshold=1.0)
    assert ledger.check_unit_records("u", [good, dict(good, residual=None, threshold=None, dps=None)])
    assert ledger.check_unit_records("u", [])
    bads = [dict(good, status="maybe"), dict(good, expected="x"), dict(good, wellposed="w"),
            dict(good, claim=1), dict(good, note=None), dict(good, residual=float("nan")), dict(good, residual=True),
            dict(good, residual="1"), dict(good, threshold=float("inf")), dict(good, dps=0), dict(good, dps=True),
            dict(good, dps=4.0), dict(good, seconds=None), dict(good, seconds=-0.001), dict(good, seconds=float("inf")),
            {k: v for k, v in good.items() if k != "note"}, dict(good, extra=1)]
    for b in bads:
        with pytest.raises(LdasparkError):
            ledger.check_unit_records("u", [good, b])
    with pytest.raises(LdasparkError, match="not a list"):
        ledger.check_unit_records("u", (good,))
    # the boundaries that are allowed: seconds 0, dps 1, a negative residual
    assert ledger.check_unit_records("u", [dict(good, seconds=0.0, dps=1, residual=-1.0)])


def _ledger_t1(q0, q1, mu=0.0, wellposed="well-posed"):
    return {"theorem1-q0": q0, "theorem1-q1": q1, "fd_error": 1e-40, "f_d_minus_norm": 1.0, "without_forces_q0": 1.0,
            "sigma_min_nonzero": 1e-3, "sigma_max": 1.0, "rank_deficiency": 0, "mu_norm": mu, "wellposed": wellposed,
            "seconds": 4.0}


def test_ledger_theorem1_records_rules_and_notes(monkeypatch):
    res = {}
    monkeypatch.setattr(ledger, "theorem1_residuals", lambda *a, **k: res["r"])
    T, N = ledger.TOL_THEOREM1, ledger.TOL_NEGATIVE
    exp = {"theorem1-q0": "pass", "theorem1-q1": "fail"}
    res["r"] = _ledger_t1(T, N)
    recs, r = ledger.theorem1_records(_scene(), _tab(), exp, "base", 0, [0], [0])
    assert r is res["r"] and [x["status"] for x in recs] == ["pass", "fail"]
    assert [x["threshold"] for x in recs] == [T, N] and recs[0]["seconds"] == 2.0
    assert "solvability defect" not in recs[0]["note"] and "SINGULAR" not in recs[0]["note"]
    res["r"] = _ledger_t1(T * 1.01, N * 0.99, mu=2e-30, wellposed=ledger.SINGULAR)
    recs, _ = ledger.theorem1_records(_scene(), _tab(), exp, "base", 0, [0], [0])
    assert [x["status"] for x in recs] == ["fail", "pass"]
    assert "solvability defect 2.0e-30" in recs[0]["note"] and "SINGULAR BVP" in recs[0]["note"]
    res["r"] = _ledger_t1(0.0, 0.0, mu=1e-30)          # exactly 1e-30: not a defect (> 1e-30)
    recs, _ = ledger.theorem1_records(_scene(), _tab(), exp, "base", 0, [0], [0])
    assert "solvability defect" not in recs[0]["note"]

    def boom(*a, **k):
        raise ZeroDivisionError("pivot")
    monkeypatch.setattr(ledger, "theorem1_residuals", boom)
    recs, r = ledger.theorem1_records(_scene(), _tab(), exp, "pt", 0, [0], [0])
    assert r is None and [(x["status"], x["expected"], x["wellposed"], x["point"], x["residual"]) for x in recs] == [
        ("fail", "pass", "singular", "pt", None), ("fail", "fail", "singular", "pt", None)]
    assert "pivot" in recs[0]["note"]


def _classification(cls, rank):
    return {"class": cls, "sigma_min_nonzero_rel": 1e-3, "rank_deficiency": rank, "floor_tracks_precision": True,
            "sigma_min_power_of_h": 1.0, "sigma_stable_across_dps": True,
            "null_support": {"V": 1.0, "Lambda": 0.0, "v0": 0.0}}


def test_ledger_wellposed_and_gauge_records(monkeypatch):
    c = {}
    monkeypatch.setattr(ledger, "classify_wellposedness", lambda *a, **k: c["c"])
    g = {}

    def gauge(*a, **k):
        if isinstance(g["g"], Exception):
            raise g["g"]
        return g["g"]
    monkeypatch.setattr(ledger, "gauge_invariance", gauge)
    S = ledger.TOL_SYMMETRY
    # well-posed: one record, no gauge check
    c["c"] = _classification(ledger.WELLPOSED, 0)
    out, cls = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base")
    assert cls == ledger.WELLPOSED and [(r["claim"], r["status"], r["residual"]) for r in out] == [
        ("implicit-function", "pass", 0.0)]
    # gauge-deficient: gauge invariance by the largest of the three moves, <= TOL_SYMMETRY
    c["c"] = _classification(ledger.GAUGE, 1)
    for moves, st in (((S, S / 2, 0.0), "pass"), ((0.0, 0.0, 2 * S), "fail"), ((0.0, 2 * S, 0.0), "fail"),
                      ((2 * S, 0.0, 0.0), "fail")):
        g["g"] = {"dL_d": moves[0], "d(p0+f_d_minus)": moves[1], "d(p1-f_d_plus)": moves[2], "dp0": 1.0, "dV": 1.0}
        out, cls = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base")
        assert [r["claim"] for r in out] == ["implicit-function", "gauge-invariance"]
        assert out[0]["status"] == "pass" and out[0]["residual"] == 1.0
        assert out[1]["status"] == st and out[1]["residual"] == max(moves)
    # singular: the implicit function fails, the gauge check is not-applicable
    c["c"] = _classification(ledger.SINGULAR, 2)
    g["g"] = {"dL_d": 0.0, "d(p0+f_d_minus)": 0.0, "d(p1-f_d_plus)": 0.0, "dp0": 1.0, "dV": 1.0}
    out, cls = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base")
    assert [r["status"] for r in out] == ["fail", "not-applicable"] and cls == ledger.SINGULAR
    # the gauge re-solve fails: one fail record, nothing else
    c["c"] = _classification(ledger.GAUGE, 1)
    g["g"] = LdasparkError("re-solve diverged")
    out, _ = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "p")
    assert [(r["claim"], r["status"], r["residual"], r["point"]) for r in out] == [
        ("implicit-function", "pass", 1.0, "p"), ("gauge-invariance", "fail", None, "p")]
    assert "re-solve diverged" in out[1]["note"]

    def boom(*a, **k):
        raise LdasparkError("no class")
    monkeypatch.setattr(ledger, "classify_wellposedness", boom)
    out, cls = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "p")
    assert cls == "singular" and [(r["claim"], r["status"], r["wellposed"]) for r in out] == [
        ("wellposedness", "fail", "singular")]


def _sym(ld=0.0, plus=0.0, minus=0.0, phi=0.0, wellposed="well-posed", nplus=(1.0, 0.0), nminus=(0.0, 1.0)):
    return {"symmetry-Ld": ld, "symmetry-fd-plus": plus, "symmetry-fd-minus": minus, "symmetry-Phi": phi,
            "wellposed": wellposed, "seconds": 8.0, "tangent_dim": 1, "fd_restricted_norm": (1.0, 2.0),
            "symmetry-fd-unrestricted": (3e-3, 4e-3), "fd_plus_identity_norms": list(nplus),
            "fd_minus_identity_norms": list(nminus)}


def test_ledger_symmetry_records(monkeypatch):
    r = {}
    monkeypatch.setattr(ledger, "check_symmetry", lambda *a, **k: r["r"])
    S = ledger.TOL_SYMMETRY
    r["r"] = _sym(ld=S, plus=2 * S, minus=S / 2, phi=1.5 * S)
    out = ledger.symmetry_records(_scene(), _tab(), "pass", 0, [0], [0], "base", "well-posed")
    assert [(x["claim"], x["status"]) for x in out] == [("symmetry-Ld", "pass"), ("symmetry-fd-plus", "fail"),
                                                         ("symmetry-fd-minus", "pass"), ("symmetry-Phi", "fail")]
    assert [x["residual"] for x in out] == [S, 2 * S, S / 2, 1.5 * S] and out[0]["seconds"] == 2.0
    assert out[0]["note"] == ""
    assert out[1]["note"] == out[2]["note"] == ("restricted to variations tangent to C_d (dims 1; restricted |f_d| "
                                                "1.0e+00, 2.0e+00); unrestricted covectors differ by 3.0e-03, 4.0e-03")
    # a predicted failure that holds at the base point is marked accidental (not at another point)
    out = ledger.symmetry_records(_scene(), _tab(), "fail", 0, [0], [0], "base", "well-posed")
    assert out[0]["note"].startswith("accidental")
    assert ledger.symmetry_records(_scene(), _tab(), "fail", 0, [0], [0], "perturbed-ivp", "w")[0]["note"] == ""
    r["r"] = _sym(ld=2 * S)
    assert ledger.symmetry_records(_scene(), _tab(), "fail", 0, [0], [0], "base", "w")[0]["note"] == ""
    # singular: the covector identities are not-applicable
    r["r"] = _sym(plus=2 * S, minus=2 * S, wellposed=ledger.SINGULAR)
    out = ledger.symmetry_records(_scene(), _tab(), "pass", 0, [0], [0], "base", "s")
    assert [x["status"] for x in out[1:3]] == ["not-applicable"] * 2 and out[1]["note"].startswith("singular BVP")
    # vacuous when the restricted forces vanish: the LARGEST norm below 1e-30 (one side alone is not enough)
    r["r"] = _sym(plus=2 * S, minus=2 * S, nplus=(0.0, 0.0), nminus=(0.0, 2e-30))
    out = ledger.symmetry_records(_scene(), _tab(), "pass", 0, [0], [0], "base", "w")
    assert [x["status"] for x in out[1:3]] == ["not-applicable", "fail"] and out[1]["note"].startswith("vacuous")
    r["r"] = _sym(plus=2 * S, nplus=(1e-30, 0.0))
    assert ledger.symmetry_records(_scene(), _tab(), "pass", 0, [0], [0], "base", "w")[1]["status"] == "fail"

    def boom(*a, **k):
        raise LdasparkError("no sym")
    monkeypatch.setattr(ledger, "check_symmetry", boom)
    out = ledger.symmetry_records(_scene(), _tab(), "pass", 0, [0], [0], "p", "gauge-deficient")
    assert [(x["claim"], x["status"], x["wellposed"], x["residual"]) for x in out] == [
        ("symmetry-Ld", "fail", "gauge-deficient", None)]


def test_ledger_constraint_records(monkeypatch):
    eps = {None: 2.0 ** -52, 30: 1e-30}

    def resid(scene, tab, dps=None):
        if dps == 30:
            raise LdasparkError("newton failed")
        return 1e3 * eps[None], 0.5, eps[None]
    monkeypatch.setattr(ledger, "constraint_residuals", resid)
    out = ledger.constraint_records(_scene(), _tab())
    assert [(r["dps"], r["status"], r["residual"]) for r in out] == [(None, "pass", 1e3 * eps[None]), (30, "fail", None)]
    assert out[0]["threshold"] == 1e3 * eps[None] and "secant velocity gives 5.0e-01" in out[0]["note"]
    monkeypatch.setattr(ledger, "constraint_residuals",
                        lambda scene, tab, dps=None: (1.0001e3 * eps[dps], 0.0, eps[dps]))
    assert [r["status"] for r in ledger.constraint_records(_scene(), _tab())] == ["fail", "fail"]


def _holo(tang, p, full=(1.0, 0.5, 0.25), pf=1.0):
    return {"h": [0.1, 0.05, 0.025], "tangential": list(tang), "full": list(full), "p_tangential": p,
            "p_full": pf, "wellposed": "well-posed"}


def test_ledger_holonomic_rule(monkeypatch):
    r = {}
    monkeypatch.setattr(ledger, "holonomic_order", lambda tab: r["r"])
    R = ledger.HOLONOMIC_RATE
    for tang, p, st in (((1e-3, 1e-4, 1e-5), R, "pass"), ((1e-3, 1e-4, 1e-5), R - 1e-9, "fail"),
                        ((1e-3, 1e-4, 0.0), float("nan"), "pass"), ((1e-3, 1e-4, 1e-30), 0.0, "fail"),
                        ((1e-3, 1e-4, 0.99e-30), 0.0, "pass")):
        r["r"] = _holo(tang, p)
        out = ledger.holonomic_records(_tab(), "pass")
        assert out[0]["status"] == st, (tang, p) and out[0]["residual"] == tang[-1]

    def boom(tab):
        raise LdasparkError("sweep failed")
    monkeypatch.setattr(ledger, "holonomic_order", boom)
    out = ledger.holonomic_records(_tab(), "pass")
    assert [(x["status"], x["residual"], x["wellposed"], x["scene"]) for x in out] == [
        ("fail", None, "singular", "pendulum")]


def test_ledger_expectations_of_a_control_are_its_construction():
    g2 = ledger.get_method("gauss-2", exact=True)
    ex, t1 = ledger._expectations(g2, None)
    assert ex == {"22a": "pass", "22b": "pass", "23": "pass"} and t1 == {"theorem1-q0": "pass", "theorem1-q1": "pass"}
    (ctl, intent), (_, _), (bh, bh_intent) = ledger.negative_controls()
    # a control's (22) expectations are the intended ones even when told otherwise by a measurement
    ex, t1 = ledger._expectations(ctl, {"22a": "fail", "22b": "pass"})
    assert ex["22a"] == "fail" and ex["22b"] == "pass"
    ex, t1 = ledger._expectations(bh, bh_intent)
    assert ex["22a"] == "fail" and t1 == {"theorem1-q0": "pass", "theorem1-q1": "fail"}
    ex, t1 = ledger._expectations(ctl, intent)
    assert t1 == {"theorem1-q0": "fail", "theorem1-q1": "fail"}
    eu = ledger.get_method("euler-i", exact=True)
    assert ledger._expectations(eu, None)[0]["23"] == "fail"


def test_ledger_scene_records_order_and_control_paths(monkeypatch):
    calls = []
    scene = SimpleNamespace(name="sc", initial=lambda dps: (0, [1, 2], [3, 4]))
    monkeypatch.setattr(ledger, "get_scene", lambda name: scene)
    monkeypatch.setattr(ledger, "perturbed_initial", lambda sc, dps: (5, [6, 7], [8, 9]))
    monkeypatch.setattr(ledger, "_expectations", lambda tab, control: ({"23": "e23"}, {"e": 1}))
    monkeypatch.setattr(ledger, "wellposed_records",
                        lambda sc, tab, t0, q0, v0, point: ([("wp", point)], "cls-" + point))
    wp = {}

    def t1(sc, tab, exp, point, t0, q0, v0, q1_shift=None):
        calls.append(("t1", point, q1_shift))
        return [("t1", point)], {"wellposed": wp.get(point, ledger.WELLPOSED)}
    monkeypatch.setattr(ledger, "theorem1_records", t1)
    monkeypatch.setattr(ledger, "symmetry_records",
                        lambda sc, tab, exp, t0, q0, v0, point, cls: [("sym", point, exp, cls, t0)])
    monkeypatch.setattr(ledger, "constraint_records", lambda sc, tab: [("con",)])
    out = ledger._scene_records(_tab(), None, "sc", True)
    assert out == [("wp", "base"), ("wp", "perturbed-ivp"), ("t1", "base"), ("t1", "perturbed-ivp"),
                   ("t1", "q1-off-C_d"), ("sym", "base", "e23", "cls-base", 0),
                   ("sym", "perturbed-ivp", "e23", "cls-base", 5), ("con",)]
    shift = calls[-1][2]
    assert [float(x) for x in shift] == [1e-4, -1e-4]
    # a control: base Theorem 1 only
    assert ledger._scene_records(_tab(), {"22a": "pass"}, "sc", True) == [
        ("wp", "base"), ("wp", "perturbed-ivp"), ("t1", "base")]
    # not perturbed: no perturbed well-posedness, no base symmetry
    assert ledger._scene_records(_tab(), None, "sc", False) == [
        ("wp", "base"), ("t1", "base"), ("sym", "perturbed-ivp", "e23", "cls-base", 5), ("con",)]
    # the q1-off-C_d check only at a well-posed perturbed point
    wp["perturbed-ivp"] = ledger.GAUGE
    assert ("t1", "q1-off-C_d") not in ledger._scene_records(_tab(), None, "sc", True)


def test_ledger_tab_records_holonomic_only_for_real_tableaux(monkeypatch):
    monkeypatch.setattr(ledger, "_expectations", lambda tab, control: ({"22a": "pass"}, {}))
    monkeypatch.setattr(ledger, "exact_condition_records", lambda tab, exp: [("ex", exp["22a"])])
    monkeypatch.setattr(ledger, "holonomic_records", lambda tab, exp: [("holo", exp)])
    assert ledger._tab_records(_tab(), None, True) == [("ex", "pass"), ("holo", "pass")]
    assert ledger._tab_records(_tab(), {"22a": "fail"}, True) == [("ex", "pass")]
    assert ledger._tab_records(_tab(), None, False) == [("ex", "pass")]


def test_ledger_jobs_environment(monkeypatch):
    monkeypatch.setenv("LDASPARK_JOBS", "3")
    assert ledger.ledger_jobs() == 3 and ledger.ledger_jobs(5) == 5 and ledger.ledger_jobs(0) == 1
    monkeypatch.setenv("LDASPARK_JOBS", "x3")
    assert ledger.ledger_jobs() == max(1, os.cpu_count() or 1)
    monkeypatch.setenv("LDASPARK_JOBS", " 2 ")
    assert ledger.ledger_jobs() == 2


def test_unit_cost_and_names():
    names = ["gauss-2", "other"]
    assert ledger.unit_cost((0, None), names) == 0.5
    assert ledger.unit_cost((0, "robot"), names) == pytest.approx(12.0 * 0.19)
    assert ledger.unit_cost((1, "nowhere"), names) == pytest.approx(10.0 * 0.2)
    assert ledger.unit_cost((0, "skate")) == pytest.approx(10.0 * 0.07)
    assert ledger.unit_cost(("group", "ldaspark.lab.claims.claims_paper:records", "energy-2.2")) == 0.8
    assert ledger.unit_cost(("group", "ldaspark.lab.claims.claims_index:x", None)) == 5.0
    assert ledger.unit_name((1, None), names) == "other on tableau [1]"
    assert ledger.unit_name((0, "robot"), names) == "gauss-2 on robot [0]"
    assert ledger.unit_name(("group", "a.b.mod:f", ("x", "y")), names) == "group mod x y [a.b.mod:f|('x', 'y')]"
    assert ledger._piece_label("a.mod:f", None) == "mod" and ledger._piece_label("a.mod:f", "p") == "mod p"


def test_group_task_whole_group_and_piece(monkeypatch):
    import types
    import sys
    mod = types.ModuleType("ldaspark_fake_group")
    mod.records = lambda quick, progress: [("all", quick, progress)]
    mod.piece_records = lambda piece, quick: [("piece", piece, quick)]
    monkeypatch.setitem(sys.modules, "ldaspark_fake_group", mod)
    assert ledger._group_task("ldaspark_fake_group:records", None, True) == [("all", True, None)]
    assert ledger._group_task("ldaspark_fake_group:records", "p1", False) == [("piece", "p1", False)]
    assert ledger.group_pieces("ldaspark_fake_group:records") == [None]
    mod.pieces = lambda quick: ("a", "b") if quick else ("a",)
    assert ledger.group_pieces("ldaspark_fake_group:records", True) == ["a", "b"]
    assert ledger.extra_records(quick=True, groups=("ldaspark_fake_group:records",)) == [("all", True, None)]


def test_summarize_counts_unexpected_only():
    recs = [{"status": "pass", "expected": "pass"}, {"status": "fail", "expected": "pass"},
            {"status": "not-applicable", "expected": "pass"}, {"status": "pass", "expected": "fail"},
            {"status": "fail", "expected": "fail"}]
    assert ledger.summarize(recs) == 2


def test_run_ledger_progress_and_order(monkeypatch):
    """run_ledger on fake tableaux and a fake group, in this process: records in unit order,
    progress for (tableau, scene) units counted against n_tabs x n_scenes, groups against all."""
    import types
    import sys
    mod = types.ModuleType("ldaspark_fake_group2")
    mod.pieces = lambda quick: ["p1", "p2"]
    mod.piece_records = lambda piece, quick: [ledger.record("g", piece, "-", "pass", 0.0, "pass")]
    mod.piece_cost = lambda piece: 100.0 if piece == "p2" else 0.0
    monkeypatch.setitem(sys.modules, "ldaspark_fake_group2", mod)
    tabs = [(_tab("A"), None), (_tab("B"), None)]
    monkeypatch.setattr(ledger, "_ledger_tabs", lambda max_s, controls: tabs)

    def task(max_s, controls, holonomic, perturbed, i, scn):
        return [ledger.record("c", tabs[i][0].name, scn or "-", "pass", 0.0, "pass")]
    monkeypatch.setattr(ledger, "_ledger_task", task)
    seen = []
    out = ledger.run_ledger(scenes=("s1", "s2"), groups=("ldaspark_fake_group2:records",),
                            progress=lambda *a: seen.append(a), jobs=1, where="local")
    assert [(r["method"], r["scene"]) for r in out] == [
        ("A", "-"), ("A", "s1"), ("A", "s2"), ("B", "-"), ("B", "s1"), ("B", "s2"), ("p1", "-"), ("p2", "-")]
    # one worker: the units run longest first (p2: 100 s; the scene units 10 x 0.2 s; the per-tableau
    # units 0.5 s; p1: 0 s); scene units counted against n_tabs x n_scenes = 4, the group pieces by
    # every unit seen so far against all 8 units, the per-tableau units not reported
    assert seen == [(1, 8, "claim group", "ldaspark_fake_group2 p2"), (1, 4, "A", "s1"), (2, 4, "A", "s2"),
                    (3, 4, "B", "s1"), (4, 4, "B", "s2"), (8, 8, "claim group", "ldaspark_fake_group2 p1")]


# ============================== workers ====================================================
def test_inline_executor_delivers_errors_but_not_ctrl_c():
    ex = InlineExecutor()
    assert ex.submit(lambda a, b=0: a + b, 1, b=2).result() == 3
    f = ex.submit(lambda: 1 / 0)
    assert isinstance(f.exception(), ZeroDivisionError)

    def ctrl_c():
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        ex.submit(ctrl_c)


def test_describe_names_each_place():
    assert workers.describe(None, 3) == "local pool of 3 worker process(es)"
    assert workers.describe("local", 0) == f"local pool of {max(1, os.cpu_count() or 1)} worker process(es)"
    assert workers.describe("tcp://h:1") == "Dask scheduler tcp://h:1"
    assert workers.describe(Client()) == "Dask client"
    assert workers.describe(cf.ThreadPoolExecutor) == "type"
    assert workers.describe(InlineExecutor()) == "InlineExecutor"
    assert workers.is_address("tcp://x") and not workers.is_address("tcp:/x") and not workers.is_address(3)


def test_describe_counts_workers_as_the_pool_would(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    assert workers.describe(None) == "local pool of 7 worker process(es)"
    assert workers.describe(None, 2) == "local pool of 2 worker process(es)"
    assert workers.describe(None, -3) == "local pool of 1 worker process(es)"
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert workers.describe("local") == "local pool of 1 worker process(es)"


class _FakeExecutor(cf.Executor):
    def __init__(self):
        self.inner = InlineExecutor()

    def submit(self, fn, /, *args, **kwargs):
        return self.inner.submit(fn, *args, **kwargs)


class Client:
    """Looks like a distributed.Client (by the name and the two methods)."""

    def __init__(self):
        self.closed = False

    def get_executor(self, pure=True):
        assert pure is False
        return _FakeExecutor()

    def cancel(self, futures):
        pass

    def close(self):
        self.closed = True


def test_check_where_addresses_and_objects():
    for good in (None, "local", "tcp://host:8786", "tls://10.0.0.1:1", "ws://h", "tcp://[::1]:65535", "tcp://h:1/",
                 Client(), cf.ThreadPoolExecutor(1), SimpleNamespace(submit=lambda *a: None)):
        workers.check_where(good)
    for bad in ("x://y", "tcp://", "tcp://h:0", "tcp://h:65536", "tcp://[::1", "tcp://h:1/path", "tcp://h:",
                "tcp://u@h:1", "tcp://h h:1", "tcp://1.2.3.456:1", "tcp://[zz::]:1", "tcp://h:1?q", "inproc://a/1/2",
                "tcp://" + "a" * 300, 3, "remote", cf.ThreadPoolExecutor, SimpleNamespace(submit=3)):
        with pytest.raises(InputError):
            workers.check_where(bad)
    workers.check_where(f"inproc://10.0.0.1/{os.getpid()}/3")
    for bad in (f"inproc://10.0.0.1/{os.getpid()}/x", f"inproc:///{os.getpid()}/3", f"inproc://h/{os.getpid() + 1}/3",
                f"inproc://h/{os.getpid()}/3/4", "tcp://h\x00:1", "tcp://h\u00e9\t:1"):
        with pytest.raises(InputError):
            workers.check_where(bad)
    at300 = "tcp://" + "a" * 289 + ":8786"              # 300 characters: the longest admitted
    assert len(at300) == 300
    workers.check_where(at300)
    with pytest.raises(InputError):
        workers.check_where("tcp://" + "a" * 290 + ":8786")
    for j in (1, np.int64(2)):
        workers.check_where(None, j)
    for j in (0, -1, True, np.bool_(True), 1.0, "2"):
        with pytest.raises(InputError):
            workers.check_where(None, j)


def test_client_place_uses_the_clients_executor_and_leaves_it_open():
    c = Client()
    res = workers.run_units([Unit("a", pow, (2, 3)), Unit("b", pow, (3, 2))], where=c)
    assert res == {"a": 8, "b": 9} and not c.closed


def test_address_without_distributed_is_an_input_error(monkeypatch):
    import builtins
    real = builtins.__import__

    def no_distributed(name, *a, **k):
        if name == "distributed":
            raise ImportError("no distributed")
        return real(name, *a, **k)
    monkeypatch.setattr(builtins, "__import__", no_distributed)
    with pytest.raises(InputError, match="dist extra"):
        workers.run_units([Unit("a", pow, (2, 3))], where="tcp://127.0.0.1:9")


def test_address_client_is_opened_and_closed(monkeypatch):
    import sys
    import types
    made = []

    class FakeDistClient(Client):
        def __init__(self, addr, timeout=None, set_as_default=True):
            super().__init__()
            made.append((addr, set_as_default))
    fake = types.ModuleType("distributed")
    fake.Client = FakeDistClient
    monkeypatch.setitem(sys.modules, "distributed", fake)
    assert workers.run_units([Unit("a", pow, (2, 5))], where="tcp://127.0.0.1:8786/") == {"a": 32}
    assert made == [("tcp://127.0.0.1:8786", False)]

    class Unreachable:
        def __init__(self, *a, **k):
            raise TimeoutError("timed out")
    fake.Client = Unreachable
    with pytest.raises(InputError, match="cannot reach"):
        workers.run_units([Unit("a", pow, (2, 5))], where="tcp://127.0.0.1:8786")


def test_place_cancel_renew_and_close_of_an_own_pool(monkeypatch):
    stopped, made = [], []

    class Pool:
        def __init__(self, n):
            self.n, self.shut = n, None
            made.append(self)

        def shutdown(self, wait=True):
            self.shut = wait

        def submit(self, fn, *a, **k):
            return cf.Future()
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: Pool(n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: stopped.append(ex))
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    p = workers._Place(None, 2, None)
    assert p.local_pool and made[0].n == 2
    p.renew()
    assert stopped == [made[0]] and p.executor is made[1] and made[1].n == 2
    futs = [cf.Future(), cf.Future()]
    p.cancel(futs)
    assert all(f.cancelled() for f in futs) and stopped == [made[0], made[1]] and not p.local_pool
    p.close()
    assert made[1].shut is None                 # stopped already: not shut down again
    q = workers._Place("local", 3, None)
    q.close()
    assert made[2].shut is True
    # one worker: inline, nothing to renew, stop or close
    i = workers._Place(None, 1, None)
    assert isinstance(i.executor, InlineExecutor) and not i.local_pool
    i.renew()
    i.cancel([])
    i.close()
    assert len(made) == 3 and len(stopped) == 2
    # no jobs given: one worker per CPU (7 here), renewed with as many; no CPU count: inline
    d = workers._Place(None, None, None)
    assert made[-1].n == 7 and d.local_pool
    d.renew()
    assert made[-1].n == 7 and len(made) == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert isinstance(workers._Place("local", 0, None).executor, InlineExecutor) and len(made) == 5
    # open_executor: a pool even for one worker; an exception cancels what was submitted
    with pytest.raises(RuntimeError, match="interrupted"):
        with workers.open_executor(None, 1) as ex:
            assert made[-1].n == 1
            f = ex.submit(pow, 2, 2)
            raise RuntimeError("interrupted")
    assert f.cancelled() and stopped[-1] is made[-1]


def test_stop_pool_terminates_and_tolerates_gone_processes():
    events = []

    class Proc:
        def __init__(self, i, fail):
            self.i, self.fail = i, fail

        def terminate(self):
            events.append(("term", self.i))
            if self.fail:
                raise OSError("gone")

        def join(self, timeout=None):
            events.append(("join", self.i, timeout))
            if self.fail:
                raise ValueError("closed")

    class Ex:
        _processes = {1: Proc(1, True), 2: Proc(2, False)}

        def shutdown(self, wait=True, cancel_futures=False):
            events.append(("shutdown", wait, cancel_futures))
    workers._stop_pool(Ex())
    assert events == [("shutdown", False, True), ("term", 1), ("term", 2), ("join", 1, 2), ("join", 2, 2)]

    class Ex2:
        def terminate_workers(self):
            events.append("tw")
            raise RuntimeError("already")

        def shutdown(self, **k):
            events.append("shutdown2")
    workers._stop_pool(Ex2())
    assert events[-1] == "tw"


def _fail_unit(x):
    raise ValueError(f"bad {x}")


def test_run_units_retries_lost_workers_only(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    tries = {}

    def flaky(name, n_fail):
        tries[name] = tries.get(name, 0) + 1
        if tries[name] <= n_fail:
            raise BrokenProcessPool("worker died")
        return name
    units = [Unit("ok2", flaky, ("ok2", 2)), Unit("lost3", flaky, ("lost3", 3)), Unit("err", _fail_unit, (1,))]
    res, failed = workers.run_units_partial(units, jobs=1, retries=2)
    assert res == {"ok2": "ok2"} and tries == {"ok2": 3, "lost3": 3}
    assert failed["lost3"] == "worker lost 3 times (BrokenProcessPool)" and failed["err"] == "ValueError: bad 1"
    tries.clear()
    res, failed = workers.run_units_partial([Unit("z", flaky, ("z", 1))], jobs=1, retries=0)
    assert res == {} and "worker lost 1 times" in failed["z"]
    with pytest.raises(InputError, match="retries"):
        workers.run_units([Unit("a", pow, (1, 1))], retries=-1)
    with pytest.raises(InputError, match="unique"):
        workers.run_units([Unit("a", pow, (1, 1)), Unit("a", pow, (1, 1))])
    with pytest.raises(workers.UnitsFailed) as ei:
        workers.run_units([Unit("a", pow, (2, 2)), Unit("b", _fail_unit, (2,))], jobs=1)
    assert ei.value.results == {"a": 4} and list(ei.value.failed) == ["b"]
    assert workers.run_units([Unit("a", pow, (2, 2)), Unit("b", _fail_unit, (2,))], jobs=1, raise_failed=False) == {"a": 4}
    assert workers._worker_lost(BrokenProcessPool()) and not workers._worker_lost(ValueError())
    assert workers._worker_lost(type("KilledWorker", (Exception,), {})())


def test_units_failed_message_lists_five_and_counts_the_rest():
    e = workers.UnitsFailed({f"u{i}": "x" for i in range(7)}, {"a": 1}, kept="/ck")
    msg = str(e)
    assert msg.startswith("7 work unit(s) failed (1 finished)") and "u4: x" in msg and "u5" not in msg
    assert "(and 2 more)" in msg and "kept in /ck" in msg
    e = workers.UnitsFailed({f"u{i}": "x" for i in range(5)}, {})
    assert "more" not in str(e) and "kept" not in str(e)


def test_environment_identity_names_absent_distributions(monkeypatch):
    import importlib.metadata as md
    real = md.version

    def version(name):
        if name == "numba":
            raise md.PackageNotFoundError(name)
        return real(name) if name != "gmpy2" else "9.9"
    monkeypatch.setattr(md, "version", version)
    ident = workers._environment_identity()
    assert "numba absent" in ident and "gmpy2==9.9" in ident and len(ident) == 2 + len(workers._FINGERPRINT_DISTS)


def test_source_fingerprint_covers_paths_dirs_and_config(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "a.py").write_text("x = 1\n")
    (d / "b.txt").write_text("t\n")
    p = tmp_path / "p"
    p.mkdir()
    (p / "data.csv").write_text("1,2\n")
    (p / "__pycache__").mkdir()
    (p / "__pycache__" / "c.pyc").write_bytes(b"0")
    (p / "run.partial.jsonl").write_text("{}\n")
    f = tmp_path / "single.json"
    f.write_text("{}")
    base = workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert base == workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert base != workers.source_fingerprint("cfg2", dirs=[d], paths=[p, f])
    (d / "b.txt").write_text("changed\n")            # not *.py under dirs: no change
    assert base == workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    (p / "__pycache__" / "c.pyc").write_bytes(b"1")   # caches and checkpoints: no change
    (p / "run.partial.jsonl").write_text("{\"x\": 1}\n")
    assert base == workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    (d / "a.py").write_text("x = 2\n")
    b2 = workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b2 != base
    (p / "data.csv").write_text("1,3\n")
    b3 = workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b3 != b2
    f.write_text("[]")
    b4 = workers.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b4 != b3
    f.unlink()                                         # absent is its own state
    assert workers.source_fingerprint("cfg", dirs=[d], paths=[p, f]) not in (b3, b4)
    # a renamed file changes it (the relative name is hashed, not only the contents)
    (p / "data.csv").rename(p / "data2.csv")
    assert workers.source_fingerprint("cfg", dirs=[d], paths=[p, f]) != workers.source_fingerprint(
        "cfg", dirs=[d], paths=[p])


def test_json_depth_skips_strings_and_escapes():
    assert workers._json_depth('{"a": [1, {"b": 2}]}') == 3
    assert workers._json_depth('"[[[[" ') == 0
    assert workers._json_depth('["a\\"[[[", [1]]') == 2
    assert workers._json_depth('["a\\\\", [[1]]]') == 3
    assert workers._json_depth('["unclosed [[[[') == 1
    assert workers._json_depth("") == 0 and workers._json_depth("]]") == 0


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    monkeypatch.setattr(workers, "_KEYS", {})
    return d


def test_read_key_refuses_what_is_not_a_private_key_file(tmp_path, monkeypatch):
    good = tmp_path / "k"
    good.write_bytes(b"ab" * 32 + b"\n")
    os.chmod(good, 0o600)
    assert workers._read_key(str(good)) == bytes.fromhex("ab" * 32)
    os.chmod(good, 0o640)
    assert workers._read_key(str(good)) is None
    os.chmod(good, 0o600)
    good.write_bytes(b"AB" * 32 + b"\n")
    assert workers._read_key(str(good)) is None
    good.write_bytes(b"ab" * 32 + b"\n\n")
    assert workers._read_key(str(good)) is None
    assert workers._read_key(str(tmp_path / "none")) is None

    def bad_read(fd, n):
        raise OSError("EIO")
    good.write_bytes(b"ab" * 32 + b"\n")
    monkeypatch.setattr(os, "read", bad_read)
    assert workers._read_key(str(good)) is None


def test_checkpoint_key_errors(private_cache, monkeypatch, tmp_path):
    from ldaspark.compiled import cache as cache_mod

    def no_dir():
        raise cache_mod.CacheDirectoryError("nowhere safe")
    monkeypatch.setattr(cache_mod, "cache_dir", no_dir)
    with pytest.raises(workers.CheckpointKeyError, match="nowhere safe"):
        workers.checkpoint_key()
    d = tmp_path / "keys"
    d.mkdir(mode=0o700)
    os.chmod(d, 0o700)
    key = workers.checkpoint_key(str(d))
    assert len(key) == 32 and workers.checkpoint_key(str(d)) is key
    # a key that cannot be created: a CheckpointKeyError, the temporary file removed
    d2 = tmp_path / "keys2"
    d2.mkdir()
    os.chmod(d2, 0o700)
    real_open = os.open

    def no_create(path, flags, mode=0o777):
        if str(path).startswith(str(d2)) and flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, mode)
    monkeypatch.setattr(os, "open", no_create)
    with pytest.raises(workers.CheckpointKeyError, match="cannot create"):
        workers.checkpoint_key(str(d2))
    monkeypatch.setattr(os, "open", real_open)
    # a key that never reads back as trustworthy (mode reset by someone): three tries, then an error
    d3 = tmp_path / "keys3"
    d3.mkdir()
    os.chmod(d3, 0o700)
    monkeypatch.setattr(workers, "_read_key", lambda path: None)
    with pytest.raises(workers.CheckpointKeyError, match="cannot be made trustworthy"):
        workers.checkpoint_key(str(d3))
    assert [p.name for p in d3.iterdir()] == ["checkpoint-hmac.key"]


def test_checkpoint_key_race_keeps_the_other_creators_key(tmp_path, monkeypatch):
    d = tmp_path / "keys"
    d.mkdir()
    os.chmod(d, 0o700)
    monkeypatch.setattr(workers, "_KEYS", {})
    theirs = b"cd" * 32 + b"\n"

    def racing_link(src, dst):
        fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.write(fd, theirs)
        os.close(fd)
        raise FileExistsError(17, "File exists")
    monkeypatch.setattr(os, "link", racing_link)
    assert workers.checkpoint_key(str(d)) == bytes.fromhex("cd" * 32)
    assert sorted(p.name for p in d.iterdir()) == ["checkpoint-hmac.key"]


KEY = bytes(range(32))


def _ck(path, fp="fp", **kw):
    notes = []
    kw.setdefault("key", KEY)
    return Checkpoint(path, fp, say=notes.append, **kw), notes


def test_checkpoint_mac_binds_fingerprint_name_and_value(tmp_path):
    a, _ = _ck(tmp_path / "c")
    b, _ = _ck(tmp_path / "c", fp="fp2")
    c, _ = _ck(tmp_path / "c", key=bytes(32))
    m = a._mac("u", {"x": 1})
    assert len(m) == 64 and m == a._mac("u", {"x": 1})
    assert m not in (b._mac("u", {"x": 1}), c._mac("u", {"x": 1}), a._mac("v", {"x": 1}), a._mac("u", {"x": 2}))
    assert a.bound_to(1).fingerprint != a.bound_to(2).fingerprint and a.bound_to(1).fingerprint != a.fingerprint
    assert a.bound_to(1)._key == KEY
    nokey = Checkpoint(tmp_path / "c", "fp")
    nokey._key_error = "no trusted directory"
    assert nokey._mac("u", 1) == ""


def test_checkpoint_parse_reasons(tmp_path):
    ck, _ = _ck(tmp_path / "c")
    units = {"u"}

    def line(obj):
        return (json.dumps(obj) + "\n").encode()
    good = line({"unit": "u", "value": [1, 2], "mac": ck._mac("u", [1, 2])})
    assert ck._parse(good, units) == ("u", [1, 2])
    assert ck._parse(good, None) == ("u", [1, 2])
    assert ck._parse(good[:-1], units)[1] == "truncated"
    assert ck._parse(b"\xff\xfe\n", units)[1] == "not UTF-8"
    assert ck._parse(b"[" * 70 + b"\n", units)[1].startswith("nested")
    assert ck._parse(b'{"unit": NaN}\n', units)[1].startswith("not finite JSON")
    assert ck._parse(line({"unit": "u", "value": 1}), units)[1] == "not a record {unit, value, mac}"
    assert ck._parse(line({"unit": "u", "value": 1, "mac": "XYZ"}), units)[1] == "no HMAC"
    assert ck._parse(line({"unit": "v", "value": 1, "mac": "0" * 64}), units)[1].startswith("unit 'v' is not one")
    assert ck._parse(line({"unit": 3, "value": 1, "mac": "0" * 64}), units)[1] == "the unit name is not a string"
    assert ck._parse(line({"unit": "u", "value": [1, 2], "mac": "0" * 64}), units)[1].startswith("wrong HMAC")
    nokey = Checkpoint(tmp_path / "c", "fp")
    nokey._key_error = "no key here"
    assert nokey._parse(good, units) == (None, "no key to check it (no key here)")
    # authentic, but refused by the schema (exception or False)
    ck.validate = lambda name, value: value == [9]
    assert ck._parse(good, units) == (None, "not a valid record")
    ck.validate = lambda name, value: (_ for _ in ()).throw(LdasparkError("schema says no"))
    assert ck._parse(good, units) == (None, "not a valid record: schema says no")


def test_checkpoint_why_not_bounds(tmp_path, monkeypatch):
    ck, _ = _ck(tmp_path / "c")
    assert ck._why_not("", 1, None) == "the unit name is not a string"
    assert ck._why_not("u", float("nan"), None).startswith("the value is not finite JSON")
    assert ck._why_not("u", {1j: 2}, None).startswith("the value is not finite JSON")
    monkeypatch.setattr(workers, "MAX_CHECKPOINT_LINE", 300)
    assert ck._why_not("u", "x" * 98, None) == ""                        # 100 bytes = 300 - 200
    assert "101 bytes, more than" in ck._why_not("u", "x" * 99, None)
    monkeypatch.setattr(workers, "MAX_CHECKPOINT_LINE", 8 * 2 ** 20)
    deep = [[[[1]]]]
    monkeypatch.setattr(workers, "MAX_CHECKPOINT_DEPTH", 6)
    assert ck._why_not("u", deep, None) == ""                 # depth 4 = 6 - 2
    assert ck._why_not("u", [deep], None).startswith("the value is nested")


def test_checkpoint_load_header_duplicates_and_open_failures(tmp_path, monkeypatch):
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    assert ck.load() == {}
    ck.open({"a": 1})
    ck.add("b", 2)
    ck.add("a", 99)                # a second record of a unit: the first one is kept
    ck.close()
    ck2, notes2 = _ck(p)
    assert ck2.load() == {"a": 1, "b": 2} and notes2 == []
    assert ck2.load(units=["b"]) == {"b": 2} and "2 record(s) discarded" in notes2[-1]
    # a header that is not JSON, or JSON without the fingerprint: not resumed
    text = p.read_text().splitlines(True)
    for head in ("not json\n", "[1, 2]\n", json.dumps({"fingerprint": "other"}) + "\n"):
        p.write_text(head + "".join(text[1:]))
        ck3, notes3 = _ck(p)
        assert ck3.load() == {} and "not resumed" in notes3[-1]
    # a file that cannot be opened: an InputError, the file not touched
    p.write_text("".join(text))
    real_open = os.open

    def refuse(path, flags, *a):
        if str(path) == str(p):
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, *a)
    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(InputError, match="cannot be read"):
        _ck(p)[0].load()
    monkeypatch.setattr(os, "open", real_open)
    assert p.read_text() == "".join(text)
    # not a regular file after the lstat check (a race): refused on the descriptor
    monkeypatch.setattr(Checkpoint, "_check_regular", lambda self: None)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        _ck(fifo)[0].load()


def test_checkpoint_discard_notes_at_most_two_reasons(tmp_path):
    p = tmp_path / "c.jsonl"
    ck, _ = _ck(p)
    ck.open({})
    ck.close()
    with open(p, "a") as fh:
        fh.write("x\n" * 3)
    ck2, notes = _ck(p)
    assert ck2.load() == {}
    assert notes == ["checkpoint %s: 3 record(s) discarded and their units computed again: line 2: not finite JSON "
                     "(Expecting value: line 1 column 1 (char 0)); line 3: not finite JSON (Expecting value: line 1 "
                     "column 1 (char 0)) (and 1 more)" % p]
    with open(p, "w") as fh:
        fh.write(json.dumps({"fingerprint": "fp"}) + "\n" + "x\n" * 2)
    ck3, notes3 = _ck(p)
    assert ck3.load() == {} and "more" not in notes3[-1] and "2 record(s)" in notes3[-1]


def test_checkpoint_add_notes_a_refused_unit_once(tmp_path):
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    ck.open({})
    ck.add("u", float("inf"))
    ck.add("u", float("inf"))
    ck.add("v", float("nan"))
    ck.add("w", 1)
    ck.close()
    assert len(notes) == 2 and "'u' not recorded" in notes[0] and "'v' not recorded" in notes[1]
    assert _ck(p)[0].load() == {"w": 1}
    nokey = Checkpoint(tmp_path / "d.jsonl", "fp", say=notes.append)
    nokey._key_error = "no trusted key directory"
    nokey.open({})
    nokey.add("x", 1)
    nokey.close()
    assert "no trusted key directory" in notes[-1] and len(nokey.path.read_text().splitlines()) == 1


def test_run_resumable_says_what_it_resumes(tmp_path):
    p = tmp_path / "c.jsonl"
    said, ran = [], []

    def unit(i):
        ran.append(i)
        return i * 10
    units = [Unit(f"u{i}", unit, (i,)) for i in range(3)]
    ck = Checkpoint(p, "fp", key=KEY)
    assert workers.run_resumable(units[:2], ck, jobs=1, say=said.append) == {"u0": 0, "u1": 10}
    assert said == [] and ck.say == said.append
    ran.clear()
    done = []
    ck = Checkpoint(p, "fp", key=KEY)
    out = workers.run_resumable(units, ck, jobs=1, say=said.append, on_done=lambda n, v: done.append(n))
    assert out == {"u0": 0, "u1": 10, "u2": 20} and ran == [2] and done == ["u2"]
    assert said == [f"resuming: 2 of 3 units from {p}"]
    # a checkpoint with its own say keeps it
    mine = []
    ck = Checkpoint(p, "other-fp", key=KEY, say=mine.append)
    workers.run_resumable(units[:1], ck, jobs=1, say=said.append)
    assert mine and "not resumed" in mine[0] and len(said) == 1
    # no checkpoint: no say about resuming
    assert workers.run_resumable(units[:1], None, jobs=1, say=said.append) == {"u0": 0} and len(said) == 1


# ============================== core/validate ==============================================
def test_check_executor_refuses_a_shut_down_pool_and_keeps_a_live_one():
    from ldaspark.core import validate
    live = cf.ThreadPoolExecutor(1)
    assert validate.check_executor(live) is live and validate.check_executor(None) is None
    live.shutdown()
    with pytest.raises(InputError, match="shut down"):
        validate.check_executor(live)
    flag = SimpleNamespace(submit=print, map=map, _shutdown=1)        # truthy but not True: not shut down
    assert validate.check_executor(flag) is flag
    with pytest.raises(InputError, match="shut down"):
        validate.check_executor(SimpleNamespace(submit=print, map=map, _shutdown_thread=True))
    with pytest.raises(InputError, match="submit, map"):
        validate.check_executor(SimpleNamespace(submit=print))


def test_point_takes_the_scenes_data_only_where_none_is_given():
    from ldaspark.core import validate
    calls = []
    scene = SimpleNamespace(initial=lambda dps: calls.append(dps) or (0.5, [1.0, 2.0], [3.0, 4.0]))
    sys2 = SimpleNamespace(n=2)
    assert validate.point(sys2, None, None, [7.0, 8.0], scene=scene, dps=30) == (0.5, [1.0, 2.0], [7.0, 8.0])
    assert calls == [30]
    assert validate.point(sys2, 1.0, [5.0, 6.0], None, scene=scene) == (1.0, [5.0, 6.0], [3.0, 4.0])
    assert validate.point(sys2, 2.0, [5.0, 6.0], [7.0, 8.0], scene=scene) == (2.0, [5.0, 6.0], [7.0, 8.0])
    assert len(calls) == 2                           # everything given: the scene is not asked
    with pytest.raises(InputError, match="give q0 and v0"):
        validate.point(sys2, 0.0, None, [1.0, 2.0])
    with pytest.raises(InputError, match="n = 2"):
        validate.point(sys2, 0.0, [1.0], [1.0, 2.0])


def test_step_advances_boundary_in_float64_and_digits():
    from ldaspark.core import validate
    t0 = 1e17
    need = 2 * float(np.spacing(t0 + 64))          # T = t0 + n h, h = need (the same spacing)
    validate.step_advances(t0, need, 1)
    with pytest.raises(InputError, match="does not advance"):
        validate.step_advances(t0, np.nextafter(need, 0), 1)
    with pytest.raises(InputError, match="does not advance"):
        validate.step_advances(-t0, -1.0, 1)
    validate.step_advances(0.0, 1e-300, 3)
    need30 = 2 * 1.0 * 10.0 ** (1 - 30)
    validate.step_advances(1.0, need30, 1, dps=30)
    with pytest.raises(InputError, match="30 digits"):
        validate.step_advances(1.0, need30 * 0.99, 1, dps=30)
    # n_steps enters T: the last time sets the spacing
    validate.step_advances(0.0, 1.0, 10 ** 15)
    with pytest.raises(InputError):
        validate.step_advances(0.0, 1.0, 10 ** 17)


def test_fmt_int_names_huge_integers_by_their_decimal_exponent():
    from ldaspark.core import validate
    assert validate._fmt_int(10 ** 30 - 1) == str(10 ** 30 - 1)
    assert validate._fmt_int(10 ** 30) == "about 10^30"
    assert validate._fmt_int(-(10 ** 40) + 1) == "-about 10^39"
    assert validate._fmt_int(10 ** 5000) == "about 10^5000"
    assert validate._fmt_int(2 ** 200) == "about 10^60"


# ============================== workers: pools, flags (mutant survivors) ===================
class _InlinePool(cf.Executor):
    """A stand-in for a local process pool: runs each call at once (not an InlineExecutor, so
    run_units takes the pool path: futures, as_completed, renew on a broken pool)."""

    def __init__(self, made, n):
        self.n, self.shut = n, None
        made.append(self)

    def submit(self, fn, /, *args, **kwargs):
        return InlineExecutor().submit(fn, *args, **kwargs)

    def shutdown(self, wait=True, **k):
        self.shut = wait


def test_a_local_pool_is_renewed_only_when_a_worker_died(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    made, stopped = [], []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: stopped.append(ex))
    assert workers.run_units([Unit(f"u{i}", pow, (i, 2)) for i in range(4)], jobs=3) == {
        "u0": 0, "u1": 1, "u2": 4, "u3": 9}
    assert len(made) == 1 and made[0].n == 3 and stopped == [] and made[0].shut is True
    tries = []

    def dies_once(x):
        tries.append(x)
        if len(tries) == 1:
            raise BrokenProcessPool("killed")
        return -x
    made.clear()
    assert workers.run_units([Unit("a", dies_once, (5,)), Unit("b", pow, (2, 3))], jobs=2) == {"a": -5, "b": 8}
    assert len(made) == 2 and stopped == [made[0]] and made[1].shut is True
    # a unit's own error does not renew the pool
    made.clear()
    stopped.clear()
    res, failed = workers.run_units_partial([Unit("e", _fail_unit, (3,)), Unit("b", pow, (2, 3))], jobs=2)
    assert res == {"b": 8} and list(failed) == ["e"] and len(made) == 1 and stopped == []


def test_run_units_on_a_users_executor_and_a_shut_down_one():
    with cf.ThreadPoolExecutor(2) as ex:
        assert workers.run_units([Unit("a", pow, (2, 4)), Unit("b", pow, (3, 3))], where=ex) == {"a": 16, "b": 27}
    assert workers.run_units([Unit("a", pow, (2, 4))], where=SimpleNamespace(
        submit=lambda fn, *a: InlineExecutor().submit(fn, *a))) == {"a": 16}
    with pytest.raises(InputError, match="refused new work"):
        workers.run_units([Unit("a", pow, (2, 4))], where=ex)


@pytest.mark.parametrize("flag", ["O_NOFOLLOW", "O_NONBLOCK", "O_CLOEXEC"])
def test_open_flags_missing_on_a_platform_are_left_out(tmp_path, monkeypatch, flag):
    """Where os lacks a flag, the reader opens without it (read-only still: never O_WRONLY)."""
    good = tmp_path / "k"
    good.write_bytes(b"ab" * 32 + b"\n")
    os.chmod(good, 0o600)
    p = tmp_path / "c.jsonl"
    ck, _ = _ck(p)
    ck.open({"a": [1]})
    ck.close()
    monkeypatch.delattr(os, flag)
    assert workers._read_key(str(good)) == bytes.fromhex("ab" * 32)
    assert _ck(p)[0].load() == {"a": [1]}
    d = tmp_path / "keys"
    d.mkdir()
    os.chmod(d, 0o700)
    monkeypatch.setattr(workers, "_KEYS", {})
    key = workers.checkpoint_key(str(d))
    assert len(key) == 32 and stat.S_IMODE(os.lstat(d / "checkpoint-hmac.key").st_mode) == 0o600


# ============================== ledger: per-tableau pieces =================================
def test_exact_condition_records_rule(monkeypatch):
    truth = {"22a": True, "22b": False, "23": True}
    monkeypatch.setattr(ledger, "check_22a", lambda tab: truth["22a"])
    monkeypatch.setattr(ledger, "check_22b", lambda tab: truth["22b"])
    monkeypatch.setattr(ledger, "check_23", lambda tab: truth["23"])
    out = ledger.exact_condition_records(_tab("t"), {"22a": "pass", "22b": "pass", "23": "fail"})
    assert [(r["claim"], r["status"], r["residual"], r["expected"], r["scene"]) for r in out] == [
        ("22a", "pass", 0.0, "pass", "-"), ("22b", "fail", 1.0, "pass", "-"), ("23", "pass", 0.0, "fail", "-")]


def test_proof_conditions_of_the_controls():
    g2 = ledger.get_method("gauss-2", exact=True)
    assert ledger.proof_conditions(g2) == (True, True)
    (ah, _), (ah2, _), (bh, _) = ledger.negative_controls()
    assert ledger.proof_conditions(ah) == (False, False)
    assert ledger.proof_conditions(bh) == (True, False)        # q0 needs no b_hat
    assert [t.name for t, _ in ledger.negative_controls()] == [
        "negctl-gauss-2+dA_hat[0,1]", "negctl-lobatto-iiia-iiib-3+dA_hat[1,0]", "negctl-gauss-2+db_hat[0]"]


def test_ledger_tabs_and_task(monkeypatch):
    names = [t.name for t, _ in ledger._ledger_tabs(2, False)]
    assert names == ["gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-2", "euler-i", "euler-ii"]
    with_ctl = ledger._ledger_tabs(2, True)
    assert [t.name for t, _ in with_ctl[:6]] == names and len(with_ctl) == 9
    assert with_ctl[0][1] is None and with_ctl[-1][1] == {"22a": "fail", "22b": "fail"}
    # the ledger's tableaux are exact (sympy entries): the exact conditions need them
    assert all(t.is_exact for t, _ in with_ctl)
    tabs = [(_tab("A"), None), (_tab("B"), {"c": 1})]
    built = []
    monkeypatch.setattr(ledger, "_ledger_tabs", lambda max_s, controls: built.append((max_s, controls)) or tabs)
    monkeypatch.setattr(ledger, "_WORKER_TABS", {})
    monkeypatch.setattr(ledger, "_tab_records", lambda tab, control, holo: [("tab", tab.name, control, holo)])
    monkeypatch.setattr(ledger, "_scene_records", lambda tab, control, scn, pert: [("scn", tab.name, scn, pert)])
    assert ledger._ledger_task(3, True, False, True, 1, None) == [("tab", "B", {"c": 1}, False)]
    assert ledger._ledger_task(3, True, False, True, 0, "robot") == [("scn", "A", "robot", True)]
    assert built == [(3, True)]                      # built once per (max_s, controls) in a worker
    ledger._ledger_task(2, True, False, True, 0, "robot")
    assert built == [(3, True), (2, True)]


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
    monkeypatch.setattr(cg, "_constraint_record", lambda s, tab: ("con", tab.name))
    out = cg._scene_checks("turntable", True)
    assert out == [("t1", "gauss-2", "pass", "t0"), ("t1", "lobatto-iiia-iiib-3", "pass", "t0"),
                   ("t1", "negctl-gauss-2+dA_hat[0,1]", "fail", "t0"), ("sym", "gauss-2", "pass"),
                   ("sym", "euler-i", "fail"), ("con", "gauss-2"), ("con", "lobatto-iiia-iiib-iiid-3")]
    assert [x[1] for x in cg._scene_checks("turntable", False)[:3]] == [
        "gauss-2", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-2"]


# ============================== messages cut to a bound (mutant survivors) =================
def test_messages_quote_at_most_their_bound():
    with pytest.raises(InputError) as ei:
        workers.check_where(None, "j" * 100)
    assert str(ei.value) == "jobs must be a positive integer, got '" + "j" * 60 + "'"
    ck, _ = _ck("/nonexistent/c.jsonl")
    ck.validate = lambda name, value: (_ for _ in ()).throw(LdasparkError("w" * 150))
    assert ck._why_not("u", 1, None) == "not a valid record: " + "w" * 100
    ck.validate = lambda name, value: (_ for _ in ()).throw(ValueError())
    assert ck._why_not("u", 1, None) == "not a valid record: ValueError"
    assert ck._why_not("u" * 100, 1, {"v"}) == f"unit {'u' * 60!r} is not one of this run's"


def test_renew_without_a_cpu_count_makes_one_worker(monkeypatch):
    made = []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: None)
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    p = workers._Place(None, None, None)
    assert made[-1].n == 7
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    p.renew()
    assert made[-1].n == 1 and len(made) == 2
    p = workers._Place(None, 3, None)
    p.renew()
    assert made[-1].n == 3 and len(made) == 4


# ============================== claims_paper: section 7 rules ==============================
def test_paper_status_rule_both_expectations():
    T, N = 1e-20, cp.NEG
    assert cp._st(T, T) == "pass" and cp._st(T * 1.01, T) == "fail" and cp._st(None, T) == "fail"
    assert cp._st(N, T, "fail") == "fail" and cp._st(N * 0.99, T, "fail") == "pass"
    assert cp._st(None, T, "fail") == "pass" and cp._st(2 * N, T, "fail") == "fail"


def test_section7_records_rules_and_arguments(monkeypatch):
    red_calls, newton_calls = [], []
    T, N = cp.TOL_S7, cp.NEG

    def reduction(kind, tab, constant_K=True):
        red_calls.append((kind, tab.name, constant_K))
        assert tab.is_exact                     # the reductions are checked in exact arithmetic
        # expected-pass cases: diff tiny, stage statement just above TOL (max catches it for euler-ii);
        # expected-fail cases: diff large, stage tiny (only diff counts)
        if tab.name == "euler-ii" and kind == "euler-ii":
            return {"diff": 0.0, "stage": 2 * T}
        if tab.name in ("euler-i", "gauss-1") and kind in ("euler-i", "midpoint"):
            return {"diff": T, "stage": T / 2}
        return {"diff": 2 * N, "stage": 0.0}

    def newton(tab, ck, guess):
        newton_calls.append((tab.name, ck, guess))
        assert tab.is_exact
        return {"after_one": {True: T / 2, False: 2 * T}[ck] if tab.name == "euler-i" and guess == "generic" and ck
                else (0.0 if tab.name == "euler-ii" else N)}
    monkeypatch.setattr(cp, "reduction", reduction)
    monkeypatch.setattr(cp, "one_newton_iteration", newton)
    out = cp.section7_records(True)
    assert red_calls == [("euler-i", "euler-i", False), ("euler-ii", "euler-ii", False), ("midpoint", "gauss-1", False),
                         ("euler-ii", "euler-i", False), ("midpoint", "lobatto-iiia-iiib-2", False)]
    assert newton_calls == [("euler-i", True, "generic"), ("euler-ii", False, "default"), ("euler-i", False, "generic")]
    assert [(r["claim"], r["method"], r["status"], r["expected"]) for r in out] == [
        ("euler-i-reduction", "euler-i", "pass", "pass"), ("euler-ii-reduction", "euler-ii", "fail", "pass"),
        ("midpoint-7.3", "gauss-1", "pass", "pass"), ("euler-ii-reduction", "euler-i", "fail", "fail"),
        ("midpoint-7.3", "lobatto-iiia-iiib-2", "fail", "fail"), ("linearly-implicit-7", "euler-i", "pass", "pass"),
        ("linearly-implicit-7", "euler-ii", "pass", "pass"), ("linearly-implicit-7", "euler-i", "fail", "fail")]
    assert [r["residual"] for r in out[:5]] == [T, 2 * T, T, 2 * N, 2 * N]
    assert all(r["dps"] == 40 for r in out) and [r["threshold"] for r in out] == [T, T, T, N, N, T, T, N]
    assert [r["scene"] for r in out[5:]] == ["affine-const-K", "affine-K(q)", "affine-K(q)"]


# ============================== defaults and bounds fixed at import =========================
def test_default_retries_are_two(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    made = []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: None)
    tries = {}

    def dies(name, n_fail):
        tries[name] = tries.get(name, 0) + 1
        if tries[name] <= n_fail:
            raise BrokenProcessPool("killed")
        return tries[name]
    assert workers.run_units([Unit("two", dies, ("two", 2))], jobs=2) == {"two": 3}
    with pytest.raises(workers.UnitsFailed, match="worker lost 3 times"):
        workers.run_units([Unit("three", dies, ("three", 3))], jobs=2)
    res, failed = workers.run_units_partial([Unit("p2", dies, ("p2", 2)), Unit("p3", dies, ("p3", 3))], jobs=2)
    assert res == {"p2": 3} and list(failed) == ["p3"]


def test_units_are_frozen():
    import dataclasses
    u = Unit("a", pow, (1, 2))
    with pytest.raises(dataclasses.FrozenInstanceError):
        u.name = "b"
    assert hash(u) == hash(Unit("a", pow, (1, 2)))


def test_checkpoint_line_bound_is_eight_mebibytes(tmp_path):
    """A unit of ~8.4 MB (past 8 MiB) is not recorded; one of ~2 MB is, and is resumed."""
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    ck.open({})
    ck.add("big", "x" * (8 * 2 ** 20 - 150))
    ck.add("ok", "y" * (2 * 2 ** 20))
    ck.close()
    assert len(notes) == 1 and "'big' not recorded" in notes[0]
    assert _ck(p)[0].load() == {"ok": "y" * (2 * 2 ** 20)}


def test_why_not_quotes_the_json_error_up_to_sixty_characters(tmp_path):
    ck, _ = _ck(tmp_path / "c")
    long_name = type("AVeryLongClassNameThatMakesTheJsonErrorMessageLongerThanSixtyCharacters", (), {})
    for value in (float("nan"), long_name()):
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            msg = str(exc)
        assert ck._why_not("u", value, None) == f"the value is not finite JSON ({msg[:60]})"
    assert len(msg) > 60


def test_parse_depth_bound_of_the_line_and_of_the_value(tmp_path, monkeypatch):
    """A line nested exactly MAX_CHECKPOINT_DEPTH deep passes the reader's bound (the record's value,
    one level less, then meets the writer's bound); one level more is refused unparsed."""
    monkeypatch.setattr(workers, "MAX_CHECKPOINT_DEPTH", 6)
    ck, _ = _ck(tmp_path / "c")

    def line(value):
        return (json.dumps({"unit": "u", "value": value, "mac": ck._mac("u", value)}) + "\n").encode()
    assert ck._parse(line([[[[1]]]]), {"u"}) == ("u", [[[[1]]]])                  # line depth 5
    assert ck._parse(line([[[[[1]]]]]), {"u"}) == (None, "the value is nested more deeply than the reader's bound")
    assert ck._parse(line([[[[[[1]]]]]]), {"u"}) == (None, "nested more deeply than the reader's bound")
