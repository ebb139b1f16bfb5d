"""Survivors of the generated mutants' final sample (reports/mutation-generated.md), each killed by
an input on which the right computation and the mutated one differ."""
from __future__ import annotations

from ldaspark.lab.theory import audit as au


def test_a_disagreement_names_the_scene_after_the_first_colon_only():
    """The scene part of 'theorem1:SCENE' is everything after the first colon (a scene named
    'ring:2' is 'ring:2', not 'ring')."""
    res = au.AuditResult("t", 2, False, 30, True)
    res.facts = {"22": False}
    res.checks = [au.Check("22a", au.FAIL, 1e-20, "", "balls", 1e-25), au.Check("22b", au.PASS, 0.0, "", "balls", 1e-25),
                  au.Check("theorem1:ring:2", au.PASS, 1e-30, "", None, 1e-15), au.Check("theorem1", au.PASS, 1e-30, "")]
    text = au.disagreement(res)
    assert "DISAGREEMENT" in text and "passes on ring:2." in text


def test_omega_is_refused_below_the_absolute_tolerance_when_its_scale_is_below_one():
    """The rank tolerance scales with max(largest singular value, 1): for omega with singular
    values 0.5 and 2e-7 at 10 source digits (tol = 3e-7), 2e-7 is singular (scaling by 0.5 alone
    would pass it); 4e-7 passes."""
    import types

    import mpmath
    import pytest

    from ldaspark.core.errors import TableauError
    from ldaspark.lab.theory import audit_checks as ac

    def tab(omega):
        with mpmath.workdps(30):
            om = [[mpmath.mpf(x) for x in row] for row in omega]
        return types.SimpleNamespace(s=3, source_digits=10, mp_entries=lambda dps: {"omega": om})
    with pytest.raises(TableauError, match="singular"):
        ac.check_omega(tab([[0.5, 0, 0], [0, 2e-7, 0]]), None, None, 30)
    c = ac.check_omega(tab([[0.5, 0, 0], [0, 4e-7, 0]]), None, None, 30)
    assert c.status == ac.PASS and c.tolerance == pytest.approx(3e-7, rel=1e-12, abs=0)


def test_the_method_table_lists_the_builtin_methods_up_to_four_stages(monkeypatch):
    from ldaspark.analysis import conditions as cond
    asked = []
    monkeypatch.setattr(cond, "builtin_method_names", lambda max_s: asked.append(max_s) or [])
    assert cond.method_table() == [] and asked == [4]


def test_the_discrete_bvp_works_at_40_digits_unless_told():
    from ldaspark.core.families import get_method
    from ldaspark.models.scenes import particle
    from ldaspark.analysis.discrete import DiscreteBVP
    sysm = particle().system
    bvp = DiscreteBVP(sysm, get_method("gauss-2", exact=True))
    assert bvp.dps == 40 and bvp.method.backend.dps == 40
    assert DiscreteBVP(sysm, get_method("gauss-2", exact=True), dps=None).dps is None


def test_the_exact_flow_bvp_starts_from_the_secant_and_counts_from_one():
    """A free particle under k = v2: the straight line is the solution, and the secant velocity
    (q1 - q0)/h with zero accelerations solves the collocation system at once: one Newton
    iteration (the first increment is zero). A guess (q1 - q0) * h needs a second; so does a count
    that starts at 2."""
    import mpmath
    import sympy

    from ldaspark.core.system import LagrangianSystem
    from ldaspark.lab.theory import exact_flow as EF
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    free = LagrangianSystem((v[0] ** 2 + v[1] ** 2) / 2, [v[1]], q, v, name="free")
    with mpmath.workdps(25):
        r = EF.ExactFlow(free, dps=25, stages=2).bvp(0, ["0.3", "0"], "0.5", ["1.3", "0"], sensitivities=False)
        assert r.iterations == 1
        assert abs(r.v0[0] - 2) < mpmath.mpf(10) ** -20 and abs(r.v0[1]) < mpmath.mpf(10) ** -20


