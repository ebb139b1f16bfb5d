"""Issue #31 (generated mutants): the verdict rules of the stability report's modules
(``ldaspark.lab.reports.stability``, ``stability_checks``, ``stability_stiff``, ``stability_regimes``)
and of the bicycle references (``ldaspark.lab.theory.bicycle_flow``, ``ldaspark.models.bicycle_benchmark``)
fed inputs on which the right rule and its plausible neighbours (< vs <=, min vs max, all vs any,
a ratio upside down, one field of a pair) give different answers.

The expensive inner computations (compiled runs, whole integrations, the SPARK flow Jacobian) are
replaced by small synthetic stand-ins with known answers, so the rules themselves are checked in
pure Python; the whole file runs in a few seconds."""
from __future__ import annotations

import math
import sys
import types

import numpy as np
import pytest

from ldaspark.core.errors import NewtonError
from ldaspark.lab.reports import stability as st
from ldaspark.lab.reports import stability_checks as sc_
from ldaspark.lab.reports import stability_regimes as rg
from ldaspark.lab.reports import stability_stiff as ss


# ================================================================================================
# a fake ``ldaspark.compiled.fast`` (the real one compiles numba kernels: minutes on a cold cache)
# ================================================================================================
class _Sol:
    def __init__(self, energy, constraint, stats=None, q=None, v=None):
        self.energy, self.constraint = energy, constraint
        self.stats = stats or {}
        self.q, self.v = q, v


def _fake_fast(monkeypatch, fast_integrate=None, roundoff_errors=None):
    mod = types.ModuleType("ldaspark.compiled.fast")
    if fast_integrate is not None:
        mod.fast_integrate = fast_integrate
    if roundoff_errors is not None:
        mod.roundoff_errors = roundoff_errors
    monkeypatch.setitem(sys.modules, "ldaspark.compiled.fast", mod)
    return mod


# ================================================================================================
# stability_checks
# ================================================================================================
def test_local_order_uses_the_closed_interval_and_needs_two_points():
    h = [1e-4, 1e-3, 1e-2, 1e-1, 1.0]
    err = [1.0, 1e-9, 1e-6, 1e-3, 5.0]       # slope 3 on [1e-3, 1e-1]; the outer points are off the line
    assert sc_.local_order(h, err, 1e-3, 1e-1) == pytest.approx(3.0, abs=1e-9)
    # exactly the two end points of the interval: both included (lo <= a <= hi), a slope, not nan
    assert sc_.local_order(h, err, 1e-3, 1e-2) == pytest.approx(3.0, abs=1e-9)
    # one point: nan; a zero error is left out (log 0), not counted
    assert math.isnan(sc_.local_order(h, err, 1e-3, 1e-3))
    assert math.isnan(sc_.local_order(h, [1.0, 1e-9, 0.0, 0.0, 5.0], 1e-3, 1e-1))
    # the slope of log err against log h, not its reciprocal
    assert sc_.local_order([1e-2, 1e-1], [1e-4, 1.0], 1e-3, 1.0) == pytest.approx(4.0, abs=1e-9)


def test_float64_floor_h_is_the_largest_h_strictly_above_factor_times_reference():
    h = [1e-6, 1e-5, 1e-4, 1e-3]
    ref = [1e-20, 1e-18, 1e-16, 1e-14]
    e64 = [1e-15, 4e-18, 5e-16, 1e-14]      # 1e-6: bad; 1e-5: exactly 4x (not bad); 1e-4: bad; 1e-3: good
    assert sc_.float64_floor_h(h, e64, ref) == 1e-4
    assert sc_.float64_floor_h(h, e64, ref, factor=10.0) == 1e-6
    assert sc_.float64_floor_h(h, ref, ref) is None
    # a zero reference error does not make every point "bad" by 0 * factor: it is floored at 1e-300
    assert sc_.float64_floor_h([1.0], [1e-301], [0.0]) is None


def test_stage_sweep_two_stages_families_and_rounding_levels():
    rows = sc_.stage_sweep(max_s=2)
    assert [(r["method"], r["s"]) for r in rows] == [("gauss-1", 1), ("gauss-2", 2), ("lobatto-iiia-iiib-2", 2),
                                                     ("lobatto-iiia-iiib-iiid-2", 2)]
    for r in rows:
        # the right order conditions for the family (B(2s) for Lobatto would fail at O(1))
        assert max(r["float64"].values()) < 1e-15 and max(r["mp50"].values()) < 1e-48, r
        assert set(r["float64"]) == {"B", "C", "D", "22b"}
    # gauss-2 has irrational nodes: the float64 residuals are rounding, not zero, and above the 50-digit ones
    g2 = rows[1]
    assert max(g2["float64"].values()) > 1e-19 > 1e-45 > max(g2["mp50"].values())


def test_residuals_see_a_wrong_weight_and_the_family_order():
    # Gauss 1: c = 1/2, b = 1, A = A_hat = 1/2: every residual 0; b = 0.9 breaks B(1) by exactly 0.1
    ent = {"c": np.array([0.5]), "b": np.array([1.0]), "A": np.array([[0.5]]), "A_hat": np.array([[0.5]])}
    r = sc_._residuals(ent, 1, "gauss")
    assert max(r.values()) == 0.0
    bad = dict(ent, b=np.array([0.9]))
    r = sc_._residuals(bad, 1, "gauss")
    assert r["B"] == pytest.approx(0.1, rel=1e-12)
    # midpoint is order 2 = 2s: B(2) holds; asked as Lobatto (p = 2s - 2 = 0) nothing is checked -> B = max of []
    with pytest.raises(ValueError):
        sc_._residuals(ent, 1, "lobatto")


def _energies(n_samples, every):
    steps = np.arange(n_samples) * every
    E = 1.0 + 1e-12 * np.sin(steps / 500.0)        # Kahan: bounded oscillation
    gap = np.where(steps >= 10 * every, 1e-10 * np.sqrt(np.maximum(steps, 1.0)), 0.0)
    gap[3] = 1e-9                                    # an early point (step < 10 every): left out of the fit
    return steps, E, gap


