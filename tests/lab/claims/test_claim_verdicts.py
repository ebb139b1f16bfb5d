"""Who checks the checker (one-sided verdicts, untested record builders): every ledger record builder runs here at a
small size, every verdict rule is fed a failing value (the computation monkeypatched: the real
result with one quantity replaced) and must give a "fail" record, and every order prediction is
pinned per family and s with its source, so that a prediction raised or lowered by one fails.

Order checks are two-sided, |observed - predicted| <= tol with tol < 1/2 (a prediction off by
one cannot pass where the right one does); the ones that stay one-sided say why in their module.
Cost: ~15 s (the quick claim groups and two ledger units run for real once)."""
import math

import numpy as np
import pytest

from ldaspark.core.families import builtin_method_names, get_method
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.lab.claims import claims_general as cg
from ldaspark.lab.claims import claims_paper as cp
from ldaspark.lab.claims import ledger as lg
from ldaspark.lab.theory.energy_balance import predicted_mismatch_order
from ldaspark.lab.theory.orders import claimed_order_of
from ldaspark.lab.theory.variational import predicted_local_order


_REAL = {}          # the real computations' results, shared by the tests of this module (cost)


def _key(x):
    if isinstance(x, (list, tuple)):
        return tuple(_key(y) for y in x)
    if isinstance(x, np.ndarray):
        return ("array",) + tuple(str(y) for y in x.reshape(-1))
    if hasattr(x, "name") and not isinstance(x, str):
        return (type(x).__name__, x.name)
    return repr(x)


def _memo(mod, name):
    """The real ``mod.name`` (the module's binding at first use), memoized on the arguments
    (systems and tableaux by name); returns a shallow copy of its dict, so that callers may
    replace entries."""
    real = _REAL.setdefault(("fn", mod.__name__, name), getattr(mod, name))

    def fn(*a, **k):
        key = (mod.__name__, name, _key(a), _key(sorted(k.items())))
        if key not in _REAL:
            _REAL[key] = real(*a, **k)
        return dict(_REAL[key])
    return fn


def _override(monkeypatch, mod, name, **over):
    """Replace ``mod.name`` by the real computation with the keys ``over`` replaced."""
    real = _memo(mod, name)
    monkeypatch.setattr(mod, name, lambda *a, **k: {**real(*a, **k), **over})


def _bad(recs):
    """Records whose status differs from the paper's expectation (not-applicable excepted)."""
    return [r for r in recs if r["status"] != "not-applicable" and r["status"] != r["expected"]]


# --- class 1: the predictions, pinned per family and s --------------------------------------------
# section 7 and [26, 27]: Gauss 2s, Lobatto IIIA-B (and IIIA-B-D) 2s-2; Euler I, II: 1 (7.1, 7.2)
GLOBAL = {"gauss-1": 2, "gauss-2": 4, "gauss-3": 6, "gauss-4": 8, "lobatto-iiia-iiib-2": 2,
          "lobatto-iiia-iiib-3": 4, "lobatto-iiia-iiib-4": 6, "lobatto-iiia-iiib-iiid-2": 2,
          "lobatto-iiia-iiib-iiid-3": 4, "lobatto-iiia-iiib-iiid-4": 6, "euler-i": 1, "euler-ii": 1}


def test_global_order_claims_are_the_papers():
    assert set(GLOBAL) == set(builtin_method_names(4))
    for name, p in GLOBAL.items():
        assert get_method(name).claimed_order == p, name
        assert claimed_order_of(name) == p, name
    assert claimed_order_of("gauss-irk-1") == 1 and claimed_order_of("gauss-irk-2") == 2     # 7.3-7.4


def test_variational_order_predictions_pinned():
    """Marsden-West variational error analysis: |L_d - L_d^E| = O(h^{r+1}), r the global order:
    Gauss 2s+1, Lobatto 2s-1, Euler 2."""
    want = {"gauss-1": 3, "gauss-2": 5, "gauss-3": 7, "gauss-4": 9, "lobatto-iiia-iiib-2": 3,
            "lobatto-iiia-iiib-3": 5, "lobatto-iiia-iiib-4": 7, "lobatto-iiia-iiib-iiid-2": 3,
            "lobatto-iiia-iiib-iiid-3": 5, "lobatto-iiia-iiib-iiid-4": 7, "euler-i": 2, "euler-ii": 2}
    for name, p in want.items():
        assert predicted_local_order(get_method(name)) == p, name


