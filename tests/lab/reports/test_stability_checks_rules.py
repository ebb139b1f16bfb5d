"""Rules of ``ldaspark.lab.reports.stability_checks`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import sys
import types
import numpy as np
import pytest
from ldaspark.core.errors import NewtonError
from ldaspark.lab.reports import stability_checks as sc_
from stability_fakes import _fake_fast


def _energies(n_samples, every):
    steps = np.arange(n_samples) * every
    E = 1.0 + 1e-12 * np.sin(steps / 500.0)        # Kahan: bounded oscillation
    gap = np.where(steps >= 10 * every, 1e-10 * np.sqrt(np.maximum(steps, 1.0)), 0.0)
    gap[3] = 1e-9                                    # an early point (step < 10 every): left out of the fit
    return steps, E, gap


class _FakeScene:
    """initial data 0; the exact solution at t: q = (t, 0), v = (1, 0)."""
    def initial(self, dps=None):
        return 0.0, [0.0, 0.0], [1.0, 0.0]

    def exact_solution(self, t, dps=None):
        import mpmath
        t = mpmath.mpf(t) if dps else float(t)
        return [t, 0 * t], [1 + 0 * t, 0 * t], None

    system = None


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
