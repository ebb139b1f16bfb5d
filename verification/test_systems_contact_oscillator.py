"""Contact oscillator x' + y z' = 0 (scene ``contact-oscillator``): the y-energy (y^2 + y'^2)/2 is an
exact first integral (K = (1, 0, y) has no y-component: y'' = -y), the energy (8) another; orders
2s / 2s - 2 against the 40-digit Taylor reference of (3a-b); the constraint at round-off; the
long-time invariants. Gauss methods conserve the y-energy to round-off (a quadratic invariant of
the decoupled linear y-oscillator, which the Gauss SPARK method integrates with Gauss's
collocation: 3.5 of Hairer-Lubich-Wanner), Lobatto IIIA-B keeps it bounded. Each check with a
negative control. Tolerances: ``verification/systems_checks.py``. Default cost ~6 s."""
import numpy as np
import pytest

import ldaspark
from ldaspark.models.scenes import get_scene
from ldaspark.core.system import LagrangianSystem
from ldaspark.lab.theory.orders import make_reference

from systems_checks import (EXHAUSTIVE_PLAN, ORDER_PLAN, check_constraint_roundoff_and_engines, long_run,
                            observed_orders, orders_hold)

SC = "contact-oscillator"


def _wrong_L():
    """The sign of the y-potential reversed (L + y^2: the potential has -y^2/2 in place of y^2/2): y'' = +y."""
    S = get_scene(SC).system
    y = S.q[1]
    return LagrangianSystem(S.L + y ** 2, list(S.k), S.q, S.v, name="contact-oscillator-wrong-L")


def test_y_energy_exact_first_integral_gauss_roundoff():
    """Gauss 1-3 keep (y^2 + y'^2)/2 to round-off over 2000 steps (h = 0.1), the energy (8) to
    O(h^2s); control: the wrong sign of the y-potential in L changes the y-energy by O(1)."""
    sc = get_scene(SC)
    for meth in ("gauss-1", "gauss-2", "gauss-3"):
        _, rec = long_run(sc, meth, 200, 0.1)
        assert rec["y-energy"]["roundoff"], (meth, rec["y-energy"])
    t0, q0, v0 = sc.initial()
    res = ldaspark.integrate(_wrong_L(), "gauss-2", t_span=(0, 5), h=0.1, q0=q0, v0=v0)
    ye = (res.q[:, 1] ** 2 + res.v[:, 1] ** 2) / 2
    assert np.abs(ye - ye[0]).max() > 1.0


def test_orders_2s_and_2s_minus_2_against_40_digit_reference():
    """Orders on [0, 1] against mpmath's Taylor solution of (3a-b) at 40 digits, two-sided within
    0.3; control: the wrong-sign L does not converge to it."""
    sc = get_scene(SC)
    ref = make_reference(sc, 40)
    obs = observed_orders(sc, ref, plan=ORDER_PLAN)
    assert orders_hold(obs), obs
    bad = observed_orders(sc, ref, plan=(("gauss-2", [4, 8, 16, 32]),), system=_wrong_L())
    assert not orders_hold(bad), bad


def test_constraint_at_roundoff_and_engines_agree():
    check_constraint_roundoff_and_engines(SC)


def test_long_time_invariants_bounded_drift_for_euler():
    """Over [0, 500], h = 0.1: energy and y-energy bounded for Gauss-2 and Lobatto IIIA-B 3;
    control: Euler I's energy drifts (last/first quarter >= 2)."""
    sc = get_scene(SC)
    for meth in ("gauss-2", "lobatto-iiia-iiib-3"):
        _, rec = long_run(sc, meth, 500, 0.1)
        assert all(r["bounded"] for r in rec.values()), (meth, rec)
    _, rec = long_run(sc, "euler-i", 500, 0.1)
    assert rec["energy"]["drift"], rec["energy"]


@pytest.mark.exhaustive
def test_orders_exhaustive():
    sc = get_scene(SC)
    obs = observed_orders(sc, make_reference(sc, 40), plan=EXHAUSTIVE_PLAN)
    assert orders_hold(obs), obs
