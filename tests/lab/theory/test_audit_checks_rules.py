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
from ldaspark.core.tableau import from_json_dict
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac
from ldaspark.analysis import order_conditions as oc
from types import SimpleNamespace
from ldaspark.core.errors import TableauError


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


# ==== audit: algebraic checks on small tableaux ===============================================
def _tab(**over):
    d = {"c": ["1/2"], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]],
         "b": [1], "b_hat": [1], "b_tilde": [1]}
    d.update(over)
    return from_json_dict(d, "t")


def _lobatto2(**over):
    d = {"c": [0, 1], "A": [[0, 0], ["1/2", "1/2"]], "A_hat": [["1/2", 0], ["1/2", 0]],
         "A_tilde": [["1/2", 0], ["1/2", 0]], "b": ["1/2", "1/2"], "b_hat": ["1/2", "1/2"],
         "b_tilde": ["1/2", "1/2"]}
    d.update(over)
    return from_json_dict(d, "l2")


def _omtab(omega, s, digits=None, b=None, c=None):
    b = b or [1.0 / s] * s
    c = c or [(i + 0.5) / s for i in range(s)]
    return types.SimpleNamespace(s=s, source_digits=digits,
                                 mp_entries=lambda dps: {"omega": mpv(omega), "b": mpv(b), "c": mpv(c)})


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


TABX = types.SimpleNamespace(source_digits=None, decimal_digits=None, decimal_digits_min=None)


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


def test_coefficient_strings_show_a_changed_entry_as_value_plus_delta():
    t = _lobatto2().with_entry("A", 1, 0, "1/1000").with_entry("b", 0, None, "-1/7")
    cs = ac._coefficient_strings(t)
    assert cs["A"][1] == ["1/2 + (1/1000)", "1/2"] and cs["b"] == ["1/2 + (-1/7)", "1/2"]
    t2 = t.with_entry("A", 1, 0, "2")                      # changed twice: nested
    assert ac._coefficient_strings(t2)["A"][1][0] == "1/2 + (1/1000) + (2)"


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


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


# --- audit_checks: omega (21e), entry precision, convergence --------------------------------------
def _omega_tab(omega, s, source_digits=15, b=None, c=None):
    ent = {"omega": [[mpmath.mpf(x) for x in row] for row in omega]}
    if b is not None:
        ent["b"] = [mpmath.mpf(x) for x in b]
        ent["c"] = [mpmath.mpf(x) for x in c]
    return SimpleNamespace(s=s, source_digits=source_digits, mp_entries=lambda dps: ent)


def _conv_tab(source_digits):
    return SimpleNamespace(source_digits=source_digits, decimal_digits_min=None, decimal_digits=None)


def test_omega_rank_21e_tolerance_scales_with_the_largest_singular_value():
    # singular values 1e6 and 1e-8; tol = 10^(3-15) * 3 = 3e-12: relative to smax (3e-6) omega is
    # singular, relative to min(smax, 1) (3e-12) it would pass
    tab = _omega_tab([["1e6", 0, 0], [0, "1e-8", 0]], 3)
    with pytest.raises(TableauError, match="omega is singular"):
        ac.check_omega(tab, None, None, 30)
    # smax < 1: the floor 1 applies, so smin = 1e-13 < tol = 3e-12 is singular as well
    tab = _omega_tab([["1e-1", 0, 0], [0, "1e-13", 0]], 3)
    with pytest.raises(TableauError):
        ac.check_omega(tab, None, None, 30)
    ok = ac.check_omega(_omega_tab([["1e-1", 0, 0], [0, "1e-9", 0]], 3), None, None, 30)
    assert ok.status == P and ok.tolerance == _close(3e-12, rel=1e-9)


def test_omega_span_tolerance_uses_the_entries_digits_and_the_largest_singular_value():
    # s = 2: omega (one row) stacked on (b_j c_j^0) = b; singular values ~1e6 and 1e-8
    b, c = ["1e6", "0"], ["0.5", "0.5"]
    tab = _omega_tab([["1e6", "1e-8"]], 2, source_digits=16, b=b, c=c)
    chk = ac.check_omega_default(tab, 30)
    # tol = 10^(3 - min(30, 16)) * 2 * max(sv0, 1), sv0 = sqrt(2) 1e6 (not 10^(3-30), not * 1)
    assert chk.tolerance == _close(2e-13 * math.sqrt(2) * 1e6, rel=1e-6)
    assert chk.status == P          # 1e-8 is below 2e-7: the rows span the default choice
    # sv0 < 1: the floor 1 applies
    tab = _omega_tab([["0.5", "1e-15"]], 2, source_digits=16, b=["0.5", "0"], c=c)
    assert ac.check_omega_default(tab, 30).tolerance == _close(2e-13, rel=1e-9)


