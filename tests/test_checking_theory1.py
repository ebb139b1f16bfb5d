"""Verdict rules of the audit (ldaspark.lab.theory.audit, audit_checks), the order estimates and claim
verdicts (orders), the exact (22)/(23) checks (conditions), the tree-order machinery
(order_conditions), the symmetry summary and the variational prediction, each fed an input on
which the right rule and its plausible neighbours (<= vs <, all vs any, min vs max, a/b vs b/a,
one side of a pair vs both, a tolerance moved) give different answers (issue #31).

Expensive inner computations (boundary-value solves, integrations) are replaced by synthetic
records through monkeypatch: what is tested is the rule applied to them. Cost: a few seconds."""
from __future__ import annotations

import argparse
import json
import math
import types

import mpmath
import numpy as np
import pytest
import sympy

from ldaspark.core.errors import InputError, LdasparkError, TableauError
from ldaspark.core.families import gauss, get_method
from ldaspark.core.tableau import from_json_dict
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.analysis import conditions as cond
from ldaspark.analysis import order_conditions as oc
from ldaspark.lab.theory import orders as orr
from ldaspark.lab.theory import variational as var

def approx(expected, rel=1e-9, abs=0.0):
    """pytest.approx without its default absolute tolerance 1e-12, which would let every residual
    of these tests (1e-15 .. 1e-30) equal every other."""
    return pytest.approx(expected, rel=rel, abs=abs)


PASS, FAIL, INFO, SKIP = au.PASS, au.FAIL, au.INFO, au.SKIP
Check = au.Check


def mp_ar(tol=1e-10, dps=30):
    return oc.Arith("mp", dps=dps, tol=tol)


def mpv(v):
    with mpmath.workdps(30):
        return [mpv(x) for x in v] if isinstance(v, list) else mpmath.mpf(v)


# ==== audit: AuditResult ======================================================================
def _res(checks=(), facts=None, exact=True, s=2):
    r = au.AuditResult("T", s, exact, 30, True)
    r.checks = list(checks)
    r.facts = dict(facts or {})
    return r


def test_exit_code_is_1_when_any_single_check_fails():
    r = _res([Check("a", PASS, None, ""), Check("b", INFO, None, ""), Check("c", FAIL, None, "")])
    assert r.exit_code == 1
    r = _res([Check("a", PASS, None, ""), Check("b", INFO, None, ""), Check("c", SKIP, None, "")])
    assert r.exit_code == 0
    assert _res([]).exit_code == 0


def test_get_finds_by_name_and_as_dict():
    a, b = Check("a", PASS, 1.0, ""), Check("b", FAIL, 2.0, "")
    r = _res([a, b], {"x": float("nan")})
    assert r.get("b") is b and r.get("a") is a and r.get("zz") is None
    r.seconds = 1.23456
    d = r.as_dict()
    assert d["seconds"] == 1.23 and d["exit_code"] == 1 and d["facts"] == {"x": "nan"}
    assert [c["name"] for c in d["checks"]] == ["a", "b"]


# ==== audit: tolerances =======================================================================
def test_entry_tolerances_largest_passing_residual_and_zero_on_any_failure():
    C = [Check("22a", PASS, 1e-20, ""), Check("22b", PASS, 3e-20, ""),
         Check("row-sums:A", PASS, 1.0, ""),                       # not one of (22), (23)
         Check("23a", PASS, 2e-19, ""), Check("23b", PASS, None, ""), Check("23c", PASS, 5e-19, ""),
         Check("23d", PASS, 4e-19, "")]
    t22, t23 = au.entry_tolerances(C)
    assert t22 == approx(au.ENTRY_TOL_FACTOR * 3e-20, rel=1e-12)
    assert t23 == approx(au.ENTRY_TOL_FACTOR * 5e-19, rel=1e-12)
    C[4] = Check("23b", INFO, 1e-30, "")                          # one violated: full strength
    assert au.entry_tolerances(C) == (approx(3e-17, rel=1e-12), 0.0)
    C[1] = Check("22b", FAIL, 1e-30, "")
    assert au.entry_tolerances(C)[0] == 0.0
    assert au.entry_tolerances([]) == (0.0, 0.0)


def test_theorem1_tolerance_is_the_largest_of_its_three_parts():
    tab = types.SimpleNamespace(source_digits=None)
    assert au._theorem1_tol(tab, 30, 1e-12) == approx(1e-11, rel=1e-12)        # FD error dominates
    assert au._theorem1_tol(tab, 30, 1e-20) == approx(1e-15, rel=1e-12)        # working precision
    assert au._theorem1_tol(tab, 30, 1e-20, 1e-9) == approx(1e-9, rel=1e-12)   # entries
    tab20 = types.SimpleNamespace(source_digits=20)
    assert au._theorem1_tol(tab20, 60, 0.0) == approx(1e-17, rel=1e-12)       # 10^(3 - 20)
    assert au._theorem1_tol(tab20, 60, 0.0, 0.0) == approx(1e-30, rel=1e-12)  # given: not from digits


# ==== audit: Theorem 1 summary ================================================================
def _th(status, res=None, name="x"):
    return Check(f"theorem1:{name}", status, res, "")


def test_theorem1_summary_needs_two_decided_scenes_and_no_failure():
    s = au._theorem1_summary([_th(PASS, 1e-20, "a"), _th(SKIP, 5.0, "b"), _th(SKIP, None, "c")])
    assert s.status == FAIL and "only 1 of 3" in s.detail and "at least 2" in s.detail
    s = au._theorem1_summary([_th(PASS, 1e-20, "a"), _th(PASS, 3e-20, "b"), _th(SKIP, 5.0, "c"),
                              Check("symmetry", FAIL, 9.0, "")])
    assert s.status == PASS and s.residual == 3e-20          # largest decided, the skipped one not counted
    s = au._theorem1_summary([_th(PASS, 1e-20, "a"), _th(FAIL, 1e-3, "b"), _th(PASS, 2e-20, "c")])
    assert s.status == FAIL and "1 failing" in s.detail and s.residual == 1e-3
    s = au._theorem1_summary([_th(PASS, None, "a")])            # one scene: one is enough
    assert s.status == PASS and s.residual == 0.0


# ==== audit: Theorem 1 per scene (the BVP solve replaced by records) ===========================
class _Scene:
    def __init__(self, exact=None):
        self.system = "SYS"
        self.exact = exact
        self.calls = []

    def initial(self, dps=None):
        self.calls.append(dps)
        return 0, [0], [0]


def _r(q0=1e-30, q1=3e-30, fd=1e-35, dps=30):
    return {"theorem1-q0": q0, "theorem1-q1": q1, "fd_error": fd, "dps": dps, "wellposed": "regular",
            "rank_deficiency": 0, "dps_fd": dps, "without_forces_q0": 0.5, "null_support": [1, 2]}


@pytest.fixture
def t1env(monkeypatch):
    from ldaspark.models import scenes
    from ldaspark.analysis import discrete, wellposedness
    env = types.SimpleNamespace(results=[], calls=[], classify=None, scene=_Scene())
    monkeypatch.setattr(scenes, "get_scene", lambda name: env.scene)

    def fake(system, tab, t0, q0, v0, h, dps):
        env.calls.append(dps)
        r = env.results.pop(0)
        if isinstance(r, Exception):
            raise r
        return dict(r, dps=dps)

    def classify(system, tab, t0, q0, v0, h, dps):
        if isinstance(env.classify, Exception):
            raise env.classify
        return {"class": "regular", "rank_deficiency": 0}

    monkeypatch.setattr(discrete, "theorem1_residuals", fake)
    monkeypatch.setattr(wellposedness, "classify_wellposedness", classify)
    return env


TAB0 = types.SimpleNamespace(source_digits=None)


def test_theorem1_scene_residual_is_the_larger_side_and_tolerance_is_inclusive(t1env):
    t1env.results = [_r(q0=1e-20, q1=3e-20)]
    c, fact = au._theorem1_scene(TAB0, "particle", True, 30, True)
    assert c.status == PASS and c.residual == 3e-20 and c.tolerance == approx(1e-15, rel=1e-12)
    assert "agrees with Theorem 1" in c.detail and "null_support" not in fact and fact["theorem1-q0"] == 1e-20
    # one side above the tolerance fails, whichever side
    for q0, q1 in ((1e-20, 2e-15), (2e-15, 1e-20)):
        t1env.results = [_r(q0=q0, q1=q1)]
        c, _ = au._theorem1_scene(TAB0, "particle", True, 30, True)
        assert c.status == FAIL and c.residual == 2e-15
    tol = 10.0 ** (-30 / 2)
    t1env.results = [_r(q0=tol, q1=0.0)]                    # exactly at the tolerance: holds
    assert au._theorem1_scene(TAB0, "particle", True, 30, True)[0].status == PASS
    assert t1env.calls == [30] * 4                          # quick: one dps only


def test_theorem1_scene_claims_without_22(t1env):
    t1env.results = [_r(), _r(q1=1e-3)]
    c, _ = au._theorem1_scene(TAB0, "skate", False, 30, True)
    assert c.status == PASS and "holds although (22) fails" in c.detail
    c, _ = au._theorem1_scene(TAB0, "skate", False, 30, True)
    assert c.status == FAIL and "fails, as expected without (22)" in c.detail


def test_theorem1_scene_without_teeth_is_not_decided(t1env):
    t1env.results = [_r(fd=1e-6, q1=1e-9)]                  # 10 x FD error = 1e-5 > TEETH
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, True)
    assert c.status == SKIP and "not decided" in c.detail
    # a large tolerance from the entries alone is decided, and said so
    t1env.results = [_r(q1=1e-5)]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, True, entry_tol=1e-4)
    assert c.status == PASS and "to the precision of the entries" in c.detail and c.tolerance == 1e-4
    t1env.results = [_r(q1=1e-3)]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, True, entry_tol=1e-4)
    assert c.status == FAIL
    # just below TEETH: decided (10 x 9e-8 = 9e-7 <= 1e-6)
    t1env.results = [_r(fd=9e-8, q1=1e-9)]
    assert au._theorem1_scene(TAB0, "skate", True, 30, True)[0].status == PASS


def test_theorem1_scene_full_retries_at_more_digits(t1env):
    # full: the first solve fails, the second (+20 digits) decides
    t1env.results = [LdasparkError("stall\nmore"), _r()]
    c, fact = au._theorem1_scene(TAB0, "skate", True, 30, False)
    assert t1env.calls == [30, 50] and c.status == PASS and "dps 50" in c.detail
    assert "regular (rank deficiency 0, decided at dps 30, 50" in c.detail
    # a first solve without teeth is retried too; one with teeth is not
    t1env.calls.clear()
    t1env.results = [_r(fd=1e-5), _r()]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, False)
    assert t1env.calls == [30, 50] and c.status == PASS
    t1env.calls.clear()
    t1env.results = [_r(), _r(q1=1.0)]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, False)
    assert t1env.calls == [30] and c.status == PASS
    # classification failure is reported, not fatal
    t1env.classify = LdasparkError("boom")
    t1env.results = [_r()]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 30, False)
    assert c.status == PASS and "classification failed: boom" in c.detail


def test_theorem1_scene_both_solves_failing_is_skip(t1env):
    t1env.results = [LdasparkError("a"), LdasparkError("b\nc")]
    c, fact = au._theorem1_scene(TAB0, "skate", True, 30, False)
    assert c.status == SKIP and fact is None and "(b)" in c.detail and "at dps 30 and 50" in c.detail
    t1env.results = [LdasparkError("a")]
    c, fact = au._theorem1_scene(TAB0, "skate", True, 30, True)
    assert c.status == SKIP and "at dps 30;" in c.detail and "and 50" not in c.detail
    assert t1env.scene.calls[-1] == 30 + 45


def test_theorem1_checks_skip_without_discrete(monkeypatch):
    import importlib.util
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "ldaspark.analysis.discrete" else real(name, *a))
    checks, facts = au.theorem1_checks(TAB0, True, True, 30, True)
    assert [c.name for c in checks] == ["theorem1"] and checks[0].status == SKIP and facts == {}


