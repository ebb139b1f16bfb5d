"""Events and dense output: events are validated once for both engines
(``ldaspark.core.dense.Event``): events that never fire give empty (0, n) arrays, a bad
``direction`` / ``terminal`` / return value is one InputError naming the event, and an event
function that modifies its q argument cannot change the trajectory; ``sol(t)`` refuses NaN,
None, strings, complex and 2-D t."""
import numpy as np
import pytest

import ldaspark
from ldaspark.core.errors import InputError

from run_helpers import time_bound

ENGINES = ["generic", "compiled"]


def run(engine, **kw):
    with time_bound(300):     # a hang, not the speed (a first run may compile the kernels)
        return ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.5), h=0.05, engine=engine, **kw)


def with_attrs(fn, **attrs):
    for k, v in attrs.items():
        setattr(fn, k, v)
    return fn


@pytest.mark.parametrize("engine", ENGINES)
def test_event_that_never_fires(engine):
    # before: ValueError: cannot reshape array of size 0 into shape (0,newaxis), both engines
    res = run(engine, events=lambda t, q, v: q[0] + 0.3)
    assert res.status == 0 and res.engine == engine
    assert res.t_events[0].shape == (0,) and res.q_events[0].shape == (0, 3) and res.v_events[0].shape == (0, 3)


@pytest.mark.parametrize("engine", ENGINES)
def test_one_of_two_events_never_fires(engine):
    res = run(engine, events=[lambda t, q, v: q[0] + 0.3, lambda t, q, v: t - 0.22])
    assert res.q_events[0].shape == (0, 3)
    # the other fires once at t = 0.22 (brentq on the dense output: 1e-12 is ample)
    assert res.t_events[1] == pytest.approx([0.22], abs=1e-12) and res.q_events[1].shape == (1, 3)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("attrs, match", [
    (dict(direction=float("nan")), "direction"), (dict(direction="up"), "direction"),
    (dict(direction=1j), "direction"), (dict(direction=float("inf")), "direction"),
    (dict(direction=None), "direction"), (dict(terminal=np.array([1, 0])), "terminal"),
    (dict(terminal="yes"), "terminal"), (dict(terminal=2), "terminal"),
])
def test_bad_event_attributes(engine, attrs, match):
    with pytest.raises(InputError, match=f"event 0: {match}"):
        run(engine, events=with_attrs(lambda t, q, v: t - 0.2, **attrs))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("value", [[1.0], None, "a", np.array([1.0]), 1j, True, np.array([[1.0]])])
def test_event_returning_a_non_number(engine, value):
    with pytest.raises(InputError, match="event 1 must return a real number"):
        run(engine, events=[lambda t, q, v: t - 10, lambda t, q, v: value])


@pytest.mark.parametrize("engine", ENGINES)
def test_event_returning_nan_is_named(engine):
    with pytest.raises(InputError, match="event 0 returned NaN"):
        run(engine, events=lambda t, q, v: float("nan"))


@pytest.mark.parametrize("events", [42, "g", [42], {"a": 1}, (lambda t, q, v: t, 3)])
def test_events_must_be_callables(events):
    with pytest.raises(InputError, match="event"):
        run("generic", events=events)


@pytest.mark.parametrize("engine", ENGINES)
def test_event_function_modifying_q_does_not_change_the_trajectory(engine):
    # before: |dq| = 11 on the generic engine (the event got the live state array)
    def meddle(t, q, v):
        q[0] += 1.0
        v[:] = 0
        return t - 0.33
    plain = run(engine)
    res = run(engine, events=meddle)
    np.testing.assert_array_equal(res.q, plain.q)
    np.testing.assert_array_equal(res.v, plain.v)
    assert len(res.t_events[0]) == 1                  # it did fire (and saw copies)


@pytest.mark.parametrize("engine", ENGINES)
def test_good_events_still_work(engine):
    # control: numbers of every accepted type, direction and terminal as scipy's
    g = with_attrs(lambda t, q, v: np.float32(t - 0.2), terminal=True, direction=1)
    h = with_attrs(lambda t, q, v: np.array(0.3 - t), terminal=np.bool_(False), direction=-1.0)
    res = run(engine, events=[g, h])
    assert res.status == 1 and res.t_events[0] == pytest.approx([0.2], abs=1e-6)


@pytest.fixture(scope="module")
def dense():
    return ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.5), h=0.05, dense_output=True).sol


@pytest.mark.parametrize("t, match", [
    (float("nan"), "finite"), (None, "real number"), ([0, 0.5, float("nan")], "finite"), ("abc", "real number"),
    (1j, "real number"), ([[0.1, 0.2]], "1-D"), (float("inf"), "finite"), (True, "real number"),
    ([0.1, "a"], "real number"), (0.6, "outside"),
])
def test_dense_output_refuses_bad_times(dense, t, match):
    with pytest.raises(InputError, match=match):
        dense(t)


def test_dense_output_accepts_numbers_and_vectors(dense):
    q, v = dense(0.25)
    assert q.shape == (3,) and np.all(np.isfinite(q))
    q, v = dense(np.array([0, 0.1, 0.5], dtype=np.float32))
    assert q.shape == (3, 3) and np.all(np.isfinite(q))
    assert dense(np.int64(0))[0].shape == (3,)