def test_energy_balance_predictions_pinned():
    """Section 2.2: Delta E - h sum b_i rhs_i over one step is a local error, O(h^{p+1})."""
    for name, p in GLOBAL.items():
        assert predicted_mismatch_order(get_method(name)) == p + 1, name


@pytest.mark.parametrize("name", builtin_method_names(3))
def test_audit_tree_prediction_pinned(name):
    """The audit's prediction (forced-ODE trees, exact) is the paper's order for every built-in."""
    from ldaspark.lab.theory import audit as au
    ar, e = au.oc.arith_for(get_method(name, exact=True), 30)
    _, facts = au.order_checks(ar, e)
    assert au.predicted_order(None, facts) == GLOBAL[name]


def test_tolerances_cannot_absorb_an_off_by_one_prediction():
    for tol in (cp.TOL_VARIATIONAL, cp.TOL_ENERGY_ORDER, ac.ORDER_SLACK, cg.TOL_ORDER):
        assert 0 < tol < 0.5


# --- class 6: every record builder runs (small size) and agrees with the paper --------------------
PAPER_COMPUTATIONS = ("definition1_residuals", "exact_identities", "antisymmetry", "holonomic_exact", "exact_del",
                      "variational_errors", "exact_balance", "discrete_balance", "reduction", "one_newton_iteration")


def test_claims_paper_quick_records_all_as_expected(monkeypatch):
    for fn in PAPER_COMPUTATIONS:        # the real computations, memoized for the verdict tests below
        _override(monkeypatch, cp, fn)
    recs = cp.records(quick=True)
    claims = {r["claim"] for r in recs}
    assert {"15a", "15b", "16", "18", "17-integral", "19-integral", "20-integral", "antisymmetry-exact",
            "5.1-exact", "variational-order", "energy-balance-2.2", "euler-i-reduction",
            "linearly-implicit-7"} <= claims
    assert not _bad(recs), _bad(recs)
    assert sum(r["expected"] == "fail" for r in recs) >= 8          # the negative controls ran too


@pytest.mark.parametrize("piece", [("checks", "rheonomic-skate"), ("orders", "rheonomic-skate"), ("nonideal",)])
def test_claims_general_pieces_run_and_agree(piece):
    recs = cg.piece_records(piece, quick=True)
    assert recs and not _bad(recs), _bad(recs)


def test_ledger_units_run_and_agree():
    """A per-tableau unit (exact conditions, 5.1) and a (tableau, scene) unit, and a negative
    control's unit (max_s = 1: Gauss-1, then the three controls)."""
    recs = lg._ledger_task(1, True, True, True, 0, None) + lg._ledger_task(1, True, True, True, 0, "particle")
    claims = {r["claim"] for r in recs}
    assert {"22a", "22b", "23", "5.1-holonomic", "implicit-function", "theorem1-q0", "theorem1-q1",
            "symmetry-Ld", "symmetry-Phi", "constraint"} <= claims
    ctl = lg._ledger_task(1, True, True, True, 1, "particle")
    assert any(r["expected"] == "fail" and r["status"] == "fail" for r in ctl)
    assert not _bad(recs + ctl), _bad(recs + ctl)


# --- class 6: each verdict rule fed a failing value ------------------------------------------------
def _status(recs, claim, **match):
    out = [r["status"] for r in recs if r["claim"] == claim and all(r[k] == v for k, v in match.items())]
    assert out, (claim, match)
    return out


@pytest.mark.parametrize("shift,status", [(0.0, "pass"), (0.3, "pass"), (-0.3, "pass"), (1.0, "fail"),
                                          (-1.0, "fail"), (0.5, "fail")])
def test_variational_verdict_is_two_sided(monkeypatch, shift, status):
    real = _memo(cp, "variational_errors")

    def fake(tab, *a, **k):
        r = real(tab, *a, **k)
        r["orders"] = dict(r["orders"], L_d=r["predicted_local_order"] + shift)
        return r
    monkeypatch.setattr(cp, "variational_errors", fake)
    recs = cp.variational_records(quick=True)
    assert _status(recs, "variational-order", expected="pass") == [status] * 2   # skate, rheonomic
    # the control (22b broken) is judged against Gauss-2's 5, not its own shifted prediction: it fails
    assert _status(recs, "variational-order", expected="fail") == ["fail"]


