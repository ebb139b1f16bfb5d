"""Each symbolic step of the potential search has a time bound (``core.bounded.call_bounded``)."""
from __future__ import annotations

import sympy

from ldaspark.core import bounded


def _forever():
    while True:
        pass


def test_a_step_that_never_ends_is_abandoned_at_its_bound():
    assert bounded.call_bounded(_forever, seconds=0.5) is bounded.TIMED_OUT


def test_a_step_that_ends_returns_its_value():
    x = sympy.Symbol("x")
    assert bounded.call_bounded(sympy.integrate, sympy.cos(x), x, seconds=60) == sympy.sin(x)


def test_a_step_that_raises_is_reported_as_not_done():
    assert bounded.call_bounded(int, "not a number", seconds=60) is bounded.TIMED_OUT
