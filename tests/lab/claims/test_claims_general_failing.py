"""The verdict rules of ``ldaspark.lab.claims.claims_general`` fed their failing values, computed
for real on general scenes where the term each rule is about is nonzero (docs/verification.md,
"Every check fed its failing value"):

* Theorem 1 with (22b) broken (A_hat_12 + 1/10): A_hat enters (21) through F = grad_q L, which
  is nonzero on the rheonomic skate (-cos(t)/2 - 1) and zero on the turntable; the rule fails
  the first, and calls the second vacuous;
* symmetry (23): Euler I on the rheonomic skate (L and k depend on t);
* (21f): the constraint evaluated at the left end of each step (a clock one step behind) on the
  rheonomic skate, whose k_t = sin(q3) cos(t)/2 is nonzero; on the skate (k_t = 0) the same
  fault is invisible, so the scene is what makes the check able to fail;
* the order rule: the real errors of Gauss-1 (order 2) judged against claims 1 and 3;
* the nonideal control: the ideal skate converges to a reference without N and must stall
  against the reference with N (friction nonzero along the trajectory).
Cost: ~3 s."""
from __future__ import annotations

import functools

import numpy as np
import sympy

from ldaspark.core.backend import Backend
from ldaspark.core.families import get_method
from ldaspark.lab.claims import claims_general as cg
from ldaspark.lab.theory.orders import make_reference, measure_errors, order_records
from ldaspark.models.scenes import get_scene


def _broken_22b():
    ctl = get_method("gauss-2", exact=True).with_entry("A_hat", 0, 1, "1/10")
    ctl.name = "negctl-gauss-2+dA_hat[0,1]"
    return ctl


def test_theorem1_fails_for_a_22b_breaking_tableau_where_grad_q_L_is_nonzero():
    scn = get_scene("rheonomic-skate")
    assert any(sympy.simplify(e) != 0 for e in scn.system.L_q)
    t0, q0, v0 = scn.initial(60)
    bad = cg._theorem1_records(scn, _broken_22b(), "pass", t0, q0, v0)
    assert [r["status"] for r in bad] == ["fail", "fail"] and min(r["residual"] for r in bad) >= cg.TOL_NEGATIVE
    good = cg._theorem1_records(scn, get_method("gauss-2", exact=True), "pass", t0, q0, v0)
    assert [r["status"] for r in good] == ["pass", "pass"]
    # where grad_q L = 0 the same tableau cannot fail: the rule says so instead of "pass"
    tt = get_scene("turntable")
    assert all(e == 0 for e in tt.system.L_q)
    recs = cg._theorem1_records(tt, _broken_22b(), "fail", *tt.initial(60))
    assert [r["status"] for r in recs] == ["not-applicable"] * 2


def test_symmetry_fails_for_euler_i_on_the_rheonomic_skate():
    scn = get_scene("rheonomic-skate")
    t0, q0, v0 = scn.initial(60)
    bad = cg._symmetry_record(scn, get_method("euler-i"), "pass", t0, q0, v0)
    assert bad["status"] == "fail" and bad["residual"] >= cg.TOL_NEGATIVE
    assert cg._symmetry_record(scn, get_method("gauss-2", exact=True), "pass", t0, q0, v0)["status"] == "pass"


def _left_end_clock(monkeypatch, system):
    """integrate with its constraint column recomputed at t_n - h: (21f) checked at the wrong time."""
    real = cg.integrate
    bk = Backend(None)

    def late(*a, **k):
        sol = real(*a, **k)
        h = float(a[5])
        sol.constraint = np.array([np.asarray(system.constraint(bk, float(t) - h, np.asarray(q, float),
                                                                np.asarray(v, float)), float)
                                   for t, q, v in zip(sol.t, sol.q, sol.v)])
        return sol
    monkeypatch.setattr(cg, "integrate", late)