def test_long_run_rules_on_synthetic_runs(monkeypatch):
    every, n = 100, 10 ** 4
    steps, E, gap = _energies(n // every + 1, every)
    E[60:] += 3e-11                                   # a jump in the second half of the run
    E[10] += 5e-12                                    # a spike at step 1000: on the window's edge (n <= w)
    gap[50] = 0.0                                     # an exactly equal pair inside the fit range: left out (log 0)
    Ep = E + gap
    Kk = np.zeros((len(E), 2)); Kk[5, 1] = -2e-17
    Kp = np.zeros((len(E), 2)); Kp[7, 0] = 3e-16
    calls = []

    def fake(scene, method, h, n_steps, every, compensated):
        calls.append((method, h, n_steps, every, compensated))
        return types.SimpleNamespace(energy=E if compensated else Ep, constraint=Kk if compensated else Kp,
                                     stats={"path": "kernel-x"})
    _fake_fast(monkeypatch, fast_integrate=fake)
    out = sc_.long_run("gauss-2", "particle", 0.05, n, every)
    assert calls == [("gauss-2", 0.05, n, every, True), ("gauss-2", 0.05, n, every, False)]
    assert out["path"] == "kernel-x" and out["windows"] == [1000, 10000]
    assert out["max_k"] == {"kahan": 2e-17, "plain": 3e-16}
    assert out["E0"] == E[0]
    # windows n <= w (inclusive): the jump at sample 60 (step 6000) is in the 1e4 window only
    assert out["dE_window"]["kahan"][0] == pytest.approx(np.max(np.abs(E[:11] - E[0])), rel=0, abs=0)
    assert out["dE_window"]["kahan"][1] == pytest.approx(np.max(np.abs(E - E[0])), rel=1e-15)
    assert out["dE_window"]["kahan"][1] > 2e-11 > out["dE_window"]["kahan"][0]
    assert out["dE_window"]["plain"][0] == pytest.approx(float(np.max(np.abs(Ep[:11] - Ep[0]))), rel=1e-12)
    assert out["dE_window"]["plain"][0] > 1.01 * float(np.max(np.abs(Ep[:10] - Ep[0])))
    assert out["dE_window"]["kahan"][0] > 1.01 * float(np.max(np.abs(E[:10] - E[0])))
    gapv = np.abs(Ep - E)
    assert out["plain_minus_kahan"] == [float(np.max(gapv[:11])), float(np.max(gapv))]
    assert out["plain_minus_kahan"][0] > 1.01 * float(np.max(gapv[:10]))
    # the gap grows like sqrt(N) where it is fitted (steps >= 10 every): exponent 1/2, the early outlier ignored
    assert out["gap_exponent"] == pytest.approx(0.5, abs=1e-4)
    half = len(E) // 2
    assert out["drift_halves"]["kahan"] == pytest.approx(float(np.mean(E[half:]) - np.mean(E[:half])), rel=1e-12)
    assert out["drift_halves"]["kahan"] > 1e-11                 # second half minus first half, not the reverse
    assert out["drift_halves"]["plain"] == pytest.approx(float(np.mean(Ep[half:]) - np.mean(Ep[:half])), rel=1e-12)
    assert out["series"]["steps"][-1] == n and out["series"]["k_kahan"][5] == 2e-17
    assert out["series"]["dE_plain"][3] == pytest.approx(Ep[3] - Ep[0], rel=1e-12)
    assert out["series"]["dE_kahan"][10] == pytest.approx(E[10] - E[0], rel=1e-12) and out["series"]["dE_kahan"][0] == 0


def test_long_run_generic_fallback_when_the_compiled_path_is_missing(monkeypatch):
    monkeypatch.setitem(sys.modules, "ldaspark.compiled.fast", None)    # import -> ImportError
    seen = []

    def generic(system, tab, t0, q0, v0, h, n_steps):
        seen.append((tab.name, h, n_steps))
        E = np.full(n_steps + 1, 2.0)
        E[100], E[250] = 2.5, 1.0                        # every 250th sample is kept: 1.0 seen, 2.5 not
        K = np.zeros((n_steps + 1, 1))
        K[500, 0], K[7, 0] = -1e-14, 1.0
        return types.SimpleNamespace(energy=E, constraint=K)
    monkeypatch.setattr(sc_, "integrate", generic)
    out = sc_.long_run("lobatto-iiia-iiib-2", "particle", 0.05, 1000, 250)
    assert seen == [("lobatto-iiia-iiib-2", 0.05, 1000)] * 2
    assert out["path"] == "generic" and out["windows"] == [1000]
    assert out["series"]["steps"] == [0, 250, 500, 750, 1000]
    assert out["series"]["dE_kahan"] == [0.0, -1.0, 0.0, 0.0, 0.0]
    assert out["max_k"] == {"kahan": 1e-14, "plain": 1e-14} and out["dE_window"]["kahan"] == [1.0]
    # both runs are the same generic run: no plain - Kahan gap, so no exponent can be fitted
    assert out["plain_minus_kahan"] == [0.0] and math.isnan(out["gap_exponent"])


def test_roundoff_growth_fits_only_n_at_least_ten_samples_and_needs_three_points(monkeypatch):
    every = 10
    N = [10, 50, 100, 1000, 10000, 100000]
    r = {"N": N, "rms": {"plain": [1.0, 1.0, 1e-3, 1e-3 * 10 ** 0.5, 1e-2, 1e-2 * 10 ** 0.5],  # sqrt law from N = 100
                         "compensated": [1e-3, 1e-3, 0.0, 0.0, 2e-4, 2e-2],      # two usable points: no fit
                         "exact3": [5.0, 5.0, 0.0, 1e-2, 1e-1, 1.0]}}            # a zero (left out), then linear
    seen = {}

    def fake(n_steps, every, n_ics):
        seen.update(n_steps=n_steps, every=every, n_ics=n_ics)
        return {k: (dict(v) if isinstance(v, dict) else list(v)) for k, v in r.items()}
    _fake_fast(monkeypatch, roundoff_errors=fake)
    out = sc_.roundoff_growth(n_steps=100000, every=every, n_ics=3)
    assert seen == {"n_steps": 100000, "every": every, "n_ics": 3}
    assert out["exponent"]["plain"] == pytest.approx(0.5, abs=1e-9)
    assert out["exponent"]["exact3"] == pytest.approx(1.0, abs=1e-9)
    assert math.isnan(out["exponent"]["compensated"])


def test_newton_limit_doubles_up_to_and_including_h_max(monkeypatch):
    tried = []

    class Fake:
        def __init__(self, system, tab):
            pass

        def step(self, t0, q0, v0, h):
            tried.append(h)
            if h >= fail_at:
                raise NewtonError("no convergence")
    monkeypatch.setattr(sc_, "SparkMethod", Fake)
    monkeypatch.setattr(sc_, "get_scene", lambda name: _FakeScene())
    fail_at = 2.0
    assert sc_.newton_limit("gauss-2", "skate", 0.25, 64.0)[:2] == (1.0, 2.0)
    tried.clear()
    fail_at = 1e9
    ok, bad, msg = sc_.newton_limit("gauss-2", "skate", 0.25, 4.0)
    assert (ok, bad, msg) == (4.0, None, "") and tried == [0.25, 0.5, 1.0, 2.0, 4.0]


# ================================================================================================
# stability_stiff
# ================================================================================================
def test_classify_thresholds_are_strict():
    row = lambda g, e, o="ok": {"outcome": o, "dE_growth": g, "max_rel_dE": e}  # noqa: E731
    assert ss.classify(row(ss.DE_GROWTH * 1.01, 1e-3)) == "growing"
    assert ss.classify(row(ss.DE_GROWTH, 1e-3)) == "bounded"              # exactly the factor: not growing
    assert ss.classify(row(100.0, 1e-8)) == "bounded"                     # at the round-off bound: not judged
    assert ss.classify(row(100.0, 2e-8)) == "growing"
    assert ss.classify(row(None, 1.0)) == "bounded"
    assert ss.classify(row(100.0, 1.0, "NewtonError")) == "failed"


def test_why_names_the_cause():
    base = {"class": "failed", "rho": 1.0, "dE_before": None}
    assert ss.why(dict(base, **{"class": "bounded", "rho": 5.0})) == ""
    assert ss.why(dict(base, rho=1 + 2e-9)) == "linear instability"
    assert ss.why(dict(base, rho=1 + 0.5e-9, **{"class": "growing"})) == "energy growth"
    assert ss.why(base) == "Newton"
    assert ss.why(dict(base, dE_before=ss.DE_BOUND * 0.99)) == "Newton"
    assert ss.why(dict(base, dE_before=ss.DE_BOUND)) == "energy growth, then Newton"


def test_stiff_run_growth_ratio_and_failure_context(monkeypatch):
    n_calls = []

    def fake(system, method, t0, q0, v0, h, n, every, kernel):
        n_calls.append((method, h, n))
        if n > 100:
            raise NewtonError("Newton failed at step 7\nsecond line", step=7)
        E = np.ones(n + 1)
        E[1] = 1.02           # relative to E[0] = 1, not to E[1]
        E[2] = 1.1            # first half (samples 0 .. half - 1): max rel dE 0.1
        E[(n + 1) // 2] = 0.5  # second half starts at sample half: 0.5 -> growth 5
        E[-1] = 0.7
        return _Sol(E, np.array([[1e-16], [-3e-16]]), {"mean_iterations": 2.5, "max_iterations": 4,
                                                      "generic_steps": 1})
    _fake_fast(monkeypatch, fast_integrate=fake)
    r = ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10, omega=100)
    assert n_calls[-1] == ("gauss-1", 0.02, 10)
    assert r["outcome"] == "ok" and r["max_rel_dE"] == pytest.approx(0.5, rel=1e-12)
    assert r["dE_growth"] == pytest.approx(5.0, rel=1e-12)                   # second / first, not first / second
    assert r["max_k"] == 3e-16 and r["iterations"] == 2.5 and r["max_iterations"] == 4
    assert r["generic_steps"] == 1 and r["full_newton_steps"] == 0
    # a constant energy in the first half: no ratio
    def flat(system, method, t0, q0, v0, h, n, every, kernel):
        E = np.ones(n + 1); E[-1] = 2.0
        return _Sol(E, np.zeros((2, 1)), {"mean_iterations": 1.0, "max_iterations": 1})
    _fake_fast(monkeypatch, fast_integrate=flat)
    assert ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10)["dE_growth"] is None
    _fake_fast(monkeypatch, fast_integrate=fake)
    bad = ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=1000)
    assert bad["outcome"] == "NewtonError" and bad["step"] == 7 and bad["message"] == "Newton failed at step 7"

    def long_msg(*a, **k):
        raise NewtonError("x" * 170 + "\nsecond line", step=3)
    _fake_fast(monkeypatch, fast_integrate=long_msg)
    assert ss.stiff_run("stiff-particle", "gauss-1", 2.0, n=10)["message"] == "x" * 160    # the first line, cut at 160
    assert ss.tiny_step_run("skate", "gauss-1", 1e-4, 10)["message"] == "x" * 160
    _fake_fast(monkeypatch, fast_integrate=fake)
    # the context reruns the same scene, method and h omega up to the step before the failure
    n_calls.clear()
    assert ss.failure_context(bad) == pytest.approx(0.5, rel=1e-12) and n_calls == [("gauss-1", 0.02, 7)]
    assert ss.failure_context(dict(bad, step=0)) is None and ss.failure_context(r) is None and len(n_calls) == 1


def test_stiff_job_labels_each_row(monkeypatch):
    rows = [{"hw": 1.0, "outcome": "ok", "class": "bounded", "rho": 1.0},
            {"hw": 3.0, "outcome": "NewtonError", "class": "failed", "rho": 1.5, "step": 3}]
    monkeypatch.setattr(ss, "stiff_sweep", lambda scene, method, hws, n: [dict(r) for r in rows])
    monkeypatch.setattr(ss, "failure_context", lambda r: None if r["outcome"] == "ok" else 0.9)
    out = ss.stiff_job("stiff-skate", "gauss-2", (1.0, 3.0), 10)
    assert [(r["dE_before"], r["why"]) for r in out] == [(None, ""), (0.9, "linear instability")]