def test_variational_control_is_judged_against_the_unperturbed_prediction(monkeypatch):
    """The (22b)-broken Gauss-2 must miss Gauss-2's 5, not its own fallback prediction (2): a
    control that kept the order 5 is reported (pass where fail is expected)."""
    real = _memo(cp, "variational_errors")

    def fake(tab, *a, **k):
        if not tab.name.startswith("negctl"):
            return real(tab, *a, **k)
        r = real("gauss-1", *a, **k)
        r["orders"] = dict(r["orders"], L_d=5.0)
        r["predicted_local_order"] = predicted_local_order(tab)
        return r
    monkeypatch.setattr(cp, "variational_errors", fake)
    assert predicted_local_order(lg.negative_controls()[0][0]) != 5      # the fallback differs
    ctl = [r for r in cp.variational_records(quick=False) if r["method"].startswith("negctl")]
    assert len(ctl) == 1 and ctl[0]["status"] == "pass" and ctl[0]["expected"] == "fail"


@pytest.mark.parametrize("shift,status", [(0.0, "pass"), (0.35, "pass"), (1.0, "fail"), (-1.0, "fail")])
def test_energy_discrete_verdict_is_two_sided(monkeypatch, shift, status):
    real = _memo(cp, "discrete_balance")

    def fake(name, tab, *a, **k):
        r = real(name, tab, *a, **k)
        if name == "time-L":
            r["order_mismatch"] = predicted_mismatch_order(tab) + shift
        return r
    monkeypatch.setattr(cp, "discrete_balance", fake)
    recs = cp.energy_records(quick=True)
    assert _status(recs, "energy-balance-2.2", method="gauss-2") == [status]


def test_energy_exact_verdicts(monkeypatch):
    _override(monkeypatch, cp, "exact_balance", pointwise=1e-10)
    recs = cp.energy_records(quick=True)
    assert _status(recs, "energy-balance-2.2", method="exact-flow") == ["fail", "fail"]
    _override(monkeypatch, cp, "exact_balance", without_L_t=1e-30, without_psi_term=1e-30)
    recs = cp.energy_records(quick=True)
    ctl = [r for r in recs if "control" in r["method"]]
    assert [r["status"] for r in ctl] == ["pass", "pass"] and {r["expected"] for r in ctl} == {"fail"}


def test_definition1_verdicts(monkeypatch):
    _override(monkeypatch, cp, "definition1_residuals", **{"15a": 1e-20, "15b": 1e-25})
    recs = cp.definition1_records(quick=True)
    assert _status(recs, "15a", expected="pass") == ["fail"] and _status(recs, "15b", expected="pass") == ["fail"] * 2
    _override(monkeypatch, cp, "definition1_residuals", **{"15b_left_end": 1e-30})
    assert _status(cp.definition1_records(quick=True), "15b", expected="fail") == ["pass"]   # control too small
    _override(monkeypatch, cp, "definition1_residuals", **{"15a": 1e-9})
    assert _status(cp.definition1_records(quick=True), "15a", expected="fail") == ["pass"]   # control too small


@pytest.mark.parametrize("key,claim", [("16", "16"), ("18", "18"), ("17", "17-integral"), ("19", "19-integral"),
                                       ("20b-corrected", "20-integral")])
def test_section5_identity_verdicts(monkeypatch, key, claim):
    _override(monkeypatch, cp, "exact_identities", **{key: 1e-15})
    recs = cp.section5_records(quick=True)
    assert "fail" in _status(recs, claim, method="exact-flow")


def test_section5_controls_and_antisymmetry_verdicts(monkeypatch):
    _override(monkeypatch, cp, "exact_identities", **{"16-without-force": 1e-9, "20b-printed": 1e-9})
    _override(monkeypatch, cp, "antisymmetry", L=1e-15, **{"wrong-pairing": 1e-9})
    _override(monkeypatch, cp, "holonomic_exact", tangential=1e-20)
    recs = cp.section5_records(quick=True)
    assert _status(recs, "16", expected="fail") == ["pass", "pass"]          # particle, rheonomic skate
    assert _status(recs, "20-integral", expected="fail") == ["pass", "pass"]
    assert _status(recs, "antisymmetry-exact") == ["fail", "pass"] * 2     # identity fails, control passes
    assert _status(recs, "5.1-exact") == ["fail", "pass"]                  # pendulum fails, control too small


