"""The extremes of ``ldaspark.integrate`` (probe t8): huge steps at mpmath precision, and the
set-up check of (4) at the run's digits. Each case with its control (the case that passed before
and the case that must still fail)."""
from __future__ import annotations

import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import NonFiniteError

x, y, vx, vy, w = sympy.symbols("x y vx vy w")
#: a particle in the plane, k = v_y - x v_x, U = w x^2 / 2 (tests/api/test_option_matrix.py's system)
PARTICLE = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - w * x ** 2 / 2, [vy - x * vx], [x, y], [vx, vy],
                                     params=[w], name="param-particle")


def _huge_step(h, dps=400):
    return ldaspark.integrate(PARTICLE, "gauss-2", t0=0, n_steps=1, h=h, params={"w": "1.5"}, engine="generic",
                              dps=dps, q0=["0.3", "0"], v0=["0.2", "0.06"])


@pytest.mark.parametrize("h", ["1e140", "1e160"])
def test_a_residual_beyond_float64s_range_is_a_number_at_dps(h):
    # one gauss-2 step of h = 1e160 at 400 digits: the first residual is ~ w h^2 = 1.5e320, an mpf
    # beyond float64's range. Before: math.isfinite rounded it to inf and the step ended with status
    # -3, "complex or non-finite residual: L or k evaluated outside its domain"; now the step
    # converges (16 iterations). h = 1e140 (residual 1.5e280) is the control that passed before.
    r = _huge_step(h)
    assert r.status == 0, r.message
    # (21f) holds at the end point to the round-off of O(1) numbers at 400 digits (measured
    # 1.3e-402; 1e-395 leaves 7 digits for the conditioning of a step of 1e160)
    assert max(abs(c) for c in r.constraint[-1]) < mpmath.mpf("1e-395")
    with mpmath.workdps(400):
        assert r.t[-1] == mpmath.mpf(h)


def test_a_non_finite_residual_is_still_a_non_finite_step():
    # control: in float64 the same residual overflows (h = 1e300: w h^2 is inf), a NonFiniteError
    # with status -3 on every engine, as before
    for engine in ("generic", "compiled"):
        r = ldaspark.integrate(PARTICLE, "gauss-2", t0=0.0, n_steps=1, h=1e300, params={"w": 1.5},
                               engine=engine, q0=[0.3, 0.0], v0=[0.2, 0.06])
        assert r.status == -3 and isinstance(r.error, NonFiniteError), (engine, r.message)
        assert np.all(np.isfinite(np.asarray(r.q, float)))
