"""An executor that misbehaves ends in one LdasparkError naming it; a function that cannot reach a
process pool is refused up front (docs/reliability.md "A misbehaving executor is one error")."""
import concurrent.futures as cf

import pytest

import ldaspark
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.executors import Unit, open_executor, run_units


def square(x):
    return x * x


def event_q0(t, q, v):
    return q[0]


class ReturnsNone(cf.Executor):
    def submit(self, fn, /, *args, **kwargs):
        return None


class Raises(cf.Executor):
    def submit(self, fn, /, *args, **kwargs):
        raise ValueError("no capacity")


class ShutDown(cf.Executor):
    def submit(self, fn, /, *args, **kwargs):
        raise RuntimeError("cannot schedule new futures after shutdown")


@pytest.mark.parametrize("ex, match", [(ReturnsNone(), "ReturnsNone's submit returned NoneType None, not a future"),
                                       (Raises(), "Raises's submit raised ValueError: no capacity"),
                                       (ShutDown(), "refused new work")])
def test_a_bad_submit_is_one_error_naming_the_executor(ex, match):
    with pytest.raises(InputError, match=match):
        run_units([Unit("a", square, (2,)), Unit("b", square, (3,))], where=ex)
    with pytest.raises(InputError, match=match):
        with open_executor(ex) as e:
            e.submit(square, 2)


def test_negative_control_a_good_executor_runs():
    with cf.ThreadPoolExecutor(2) as ex:
        assert run_units([Unit("a", square, (2,)), Unit("b", square, (3,))], where=ex) == {"a": 4, "b": 9}


def _local():
    def h(x):
        return x
    return h


def test_a_local_function_with_a_process_pool_is_refused_up_front():
    with pytest.raises(InputError, match=r"_local.<locals>.h cannot be sent to the process pool"):
        run_units([Unit("a", _local(), (1,))], jobs=2)
    # a thread pool takes it
    with cf.ThreadPoolExecutor(1) as ex:
        assert run_units([Unit("a", _local(), (1,))], where=ex) == {"a": 1}


ENS = dict(t0=0, h=0.1, n_steps=2, q0=[[1, 0, 0], [1, 0, 0.1]], v0=[[0, 1, 0], [0, 1, 0]], engine="generic")


def test_a_lambda_event_with_a_process_pool_is_refused_up_front():
    with cf.ProcessPoolExecutor(1) as ex:
        with pytest.raises(LdasparkError, match=r"the event function \S*<lambda> cannot be sent to the process pool"):
            ldaspark.integrate("particle", "gauss-1", events=lambda t, q, v: q[0], executor=ex, **ENS)


def test_negative_control_a_lambda_event_with_threads_is_accepted():
    with cf.ThreadPoolExecutor(1) as ex:
        res = ldaspark.integrate("particle", "gauss-1", events=lambda t, q, v: q[0], executor=ex, **ENS)
    assert res.q.shape[0] == 2


class ResolvesToInt(cf.Executor):
    """Runs nothing; every future it returns resolves to 42."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        f.set_result(42)
        return f


class DropsARun(cf.Executor):
    """Runs each task in this process and drops the last run of its output."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        f.set_result(fn(*args, **kwargs)[:-1])
        return f


@pytest.mark.parametrize("ex, match", [(ResolvesToInt(), r"ResolvesToInt returned int 42 for a task of \d ensemble member"),
                                       (DropsARun(), r"DropsARun returned list .* for a task of \d ensemble member")])
def test_an_executor_whose_futures_return_no_runs_is_one_error_naming_it(ex, match):
    # the kernel tasks of run_many (guard=False sends an executor's ensemble there): a future that
    # resolves to something other than the task's runs was a TypeError ('int' object is not
    # iterable) or a short ensemble
    sc = ldaspark.get_scene("skate")
    kw = dict(q0=[sc.q0, sc.q0], v0=[sc.v0, sc.v0], h=0.1, n_steps=3, guard=False)
    from ldaspark.ensemble import RunSpec, run_many
    with pytest.raises(LdasparkError, match=match):
        ldaspark.integrate("skate", "gauss-2", executor=ex, **kw)
    with pytest.raises(LdasparkError, match=match):
        run_many([RunSpec(sc.system, "gauss-2", 0.0, kw["q0"], kw["v0"], 0.1, 3)], where=ex, chunk=2)
    with cf.ThreadPoolExecutor(1) as good:      # negative control
        assert ldaspark.integrate("skate", "gauss-2", executor=good, **kw).q.shape == (2, 4, 3)