def test_section5_full_del_verdict(monkeypatch):
    monkeypatch.setattr(cp, "exact_del", lambda scn: {"del": 1e-15, "del-printed-20b": 1.0,
                                                      "momentum-continuity": 0.0})
    recs = cp.section5_records(quick=False)
    assert _status(recs, "20-integral", method="exact-flow", point="exact-2-steps") == ["fail", "fail"]


@pytest.mark.parametrize("shift,status", [(0.0, "pass"), (0.25, "pass"), (1.0, "fail"), (-1.0, "fail")])
def test_general_order_record_is_two_sided(shift, status):
    r = {"method": "gauss-2", "scene": "s", "variable": "q", "claimed_order": 4, "observed_order": 4 + shift,
         "pairwise_orders": [4.0], "errors": [1e-3, 1e-4], "dps": None, "reference": "ref"}
    assert cg._order_record("order-general-scenes", r, 0.0)["status"] == status
    assert cg._order_record("x", dict(r, observed_order=None), 0.0)["status"] == "fail"


def test_general_checks_verdicts(monkeypatch):
    _override(monkeypatch, cg, "theorem1_residuals", **{"theorem1-q0": 1e-12})
    _override(monkeypatch, cg, "check_symmetry", **{"symmetry-Phi": 1e-12})
    recs = cg._scene_checks("rheonomic-skate", quick=True)
    assert "fail" in _status(recs, "theorem1-general-q0", expected="pass")
    assert _status(recs, "symmetry-general", expected="pass") == ["fail"]
    monkeypatch.setattr(cg, "theorem1_residuals", lambda *a, **k: {
        **lg_real_t1(*a, **k), "theorem1-q0": 1e-9, "theorem1-q1": 1e-9})
    recs = cg._scene_checks("rheonomic-skate", quick=True)
    assert _status(recs, "theorem1-general-q0", expected="fail") == ["pass"]    # control too small


def lg_real_t1(*a, **k):
    from ldaspark.analysis.discrete import theorem1_residuals
    return theorem1_residuals(*a, **k)


def test_general_constraint_and_nonideal_control_verdicts(monkeypatch):
    real = cg.integrate

    def drifting(*a, **k):
        sol = real(*a, **k)
        sol.constraint[-1] = sol.constraint[-1] + 1e-9
        return sol
    monkeypatch.setattr(cg, "integrate", drifting)
    rec = cg._constraint_record(cg.get_scene("rheonomic-skate"), get_method("gauss-2"))
    assert rec["status"] == "fail"
    monkeypatch.setattr(cg, "ideal_control_error", lambda ref: [1e-2, 2.5e-3, 6.25e-4])    # converges
    monkeypatch.setattr(cg, "nonideal_orders", lambda methods: ([], None))
    recs = cg._nonideal_records(quick=True)
    assert [r["status"] for r in recs] == ["pass"] and recs[0]["expected"] == "fail"


def test_ledger_verdicts(monkeypatch):
    tab, scene = get_method("gauss-1", exact=True), lg.get_scene("particle")
    t0, q0, v0 = scene.initial(60)
    monkeypatch.setattr(lg, "check_22a", lambda t: False)
    assert _status(lg.exact_condition_records(tab, {"22a": "pass", "22b": "pass", "23": "pass"}), "22a") == ["fail"]
    _override(monkeypatch, lg, "theorem1_residuals", **{"theorem1-q1": 1e-15})
    recs, _ = lg.theorem1_records(scene, tab, {"theorem1-q0": "pass", "theorem1-q1": "pass"}, "base", t0, q0, v0)
    assert [r["status"] for r in recs] == ["pass", "fail"]
    recs, _ = lg.theorem1_records(scene, tab, {"theorem1-q0": "fail", "theorem1-q1": "fail"}, "base", t0, q0, v0)
    assert [r["status"] for r in recs] == ["pass", "pass"]          # controls: residual 1e-15 < 1e-6
    _override(monkeypatch, lg, "check_symmetry", **{"symmetry-Ld": 1e-20, "symmetry-Phi": 1e-20,
                                                    "symmetry-fd-plus": 1e-20})
    recs = lg.symmetry_records(scene, tab, "pass", t0, q0, v0, "base", "well-posed")
    st = {r["claim"]: r["status"] for r in recs}
    assert st["symmetry-Ld"] == st["symmetry-Phi"] == st["symmetry-fd-plus"] == "fail", st
    assert st["symmetry-fd-minus"] == "pass"
    monkeypatch.setattr(lg, "constraint_residuals", lambda sc, t, dps=None: (1e-10, 1e-3, 1e-16 if dps is None
                                                                               else 1e-30))
    assert _status(lg.constraint_records(scene, tab), "constraint") == ["fail", "fail"]
    _override(monkeypatch, lg, "classify_wellposedness", **{"class": lg.SINGULAR})
    recs, cls = lg.wellposed_records(scene, tab, t0, q0, v0, "base")
    assert cls == lg.SINGULAR and _status(recs, "implicit-function") == ["fail"]