def test_the_classical_order_is_searched_up_to_eight():
    """Gauss with 5 stages has order 10: the tree conditions hold through order 8, the cap
    (MAX_ORDER), so the reported order is 8, not more."""
    import mpmath

    from ldaspark.core.families import get_method
    from ldaspark.analysis import order_conditions as oc
    tab = get_method("gauss-5")
    with mpmath.workdps(30):
        e = tab.mp_entries(30)
        ar = oc.Arith("mp", dps=30, tol=1e-20)
        r = oc.rk_order(ar, e["A"], e["b"])
    assert oc.MAX_ORDER == 8 and r.order == 8


# --- documented defaults and the precision the ledger reports ------------------------------------
def _documented_defaults(doc):
    """{parameter: text} for numpydoc parameters whose description says '(default X' (X up to the
    first ';' or ')' that closes it)."""
    import re
    out, name = {}, None
    for line in (doc or "").splitlines():
        m = re.match(r"^(\w+)(?:, (\w+))* : ", line)
        if m and not line.startswith(" "):
            name = [n.strip() for n in line.split(" : ")[0].split(",")]
            continue
        if name and line.startswith(" "):
            d = re.search(r"\(default ([^;]*?)(?:;|\)$|\)\.|\)\s*$)", line.strip())
            if d:
                for n in name:
                    out[n] = d.group(1).strip()
        elif not line.strip():
            continue
        else:
            name = None
    return out


def test_documented_defaults_are_the_signatures_defaults():
    """Where a docstring states a parameter's default, it is the one the signature has (a working
    precision or a step factor changed in one place and not the other misreports what ran)."""
    import ast
    import importlib
    import inspect
    import pkgutil

    import ldaspark
    seen, bad = 0, []
    for info in pkgutil.walk_packages(ldaspark.__path__, "ldaspark."):
        if info.name.startswith(("ldaspark.lab.mutants.catalogue", "ldaspark.__main__")):
            continue
        mod = importlib.import_module(info.name)
        for fname, obj in vars(mod).items():
            if not inspect.isfunction(obj) or obj.__module__ != mod.__name__:
                continue
            try:
                params = inspect.signature(obj).parameters
            except (TypeError, ValueError):
                continue
            for p, text in _documented_defaults(inspect.getdoc(obj)).items():
                if p not in params or params[p].default in (inspect.Parameter.empty, None):
                    continue          # None: the docstring names the value it stands for
                try:
                    want = ast.literal_eval(text)
                except (ValueError, SyntaxError):
                    continue
                seen += 1
                if params[p].default != want:
                    bad.append(f"{info.name}.{fname}({p}): documented {text}, signature {params[p].default!r}")
    assert seen >= 4 and not bad, bad


def test_the_documented_default_parser():
    doc = "Parameters\n----------\nh : float\n    Step.\ndps : int, optional\n    Working digits (default 40).\n" \
          "h_factors : tuple\n    Factors (default (1, \"1/2\")).\nx : int\n    Bound (default 20; more is slow).\n"
    assert _documented_defaults(doc) == {"dps": "40", "h_factors": "(1, \"1/2\")", "x": "20"}


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
                           "20b-corrected", "f_d_minus", "k0")}
    monkeypatch.setattr(cp, "exact_identities", spy("s5", S5.exact_identities, r5))
    monkeypatch.setattr(cp, "reduction", spy("s7", S7.reduction, {"diff": 0.0, "stage": 0.0}))
    monkeypatch.setattr(cp, "one_newton_iteration", spy("s7n", S7.one_newton_iteration, {"after_one": 0.0}))
    recs5 = [r for r in cp.section5_records(True) if r["claim"] in ("16", "18", "17-integral")]
    recs7 = cp.section7_records(True)
    assert recs5 and {r["dps"] for r in recs5} == {ran["s5"]} == {32}
    assert recs7 and {r["dps"] for r in recs7} == {ran["s7"]} == {ran["s7n"]} == {40}


def test_the_null_vectors_are_recomputed_only_under_a_genuine_sigma_below_float64(monkeypatch):
    """With one structural zero (at the precision floor), the float64 null vectors serve unless
    the smallest *genuine* sigma (the one above the structural zeros) is below 1e-12; the
    structural zero itself always is, and must not decide."""
    from test_checking_theory2 import GOOD, _classify, _fake_wellposed
    calls = []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 2 * h, 10.0 ** -d], GOOD, svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-float" and calls == []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-14 * h, 10.0 ** -d], GOOD, svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-full" and len(calls) == 1