def test_stiff_sweep_attaches_class_and_linear_prediction(monkeypatch):
    monkeypatch.setattr(ss, "stiff_run", lambda scene, method, hw, n: {"hw": hw, "outcome": "ok", "dE_growth": hw,
                                                                        "max_rel_dE": 1.0})
    out = ss.stiff_sweep("stiff-skate", "lobatto-iiia-iiib-2", hws=(1.0, 2.5, 5.0), n=10)
    assert [r["class"] for r in out] == ["bounded", "bounded", "growing"]
    # Stormer-Verlet: rho = 1 below z = 2, > 1 above; no R (A != A_hat)
    assert out[0]["rho"] == pytest.approx(1.0, abs=1e-12) and out[1]["rho"] > 1.5 and out[0]["R"] is None


def test_tiny_step_run_and_grid(monkeypatch):
    seen = []

    def fake(scene, method, h, n_steps, every):
        seen.append((method, h, n_steps, every))
        if method == "euler-i":
            raise NewtonError("stopped\nmore")
        return _Sol(np.array([2.0, 2.5, 1.0, 2.0]), np.array([[1e-17, -4e-17], [0.0, 0.0]]),
                    {"kernel": "spark", "mean_iterations": 2.0, "full_newton_steps": 3} if h > 1e-6
                    else {"kernel": "spark", "mean_iterations": 2.0})
    _fake_fast(monkeypatch, fast_integrate=fake)
    r = ss.tiny_step_run("skate", "gauss-2", 1e-5, 50)
    assert seen[-1] == ("gauss-2", 1e-5, 50, 1)                 # every = max(1, n // 100)
    assert r["outcome"] == "ok" and r["max_dE"] == 1.0 and r["max_k"] == 4e-17 and r["full_newton_steps"] == 3
    assert r["generic_steps"] == 0 and r["kernel"] == "spark" and r["seconds"] >= 0
    ss.tiny_step_run("skate", "gauss-2", 1e-5, 1000)
    assert seen[-1][3] == 10
    ss.tiny_step_run("skate", "gauss-2", 1e-5, 150)
    assert seen[-1][3] == 1 and type(seen[-1][3]) is int           # n // 100, not n / 100 = 1.5
    r0 = ss.tiny_step_run("skate", "gauss-2", 1e-7, 50)
    assert r0["full_newton_steps"] == 0 and r0["generic_steps"] == 0       # counters absent: none taken
    f = ss.tiny_step_run("skate", "euler-i", 1e-5, 50)
    assert f["outcome"] == "NewtonError" and f["message"] == "stopped" and "max_dE" not in f
    grid = ss.tiny_step_grid(7, methods=("gauss-1", "euler-i"), hs=(1e-4, 1e-6), scenes=("skate", "robot"))
    assert [(g["scene"], g["method"], g["h"], g["N"]) for g in grid] == [
        (s, m, h, 7) for s in ("skate", "robot") for m in ("gauss-1", "euler-i") for h in (1e-4, 1e-6)]


def test_error_floor_steps_and_error_measure(monkeypatch):
    qe, ve = ss._skate_exact(0.1)
    assert qe.shape == (3,) and ve.shape == (3,)
    seen = []

    def fake(scene, method, h, n_steps, every, compensated):
        seen.append((h, n_steps, every, compensated))
        q = np.tile(qe, (3, 1)) + 1.0; v = np.tile(ve, (3, 1)) + 1.0     # only the last row is at T
        q[-1], v[-1] = qe, ve
        q[-1, 0] += 1e-6 if compensated else 3e-6       # position error
        v[-1, 2] -= 2e-6                                 # velocity error: larger than Kahan's q error
        return _Sol(None, None, q=q, v=v)
    _fake_fast(monkeypatch, fast_integrate=fake)
    out = ss.error_floor("gauss-1", hs=(0.01, 0.03), T=0.1)
    assert out["h"] == [0.01, 0.03] and out["N"] == [10, 3]
    assert [s[1:] for s in seen] == [(10, 10, False), (10, 10, True), (3, 3, False), (3, 3, True)]
    assert seen[2][0] == pytest.approx(0.1 / 3, rel=1e-15)         # h = T / N, not the requested h
    assert out["plain"] == [pytest.approx(3e-6, rel=1e-6)] * 2
    assert out["kahan"] == [pytest.approx(2e-6, rel=1e-6)] * 2


# ================================================================================================
# stability_regimes
# ================================================================================================
def test_family_names():
    assert rg.family("euler-ii") == ("euler-i/ii", 1)
    assert rg.family("lobatto-iiia-iiib-iiid-3") == ("lobatto-iiia-iiib-iiid", 3)
    assert rg.family("gauss-10") == ("gauss", 10)


def test_rng_formats():
    assert rg._rng([None, None], str) == "-"
    assert rg._rng([3, None, 3], str) == "3"
    assert rg._rng([5, 1, 3], str) == "1 .. 5"


def _stiff_row(scene, method, hw, cls, why="", rho=1.0, outcome=None, iterations=3.0, **kw):
    r = {"scene": scene, "method": method, "hw": hw, "h": hw / 100, "N": 1000, "class": cls, "why": why,
         "rho": rho, "R": None, "outcome": outcome or ("ok" if cls != "failed" else "NewtonError"),
         "iterations": iterations, "max_rel_dE": 1e-3 * hw, "generic_steps": None, "full_newton_steps": 0}
    if r["outcome"] != "ok":
        r.update(step=5, dE_before=kw.pop("dE_before", 1e-4), message="failed")
    r.update(kw)
    return r


def _stiff_rows():
    S = []
    for scene in ss.STIFF_SCENES:
        S += [_stiff_row(scene, "gauss-2", 0.1, "bounded", iterations=2.0),
              _stiff_row(scene, "gauss-2", 1.0, "bounded", iterations=4.0),
              _stiff_row(scene, "gauss-2", 3.0, "bounded", iterations=5.0),
              _stiff_row(scene, "gauss-2", 10.0, "bounded", iterations=6.0, generic_steps=2),
              _stiff_row(scene, "gauss-2", 100.0, "failed", "Newton"),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 0.1, "bounded", iterations=1.5),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 1.0, "growing", "energy growth", iterations=3.0),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 1.9, "bounded", rho=1 + 1e-9),
              _stiff_row(scene, "lobatto-iiia-iiib-2", 2.1, "failed", "linear instability", rho=1.2),
              _stiff_row(scene, "lobatto-iiia-iiib-3", 3.0, "failed", "linear instability", rho=1.5),
              _stiff_row(scene, "lobatto-iiia-iiib-3", 10.0, "failed", "linear instability", rho=3.0,
                         dE_before=None)]
    return S


def test_stiff_summary_first_not_bounded_and_linear_limit():
    S = {(r["scene"], r["method"]): r for r in rg.stiff_summary({"stiff": _stiff_rows()})}
    assert ("stiff-skate", "gauss-1") not in S
    g = S[("stiff-skate", "gauss-2")]
    assert g["bounded_to"] == 10.0 and g["first"] == {"hw": 100.0, "class": "failed", "why": "Newton",
                                                      "outcome": "NewtonError"}
    assert g["iterations"] == {1.0: 4.0, 10.0: 6.0, 100.0: 3.0}
    assert g["generic_steps"] == 2 and g["full_newton_steps"] == 0
    lo = S[("stiff-particle", "lobatto-iiia-iiib-2")]
    # bounded up to the last bounded h omega BEFORE the first non-bounded one (1.9 is bounded again, later)
    assert lo["bounded_to"] == 0.1 and lo["first"]["hw"] == 1.0 and lo["first"]["why"] == "energy growth"
    # rho = 1 + 1e-9 counts as stable (the tolerance), 1.2 does not
    assert lo["linear_stable_to"] == 1.9 and lo["unstable_linear"] == [2.1]
    l3 = S[("stiff-skate", "lobatto-iiia-iiib-3")]
    assert l3["bounded_to"] is None and l3["first"]["hw"] == 3.0 and l3["linear_stable_to"] is None
    assert l3["iterations"] == {1.0: None, 10.0: 3.0, 100.0: None}


def test_section_stiff_cells():
    d = {"stiff": _stiff_rows()}
    L = "\n".join(rg.section_stiff(d))
    assert "| stiff-skate | gauss-2 | 10 | 100: failed (Newton) | 100 | 4.0 / 6.0 / 3.0 | 0 / 2 |" in L
    assert "| stiff-skate | lobatto-iiia-iiib-2 | 0.1 | 1: growing (energy growth) | 1.9 (rho > 1 from 2.1) |" in L
    assert "| stiff-skate | lobatto-iiia-iiib-3 | - | 3: failed (linear instability) | - |" in L
    assert "failed step 5 (Newton, dE before 1.0e-04)" in L
    assert "failed step 5 (linear instability)" in L          # dE_before None: no 'dE before'
    assert "g 1.0e-03 (3.0)" in L and "b 1.0e-04 (2.0)" in L
    assert L.count("stiff-particle: class, dE and Newton iterations") == 1


