"""Rules of ``ldaspark.lab.theory.audit_checks`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import json
import math
import types
import mpmath
import numpy as np
import pytest
import sympy
from ldaspark.core.errors import InputError, LdasparkError, TableauError
from ldaspark.core.families import gauss, get_method
from ldaspark.core.tableau_file import from_json_dict
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.analysis import order_conditions as oc
from types import SimpleNamespace

from tableau_fakes import _lobatto2, _tab, approx
from run_helpers import two_line_error


PASS, FAIL, INFO, SKIP = au.PASS, au.FAIL, au.INFO, au.SKIP


Check = au.Check


def mp_ar(tol=1e-10, dps=30):
    return oc.Arith("mp", dps=dps, tol=tol)


def mpv(v):
    with mpmath.workdps(30):
        return [mpv(x) for x in v] if isinstance(v, list) else mpmath.mpf(v)


# ==== audit: algebraic checks on small tableaux ===============================================
# ==== audit_checks: numerical checks ==========================================================
class _Sol:
    def __init__(self, q, v, k=(0.0,), energy=None):
        self.q, self.v = [np.array([0.0]), np.array(q, dtype=float)], [np.array([0.0]), np.array(v, dtype=float)]
        self.constraint = np.array(k, dtype=float)
        self.energy = energy


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


#: entries known exactly: no entries' floor (``entry_radii`` None)
TABX = types.SimpleNamespace(source_digits=None, decimal_digits=None, decimal_digits_min=None, exact=None,
                             known_exactly=True)


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
    # within an uncertainty 2e-45: the condition holds to 44 digits (floor(-log10 2e-45)), said so
    assert ac._mode(ball, 1e-50, 2e-45) == ("to 40 digits (holds to 44 digits: largest |residual| 1.0e-50, "
                                            "within the uncertainty 2.0e-45)")
    assert "holds to" not in ac._mode(ball, 0.0, 0.0)
    assert ac.digits_of(2e-45) == 44 and ac.digits_of(1e-3, 10.0) == 4 and ac.digits_of(0.0) == 99
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


def _om3(omega, b=("1/3", "1/3", "1/3"), c=("0", "1/2", "1")):
    """A 3-stage tableau with the given omega (entries otherwise exact)."""
    A = [["1/6"] * 3] * 3
    return {"c": list(c), "A": A, "A_hat": A, "A_tilde": A, "b": list(b), "b_hat": list(b), "b_tilde": list(b),
            "omega": omega}


def test_omega_rank_is_decided_against_the_entries_uncertainty():
    """rank(omega) = s-1 when its smallest singular value lies above the uncertainty of the matrix
    the entries stand for (||Delta omega||_F from their balls) plus the arithmetic's: the same value
    1e-10 is nonzero exactly or in float64 (half an ulp of 1: 1.1e-16) and not decided in 10-digit
    decimals (half a unit in the 10th digit of 1.000000000: 5e-10)."""
    assert ac.check_omega(from_json_dict(_om3([["1", "0", "0"], ["0", "1", "0"]])), None, None, 30).status == PASS
    assert ac.check_omega(_tab(), None, None, 30).residual is None                           # s = 1
    ex = from_json_dict(_om3([["1", "0", "0"], ["0", "1/10000000000", "0"]]))
    c = ac.check_omega(ex, None, None, 30)
    assert c.status == PASS and c.residual == approx(1e-10) and c.tolerance < 1e-50          # exact: arithmetic only
    fl = from_json_dict(_om3([[1.0, 0.0, 0.0], [0.0, 1e-10, 0.0]]))
    c = ac.check_omega(fl, None, None, 30)
    assert c.status == PASS and 1e-16 < c.tolerance < 3e-16                                  # half ulps of omega
    with pytest.raises(TableauError, match="omega is singular"):
        from_json_dict(_om3([["1.000000000", "0", "0"], ["0", "0.0000000001000000000", "0"]]))
    # 1e-6 in 10 digits: above 5e-10, rank 2
    c = ac.check_omega(from_json_dict(_om3([["1.000000000", "0", "0"], ["0", "0.000001000000000", "0"]])),
                       None, None, 30)
    assert c.status == PASS and 5e-10 < c.tolerance < 1e-9
    # the uncertainty scales with the entries: 1e6 in float64 carries 1.1e-10, so 1e-11 is not decided
    # (an absolute tolerance would pass it), 1e-9 is
    with pytest.raises(TableauError, match="omega is singular"):
        from_json_dict(_om3([[1e6, 0.0, 0.0], [0.0, 1e-11, 0.0]]))
    assert ac.check_omega(from_json_dict(_om3([[1e6, 0.0, 0.0], [0.0, 1e-9, 0.0]])), None, None, 30).status == PASS
    with pytest.raises(TableauError, match="omega is singular"):                             # exactly singular
        from_json_dict(_om3([["1", "2", "3"], ["2", "4", "6"]]))


def test_omega_default_span_within_the_entries_uncertainty():
    """omega's rows against (b_j c_j^(i-1)): the stacked rank, decided against twice omega's
    uncertainty. (1, 1 + 2^-52) spans b = (1/2, 1/2) in float64 (one ulp, within the half ulps), not
    exactly; (1, -1) spans it in no writing; s = 3 with the default rows spans, unit rows do not."""
    two = lambda om, b: {"c": [0, 1], "A": [[0, 0], ["1/2", "1/2"]], "A_hat": [["1/2", 0], ["1/2", 0]],
                         "A_tilde": [["1/2", 0], ["1/2", 0]], "b": b, "b_hat": b, "b_tilde": b, "omega": om}
    assert ac.check_omega_default(_tab(), 30).status == INFO                                 # s = 1
    ok = ac.check_omega_default(from_json_dict(two([["1", "1"]], ["1/2", "1/2"])), 30)
    assert ok.status == PASS and ok.residual == approx(0.0, abs=1e-50)
    fl = ac.check_omega_default(from_json_dict(two([[1.0, 1.0 + 2.0 ** -52]], [0.5, 0.5])), 30)
    assert fl.status == PASS and 0 < fl.residual < fl.tolerance < 1e-15
    ex = ac.check_omega_default(from_json_dict(two([["1", "4503599627370497/4503599627370496"]], ["1/2", "1/2"])), 30)
    assert ex.status == INFO and "stacked rank 2" in ex.detail
    no = ac.check_omega_default(from_json_dict(two([[1.0, -1.0]], [0.5, 0.5])), 30)
    assert no.status == INFO and no.residual == approx(math.sqrt(0.5), rel=1e-12)
    dflt = [["1/3", "1/3", "1/3"], ["0", "1/6", "1/3"]]                                     # b_j, b_j c_j
    assert ac.check_omega_default(from_json_dict(_om3(dflt)), 30).status == PASS
    assert ac.check_omega_default(from_json_dict(_om3([["1", "0", "0"], ["0", "1", "0"]])), 30).status == INFO


def test_probe_step_rejects_failure_and_nonfinite(monkeypatch):
    from ldaspark.core import spark
    mode = {"m": "nan"}

    class Fake:
        def __init__(self, system, tab):
            pass

        def step(self, t0, q0, v0, h):
            if mode["m"] == "raise":
                raise two_line_error(LdasparkError, "newton", "x")
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
    # the reference is Gauss-max(5, s+1): above the audited method's order 2s, never itself; a
    # 20-stage tableau (MAX_STAGES) still gets one
    assert [ac._reference_tableau(types.SimpleNamespace(s=s)).s for s in (1, 4, 5, 6, 7, 20)] == [5, 5, 6, 7, 8, 21]


def test_step_counts():
    assert ac._step_counts(0, False) == [16, 32, 64] == ac._step_counts(1, True)
    assert ac._step_counts(2, True) == [8, 16, 32] == ac._step_counts(2, False)
    assert ac._step_counts(3, False) == [4, 8, 16] and ac._step_counts(3, True) == [4, 8]
    assert ac._step_counts(4, False) == [4, 8, 16] and ac._step_counts(6, True) == [4, 8]


def test_convergence_one_sided_with_slack(convenv):
    """Below the prediction by more than ORDER_SLACK fails; above it by any amount is reported
    ("faster than the trees predict"), not failed (docs/audit.md: one-sided)."""
    p, s = 4, ac.ORDER_SLACK
    for obs, want in ((p - s - 0.01, FAIL), (p - s + 0.01, PASS), (p, PASS), (p + s - 0.01, PASS),
                      (p + s + 0.01, PASS), (p + 3, PASS), (float("nan"), FAIL)):
        convenv.obs = {"skate": obs, "particle": p}
        C, f = ac.convergence_checks(TABX, p, 30, False)
        assert C[0].status == want, obs
        assert ("faster than the trees predict" in C[0].detail) == (obs > p + s), obs
        assert C[1].status == PASS and C[1].residual == 0.0
        if math.isfinite(obs):
            assert C[0].residual == approx(abs(obs - p))
        else:
            assert C[0].residual is None and "no usable slope" in C[0].detail
    # at the tree cap the prediction is a lower bound, said so
    convenv.obs = {"skate": p + 2, "particle": p - 1}
    C, _ = ac.convergence_checks(TABX, p, 30, False, capped=True)
    assert [C[0].status, C[1].status] == [PASS, FAIL] and "tree cap" in C[0].detail


def test_convergence_floor_is_the_working_precision_or_the_measured_entries_floor(convenv, monkeypatch):
    """The slope uses errors above max(10^(4 - digits), the entries' floor measured on the scene):
    float64 up to order 4 (1e-11), dps digits above (1e-26 at dps 30, whatever digits the entries
    carry: what they contribute is measured, ``_entry_floor_measured``)."""
    floors = {}
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda tab, sc, N, t, w: floors.get(sc, (0.0, 0.0)))
    convenv.obs = {"skate": 4.0, "particle": 4.0}
    _, f = ac.convergence_checks(TABX, 4, 30, True)
    assert f["convergence_dps"] is None and convenv.calls[0][2] is None
    assert convenv.calls[0][3] == approx(1e-11) and convenv.calls[0][1] == [4, 8]
    convenv.calls.clear()
    _, f = ac.convergence_checks(types.SimpleNamespace(source_digits=20), 5, 30, False)
    assert f["convergence_dps"] == 30 and convenv.calls[0][3] == approx(1e-26)
    # a measured entries' floor above the working precision's is the floor, and said so
    convenv.calls.clear()
    floors["skate"] = (1e-7, 3.0)
    C, f = ac.convergence_checks(TABX, 4, 30, False)
    assert [c[3] for c in convenv.calls] == [approx(1e-7), approx(1e-11)]
    assert "errors below 1e-07 not used" in C[0].detail and "response of 3.0e+00" in C[0].detail
    assert f["convergence:skate"]["entry_floor"] == 1e-7 and "not used" not in C[1].detail
    # a measurement that fails (a moved tableau's run): the working precision's floor only
    def boom(*a):
        raise LdasparkError("Newton failed")
    monkeypatch.setattr(ac, "_entry_floor_measured", boom)
    convenv.calls.clear()
    C, _ = ac.convergence_checks(TABX, 4, 30, False)
    assert [c[3] for c in convenv.calls] == [approx(1e-11)] * 2 and C[0].status == PASS


def test_convergence_at_the_entries_floor_measures_at_coarser_steps(convenv, monkeypatch):
    """No usable pair above the entries' floor: coarser steps are added (N halved, down to 1)
    until a slope is found; none even there is undecided (info: the digits given cannot show the
    order), not a failure; at the working precision's floor alone, with errors above it (1e-3), there
    is no such retry and no slope fails (errors below it: the test after this one)."""
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda tab, sc, N, t, w: (1e-5, 1.0))
    seq = {"skate": [float("nan"), 4.1], "particle": [4.0]}
    calls = []

    def fake(tab, scene, Ns, t_end, wdps, floor):
        calls.append((scene, list(Ns)))
        o = seq[scene].pop(0)
        return {"observed": o, "N": Ns, "errors": [1e-3] * len(Ns), "reference": "R", "max_constraint": 0.0}
    monkeypatch.setattr(ac, "observed_order", fake)
    C, _ = ac.convergence_checks(TABX, 4, 30, False)
    assert [n for sc, n in calls if sc == "skate"] == [[4, 8, 16], [2, 4, 8, 16]] and C[0].status == PASS
    # down to h = t_end: still no slope there is undecided
    seq.update(skate=[float("nan")] * 3, particle=[4.0])
    calls.clear()
    C, _ = ac.convergence_checks(TABX, 4, 30, False)
    assert [n for sc, n in calls if sc == "skate"] == [[4, 8, 16], [2, 4, 8, 16], [1, 2, 4, 8, 16]]
    assert C[0].status == INFO and "undecided" in C[0].detail
    # the working precision's floor only, errors above it: no coarser steps, no usable slope fails
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda tab, sc, N, t, w: (0.0, 0.0))
    seq.update(skate=[float("nan")], particle=[4.0])
    calls.clear()
    C, _ = ac.convergence_checks(TABX, 4, 30, False)
    assert [n for sc, n in calls if sc == "skate"] == [[4, 8, 16]] and C[0].status == FAIL


def test_convergence_below_the_working_floor_measures_at_coarser_steps(monkeypatch):
    """The finest errors below the working precision's floor (10^(4 - dps)): the method is more
    accurate than the arithmetic shows, not failing. Gauss-12 saved at 40 digits exited 1
    ('no usable slope': 4.9e-32 at h = 1/4 and 1/8 on the skate at dps 30). Coarser steps are
    added as at the entries' floor; none even at h = t_end is undecided (info); a NaN error, or no
    slope with the finest error above the floor, still fails without retries."""
    monkeypatch.setattr(ac, "_entry_floor_measured", lambda tab, sc, N, t, w: (0.0, 0.0))
    runs = {"skate": [([4, 8], [4.9e-32, 4.9e-32], float("nan")), ([2, 4, 8], [3e-25, 4.9e-32, 4.9e-32], 22.5)],
            "particle": [([4, 8], [1.8e-27, 3e-31], float("nan")), ([2, 4, 8], [2e-28, 1.8e-27, 3e-31], float("nan")),
                         ([1, 2, 4, 8], [1e-27, 2e-28, 1.8e-27, 3e-31], float("nan"))]}
    calls = []

    def fake(tab, scene, Ns, t_end, wdps, floor):
        calls.append((scene, list(Ns), floor))
        want_N, errs, o = runs[scene].pop(0)
        assert list(Ns) == want_N
        return {"observed": o, "N": Ns, "errors": errs, "reference": "R", "max_constraint": 0.0}
    monkeypatch.setattr(ac, "observed_order", fake)
    C, f = ac.convergence_checks(TABX, 8, 30, True, capped=True)
    assert all(c[2] == approx(1e-26) for c in calls)
    assert C[0].status == PASS and "22.50" in C[0].detail
    assert C[1].status == INFO and "above the working precision's floor 1e-26" in C[1].detail and "1/1" in C[1].detail
    # a NaN error (a broken run), or the finest error above the floor: no retry, no slope fails
    for errs in ([float("nan"), 1e-30], [1e-3, 1e-4]):
        runs.update(skate=[([4, 8], errs, float("nan"))], particle=[([4, 8], [1e-10, 1e-12], 6.6)])
        calls.clear()
        C, _ = ac.convergence_checks(TABX, 8, 30, True, capped=True)
        assert [n for sc, n, _ in calls if sc == "skate"] == [[4, 8]] and C[0].status == FAIL
        assert "no usable slope" in C[0].detail


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
    convenv.obs = {"skate": two_line_error(LdasparkError, "newton", "x"), "particle": 4.0}
    C, f = ac.convergence_checks(TABX, 4, 30, False)
    assert [c.name for c in C] == ["convergence:skate", "convergence:particle", "constraint"]
    assert C[0].status == FAIL and C[0].detail == "integration failed: newton" and C[1].status == PASS
    assert "convergence:skate" not in f and f["max_constraint"] == 1e-20


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
        raise two_line_error(LdasparkError, "diverged", "x")
    monkeypatch.setattr(ac, "_run", boom)
    c, f = ac.energy_check(None, True)
    assert c.status == FAIL and f == {} and c.detail.endswith("failed: diverged") and "h = 0.1" in c.detail


def test_coefficient_strings_show_a_changed_entry_as_value_plus_delta():
    t = _lobatto2().with_entry("A", 1, 0, "1/1000").with_entry("b", 0, None, "-1/7")
    cs = ac._coefficient_strings(t)
    assert cs["A"][1] == ["1/2 + (1/1000)", "1/2"] and cs["b"] == ["1/2 + (-1/7)", "1/2"]
    t2 = t.with_entry("A", 1, 0, "2")                      # changed twice: nested
    assert ac._coefficient_strings(t2)["A"][1][0] == "1/2 + (1/1000) + (2)"


P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


# --- audit_checks: omega (21e), entry precision, convergence --------------------------------------
# omega's rank and span: decided against the entries' uncertainty
# (test_omega_rank_is_decided_against_the_entries_uncertainty, test_omega_default_span_within_the_entries_uncertainty)


def test_convergence_error_is_the_worst_component_of_q_and_v():
    sol = SimpleNamespace(q=[np.array([1.0 + 1e-3, 2.0 + 1e-6])], v=[np.array([0.0, 1e-9])])
    assert ac._err(sol, [1.0, 2.0], [0.0, 0.0]) == approx(1e-3, rel=1e-9)


# the convergence floor and the one-sided check: test_convergence_floor_is_the_working_precision_or_the_measured_entries_floor,
# test_convergence_at_the_entries_floor_measures_at_coarser_steps, test_convergence_one_sided_with_slack


def test_the_energy_rate_is_log2_of_coarse_over_fine(monkeypatch):
    import types

    import numpy as np

    from ldaspark.lab.theory import audit_checks as ac
    runs = iter([4e-6, 1e-6])                                         # h then h/2: errors fall 4x: rate 2

    def fake_run(tab, sc, N, T, dps):
        m = next(runs)
        return types.SimpleNamespace(energy=np.array([1.0, 1.0 + m, 1.0 - m / 2]))
    monkeypatch.setattr(ac, "_run", fake_run)
    chk, facts = ac.energy_check(None, True)
    # |E - E0| of 1 + 4e-6 carries a rounding of eps / 4e-6 ~ 6e-11 relative
    assert facts["energy_rate"] == approx(2.0, rel=1e-9)
    assert chk.residual == approx(1e-6) and chk.status == au.INFO
    assert [h for h, _ in facts["energy"]] == [0.1, 0.05]


def test_a_condition_within_the_uncertainty_reports_its_largest_residual():
    import types

    from ldaspark.lab.theory.audit_checks import _worst
    ball = types.SimpleNamespace(exact=False, radius=lambda v: 1e-28, is_zero=lambda v: abs(v) <= 1e-28,
                                 to_float=float)
    assert _worst(ball, [(1e-30, "a"), (-3e-30, "b"), (2e-30, "c")]) == (3e-30, None, True, 1e-28)
    # one item beyond the uncertainty: that one, and the largest of those beyond
    w, lab, ok, _ = _worst(ball, [(1e-30, "a"), (5e-20, "b"), (-7e-20, "c"), (6e-20, "d")])
    assert (w, lab, ok) == (7e-20, "c", False)


def test_the_audit_error_is_the_worst_component_of_q_and_v():
    import types

    import numpy as np

    from ldaspark.lab.theory.audit_checks import _err
    sol = types.SimpleNamespace(q=[np.array([1.0, 2.5])], v=[np.array([0.0, 5.0])])
    assert _err(sol, [1.0, 2.0], [0.0, 0.0]) == 5.0                    # v's second component
    assert _err(sol, [1.0, -4.0], [0.0, 5.0]) == 6.5                   # q's second component


def test_entry_radii_is_the_rank_probes_reading_of_the_balls(monkeypatch):
    """``entry_radii`` read the entries' balls itself (``tab.ball_entries(ball_digits(tab, 30))``)
    beside ``analysis.discrete._entry_balls``, the rank probe's reading: one reading now
    (``discrete.entry_radii_of``). A stand-in for ``_entry_balls`` reaches the audit (it did not
    before). Control: on a tableau of short decimals and floats the radii are those of the former
    reading, entry by entry, and a tableau known exactly still has none."""
    from ldaspark.analysis import discrete
    tab = _lobatto2(c=[0, 1.0], b=["0.5", 0.5])              # a float and a 1-digit decimal
    balls = tab.ball_entries(oc.ball_digits(tab, 30))
    before = {k: [[float(x.rad()) for x in r] if isinstance(r, list) else float(r.rad()) for r in balls[k]]
              for k in ac.PERTURBED}
    assert ac.PERTURBED == discrete._PROBED
    assert ac.entry_radii(tab) == before and max(before["b"]) > 0
    assert ac.entry_radii(_lobatto2()) is None                 # exact entries: nothing to propagate
    def ball(r):
        return types.SimpleNamespace(rad=lambda: r)
    stand_in = {k: [ball(1.0 if k == "c" else 0.0) for _ in range(2)] if k in ("c", "b", "b_hat", "b_tilde")
                else [[ball(0.0)] * 2 for _ in range(2)] for k in discrete._PROBED}
    monkeypatch.setattr(discrete, "_entry_balls", lambda t: stand_in)
    got = ac.entry_radii(tab)
    assert got["c"] == [1.0, 1.0] and max(got["A"][0] + got["A"][1] + got["b"]) == 0.0, got