def test_theorem1_with_discrete_scenes_facts_and_symmetry(monkeypatch):
    seen = {}

    def scene(tab, name, hyp22, dps, quick, tol22):
        seen.setdefault("tol22", []).append(tol22)
        return Check(f"theorem1:{name}", PASS, 1e-20, ""), (None if name == "robot" else {"n": name})

    def sym(tab, dps, scenes, tol23):
        seen["sym"] = (list(scenes), tol23)
        return [Check("symmetry", PASS, 0.0, "")], {"symmetry:x": 1}

    monkeypatch.setattr(au, "_theorem1_scene", scene)
    monkeypatch.setattr(au, "_symmetry_checks", sym)
    checks, facts = au._theorem1_with_discrete(TAB0, True, True, 30, True, au.PAPER_SCENES, (1e-9, 2e-9))
    assert seen["tol22"] == [1e-9] * 4 and seen["sym"] == (["particle", "skate"], 2e-9)
    assert set(facts) == {"theorem1:particle", "theorem1:skate", "theorem1:mp-particles", "symmetry:x"}
    assert [c.name for c in checks][-2:] == ["theorem1", "symmetry"]
    checks, _ = au._theorem1_with_discrete(TAB0, True, True, 30, False, au.PAPER_SCENES)
    assert seen["sym"] == (list(au.PAPER_SCENES), None) and seen["tol22"][-1] is None
    checks, facts = au._theorem1_with_discrete(TAB0, True, False, 30, True, ("skate",))
    assert checks[-1].name == "symmetry" and checks[-1].status == SKIP and "symmetry:x" not in facts


# ==== audit: symmetry per scene ===============================================================
def _sym(ld=1e-20, fp=1e-20, fm=1e-20, phi=1e-20, wp="regular"):
    return {"symmetry-Ld": ld, "symmetry-fd-plus": fp, "symmetry-fd-minus": fm, "symmetry-Phi": phi,
            "wellposed": wp, "tangent_dim": (1, 1), "dps": 30}


@pytest.fixture
def symenv(monkeypatch):
    from ldaspark.models import scenes
    from ldaspark.analysis import symmetry
    env = types.SimpleNamespace(results={}, scene=_Scene())
    monkeypatch.setattr(scenes, "get_scene", lambda name: env.scene)

    def fake(system, tab, t0, q0, v0, h, dps):
        r = env.results[len(env.scene.calls) - 1]
        if isinstance(r, Exception):
            raise r
        return r
    monkeypatch.setattr(symmetry, "check_symmetry", fake)
    return env


def test_symmetry_checks_judge_every_identity_of_a_wellposed_bvp(symenv):
    tol = 10.0 ** (-30 / 2)
    for k in ("ld", "fp", "fm", "phi"):
        symenv.scene.calls.clear()
        symenv.results = {0: _sym(**{k: 1e-10})}
        checks, facts = au._symmetry_checks(TAB0, 30, ["skate"])
        assert checks[0].status == FAIL and checks[0].residual == 1e-10, k
        assert checks[-1].name == "symmetry" and checks[-1].status == FAIL
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(ld=tol, fp=3e-20)}
    checks, facts = au._symmetry_checks(TAB0, 30, ["skate"])
    assert checks[0].status == PASS and checks[0].residual == tol      # at the tolerance: holds
    assert facts["symmetry:skate"]["wellposed"] == "regular" and "tangent_dim" not in facts["symmetry:skate"]
    assert symenv.scene.calls == [35]


def test_symmetry_checks_singular_bvp_judges_only_Ld_and_Phi(symenv):
    symenv.results = {0: _sym(fp=0.5, fm=0.5, phi=2e-20, wp="singular")}
    checks, _ = au._symmetry_checks(TAB0, 30, ["skate"])
    assert checks[0].status == PASS and checks[0].residual == 2e-20 and "not judged" in checks[0].detail
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(fp=0.5, wp="singular", phi=1e-3)}
    assert au._symmetry_checks(TAB0, 30, ["skate"])[0][0].status == FAIL


def test_symmetry_summary_needs_one_decided_scene_and_no_failure(symenv):
    symenv.results = {0: LdasparkError("no\nmore"), 1: _sym(ld=2e-20)}
    checks, _ = au._symmetry_checks(TAB0, 30, ["skate", "particle"], entry_tol=1e-25)
    assert [c.status for c in checks] == [SKIP, PASS, PASS]
    assert checks[0].detail.endswith("(no)") and checks[-1].residual == 2e-20
    assert "decided on 1 of 2 scenes, 0 failing" in checks[-1].detail
    symenv.scene.calls.clear()
    symenv.results = {0: LdasparkError("x")}
    checks, _ = au._symmetry_checks(TAB0, 30, ["skate"])
    assert [c.status for c in checks] == [SKIP, FAIL] and "at least one needed" in checks[-1].detail
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(), 1: _sym(phi=1e-3)}
    checks, _ = au._symmetry_checks(TAB0, 30, ["skate", "particle"])
    assert [c.status for c in checks] == [PASS, FAIL, FAIL] and checks[-1].residual == 1e-3
    assert au._symmetry_checks(TAB0, 30, []) == ([], {})
    # the entries' tolerance counts when larger than the working precision
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(ld=1e-12)}
    assert au._symmetry_checks(TAB0, 30, ["skate"], entry_tol=1e-11)[0][0].status == PASS


# ==== audit: algebraic checks on small tableaux ===============================================
def _tab(**over):
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
         "b": [1], "b_hat": [1], "b_tilde": [1]}
    d.update(over)
    return from_json_dict(d, "t")


def _extab(c):
    """A one-stage exact tableau with c = [c] (expressions the file parser does not take)."""
    tab = get_method("gauss-1", exact=True)
    ex = dict(tab.exact)
    ex["c"] = sympy.Matrix([[c]])
    return type(tab)("x", 1, exact=ex)


def _lobatto2(**over):
    d = {"c": [0, 1], "A": [[0, 0], ["1/2", "1/2"]], "A_hat": [["1/2", 0], ["1/2", 0]],
         "A_tilde": [["1/2", 0], ["1/2", 0]], "b": ["1/2", "1/2"], "b_hat": ["1/2", "1/2"],
         "b_tilde": ["1/2", "1/2"]}
    d.update(over)
    return from_json_dict(d, "l2")


def _alg(tab):
    ar, e, _ = au.decide_arith(tab, 30)
    C, facts = au.algebraic_checks(tab, ar, e, 30)
    return {c.name: c for c in C}, facts


def test_algebraic_facts_22_needs_both_and_23_needs_all():
    C, f = _alg(_lobatto2())
    assert f["22"] and f["23"] and C["22a"].status == PASS and C["22b"].status == PASS
    assert f["predicted_order"] == 2 and C["consistent"].status == PASS
    # (22b) alone violated (A_hat changed, b_hat = b still)
    C, f = _alg(_lobatto2(A_hat=[["1/2", 0], ["1/2", "1/10"]]))
    assert C["22a"].status == PASS and C["22b"].status == FAIL and not f["22"]
    # (22a) alone violated... (22b) then fails too unless compensated: check the 1-stage case
    C, f = _alg(_tab(b_hat=["11/10"], A_hat=[["6/11"]]))   # b_hat a + b a_hat - b_hat b: 0.6 + 6/11 - 1.1 != 0
    assert C["22a"].status == FAIL and not f["22"]
    C, f = _alg(_tab(b_hat=["11/10"], A_hat=[["11/20"]]))  # 11/10*1/2 + 11/20 - 11/10 = 0: (22b) holds
    assert C["22a"].status == FAIL and C["22b"].status == PASS and not f["22"]
    # one of the four (23) conditions fails: (23d) only
    C, f = _alg(_lobatto2(A_tilde=[["1/2", 0], ["1/2", "1/10"]]))
    assert [C[k].status for k in ("23a", "23b", "23c", "23d")] == [PASS, PASS, PASS, INFO] and not f["23"]
    assert f["22"]
    C, f = _alg(_lobatto2(c=["1/5", 1], A=[["1/5", 0], ["1/2", "1/2"]]))
    assert C["23a"].status == INFO and not f["23"]


def test_inconsistent_method_is_order_0_and_fails():
    C, f = _alg(_tab(b=["1/2"], b_hat=["1/2"], b_tilde=["1/2"], A=[["1/4"]], A_hat=[["1/4"]], A_tilde=[["1/4"]],
                     c=["1/4"]))
    assert f["predicted_order"] == 0 and C["consistent"].status == FAIL
    C, f = _alg(_tab(c=[1], A=[[1]], A_hat=[[0]], A_tilde=[[0]]))     # Euler pair: order 1 exactly
    assert f["predicted_order"] == 1 and C["consistent"].status == PASS


def test_decide_arith_choices():
    flt = from_json_dict({"c": [0.5], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1.0],
                          "b_hat": [1.0], "b_tilde": [1.0]}, "f")
    with pytest.raises(InputError):
        au.decide_arith(flt, 30, "exact")
    ar, e, why = au.decide_arith(flt, 30)
    assert ar.ball and "float64" in why
    ar, e, why = au.decide_arith(_tab(), 30, "mp")
    assert ar.ball and "--arith mp" in why
    ar, e, why = au.decide_arith(_tab(), 30)
    assert ar.exact and ar.deadline is not None and "cheap" in why
    dec = _tab(c=["0.5"])
    ar, e, why = au.decide_arith(dec, 30, "exact")
    assert ar.exact and "decimal literals read as exact rationals" in why
    ar, e, why = au.decide_arith(dec, 30)
    assert ar.ball


def test_predicted_order_reads_the_forced_ode_order():
    assert au.predicted_order(None, {"order:forced-ode": 3, "order:pair": 5}) == 3


# ==== audit: verdict and disagreement =========================================================
def _vres(hyp22=True, hyp23=True, th=(), summ=PASS, conv=(PASS, PASS), p=2, exact=True, extra=(), **facts):
    checks = [Check("22a", PASS if hyp22 else FAIL, 1e-30, "d22a", tolerance=1e-40),
              Check("22b", PASS if hyp22 else FAIL, 2e-30, "d22b", tolerance=3e-40)]
    checks += list(th)
    if summ is not None:
        checks.append(Check("theorem1", summ, None, ""))
    checks += [Check("convergence:skate", conv[0], 0.1, ""), Check("convergence:particle", conv[1], 0.1, ""),
               Check("constraint", PASS, 1e-15, ""), Check("energy", INFO, 2e-6, "")] + list(extra)
    f = {"22": hyp22, "23": hyp23, "predicted_order": p, "order:pair": p, "arithmetic": "ARITH",
         "convergence:skate": {"observed": 2.01}, "convergence:particle": {"observed": 1.98}}
    f.update(facts)
    return _res(checks, f, exact=exact)


def test_verdict_22_and_theorem1_sentences():
    v = au.verdict(_vres(th=[_th(PASS, 1e-20, "a"), _th(PASS, 3e-20, "b")]))
    assert "satisfies (22a) and (22b) exactly" in v and "agrees (largest residual 3.0e-20)" in v
    assert "Result: all checks agree with the theory." in v and "stages" in v
    v = au.verdict(_vres(exact=False, decided_to="the 20 digits given"))
    assert "to the 20 digits given (ARITH)" in v
    r = _vres(hyp22=False)
    r.checks[0] = Check("22a", PASS, 0.0, "ok")
    v = au.verdict(r)
    assert "violates (22b) (d22b), so Theorem 1 does not apply" in v and "(22a)" not in v.split("Result")[0]
    v = au.verdict(_vres(th=[_th(PASS, 1e-20, "a"), _th(FAIL, 1e-3, "b"), _th(SKIP, 9.0, "c")], summ=FAIL))
    assert "fails on 1 of 2 decided scenes (largest residual 1.0e-03); not decided on c" in v
    v = au.verdict(_vres(th=[_th(PASS, 1e-20, "a"), _th(SKIP, None, "b")], summ=FAIL))
    assert "is decided on too few scenes" in v and "Result: 1 check(s) failed: theorem1." in v
    v = au.verdict(_vres(th=[], summ=SKIP))
    assert "not checked numerically" in v
    v = au.verdict(_vres(th=[], summ=None))
    assert "numerical check of Theorem 1" not in v