def test_ledger_gauge_invariance_verdict(monkeypatch):
    tab, scene = get_method("gauss-1", exact=True), lg.get_scene("particle")
    t0, q0, v0 = scene.initial(60)
    _override(monkeypatch, lg, "classify_wellposedness", **{"class": lg.GAUGE, "rank_deficiency": 1})
    monkeypatch.setattr(lg, "gauge_invariance", lambda *a, **k: {"dL_d": 1e-20, "d(p0+f_d_minus)": 0.0,
                                                                 "d(p1-f_d_plus)": 0.0, "dp0": 1e-3, "dV": 1e-3})
    recs, _ = lg.wellposed_records(scene, tab, t0, q0, v0, "base")
    assert _status(recs, "gauge-invariance") == ["fail"]


@pytest.mark.parametrize("residual,status", [(1e-20, "pass"), (1e-7, "pass"), (1e-6, "fail"), (1e-2, "fail")])
def test_symmetry_controls_fail_only_at_tol_negative(monkeypatch, residual, status):
    """The symmetry records of Euler I (expected fail) are negative controls: they count as the
    failure that shows the check's teeth only at >= TOL_NEGATIVE (1e-6), as Theorem 1's and every
    other control; they were judged at the claim's 1e-25, so a control missing (23) by 1e-20 (a
    method all but symmetric, or a checker that compares a quantity with itself up to round-off)
    counted as the expected failure. Measured: Euler I/II miss by >= 3.6e-6 on every scene."""
    tab, scene = get_method("euler-i", exact=True), lg.get_scene("particle")
    t0, q0, v0 = scene.initial(60)
    keys = ("symmetry-Ld", "symmetry-Phi", "symmetry-fd-plus", "symmetry-fd-minus")
    _override(monkeypatch, lg, "check_symmetry", **{k: residual for k in keys})
    recs = lg.symmetry_records(scene, tab, "fail", t0, q0, v0, "base", "well-posed")
    assert {r["claim"]: (r["status"], r["threshold"]) for r in recs} == {k: (status, lg.TOL_NEGATIVE) for k in keys}
    # the claims themselves (expected pass) keep the 1e-25 threshold
    recs = lg.symmetry_records(scene, tab, "pass", t0, q0, v0, "base", "well-posed")
    assert {r["threshold"] for r in recs} == {lg.TOL_SYMMETRY}
    _override(monkeypatch, cg, "check_symmetry", **{k: residual for k in keys})
    sc = cg.get_scene("rheonomic-skate")
    t0, q0, v0 = sc.initial(60)
    rec = cg._symmetry_record(sc, get_method("euler-i"), "fail", t0, q0, v0)
    assert (rec["status"], rec["threshold"]) == (status, lg.TOL_NEGATIVE)


def test_symmetry_controls_fail_as_expected_on_the_real_residuals():
    """Control of the test above: unpatched, Euler I's residuals (>= 1e-3 here) fail as expected."""
    tab, scene = get_method("euler-i", exact=True), lg.get_scene("particle")
    t0, q0, v0 = scene.initial(60)
    recs = lg.symmetry_records(scene, tab, "fail", t0, q0, v0, "base", "well-posed")
    assert [r["status"] for r in recs] == ["fail"] * 4, recs
    sc = cg.get_scene("rheonomic-skate")
    t0, q0, v0 = sc.initial(60)
    assert cg._symmetry_record(sc, get_method("euler-i"), "fail", t0, q0, v0)["status"] == "fail"


