"""Extremes (reports/stability.md): each measured behaviour has a test that fails if it
regresses, and each detector has a negative control."""

import numpy as np
import pytest

from ldaspark.lab.reports import stability as S
from ldaspark.core.errors import SingularSaddleError
from ldaspark.core.families import get_method


# --- 1. step size ------------------------------------------------------------------------------
def test_float64_round_off_floor_and_mpmath_removes_it():
    e64, _ = S.one_step_error("gauss-2", "1e-5")
    e30, _ = S.one_step_error("gauss-2", "1e-5", 30)
    e50, _ = S.one_step_error("gauss-2", "1e-5", 50)
    assert 1e-18 < e64 < 2e-16            # float64 is at its floor ...
    assert 1e-28 < e50 < 1e-27            # ... the truncation error is C h^5 ~ 6e-28
    assert e30 == pytest.approx(e50, rel=1e-2)
    # at h = 1e-6 the 30-digit run hits its own floor (3e-32) while 50 digits go on (6e-33)
    f30, _ = S.one_step_error("gauss-2", "1e-6", 30)
    f50, _ = S.one_step_error("gauss-2", "1e-6", 50)
    assert f30 > 3 * f50 and f50 < 1e-32


def test_float64_floor_h_is_named_and_detector_has_teeth():
    hs = ["1e-5", "1e-4", "1e-3", "1e-2"]
    r = S.step_size_sweep(("gauss-2",), hs, precisions=(None, 50))[0]
    fh = S.float64_floor_h(r["h"], r["err"]["float64"], r["err"]["50"])
    assert 1e-4 <= fh <= 1e-3
    # negative control: identical errors (no floor) -> None; a floor at 1e-2 is found
    assert S.float64_floor_h(r["h"], r["err"]["50"], r["err"]["50"]) is None
    fake = [max(e, 1e-9) for e in r["err"]["50"]]
    assert S.float64_floor_h(r["h"], fake, r["err"]["50"]) == 1e-2


@pytest.mark.parametrize("method, slope", [("gauss-2", 5), ("gauss-3", 7), ("euler-i", 2)])
def test_local_error_slope_at_50_digits(method, slope):
    hs = ["1e-3", "1e-2", "1e-1"]
    r = S.step_size_sweep((method,), hs, precisions=(50,))[0]
    assert S.local_order(r["h"], r["err"]["50"], 1e-3, 1e-1) == pytest.approx(slope, abs=0.15)


def test_newton_limits():
    ok, bad, _ = S.newton_limit("gauss-2", "skate", h0=256.0)
    assert ok == 4096 and bad is None          # skate: solvable at any h tried
    ok, bad, msg = S.newton_limit("gauss-2", "robot")
    assert (ok, bad) == (2.0, 4.0) and "step 0" in msg and "iterations" in msg


# --- 2. stage counts --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["gauss-10", "lobatto-iiia-iiib-10", "lobatto-iiia-iiib-iiid-10", "gauss-7"])
def test_coefficient_residuals_s_up_to_10(name):
    tab = get_method(name)
    fam = "gauss" if name.startswith("gauss") else "lobatto"
    for dps, bound in ((None, 2e-16), (50, 1e-50)):
        a = tab.arrays(dps)
        res = S._residuals({k: getattr(a, k) for k in ("c", "b", "A", "A_hat")}, tab.s, fam)
        assert max(res.values()) < bound, (dps, res)


def test_coefficient_residuals_detect_a_perturbation():
    tab = get_method("gauss-3").with_entry("A", 0, 0, "1e-12")
    a = tab.arrays(50)
    res = S._residuals({k: getattr(a, k) for k in ("c", "b", "A", "A_hat")}, 3, "gauss")
    assert res["C"] > 1e-13 and res["22b"] > 1e-13


def test_order_reached_at_50_digits_not_in_float64():
    o = S.order_at_precision("gauss-6", 50)
    assert o["order"][0] == pytest.approx(12, abs=0.1)
    o64 = S.order_at_precision("gauss-6", None)
    assert o64["order"][0] < 6 and max(o64["err"]) < 1e-15     # float64 floor hides order 12


@pytest.mark.exhaustive
@pytest.mark.parametrize("name, p", [("gauss-10", 20), ("lobatto-iiia-iiib-10", 18),
                                     ("lobatto-iiia-iiib-iiid-10", 18), ("gauss-8", 16)])
def test_order_s10_at_50_digits(name, p):
    o = S.order_at_precision(name, 50)
    assert o["order"][0] == pytest.approx(p, abs=0.3)


# --- 3. long runs -------------------------------------------------------------------------------------
def test_long_run_constraint_at_roundoff_energy_bounded():
    lr = S.long_run("gauss-2", "particle", 0.05, 10000, 100)
    assert lr["max_k"]["kahan"] < 1e-15 and lr["max_k"]["plain"] < 1e-15
    w = lr["dE_window"]["kahan"]              # windows 1e3, 1e4
    assert w[-1] < 1.2e-7 and w[-1] < 1.6 * w[0]


def test_drift_detector_has_teeth():
    # the windowed maximum grows for a drifting energy and not for a bounded oscillation
    n = np.arange(0, 10 ** 6 + 1, 1000)
    osc = 1e-7 * np.sin(0.01 * n)
    drift = osc + 1e-12 * n
    win = lambda E: [np.max(np.abs(E[n <= w])) for w in (10 ** 4, 10 ** 6)]
    assert win(osc)[1] < 1.6 * win(osc)[0]
    assert win(drift)[1] > 1.6 * win(drift)[0]