def _tiny_rows():
    rows = []
    for scene in ("skate", "robot"):
        for m in ("gauss-2", "euler-i"):
            for h in ss.TINY_H:
                if scene == "robot" and m == "euler-i" and h == 1e-5:
                    rows.append({"scene": scene, "method": m, "h": h, "N": 10 ** 4, "outcome": "NewtonError",
                                 "message": "no convergence"})
                else:
                    rows.append({"scene": scene, "method": m, "h": h, "N": 10 ** 4 if h > 1e-7 else 10 ** 5,
                                 "outcome": "ok", "max_dE": 1e-15 / h * 1e-6, "iterations": 2.0,
                                 "full_newton_steps": 2 if m == "gauss-2" and h == 1e-4 else 0,
                                 "generic_steps": 1 if h == 1e-6 else 0})
    return rows[:-2]          # the robot's euler-i at 1e-6 and 1e-7 missing: "-" cells


def _floor_rows():
    return [{"method": "gauss-1", "h": [1e-2, 1e-3, 1e-4], "N": [10, 100, 1000],
             "plain": [1e-6, 3e-12, 5e-11], "kahan": [1e-6, 2e-12, 1e-13]},
            {"method": "gauss-2", "h": [1e-2, 1e-3, 1e-4], "N": [10, 100, 1000],
             "plain": [4e-14, 1e-13, 9e-13], "kahan": [5e-14, 3e-15, 4e-15]}]


def _dps_rows():
    return [{"dps": 400, "N": 3, "seconds": 1.5, "iterations": 3.0, "log10_diff": -398.2, "ref_dps": 440},
            {"dps": 2000, "N": 3, "seconds": 9.0, "iterations": 3.0, "log10_diff": None, "ref_dps": 1960},
            {"dps": 100, "N": 2, "seconds": 0.5, "iterations": 2.0, "log10_diff": -120.4},      # older rows: no ref_dps
            {"dps": 60, "N": 2, "seconds": 0.5, "iterations": 2.0, "log10_diff": None}]


def test_section_tiny_table_and_floor():
    d = {"tiny": _tiny_rows(), "floor": _floor_rows(), "dps": _dps_rows()}
    L = "\n".join(rg.section_tiny(d))
    n = len(d["tiny"])
    assert "whole runs of N = 1e+05 steps" in L                     # the largest N, not the smallest
    assert f"{n - 1} of {n} runs finish" in L
    assert "| skate | gauss-2 | 2.00 it., 2 full, dE 1.0e-17 |" in L
    assert "2.00 it., 1 generic, dE 1.0e-15 |" in L
    assert "| robot | euler-i | 2.00 it., dE 1.0e-17 | NewtonError: `no convergence` | - | - |" in L
    # min error and the h where it is reached
    assert "| gauss-1 | 3.0e-12 (0.001) | 1.0e-13 (0.0001) | 5.0e-11 / 1.0e-13 |" in L
    assert "| gauss-2 | 4.0e-14 (0.01) | 3.0e-15 (0.001) | 9.0e-13 / 4.0e-15 |" in L
    assert "dps = 400: 3 steps in 1.50 s, 3.0 Newton it./step, difference to the run at 440 digits 1e-398" in L
    assert "dps = 2000: identical to the run at 1960 digits" in L
    assert "dps = 100: 2 steps in 0.50 s, 2.0 Newton it./step, difference to the run at 140 digits 1e-120" in L
    assert "dps = 60: identical to the run at 100 digits" in L
    d["tiny"].append({"scene": "robot", "method": "euler-i", "h": 1e-6, "N": 10, "outcome": "NonFiniteError",
                      "message": "nan at step 3"})
    assert "NonFiniteError: `nan at step 3`" in "\n".join(rg.section_tiny(d))


def test_findings_lines_quote_the_extremes():
    d = {"stiff": _stiff_rows(), "tiny": _tiny_rows(), "floor": _floor_rows()}
    tiny_fail = sum(r["outcome"] != "ok" for r in d["tiny"])
    a, b = rg.findings_lines(d)
    n = len(d["tiny"])
    assert a.startswith(f"* Tiny steps: {n - tiny_fail} of {n} whole runs")
    assert "gauss-1 3.0e-12 plain, 1.0e-13 Kahan; gauss-2 4.0e-14 plain, 3.0e-15 Kahan." in a
    assert "gauss-2: 100 (Newton) / 100 (Newton)" in b
    assert "lobatto-iiia-iiib-2: 1 (energy growth) / 1 (energy growth)" in b
    assert "euler-i:" in b and "gauss-1: ;" in b                      # no rows: nothing listed
    assert "(4 scene-method pairs)" not in b and "2 scene-method pairs" in b
    # the O(1) errors of bounded Gauss runs at h omega >= 3 (3 and 10 here): min .. max
    assert "at O(1) (3.0e-03 .. 1.0e-02 relative" in b
    assert "gauss-2 stiff-particle at 100, gauss-2 stiff-skate at 100" in b
    assert "rho > 1 from h omega = 2.1 (s = 2, Stormer-Verlet: bound 2) and 3 (s = 3)" in b
    assert "Newton iterations per step: 1.5 .. 2.0 at h omega <= 0.1, 3.0 .. 4.0 at h omega = 1" in b
    # no bounded Gauss run at h omega >= 3: the O(1) clause is left out
    d["stiff"] = [r for r in d["stiff"] if not (r["method"] == "gauss-2" and r["hw"] in (3.0, 10.0))]
    assert "at O(1)" not in rg.findings_lines(d)[1]


def test_records_and_regimes_over_every_kind_of_measurement():
    d = {"tiny": [{"scene": "skate", "method": "gauss-2", "h": 1e-4, "N": 10 ** 4, "outcome": "ok", "max_dE": 1e-14},
                  {"scene": "robot", "method": "gauss-2", "h": 1e-7, "N": 10 ** 4, "outcome": "ok", "max_dE": 1e-12},
                  {"scene": "skate", "method": "euler-i", "h": 1e-5, "N": 10 ** 4, "outcome": "NewtonError"}],
         "stiff": [_stiff_row("stiff-skate", "gauss-2", 0.1, "bounded")],
         "floor": [{"method": "gauss-3", "h": [1e-2, 1e-6], "N": [10, 10 ** 5], "kahan": [1e-9, 1e-14]}],
         "long": [{"method": "lobatto-iiia-iiib-2"}],
         "step": [{"method": "gauss-1", "h": [1e-6, 0.5], "newton": [(64.0, 128.0), (None, 0.25), (4096.0, None)]}],
         "order": [({"method": "gauss-4"}, {"method": "gauss-4"})],
         "reversal": [({"method": "euler-ii"}, {"method": "euler-ii", "N": 20}),
                      ({"method": "gauss-2"}, {"method": "gauss-2", "N": 20})],
         "dps": [{"dps": 400, "N": 3}]}
    recs = rg._records(d)
    fams = {(r[0], r[1]) for r in recs}
    assert fams == {("compiled float64", "gauss"), ("compiled float64", "euler-i/ii"),
                    ("compiled float64", "lobatto-iiia-iiib"), ("generic float64", "gauss"),
                    ("generic mpmath", "gauss"), ("generic float64", "euler-i/ii"), ("generic mpmath", "euler-i/ii")}
    rows = {(r["engine"], r["family"]): r for r in rg.regimes(d)}
    c = rows[("compiled float64", "gauss")]
    assert c["h"] == "1e-07 .. 0.01" and c["hw"] == "0.1" and c["s"] == "2 .. 3" and c["dps"] == "float64"
    assert c["N"] == "10 .. 1e+05"
    assert c["worst"] == "max abs dE 1.0e-12 (gauss-2, robot, h = 1e-07, N = 1e+04)"   # the larger error
    e = rows[("compiled float64", "euler-i/ii")]
    assert e["worst"] == "NewtonError at h = 1e-05 (euler-i, skate)" and e["hw"] == "-"
    assert rows[("compiled float64", "lobatto-iiia-iiib")]["N"] == "1e+06"
    assert rows[("compiled float64", "lobatto-iiia-iiib")]["h"] == "0.05"
    gf = rows[("generic float64", "gauss")]
    # the Newton failure at the smallest h is the worst; h spans the sweep, the Newton limits and the order runs
    assert gf["worst"] == "NewtonError from h = 0.25 (gauss-1, Newton limit, section 1)"
    assert gf["h"] == "1e-06 .. 4096" and gf["s"] == "1 .. 4" and gf["N"] == "1 .. 200"
    gm = rows[("generic mpmath", "gauss")]
    assert gm["dps"] == "30 .. 400" and gm["worst"] == "no failure" and gm["N"] == "1 .. 40"
    em = rows[("generic mpmath", "euler-i/ii")]
    assert em["N"] == "40" and em["dps"] == "30" and em["h"] == "0.05"
    assert rows[("generic float64", "euler-i/ii")]["N"] == "200"
    # only the Newton limits of section 1 (no h sweep): one-step runs, N = 1, the converged h and the failing h
    only = {"step": [{"method": "gauss-2", "h": [], "newton": [(64.0, 128.0), (2.0, None)]}]}
    (row,) = rg.regimes(only)
    assert row["N"] == "1" and row["h"] == "2 .. 128" and row["worst"].startswith("NewtonError from h = 128")
    L = "\n".join(rg.section_regimes(d))
    assert "| generic mpmath | gauss | 0.05 .. 0.5 |" not in L and "| generic mpmath | gauss |" in L
    assert L.count("\n| ") == 2 + len(rows) - 1


