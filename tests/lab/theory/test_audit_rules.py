"""Rules of ``ldaspark.lab.theory.audit`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import argparse
import json
import types
import pytest
from ldaspark.core.errors import InputError, LdasparkError, TableauError
from ldaspark.core.tableau_file import from_json_dict
from ldaspark.lab.theory import audit as au
from ldaspark.core.families import get_method
from run_helpers import two_line_error


def approx(expected, rel=1e-9, abs=0.0):
    """pytest.approx without its default absolute tolerance 1e-12, which would let every residual
    of these tests (1e-15 .. 1e-30) equal every other."""
    return pytest.approx(expected, rel=rel, abs=abs)


PASS, FAIL, INFO, SKIP = au.PASS, au.FAIL, au.INFO, au.SKIP


Check = au.Check


# ==== audit: AuditResult ======================================================================
def _res(checks=(), facts=None, exact=True, s=2):
    r = au.AuditResult("T", s, exact, 30, True)
    r.checks = list(checks)
    r.facts = dict(facts or {})
    return r


# ==== audit: Theorem 1 summary ================================================================
def _th(status, res=None, name="x"):
    return Check(f"theorem1:{name}", status, res, "")


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


#: a tableau known exactly (``entry_radii`` None: the entries' uncertainty contributes nothing)
TAB0 = types.SimpleNamespace(source_digits=None, decimal_digits=None, exact={}, known_exactly=True, name="T0")
#: a tableau known to its digits only (the allowance is measured: ``entry_effect`` is replaced)
TABD = types.SimpleNamespace(source_digits=None, decimal_digits=20, exact={}, known_exactly=False, name="TD")


@pytest.fixture
def effect(monkeypatch):
    """``entry_radii`` / ``entry_effect`` replaced: the allowance measured on a scene is env.bound
    (per unit change env.per), or env.bound is an exception raised by the moved tableau's solve."""
    env = types.SimpleNamespace(bound=0.0, per=1.0, calls=0)
    monkeypatch.setattr(au, "entry_radii", lambda tab: None if tab.known_exactly else {"A": [[1e-20]]})

    def eff(tab, radii, response):
        env.calls += 1
        if isinstance(env.bound, Exception):
            raise env.bound
        return env.bound, env.per
    monkeypatch.setattr(au, "entry_effect", eff)
    return env


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


# ==== audit: algebraic checks on small tableaux ===============================================
def _tab(**over):
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
         "b": [1], "b_hat": [1], "b_tilde": [1]}
    d.update(over)
    return from_json_dict(d, "t")


def _alg(tab):
    ar, e, _ = au.decide_arith(tab, 30)
    C, facts = au.algebraic_checks(tab, ar, e, 30)
    return {c.name: c for c in C}, facts


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


def _args(**kw):
    d = dict(file=None, method=None, example=None, dps=30, quick=True, max_stages=None, arith="auto",
             out=None, json=None)
    d.update(kw)
    return argparse.Namespace(**d)


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
    assert au._theorem1_tol(tab, 30, 1e-20, 1e-9) == approx(1e-9, rel=1e-12)   # given
    # the entries' digits no longer enter as a fixed factor (was 10^(3 - 20) = 1e-17): what they
    # contribute is measured on each scene (``entry_effect``)
    tab20 = types.SimpleNamespace(source_digits=20)
    assert au._theorem1_tol(tab20, 60, 0.0) == approx(1e-30, rel=1e-12)
    assert au._theorem1_tol(tab20, 60, 0.0, 0.0) == approx(1e-30, rel=1e-12)


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
    # just below TEETH: decided (10 x 9e-8 = 9e-7 <= 1e-6)
    t1env.results = [_r(fd=9e-8, q1=1e-9)]
    assert au._theorem1_scene(TAB0, "skate", True, 30, True)[0].status == PASS


