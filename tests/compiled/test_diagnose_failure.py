"""``fast._diagnose_newton_failure``: a kernel's Newton failure at step k is re-examined by the
generic full-Newton step at the state the same compiled arithmetic reaches after k steps."""
from __future__ import annotations

import numpy as np

import ldaspark
from ldaspark.compiled import fast, runner
from ldaspark.core.errors import NewtonError


def _start(sc):
    t0, q0, v0 = sc.initial()
    return float(t0), np.array(q0, float), np.array(v0, float)


def test_a_spark_failure_is_retried_by_the_generic_step_at_the_same_state():
    sc = ldaspark.get_scene("skate")
    cs = fast.compile_system(sc.system)
    planted = NewtonError("planted", step=3, time=0.3)
    out = fast._diagnose_newton_failure(planted, sc.system, cs, "gauss-2", _start(sc), 0.1, runner.KernelOptions())
    # the skate at h = 0.1 is an easy step: the generic step converges there, and says so
    assert isinstance(out, NewtonError) and out is not planted
    assert "generic full-Newton step converges" in str(out) and out.step == 3
    assert abs(out.time - 0.3) < 1e-15


def test_a_comparator_failure_is_returned_as_it_is():
    sc = ldaspark.get_scene("skate")
    cs = fast.compile_system(sc.system)
    planted = NewtonError("planted", step=3, time=0.3)
    out = fast._diagnose_newton_failure(planted, sc.system, cs, "lobatto-iiia-iiib-2-leapfrog", _start(sc), 0.1,
                                        runner.KernelOptions())
    assert out is planted