def test_verdict_orders_symmetry_and_notes():
    v = au.verdict(_vres(hyp23=False, conv=(PASS, FAIL)))
    assert "does not satisfy (23)" in v and "do NOT agree with it." in v
    assert "2.01 on the skate, 1.98 on the particle" in v
    v = au.verdict(_vres(conv=(FAIL, PASS)))
    assert "do NOT agree" in v and "It satisfies the symmetry conditions (23)" in v
    v = au.verdict(_vres(**{"order:forced-ode-capped": True}))
    assert "2+ for" in v and "agree with it." in v and "NOT" not in v
    r = _vres()
    del r.facts["convergence:skate"], r.facts["convergence:particle"]
    assert "(none: runs failed)" in au.verdict(r)
    fo = lambda x: [Check("order:forced-ode", INFO, x, "")]
    assert "misses by only 5.0e-09" in au.verdict(_vres(extra=fo(5e-9)))
    assert "misses by only" not in au.verdict(_vres(extra=fo(2e-8)))
    assert "misses by only" not in au.verdict(_vres(extra=fo(0.0)))
    v = au.verdict(_vres(p=0))
    assert "Order 0 means" in v and "by more than the precision" not in v
    assert "by more than the precision" in au.verdict(_vres(p=0, exact=False))
    assert "Order 0" not in au.verdict(_vres(p=1))
    assert "(Claimed order of this built-in: 4.)" in au.verdict(_vres(claimed_order=4))
    assert "Claimed order" not in au.verdict(_vres(claimed_order=None))
    v = au.verdict(_vres())
    assert "satisfied to 1.00e-15" in v and "run is 2.00e-06" in v
    r = _vres()
    r.checks = [c for c in r.checks if c.name != "energy"]
    assert "short particle run is -." in au.verdict(r)


def test_disagreement_rules():
    assert au.disagreement(_vres(summ=None)) == ""
    assert au.disagreement(_vres(summ=SKIP)) == ""
    assert au.disagreement(_vres(th=[_th(SKIP, 1.0, "a")], summ=FAIL)) == ""
    assert au.disagreement(_vres(th=[_th(PASS, 1e-20, "a")])) == ""
    # (22) violated, Theorem 1 passes: the smallest tolerance of the passing scenes decides
    th = [Check("theorem1:a", PASS, 1e-20, "", tolerance=1e-6), Check("theorem1:b", PASS, 1e-20, "", tolerance=1e-10),
          Check("theorem1:c", FAIL, 1.0, "", tolerance=1e-30)]
    r = _vres(hyp22=False, th=th)
    r.checks[1] = Check("22b", FAIL, 1e-8, "", tolerance=0.0)          # r22 = max(1e-30, 1e-8)
    d = au.disagreement(r)
    assert d.startswith("DISAGREEMENT: (22) is violated") and "passes on a, b." in d and "unexpected" in d
    r.checks[1] = Check("22b", FAIL, 1e-11, "", tolerance=0.0)
    d = au.disagreement(r)
    assert "below the resolution" in d and "1.0e-11" in d and "1e-10" in d
    # a lone passing scene: its tolerance None counts as 0
    r = _vres(hyp22=False, th=[_th(PASS, 1e-20, "a")])
    assert "unexpected" in au.disagreement(r)
    # (22) holds, Theorem 1 fails
    th = [_th(FAIL, 1e-3, "a"), _th(FAIL, 2e-3, "b"), _th(PASS, 5.0, "z")]
    d = au.disagreement(_vres(th=th, summ=FAIL))
    assert "fails on a, b (largest residual 2.0e-03)" in d and "numerical" in d and "holds exactly" in d
    d = au.disagreement(_vres(th=th, summ=FAIL, exact=False))
    assert "limited precision: (22) holds only to 2.0e-30 (uncertainty 3.0e-40)" in d
    r = _vres(th=th, summ=FAIL, exact=False)
    r.checks[0] = Check("22a", PASS, 0.0, "")
    r.checks[1] = Check("22b", PASS, None, "")
    assert "numerical" in au.disagreement(r)


# ==== audit: report and CLI ===================================================================
def test_to_markdown_sections():
    r = _vres()
    r.verdict = "V"
    r.checks.append(Check("x", INFO, None, "a|b"))
    md = au.to_markdown(r, "ldaspark audit X")
    assert "- reproduce: `ldaspark audit X`" in md and "- exit code 0" in md and "a\\|b" in md
    assert "## Coefficients" not in md and "the algebraic checks are decided" not in md
    r.facts.update(arithmetic_reason="R", entries="E", coefficients={"b": ["1"]})
    r.exact = False
    md = au.to_markdown(r)
    assert "reproduce" not in md and "decided in ball arithmetic because R" in md and "b = ['1']" in md
    assert md.endswith("```\n")
    r.exact = True
    assert "decided exactly because R" in au.to_markdown(r)


def _args(**kw):
    d = dict(file=None, method=None, example=None, dps=30, quick=True, max_stages=None, arith="auto",
             out=None, json=None)
    d.update(kw)
    return argparse.Namespace(**d)


def test_load_for_args_choices_and_dps_bounds():
    names = au.example_names()
    assert names and all(not n.endswith(".json") for n in names)
    with pytest.raises(InputError, match="exactly one"):
        au.load_for_args(_args(example=names[0], method="gauss-1"))
    with pytest.raises(InputError, match="exactly one"):
        au.load_for_args(_args(example=names[0], file="x.json"))
    with pytest.raises(InputError, match="unknown example"):
        au.load_for_args(_args(example="no-such"))
    a = _args(example="gauss2")
    tab = au.load_for_args(a)
    assert a.file.endswith("gauss2.json") and tab.s == 2
    for dps, ok in ((9, False), (10, True), (200, True), (201, False)):
        if ok:
            au.load_for_args(_args(method="gauss-1", dps=dps))
        else:
            with pytest.raises(InputError, match="--dps"):
                au.load_for_args(_args(method="gauss-1", dps=dps))
    assert au.load_for_args(_args(method="gauss-3")).exact is not None          # s <= 3: exact
    assert au.load_for_args(_args(method="gauss-4")).exact is None              # s = 4: computed
    assert au.load_for_args(_args(method="gauss-4", arith="exact")).exact is not None
    assert au.load_for_args(_args(method="gauss-2", arith="mp")).exact is None
    assert au.load_for_args(_args(method="euler-i", arith="mp")).exact is not None   # exact already


def test_run_writes_report_and_json_and_returns_exit_code(monkeypatch, tmp_path, capsys):
    r = _vres()
    r.checks.append(Check("bad", FAIL, 1.0, ""))
    r.verdict = "VV"
    monkeypatch.setattr(au, "audit", lambda tab, **kw: r)
    out, js = tmp_path / "a.md", tmp_path / "a.json"
    rc = au.run(_args(method="gauss-1", out=str(out), json=str(js), arith="mp", quick=False))
    assert rc == 1 and "VV" in out.read_text()
    d = json.loads(js.read_text())
    assert d["command"] == "ldaspark audit --method gauss-1 --dps 30 --arith mp" and d["exit_code"] == 1
    r.checks.pop()
    rc = au.run(_args(method="gauss-1"))
    assert rc == 0 and "--method gauss-1 --dps 30 --quick`" in capsys.readouterr().out


# ==== audit_checks: helpers ===================================================================
def test_worst_largest_magnitude_first_label_on_ties():
    ar = mp_ar(1e-10)
    w, lab, ok, rad = ac._worst(ar, [(mpv(1e-12), "a"), (mpv(-5e-3), "c"), (mpv(2e-3), "d"), (mpv(5e-3), "e")])
    assert (w, lab, ok, rad) == (approx(5e-3), "c", False, 1e-10)
    w, lab, ok, rad = ac._worst(ar, [(mpv(2e-3), "a"), (mpv(1e-3), "b")])
    assert lab == "a" and w == approx(2e-3)
    # all within the tolerance: holds, and the size reported is the largest |value|
    w, lab, ok, rad = ac._worst(ar, [(mpv(1e-12), "a"), (mpv(-3e-11), "b"), (mpv(2e-11), "c")])
    assert ok and lab is None and w == approx(3e-11)
    ex = oc.Arith("exact", K=sympy.QQ)
    w, lab, ok, rad = ac._worst(ex, [(sympy.QQ(0), "a"), (sympy.QQ(0), "b")])
    assert (w, lab, ok, rad) == (0.0, None, True, 0.0)
    w, lab, ok, rad = ac._worst(ex, [(sympy.QQ(0), "a"), (sympy.QQ(-1, 4), "b")])
    assert (w, lab, ok) == (0.25, "b", False)


def test_mode_beyond_tol_per_arithmetic():
    ex, mp, ball = oc.Arith("exact", K=sympy.QQ), mp_ar(1e-10), oc.Arith("ball", dps=40, scope="")
    assert ac._mode(ex) == "exactly" and ac._beyond(ex, 1.0) == "exactly nonzero" and ac._tol(ex, 1.0) == 0.0
    assert ac._mode(mp) == "to tolerance 1.0e-10" and ac._beyond(mp, 1.0) == "above the tolerance 1.0e-10"
    assert ac._tol(mp, 1.0) == 1e-10
    assert ac._mode(ball, 1e-50, 2e-45) == "to 40 digits (largest |residual| 1.0e-50, within the uncertainty 2.0e-45)"
    assert ac._beyond(ball, 2e-45) == "beyond the uncertainty 2.0e-45 (40 digits)" and ac._tol(ball, 2e-45) == 2e-45
    ball.scope = "the 20 digits given"
    assert "to the 20 digits given" in ac._mode(ball) and "(the 20 digits given)" in ac._beyond(ball, 0.0)


def test_fmt_jsonable_and_as_dict():
    assert ac._fmt(None) == "-" and ac._fmt(0.0) == "0.0" and ac._fmt(float("inf")) == "inf"
    assert ac._fmt(1.5) == "1.50e+00" and ac._fmt(0) == "0.00e+00"
    x = {1: (True, None, 3, "s", np.float64(2.5), float("nan"), mpmath.mpf(1) / 4, float("-inf")), "o": object}
    j = ac._jsonable(x)
    assert j["1"] == [True, None, 3, "s", 2.5, "nan", 0.25, "-inf"] and isinstance(j["o"], str)
    json.dumps(j)
    d = Check("n", FAIL, float("inf"), "d", "ar", float("nan")).as_dict()
    assert d["residual"] is None and d["tolerance"] is None
    d = Check("n", FAIL, 1e-3, "d", None, 2e-3).as_dict()
    assert d["residual"] == 1e-3 and d["tolerance"] == 2e-3
    assert Check("n", FAIL, None, "d").as_dict()["residual"] is None


def test_coefficient_strings_per_origin():
    t = _tab(c=["0.5"])
    cs = ac._coefficient_strings(t)
    assert cs["c"] == ["0.5"] and cs["A"] == [["1/2"]] and cs["omega"] == []
    cs = ac._coefficient_strings(get_method("gauss-1", exact=True))
    assert cs["b"] == ["1"] and cs["A"] == [["1/2"]]
    cs = ac._coefficient_strings(gauss(2))
    assert cs["b"] == ["0.5", "0.5"] and len(cs["A"]) == 2 and isinstance(cs["A"][0], list)
    assert abs(float(cs["c"][0]) - (0.5 - math.sqrt(3) / 6)) < 1e-15


# ==== audit_checks: algebraic checks ==========================================================
def test_row_sums_pass_and_worst_row():
    ar = mp_ar(1e-10)
    e = {"c": mpv([0.5, 1.0, 0.25]), "A": mpv([[0.25, 0.25, 0], [0.5, 0.5, 0], [0.25, 0, 0]]),
         "A_hat": mpv([[0.5, 0, 0], [1.0, 0.1, 0], [0.25, 0, -0.05]])}
    c = ac.check_row_sums(ar, e, "A")
    assert c.status == PASS and c.name == "row-sums:A" and c.tolerance == 1e-10
    c = ac.check_row_sums(ar, e, "A_hat")
    assert c.status == INFO and "worst at row 2" in c.detail and c.residual == approx(0.1)
    assert "t-dependence" in c.detail
    e["A"][2][2] = mpv(0.3)
    c = ac.check_row_sums(ar, e, "A")
    assert c.status == INFO and "row 3" in c.detail and "stage order" in c.detail


def test_22a_22b_decided_entrywise_with_the_transposed_index():
    ar = oc.Arith("exact", K=sympy.QQ)
    Q = sympy.QQ
    b = [Q(1, 2), Q(1, 2)]
    A = [[Q(1, 10), Q(2, 10)], [Q(3, 10), Q(4, 10)]]
    Ah = [[Q(4, 10), Q(2, 10)], [Q(3, 10), Q(1, 10)]]     # a_hat_ji = 1/2 - a_ij
    e = {"b": b, "b_hat": list(b), "A": A, "A_hat": Ah}
    assert ac.check_22a(ar, e).status == PASS and ac.check_22b(ar, e).status == PASS
    assert ac.check_22b(ar, e).residual == 0.0 and ac.check_22b(ar, e).tolerance == 0.0
    e2 = dict(e, A_hat=[[Q(4, 10), Q(2, 10)], [Q(3, 10), Q(1, 10) + Q(1, 100)]])
    c = ac.check_22b(ar, e2)
    assert c.status == FAIL and "(i, j) = (2, 2)" in c.detail and c.residual == approx(0.005)
    e3 = dict(e, b_hat=[Q(1, 2), Q(6, 10)])
    c = ac.check_22a(ar, e3)
    assert c.status == FAIL and "i = 2" in c.detail and c.residual == approx(0.1)