def test_an_exact_value_is_reported_as_the_nearest_double():
    """1.00000000000000011103 lies above the midpoint 1 + 2^-53 of 1 and 1 + 2^-52: the nearest
    double is 1 + 2^-52. Rounding to 20 digits first lands below the midpoint (1.0): a double rounding."""
    import sympy
    from sympy.polys.domains import QQ

    from ldaspark.analysis import order_conditions as oc
    ar = oc.Arith("exact", K=QQ)
    x = QQ(100000000000000011103, 10 ** 20)
    assert ar.to_float(x) == 1 + 2.0 ** -52
    assert ar.to_float(QQ(1, 3)) == 1 / 3
    alg = oc.Arith("exact", K=QQ.algebraic_field(sympy.sqrt(2)))
    assert alg.to_float(alg.K.from_sympy(sympy.sqrt(2))) == 2 ** 0.5


def test_the_exact_flow_takes_24_gauss_stages_unless_told():
    """The module's docstring: s = 24 by default (order 48)."""
    import sympy

    from ldaspark.core.system import LagrangianSystem
    from ldaspark.lab.theory import exact_flow as EF
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    free = LagrangianSystem((v[0] ** 2 + v[1] ** 2) / 2, [v[1]], q, v, name="free")
    assert EF.ExactFlow(free, dps=20).s == 24 and EF.ExactFlow(free, dps=20, stages=3).s == 3
    import pytest

    from ldaspark.core.errors import TableauError
    with pytest.raises(TableauError, match="limit 48"):               # still bounded
        EF.ExactFlow(free, dps=20, stages=49)


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


def test_the_exact_flow_newton_stops_after_max_iter_iterations():
    """From a wrong start the free particle needs two iterations (one to solve the linear system,
    one to see a zero increment): max_iter = 1 is refused, 2 converges."""
    import mpmath
    import pytest
    import sympy

    from ldaspark.core.system import LagrangianSystem
    from ldaspark.lab.theory import exact_flow as EF
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    free = LagrangianSystem((v[0] ** 2 + v[1] ** 2) / 2, [v[1]], q, v, name="free")
    fl = EF.ExactFlow(free, dps=25, stages=2)
    with mpmath.workdps(25):
        guess = [0] * 4 + [mpmath.mpf(1), mpmath.mpf(0)]
        with pytest.raises(EF.ExactFlowError, match="did not converge in 1 iterations"):
            fl.bvp(0, ["0.3", "0"], "0.5", ["1.3", "0"], x_guess=guess, max_iter=1, sensitivities=False)
        r = fl.bvp(0, ["0.3", "0"], "0.5", ["1.3", "0"], x_guess=guess, max_iter=2, sensitivities=False)
        assert r.iterations == 2 and abs(r.v0[0] - 2) < mpmath.mpf(10) ** -20


def test_the_null_vectors_and_their_recomputation_are_those_of_the_highest_precision(monkeypatch):
    """With three precisions the null space is read at the last (highest) one, and whether a
    genuine sigma is below float64 resolution is decided there too."""
    from test_checking_theory2 import GOOD, _classify, _fake_wellposed

    from ldaspark.analysis import wellposedness as W
    _fake_wellposed(monkeypatch, lambda d, h: [1, 2 * h, 10.0 ** -d], GOOD)
    got = {}
    monkeypatch.setattr(W, "_null_support", lambda bvp, Vh, r: got.update(d=bvp.d) or dict(GOOD))
    assert _classify(dps=(30, 40, 50))["rank_deficiency"] == 1 and got["d"] == 50
    calls = []
    seen = _fake_wellposed(monkeypatch, lambda d, h: [1, 1e-14 if d == 30 else 1e-11, 10.0 ** -d], GOOD,
                           svd_calls=calls)
    assert _classify()["rank_deficiency"] == 1 and seen["Vh"] == "Vh-float" and calls == []


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
