"""Rules of ``ldaspark.lab.claims.claims_paper`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from ldaspark.lab.claims import claims_paper as cp
import pytest
import mpmath


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
                         ("euler-i", "euler-ii", False), ("euler-ii", "euler-i", False),
                         ("midpoint", "lobatto-iiia-iiib-2", False)]
    assert newton_calls == [("euler-i", True, "generic"), ("euler-ii", False, "default"), ("euler-i", False, "generic")]
    assert [(r["claim"], r["method"], r["status"], r["expected"]) for r in out] == [
        ("euler-i-reduction", "euler-i", "pass", "pass"), ("euler-ii-reduction", "euler-ii", "fail", "pass"),
        ("midpoint-7.3", "gauss-1", "pass", "pass"), ("euler-i-reduction", "euler-ii", "fail", "fail"),
        ("euler-ii-reduction", "euler-i", "fail", "fail"),
        ("midpoint-7.3", "lobatto-iiia-iiib-2", "fail", "fail"), ("linearly-implicit-7", "euler-i", "pass", "pass"),
        ("linearly-implicit-7", "euler-ii", "pass", "pass"), ("linearly-implicit-7", "euler-i", "fail", "fail")]
    assert [r["residual"] for r in out[:6]] == [T, 2 * T, T, 2 * N, 2 * N, 2 * N]
    assert all(r["dps"] == 40 for r in out) and [r["threshold"] for r in out] == [T, T, T, N, N, N, T, T, N]
    assert [r["scene"] for r in out[6:]] == ["affine-const-K", "affine-K(q)", "affine-K(q)"]


def test_the_section_5_and_7_records_report_the_precision_their_computations_ran_at(monkeypatch):
    """The ledger's records of sections 5 and 7 state their working precision (32 and 40 digits);
    the computations take it from their modules' defaults: the two agree."""
    import inspect

    from ldaspark.lab.claims import claims_paper as cp
    from ldaspark.lab.theory import section5 as S5
    from ldaspark.lab.theory import section7 as S7
    ran = {}

    def spy(name, fn, result):
        def f(*a, **k):
            ran[name] = k.get("dps", inspect.signature(fn).parameters["dps"].default)
            return result
        return f
    r5 = {k: 0.0 for k in ("16", "18", "16-without-force", "18-without-force", "17", "19", "20b-printed",
                           "20b-corrected", "f_d_minus", "k0", "17-other-inner", "19-other-inner")}
    monkeypatch.setattr(cp, "exact_identities", spy("s5", S5.exact_identities, r5))
    monkeypatch.setattr(cp, "reduction", spy("s7", S7.reduction, {"diff": 0.0, "stage": 0.0}))
    monkeypatch.setattr(cp, "one_newton_iteration", spy("s7n", S7.one_newton_iteration, {"after_one": 0.0}))
    recs5 = [r for r in cp.section5_records(True) if r["claim"] in ("16", "18", "17-integral")]
    recs7 = cp.section7_records(True)
    assert recs5 and {r["dps"] for r in recs5} == {ran["s5"]} == {32}
    assert recs7 and {r["dps"] for r in recs7} == {ran["s7"]} == {ran["s7n"]} == {40}


def test_the_section_5_records_split_the_time_of_a_four_claim_run_and_state_32_digits(monkeypatch):
    import collections

    from ldaspark.lab.claims import claims_paper as cp
    stub = lambda *a, **k: collections.defaultdict(float)  # noqa: E731
    for name in ("exact_identities", "exact_del", "antisymmetry", "holonomic_exact"):
        monkeypatch.setattr(cp, name, stub)
    monkeypatch.setattr(cp, "_timed", lambda fn, *a, **k: (fn(*a, **k), 8.0))
    recs = cp.section5_records(False)
    four = [r for r in recs if r["claim"] in ("16", "18", "17-integral", "19-integral") and "control" not in r["method"]]
    assert four and {r["seconds"] for r in four} == {2.0}          # one run timed, four claims
    exact = [r for r in recs if r["method"].startswith("exact-flow")]
    assert any(r["claim"] == "20-integral" for r in exact) and {r["dps"] for r in exact} == {32}