def test_check_23_each_condition_separately():
    ar = oc.Arith("exact", K=sympy.QQ)
    Q = sympy.QQ
    h = Q(1, 2)
    base = {"c": [Q(1, 4), Q(3, 4)], "b": [h, h], "b_hat": [h, h], "b_tilde": [h, h],
            "A": [[Q(1, 4), Q(0)], [h, Q(1, 4)]], "A_hat": [[Q(1, 4), Q(0)], [h, Q(1, 4)]],
            "A_tilde": [[Q(1, 4), Q(0)], [h, Q(1, 4)]]}
    assert [c.status for c in ac.check_23(ar, base)] == [PASS] * 4
    bad = dict(base, A_tilde=[[Q(1, 4), Q(0)], [Q(1, 4), Q(1, 4)]])
    st = [c.status for c in ac.check_23(ar, bad)]
    assert st == [PASS, PASS, PASS, INFO]
    bad = dict(base, c=[Q(1, 4), Q(1, 2)])
    c = ac.check_23(ar, bad)[0]
    assert c.status == INFO and c.residual == 0.25 and "i = 1" in c.detail
    bad = dict(base, b_hat=[h, Q(1, 4)], A_hat=[[Q(1, 4), Q(0)], [h, Q(0)]])
    c = ac.check_23(ar, bad)[2]
    assert c.status == INFO and "not symmetric" in c.detail


def _omtab(omega, s, digits=None, b=None, c=None):
    b = b or [1.0 / s] * s
    c = c or [(i + 0.5) / s for i in range(s)]
    return types.SimpleNamespace(s=s, source_digits=digits,
                                 mp_entries=lambda dps: {"omega": mpv(omega), "b": mpv(b), "c": mpv(c)})


def test_omega_rank_tolerance_relative_to_entry_digits_and_scale():
    assert ac.check_omega(_omtab([], 1), None, None, 30).residual is None
    c = ac.check_omega(_omtab([[1, 0, 0], [0, 1e-6, 0]], 3, digits=10), None, None, 30)
    assert c.status == PASS and c.residual == approx(1e-6) and c.tolerance == approx(3e-7)
    with pytest.raises(TableauError, match="singular"):
        ac.check_omega(_omtab([[1, 0, 0], [0, 1e-7, 0]], 3, digits=10), None, None, 30)
    with pytest.raises(TableauError):                       # scaled by the largest singular value
        ac.check_omega(_omtab([[100, 0, 0], [0, 1e-5, 0]], 3, digits=10), None, None, 30)
    c = ac.check_omega(_omtab([[0.5, 0, 0], [0, 1e-6, 0]], 3, digits=10), None, None, 30)
    assert c.tolerance == approx(3e-7)              # scale never below 1
    with pytest.raises(TableauError):
        ac.check_omega(_omtab([[0, 0]], 2), None, None, 30)
    c = ac.check_omega(_omtab([[3, 4]], 2), None, None, 30)
    assert c.residual == approx(5.0)


def test_omega_default_span():
    assert ac.check_omega_default(_omtab([], 1), 30).status == INFO
    b, c = [0.5, 0.5], [0.25, 0.75]
    ok = ac.check_omega_default(_omtab([[1, 1]], 2, b=b, c=c), 30)        # parallel to (b_j)
    assert ok.status == PASS and ok.residual == approx(0.0, abs=1e-20)
    no = ac.check_omega_default(_omtab([[1, -1]], 2, b=b, c=c), 30)
    assert no.status == INFO and "stacked rank 2" in no.detail and no.residual == approx(math.sqrt(0.5) * 1)
    b3, c3 = [1 / 6, 2 / 3, 1 / 6], [0.0, 0.5, 1.0]
    dflt = [[x for x in b3], [bj * cj for bj, cj in zip(b3, c3)]]
    assert ac.check_omega_default(_omtab(dflt, 3, b=b3, c=c3), 30).status == PASS
    om = [[1, 0, 0], [0, 1, 0]]
    assert ac.check_omega_default(_omtab(om, 3, b=b3, c=c3), 30).status == INFO


def test_order_checks_facts_on_implicit_midpoint_and_euler():
    ar, e = oc.exact_arith(get_method("gauss-1", exact=True))
    C, f = ac.order_checks(ar, e)
    assert f["order:A"] == 2 and f["order:pair"] == 2 and f["order:forced-ode"] == 2
    assert f["R_inf:A"] == "-1" and f["BCD:A"] == {"B": 2, "C": 1, "D": 1}
    assert not f["order:forced-ode-capped"]
    names = {c.name: c for c in C}
    assert "first failing tree" in names["order:A"].detail and "A invertible" in names["stability:A"].detail
    ar, e = oc.exact_arith(_tab(c=[1], A=[[1]], A_hat=[[1]], A_tilde=[[1]]))     # implicit Euler
    C, f = ac.order_checks(ar, e)
    assert f["R_inf:A"] == "0" and "L-stable-type" in {c.name: c for c in C}["stability:A"].detail


# ==== audit_checks: numerical checks ==========================================================
class _Sol:
    def __init__(self, q, v, k=(0.0,), energy=None):
        self.q, self.v = [np.array([0.0]), np.array(q, dtype=float)], [np.array([0.0]), np.array(v, dtype=float)]
        self.constraint = np.array(k, dtype=float)
        self.energy = energy


def test_probe_step_rejects_failure_and_nonfinite(monkeypatch):
    from ldaspark.core import spark
    mode = {"m": "nan"}

    class Fake:
        def __init__(self, system, tab):
            pass

        def step(self, t0, q0, v0, h):
            if mode["m"] == "raise":
                raise LdasparkError("newton\nx")
            bad = np.full_like(np.asarray(q0, dtype=float), np.nan)
            ok = np.asarray(q0, dtype=float)
            return types.SimpleNamespace(q1=bad if mode["m"] == "nan" else ok,
                                         v1=bad if mode["m"] == "vnan" else np.asarray(v0, dtype=float))
    monkeypatch.setattr(spark, "SparkMethod", Fake)
    tab = types.SimpleNamespace(name="T")
    for m in ("nan", "vnan"):
        mode["m"] = m
        with pytest.raises(InputError, match="non-finite"):
            ac.probe_step(tab)
    mode["m"] = "raise"
    with pytest.raises(InputError, match=r"cannot be solved .*\(skate, h = 0.05\): newton$"):
        ac.probe_step(tab)
    mode["m"] = "ok"
    assert ac.probe_step(tab) is None


def test_observed_order_finest_usable_slope_and_reference(monkeypatch):
    from ldaspark.models import scenes
    sc = types.SimpleNamespace(exact=object(), system="S",
                               exact_solution=lambda t, dps: ([1.0], [2.0], None))
    monkeypatch.setattr(scenes, "get_scene", lambda name: sc)
    errs = {4: 1e-2, 8: 2.5e-3, 16: 1e-9}
    monkeypatch.setattr(ac, "_run", lambda tab, scene, N, t, dps: _Sol([1.0 + errs[N]], [2.0 - errs[N] / 2],
                                                                        k=[[1e-16, -3e-15]] if N == 8 else [1e-16]))
    r = ac.observed_order(None, "x", [4, 8, 16], 1, None, 1e-8)
    assert r["errors"] == approx([1e-2, 2.5e-3, 1e-9], rel=1e-6)
    assert r["slopes"][0] == approx(2.0, rel=1e-6) and r["observed"] == approx(2.0, rel=1e-6)
    assert r["max_constraint"] == approx(3e-15) and r["reference"] == "exact solution"
    r = ac.observed_order(None, "x", [4, 8, 16], 1, None, 1e-12)          # floor lower: the finest pair
    assert r["observed"] == approx(math.log(2.5e6) / math.log(2), rel=1e-6)
    errs[8] = errs[4]                                                        # equal: slope 0, usable
    assert ac.observed_order(None, "x", [4, 8], 1, None, 1e-12)["observed"] == approx(0.0, abs=1e-9)
    errs[16] = 0.0
    r = ac.observed_order(None, "x", [8, 16], 1, None, 0.0)
    assert math.isnan(r["slopes"][0]) and math.isnan(r["observed"])
    # without an exact solution: a reference run at twice the finest N, by another tableau
    runs = []
    sc.exact = None
    errs.update({4: 1e-2, 8: 1e-3})
    monkeypatch.setattr(ac, "_run", lambda tab, scene, N, t, dps: runs.append((tab, N)) or
                        _Sol([1.0 + errs.get(N, 0.0)], [2.0]))
    r = ac.observed_order(gauss(2), "x", [4, 8], 1, None, 0.0)
    assert runs[0][1] == 16 and runs[0][0].name == "gauss-5" and r["reference"] == "gauss-5 with h = 1/16"
    assert r["observed"] == approx(math.log(10) / math.log(2), rel=1e-6)
    assert ac._reference_tableau(types.SimpleNamespace(s=5)).s == 6


def test_step_counts():
    assert ac._step_counts(0, False) == [16, 32, 64] == ac._step_counts(1, True)
    assert ac._step_counts(2, True) == [8, 16, 32] == ac._step_counts(2, False)
    assert ac._step_counts(3, False) == [4, 8, 16] and ac._step_counts(3, True) == [4, 8]
    assert ac._step_counts(4, False) == [4, 8, 16] and ac._step_counts(6, True) == [4, 8]


@pytest.fixture
def convenv(monkeypatch):
    env = types.SimpleNamespace(obs={}, calls=[], errs=[1e-3, 1e-4], k={"skate": 1e-16, "particle": 2e-16})

    def fake(tab, scene, Ns, t_end, wdps, floor):
        env.calls.append((scene, list(Ns), wdps, floor))
        o = env.obs[scene]
        if isinstance(o, Exception):
            raise o
        return {"observed": o, "N": Ns, "errors": env.errs[:len(Ns)], "reference": "R", "max_constraint": env.k[scene]}
    monkeypatch.setattr(ac, "observed_order", fake)
    return env


TABX = types.SimpleNamespace(source_digits=None, decimal_digits=None, decimal_digits_min=None)


def test_convergence_two_sided_with_slack(convenv):
    p, s = 4, ac.ORDER_SLACK
    for obs, want in ((p - s - 0.01, FAIL), (p - s + 0.01, PASS), (p, PASS), (p + s - 0.01, PASS),
                      (p + s + 0.01, FAIL), (float("nan"), FAIL)):
        convenv.obs = {"skate": obs, "particle": p}
        C, f = ac.convergence_checks(TABX, p, 30, False)
        assert C[0].status == want, obs
        assert C[1].status == PASS and C[1].residual == 0.0
        if math.isfinite(obs):
            assert C[0].residual == approx(abs(obs - p))
        else:
            assert C[0].residual is None and "no usable slope" in C[0].detail
    # at the tree cap only the lower bound counts
    convenv.obs = {"skate": p + 2, "particle": p - 1}
    C, _ = ac.convergence_checks(TABX, p, 30, False, capped=True)
    assert [C[0].status, C[1].status] == [PASS, FAIL] and "tree cap" in C[0].detail


def test_convergence_entry_floor_and_precision(convenv):
    dec = types.SimpleNamespace(source_digits=None, decimal_digits=8, decimal_digits_min=None)   # floor 1e-5
    convenv.obs = {"skate": 6.0, "particle": 4.0}
    convenv.errs = [1e-3, 2e-6]
    C, _ = ac.convergence_checks(dec, 4, 30, False)
    assert C[0].status == PASS and "only the lower bound" in C[0].detail
    convenv.errs = [1e-3, 2e-5]
    assert ac.convergence_checks(dec, 4, 30, False)[0][0].status == FAIL
    convenv.errs = [1e-3, 2e-6]
    assert ac.convergence_checks(TABX, 4, 30, False)[0][0].status == FAIL
    # float64 up to order 4 (floor 1e-11), dps digits above (floor from min(dps, source digits))
    convenv.calls.clear()
    _, f = ac.convergence_checks(TABX, 4, 30, True)
    assert f["convergence_dps"] is None and convenv.calls[0][2] is None
    assert convenv.calls[0][3] == approx(1e-11) and convenv.calls[0][1] == [4, 8]
    convenv.calls.clear()
    _, f = ac.convergence_checks(types.SimpleNamespace(source_digits=20), 5, 30, False)
    assert f["convergence_dps"] == 30 and convenv.calls[0][3] == approx(1e-16)
    convenv.calls.clear()
    ac.convergence_checks(TABX, 5, 30, False)
    assert convenv.calls[0][3] == approx(1e-26)