# ================================================================================================
# stability (the report)
# ================================================================================================
def _step(method, floor_err64=1e-16, fail=None):
    h = [1e-6, 1e-3, 1e-2, 1e-1]
    return {"method": method, "order": 4, "h": h,
            "err": {"float64": [floor_err64, 1e-14, 1e-11, 1e-6], "30": [1e-29, 1e-16, 1e-11, 1e-6],
                    "50": [1e-36, 1e-16, 1e-11, 1e-6]},
            "floor_h": 1e-4 if method == "gauss-2" else 1e-3, "slope50": 5.0,
            "newton": [(4096.0, None), (64.0, fail), (None, 0.25)]}


def _results(mass_bad=True, soft_silent=True):
    """Synthetic job results for every job of the default report (keys of ``jobs``)."""
    R = {}
    for key, fn, args, cost in st.jobs(False):
        kind = key[0]
        if kind == "step":
            R[key] = _step(args[0], floor_err64=3e-15 if args[0] == "gauss-2" else 1e-16,
                           fail=128.0 if args[0] == "gauss-3" else None)
        elif kind == "stage":
            R[key] = [{"method": "gauss-1", "s": 1, "float64": {"B": 0.0, "C": 1e-17, "D": 2e-17, "22b": 0.0},
                       "mp50": {"B": 0.0, "C": 1e-51, "D": 0.0, "22b": 0.0}},
                      {"method": "gauss-2", "s": 2, "float64": {"B": 3e-17, "C": 5e-17, "D": 2e-17, "22b": 4e-17},
                       "mp50": {"B": 2e-51, "C": 1e-52, "D": 0.0, "22b": 0.0}}]
        elif kind == "order":
            m = args[0]
            R[key] = ({"method": m, "claimed": 4, "err": [1e-6, 6.25e-8], "order": [4.0]},
                      {"method": m, "claimed": 4, "err": [1e-6, 6.3e-8], "order": [3.99]})
        elif kind == "long":
            m = args[0]
            R[key] = {"method": m, "path": "spark", "windows": [10 ** 3, 10 ** 4, 10 ** 5, 10 ** 6],
                      "max_k": {"kahan": {"gauss-2": 1e-16, "lobatto-iiia-iiib-2": 4e-16}.get(m, 2e-16),
                                "plain": 1e-15},
                      "dE_window": {"kahan": [1e-10] * 4, "plain": [2e-10] * 4},
                      "plain_minus_kahan": [1e-16, 1e-15, 1e-14, 3e-14], "gap_exponent": 0.51,
                      "drift_halves": {"kahan": 1e-15, "plain": 1e-14}, "seconds_kahan": 1.0, "seconds_plain": 0.5,
                      "series": {"steps": [0, 1000], "dE_kahan": [0.0, 1e-10], "dE_plain": [0.0, 2e-10],
                                 "k_kahan": [0.0, 1e-16]}}
        elif kind == "roundoff":
            R[key] = {"N": [1e3, 1e4, 1e5, 1e6], "rms": {"plain": [1e-16, 1e-15, 1e-14, 1e-13],
                                                        "compensated": [1e-17, 1e-16, 1e-15, 1e-14]},
                      "exponent": {"plain": 0.98, "compensated": 0.97}, "extra": "dropped from the json"}
        elif kind == "mass":
            R[key] = [{"mu": 1e8, "rcond": 1e-9, "outcome": "ok", "rel_err": 1e-15, "iterations": 2.0},
                      {"mu": 1e16, "rcond": 1e-17, "outcome": "ok", "rel_err": 2e-15, "iterations": 2.0},
                      {"mu": 1e20, "rcond": 1e-21, "outcome": "SingularSaddleError" if mass_bad else "ok",
                       "message": "rcond too small"},
                      {"mu": 1e24, "rcond": 1e-25, "outcome": "SingularSaddleError" if mass_bad else "ok",
                       "message": "rcond too small"}]
        elif kind == "rank":
            R[key] = [{"eps": 1e-2, "rcond": 1e-4, "outcome": "ok", "err": 1e-13, "max_psi": 1e2, "iterations": 2},
                      {"eps": 1e-4, "rcond": 1e-8, "outcome": "ok", "err": 1e-9, "max_psi": 1e4, "iterations": 3},
                      {"eps": 1e-8, "rcond": 1e-16, "outcome": "SingularSaddleError", "message": "singular"}]
        elif kind == "soft":
            R[key] = [{"delta": 1e-1, "rcond": 0.1, "outcome": "ok", "min_v1": 0.9, "max_v1": 0.95,
                       "crossing_step": None, "dE": 1e-9},
                      {"delta": 1e-3, "rcond": 1e-3, "outcome": "ok", "min_v1": 0.99, "max_v1": 1.01,
                       "crossing_step": 7 if soft_silent else None, "dE": 1e-8},
                      {"delta": 1e-5, "rcond": 1e-5, "outcome": "SingularSaddleError", "message": "crossed",
                       "crossing_step": 3}]
        elif kind == "reversal":
            m, scene, full = args
            sym = m in st.SYMMETRIC
            base = {"gauss-1": 1e-15, "gauss-3": 4e-15, "euler-i": 0.3, "euler-ii": 0.02}.get(m, 2e-15)
            R[key] = ({"method": m, "scene": scene, "return_error": base * (2 if scene == "robot" else 1),
                       "excursion": 1.5, "N": 100},
                      {"method": m, "scene": scene, "return_error": (1e-29 if sym else 0.01) * (3 if m == "gauss-2"
                                                                                            else 1), "N": 20})
        elif kind == "stiff":
            scene, m = args
            R[key] = [r for r in _stiff_rows() if r["scene"] == scene and r["method"] == m]
        elif kind == "tiny":
            R[key] = [r for r in _tiny_rows() if r["scene"] == args[0]]
        elif kind == "floor":
            R[key] = dict(_floor_rows()[0], method=args[0])
        elif kind == "dps":
            R[key] = _dps_rows()
    return R


def test_findings_numbers_pick_the_right_extremes():
    d = st.collect(_results())
    # the job order, whatever order the results come in
    d2 = st.collect(dict(reversed(list(_results().items()))))
    assert [r["method"] for r in d2["step"]] == list(st.DEFAULT_SWEEP) and d2["reversal"] == d["reversal"]
    f = st.findings_numbers(d)
    assert f["floor_method"] == "gauss-2" and f["floor_h"] == 1e-4 and f["floor_float64"] == 3e-15
    assert f["floor_30"] == 1e-29 and f["floor_50"] == 1e-36
    assert f["stage_max_float64"] == 5e-17 and f["stage_max_mp50"] == 2e-51
    assert f["long_max_k"] == 4e-16
    assert f["long_gap_exponents"] == {m: 0.51 for m in st.LONG_METHODS}
    assert f["roundoff_exponent"] == {"plain": 0.98, "compensated": 0.97}
    assert f["mu_ok"] == 1e16 and f["mu_bad"] == 1e20
    assert f["eps_ok"] == 1e-4 and f["eps_err"] == 1e-9
    assert f["soft_silent"] == [1e-3]
    assert f["reversal_symmetric_float64"] == 8e-15          # gauss-3 on the robot
    assert f["reversal_symmetric_30"] == pytest.approx(3e-29, rel=1e-12, abs=0)     # gauss-2
    assert f["reversal_nonsymmetric_min"] == 0.02
    # no gauss-2 in the sweep: the first row; no ok rank run: None
    d["step"] = [r for r in d["step"] if r["method"] != "gauss-2"]
    d["rank"] = [r for r in d["rank"] if r["outcome"] != "ok"]
    f = st.findings_numbers(d)
    assert f["floor_method"] == d["step"][0]["method"] and f["eps_ok"] is None and f["eps_err"] is None


def test_findings_text_both_branches():
    L = "\n".join(st.section_findings(st.collect(_results())))
    assert "up to mu = 1.0e+16; from mu = 1.0e+20 on, `check_saddle` rejects" in L
    assert "the user is NOT warned: for delta in 1e-03 the run" in L
    assert "Newton limit (first failing h, doubling from 0.25 to 4096): euler-i -/-/0.25;" in L
    assert "gauss-3 -/128/0.25" in L
    assert "N^0.51/0.51/0.51 (gauss-2/lobatto-iiia-iiib-2/gauss-1" in L
    assert "works down to eps = 1.0e-04 with error 1.0e-09" in L
    assert "methods miss by >= 2.0e-02." in L
    L = "\n".join(st.section_findings(st.collect(_results(mass_bad=False, soft_silent=False))))
    assert "up to mu = 1.0e+24 (the largest tried)" in L and "rejects the problem" not in L
    assert "NOT warned" not in L and "outcomes per delta: 1e-01: ok, 1e-03: ok, 1e-05: SingularSaddleError." in L


