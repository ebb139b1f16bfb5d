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