@pytest.mark.parametrize("p,status", [(2.0, "pass"), (1.6, "pass"), (1.2, "fail"), (0.9, "fail")])
def test_holonomic_verdict(monkeypatch, p, status):
    """One-sided (no rate is predicted, see ledger.HOLONOMIC_RATE): a slow decay fails."""
    _override(monkeypatch, lg, "holonomic_order", p_tangential=p, tangential=[1e-3, 5e-4, 2e-4])
    recs = lg.holonomic_records(get_method("gauss-1", exact=True), "pass")
    assert _status(recs, "5.1-holonomic", expected="pass") == [status]
    assert _status(recs, "5.1-holonomic", expected="fail") == ["fail"]      # the unprojected covector ~ h^0.9


# --- the audit's convergence verdict --------------------------------------------------------------
@pytest.mark.parametrize("obs,capped,status", [(4.0, False, "pass"), (4.4, False, "pass"), (3.6, False, "pass"),
                                               (5.0, False, "pass"), (3.0, False, "fail"), (3.5, False, "fail"),
                                               (5.0, True, "pass"), (3.0, True, "fail"), (math.nan, False, "fail")])
def test_audit_convergence_verdict_is_one_sided(monkeypatch, obs, capped, status):
    monkeypatch.setattr(ac, "observed_order", lambda tab, scn, Ns, t_end, dps, floor: {
        "scene": scn, "N": Ns, "t_end": t_end, "errors": [1e-3] * len(Ns), "slopes": [obs],
        "observed": obs, "reference": "fake", "max_constraint": 0.0})
    checks, _ = ac.convergence_checks(get_method("gauss-2"), 4, 30, True, capped)
    assert {c.name: c.status for c in checks if c.name.startswith("convergence:")} == {
        "convergence:skate": status, "convergence:particle": status}


class _FakeSol:
    def __init__(self, err):
        import numpy as np
        self.q = [np.array([err])]
        self.v = [np.array([0.0])]
        self.constraint = np.zeros((1, 1))


@pytest.mark.parametrize("scene_name", ["skate", "particle"])
def test_audit_observed_order_comes_from_the_finest_pair(monkeypatch, scene_name):
    """A pre-asymptotic sweep (coarse slope 2.32, fine slope 4): the observed order is the finest
    pair's, and the verdict follows it; the coarsest pair would give 2.32."""
    import types

    import numpy as np
    from ldaspark.models.scenes import get_scene
    ref = types.SimpleNamespace(name="ref")
    errs = {4: 1e-1, 8: 2e-2, 16: 1.25e-3}
    monkeypatch.setattr(ac, "_run", lambda tab, sc, N, t_end, dps: _FakeSol(0.0 if tab is ref else errs[N]))
    monkeypatch.setattr(ac, "_reference_tableau", lambda tab: ref)
    monkeypatch.setattr(type(get_scene("skate")), "exact_solution",
                        lambda self, t, dps: (np.zeros(1), np.zeros(1), None))
    res = ac.observed_order(get_method("gauss-2"), scene_name, [4, 8, 16], 1, None, 1e-11)
    assert [round(s, 2) for s in res["slopes"]] == [2.32, 4.0]
    assert res["observed"] == pytest.approx(4.0, abs=1e-12)
    # the floor: a finest error at the floor is not usable, the next pair decides
    res = ac.observed_order(get_method("gauss-2"), scene_name, [4, 8, 16], 1, None, 2e-3)
    assert res["observed"] == pytest.approx(math.log(5) / math.log(2), abs=1e-12)


def test_summarize_counts_outcomes_other_than_the_papers():
    """A control that fails as predicted is not a finding; a check that passes where the paper
    predicts a failure is; not-applicable is neither."""
    rec = lambda st, exp: lg.record("x", "m", "s", st, 0.0, exp)
    assert lg.summarize([rec("pass", "pass"), rec("fail", "fail"), rec("not-applicable", "pass")]) == 0
    assert lg.summarize([rec("fail", "pass"), rec("pass", "fail"), rec("not-applicable", "fail")]) == 2