def test_the_full_variational_records_take_the_first_negative_control(monkeypatch):
    from ldaspark.lab.claims import claims_paper as cp
    from ldaspark.lab.claims.ledger import negative_controls
    r = {"orders": {"L_d": 3.0, "f_minus": 2.0, "f_minus_tangential": 2.0}, "predicted_local_order": 3,
         "global_order": 2, "h": "0.1"}
    monkeypatch.setattr(cp, "_timed", lambda fn, *a, **k: (r, 1.0))
    monkeypatch.setattr(cp, "predicted_local_order", lambda tab: 5)
    recs = cp.variational_records(False)
    controls = [x for x in recs if x["method"].startswith("negctl")]
    assert [x["method"] for x in controls] == [negative_controls()[0][0].name]
    assert controls[0]["expected"] == "fail" and controls[0]["status"] == "fail"      # 3 vs the prediction 5


# --- the ledger's anti-symmetry record -------------------------------------------------------------
def _fake_section5(monkeypatch, anti):
    """section5_records on constructed results: every identity holds (1e-30) and every control
    fails (1e-3), except the anti-symmetry results ``anti(scene)``."""
    from ldaspark.lab.claims import claims_paper as cp
    ident = {k: 1e-30 for k in ("16", "18", "17", "19", "20b-corrected")}
    ident.update({"16-without-force": 1e-3, "18-without-force": 1e-3, "20b-printed": 1e-3, "f_d_minus": 1.0,
                  "k0": 0.0, "17-other-inner": 1e-3, "19-other-inner": 1e-3})
    monkeypatch.setattr(cp, "exact_identities", lambda scn, **k: dict(ident))
    monkeypatch.setattr(cp, "antisymmetry", lambda scn, **k: anti(scn))
    monkeypatch.setattr(cp, "holonomic_exact",
                        lambda scn, **k: {"tangential": 1e-30 if scn == "pendulum" else 1e-3, "full": 1.0})
    return cp.section5_records(quick=True)


def _anti_status(recs):
    return [(r["scene"], r["status"]) for r in recs if r["claim"] == "antisymmetry-exact" and "control" not in r["method"]]


@pytest.mark.parametrize("bad", ["L", "f_plus", "f_minus"])
def test_the_antisymmetry_record_fails_when_one_identity_fails(monkeypatch, bad):
    good = {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30, "wrong-pairing": 1.0}
    recs = _fake_section5(monkeypatch, lambda scn: dict(good, **({bad: 1e-10} if scn == "rheonomic-skate" else {})))
    assert _anti_status(recs) == [("particle", "pass"), ("rheonomic-skate", "fail")]
    rec = [r for r in recs if r["claim"] == "antisymmetry-exact" and r["scene"] == "rheonomic-skate"][0]
    assert rec["residual"] == pytest.approx(1e-10)
    # negative control: all three hold -> pass on both scenes
    recs = _fake_section5(monkeypatch, lambda scn: dict(good))
    assert _anti_status(recs) == [("particle", "pass"), ("rheonomic-skate", "pass")]


def test_the_antisymmetry_control_record_is_the_wrong_pairing(monkeypatch):
    good = {"L": 1e-30, "f_plus": 1e-30, "f_minus": 1e-30, "wrong-pairing": 1e-30}
    recs = _fake_section5(monkeypatch, lambda scn: dict(good))
    ctl = [r["status"] for r in recs if r["claim"] == "antisymmetry-exact" and "control" in r["method"]]
    assert ctl == ["pass", "pass"]          # a control that is satisfied: "pass" against expected "fail"


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