def test_convergence_error_is_the_worst_component_of_q_and_v():
    sol = SimpleNamespace(q=[np.array([1.0 + 1e-3, 2.0 + 1e-6])], v=[np.array([0.0, 1e-9])])
    assert ac._err(sol, [1.0, 2.0], [0.0, 0.0]) == _close(1e-3, rel=1e-9)


def test_entry_floor_uses_the_fewest_digits_given():
    tab = SimpleNamespace(source_digits=10, decimal_digits_min=None, decimal_digits=12)
    assert ac._entry_floor(tab) == _close(1e3 * 1e-10, rel=1e-12)
    tab = SimpleNamespace(source_digits=None, decimal_digits_min=13, decimal_digits=11)
    assert ac._entry_floor(tab) == _close(1e3 * 1e-11, rel=1e-12)


def test_convergence_floor_uses_the_fewer_of_dps_and_the_entries_digits(monkeypatch):
    floors = []

    def obs(tab, scene_name, Ns, t_end, wdps, floor):
        floors.append(floor)
        return {"errors": [1e-6, 1e-8], "observed": 6.0, "N": Ns, "reference": "fake", "max_constraint": 0.0}
    monkeypatch.setattr(ac, "observed_order", obs)
    checks, facts = ac.convergence_checks(_conv_tab(20), 6, 30, True)
    # predicted 6 > 4: runs at dps 30; entries known to 20 digits: floor 10^(4 - 20)
    assert floors == [_close(1e-16, rel=1e-12)] * 2
    assert [c.status for c in checks if c.name.startswith("convergence:")] == [P, P]


def test_convergence_above_prediction_passes_only_when_the_finest_error_nears_the_entry_floor(monkeypatch):
    # observed 8 > predicted 4 + slack; errors 1e-2 (coarse) and 1e-9 (finest); entries of 10
    # digits: floor 1e3 * 1e-10 = 1e-7 > the finest error, so only the lower bound is decided
    monkeypatch.setattr(ac, "observed_order", lambda tab, sc, Ns, t, w, fl: {
        "errors": [1e-2, 1e-9], "observed": 8.0, "N": Ns, "reference": "fake", "max_constraint": 0.0})
    checks, _ = ac.convergence_checks(_conv_tab(10), 4, 30, True)
    conv = [c for c in checks if c.name.startswith("convergence:")]
    assert [c.status for c in conv] == [P, P]
    assert "only the lower bound is decided" in conv[0].detail


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


def _close_4(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


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
    assert facts["energy_rate"] == _close_4(2.0, rel=1e-9)
    assert chk.residual == _close_4(1e-6) and chk.status == au.INFO
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


def test_omega_rank_is_decided_by_the_smallest_singular_value_relative_to_the_largest():
    import types

    from ldaspark.core.errors import TableauError
    from ldaspark.lab.theory import audit_checks as ac

    def tab(om, src=None):
        return types.SimpleNamespace(s=3, source_digits=src, mp_entries=lambda dps: {"omega": om})
    c = ac.check_omega(tab([[2, 0, 0], [0, 0.5, 0]]), None, None, 30)
    assert c.status == ac.PASS and c.residual == _close_4(0.5)
    assert c.tolerance == _close_4(10.0 ** -27 * 3 * 2)                  # relative to the largest (2 > 1)
    c = ac.check_omega(tab([[2, 0, 0], [0, 0.5, 0]], src=20), None, None, 30)
    assert c.tolerance == _close_4(10.0 ** -17 * 3 * 2)                  # the fewer digits given decide
    with pytest.raises(TableauError):
        ac.check_omega(tab([[2, 0, 0], [0, 1e-30, 0]]), None, None, 30)  # one small singular value of two


def test_the_audit_error_is_the_worst_component_of_q_and_v():
    import types

    import numpy as np

    from ldaspark.lab.theory.audit_checks import _err
    sol = types.SimpleNamespace(q=[np.array([1.0, 2.5])], v=[np.array([0.0, 5.0])])
    assert _err(sol, [1.0, 2.0], [0.0, 0.0]) == 5.0                    # v's second component
    assert _err(sol, [1.0, -4.0], [0.0, 5.0]) == 6.5                   # q's second component