def test_sections_render_the_data():
    d = st.collect(_results())
    s1 = "\n".join(st.section_step_size(d))
    assert "| gauss-2 | 4 | 1.0e-04 | 3.0e-15 | 1.0e-29 | 1.0e-36 | 5.00 | 4096 / 64 / none (fails at 0.25) |" in s1
    assert "First failures: euler-i on robot at h = 0.25," in s1 and "gauss-3 on particle at h = 128" in s1
    assert "| 1.0e-06 | 1.0e-16 / 1.0e-29 / 1.0e-36 |" in s1
    s2 = "\n".join(st.section_stages(d))
    assert "| gauss-2 | 2 | 3.0e-17 | 5.0e-17 | 2.0e-17 | 4.0e-17 | 2.0e-51 | 1.0e-52 | 0.0e+00 | 0.0e+00 |" in s2
    assert "| gauss-4 | 4 | 1.00e-06, 6.25e-08 | 4.00 | 1.00e-06, 6.30e-08 | 3.99 |" in s2
    s3 = "\n".join(st.section_long_runs(d))
    assert "max dE n<=1e6" in s3 and "| gauss-2 | 1.0e-16 | 1.0e-15 | 1.00e-10 |" in s3 and "| 0.51 |" in s3
    assert "| plain | 1.0e-15 | 1.0e-14 | 1.0e-13 | 0.98 | 2.2e-13 |" in s3
    s4 = "\n".join(st.section_ill_conditioned(d))
    assert "| 1e+20 | 1.0e-21 | SingularSaddleError: `rcond too small` | - | - |" in s4
    assert "| 1e-04 | 1.0e-08 | ok | 1.0e-09 | 1.0e+04 | 3 |" in s4
    assert "| 1e-03 | 1.0e-03 | ok | 0.99 | 1.01 | 7 | 1.0e-08 |" in s4
    s5 = "\n".join(st.section_time_reversal(d))
    assert "| euler-i | no | particle | 0.05 | 100 (30 digits: 20) | 3.0e-01 | 1.0e-02 | 1.50 |" in s5
    assert "| gauss-1 | yes | robot |" in s5
    s6 = "\n".join(st.section_bad_input(d))
    assert s6.count("\n| ") == 1 + len(st.BAD_INPUT) and "SingularSaddleError" in s6
    assert "tests/lab/reports/test_extremes.py" in "\n".join(st.section_header(d)) and "--full" not in st.section_header(d)[2]
    assert "report stability --full" in st.section_header(dict(d, full=True))[2]
    assert st._e(None) == "-" and st._e(2.5) == "2.5e+00" and st._e(3) == "3"


def test_jobs_cover_the_report_and_run_here(monkeypatch, tmp_path):
    J = st.jobs(False)
    keys = [j[0] for j in J]
    assert len(keys) == len(set(keys))
    assert [k[1] for k in keys if k[0] == "step"] == list(st.DEFAULT_SWEEP)
    assert len([k for k in keys if k[0] == "reversal"]) == 2 * (len(st.SYMMETRIC) + len(st.NONSYMMETRIC))
    assert len([k for k in keys if k[0] == "stiff"]) == len(st.STIFF_SCENES) * len(st.STIFF_METHODS)
    costs = {j[0]: j[3] for j in J}
    assert costs[("long", "gauss-2")] > costs[("long", "lobatto-iiia-iiib-2")]
    JF = st.jobs(True)
    assert [k[1] for k, *_ in JF if k[0] == "step"] == list(st.SWEEP_METHODS)
    assert all(a[-1] is True for k, fn, a, c in JF if k[0] in ("reversal", "tiny"))
    assert st.order_methods(False) == st.order_methods(True)[:5] and "gauss-10" in st.order_methods(True)
    R = _results()
    by_call = {(fn, args): key for key, fn, args, cost in J}
    for fn in {j[1] for j in J}:
        monkeypatch.setattr(st, fn, (lambda f: (lambda *a: R[by_call[(f, a)]]))(fn))
    figs = []
    for name in ("_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"):
        monkeypatch.setattr(st, name, (lambda n: (lambda *a: figs.append((n, a[-1]))))(name))
    d = st.build_report(False, str(tmp_path))
    assert [n for n, _ in figs] == ["_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"]
    assert all(p.startswith(str(tmp_path / "figures")) for _, p in figs)
    md = (tmp_path / "stability.md").read_text()
    assert md.startswith("# Numerical stability") and "## Findings" in md and "## 8. Tiny steps" in md
    assert "Generated by `ldaspark report stability`" in md
    import json
    js = json.loads((tmp_path / "stability.json").read_text())
    assert "series" not in js["long"][0] and js["long"][0]["gap_exponent"] == 0.51
    assert set(js["roundoff"]) == {"N", "rms", "exponent"}
    assert js["findings"]["mu_bad"] == 1e20 and js["regimes"] and len(js["stiff_summary"]) == 6
    assert d["full"] is False and len(d["stiff"]) == len(_stiff_rows())
    # the CLI entry points
    import argparse
    p = argparse.ArgumentParser()
    st.add_arguments(p)
    args = p.parse_args(["--outdir", str(tmp_path / "o")])
    assert args.full is False and st.run(args) == 0 and (tmp_path / "o" / "stability.md").exists()
    st.run_default(str(tmp_path / "p"))
    assert (tmp_path / "p" / "stability.json").exists()


def test_job_functions_pass_the_right_arguments(monkeypatch):
    calls = []
    rec = lambda name, ret=None: (lambda *a, **k: calls.append((name, a, k)) or ret)  # noqa: E731
    monkeypatch.setattr(st, "order_at_precision", lambda m, dps: (m, dps))
    assert st.order_pair("gauss-2") == (("gauss-2", 50), ("gauss-2", None))
    monkeypatch.setattr(st, "time_reversal", rec("rev", 1))
    st.reversal_pair("gauss-1", "robot")
    st.reversal_pair("gauss-1", "robot", True)
    assert [c[1:] for c in calls] == [(("gauss-1", "robot", 0.05, 100), {}), (("gauss-1", "robot", 0.05, 20), {"dps": 30}),
                                      (("gauss-1", "robot", 0.05, 100), {}), (("gauss-1", "robot", 0.05, 100), {"dps": 30})]
    calls.clear()
    for name in ("long_run", "roundoff_growth", "tiny_step_grid", "error_floor"):
        monkeypatch.setattr(st, name, rec(name, 1))
    st.long_job("gauss-2"); st.roundoff_job(); st.tiny_job("skate"); st.tiny_job("robot", True); st.floor_job("gauss-1")
    assert calls == [("long_run", ("gauss-2", "particle", 0.05, st.N_LONG, 1000), {}),
                     ("roundoff_growth", (), {"n_steps": st.N_LONG, "every": 1000, "n_ics": 8}),
                     ("tiny_step_grid", (st.N_TINY,), {"scenes": ("skate",)}),
                     ("tiny_step_grid", (st.N_TINY_FULL,), {"scenes": ("robot",)}),
                     ("error_floor", ("gauss-1",), {})]
    # step_row: the floor from float64 against 50 digits, the slope of the 50-digit errors on [1e-3, 1e-1]
    row = _step("gauss-2")
    row["err"]["float64"] = [1e-15, 1e-14, 2 * 10 ** -13.5, 1e-11]
    row["err"]["50"] = [1e-36, 1e-16, 10 ** -13.5, 1e-11]     # slope 2.5 on [1e-3, 1e-1]; float64 > 4x up to 1e-3
    row["err"]["30"] = [1e-29, 1e-14, 10 ** -13.5, 1e-11]     # would give the floor 1e-6 and another slope
    monkeypatch.setattr(st, "step_size_sweep", lambda ms: [dict(row, method=ms[0])])
    monkeypatch.setattr(st, "newton_limit", lambda m, scene: (8.0, {"robot": 16.0}.get(scene), "msg"))
    r = st.step_row("gauss-2")
    assert r["floor_h"] == 1e-3 and r["slope50"] == pytest.approx(2.5, abs=1e-9)
    assert r["newton"] == [(8.0, None), (8.0, None), (8.0, 16.0)]


def test_run_jobs_here_calls_every_job_once(monkeypatch):
    seen = []
    for key, fn, args, cost in st.jobs(False):
        monkeypatch.setattr(st, fn, (lambda f: (lambda *a: seen.append((f, a)) or (f, a)))(fn))
    out = st.run_jobs_here(False)
    assert list(out) == [j[0] for j in st.jobs(False)]
    assert out[("step", "gauss-1")] == ("step_row", ("gauss-1",)) and len(seen) == len(out)


