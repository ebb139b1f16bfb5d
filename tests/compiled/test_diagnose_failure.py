"""``fast._diagnose_newton_failure``: a kernel's Newton failure at step k is re-examined by the
generic full-Newton step at the state the same compiled arithmetic reaches after k steps."""
from __future__ import annotations

import numpy as np
import pytest

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


def test_the_failing_step_is_examined_at_its_own_time_when_t0_is_not_zero():
    # integrate on the compiled engine with one Newton iteration fails at step 0; the engine
    # examines that step with the generic step at t0 + k h (not k h): the error names that
    # time, which is where the returned trajectory ends
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ldaspark.integrate("pendulum", "gauss-2", engine="compiled", t0=5.0, n_steps=20, h=0.5,
                                 newton=ldaspark.Newton(kind="full", max_iter=1), guard=False)
    assert res.status < 0 and isinstance(res.error, NewtonError)
    k = res.error.step
    assert res.error.time == 5.0 + k * 0.5 == float(res.t[-1])
    # the generic step with the same root finder (one full-Newton iteration) fails there too, and
    # the message says so (it said "the generic full-Newton step converges there", which took 50
    # iterations, not the run's 1); where it converges, the message says that (control: a planted
    # kernel failure at an easy step of the skate, explained by the engine with max_iter = 5)
    assert "fails there too" in res.message and res.stats["root_finder"]["max_iter"] == 1
    from ldaspark import solve
    from ldaspark.engines import ENGINES
    sc = ldaspark.get_scene("skate")
    opts = solve.IntegrationOptions.checked(engine="compiled", newton=ldaspark.Newton(kind="full", max_iter=5))
    prob = solve._Problem("spark", solve.resolve_method("gauss-2")[1], "gauss-2", 0.0, 0.1, 10, "skate")
    prep = ENGINES["compiled"].prepare(sc.system, prob, opts)
    out = ENGINES["compiled"].explain(prep, NewtonError("planted", step=0, time=0.0), None, _start(sc))
    assert isinstance(out, NewtonError) and "same root finder converges there" in str(out)


def test_the_failure_message_names_the_root_finder_that_ran():
    # one iteration per step cannot converge at h = 0.5: the default ("auto") ran the quasi-Newton
    # iteration on this small mechanical system, kind="full" the kernels' Newton; each message says which
    import warnings
    msgs = {}
    for newton in ("auto", "full"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = ldaspark.integrate("pendulum", "gauss-2", engine="compiled", n_steps=20, h=0.5,
                                     newton=ldaspark.Newton(kind=newton, max_iter=1), guard=False)
        assert res.status < 0 and isinstance(res.error, NewtonError)
        msgs[newton] = res.message
    assert "quasi-Newton iteration" in msgs["auto"] and "quasi" not in msgs["full"]
    assert "Newton (full)" in msgs["full"]


@pytest.mark.parametrize("chunk", [None, 4])
def test_a_later_step_s_failure_is_examined_from_the_state_the_run_returned(monkeypatch, chunk):
    """``CompiledEngine.explain`` retries the failed step k with the generic step from the end of
    the run's prefix, the state the Result ends at (t_k, q_k, v_k), in one kernel call or in
    blocks of 4 steps; every other test fails at step 0 (no prefix), so a retry from another
    row of the prefix (v_1 for v_k) went unseen. Control: the failure is at a step k >= 4 (a
    prefix of several rows, q_1 != q_k)."""
    import sympy
    from ldaspark.core import chunks
    from ldaspark.core.spark import SparkMethod
    x, y, th, vx, vy, vth = sympy.symbols("x y th vx vy vth")
    # a stiff quartic spring with a nonholonomic constraint: gauss-2 at h = 0.7 fails after a few
    # steps with full Newton (tests/api/test_chunked_runs.py)
    quartic = ldaspark.LagrangianSystem((vx**2 + vy**2) / 2 + vth**2 / 2 - 1e4 * (x**4 / 4 + x**2 * y**2 / 2)
                                        - 3 * sympy.cos(th), [vy - 3 * x * vth], [x, y, th], [vx, vy, vth],
                                        name="quartic")
    seen, real = [], SparkMethod.step

    def recording(self, t, q, v, h, *a, **kw):
        if "step_index" in kw:          # explain's retry (and the kernels' rescue of a step) names it
            seen.append((kw["step_index"], t, np.array(q, float), np.array(v, float)))
        return real(self, t, q, v, h, *a, **kw)
    monkeypatch.setattr(SparkMethod, "step", recording)
    if chunk is not None:
        monkeypatch.setattr(chunks, "COMPILED_CHUNK", chunk)
    res = ldaspark.integrate(quartic, "gauss-2", q0=[0.5, 0.1, 0.3], v0=[1.0, 0.75, 0.5], h=0.7, n_steps=30,
                             engine="compiled", newton="full", guard=False)
    k = res.error.step
    assert res.status < 0 and isinstance(res.error, NewtonError) and k >= 4 and len(res.t) == k + 1
    assert not np.array_equal(np.asarray(res.q)[1], np.asarray(res.q)[-1])
    assert seen and seen[-1][0] == k            # explain's retry comes last, after the run
    _, t, q, v = seen[-1]
    assert t == float(res.t[-1])
    np.testing.assert_array_equal(q, np.asarray(res.q, float)[-1])
    np.testing.assert_array_equal(v, np.asarray(res.v, float)[-1])