def test_roundoff_growth_small():
    r = S.roundoff_growth(n_steps=10 ** 4, every=100, n_ics=4)
    assert r["rms"]["compensated"][-1] < r["rms"]["plain"][-1] < 1e-14
    for k in ("compensated", "plain"):
        assert 0.2 < r["exponent"][k] < 1.3     # measured ~1 at 1e6 (report); never worse than linear


# --- 4. ill-conditioned scenes -------------------------------------------------------------------------
def test_mass_ratio_1e8_and_1e16_accurate():
    """check_saddle equilibrates (4) before judging it: mass ratios are not singularity."""
    rows = S.mass_ratio_scene((1e8, 1e13, 1e16), n_steps=10)
    for r in rows:
        assert r["outcome"] == "ok" and r["rel_err"] < 1e-13, r
        assert r["rcond"] < 1e-8          # the unscaled matrix is badly conditioned all the same


def test_rank_loss_accuracy_and_setup_error():
    rows = S.rank_loss_scene((1e-4, 1e-6, 1e-8), n_steps=10)
    assert rows[0]["outcome"] == "ok" and rows[0]["err"] < 1e-11
    assert rows[1]["outcome"] == "ok" and rows[1]["err"] < 1e-9 and rows[1]["max_psi"] > 1e5
    assert rows[2]["outcome"] == "SingularSaddleError"


def test_near_limit_of_4_wrong_branch_is_detected():
    # what holds for any round-off (any BLAS kernel, any CPU): the det (4) monitor stops the run
    # at the step that jumps to the other branch, and that step is where the trajectory computed
    # without the monitor crosses the singular set (never a Newton failure at a 1e-17 residual)
    import re
    from ldaspark.core.spark import integrate
    sysm = S.soft_system()
    tab = get_method("gauss-2")
    with pytest.raises(SingularSaddleError, match=r"step \d+ .*crossed the singular set") as ei:
        integrate(sysm, tab, 0.0, [0.0, 0.0, 0.0], [1 - 1e-6, 0.0, 0.0], 0.01, n_steps=220)
    n = int(re.search(r"step (\d+)", str(ei.value)).group(1))
    assert 190 <= n <= 210                       # v1 returns to 1 - delta after half a period (t ~ 2)
    # without the per-step monitor the jump is silent; check_saddle_along finds it afterwards
    bad = integrate(sysm, tab, 0.0, [0.0, 0.0, 0.0], [1 - 1e-6, 0.0, 0.0], 0.01, n_steps=220,
                    monitor_saddle=False)
    assert np.min(bad.v[:, 0]) < -1.1            # silently on the other branch (|v1| > 1)
    assert S.saddle_crossings(sysm, bad) == [n]
    with pytest.raises(SingularSaddleError, match=f"step {n}"):
        S.check_saddle_along(sysm, bad)
    good = integrate(sysm, tab, 0.0, [0.0, 0.0, 0.0], [0.9, 0.0, 0.0], 0.01, n_steps=220)
    assert S.saddle_crossings(sysm, good) == [] and S.check_saddle_along(sysm, good) is None


def test_exactly_singular_velocity_is_a_setup_error():
    rows = S.soft_scene((0.0, 1e-15), n_steps=5)
    assert all(r["outcome"] == "SingularSaddleError" for r in rows)


# --- 5. time reversal -------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-3"])
def test_time_reversal_symmetric_returns_to_roundoff(method):
    r = S.time_reversal(method, "particle", 0.05, 60)
    assert r["return_error"] < 1e-13 and r["excursion"] > 0.5


@pytest.mark.parametrize("method", ["euler-i", "euler-ii"])
def test_time_reversal_nonsymmetric_control(method):
    assert S.time_reversal(method, "particle", 0.05, 60)["return_error"] > 1e-3


def test_time_reversal_mp_removes_the_floor():
    r = S.time_reversal("gauss-2", "robot", 0.05, 10, dps=30)
    assert r["return_error"] < 1e-26


def test_report_section_is_registered():
    from ldaspark.cli import build_parser
    args = build_parser().parse_args(["report", "stability", "--full", "--outdir", "x"])
    assert args.full and args.outdir == "x" and args.section_run is S.run


def test_newton_near_limit_of_4_residual_at_roundoff_is_converged():
    # delta = 1e-9: at step 199 the Newton matrix is so ill-conditioned that the increments are
    # amplified noise (how large depends on the BLAS kernel) while the residual is ~1e-17; the
    # residual test accepts the step, and the det (4) monitor names the wrong-branch step
    rows = S.soft_scene((1e-9,), n_steps=210)
    assert rows[0]["outcome"] == "SingularSaddleError", rows[0]
    assert "crossed the singular set" in rows[0]["message"]


@pytest.mark.exhaustive
def test_report_is_reproducible(tmp_path):
    # two runs of the default report give the same text, except wall-clock columns
    import re
    texts = []
    for d in ("a", "b"):
        S.build_report(full=False, outdir=str(tmp_path / d))
        t = (tmp_path / d / S.REPORT).read_text()
        t = re.sub(r"\| [0-9.]+ / [0-9.]+ \|\n", "|\n", t)          # seconds (Kahan / plain)
        t = re.sub(r"_Written by .*_", "", t)                                # run time of this report
        texts.append(t)
        assert (tmp_path / d / "figures" / "stability_step_size.png").stat().st_size > 10000
    assert texts[0] == texts[1]
