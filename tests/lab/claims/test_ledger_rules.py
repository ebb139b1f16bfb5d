"""Rules of ``ldaspark.lab.claims.ledger`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import os
from types import SimpleNamespace
import mpmath
import pytest
from ldaspark.lab.claims import ledger
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.core.errors import InputError
import types
import numpy as np
# --- lab/claims/ledger.py ---------------------------------------------------------------------------
from ldaspark.lab.claims import ledger as LG  # noqa: E402
from system_fakes import _binding, no_client  # noqa: F401 (pytest fixtures)


def _tab(name="tab-x"):
    return SimpleNamespace(name=name)


def _scene(name="scene-x", L_q=(0, 0)):
    return SimpleNamespace(name=name, system=SimpleNamespace(L_q=list(L_q)))


def _ledger_t1(q0, q1, mu=0.0, wellposed="well-posed", fd_error=1e-40):
    return {"theorem1-q0": q0, "theorem1-q1": q1, "fd_error": fd_error, "f_d_minus_norm": 1.0, "without_forces_q0": 1.0,
            "sigma_min_nonzero": 1e-3, "sigma_max": 1.0, "rank_deficiency": 0, "mu_norm": mu, "wellposed": wellposed,
            "seconds": 4.0, "dps_fd": 60}


def _classification(cls, rank):
    return {"class": cls, "sigma_min_nonzero_rel": 1e-3, "rank_deficiency": rank, "floor_tracks_precision": True,
            "sigma_min_power_of_h": 1.0, "sigma_stable_across_dps": True,
            "null_support": {"V": 1.0, "Lambda": 0.0, "v0": 0.0}}


def _sym(ld=0.0, plus=0.0, minus=0.0, phi=0.0, wellposed="well-posed", nplus=(1.0, 0.0), nminus=(0.0, 1.0)):
    return {"symmetry-Ld": ld, "symmetry-fd-plus": plus, "symmetry-fd-minus": minus, "symmetry-Phi": phi,
            "wellposed": wellposed, "seconds": 8.0, "tangent_dim": 1, "fd_restricted_norm": (1.0, 2.0),
            "symmetry-fd-unrestricted": (3e-3, 4e-3), "fd_plus_identity_norms": list(nplus),
            "fd_minus_identity_norms": list(nminus)}


def _holo(tang, p, full=(1.0, 0.5, 0.25), pf=1.0):
    return {"h": [0.1, 0.05, 0.025], "tangential": list(tang), "full": list(full), "p_tangential": p,
            "p_full": pf, "wellposed": "well-posed"}


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


def test_ledger_theorem1_records_rules_and_notes(monkeypatch):
    res = {}
    monkeypatch.setattr(ledger, "theorem1_residuals", lambda *a, **k: res["r"])
    # the derived bound of these results: 10 x 1e-40 + 1e3 x 1e3 x 1e-60 = 1e-39 (below the 1e-20 cap)
    T, N = ledger.theorem1_threshold(_ledger_t1(0.0, 0.0)), ledger.TOL_NEGATIVE
    assert T == pytest.approx(1e-39, rel=1e-12)
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
    # singular: the implicit function fails; the gauge check is a negative control there (the null
    # vector moves V, L_d is not a function of the endpoints): expected fail, fails when a move >= 1e-6
    c["c"] = _classification(ledger.SINGULAR, 2)
    g["g"] = {"dL_d": 0.0, "d(p0+f_d_minus)": 0.0, "d(p1-f_d_plus)": 0.0, "dp0": 1.0, "dV": 1.0}
    out, cls = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base")
    assert [(r["status"], r["expected"]) for r in out] == [("fail", "pass"), ("pass", "fail")]
    assert cls == ledger.SINGULAR
    for moves, st in (((ledger.TOL_NEGATIVE, 0.0, 0.0), "fail"), ((0.0, 0.0, 2e-6), "fail"),
                      ((0.0, ledger.TOL_NEGATIVE / 2, 0.0), "pass")):
        g["g"] = {"dL_d": moves[0], "d(p0+f_d_minus)": moves[1], "d(p1-f_d_plus)": moves[2], "dp0": 1.0, "dV": 1.0}
        out, _ = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base")
        assert (out[1]["status"], out[1]["expected"], out[1]["threshold"]) == (st, "fail", ledger.TOL_NEGATIVE)
    # the implicit-function control: its expectation is passed through, the gauge check left out
    out, _ = ledger.wellposed_records(_scene(), _tab(), 0, [0], [0], "base", expected="fail", gauge=False)
    assert [(r["claim"], r["status"], r["expected"]) for r in out] == [("implicit-function", "fail", "fail")]
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
        ("implicit-function", "fail", "singular")]


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
    monkeypatch.setattr(ledger, "_scene_records", lambda tab, control, scn, pert, scene_controls=False: [
        ("scn", tab.name, scn, pert, scene_controls)])
    assert ledger._ledger_task(3, True, False, True, 1, None) == [("tab", "B", {"c": 1}, False)]
    assert ledger._ledger_task(3, True, False, True, 0, "robot") == [("scn", "A", "robot", True, False)]
    # the first negative control's scene units carry the per-scene controls, no other unit does
    assert ledger._ledger_task(3, True, False, True, 1, "robot") == [("scn", "B", "robot", True, True)]
    assert built == [(3, True)]                      # built once per (max_s, controls) in a worker
    ledger._ledger_task(2, True, False, True, 0, "robot")
    assert built == [(3, True), (2, True)]


def test_ledger_refuses_a_malformed_address_before_work(no_client, monkeypatch):
    from ldaspark.lab.claims import ledger
    built = []
    monkeypatch.setattr(ledger, "_ledger_tabs", lambda *a: built.append(a) or [])
    with pytest.raises(InputError, match="malformed"):
        ledger.run_ledger(where="tcp://")
    assert built == [] and no_client == []      # refused before the tableaux are built


def _symmetry_result(minus, plus):
    return {"seconds": 0.4, "symmetry-Ld": 1e-40, "wellposed": LG.WELLPOSED, "tangent_dim": (1, 1),
            "fd_restricted_norm": (1.0, 1.0), "symmetry-fd-unrestricted": (0.0, 0.0),
            "symmetry-fd-plus": 1e-40, "symmetry-fd-minus": 1e-40, "symmetry-Phi": 1e-40,
            "fd_plus_identity_norms": plus, "fd_minus_identity_norms": minus}


def test_symmetry_fd_record_is_vacuous_only_when_every_restricted_force_vanishes(monkeypatch):
    scene = types.SimpleNamespace(name="s", system=None)
    tab = types.SimpleNamespace(name="m")
    monkeypatch.setattr(LG, "check_symmetry", lambda *a, **k: _symmetry_result([0.0, 0.5], [0.0, 0.0]))
    recs = {r["claim"]: r for r in LG.symmetry_records(scene, tab, "pass", 0, [0], [0], "base", None)}
    assert recs["symmetry-fd-minus"]["status"] == "pass"
    assert recs["symmetry-fd-plus"]["status"] == "not-applicable"
    assert recs["symmetry-fd-plus"]["note"].startswith("vacuous")


def test_constraint_residuals_are_the_largest_over_the_steps(monkeypatch):
    n = 3
    ks = [0.0, 2e-3, 1e-3, 5e-4]                       # k(t_i) per step

    def fake_integrate(system, tab, t0, q0, v0, h, n_steps, dps, newton):
        assert n_steps == n
        q = [np.array([0.1 * i]) for i in range(n + 1)]
        return types.SimpleNamespace(t=[0.1 * i for i in range(n + 1)], q=q,
                                     v=[np.array([0.0])] * (n + 1), constraint=[np.array([k]) for k in ks])

    # the secant velocity's constraint: 3, 7, 5 at steps 1..3
    system = types.SimpleNamespace(constraint=lambda bk, t, q, v: np.array([[0, 3.0, 7.0, 5.0][round(t * 10)]]))
    scene = types.SimpleNamespace(system=system)
    monkeypatch.setattr(LG, "perturbed_initial", lambda sc, dps: (0, [0.0], [0.0]))
    monkeypatch.setattr(LG, "integrate", fake_integrate)
    k, sec, eps = LG.constraint_residuals(scene, None, n_steps=n, dps=None)
    assert k == pytest.approx(2e-3)
    assert sec == pytest.approx(7.0)


def test_holonomic_order_takes_the_larger_of_the_two_covectors(monkeypatch):
    # the pendulum's constraint |q| = 1 at q = (1, 0): tangent variations are along (0, 1)
    def fake_lagrangian(S, tab, t0, q0, t1, q1, dps, x_guess):
        h = float(t1)
        return types.SimpleNamespace(wellposed=LG.WELLPOSED,
                                     f_d_minus=np.array([mpmath.mpf(5 * h), mpmath.mpf(h ** 3)], dtype=object),
                                     f_d_plus=np.array([mpmath.mpf(h), mpmath.mpf(2 * h ** 3)], dtype=object))

    monkeypatch.setattr(LG, "base_point", lambda S, tab, t0, q0, v0, h, dps: (mpmath.mpf(h), list(q0), None))
    monkeypatch.setattr(LG, "discrete_lagrangian", fake_lagrangian)
    out = LG.holonomic_order(None, hs=("0.1", "0.05"), dps=30)
    assert out["tangential"] == pytest.approx([2e-3, 2 * 0.05 ** 3])
    assert out["full"] == pytest.approx([0.5, 0.25])
    assert out["p_tangential"] == pytest.approx(3.0)


def test_holonomic_forces_that_grow_out_of_zero_do_not_decay(monkeypatch):
    """Tangential forces 0 at h = 0.1 and 1e-10 at h = 0.05 grew: no decay, the 5.1 record fails
    (the rate was +inf from the zero at the coarser h, and the record passed); the unprojected
    covector, 0 then 0.05, gives a rate of -inf (it raised ValueError from log(0))."""
    def fake_lagrangian(S, tab, t0, q0, t1, q1, dps, x_guess):
        h = float(t1)
        f = ([mpmath.mpf(0), mpmath.mpf(0)] if h > 0.075 else [mpmath.mpf(h), mpmath.mpf("1e-10")])
        return types.SimpleNamespace(wellposed=LG.WELLPOSED, f_d_minus=np.array(f, dtype=object),
                                     f_d_plus=np.array(f, dtype=object))

    monkeypatch.setattr(LG, "base_point", lambda S, tab, t0, q0, v0, h, dps: (mpmath.mpf(h), list(q0), None))
    monkeypatch.setattr(LG, "discrete_lagrangian", fake_lagrangian)
    out = LG.holonomic_order(None, hs=("0.1", "0.05"), dps=30)
    assert out["tangential"] == pytest.approx([0.0, 1e-10]) and out["full"] == pytest.approx([0.0, 0.05])
    assert out["p_tangential"] == -float("inf") and out["p_full"] == -float("inf")
    monkeypatch.setattr(LG, "holonomic_order", lambda tab: out)
    recs = LG.holonomic_records(_tab(), "pass")
    assert [r["status"] for r in recs] == ["fail", "fail"], recs


def test_a_bad_number_names_its_bound_only_when_there_is_one():
    import pytest

    from ldaspark.lab.claims import ledger
    with pytest.raises(ledger.LdasparkError, match=r"not a finite number >= 0$"):
        ledger._number_or_none(-1.0, "seconds", low=0)
    with pytest.raises(ledger.LdasparkError, match=r"not a finite number$"):
        ledger._number_or_none(float("nan"), "residual")
    assert ledger._number_or_none(None, "x") is None and ledger._number_or_none(0.0, "x", low=0) is None


def test_a_wellposedness_record_takes_the_time_of_its_classification(monkeypatch):
    import types

    from ldaspark.lab.claims import ledger
    clock = iter([100.0, 103.5, 200.0, 200.0])
    monkeypatch.setattr(ledger.time, "time", lambda: next(clock))
    c = {"class": ledger.WELLPOSED, "sigma_min_nonzero_rel": 0.1, "rank_deficiency": 0, "floor_tracks_precision": False,
         "sigma_min_power_of_h": 1.0, "sigma_stable_across_dps": True, "null_support": {"V": 0, "Lambda": 0, "v0": 0}}
    monkeypatch.setattr(ledger, "classify_wellposedness", lambda *a, **k: c)
    recs, cls = ledger.wellposed_records(types.SimpleNamespace(system=None, name="sc"), types.SimpleNamespace(name="t"),
                                         0, [0], [0], "base")
    assert cls == ledger.WELLPOSED and recs[0]["seconds"] == 3.5 and recs[0]["status"] == "pass"


# --- fingerprints: every component of a run's identity ---------------------------------------------------


def _fake_section5_all(monkeypatch):
    from ldaspark.lab.claims import claims_paper as cp
    ident = {k: 1e-30 for k in ("16", "18", "17", "19", "20b-corrected")}
    ident.update({"16-without-force": 1e-3, "18-without-force": 1e-3, "20b-printed": 1e-3, "f_d_minus": 1.0,
                  "k0": 0.0, "17-other-inner": 1e-3, "19-other-inner": 1e-3})
    clock = iter(range(0, 10 ** 6, 7))
    monkeypatch.setattr(cp.time, "time", lambda: float(next(clock)))      # every timed call "takes" 7 s
    monkeypatch.setattr(cp, "exact_identities", lambda scn, **k: dict(ident))
    monkeypatch.setattr(cp, "antisymmetry", lambda scn, **k: {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30,
                                                                "wrong-pairing": 1.0})
    monkeypatch.setattr(cp, "holonomic_exact",
                        lambda scn, **k: {"tangential": 1e-30 if scn == "pendulum" else 1e-3, "full": 1.0})
    return cp.section5_records(quick=True)


# --- the ledger's proof conditions: every entry, both sides ------------------------------------------------
def test_the_proof_conditions_need_every_entry():
    """q0 and q1 of the proof of Theorem 1 hold when every (i, j) entry vanishes: on gauss-2 with one
    entry of A_hat (resp. b_hat) moved, some entries vanish and others do not (all, not any);
    moving b_hat changes q1 only (its own side of the pair)."""
    from ldaspark.lab.claims.ledger import proof_conditions
    from ldaspark.core.families import get_method
    tab = get_method("gauss-2", exact=True)

    def zeros(t):
        K, e = t.field_entries()
        b, bh, A, Ah = e["b"], e["b_hat"], e["A"], e["A_hat"]
        rng = range(t.s)
        return ([b[j] * A[j][i] + b[i] * Ah[i][j] - b[j] * b[i] == K.zero for i in rng for j in rng],
                [b[j] * A[j][i] + b[i] * Ah[i][j] - bh[j] * b[i] == K.zero for i in rng for j in rng])
    assert proof_conditions(tab) == (True, True)
    t_ah = tab.with_entry("A_hat", 0, 1, "1/10")
    z0, z1 = zeros(t_ah)
    assert any(z0) and not all(z0) and any(z1) and not all(z1)        # the input separates all from any
    assert proof_conditions(t_ah) == (False, False)
    t_bh = tab.with_entry("b_hat", 1, None, "1/10")
    z0, z1 = zeros(t_bh)
    assert all(z0) and any(z1) and not all(z1)
    assert proof_conditions(t_bh) == (True, False)


def test_the_ledger_binds_every_setting_that_changes_its_records(monkeypatch):
    from ldaspark.lab.claims import ledger
    base = dict(max_s=1, scenes=("particle",), perturbed=False, holonomic=False, controls=False, groups=(),
                quick=False, jobs=1)
    other = dict(max_s=2, scenes=("skate",), perturbed=True, holonomic=True, controls=True,
                 groups=("ldaspark.lab.claims.claims_general:records",), quick=True)
    fp0 = _binding(monkeypatch, lambda ck: ledger.run_ledger(**base, checkpoint=ck))
    assert fp0 == _binding(monkeypatch, lambda ck: ledger.run_ledger(**base, checkpoint=ck))
    for k, v in other.items():
        fp = _binding(monkeypatch, lambda ck: ledger.run_ledger(**dict(base, **{k: v}), checkpoint=ck))
        assert fp != fp0, k


def test_section5_control_records_carry_no_time_of_their_own(monkeypatch):
    """A control is computed with its identity (same call): its time is in the identity's record."""
    from ldaspark.lab.claims.ledger import check_unit_records
    recs = _fake_section5_all(monkeypatch)
    check_unit_records("section-5", recs)
    ctl = [r for r in recs if "control" in r["method"] or "printed" in r["method"]]
    assert ctl and all(r["seconds"] == 0 for r in ctl)


