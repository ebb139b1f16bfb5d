"""Negative powers in the audit's ball arithmetic (``core.numbers._BallEvaluator`` for file
entries, ``core.numbers._sympy_ball`` for exact sympy entries): x**-k (and x**(-p/q)) as an arb
ball must contain the value computed by mpmath at 80 digits, with a radius far below the
precision used (so that the containment is not won by a huge ball), and differ from x**k
(a sign of the exponent lost would give x**k, outside)."""
from __future__ import annotations

import flint
import mpmath
import sympy
from hypothesis import given, settings, strategies as st

from ldaspark.core.numbers import _BallEvaluator, _sympy_ball

PREC_BITS = 200          # ~60 digits; the reference has 80, so its own error is below 1e-75


def _contains(ball, exact) -> bool:
    """|mid - exact| <= rad (mid and rad read exactly as decimal strings at 80 digits)."""
    with mpmath.workdps(80):
        mid = mpmath.mpf(ball.mid().str(75, radius=False))
        rad = mpmath.mpf(ball.rad().str(10, radius=False)) * (1 + mpmath.mpf(10) ** -8) + mpmath.mpf(10) ** -74
        return abs(mid - exact) <= rad


bases = st.tuples(st.integers(1, 40), st.integers(1, 40), st.sampled_from(["", "sqrt(2)", "sqrt(3)/6"]))


@settings(max_examples=40, deadline=None)
@given(bases, st.integers(1, 9), st.booleans())
def test_negative_integer_power_of_a_file_entry_contains_the_mpmath_value(base, k, negate):
    p, q, extra = base
    text = f"{p}/{q}" + (f" + {extra}" if extra else "")
    text = f"-({text})" if negate else text
    with mpmath.workdps(80):
        x = mpmath.mpf(p) / q + {"": 0, "sqrt(2)": mpmath.sqrt(2), "sqrt(3)/6": mpmath.sqrt(3) / 6}[extra]
        x = -x if negate else x
        exact, wrong = x ** -k, x ** k
    old = flint.ctx.prec
    flint.ctx.prec = PREC_BITS
    try:
        ball = _BallEvaluator(None).leaf(f"({text})**-{k}")
        ball_sym = _sympy_ball(sympy.Pow(sympy.sympify(text), -k), 60, None)
    finally:
        flint.ctx.prec = old
    for b in (ball, ball_sym):
        assert _contains(b, exact), (text, k, b, exact)
        assert abs(float(b.rad())) <= 1e-50 * max(1.0, abs(float(exact)))
        if abs(exact - wrong) > 1e-40:
            assert not _contains(b, wrong)


@settings(max_examples=20, deadline=None)
@given(st.integers(1, 30), st.integers(1, 30), st.integers(1, 5), st.sampled_from([2, 3]))
def test_negative_rational_power_of_a_sympy_entry_contains_the_mpmath_value(p, q, a, b):
    with mpmath.workdps(80):
        exact = (mpmath.mpf(p) / q) ** (-mpmath.mpf(a) / b)
    old = flint.ctx.prec
    flint.ctx.prec = PREC_BITS
    try:
        ball = _sympy_ball(sympy.Pow(sympy.Rational(p, q), sympy.Rational(-a, b)), 60, None)
    finally:
        flint.ctx.prec = old
    assert _contains(ball, exact), (p, q, a, b, ball)
    assert abs(float(ball.rad())) <= 1e-50 * max(1.0, abs(float(exact)))