def test_theorem1_scene_entry_allowance_is_measured_on_the_scene(t1env, effect):
    """A residual above the numerical tolerance is judged against what the entries' uncertainty
    contributes on that scene (measured), only when (22) holds to the entries' precision (gate
    entry_tol > 0 or not given) and the entries are not known exactly; decided (not skipped)
    although that allowance is above TEETH, and said so with the digits to which it holds."""
    effect.bound = 1e-4
    t1env.results = [_r(q1=1e-5)]
    c, _ = au._theorem1_scene(TABD, "skate", True, 30, True, entry_tol=1e-7)
    assert c.status == PASS and c.tolerance == 1e-4 and "to the precision of the entries" in c.detail
    assert "holds to 5 digits" in c.detail and effect.calls == 1
    t1env.results = [_r(q1=1e-3)]                            # above the measured allowance
    assert au._theorem1_scene(TABD, "skate", True, 30, True, entry_tol=1e-7)[0].status == FAIL
    # (22) violated (gate 0): full strength, nothing measured
    t1env.results = [_r(q1=1e-5)]
    c, _ = au._theorem1_scene(TABD, "skate", True, 30, True, entry_tol=0.0)
    assert c.status == FAIL and c.tolerance == approx(1e-15, rel=1e-12) and effect.calls == 2   # not measured
    # exact entries: nothing to propagate, however large the (replaced) effect
    t1env.results = [_r(q1=1e-5)]
    assert au._theorem1_scene(TAB0, "skate", True, 30, True, entry_tol=1e-7)[0].status == FAIL
    # the moved tableau's solve fails: no allowance, judged at full strength
    effect.bound = LdasparkError("moved BVP failed")
    t1env.results = [_r(q1=1e-5)]
    c, _ = au._theorem1_scene(TABD, "skate", True, 30, True, entry_tol=1e-7)
    assert c.status == FAIL and "to the precision of the entries" not in c.detail
    # within the numerical tolerance: no measurement at all
    effect.calls = 0
    t1env.results = [_r(q1=1e-20)]
    assert au._theorem1_scene(TABD, "skate", True, 30, True, entry_tol=1e-7)[0].status == PASS
    assert effect.calls == 0


def test_theorem1_scene_full_retries_at_more_digits(t1env):
    # full: the first solve fails, the second (+20 digits) decides
    t1env.results = [two_line_error(LdasparkError, "stall", "more"), _r()]
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
    t1env.results = [LdasparkError("a"), two_line_error(LdasparkError, "b", "c")]
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
    symenv.results = {0: two_line_error(LdasparkError, "no", "more"), 1: _sym(ld=2e-20)}
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
    # the entries' uncertainty counts when larger than the working precision: measured on the scene
    # (``test_symmetry_entry_allowance_is_measured_on_the_scene``)


def test_symmetry_entry_allowance_is_measured_on_the_scene(symenv, effect):
    effect.bound = 1e-11
    symenv.results = {0: _sym(ld=1e-12)}
    c = au._symmetry_checks(TABD, 30, ["skate"], entry_tol=1e-20)[0][0]
    assert c.status == PASS and c.tolerance == 1e-11 and "holds to 12 digits" in c.detail
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(ld=1e-10)}                     # above the measured allowance
    assert au._symmetry_checks(TABD, 30, ["skate"], entry_tol=1e-20)[0][0].status == FAIL
    symenv.scene.calls.clear()
    symenv.results = {0: _sym(ld=1e-12)}                     # (23) violated: gate 0, full strength
    assert au._symmetry_checks(TABD, 30, ["skate"], entry_tol=0.0)[0][0].status == FAIL
    symenv.scene.calls.clear()
    assert au._symmetry_checks(TAB0, 30, ["skate"], entry_tol=1e-20)[0][0].status == FAIL   # exact entries
    symenv.scene.calls.clear()
    effect.bound = LdasparkError("moved solve failed")       # no allowance, full strength
    c = au._symmetry_checks(TABD, 30, ["skate"], entry_tol=1e-20)[0][0]
    assert c.status == FAIL and "holds to" not in c.detail


def test_a_symmetry_allowance_above_teeth_leaves_the_scene_undecided(symenv, effect):
    # an allowance above TEETH (1e-6) cannot tell (23) from its violation: 10-digit Lobatto IIIA-IIIB 3
    # passed the skate and the particle at a tolerance of 3e+02 (relative identities); now not decided,
    # and the summary says so (info), neither pass nor fail. Control: an allowance of 1e-11 decides.
    effect.bound = 3e2
    symenv.results = {0: _sym(ld=1.6e-12)}
    checks, _ = au._symmetry_checks(TABD, 30, ["skate"], entry_tol=1e-20)
    assert checks[0].status == SKIP and checks[0].detail.startswith(au.ENTRY_UNDECIDED) and "above 1e-06" in checks[0].detail
    assert checks[-1].name == "symmetry" and checks[-1].status == INFO
    symenv.scene.calls.clear()
    effect.bound = 1e-11
    checks, _ = au._symmetry_checks(TABD, 30, ["skate"], entry_tol=1e-20)
    assert [c.status for c in checks] == [PASS, PASS]


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