def test_convergence_constraint_is_the_worst_scene_and_failures_continue(convenv):
    convenv.obs = {"skate": 4.0, "particle": 4.0}
    ktol = 1e3 * 2.0 ** -52
    convenv.k = {"skate": 1e-16, "particle": 2 * ktol}
    C, f = ac.convergence_checks(TABX, 4, 30, False)
    assert C[-1].name == "constraint" and C[-1].status == FAIL and C[-1].residual == 2 * ktol
    convenv.k = {"skate": ktol, "particle": 1e-16}
    C, f = ac.convergence_checks(TABX, 4, 30, False)
    assert C[-1].status == PASS and f["max_constraint"] == ktol
    convenv.k = {"skate": 1e-28, "particle": 1e-29}          # dps 30 above order 4: tolerance 1e3 x 1e-30
    C, _ = ac.convergence_checks(TABX, 6, 30, False)
    assert C[-1].status == PASS and "tolerance 1e-27" in C[-1].detail
    convenv.k = {"skate": 1e-16, "particle": 1e-29}
    assert ac.convergence_checks(TABX, 6, 30, False)[0][-1].status == FAIL
    convenv.k = {"skate": 1e-16, "particle": 1e-20}
    convenv.obs = {"skate": LdasparkError("newton\nx"), "particle": 4.0}
    C, f = ac.convergence_checks(TABX, 4, 30, False)
    assert [c.name for c in C] == ["convergence:skate", "convergence:particle", "constraint"]
    assert C[0].status == FAIL and C[0].detail == "integration failed: newton" and C[1].status == PASS
    assert "convergence:skate" not in f and f["max_constraint"] == 1e-20


def test_entry_floor():
    T = lambda a=None, b=None, c=None: types.SimpleNamespace(source_digits=a, decimal_digits=b, decimal_digits_min=c)
    assert ac._entry_floor(T()) == 0.0
    assert ac._entry_floor(T(10)) == approx(1e-7)
    assert ac._entry_floor(T(None, 12, 8)) == approx(1e-5)        # the fewest digits
    assert ac._entry_floor(T(15)) == 0.0 and ac._entry_floor(T(14)) == approx(1e-11)


def test_energy_check_rate_and_failure(monkeypatch):
    runs = []

    def run(tab, sc, N, T, dps):
        runs.append((N, T))
        e = {100: 4e-4, 200: 1e-4, 50: 1e-3, 25: 0.0}[N]
        return types.SimpleNamespace(energy=[1.0, 1.0 + e / 2, 1.0 - e])
    monkeypatch.setattr(ac, "_run", run)
    c, f = ac.energy_check(None, False)
    assert runs == [(100, 10.0), (200, 10.0)] and c.status == INFO and c.residual == approx(1e-4)
    assert f["energy_rate"] == approx(2.0) and f["energy"][0] == (0.1, approx(4e-4))
    runs.clear()
    c, f = ac.energy_check(None, True)
    assert runs == [(50, 5.0), (100, 5.0)] and f["energy_rate"] == approx(math.log(2.5) / math.log(2))

    def boom(tab, sc, N, T, dps):
        raise LdasparkError("diverged\nx")
    monkeypatch.setattr(ac, "_run", boom)
    c, f = ac.energy_check(None, True)
    assert c.status == FAIL and f == {} and c.detail.endswith("failed: diverged") and "h = 0.1" in c.detail


# ==== orders ==================================================================================
def test_orders_method_scope_verdict_uses_the_worse_component():
    base = {"method": "gauss-irk-2", "scene": "s", "claim_scope": "method", "claimed_order": 2}
    recs = [dict(base, variable="q", observed_order=3.0), dict(base, variable="v", observed_order=2.1),
            dict(base, variable="psi", observed_order=0.1), dict(base, scene="o", variable="q", observed_order=0.5)]
    assert orr.verdict(recs[0], recs) == "holds"
    recs[1]["observed_order"] = 2.5
    assert orr.verdict(recs[0], recs) == "HIGHER than claimed"
    recs[1]["observed_order"] = 2.3                     # min 2.3 - 2 = 0.3: at the tolerance
    assert orr.verdict(recs[0], recs) == "holds"
    recs[1]["observed_order"] = 1.6
    assert orr.verdict(recs[0], recs) == "FAILS"
    recs[1]["observed_order"] = None
    assert orr.verdict(recs[0], recs) == "NO WINDOW"
    assert orr.verdict(recs[0]) == "FAILS"               # no records: its own order 3.0
    assert orr.verdict(dict(recs[0], claimed_order=None)) == "no claim"
    rec = dict(base, claim_scope="variable", variable="q", observed_order=3.2)
    assert orr.verdict(rec, recs) == "FAILS" and orr.verdict(dict(rec, observed_order=2.3)) == "holds"
    assert orr.verdict(dict(rec, observed_order=1.75)) == "holds" and orr.verdict(dict(rec, observed_order=1.65)) == "FAILS"


def test_orders_claims_and_stage_nodes():
    assert orr.claim_scope("gauss-irk-3") == "method" and orr.claim_scope("gauss-3") == "variable"
    assert orr.claimed_order_of("gauss-irk-2") == 2 and orr.claimed_order_of("gauss-irk-1") == 1
    assert orr.claimed_order_of("gauss-irk-3") is None and orr.claimed_order_of("gauss-3") == 6
    assert orr.claimed_order_of("lobatto-iiia-iiib-2-leapfrog") is None
    assert orr.stage_nodes("lobatto-iiia-iiib-2-leapfrog") is None
    c = orr.stage_nodes("gauss-irk-2")
    assert len(c) == 2 and abs(c[0] - (0.5 - math.sqrt(3) / 6)) < 1e-15
    assert list(orr.stage_nodes("lobatto-iiia-iiib-2")) == [0.0, 1.0]


def test_order_records_skip_empty_psi_and_use_scaled_floor():
    m = {"h": [0.2, 0.1, 0.05], "q": [4e-2, 1e-2, 2.5e-3], "v": [1e-1, 1e-2, 1e-3], "psi": [],
         "scale": {"q": 1e12, "v": 1.0, "psi": 0.0}}
    recs = orr.order_records("gauss-1", "sc", 2, m, None, 1, "exact", psi_claimed=1)
    assert [r["variable"] for r in recs] == ["q", "v"]
    assert recs[0]["floor"] == approx(orr.floor_for(None, 1e12)) and recs[0]["floor"] > 4e-2
    assert recs[0]["observed_order"] is None                    # every q error below the scaled floor
    assert recs[1]["observed_order"] == approx(math.log(10) / math.log(2)) and recs[1]["window"] == [0, 2]
    m["psi"] = [1e-1, 5e-2, 2.5e-2]
    recs = orr.order_records("gauss-1", "sc", 2, m, None, 1, "exact", psi_claimed=1)
    assert recs[2]["claimed_order"] == 1 and recs[1]["claimed_order"] == 2 and "Psi_i" in recs[2]["compared"]


def test_measure_orders_passes_reference_and_claim(monkeypatch):
    seen = {}

    def me(method, scene, ref, t_end, n_list, dps=None, newton="full"):
        seen.update(ref=ref, n=n_list, newton=newton)
        return {"h": [0.5, 0.25], "q": [1e-2, 2.5e-3], "v": [1e-2, 2.5e-3], "psi": [],
                "scale": {"q": 1.0, "v": 1.0, "psi": 0.0}}
    monkeypatch.setattr(orr, "measure_errors", me)
    ref = types.SimpleNamespace(kind="mine")
    recs = orr.measure_orders("gauss-1", "skate", n_list=(2, 4), reference=ref, newton="simple")
    assert seen["ref"] is ref and seen["n"] == [2, 4] and seen["newton"] == "simple"
    assert recs[0]["reference"] == "mine" and recs[0]["claimed_order"] == 2
    assert recs[0]["observed_order"] == approx(2.0)
    recs = orr.measure_orders("gauss-1", "skate", n_list=(2, 4))
    assert isinstance(seen["ref"], orr.ExactReference) and recs[0]["reference"] == "exact"


def test_asymptotic_window_strict_decrease_floor_and_ties():
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-3, 1e-4], 0.0) == (1, 2)
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-4, 1e-5], 5e-5) == (0, 1)    # 1e-5 is not above the floor
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-4, 1e-5], 1e-4) is None      # nor is 1e-4 (strictly above)
    assert orr.asymptotic_window([8, 4, 2, 1], [1e-3, 1e-4, float("nan"), 1e-4], 0.0) == (0, 1)
    assert orr.asymptotic_window([8, 4, 2, 1, 0.5], [1e-3, 1e-4, 1.0, 1e-1, 1e-2], 0.0) == (2, 4)
    with pytest.raises(InputError):
        orr.estimate_order([0.1, 0.1], [1e-2, 1e-3], 0.0)
    assert orr.pairwise_orders([0.2, 0.1], [1e-2, float("inf")]) == [None]
    assert orr.pairwise_orders([0.2, 0.1], [-1e-2, 1e-3]) == [None]


# ==== conditions (exact) ======================================================================
def test_conditions_exact_22_and_23_on_single_entries():
    t = _lobatto2()
    assert cond.check_22a(t) is cond.check_22b(t) is cond.check_23(t) is True
    assert False is cond.check_22a(_lobatto2(b_hat=["1/2", "3/5"]))
    assert False is cond.check_22b(_lobatto2(A_hat=[["1/2", 0], ["1/2", "1/10"]]))
    assert False is cond.check_22b(_lobatto2(A_hat=[["1/2", "1/10"], ["1/2", 0]]))
    assert False is cond.check_23(_lobatto2(c=["1/5", 1], A=[["1/5", 0], ["1/2", "1/2"]]))
    assert cond.check_23(_lobatto2(A_tilde=[[0, 0], ["1/2", "1/2"]])) is True       # IIIA is symmetric too
    assert False is cond.check_23(_lobatto2(A_tilde=[["1/2", 0], ["1/2", "1/10"]]))   # (23d) alone
    # b_tilde not symmetric while A_tilde_(s+1-i,s+1-j) + A_tilde_ij = b_tilde_j holds for every i, j
    assert False is cond.check_23(_lobatto2(b_tilde=["1/3", "2/3"], A_tilde=[["1/6", 0], ["2/3", "1/6"]]))
    rows = {r["method"]: r for r in cond.method_table(2)}
    assert rows["gauss-2"]["22"] and rows["gauss-2"]["23"] and rows["gauss-2"]["order"] == 4
    assert rows["euler-i"]["22"] and not rows["euler-i"]["23"] and "gauss-3" not in rows


# ==== order_conditions ========================================================================
def test_trees_counts_and_densities():
    assert oc.trees(0) == () and oc.trees(-1) == ()
    assert [len(oc.trees(n)) for n in range(1, 6)] == [1, 1, 2, 4, 9]
    assert [len(oc.trees(n, 2)) for n in range(1, 4)] == [2, 4, 14]
    assert sorted(oc.density(t) for t in oc.trees(3)) == [3, 6]
    assert sorted(oc.density(t) for t in oc.trees(4)) == [4, 8, 12, 24]
    t = (0, ((0, ()), (1, ())))
    assert oc.tree_str(t, ("q", "p")) == "q[q p]" and oc.tree_str(t) == "o[o o]"


def test_arith_mp_and_exact_helpers():
    ar = mp_ar(1e-10, dps=30)
    assert ar.to_str(mpmath.mpf(1) / 3).startswith("0.3333333333333333")
    assert ar.radius(mpmath.mpf(1)) == 1e-10 and ar.pow(mpmath.mpf(2), 3) == 8
    assert ar.is_zero(mpmath.mpf("1e-10")) and not ar.is_zero(mpmath.mpf("1.1e-10"))
    assert ar.num(1, 3) == ar.num(1, 3) and abs(ar.num(1, 3) * 3 - 1) < 1e-29
    ex, _ = oc.exact_arith(get_method("gauss-2", exact=True))
    assert ex.to_str(ex.K.from_sympy(sympy.sqrt(3) / 6)) in ("sqrt(3)/6", "sqrt(3)*(1/6)")
    assert ex.radius(ex.num(1)) == 0.0 and ex.prec == int(30 * 3.33) + 16