# --- the paper's claim group: both quantities of a record, and records that describe their run -------------
def test_a_section7_record_fails_when_either_of_its_two_quantities_fails(monkeypatch):
    from ldaspark.lab.claims import claims_paper as cp
    good, bad = 1e-40, 1e-20                                          # around TOL_S7 = 1e-35
    for diff, stage in ((good, good), (bad, good), (good, bad)):
        monkeypatch.setattr(cp, "reduction", lambda kind, tab, constant_K, d=diff, s=stage:
                            {"diff": d if tab.name != "lobatto-iiia-iiib-2" and kind != "euler-ii" or tab.name !=
                             "euler-i" else 1.0, "stage": s})
        monkeypatch.setattr(cp, "one_newton_iteration", lambda tab, ck, guess: {"after_one": 1e-40 if ck or
                                                                                 tab.name == "euler-ii" else 1.0})
        recs = [r for r in cp.section7_records(True) if r["expected"] == "pass" and r["claim"] != "linearly-implicit-7"]
        assert len(recs) == 3
        assert {r["status"] for r in recs} == {"pass" if (diff, stage) == (good, good) else "fail"}, (diff, stage)
        assert all(r["residual"] == _close(max(diff, stage)) for r in recs)


def test_an_energy_balance_record_takes_the_worse_of_pointwise_and_integral(monkeypatch):
    from ldaspark.lab.claims import claims_paper as cp
    from ldaspark.lab.claims.ledger import check_unit_records
    pred = {}

    def discrete(name, tab, hs):
        pred[tab.name] = cp.predicted_mismatch_order(tab)
        return {"order_mismatch": pred[tab.name] + 0.1, "order_delta_E": 1.0}
    monkeypatch.setattr(cp, "discrete_balance", discrete)
    for pw, it in ((1e-30, 1e-30), (1e-10, 1e-30), (1e-30, 1e-10)):
        monkeypatch.setattr(cp, "exact_balance", lambda name, dps, stages, a=pw, b=it:
                            {"pointwise": a, "integral": b, "delta_E": 0.1, "without_L_t": 1.0,
                             "without_psi_term": 1.0})
        recs = cp.energy_records(True)
        check_unit_records("energy-2.2", recs)
        exact = [r for r in recs if r["method"] == "exact-flow"]
        assert len(exact) == 2 and all(r["residual"] == _close(max(pw, it)) for r in exact)
        assert {r["status"] for r in exact} == {"pass" if max(pw, it) < 1e-22 else "fail"}
        d = [r for r in recs if r["point"] == "one-step h-sweep"]
        assert [r["status"] for r in d] == ["pass"] and d[0]["residual"] == _close(0.1)


def test_definition1_records_describe_the_runs_they_come_from(monkeypatch):
    """Each record names its step count and digits; the run must use them, from initial values
    accurate to those digits."""
    from ldaspark.lab.claims import claims_paper as cp
    from ldaspark.lab.claims.ledger import check_unit_records
    from ldaspark.models.scenes import get_scene
    calls = []

    def fake(system, tab, t0, q0, v0, h, n_steps, dps):
        calls.append((n_steps, dps, q0, system))
        return {"15a": 1e-30, "15b": 1e-45, "15a_without_forces": 1.0, "15b_secant": 1.0, "15b_left_end": 1.0,
                "wellposed": "well-posed", "seconds": 0.5}
    monkeypatch.setattr(cp, "definition1_residuals", fake)
    recs = cp.definition1_records(True)
    check_unit_records("definition-1", recs)
    runs = [r for r in recs if "control: left" not in r["method"] and not (r["claim"] == "15b" and r["point"] ==
                                                                           "ivp-10-steps")]
    assert len(runs) == len(calls) == 3
    for rec, (n, dps, q0, system) in zip(runs, calls):
        assert rec["point"].endswith(f"-{n}-steps") and rec["dps"] == dps, rec
        with mpmath.workdps(100):
            ref = get_scene(rec["scene"]).initial(80)[1]
            # the initial point to more digits than the run works with (10 guard digits)
            assert max(abs(mpmath.mpf(a) - b) for a, b in zip(q0, ref)) <= mpmath.mpf(10) ** (-dps - 10), rec
