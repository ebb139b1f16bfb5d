"""The default Newton variant of ``integrate`` / ``ldaspark.integrate`` ("auto": simplified Newton,
full Newton on slow contraction) gives full Newton's numbers to within the Newton tolerance on
every named scene, at one LU per step; near the limit of (4) the det (4) monitor stops it at the
same step as full Newton. Negative controls: a loosened tolerance is seen by the same comparison;
simplified Newton without the fall-back fails near the limit of (4)."""
import re

import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import NewtonError, SingularSaddleError
from ldaspark.core.families import get_method
from ldaspark.models.scenes import SCENES, get_scene
from ldaspark.core.spark import integrate
from ldaspark.lab.reports import stability as S

TOL = 10 * 2.0 ** -52          # SparkMethod's default Newton tolerance in float64
STEPS = 10


def _gap(a, b):
    """max |q_a - q_b|, |v_a - v_b| in units of the Newton tolerance."""
    return max(np.max(np.abs(np.asarray(a.q, float) - np.asarray(b.q, float))),
               np.max(np.abs(np.asarray(a.v, float) - np.asarray(b.v, float)))) / TOL


def _run(name, **kw):
    sc = get_scene(name)
    t0, q0, v0 = sc.initial()
    return integrate(sc.system, get_method("gauss-2"), t0, q0, v0, 0.05, n_steps=STEPS, **kw)


# the bicycle derives and compiles the Whipple model (~30 s): --exhaustive
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.exhaustive) if n == "bicycle" else n
                                  for n in SCENES])
def test_default_newton_gives_full_newton_numbers(name):
    default, full = _run(name), _run(name, newton="full")
    assert _gap(default, full) <= 10
    assert default.stats["nlu"] < full.stats["nlu"]      # the cheaper variant ran (one LU per step, or a few more)


def test_default_newton_at_30_digits():
    sc = get_scene("robot")
    t0, q0, v0 = sc.initial(30)
    runs = [integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "0.05", n_steps=4, dps=30, **kw)
            for kw in ({}, {"newton": "full"})]
    gap = max(abs(a - b) for a, b in zip(runs[0].q.reshape(-1), runs[1].q.reshape(-1)))
    assert gap <= 10 * 10 * 10.0 ** -30 and runs[0].stats["nlu"] < runs[1].stats["nlu"]


def test_interface_default_is_the_same_loop():
    res = ldaspark.integrate("constant-speed", "gauss-2", n_steps=STEPS, h=0.05, engine="generic")
    assert np.array_equal(res.q, _run("constant-speed").q)


def test_loosened_tolerance_is_seen():
    # negative control of the comparison: Newton stopped at 1e-8 instead of 10 eps
    assert _gap(_run("constant-speed", tol=1e-8), _run("constant-speed", newton="full")) > 1000


def test_near_limit_of_4_monitor_stops_default_and_full_at_the_same_step():
    steps = {}
    for newton in ("auto", "full"):
        with pytest.raises(SingularSaddleError, match="crossed the singular set") as ei:
            integrate(S.soft_system(), get_method("gauss-2"), 0.0, [0.0] * 3, [1 - 1e-6, 0.0, 0.0], 0.01,
                      n_steps=215, newton=newton)
        steps[newton] = int(re.search(r"step (\d+)", str(ei.value)).group(1))
    assert steps["auto"] == steps["full"] == 200
    # negative control: simplified Newton without the fall-back diverges at the first step
    with pytest.raises(NewtonError, match="step 0"):
        integrate(S.soft_system(), get_method("gauss-2"), 0.0, [0.0] * 3, [1 - 1e-6, 0.0, 0.0], 0.01,
                  n_steps=215, newton="simplified")


def test_auto_switch_rule():
    from ldaspark.core.spark import _full_newton_cheaper as cheaper
    # constant-speed at 30 digits: theta ~ 1e-2 leaves ~12 simplified increments, full Newton ~3
    assert cheaper(7e-5, 6e-3, 1e-29, 1e-29)
    # negative controls: fast contraction (particle, float64), converged, or not contracting
    assert not cheaper(1e-6, 8e-3, 2.2e-15, 2.2e-15)
    assert not cheaper(1e-16, 1e-3, 2.2e-15, 2.2e-15)
    assert not cheaper(1e-3, 1e-3, 2.2e-15, 2.2e-15)
    import mpmath
    with mpmath.workdps(410):   # a tolerance below the float range (400 digits): mpmath logs
        assert cheaper(mpmath.mpf("7e-5"), mpmath.mpf("6e-3"), mpmath.mpf("1e-400"), mpmath.mpf("1e-400"))