class CancelsEverything(cf.Executor):
    """Hands back each future cancelled, its waiters never notified (``cancel()`` without
    ``set_running_or_notify_cancel()``): a user's executor that drops its work."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        f.cancel()
        return f


def _within(seconds, call):
    """``call()``'s outcome, or a failure when it has not returned after ``seconds``: the bound
    catches a wait forever, not the machine's speed (the call itself takes well under a second)."""
    import threading
    out = {}

    def target():
        try:
            out["value"] = call()
        except BaseException as exc:  # noqa: BLE001  (handed to the test)
            out["error"] = exc
    th = threading.Thread(target=target, daemon=True)
    th.start()
    th.join(seconds)
    assert not th.is_alive(), f"still waiting after {seconds} s"
    if "error" in out:
        raise out["error"]
    return out["value"]


def test_an_executor_that_cancels_its_futures_is_reported_not_waited_for():
    """``run_units`` waited in ``cf.as_completed`` for a future cancelled without notification
    forever (run_many, and integrate(q0=(B, n), executor=..., guard=False) through it, hung);
    now each such unit is reported failed by name. The loop of single runs (integrate with the
    guard) already said so through ``Future.result``. Control: a thread pool runs them."""
    from concurrent.futures import CancelledError  # noqa: F401  (what each unit's reason names)
    from ldaspark.ensemble import RunSpec, run_many
    from ldaspark.executors import UnitsFailed
    with pytest.raises(UnitsFailed, match=r"2 work unit\(s\) failed \(0 finished\): a: CancelledError"):
        _within(120, lambda: run_units([Unit("a", square, (2,)), Unit("b", square, (3,))], where=CancelsEverything()))
    sc = ldaspark.get_scene("skate")
    kw = dict(q0=[sc.q0, sc.q0], v0=[sc.v0, sc.v0], h=0.1, n_steps=3)
    with pytest.raises(UnitsFailed, match="CancelledError"):
        _within(120, lambda: run_many([RunSpec(sc.system, "gauss-2", 0.0, kw["q0"], kw["v0"], 0.1, 3)],
                                      where=CancelsEverything()))
    for guard in (True, False):
        with pytest.raises(LdasparkError, match="CancelledError"):
            _within(120, lambda: ldaspark.integrate("skate", "gauss-2", executor=CancelsEverything(), guard=guard,
                                                    **kw))
    with cf.ThreadPoolExecutor(2) as good:      # control
        assert _within(120, lambda: run_units([Unit("a", square, (2,))], where=good)) == {"a": 4}
        assert ldaspark.integrate("skate", "gauss-2", executor=good, guard=False, **kw).q.shape == (2, 4, 3)


@pytest.mark.parametrize("ex, match", [(ReturnsNone(), "ReturnsNone's submit returned NoneType None, not a future"),
                                       (Raises(), "Raises's submit raised ValueError: no capacity")])
def test_a_bad_submit_is_the_same_error_on_every_ensemble_path(ex, match):
    """run_many (and integrate with guard=False, the kernel tasks) refused such an executor with
    this InputError, while the loop of single runs (integrate's default guard=True) and a single
    run with an executor went through its ``map`` and said LdasparkError "failed to run the
    ensemble members (AttributeError: 'NoneType' object has no attribute 'cancel')" (3 of 4 paths
    differed before). Control: the same calls on a thread pool run."""
    from ldaspark.ensemble import RunSpec, run_many
    sc = ldaspark.get_scene("skate")
    kw = dict(q0=[sc.q0, sc.q0], v0=[sc.v0, sc.v0], h=0.1, n_steps=3)
    calls = [lambda e: run_many([RunSpec(sc.system, "gauss-2", 0.0, kw["q0"], kw["v0"], 0.1, 3)], where=e),
             lambda e: ldaspark.integrate("skate", "gauss-2", executor=e, guard=False, **kw),
             lambda e: ldaspark.integrate("skate", "gauss-2", executor=e, **kw),
             lambda e: ldaspark.integrate("skate", "gauss-2", executor=e, **dict(kw, q0=sc.q0, v0=sc.v0))]
    for call in calls:
        with pytest.raises(InputError, match=match):
            call(ex)
    with cf.ThreadPoolExecutor(2) as good:
        for call in calls:
            assert call(good) is not None