# ================================================================================================
# bicycle_flow and bicycle_benchmark
# ================================================================================================
def test_weave_and_capsize_picks():
    from ldaspark.lab.theory import bicycle_flow as bf
    eigs = [complex(-14, 0), complex(-0.8, 4.5), complex(-0.8, -4.5), complex(-0.3, 0)]
    assert bf.weave_real_part(eigs) == -0.8
    assert bf.capsize_eigenvalue(eigs) == -0.3                 # the largest real one, not the most negative
    assert math.isnan(bf.weave_real_part([1.0 + 0j, -2.0 + 0j]))
    # a pair with an imaginary part 5e-10 counts as real (tolerance 1e-9), 2e-9 as complex
    assert math.isnan(bf.weave_real_part([complex(3, 5e-10)]))
    assert bf.weave_real_part([complex(3, 2e-9), complex(-1, 1)]) == 3
    assert bf.capsize_eigenvalue([complex(3, 5e-10), complex(7, 2e-9)]) == 3
    # exactly 1e-9 is still "real" for both rules
    assert bf.capsize_eigenvalue([complex(3, 1e-9), complex(-1, 0)]) == 3
    assert math.isnan(bf.weave_real_part([complex(3, 1e-9), complex(-1, 0)]))
    assert bf.match_error([1, 2j, -1, 5], [5, -1, 2j, 1.5]) == pytest.approx(0.5)


