"""``IntegrationOptions.checked`` remembers options that passed (per process, keyed by the values
and their types) and ``validate.real_vector`` takes finite float vectors without the entry-wise
walk: both give the verdicts of the full checks, and a change of any option is checked again."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ldaspark.core import options, validate
from ldaspark.core.errors import InputError
from ldaspark.core.options import IntegrationOptions
from ldaspark.core.rootfinder import Newton


def test_repeated_options_are_one_frozen_object_and_equal_to_a_fresh_check():
    a = IntegrationOptions.checked(engine="compiled", newton="quasi", save_every=3)
    b = IntegrationOptions.checked(engine="compiled", newton="quasi", save_every=3)
    assert a is b
    fresh = IntegrationOptions._checked(engine="compiled", dps=None, newton="quasi", tol=None, save_every=3,
                                        dense_output=False, energy_jump=None, executor=None, max_stages=None,
                                        project=False, raise_on_failure=False, guard=True)
    assert a == fresh and a.newton == Newton(kind="quasi")


@pytest.mark.parametrize("change", [dict(save_every=4), dict(newton="full"), dict(tol=1e-10), dict(guard=False),
                                    dict(engine="auto"), dict(energy_jump=0.5), dict(dense_output=True)])
def test_a_changed_option_gives_its_own_checked_options(change):
    base = dict(engine="compiled", newton="auto", save_every=3)
    a = IntegrationOptions.checked(**base)
    b = IntegrationOptions.checked(**dict(base, **change))
    assert b is not a
    for k, val in change.items():
        got = getattr(b, k)
        assert (got == val) if k != "newton" else got.kind == val
        assert getattr(a, k) != got


def test_the_types_are_part_of_the_key():
    """save_every=1 passed: save_every=True (== 1, same hash) is still refused; tol=1 (int) gives
    its own object."""
    IntegrationOptions.checked(save_every=1, dense_output=False)
    with pytest.raises(InputError, match="save_every"):
        IntegrationOptions.checked(save_every=True)
    with pytest.raises(InputError, match="dense_output"):
        IntegrationOptions.checked(dense_output=0)
    a = IntegrationOptions.checked(tol=1.0)
    assert IntegrationOptions.checked(tol=1) is not a


def test_refused_options_are_not_remembered():
    for _ in range(2):
        with pytest.raises(InputError, match="engine"):
            IntegrationOptions.checked(engine="fast")
        with pytest.raises(InputError, match="quasi"):
            IntegrationOptions.checked(engine="generic", newton="quasi")
    assert not any(k[0] == "fast" for k in options._CHECKED_OPTIONS)


def test_options_with_objects_are_checked_every_time():
    """A Newton object or an executor is not a plain value: checked at every call, not remembered."""
    n = Newton(kind="full", max_iter=7)
    size = len(options._CHECKED_OPTIONS)
    a = IntegrationOptions.checked(newton=n)
    assert a.newton is n and len(options._CHECKED_OPTIONS) == size
    assert IntegrationOptions.checked(newton=n) is not a


def test_with_events_without_events_is_the_same_options():
    a = IntegrationOptions.checked()
    assert a.with_events(None) is a
    ev = a.with_events(lambda t, q, v: q[0])
    assert ev is not a and len(ev.events) == 1 and a.events == ()
    assert ev.with_events(None).events == ()       # events dropped again: a new object


@pytest.mark.parametrize("x", [np.array([1.0, 2.0]), [0.5, -3.0], (1e300,), np.zeros((2, 3))])
def test_real_vector_takes_finite_float_vectors(x):
    assert validate.real_vector(x, "q0") is x


@pytest.mark.parametrize("x, msg", [(np.array([1.0, np.nan]), "finite"), ([1.0, math.inf], "finite"),
                                    ([1.0, True], "bool"), (np.array([]), "non-empty"), ([], "non-empty"),
                                    ((1.0, "a"), "string"), (np.array([[1.0, np.inf]]), "finite")])
def test_real_vector_refuses_as_the_entry_wise_check(x, msg):
    with pytest.raises(InputError, match=msg):
        validate.real_vector(x, "q0")
