"""Ensembles run the set-up checks of integrate on every member (an inconsistent v0 is an error
naming the member, not a run whose energy jumps in the first step), validate their options, and
stop promptly on Ctrl-C: pending tasks are cancelled and the pool's workers stopped."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import ldaspark

from ldaspark.ensemble import RunSpec, _run_plan, ensemble_integrate
from ldaspark.core.errors import InconsistentInitialDataError, InputError, SingularSaddleError
from ldaspark.models.scenes import get_scene


@pytest.fixture(scope="module")
def skate():
    return get_scene("skate")


def _ics(skate):
    t0, q0, v0 = skate.initial()
    return t0, np.array([q0, q0, q0], float), np.array([v0, v0, v0], float)


def test_inconsistent_member_is_named(skate):
    t0, Q0, V0 = _ics(skate)
    V0[2] += [0.5, 0.3, 0.2]                 # k = -v1 sin q3 + v2 cos q3 = 0.3 for member 2
    with pytest.raises(InconsistentInitialDataError, match="ensemble member 2: initial data are inconsistent"):
        ensemble_integrate(skate.system, "gauss-2", t0, Q0, V0, 0.1, 10)


def test_consistent_members_pass_the_checks(skate):
    # control: the checks alone (RunSpec builds no kernel) accept consistent data
    t0, Q0, V0 = _ics(skate)
    assert RunSpec(skate.system, "gauss-2", t0, Q0, V0, 0.1, 10).Q0.shape == (3, 3)


def test_singular_member_is_named():
    from ldaspark.lab.reports.stability import soft_system
    sysm = soft_system()
    Q0 = np.zeros((2, 3))
    V0 = np.array([[0.5, 0, 0], [1.0, 0, 0]])   # v1 = 1: (4) fails
    with pytest.raises(SingularSaddleError, match="ensemble member 1"):
        RunSpec(sysm, "gauss-2", 0.0, Q0, V0, 0.1, 10)


@pytest.mark.parametrize("kw, match", [
    (dict(h=float("nan")), "h must be finite"), (dict(h=0.0), "h must be finite"),
    (dict(n_steps=0), "n_steps"), (dict(n_steps=2.5), "n_steps"), (dict(every=0), "every"),
    (dict(tol=0.0), "tolerance"), (dict(tol=float("nan")), "tolerance"),
    (dict(n_steps=10 ** 12), r"between 1 and 1e\+09"),   # the step bound of every run
    (dict(n_steps=10 ** 9), "GiB"),
])
def test_ensemble_options(skate, kw, match):
    t0, Q0, V0 = _ics(skate)
    args = dict(h=0.1, n_steps=10, every=1, tol=None)
    args.update(kw)
    with pytest.raises(InputError, match=match):
        RunSpec(skate.system, "gauss-2", t0, Q0, V0, args["h"], args["n_steps"], args["every"], tol=args["tol"])


def _sleep_task(x):
    time.sleep(x)
    return [x]


def test_plan_results_grouped_by_spec():
    # control for the refactoring of run_many: results come back grouped and in order
    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(2) as ex:
        res = _run_plan([(0, _sleep_task, (0.0,)), (1, _sleep_task, (0.01,)), (0, _sleep_task, (0.02,))], 2, ex)
    assert res == [[0.0, 0.02], [0.01]]


_CTRL_C = """
import sys, time
sys.path.insert(0, sys.argv[1])
from test_ensemble_inputs import _sleep_task
from ldaspark.ensemble import _run_plan
print("start", flush=True)
try:
    _run_plan([(0, _sleep_task, (3.0,)) for _ in range(20)], 1, max_workers=2)   # 30 s of work
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(130)
"""


def test_ctrl_c_cancels_pending_tasks_and_stops_workers():
    # Ctrl-C (SIGINT to the process group, as a terminal sends it) ends the run well before the
    # 30 s of queued work; the bound is loose (the machine may be loaded), the queue is not
    here = os.path.dirname(os.path.abspath(__file__))
    p = subprocess.Popen([sys.executable, "-c", _CTRL_C, here], stdout=subprocess.PIPE, text=True,
                         env=dict(os.environ, PYTHONPATH=os.getcwd()), start_new_session=True,
                         # a shell's background job inherits SIGINT ignored; Python then installs no
                         # KeyboardInterrupt handler: give the child the terminal's default
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert p.stdout.readline().strip() == "start"
        time.sleep(1.0)
        t = time.monotonic()
        os.killpg(p.pid, signal.SIGINT)
        out, _ = p.communicate(timeout=60)
        elapsed = time.monotonic() - t
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130 and "interrupted" in out
    assert elapsed < 12, f"took {elapsed:.1f} s to stop (the queue holds 30 s)"


@pytest.mark.parametrize("entry", ["RunSpec", "fast_integrate", "run_compiled"])
def test_kernel_spark_of_a_comparator_is_refused(skate, entry):
    # kernel="spark" forces the SPARK kernel; a comparator of Fig. 4 has no SPARK tableau and ran on
    # the semi-implicit kernel whatever kernel said (accepted and ignored: the same numbers as
    # kernel="auto"). Control: kernel="auto" of the comparator, and kernel="spark" of the SPARK
    # method lobatto-iiia-iiib-2 (the same method (25) on the general kernel), are accepted.
    import warnings
    from ldaspark.compiled import fast, runner
    t0, Q0, V0 = _ics(skate)

    def go(method, kernel):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            if entry == "RunSpec":
                return RunSpec(skate.system, method, t0, Q0, V0, 0.1, 3, kernel=kernel)
            if entry == "fast_integrate":
                return fast.fast_integrate(skate, method, h=0.1, n_steps=3, kernel=kernel)
            return runner.run_compiled(fast.compile_system(skate.system), method, t0, Q0[0], V0[0], 0.1, 3,
                                       kernel=kernel)
    with pytest.raises(InputError, match=r"kernel='spark' runs SPARK tableaus; lobatto-iiia-iiib-2-leapfrog is a "
                                         "comparator"):
        go("lobatto-iiia-iiib-2-leapfrog", "spark")
    assert go("lobatto-iiia-iiib-2-leapfrog", "auto") is not None
    assert go("lobatto-iiia-iiib-2", "spark") is not None


def test_a_comparator_on_a_system_not_of_the_mechanical_form_is_refused_before_any_work(skate):
    # run_many sent the members of a Fig. 4 comparator on a general system (L quartic in v, k
    # nonlinear in v) to the workers, where the generic comparator refused each: failed work units
    # (UnitsFailed), not the InputError integrate raises for the same run. Control: the same
    # comparator on the skate (mechanical form) runs.
    from concurrent.futures import ThreadPoolExecutor
    from ldaspark.ensemble import run_many
    from ldaspark.executors import UnitsFailed
    from verification.general_fixtures import rheonomic_initial, rheonomic_system
    t0, q0, v0 = rheonomic_initial()
    spec = RunSpec(rheonomic_system(), "lobatto-iiia-iiib-2-leapfrog", t0, [np.asarray(q0, float)],
                   [np.asarray(v0, float)], 0.1, 3)
    with ThreadPoolExecutor(1) as ex:
        with pytest.raises(InputError, match="not of the mechanical form") as err:
            run_many([spec], where=ex)
        assert not isinstance(err.value, UnitsFailed)
        st0, sq0, sv0 = _ics(skate)
        (ok,) = run_many([RunSpec(skate.system, "lobatto-iiia-iiib-2-leapfrog", st0, sq0, sv0, 0.1, 3)], where=ex)
        # the modified method of 8.4 needs no mechanical form: its generic path runs the general system
        # (the kernels do not), as integrate does
        mod = RunSpec(rheonomic_system(), "lobatto-iiia-iiib-2-modified", t0, [np.asarray(q0, float)],
                      [np.asarray(v0, float)], 0.1, 3)
        (gen,) = run_many([mod], where=ex)
    assert ok.q.shape == (3, 4, 3)
    single = ldaspark.integrate(rheonomic_system(), "lobatto-iiia-iiib-2-modified", q0=np.asarray(q0, float),
                                v0=np.asarray(v0, float), t0=float(t0), h=0.1, n_steps=3)
    assert gen.stats[0]["path"] == "generic" and np.array_equal(gen.q[0], np.asarray(single.q, float))
