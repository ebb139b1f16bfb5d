"""The finite differences behind the Theorem 1 check (theory.discrete._theorem1_once): central
differences of L_d at delta, delta/2, delta/4, Richardson-extrapolated twice. The two first-level
extrapolants R1, R2 then agree to O(delta^4) and the final value is O(delta^6) accurate; the
reported error estimate is |R2 - R1|. An inconsistent stencil or weight would still reach the
1e-20 target after the automatic refinement of delta, so the order itself is checked here, with
refinement off: the estimate must scale like delta^4 between delta = 1e-6 (24 digits) and
delta = 1e-10 (40 digits). Cost: ~3 s."""
import math

import pytest

from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.analysis.discrete import theorem1_residuals
from ldaspark.lab.claims.ledger import TOL_THEOREM1


@pytest.fixture(scope="module")
def estimates():
    sc = get_scene("particle")
    tab = get_method("gauss-2", exact=True)
    out = {}
    for dps in (24, 40):          # delta = 10^-(dps // 4)
        t0, q0, v0 = sc.initial(dps + 20)
        out[dps] = theorem1_residuals(sc.system, tab, t0, q0, v0, "0.1", dps=dps, max_refine=0)
    return out


def test_richardson_estimate_scales_like_delta_to_the_4(estimates):
    e24, e40 = estimates[24], estimates[40]
    assert e24["fd_delta"] == pytest.approx(1e-6) and e40["fd_delta"] == pytest.approx(1e-10)
    slope = math.log(e24["fd_error"] / e40["fd_error"]) / math.log(e24["fd_delta"] / e40["fd_delta"])
    assert abs(slope - 4) < 0.5, (slope, e24["fd_error"], e40["fd_error"])
    # the extrapolated gradient itself is O(delta^6): at delta = 1e-6 the Theorem 1 residual is
    # FD error, and it shrinks like delta^6 (the estimate |R2 - R1| is a bound, not the error)
    r_slope = math.log(e24["theorem1-q0"] / e40["theorem1-q0"]) / math.log(1e4)
    assert abs(r_slope - 6) < 0.5, (r_slope, e24["theorem1-q0"], e40["theorem1-q0"])
    # negative control: the two rates are told apart (a consistent O(delta^2) stencil gives 2)
    assert abs(r_slope - slope) > 1


def test_error_estimate_bounds_the_actual_error(estimates):
    for r in estimates.values():
        assert max(r["theorem1-q0"], r["theorem1-q1"]) <= r["fd_error"], r


def test_first_attempt_is_already_accurate(estimates):
    """Without any refinement the 40-digit check resolves Theorem 1 far below its tolerance."""
    r = estimates[40]
    assert r["fd_refinements"] == 0 and r["fd_error"] < 1e-25, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= TOL_THEOREM1, r