def test_verdict_marks_the_pair_order_a_lower_bound_when_every_tree_checked_holds():
    """gauss-5's verdict said "order 8 for the pair (A, A_hat)" beside the table's "order 8+ (bi-coloured
    trees to order 8)": its order 10 is beyond the trees checked, so 8 is a lower bound (the "+")."""
    capped = au.verdict(_vres(p=8, **{"order:pair-capped": True, "order:forced-ode-capped": True}))
    assert "order 8+ for the pair (A, A_hat) and 8+ for" in capped
    exact = au.verdict(_vres(p=8, **{"order:pair-capped": False}))        # control: a failing tree bounds it
    assert "order 8 for the pair (A, A_hat) and 8 for" in exact


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


@pytest.mark.parametrize("which", ["out", "json"])
def test_run_checks_its_output_paths_before_the_audit(which, monkeypatch, tmp_path):
    """--out or --json naming a directory: refused before the audit runs (it ran the whole audit,
    minutes at s = 5, and then refused; --json a directory left the --out report written alone)."""
    from ldaspark.core.errors import LdasparkError
    ran = []
    monkeypatch.setattr(au, "audit", lambda tab, **kw: ran.append(1) or _vres())
    (tmp_path / "d").mkdir()
    paths = {"out": str(tmp_path / "a.md"), "json": str(tmp_path / "a.json"), which: str(tmp_path / "d")}
    with pytest.raises(LdasparkError, match="directory"):
        au.run(_args(method="gauss-1", arith="mp", quick=False, **paths))
    assert ran == [] and not (tmp_path / "a.md").exists() and not (tmp_path / "a.json").exists()


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


C = au.Check


P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


def _audit_result(t1_residuals=(1e-20, 3e-12), conv=(P, P), hyp22=True, c22=((0.0, 0.0), (0.0, 0.0)),
                  t1_status=(P, P), exact=True):
    checks = [C("22a", P if hyp22 else F, c22[0][0], "b_hat = b", tolerance=c22[0][1]),
              C("22b", P if hyp22 else F, c22[1][0], "a_hat", tolerance=c22[1][1])]
    for name, r, st in zip(("skate", "particle"), t1_residuals, t1_status):
        checks.append(C(f"theorem1:{name}", st, r, "", tolerance=1e-10))
    checks.append(C("theorem1", F if F in t1_status else P, max(t1_residuals), ""))
    for name, st in zip(("skate", "particle"), conv):
        checks.append(C(f"convergence:{name}", st, 0.01, ""))
    checks += [C("constraint", P, 1e-16, ""), C("energy", I, 1e-6, "")]
    facts = {"22": hyp22, "23": True, "predicted_order": 2, "order:pair": 2,
             "convergence:skate": {"observed": 2.0}, "convergence:particle": {"observed": 2.0}}
    return au.AuditResult("fake", 1, exact, 30, True, checks=checks, facts=facts)


def test_verdict_quotes_the_largest_theorem1_residual():
    text = au.verdict(_audit_result(t1_residuals=(1e-20, 3e-12)))
    assert "largest residual 3.0e-12" in text


def test_verdict_says_the_orders_agree_only_when_both_scenes_pass():
    assert "agree with it." in au.verdict(_audit_result(conv=(P, P)))
    assert "do NOT agree with it." in au.verdict(_audit_result(conv=(P, F)))
    assert "do NOT agree with it." in au.verdict(_audit_result(conv=(F, P)))


def test_disagreement_quotes_the_largest_22_residual():
    # (22) violated (22a by 5e-11, 22b by 1e-13) but Theorem 1 passes (tolerance 1e-10): the
    # violation is below the numerical resolution, and the sentence quotes the larger residual
    res = _audit_result(hyp22=False, c22=((5e-11, 0.0), (1e-13, 0.0)), t1_status=(P, P))
    d = au.disagreement(res)
    assert "|residual| 5.0e-11" in d
    # a violation above the tolerance in one of the two is called unexpected
    res = _audit_result(hyp22=False, c22=((1e-13, 0.0), (1e-3, 0.0)), t1_status=(P, P))
    assert "larger than the numerical tolerance" in au.disagreement(res)