def test_the_constraint_rule_fails_on_a_clock_one_step_behind_where_k_depends_on_t(monkeypatch):
    scn = get_scene("rheonomic-skate")
    assert sympy.diff(scn.system.k[0], scn.system.t) != 0
    assert cg._constraint_record(scn, get_method("gauss-2"))["status"] == "pass"
    _left_end_clock(monkeypatch, scn.system)
    rec = cg._constraint_record(scn, get_method("gauss-2"))
    assert rec["status"] == "fail" and rec["residual"] > 1e-4, rec
    # the skate's k does not depend on t: the same fault passes there (why the scene matters)
    sk = get_scene("skate")
    assert all(sympy.diff(e, sk.system.t) == 0 for e in sk.system.k)
    _left_end_clock(monkeypatch, sk.system)
    assert cg._constraint_record(sk, get_method("gauss-2"))["status"] == "pass"


@functools.lru_cache(maxsize=1)
def _gauss1_errors():
    scn = get_scene("rheonomic-skate")
    ref = make_reference(scn, cg.REF_DPS)
    return measure_errors("gauss-1", scn, ref, 1.0, [8, 16, 32, 64]), ref.kind


def test_the_order_rule_fails_for_a_claim_one_off_on_real_errors():
    """Gauss-1 observes 2.00 on the rheonomic skate; claims 1 and 3 miss by 1 > TOL_ORDER."""
    m, kind = _gauss1_errors()
    for claim, want in ((1, "fail"), (2, "pass"), (3, "fail")):
        recs = order_records("gauss-1", "rheonomic-skate", claim, m, None, 1.0, kind)
        st = [cg._order_record("order-general-scenes", r, 0.0)["status"] for r in recs if r["variable"] in "qv"]
        assert st == [want, want], (claim, st)


def test_the_nonideal_control_stalls_only_against_a_reference_with_N(monkeypatch):
    sc = get_scene("friction-skate")
    t0, q0, v0 = sc.initial()
    with_n = cg.DOP853Reference(sc.system, t0, q0, v0, 1.0)
    # the friction acts along the trajectory (N is 0 at the start, where the blade speed is 0)
    q, v, psi = with_n(0.5)
    N = sc.system.nonideal_terms(Backend(None), 0.5, q, v, psi, partials=False)[0]
    assert np.max(np.abs(np.asarray(N, float))) > 1e-3
    ideal = get_scene("skate")
    without_n = cg.DOP853Reference(ideal.system, t0, q0, v0, 1.0)
    for ref, want in ((with_n, "fail"), (without_n, "pass")):
        monkeypatch.setattr(cg, "nonideal_orders", lambda *a, _r=ref, **k: ([], _r))
        recs = cg._nonideal_records(quick=True)
        assert [(r["status"], r["expected"]) for r in recs] == [(want, "fail")], recs


def _gauss2_to_20_digits():
    """Gauss 2 computing with entries correct to 20 digits at every precision (the catalogued
    fault tableau-arrays-20-digit-entries, planted in one fresh copy)."""
    tab = get_method("gauss-2", exact=True).with_entry("A", 0, 0, "0")     # a fresh copy, own caches
    full = tab.mp_entries
    tab.mp_entries = lambda dps: full(20)
    tab.name = "gauss-2-20-digits"
    return tab


def test_general_theorem1_fails_for_a_tableau_correct_to_20_digits_only():
    """The general scenes' Theorem 1 records used the fixed 1e-20 too (residuals of a 20-digit
    tableau pass it); judged now against ``theorem1_residual_bound`` like the ledger's. Control:
    exact Gauss 2 passes on the same scene."""
    scn = get_scene("rheonomic-skate")
    t0, q0, v0 = scn.initial(60)
    bad = cg._theorem1_records(scn, _gauss2_to_20_digits(), "pass", t0, q0, v0)
    assert [r["status"] for r in bad] == ["fail", "fail"], bad
    assert max(r["residual"] for r in bad) < cg.TOL_THEOREM1       # what the fixed 1e-20 let through
    good = cg._theorem1_records(scn, get_method("gauss-2", exact=True), "pass", t0, q0, v0)
    assert [r["status"] for r in good] == ["pass", "pass"], good
