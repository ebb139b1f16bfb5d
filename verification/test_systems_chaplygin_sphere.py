"""Chaplygin sphere (scene ``chaplygin-sphere``): the first integrals energy, |M|^2 and (M, gamma)
(M the angular momentum about the contact point, constant in space), the orders 2s / 2s - 2,
the constraint at round-off, and the long-time invariants; each check with a negative control.
The default reference is the ODE (3a-b) in scipy's DOP853 at rtol 1e-13 (independent of every
SPARK method; ~1e-12 accurate, so the errors measured stay >= 1e-10); the 40-digit Taylor
reference (minutes for this trigonometric 5-dof system) runs with --exhaustive. Tolerances:
``verification/systems_checks.py``. Default cost ~15 s."""
import numpy as np
import pytest

import ldaspark
from ldaspark.models.scenes import get_scene
from ldaspark.lab.claims.claims_general import DOP853Reference
from ldaspark.lab.theory.orders import make_reference

from systems_checks import (EXHAUSTIVE_PLAN, ORDER_PLAN, check_constraint_roundoff_and_engines, long_run,
                            observed_orders, orders_hold, wrong_sign)

SC = "chaplygin-sphere"


def _ref(system=None, T=2.0):
    sc = get_scene(SC)
    t0, q0, v0 = sc.initial()
    return DOP853Reference(system or sc.system, t0, q0, v0, T)


def _invariant_errors(sc, ref, T=2.0):
    t = np.linspace(0, T, 41)
    qv = [ref(x) for x in t]
    q = np.array([a[0] for a in qv])
    v = np.array([a[1] for a in qv])
    return {k: float(np.abs(x - x[0]).max()) for k, x in sc.invariant_values(t, q, v).items()}


def test_invariants_along_the_ode_reference():
    """E, |M|^2, (M, gamma) are constant along (3a-b) (DOP853, rtol 1e-13: to 1e-10 over [0, 2]);
    control: with a wrong sign in k (v_theta -> -v_theta: the ball slips) |M|^2 changes by O(1e-2).
    (Flipping v_x instead only mirrors the problem, x -> -x: the invariants survive.)"""
    sc = get_scene(SC)
    errs = _invariant_errors(sc, _ref())
    assert max(errs.values()) < 1e-10, errs
    bad = wrong_sign(sc.system, "k", "v_theta")
    t0, q0, v0 = sc.initial()
    v0w = bad.project_velocity(ldaspark.core.backend.Backend(None), 0.0, np.array(q0, float), np.array(v0, float))
    refw = DOP853Reference(bad, t0, q0, v0w, 2.0)
    errs_w = _invariant_errors(sc, refw)
    assert errs_w["|M|^2"] > 1e-2, errs_w


def test_orders_2s_and_2s_minus_2():
    """Orders on [0, 1] against the DOP853 reference, two-sided within 0.3; control: the wrong
    sign in L (v_psi -> -v_psi: the omega_psi omega_phi cos(theta) coupling reversed, the data still
    consistent) does not converge to the reference."""
    sc = get_scene(SC)
    ref = _ref(T=1.0)
    obs = observed_orders(sc, ref, plan=ORDER_PLAN)
    assert orders_hold(obs), obs
    bad = observed_orders(sc, ref, plan=(("gauss-2", [4, 8, 16, 32]),), system=wrong_sign(sc.system, "L", "v_psi"))
    assert not orders_hold(bad), bad


def test_constraint_at_roundoff_and_engines_agree():
    check_constraint_roundoff_and_engines(SC)


def test_long_time_invariants_bounded_drift_for_euler():
    """Over [0, 500], h = 0.1: E and |M|^2 bounded for Gauss-2 and Lobatto IIIA-B 3 ((M, gamma) at
    round-off); control: Euler I (h = 0.05, [0, 80], before its Newton fails near t = 96) drifts in
    |M|^2 (last/first quarter >= 2)."""
    sc = get_scene(SC)
    for meth in ("gauss-2", "lobatto-iiia-iiib-3"):
        _, rec = long_run(sc, meth, 500, 0.1)
        assert all(r["bounded"] for r in rec.values()), (meth, rec)
    res, rec = long_run(sc, "euler-i", 80, 0.05)
    assert res.success and rec["|M|^2"]["drift"], rec["|M|^2"]


@pytest.mark.exhaustive
def test_orders_exhaustive_40_digit_reference():
    """Gauss 1-3 and Lobatto IIIA-B 2-4 against the Taylor reference of (3a-b) at 40 digits, t_end = 1/2."""
    sc = get_scene(SC)
    ref = make_reference(sc, 40)
    obs = observed_orders(sc, ref, t_end=0.5, plan=ORDER_PLAN + EXHAUSTIVE_PLAN)
    assert orders_hold(obs), obs
