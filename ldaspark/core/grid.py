"""The uniform time grid t_n = t0 + n h of a run, in the run's numbers (float64, or mpf at dps
digits, where t and h may lie beyond float64's range): what the driver, the guard and the det (4)
scan count steps with."""
from __future__ import annotations

import numpy as np

from .backend import _mpf     # the run's numbers: sympy reals, decimal strings, mpf alike
from .errors import InputError


def steps_between(t_a, t_b, h) -> int:
    """round((t_b - t_a) / h): the steps of a uniform grid between two of its times, in the run's
    numbers. At dps digits t and h may lie beyond float64's range (h = "1e-400" is 0.0 there, and
    the float64 quotient raised ZeroDivisionError), so mpf values and decimal strings are
    divided in mpmath at a precision that spans t's magnitude down to h's plus 64 bits (the grid's
    times carry no more: a step that does not advance t is refused before a run)."""
    plain = (float, int, np.floating, np.integer)
    if all(isinstance(x, plain) for x in (t_a, t_b, h)):
        return int(round((float(t_b) - float(t_a)) / float(h)))
    import mpmath
    with mpmath.workprec(128):
        a, b, hh = _mpf(t_a), _mpf(t_b), _mpf(h)
        if not hh:
            raise InputError(f"step size h must be nonzero, got {h}")
        top = max(abs(a), abs(b))
        span = 0 if not top else int(mpmath.floor(mpmath.log(top / abs(hh), 2)))
    with mpmath.workprec(min(max(span, 0) + 64 + 64, 10 ** 5)):
        return int(mpmath.nint((_mpf(t_b) - _mpf(t_a)) / _mpf(h)))