def test_ledger_jobs_floor_at_one_and_follow_the_environment(monkeypatch):
    from ldaspark.lab.claims.ledger import ledger_jobs
    assert ledger_jobs(3) == 3 and ledger_jobs(0) == 1
    monkeypatch.setenv("LDASPARK_JOBS", "0")
    assert ledger_jobs() == 1
    monkeypatch.setenv("LDASPARK_JOBS", "5")
    assert ledger_jobs() == 5


def test_theorem1_threshold_follows_the_working_digits(monkeypatch):
    """The cap of the pass threshold is half the working digits (``ledger.theorem1_tolerance``):
    1e-20 at the ledger's 40 digits, 1e-15 at 30; where the derived bound is larger (an FD error
    estimate of 1e-14: bound 1e-13) a residual of 1e-17 passes at 30 digits and fails at 40 (a
    fixed 1e-20 failed every correct claim checked at 30 digits). Where the bound is smaller it
    decides (``test_ledger_theorem1_records_rules_and_notes``)."""
    assert ledger.theorem1_tolerance(ledger.DPS) == ledger.TOL_THEOREM1 == 1e-20
    assert ledger.theorem1_tolerance(30) == 1e-15
    monkeypatch.setattr(ledger, "theorem1_residuals", lambda *a, **k: _ledger_t1(1e-17, 1e-17, fd_error=1e-14))
    exp = {"theorem1-q0": "pass", "theorem1-q1": "pass"}
    at30, _ = ledger.theorem1_records(_scene(), _tab(), exp, "base", 0, [0], [0], dps=30)
    at40, _ = ledger.theorem1_records(_scene(), _tab(), exp, "base", 0, [0], [0])
    assert [x["status"] for x in at30] == ["pass", "pass"] and at30[0]["threshold"] == 1e-15
    assert [x["status"] for x in at40] == ["fail", "fail"] and at40[0]["threshold"] == 1e-20
