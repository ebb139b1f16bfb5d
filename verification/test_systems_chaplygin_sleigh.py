"""Chaplygin sleigh (Bloch 2003, 1.7; scene ``chaplygin-sleigh``, ``ldaspark.models.systems_classic``):
the closed form (speed ~ tanh, angular velocity ~ sech, the path), the orders 2s / 2s - 2 against
it, the constraint at round-off, the long-time energy and asymptotic speed; each check with a
negative control (a wrong sign in L or k, a non-symmetric method, RK4 on (3a-b)). Tolerances:
``verification/systems_checks.py``. Default cost ~5 s."""
import numpy as np
import pytest

import ldaspark
from ldaspark.models.scenes import get_scene
from ldaspark.lab.theory.orders import ExactReference

from systems_checks import (EXHAUSTIVE_PLAN, RESIDUAL_TOL, constraint_bound, long_run, observed_orders, ode_residual,
                            orders_hold, rk4_constraint_drift, wrong_sign)

SC = "chaplygin-sleigh"


def test_closed_form_solves_3ab_and_reduced_equations():
    """The closed form (q, v, psi) solves (3a-b) at 30 digits; its u, omega, theta are Bloch's
    tanh / sech / 2 gd (``closed_forms``); control: a wrong sign in k (v_x -> -v_x) or in L
    (v_theta -> -v_theta: the centre of mass behind the blade) leaves an O(1) residual."""
    sc = get_scene(SC)
    acc, psi, k = ode_residual(sc)
    assert max(acc, psi, k) < RESIDUAL_TOL, (acc, psi, k)
    t = np.linspace(0, 6, 61)
    q = np.array([sc.exact_solution(x)[0] for x in t])
    v = np.array([sc.exact_solution(x)[1] for x in t])
    errs = sc.closed_form_errors(t, q, v)
    assert max(errs.values()) < 1e-13, errs          # float64 evaluation of the same functions
    for where, sym in (("k", "v_x"), ("L", "v_theta")):
        acc_w, _, k_w = ode_residual(sc, wrong_sign(sc.system, where, sym))
        assert max(acc_w, k_w) > 1e-3, (where, acc_w, k_w)


def test_orders_2s_and_2s_minus_2_against_closed_form():
    """Gauss s = 1, 2 (orders 2, 4) and Lobatto IIIA-B s = 2, 3 (orders 2, 4) on [0, 1] against the
    closed form, q and v, two-sided within 0.3; control: the wrong-sign k does not converge to it."""
    sc = get_scene(SC)
    ref = ExactReference(sc, 40)
    obs = observed_orders(sc, ref)
    assert orders_hold(obs), obs
    bad = observed_orders(sc, ref, plan=(("gauss-2", [4, 8, 16, 32]),), system=wrong_sign(sc.system, "k", "v_x"))
    assert not orders_hold(bad), bad


def test_constraint_at_roundoff_and_engines_agree():
    """k = 0 to round-off along 2000 compiled Gauss-2 steps; engine="auto" compiles the scene and
    the generic engine gives the same steps (1e-12 over 40 steps: both solve (21) to ~8 eps);
    control: RK4 on (3a-b) leaves k at its truncation error, far above the bound."""
    sc = get_scene(SC)
    res = ldaspark.integrate(SC, "gauss-2", t_span=(0, 200), h=0.1)
    assert res.engine == "compiled" and res.success
    assert np.abs(res.constraint).max() <= constraint_bound(res), np.abs(res.constraint).max()
    gen = ldaspark.integrate(SC, "gauss-2", t_span=(0, 4), h=0.1, engine="generic")
    assert np.abs(gen.q[-1] - res.q[40]).max() < 1e-12
    assert rk4_constraint_drift(sc, 0.1, 40) > 10 * constraint_bound(res)


def test_long_time_energy_bounded_and_speed_limit():
    """Over t in [0, 500] (h = 0.1): Gauss-2 and Lobatto IIIA-B 3 keep the energy error bounded and
    the speed at its limit u -> V = 2 a omega0 within 1e-5 (their O(h^4) error, ~1e-7); the
    sleigh's reduced flow is asymptotically stable (u -> V, omega -> 0), so no method drifts:
    the control is the non-symmetric Euler I, whose O(h) error puts the limit 1e-2 off."""
    sc = get_scene(SC)
    V = float(2 * sc.params["a"] * sc.params["omega0"])
    for meth in ("gauss-2", "lobatto-iiia-iiib-3"):
        res, rec = long_run(sc, meth, 500, 0.1)
        assert rec["energy"]["bounded"], (meth, rec["energy"])
        u = np.cos(res.q[-1, 2]) * res.v[-1, 0] + np.sin(res.q[-1, 2]) * res.v[-1, 1]
        assert abs(u - V) < 1e-5, (meth, u - V)
    res, rec = long_run(sc, "euler-i", 500, 0.1)
    u = np.cos(res.q[-1, 2]) * res.v[-1, 0] + np.sin(res.q[-1, 2]) * res.v[-1, 1]
    assert abs(u - V) > 1e-2, u - V


@pytest.mark.exhaustive
def test_orders_exhaustive():
    sc = get_scene(SC)
    obs = observed_orders(sc, ExactReference(sc, 40), plan=EXHAUSTIVE_PLAN)
    assert orders_hold(obs), obs