def test_critical_speeds_secant_on_synthetic_modes(monkeypatch):
    from ldaspark.lab.theory import bicycle_flow as bf
    vw, vc = 4.29238253634111, 6.02426201538837
    calls = []

    def fake(v, method, h, model=None):
        calls.append((method, h, model))
        w = 0.7 * (vw - v) + 0.05 * (vw - v) ** 2             # weave real part: positive below vw
        c = 0.4 * (v - vc)                                      # capsize: positive above vc
        return [complex(-14, 0), complex(w, 4.0), complex(w, -4.0), complex(c, 0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    model = object()
    a, b = bf.critical_speeds("gauss-2", 0.02, model=model, xtol=1e-12)
    assert a == pytest.approx(vw, abs=1e-10) and b == pytest.approx(vc, abs=1e-10)
    assert set(calls) == {("gauss-2", 0.02, model)}
    # the stopping test: a loose xtol stops after fewer evaluations than a tight one
    n_tight = len(calls)
    calls.clear()
    # the default tolerance 1e-9 stops the secant on a smooth root well before its 30 steps
    spy = []
    monkeypatch.setattr(bf, "spark_eigenvalues", lambda v, *a, **k: spy.append(v) or fake(v, *a, **k))
    a, b = bf.critical_speeds("gauss-2", 0.02, model=model)
    assert a == pytest.approx(vw, abs=1e-8) and b == pytest.approx(vc, abs=1e-8) and len(spy) < 2 * 32
    for seq in ([v for v in spy if v < 5], [v for v in spy if v > 5]):
        # it stops at the first secant step <= 1e-9: the step before was larger
        assert abs(seq[-1] - seq[-2]) <= 1e-9 < abs(seq[-2] - seq[-3])
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    calls.clear()
    bf.critical_speeds("gauss-2", 0.02, model=model, xtol=1e-2)
    assert len(calls) < n_tight


def test_benchmark_unknown_parameter_and_max_real_part():
    from ldaspark.models import bicycle_benchmark as bb
    with pytest.raises(KeyError, match="unknown benchmark parameter 'cc'"):
        bb.matrices(15, cc="1")
    # at 5 m/s (between the weave and capsize speeds) all real parts are negative; the largest is
    # the capsize eigenvalue -0.3229 of Table 2, not the most negative -14.08
    m5 = bb.max_real_part(5, 20)
    assert float(m5) == pytest.approx(float(bb.PUBLISHED["eig_v5"][3]), abs=1e-10)
    # at rest the bicycle falls over: the largest real eigenvalue is +5.53
    assert float(bb.max_real_part(0, 20)) == pytest.approx(float(bb.PUBLISHED["eig_v0"][3]), abs=1e-10)


def test_critical_speeds_stops_after_thirty_secant_steps(monkeypatch):
    """A triple root: the secant iteration converges only linearly; with xtol < 0 it never stops
    early and takes its 30 steps (2 starting values + 30 evaluations per speed)."""
    from ldaspark.lab.theory import bicycle_flow as bf
    calls = []

    def fake(v, method, h, model=None):
        calls.append(v)
        w, c = (4.3 - v) ** 3, (v - 6.02) ** 3
        return [complex(w, 1.0), complex(w, -1.0), complex(c, 0.0), complex(-9.0, 0.0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    a, b = bf.critical_speeds(model=object(), xtol=-1.0)
    assert len(calls) == 2 * 32
    assert abs(a - 4.3) < 1e-2 and abs(b - 6.02) < 1e-2


def test_write_without_a_clock_has_no_timing_line(monkeypatch, tmp_path):
    for name in ("_fig_step_sweep", "_fig_stage", "_fig_long", "_fig_stiff", "_fig_floor"):
        monkeypatch.setattr(st, name, lambda *a: None)
    from ldaspark.lab.reports.timing import Clock
    st.write(_results(), str(tmp_path / "a"))
    st.write(_results(), str(tmp_path / "b"), clock=Clock(), command="ldaspark report stability --x")
    a, b = (tmp_path / "a" / "stability.md").read_text(), (tmp_path / "b" / "stability.md").read_text()
    assert "ldaspark report stability --x" not in a and "ldaspark report stability --x" in b
    assert b.startswith(a.rstrip("\n"))


def test_job_costs_are_positive_and_sizes_match_the_report_text():
    """Every job has a positive cost estimate (the scheduler starts the longest first; a zero
    would put a 2 s job behind every other one), and the long runs are the 1e6 steps the report's
    section 3 heading and the findings quote."""
    for full in (False, True):
        assert all(c > 0 for *_, c in st.jobs(full))
    assert st.N_LONG == 10 ** 6 and st.N_TINY == 10 ** 4 and st.N_TINY_FULL == 10 ** 5
    d = st.collect(_results())
    assert "N = 1e+06 steps" in "\n".join(st.section_long_runs(d))


def test_step_size_sweep_default_grid_and_precisions(monkeypatch):
    seen = []
    monkeypatch.setattr(sc_, "one_step_error", lambda name, h, p: seen.append((name, h, p)) or (float(h) * 2, 3))
    (row,) = sc_.step_size_sweep(("gauss-2",))
    # h = 10^k for k = -6, -5.5, ..., 0 as decimal strings
    assert len(row["h"]) == 13
    for k, h in zip(np.arange(-6, 0.01, 0.5), row["h"]):
        assert h == pytest.approx(10.0 ** k, rel=1e-2)
    assert row["h"][0] == 1e-6 and row["h"][-1] == 1.0 and row["order"] == 4
    assert list(row["err"]) == ["float64", "30", "50"] and row["err"]["50"] == [2 * h for h in row["h"]]
    assert {p for _, _, p in seen} == {None, 30, 50} and all(isinstance(h, str) for _, h, _ in seen)


def test_stage_sweep_rows_are_the_residuals_of_float64_and_50_digit_coefficients():
    from ldaspark.core.families import get_method
    rows = {r["method"]: r for r in sc_.stage_sweep(max_s=2)}
    tab = get_method("gauss-2")
    for prec, key in ((None, "float64"), (50, "mp50")):
        a = tab.arrays(prec)
        assert rows["gauss-2"][key] == sc_._residuals({k: getattr(a, k) for k in ("c", "b", "A", "A_hat")}, 2, "gauss")
    # 51 digits would be another (smaller) rounding: the 50-digit row is not that one
    a = tab.arrays(51)
    assert rows["gauss-2"]["mp50"] != sc_._residuals({k: getattr(a, k) for k in ("c", "b", "A", "A_hat")}, 2, "gauss")


class _FakeScene:
    """initial data 0; the exact solution at t: q = (t, 0), v = (1, 0)."""
    def initial(self, dps=None):
        return 0.0, [0.0, 0.0], [1.0, 0.0]

    def exact_solution(self, t, dps=None):
        import mpmath
        t = mpmath.mpf(t) if dps else float(t)
        return [t, 0 * t], [1 + 0 * t, 0 * t], None

    system = None


def test_order_at_precision_error_is_the_max_over_q_and_v(monkeypatch):
    import mpmath
    monkeypatch.setattr(sc_, "get_scene", lambda name: _FakeScene())
    calls = []

    def integrate(system, tab, t0, q0, v0, h, n_steps, dps=None, newton=None):
        calls.append((h, n_steps, dps, newton))
        eq, ev = 1e-4 / n_steps ** 2, 4e-3 / n_steps ** 3        # v error larger: order 3 from max, 2 from min
        if dps is None:
            q = np.array([[0.0, 0.0], [1.0 + eq, 0.0]]); v = np.array([[1.0, 0.0], [1.0, -ev]])
        else:
            with mpmath.workdps(dps):
                q = [[0, 0], [mpmath.mpf(1) + mpmath.mpf(eq), mpmath.mpf(0)]]
                v = [[1, 0], [mpmath.mpf(1), -mpmath.mpf(ev)]]
        return types.SimpleNamespace(q=q, v=v)
    monkeypatch.setattr(sc_, "integrate", integrate)
    for dps in (None, 50):
        calls.clear()
        r = sc_.order_at_precision("gauss-2", dps, Ns=(4, 8))
        assert r["N"] == [4, 8] and r["claimed"] == 4 and r["method"] == "gauss-2"
        assert r["err"][0] == pytest.approx(4e-3 / 64, rel=1e-9) and r["err"][1] == pytest.approx(4e-3 / 512, rel=1e-9)
        assert r["order"] == [pytest.approx(3.0, abs=1e-6)]
        assert [float(c[0]) for c in calls] == [0.25, 0.125] and [c[1] for c in calls] == [4, 8]
        assert all(c[2] == dps for c in calls) and all(c[3] == ("mixed" if dps else None) for c in calls)

    # an error of exactly 0 at the float64 floor: no order (nan), not a division error
    def exact(system, tab, t0, q0, v0, h, n_steps, dps=None, newton=None):
        return types.SimpleNamespace(q=np.array([[0.0, 0.0], [1.0, 0.0]]), v=np.array([[1.0, 0.0], [1.0, 0.0]]))
    monkeypatch.setattr(sc_, "integrate", exact)
    r = sc_.order_at_precision("gauss-2", None, Ns=(4, 8, 16))
    assert r["err"] == [0.0, 0.0, 0.0] and len(r["order"]) == 2 and all(math.isnan(o) for o in r["order"])


@pytest.mark.parametrize("name", ["stiff-skate", "stiff-particle"])
def test_stiff_scenes_are_the_documented_oscillators(name):
    """Section 7's text: stiff-skate U = omega^2 |q|^2 / 2, q0 = (1, 0, 1/2), v0 = (0, 0, omega/2);
    stiff-particle U = omega^2 (q1^2 + q2^2) / 2, q0 = (1, 0, 0), v0 = (0, omega, 0); T = |v|^2 / 2;
    initial data consistent with k."""
    import sympy
    w = 7
    system, t0, q0, v0 = ss.stiff_scene(name, w)
    q, v = system.q, system.v
    U = -system.L.subs({x: 0 for x in v})
    T = system.L.subs({x: 0 for x in q})
    assert sympy.expand(T - sum(x ** 2 for x in v) / 2) == 0
    pot = q[:3] if name == "stiff-skate" else q[:2]
    assert sympy.expand(U - w ** 2 * sum(x ** 2 for x in pot) / 2) == 0
    # the constraints of 8.2 (blade direction q3) and 8.1
    want_k = (sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0] if name == "stiff-skate" else v[2] - q[1] * v[0])
    assert len(system.k) == 1 and sympy.simplify(system.k[0] - want_k) == 0
    if name == "stiff-skate":
        assert (q0, v0) == ([1.0, 0.0, 0.5], [0.0, 0.0, w / 2])
    else:
        assert (q0, v0) == ([1.0, 0.0, 0.0], [0.0, float(w), 0.0])
    subs = dict(zip(q + v, q0 + v0))
    assert all(abs(float(kk.subs(subs))) < 1e-15 for kk in system.k) and t0 == 0.0
    with pytest.raises(ValueError):
        ss.stiff_scene("stiff-robot", w)


@pytest.mark.parametrize("z", [0.5, 1.9, 3.0])
def test_linear_stability_against_closed_forms(z):
    """Stormer-Verlet (lobatto-iiia-iiib-2) on the oscillator: trace M = 2 - z^2, det M = 1, so
    rho = 1 for z < 2 and rho = |1 - z^2/2| + sqrt((1 - z^2/2)^2 - 1) beyond; implicit midpoint
    (gauss-1): R(i z) = (1 + i z/2) / (1 - i z/2), modulus 1, rho = 1."""
    rho, R = ss.linear_stability("lobatto-iiia-iiib-2", z)
    a = 1 - z * z / 2
    want = 1.0 if abs(a) <= 1 else abs(a) + math.sqrt(a * a - 1)
    assert R is None and rho == pytest.approx(want, rel=1e-7)
    rho, R = ss.linear_stability("gauss-1", z)
    assert rho == pytest.approx(1.0, abs=1e-12) and R == pytest.approx(1.0, abs=1e-12)


def test_spark_eigenvalues_passes_the_lateral_restriction(monkeypatch):
    import sympy
    from ldaspark.models import bicycle as bc
    from ldaspark.lab.theory import bicycle_flow as bf
    seen = {}

    def fj(system, method, q0, v0, h, dps=None, coords=None, rates=None, dependent=None):
        seen.update(system=system, method=method, q0=q0, v0=v0, h=h, dps=dps, coords=coords, rates=rates,
                    dependent=dependent)
        return types.SimpleNamespace(eigenvalues=lambda: [np.complex128(1 + 2j), -3.0])
    monkeypatch.setattr(bf, "flow_jacobian", fj)
    model = types.SimpleNamespace(system="S", upright=lambda v: ([sympy.Rational(1, 3), sympy.Integer(0)],
                                                                 [sympy.Integer(v), -sympy.Rational(v, 3)]))
    ev = bf.spark_eigenvalues(5, model=model)
    assert ev == [1 + 2j, -3 + 0j] and all(type(z) is complex for z in ev)
    assert seen["h"] == 0.01 and seen["method"] == "gauss-2" and seen["dps"] is None and seen["system"] == "S"
    assert seen["q0"] == [1 / 3, 0.0] and seen["v0"] == [5.0, -5 / 3]
    assert seen["coords"] == bf.LATERAL == seen["rates"] and seen["dependent"] == list(bc.DEPENDENT_V)
    bf.spark_eigenvalues(5, "gauss-3", 0.02, dps=30, model=model)
    assert seen["q0"][0].startswith("0.33333333333333333333333333333333333333") and seen["dps"] == 30
    assert seen["h"] == 0.02 and seen["method"] == "gauss-3"


def test_secant_brackets_and_inclusive_tolerance(monkeypatch):
    """The documented brackets 4 - 4.5 and 6 - 6.1; a linear weave function is solved by the first
    secant step (c = 4.25 exactly), whose length 0.25 then meets xtol = 0.25 (<=): 3 evaluations."""
    from ldaspark.lab.theory import bicycle_flow as bf
    calls = []

    def fake(v, method, h, model=None):
        calls.append(v)
        w, c = 4.25 - v, v - 6.0625
        return [complex(w, 1.0), complex(w, -1.0), complex(c, 0.0)]
    monkeypatch.setattr(bf, "spark_eigenvalues", fake)
    a, b = bf.critical_speeds(model=object(), xtol=0.25)
    weave = [v for v in calls if v < 5]
    assert weave == [4.0, 4.5, 4.25] and a == 4.25
    assert [v for v in calls if v > 5][:2] == [6.0, 6.1]


def test_nonlinear_run_defaults_and_outputs(monkeypatch):
    import sympy
    import ldaspark.solve
    from ldaspark.models import bicycle as bc
    from ldaspark.lab.theory import bicycle_flow as bf
    seen = {}
    n = len(bc.COORDS)
    qs = sympy.symbols(f"x0:{n}")

    def integrate(sc, method, t_span, h, engine, raise_on_failure):
        seen.update(sc=sc, method=method, t_span=t_span, h=h, engine=engine, raise_on_failure=raise_on_failure)
        q = np.zeros((2, n)); q[1, bc.LEAN] = 0.1; q[1, bc.STEER] = -0.2; q[1, 0] = 3.0
        return types.SimpleNamespace(t=[0.0, 0.01], q=q, energy=[1.0, 1.0], constraint=np.array([[1e-16, -2e-16], [0.0, 3e-16]]))
    monkeypatch.setattr(ldaspark.solve, "integrate", integrate)
    model = types.SimpleNamespace(q=list(qs), f=qs[0] ** 2, scene=lambda speed, lean_rate: ("scene", speed, lean_rate))
    out = bf.nonlinear_run(model=model)
    assert seen == {"sc": ("scene", 5, 0.5), "method": "gauss-2", "t_span": (0, 5.0), "h": 0.01, "engine": "auto",
                    "raise_on_failure": True}
    assert list(out["lean"]) == [0.0, 0.1] and list(out["steer"]) == [0.0, -0.2]
    assert list(out["k"]) == [2e-16, 3e-16] and list(out["f"]) == [0.0, 9.0] and list(out["t"]) == [0.0, 0.01]


def test_benchmark_total_mass_is_the_sum_of_the_four_bodies():
    """mT enters M, K0, K2, C1 only through mT xT and mT zT (the centre of mass times the mass), so
    a wrong sign in the sum shows only where it makes mT vanish: with mF = mR + mB + mH = 91 kg the
    sum is 182 kg and the matrices are finite, and equal to those with the mass moment written out."""
    import mpmath
    from ldaspark.models import bicycle_benchmark as bb
    with mpmath.workdps(25):
        M, C1, K0, K2, g = bb.matrices(15, mF="91")
        # K0[0, 0] = mT zT = -rR mR + zB mB + zH mH - rF mF (Table 1 values, mF = 91)
        want = -mpmath.mpf("0.3") * 2 + mpmath.mpf("-0.9") * 85 + mpmath.mpf("-0.7") * 4 - mpmath.mpf("0.35") * 91
        assert abs(K0[0, 0] - want) < mpmath.mpf(10) ** -20
        assert all(mpmath.isfinite(x) for A in (M, C1, K0, K2) for x in A)