def test_to_str_survives_nsimplify_failure(monkeypatch):
    ex, _ = oc.exact_arith(get_method("gauss-2", exact=True))
    x = ex.K.from_sympy(sympy.sqrt(3) / 6)

    def boom(e):
        raise ValueError("no")
    monkeypatch.setattr(sympy, "nsimplify", boom)
    assert "sqrt(3)" in ex.to_str(x)


def test_exact_budget_reasons():
    flt = from_json_dict({"c": [0.5], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], "b": [1.0],
                          "b_hat": [1.0], "b_tilde": [1.0]}, "f")
    assert oc.exact_budget(flt) == (False, "the entries are float64 numbers")
    ok, why = oc.exact_budget(_extab(sympy.E / 5))
    assert not ok and "involve E:" in why
    ok, why = oc.exact_budget(_tab(c=["pi/7"]))
    assert not ok and "involve pi:" in why
    ok, why = oc.exact_budget(_extab(sympy.sin(1) / 2 + sympy.pi / 10))
    assert not ok and "involve pi, sin:" in why
    ok, why = oc.exact_budget(get_method("gauss-3", exact=True))
    assert ok and why == "number field of degree <= 2"
    t = _tab(c=["sqrt(2)/4 + sqrt(3)/4 + sqrt(5)/8"])
    assert oc.exact_budget(t) == (True, "number field of degree <= 8")
    assert not oc.exact_budget(t, max_degree=4)[0] and oc.exact_budget(t, max_degree=None)[0]
    ok, why = oc.exact_budget(_tab(c=["sqrt(2)/4 + sqrt(3)/4 + sqrt(5)/8 + sqrt(7)/16"]))
    assert not ok and "4 distinct radicals: number field of degree up to 16 > 8" in why
    x = sympy.Symbol("x")
    r = sympy.CRootOf(x ** 3 - x - 1, 0)
    tab = get_method("gauss-1", exact=True)
    ex = dict(tab.exact)
    ex["c"] = sympy.Matrix([[r / 3]])
    t3 = type(tab)("cr", 1, exact=ex)
    assert oc.exact_budget(t3) == (True, "number field of degree <= 3")
    ex["c"] = sympy.Matrix([[r / 3 + sympy.sqrt(2) / 5 + sympy.sqrt(3) / 7]])
    assert oc.exact_budget(type(tab)("cr", 1, exact=ex))[0] is False          # 3 * 2 * 2 = 12 > 8


def test_arith_for_numerical_when_not_decidable(monkeypatch):
    assert oc.arith_for(get_method("gauss-1", exact=True))[0].exact
    monkeypatch.setattr(oc, "_decidable", lambda K: False)
    ar, e = oc.arith_for(get_method("gauss-1", exact=True))
    assert ar.ball and "not decidable exactly" in ar.label
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=None), 10) == 40
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=50), 30) == 70
    assert oc.ball_digits(types.SimpleNamespace(decimal_digits=10), 35) == 70


def test_additive_order_merges_identical_parts_and_caps_three_colours():
    Q = sympy.QQ
    ar = oc.Arith("exact", K=Q)
    A, b = [[Q(1, 2)]], [Q(1)]
    r = oc.additive_order(ar, [(A, b), (A, b), (A, b)], names=["q", "F", "R"])
    assert r.order == 2 and r.max_order == oc.MAX_ORDER and r.counts == {1: 1, 2: 1, 3: 2}
    # both trees of order 3 miss by 1/12 (+1/12 for o[o[o]], -1/12 for o[o o]): the first one is named
    assert r.failing == "o[o[o]]" and r.residual == approx(1 / 12)
    E, Ei = ([[Q(1)]], [Q(1)]), ([[Q(0)]], [Q(1)])
    r = oc.additive_order(ar, [E, Ei, E])
    assert r.order == 1 and r.max_order == oc.MAX_ORDER and r.counts[2] == 4   # two colours after the merge
    r = oc.additive_order(ar, [E, Ei, (A, b)])
    assert r.max_order == 6 and r.order == 1 and r.counts[2] == 9
    assert oc._same(ar, [[Q(1)]], [Q(1)], [[Q(1)]], [Q(1)])
    assert not oc._same(ar, [[Q(1)]], [Q(1)], [[Q(1)]], [Q(2)]) and not oc._same(ar, [[Q(1)]], [Q(1)], [[Q(0)]], [Q(1)])
    r = oc.pair_order(ar, *E, *Ei)
    assert r.order == 1 and "q" in r.failing and "p" in r.failing
    assert not r.complete and oc.OrderResult(8, 8).complete


def test_simplifying_assumptions_and_stability_exact():
    ar, e = oc.exact_arith(get_method("gauss-2", exact=True))
    sa = oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"])
    assert sa == {"B": 4, "C": 2, "D": 2}
    assert oc.simplifying_assumptions(ar, e["A"], e["b"], e["c"], cap=1) == {"B": 1, "C": 1, "D": 1}
    ok, w = oc.check_B(ar, e["b"], e["c"], 5)
    assert not ok and w[1] == "k=5" and w[0] == approx(1 / 180)
    st = oc.stability(ar, e["A"], e["b"])
    assert st.r_inf == 1.0 and not st.A_singular
    Q = sympy.QQ
    ex = oc.Arith("exact", K=Q)
    st = oc.stability(ex, [[Q(0)]], [Q(1)])                 # explicit Euler: R = 1 + z
    assert st.r_inf == math.inf and st.r_inf_str == "inf" and st.A_singular and "singular" in st.note
    st = oc.stability(ex, [[Q(0), Q(0)], [Q(1, 2), Q(1, 2)]], [Q(1, 2), Q(1, 2)])   # trapezoid
    assert st.r_inf == -1.0 and st.A_singular
    assert oc.char_coeffs(ex, [[Q(1), Q(2)], [Q(3), Q(4)]]) == [Q(1), Q(-5), Q(-2)]
    assert oc.largest(lambda n: (n <= 3, None), 10) == 3 and oc.largest(lambda n: (True, None), 4) == 4


# ==== variational =============================================================================
def test_predicted_local_order_per_family():
    assert var.predicted_local_order(get_method("gauss-2")) == 5
    assert var.predicted_local_order(get_method("lobatto-iiia-iiib-3")) == 5
    assert var.predicted_local_order(get_method("lobatto-iiia-iiib-iiid-2")) == 3
    assert var.predicted_local_order(get_method("euler-i")) == 2
    assert var.predicted_local_order(types.SimpleNamespace(family="custom", claimed_order=None, s=3)) == 2
    assert var.predicted_local_order(types.SimpleNamespace(family="custom", claimed_order=3, s=3)) == 4


def test_initial_point_base_and_perturbed():
    from ldaspark.models.scenes import get_scene
    from ldaspark.analysis.discrete import perturbed_initial
    sc = get_scene("skate")
    t0, q0, v0 = var.initial_point("skate", "base", 30)
    assert (t0, list(q0), list(v0)) == (sc.initial(30)[0], list(sc.initial(30)[1]), list(sc.initial(30)[2]))
    t0p, q0p, v0p = var.initial_point("skate", "perturbed", 30)
    assert list(q0p) == list(perturbed_initial(sc, 30)[1]) and list(q0p) != list(q0)


# ==== remaining branches ======================================================================
def test_decide_arith_undecidable_field_goes_to_balls(monkeypatch):
    monkeypatch.setattr(oc, "_decidable", lambda K: False)
    ar, e, why = au.decide_arith(_tab(), 30)
    assert ar.ball and why.startswith("sympy puts the entries in") and "not decidable exactly" in why


def test_decidable_domains():
    assert oc._decidable(sympy.QQ) and oc._decidable(sympy.ZZ)
    assert oc._decidable(sympy.QQ.algebraic_field(sympy.sqrt(3)))
    assert not oc._decidable(sympy.EX)


def test_additive_order_explicit_cap():
    Q = sympy.QQ
    ar = oc.Arith("exact", K=Q)
    E, Ei, M = ([[Q(1)]], [Q(1)]), ([[Q(0)]], [Q(1)]), ([[Q(1, 2)]], [Q(1)])
    r = oc.additive_order(ar, [M, M, M], max_order=2)
    assert r.order == 2 and r.max_order == 2 and r.complete and r.failing is None
    r = oc.additive_order(ar, [E, Ei, M], max_order=1)
    assert r.order == 1 and r.complete
    r = oc.spark_ode_order(ar, {"A": M[0], "b": M[1], "A_hat": M[0], "b_hat": M[1], "A_tilde": M[0], "b_tilde": M[1]})
    assert r.order == 2 and r.max_order == oc.MAX_ORDER


class _Ref:
    """psi(t) = (10 t, -1/2), q = (1, -2), v = (-3,) at every t: records where it was asked."""

    def __init__(self):
        self.ts = []

    def __call__(self, t):
        self.ts.append(float(t))
        return [1.0, -2.0], [-3.0], [float(t) * 10, -0.5]


def test_measure_errors_compares_psi_at_the_last_steps_stage_times(monkeypatch):
    sc = types.SimpleNamespace(system="S", initial=lambda dps: (0.5, [0.0, 0.0], [0.0]))
    T = 1.5

    def run(name, system, t0, q0, v0, h, N, dps=None, newton="full"):
        h = float(h)
        psi_last = [[(T - h + c * h) * 10 + 0.5 * h * (i + 1), -0.5] for i, c in enumerate((0.25, 0.75))]
        return types.SimpleNamespace(q=[None, [1.0 + h, -2.0]], v=[None, [-3.0 - 2 * h]],
                                     psi=[None, psi_last], stats={"N": N, "h": h})
    monkeypatch.setattr(orr, "run_method", run)
    monkeypatch.setattr(orr, "stage_nodes", lambda name, dps=None: [0.25, 0.75])
    ref = _Ref()
    m = orr.measure_errors("m", sc, ref, T, [2, 4])          # h = (T - t0) / N
    assert m["h"] == [0.5, 0.25] and m["q"] == approx([0.5, 0.25]) and m["v"] == approx([1.0, 0.5])
    assert m["psi"] == approx([0.5, 0.25])           # the larger of the two stages: 0.5 h * 2
    assert ref.ts[0] == T and ref.ts[1:3] == approx([1.125, 1.375]) and ref.ts[3:] == approx([1.3125, 1.4375])
    assert m["scale"] == {"q": 2.0, "v": 3.0, "psi": approx(14.375)}
    assert [s["N"] for s in m["stats"]] == [2, 4]
    monkeypatch.setattr(orr, "stage_nodes", lambda name, dps=None: None)     # a comparator: no Psi
    m = orr.measure_errors("m", sc, _Ref(), T, [2])
    assert m["psi"] == [] and m["scale"]["psi"] == 0.0