def test_disagreement_quotes_the_largest_22_uncertainty():
    # (22) holds to the entries' precision: residuals 1e-12, 0 and uncertainties 1e-9, 1e-11
    res = _audit_result(hyp22=True, c22=((1e-12, 1e-9), (0.0, 1e-11)), t1_status=(F, P),
                        t1_residuals=(1e-5, 1e-20), exact=False)
    d = au.disagreement(res)
    assert "holds only to 1.0e-12 (uncertainty 1.0e-09)" in d


def test_a_disagreement_names_the_scene_after_the_first_colon_only():
    """The scene part of 'theorem1:SCENE' is everything after the first colon (a scene named
    'ring:2' is 'ring:2', not 'ring')."""
    res = au.AuditResult("t", 2, False, 30, True)
    res.facts = {"22": False}
    res.checks = [au.Check("22a", au.FAIL, 1e-20, "", "balls", 1e-25), au.Check("22b", au.PASS, 0.0, "", "balls", 1e-25),
                  au.Check("theorem1:ring:2", au.PASS, 1e-30, "", None, 1e-15), au.Check("theorem1", au.PASS, 1e-30, "")]
    text = au.disagreement(res)
    assert "DISAGREEMENT" in text and "passes on ring:2." in text


# --- the audit's Theorem 1 verdict ------------------------------------------------------------------
SCENES4 = ("particle", "skate", "robot", "mp-particles")


def _fake_t1(**over):
    r = {"theorem1-q0": 1e-40, "theorem1-q1": 1e-40, "fd_error": 1e-35, "without_forces_q0": 1.0,
         "wellposed": "well-posed", "rank_deficiency": 0, "dps": 30, "dps_fd": 50}
    r.update(over)
    return r


def _theorem1(monkeypatch, per_scene):
    from ldaspark.lab.theory import audit as au
    from ldaspark.analysis import discrete
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda system, *a, **k: per_scene(system.name))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 30, True, SCENES4)
    return {c.name: c for c in checks}


@pytest.mark.parametrize("bad", SCENES4)
@pytest.mark.parametrize("side", ["theorem1-q0", "theorem1-q1"])
def test_theorem1_fails_when_exactly_one_scene_fails(monkeypatch, bad, side):
    from ldaspark.lab.theory import audit as au
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({side: 1e-3} if scn == bad else {})))
    assert [by[f"theorem1:{s}"].status for s in SCENES4] == [au.FAIL if s == bad else au.PASS for s in SCENES4]
    assert by["theorem1"].status == au.FAIL
    assert by["theorem1"].residual == pytest.approx(1e-3)              # the worst scene, not the first
    assert "1 failing" in by["theorem1"].detail and "4 of 4" in by["theorem1"].detail


def test_theorem1_passes_only_when_every_decided_scene_passes(monkeypatch):
    from ldaspark.lab.theory import audit as au
    by = _theorem1(monkeypatch, lambda scn: _fake_t1())
    assert by["theorem1"].status == au.PASS and "0 failing" in by["theorem1"].detail
    # one undecided scene (tolerance without teeth) and three passing: still decided, passes
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn == "robot" else {})))
    assert by["theorem1:robot"].status == au.SKIP and by["theorem1"].status == au.PASS
    assert "3 of 4" in by["theorem1"].detail
    # one undecided and one failing: fails
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn == "robot" else
                                                      {"theorem1-q1": 1e-3} if scn == "skate" else {})))
    assert by["theorem1"].status == au.FAIL
    # decided on exactly two (the minimum): passes; on one: fails
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn in ("robot", "skate") else {})))
    assert by["theorem1"].status == au.PASS
    by = _theorem1(monkeypatch, lambda scn: _fake_t1(**({"fd_error": 1e-3} if scn != "particle" else {})))
    assert by["theorem1"].status == au.FAIL and "at least 2" in by["theorem1"].detail


