"""Order estimation (ldaspark.lab.theory.orders) on synthetic data where the right answer is known
independently: step ratios other than 2, ties between candidate windows, least squares over the
whole window, the scaled round-off floor, and the stage times at which Psi is compared.
Cost: ~2 s."""
import math

import numpy as np
import pytest

from ldaspark.core.backend import Backend
from ldaspark.core.families import gauss
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import integrate
from ldaspark.lab.theory.orders import (ExactReference, asymptotic_window, estimate_order, floor_for,
                                    measure_errors, pairwise_orders, verdict)


def test_pairwise_orders_with_step_ratio_3():
    hs = [0.9, 0.3, 0.1]
    assert pairwise_orders(hs, [h ** 2 for h in hs]) == pytest.approx([2.0, 2.0], abs=1e-12)
    # negative control: read with ratio 2 the same data give log(9)/log(2), not 2
    assert abs(math.log(9) / math.log(2) - 2) > 1


def test_window_ties_go_to_the_smaller_steps():
    hs = [0.8, 0.4, 0.2, 0.1]
    errs = [1e-2, 1e-3, 1e-1, 1e-2]          # two runs of two points each
    assert asymptotic_window(hs, errs, 0) == (2, 3)
    # negative control: a longer run still wins over a later shorter one
    assert asymptotic_window(hs, [1e-2, 1e-3, 1e-4, 1e-2], 0) == (0, 2)


def test_least_squares_uses_every_point_of_the_window():
    hs = [0.4, 0.2, 0.1, 0.05]
    errs = [h ** 2 * (1 + 3 * h) for h in hs]                   # not an exact power law
    est = estimate_order(hs, errs, 0.0)
    assert est.window == (0, 3)
    full = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert est.observed_order == pytest.approx(full, abs=1e-12)
    # negative control: a fit over three of the four points differs at this resolution
    assert abs(np.polyfit(np.log(hs[:3]), np.log(errs[:3]), 1)[0] - full) > 1e-3


def test_floor_scales_with_the_reference_magnitude():
    eps = Backend(None).eps
    assert floor_for(None, 100.0) == pytest.approx(1e3 * eps * 100)
    assert floor_for(None, 0.01) == pytest.approx(1e3 * eps)      # never below unit scale


def test_verdict_is_two_sided():
    rec = {"method": "m", "scene": "s", "variable": "q", "claimed_order": 4, "claim_scope": "variable"}
    assert verdict(dict(rec, observed_order=1.0)) == "FAILS"
    assert verdict(dict(rec, observed_order=6.0)) == "FAILS"
    assert verdict(dict(rec, observed_order=4.1)) == "holds"


def test_psi_compared_at_the_stage_times_of_the_last_step():
    """measure_errors compares Psi_i of the last step [T - h, T] with psi(T - h + c_i h)."""
    sc = get_scene("skate")
    ref = ExactReference(sc, 30)
    t_end, N = 1.0, 8
    m = measure_errors("gauss-2", sc, ref, t_end, [N])
    t0, q0, v0 = sc.initial()
    h = t_end / N
    sol = integrate(sc.system, gauss(2), t0, q0, v0, h, n_steps=N)
    c = gauss(2).arrays(None).c
    at = lambda shift: max(abs(float(sol.psi[-1][i][0]) - float(ref(t_end - h + shift + c[i] * h)[2][0]))
                           for i in range(2))
    assert m["psi"][0] == pytest.approx(at(0.0), rel=1e-6, abs=1e-14)
    # negative control: at T + c_i h (one step late) the same multipliers are far off
    assert at(h) > 100 * at(0.0)