# ==== symmetry: the identities' arithmetic on synthetic BVP results ===========================
def _symmetry_with(monkeypatch, d):
    """check_symmetry with the BVP solves, projectors and steps replaced by the records in d."""
    from ldaspark.models import arguments
    from ldaspark.analysis import symmetry as sy
    seen = {"dl": [], "steps": []}
    mk = lambda **kw: types.SimpleNamespace(**kw)
    fwd = mk(L_d=d["L"][0], f_d_minus=np.array(d["fm"][0]), f_d_plus=np.array(d["fp"][0]), p0=np.array(d["p0"]),
             p1=np.array(d["p1"]), x="XF", wellposed="regular", rank_deficiency=0)
    rev = mk(L_d=d["L"][1], f_d_minus=np.array(d["fm"][1]), f_d_plus=np.array(d["fp"][1]), p0=None, p1=None,
             x="XR", wellposed="?", rank_deficiency=7)
    monkeypatch.setattr(arguments, "theory_args", lambda *a: a[:5])
    monkeypatch.setattr(sy, "base_point", lambda S, T, t0, q0, v0, h, dps: (t0 + h, "Q1", "XG"))

    def dl(S, T, ta, qa, tb, qb, dps=None, x_guess=None, gauge_ref=None):
        seen["dl"].append((ta, qa, tb, qb, x_guess, gauge_ref))
        return fwd if len(seen["dl"]) == 1 else rev
    monkeypatch.setattr(sy, "discrete_lagrangian", dl)

    class BVP:
        def __init__(self, S, T, dps):
            pass

        def unpack(self, x):
            assert x == "XF"
            return np.array([1, 2]), np.array([3, 4]), "v1", "v0"

        def pack(self, V, Lam, va, vb):
            seen["pack"] = (list(V), list(Lam), va, vb)
            return "XR0"
    monkeypatch.setattr(sy, "DiscreteBVP", BVP)
    P = {id(fwd): (np.diag([1.0, 0.0]), 1), id(rev): (np.diag([0.0, 1.0]), 2)}
    monkeypatch.setattr(sy, "_tangent_projector", lambda res, which: P[id(res)])
    q0, v0 = np.array(d["q0"]), np.array(d["v0"])

    class Meth:
        def __init__(self, S, T, dps=None, newton=None):
            pass

        def step(self, t, q, v, h):
            seen["steps"].append((t, h))
            return mk(t1=t + h, q1=q0 + np.array(d["dq"]), v1=v0 + np.array(d["dv"]))
    monkeypatch.setattr(sy, "SparkMethod", Meth)
    monkeypatch.setattr(sy, "ivp_step", lambda meth, t, q, v, h: mk(t1=t + h, q1=q + 1, v1=v + 1))
    r = sy.check_symmetry("S", "T", 0.0, q0, v0, 0.25, dps=None)
    return r, seen


SYM_DATA = [
    dict(L=(2.0, -1.5), fm=([1.0, 2.0], [5.0, -4.25]), fp=([3.0, 4.0], [-0.5, 7.0]), p0=[0.1, -0.2], p1=[0.3, 0.4],
         q0=[3.0, 0.0], v0=[0.0, 0.5], dq=[1e-3, 0.0], dv=[0.0, -2e-3]),
    dict(L=(-0.5, 0.25), fm=([-6.0, 0.5], [0.1, 0.2]), fp=([0.0, 0.3], [5.0, 9.0]), p0=[0.05, 0.1], p1=[20.0, 0.0],
         q0=[0.5, 0.0], v0=[0.0, -0.25], dq=[0.0, 3e-3], dv=[-1e-3, 0.0]),
    # a scene at rest: every covector zero, the scales fall back to 1e-300 (and 1 for the state)
    dict(L=(0.0, 0.0), fm=([0.0, 0.0], [0.0, 0.0]), fp=([0.0, 0.0], [0.0, 0.0]), p0=[0.0, 0.0], p1=[0.0, 0.0],
         q0=[0.0, 0.0], v0=[0.0, 0.0], dq=[0.0, 3e-3], dv=[-1e-3, 0.0]),
]


@pytest.mark.parametrize("d", SYM_DATA)
def test_check_symmetry_identities_and_scales(monkeypatch, d):
    r, seen = _symmetry_with(monkeypatch, d)
    n = lambda x: float(np.max(np.abs(np.asarray(x, dtype=float))))
    P0, P1 = np.diag([1.0, 0.0]), np.diag([0.0, 1.0])
    fmF, fmR, fpF, fpR = (np.array(x) for x in (d["fm"][0], d["fm"][1], d["fp"][0], d["fp"][1]))
    assert r["symmetry-Ld"] == approx(abs(d["L"][0] + d["L"][1]) / max(abs(d["L"][0]), 1e-300), rel=1e-12)
    norms_p = (n(P0 @ fmF), n(P0 @ fpR))
    norms_m = (n(P1 @ fpF), n(P1 @ fmR))
    sc = max(*norms_p, *norms_m, n(d["p0"]), n(d["p1"]), n(fmF), n(fpF), 1e-300)
    assert r["symmetry-fd-plus"] == approx(n(P0 @ (fmF + fpR)) / sc, rel=1e-12)
    assert r["symmetry-fd-minus"] == approx(n(P1 @ (fpF + fmR)) / sc, rel=1e-12)
    sc_full = max(n(fmF), n(fpF), n(d["p0"]), 1e-300)
    assert r["symmetry-fd-unrestricted"] == (approx(n(fmF + fpR) / sc_full, rel=1e-12),
                                             approx(n(fpF + fmR) / sc_full, rel=1e-12))
    sc_y = max(n(d["q0"]), n(d["v0"]), 1.0)
    assert r["symmetry-Phi"] == approx(max(n(d["dq"]), n(d["dv"])) / sc_y, rel=1e-12)
    assert r["fd_plus_identity_norms"] == norms_p and r["fd_minus_identity_norms"] == norms_m
    assert r["fd_restricted_norm"] == (n(P0 @ fmF), n(P1 @ fpF)) and r["tangent_dim"] == (1, 2)
    assert r["wellposed"] == "regular" and r["rank_deficiency"] == 0
    # the reversed BVP: endpoints exchanged, stages reversed, multipliers reversed and negated
    assert seen["pack"] == ([2, 1], [-4, -3], "v0", "v1")
    assert seen["dl"][0][0] == 0.0 and seen["dl"][0][2:4] == (0.25, "Q1")
    assert seen["dl"][0][4] == "XG" and seen["dl"][1][4] == "XR0" and seen["dl"][1][5] == "XR0"
    assert seen["dl"][1][0] == 0.25 and seen["dl"][1][1] == "Q1" and seen["dl"][1][2] == 0.0
    assert seen["steps"] == [(0.25, -0.25)]          # Phi_{-h} from the end of Phi_h


def test_tangent_projector_null_space_and_rank_threshold():
    from ldaspark.analysis import symmetry as sy
    M = np.array([[1.0, 1.0, 0.0]])
    res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M, None]}, dps=None)
    P, dim = sy._tangent_projector(res, 0)
    assert dim == 2 and np.allclose(P @ M.T, 0, atol=1e-14) and np.allclose(P @ P, P, atol=1e-14)
    assert np.allclose(P @ np.array([1.0, -1.0, 5.0]), [1.0, -1.0, 5.0], atol=1e-14)
    # a second row 1e-9 x the first's size is below the relative rank threshold 1e-8; 1e-7 is not
    for eps, want in ((1e-9, 2), (1e-7, 1)):
        M2 = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, eps]])
        res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [None, M2]}, dps=None)
        assert sy._tangent_projector(res, 1)[1] == want
    # relative to the largest singular value: 1e-6 under 1e-8 x 1414 is below the threshold
    M3 = np.array([[1000.0, 1000.0, 0.0], [0.0, 0.0, 1e-6]])
    assert sy._tangent_projector(types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M3]}, dps=None), 0)[1] == 2
    # never relative to less than 1e-300: a subnormal 5e-309 is not a condition even next to 1e-301
    M4 = np.array([[1e-301, 0.0], [0.0, 5e-309]])
    assert np.linalg.svd(M4)[1][1] == 5e-309
    assert sy._tangent_projector(types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [M4]}, dps=None), 0)[1] == 1
    # a gauge: the conditions are W^T dG/dq, and more rows than coordinates are padded
    W = np.array([[1.0], [0.0], [0.0]])
    G = np.array([[0.0, 2.0], [5.0, 5.0], [7.0, 7.0]])
    g = types.SimpleNamespace(W_left=W)
    res = types.SimpleNamespace(extra={"gauge": g, "dG_dq": [G, None]}, dps=None)
    P, dim = sy._tangent_projector(res, 0)
    assert dim == 1 and np.allclose(P, np.diag([1.0, 0.0]), atol=1e-14)
    res = types.SimpleNamespace(extra={"gauge": None, "dk0_dq": [np.array([[1.0], [2.0], [3.0]])]}, dps=None)
    assert sy._tangent_projector(res, 0)[1] == 0


# ==== variational: the error table and its orders on synthetic solves =========================
def _variational_with(monkeypatch, ld_scale=1.0, ld_const=None, method=None):
    mk = lambda **kw: types.SimpleNamespace(**kw)
    tab = mk(name="T", claimed_order=2, family="gauss", s=1)
    monkeypatch.setattr(var, "get_scene", lambda name: mk(system="S"))
    monkeypatch.setattr(var, "initial_point", lambda name, point, dps: (0.0, [0.0, 0.0], [1.0, 0.0]))
    V = lambda *x: np.array(x, dtype=float)

    def exact(name, h, dps, stages, point):
        return "Q1", mk(L_d=1.0, f_d_minus=V(0.3, 0.5), f_d_plus=V(2.0, 0.0), p0=V(0.2, -0.1), p1=V(1.0, 1.0),
                       v0="V0", v1="V1")
    monkeypatch.setattr(var, "_exact", exact)
    monkeypatch.setattr(var, "base_point", lambda S, tab, t0, q0, v0, h, dps: (None, None, "XG"))

    def dl(S, tab, t0, q0, t1, q1, dps=None, x_guess=None):
        h = t1 - t0
        return mk(L_d=1.0 + ld_scale * h ** 3 if ld_const is None else 1.0 + ld_const, f_d_minus=V(0.3 + h ** 2, 0.5 + h), f_d_plus=V(2.0 + h, h ** 3),
                  p0=V(0.2, -0.1 - h + h ** 5), p1=V(1.0 + h, 1.0))
    monkeypatch.setattr(var, "discrete_lagrangian", dl)
    monkeypatch.setattr(var, "_tangent", lambda S, bk, t, q, v: {"V0": np.diag([1.0, 0.0]),
                                                                 "V1": np.diag([0.0, 1.0])}[v])
    if method is not None:
        monkeypatch.setattr(var, "get_method", lambda name, exact=False: method.append((name, exact)) or tab)
        return var.variational_errors("meth", "sc", dps=None)
    return var.variational_errors(tab, "sc", dps=None)


def test_variational_errors_each_quantity_and_its_order(monkeypatch):
    out = _variational_with(monkeypatch)
    hs = [0.2, 0.1, 0.05]
    e = out["errors"]
    assert out["h"] == hs and out["predicted_local_order"] == 3 and out["global_order"] == 2
    assert e["L_d"] == approx([h ** 3 for h in hs], rel=1e-9)
    assert e["f_minus"] == approx(hs, rel=1e-9) and e["f_minus_tangential"] == approx([h ** 2 for h in hs])
    assert e["f_plus"] == approx(hs, rel=1e-9) and e["f_plus_tangential"] == approx([h ** 3 for h in hs])
    assert e["p0+f_minus"] == approx([h ** 2 for h in hs], rel=1e-9)
    assert e["p1-f_plus"] == approx([h ** 3 for h in hs], rel=1e-9)
    o = out["orders"]
    want = {"L_d": 3, "f_minus": 1, "f_minus_tangential": 2, "f_plus": 1, "f_plus_tangential": 3,
            "p0+f_minus": 2, "p1-f_plus": 3}
    assert o == {k: approx(v, abs=1e-6) for k, v in want.items()}


def test_variational_errors_floor(monkeypatch):
    # L_d errors 8e-15, 1e-15, 1.25e-16: all below 1e3 eps, zero to working precision
    assert _variational_with(monkeypatch, 1e-12)["orders"]["L_d"] == math.inf
    # 8e-13 above the floor, the rest below: not zero, but no window of two points
    assert _variational_with(monkeypatch, 1e-10)["orders"]["L_d"] is None


def test_variational_tangent_and_norm():
    K = np.array([[1.0, 2.0, 0.0]])
    S = types.SimpleNamespace(n=3, saddle_matrix=lambda bk, t, q, v: np.block([[np.eye(3), K.T], [K, np.zeros((1, 1))]]))
    from ldaspark.core.backend import Backend
    P = np.array(var._tangent(S, Backend(None), 0.0, None, None), dtype=float)
    assert np.allclose(P @ K.T, 0, atol=1e-14) and np.allclose(P @ P, P, atol=1e-14)
    assert np.allclose(P @ np.array([2.0, -1.0, 3.0]), [2.0, -1.0, 3.0], atol=1e-14)
    assert var._nrm(np.array([[1.0, -3.0], [2.0, 0.5]])) == 3.0 and var._nrm(np.array([])) == 0.0