def test_theorem1_summary_rule_directly():
    from ldaspark.lab.theory import audit as au
    C = au.Check

    def summary(*st):
        return au._theorem1_summary([C(f"theorem1:s{i}", x, 1e-9 * (i + 1), "") for i, x in enumerate(st)]
                                    + [C("22a", au.FAIL, 1.0, "")])       # other checks do not count
    P, F, S = au.PASS, au.FAIL, au.SKIP
    assert summary(P, P, P, P).status == P
    for i in range(4):
        st = [P] * 4
        st[i] = F
        assert summary(*st).status == F, i
    assert summary(P, S, S, S).status == F          # decided on 1 < 2
    assert summary(P, P, S, S).status == P
    assert summary(P).status == P                  # one scene given: one suffices
    assert summary(S).status == F
    assert summary(P, P, P, P).residual == pytest.approx(4e-9)


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


# --- the audit's aggregate rules -------------------------------------------------------------------------
C_5 = au.Check


def _result(*statuses):
    return au.AuditResult("t", 2, True, 30, True, checks=[C_5(f"c{i}", x, None, "") for i, x in enumerate(statuses)])


def test_the_exit_code_is_one_when_any_check_fails():
    assert _result(P, P, I, S).exit_code == 0
    assert _result(P, F, P).exit_code == 1
    assert _result(F).exit_code == 1
    assert _result(P, P, F).as_dict()["exit_code"] == 1


def test_entry_tolerances_need_every_condition_to_hold_and_take_the_largest_residual():
    good = [C_5("22a", P, 1e-20, ""), C_5("22b", P, 3e-20, ""), C_5("23a", P, 2e-18, ""), C_5("23b", P, 1e-18, ""),
            C_5("23c", P, 0.0, ""), C_5("23d", P, None, ""), C_5("theorem1", F, 1.0, "")]
    t22, t23 = au.entry_tolerances(good)
    assert t22 == _close(au.ENTRY_TOL_FACTOR * 3e-20)          # the larger, not the first
    assert t23 == _close(au.ENTRY_TOL_FACTOR * 2e-18)
    for k in range(6):
        bad = list(good)
        bad[k] = C_5(bad[k].name, F if k < 2 else I, 1e-3, "")
        t22b, t23b = au.entry_tolerances(bad)
        # one condition missed: its group is judged at full strength (0), the other keeps its tolerance
        assert (t22b, t23b) == ((0.0, t23) if k < 2 else (t22, 0.0)), k
    assert au.entry_tolerances([C_5("23a", P, 1e-9, "")]) == (0.0, _close(au.ENTRY_TOL_FACTOR * 1e-9))


def test_the_symmetry_fact_needs_all_four_of_23_and_22_needs_both(monkeypatch):
    import ldaspark.lab.theory.audit as mod
    from ldaspark.core.families import get_method

    tab = get_method("gauss-2")
    ar, e, _ = au.decide_arith(tab, 30)
    for k in range(6):
        cs = [C_5("22a", P, 0.0, ""), C_5("22b", P, 0.0, "")] + [C_5(f"23{x}", P, 0.0, "") for x in "abcd"]
        cs[k] = C_5(cs[k].name, F if k < 2 else I, 1.0, "")
        monkeypatch.setattr(mod, "check_22a", lambda ar, e, c=cs[0]: c)
        monkeypatch.setattr(mod, "check_22b", lambda ar, e, c=cs[1]: c)
        monkeypatch.setattr(mod, "check_23", lambda ar, e, c=cs[2:]: list(c))
        _, facts = au.algebraic_checks(tab, ar, e, 30)
        assert (facts["22"], facts["23"]) == ((False, True) if k < 2 else (True, False)), k


def test_a_theorem1_check_decided_nowhere_quotes_no_residual():
    """With no scene decided (each undecided by the entries' digits: Gauss-4 printed to 3 digits)
    the verdict read "is not decided at the precision of the entries (largest residual 0.0e+00)",
    a perfect residual that no scene measured. The residual is quoted only when some scene was
    decided; control: one decided scene at 3.0e-20 is quoted."""
    th = [Check(f"theorem1:{sc}", SKIP, None, "not decided") for sc in ("particle", "skate", "robot")]
    text = au.verdict(_vres(th=th, summ=INFO))
    assert "not decided at the precision of the entries" in text and "largest residual" not in text, text
    th[0] = Check("theorem1:particle", PASS, 3e-20, "agrees")
    assert "(largest residual 3.0e-20)" in au.verdict(_vres(th=th, summ=INFO))