# ==== survivors of the sampled run ============================================================
def test_theorem1_scene_teeth_boundary_is_inclusive(t1env):
    """A numerical tolerance exactly at TEETH still has teeth (``tol_num > TEETH`` skips): at dps 12
    the working-precision part is 10^-6 = TEETH exactly; in the full run that solve is kept."""
    assert 10.0 ** (-12 / 2) == au.TEETH
    t1env.results = [_r(q0=1e-9, q1=1e-9)]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 12, True)
    assert c.status == PASS and c.tolerance == au.TEETH
    t1env.results = [_r(q0=1e-9, q1=2e-6)]
    assert au._theorem1_scene(TAB0, "skate", True, 12, True)[0].status == FAIL
    t1env.calls.clear()
    t1env.results = [_r(q0=1e-9, q1=1e-9), _r()]
    c, _ = au._theorem1_scene(TAB0, "skate", True, 12, False)
    assert t1env.calls == [12] and c.status == PASS          # at TEETH: no retry at +20 digits
    # just above: not decided
    t1env.results = [_r(fd=1.01e-7)]
    assert au._theorem1_scene(TAB0, "skate", True, 30, True)[0].status == SKIP


def test_verdict_and_disagreement_count_missing_residuals_as_zero():
    v = au.verdict(_vres(th=[_th(PASS, None, "a"), _th(PASS, 0.0, "b")]))
    assert "agrees (largest residual 0.0e+00)" in v
    th = [_th(FAIL, 1e-3, "a")]
    r = _vres(th=th, summ=FAIL, exact=False)
    r.checks[0] = Check("22a", PASS, 1e-30, "", tolerance=None)
    r.checks[1] = Check("22b", PASS, 2e-30, "", tolerance=0.0)
    assert "(uncertainty 0.0e+00)" in au.disagreement(r)
    r.checks[0] = Check("22a", PASS, None, "", tolerance=0.0)
    r.checks[1] = Check("22b", PASS, 0.0, "", tolerance=0.0)
    assert "numerical" in au.disagreement(r)                 # r22 = 0: not the entries' precision


def test_coefficient_strings_show_a_changed_entry_as_value_plus_delta():
    t = _lobatto2().with_entry("A", 1, 0, "1/1000").with_entry("b", 0, None, "-1/7")
    cs = ac._coefficient_strings(t)
    assert cs["A"][1] == ["1/2 + (1/1000)", "1/2"] and cs["b"] == ["1/2 + (-1/7)", "1/2"]
    t2 = t.with_entry("A", 1, 0, "2")                      # changed twice: nested
    assert ac._coefficient_strings(t2)["A"][1][0] == "1/2 + (1/1000) + (2)"


def test_ball_arith_helpers():
    import flint
    from ldaspark.core.errors import NonFiniteError
    ar = oc.Arith("ball", dps=30)
    assert ar.prec == int(30 * 3.33) + 16
    with ar.context():
        third = ar.num(1, 3)
        assert abs(float(third.mid()) - 1 / 3) < 1e-16 and float(third.rad()) < 1e-30
        x = flint.arb(0, 1e-3)                                  # a ball around 0
        assert ar.is_zero(x) and not ar.is_zero(flint.arb(1e-2, 1e-3))
        y = ar.pow(x, 3)
        assert y.is_finite() and ar.is_zero(y) and float(y.rad()) <= 1.01e-9
        assert float(ar.pow(flint.arb(2), 3).mid()) == 8.0 and float(ar.pow(flint.arb(5), 0).mid()) == 1.0
        assert ar.radius(flint.arb(1, 0.25)) == approx(0.25, rel=1e-6) and ar.to_float(flint.arb(0.75, 0.25)) == 0.75
        assert ar.to_str(ar.num(1, 4)) == "0.25" and ar.to_str(ar.num(1, 3)).startswith("0.33333333333333")
        with pytest.raises(NonFiniteError):
            ar.is_zero(flint.arb("nan"))


def test_method_table_needs_both_halves_of_22(monkeypatch):
    tabs = {"ok": _lobatto2(), "no22b": _lobatto2(A_hat=[["1/2", 0], ["1/2", "1/10"]]),
            "no22a": _tab(b_hat=["11/10"], A_hat=[["11/20"]]),
            "no23": _lobatto2(A_tilde=[["1/2", 0], ["1/2", "1/10"]])}
    monkeypatch.setattr(cond, "builtin_method_names", lambda max_s: list(tabs))
    monkeypatch.setattr(cond, "get_method", lambda name, exact=False: tabs[name])
    rows = {r["method"]: (r["22"], r["23"], r["s"]) for r in cond.method_table()}
    assert rows == {"ok": (True, True, 2), "no22b": (False, False, 2), "no22a": (False, True, 1),
                    "no23": (True, False, 2)}


def test_simplifying_assumption_caps_when_everything_holds():
    ar = mp_ar(tol=10.0)                  # every residual is "zero": only the caps stop the search
    b, c, A = mpv([0.5, 0.5]), mpv([0.25, 0.75]), mpv([[0.25, 0.0], [0.5, 0.25]])
    assert oc.simplifying_assumptions(ar, A, b, c) == {"B": 5, "C": 3, "D": 3}
    assert oc.simplifying_assumptions(ar, A, b, c, cap=2) == {"B": 2, "C": 2, "D": 2}


def test_exact_budget_counts_only_radicals():
    ok, why = oc.exact_budget(_extab(sympy.sqrt(2) + sympy.sqrt(3) + sympy.sqrt(5) + sympy.sqrt(7)
                                     + 1 / (1 + sympy.sqrt(2))))
    assert not ok and why.startswith("4 distinct radicals: number field of degree up to 16")
    ok, why = oc.exact_budget(_extab(sympy.cbrt(2) / 3 + sympy.sqrt(3) / 5))
    assert ok and why == "number field of degree <= 6"
    ok, why = oc.exact_budget(_extab(sympy.cbrt(2) / 3 + sympy.sqrt(3) / 5 + sympy.sqrt(5) / 7))
    assert not ok and "degree up to 12 > 8" in why


def test_integer_tableau_is_lifted_to_a_field_and_mp_ball_arith():
    t = _tab(c=[1], A=[[1]], A_hat=[[0]], A_tilde=[[0]])          # integers only: sympy's ZZ
    ar, e = oc.exact_arith(t)
    assert ar.K.is_Field and ar.label == f"exact in {ar.K}"
    assert oc.rk_order(ar, e["A"], e["b"]).order == 1 and oc.rk_order(ar, e["A_hat"], e["b_hat"]).order == 1
    flt = from_json_dict({"c": [0.5, 0.5], "A": [[0.25, 0.25], [0.25, 0.25]], "A_hat": [[0.25, 0.25], [0.25, 0.25]],
                          "A_tilde": [[0.25, 0.25], [0.25, 0.25]], "b": [0.5, 0.5], "b_hat": [0.5, 0.5],
                          "b_tilde": [0.5, 0.5], "omega": [[1, -1]]}, "f")
    ar, e = oc.mp_arith(flt, 30)
    assert ar.tol == approx(1e-12 * 2) and e["b"] == [mpmath.mpf("0.5")] * 2 and e["c"] == [mpmath.mpf("0.5")] * 2
    ar, e = oc.mp_arith(get_method("gauss-1", exact=True), 20)
    assert ar.tol == approx(1e-17) and ar.dps == 20
    ar, _ = oc.ball_arith(flt, 40)
    assert ar.ball and ar.scope.startswith("the float64 precision") and ar.dps == 40
    ar, _ = oc.ball_arith(get_method("gauss-1", exact=True), 40, "R")
    assert ar.label.endswith("; not exact because R") and ar.scope.startswith("40 digits, numerically (exact")
    ar, _ = oc.ball_arith(flt, 40, "R")
    assert "not exact because" not in ar.label
    ar, _ = oc.ball_arith(_tab(c=["0.50"]), 40)
    assert ar.scope == "the 2 digits given"
    ar, _ = oc.ball_arith(gauss(2), 40)
    assert ar.scope == "40 digits, numerically"


@pytest.mark.parametrize("frac, want", [(0.6, PASS), (1.5, INFO)])
def test_omega_span_tolerance_scales_with_s_and_the_largest_singular_value(frac, want):
    """omega = (100, 100 + eps) against b = (1/2, 1/2): stacked singular values ~141 and
    sigma_1 = eps / 2 / sigma_0; the rank tolerance is 10^(3 - 10) s max(sigma_0, 1) ~ 2.8e-5 for entries
    of 10 digits. sigma_1 = 0.6 tol is rank 1 (spans); a tolerance divided by s or by sigma_0 would not say so."""
    sv0 = math.hypot(100.0, 100.0)
    tol = 1e-7 * 2 * sv0
    eps = frac * tol * sv0 * 2
    t = _omtab([[100.0, 100.0 + eps]], 2, digits=10, b=[0.5, 0.5], c=[0.25, 0.75])
    c = ac.check_omega_default(t, 30)
    assert c.status == want and c.tolerance == approx(tol, rel=1e-3)
    assert c.residual == approx(frac * tol, rel=1e-3)


def test_observed_order_zero_error_on_either_side_is_no_slope(monkeypatch):
    from ldaspark.models import scenes
    sc = types.SimpleNamespace(exact=object(), system="S", exact_solution=lambda t, dps: ([1.0], [2.0], None))
    monkeypatch.setattr(scenes, "get_scene", lambda name: sc)
    for e4, e8 in ((0.0, 1e-3), (1e-3, 0.0)):
        errs = {4: e4, 8: e8}
        monkeypatch.setattr(ac, "_run", lambda tab, scene, N, t, dps: _Sol([1.0 + errs[N]], [2.0]))
        r = ac.observed_order(None, "x", [4, 8], 1, None, 0.0)
        assert math.isnan(r["slopes"][0]) and math.isnan(r["observed"])


def test_asymptotic_window_may_start_right_after_a_bad_point():
    assert orr.asymptotic_window([4, 2, 1], [float("nan"), 1e-3, 1e-4], 0.0) == (1, 2)
    assert orr.asymptotic_window([8, 4, 2, 1], [1e-3, 1e-9, 1e-4, 1e-5], 1e-8) == (2, 3)
    # a shorter run after a longer one does not win
    assert orr.asymptotic_window([32, 16, 8, 4, 2, 1], [1e-2, 1e-3, 1e-4, 1e-5, 1.0, 1e-1], 0.0) == (0, 3)


def test_ode_reference_counts_every_rhs_evaluation():
    calls = []

    def ode_rhs(bk, t, q, v):          # q'' = -q, psi = q
        calls.append(t)
        return [-x for x in q], [q[0]]
    S = types.SimpleNamespace(n=1, ode_rhs=ode_rhs)
    ref = orr.ODEReference(S, 0, [1], [0], dps=15)
    assert ref.n_rhs == len(calls)
    q, v, psi = ref(0.5)
    assert ref.n_rhs == len(calls) - 1 and ref.n_rhs > 0     # the psi evaluation is not the ODE's
    assert abs(float(q[0]) - math.cos(0.5)) < 1e-12 and abs(float(v[0]) + math.sin(0.5)) < 1e-12
    assert float(psi[0]) == float(q[0])


def test_simplifying_assumptions_start_at_k_1():
    Q = sympy.QQ
    ex = oc.Arith("exact", K=Q)
    # implicit Euler: B(1), C(1) hold, D(1) (b_1 a_11 = b_1 (1 - c_1): 1 vs 0) does not
    assert oc.simplifying_assumptions(ex, [[Q(1)]], [Q(1)], [Q(1)]) == {"B": 1, "C": 1, "D": 0}
    ok, w = oc.check_D(ex, [[Q(1)]], [Q(1)], [Q(1)], 1)
    assert not ok and w == (1.0, "k=1, j=1")
    # sum b = 1/2: not even B(1); a_11 = 1/4 != c_1 = 1/2: not C(1) (C(2) alone would hold: 1/8 = 1/8)
    sa = oc.simplifying_assumptions(ex, [[Q(1, 4)]], [Q(1, 2)], [Q(1, 2)])
    assert sa["B"] == 0 and sa["C"] == 0
    assert oc.check_C(ex, [[Q(1, 4)]], [Q(1, 2)], 1) == (False, (0.25, "k=1, i=1"))
    assert oc.check_B(ex, [Q(1, 2)], [Q(1, 2)], 1) == (False, (0.5, "k=1"))


def test_variational_errors_floor_is_inclusive_and_names_are_exact_tableaux(monkeypatch):
    floor = 1e3 * 2.0 ** -52
    out = _variational_with(monkeypatch, ld_const=floor)        # |L_d - L_d^E| = floor exactly at every h
    assert out["errors"]["L_d"] == [floor] * 3 and out["orders"]["L_d"] == math.inf
    seen = []
    out = _variational_with(monkeypatch, method=seen)
    assert seen == [("meth", True)] and out["method"] == "T"
