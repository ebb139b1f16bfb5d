"""Tilted rolling disk in Euler angles (scene ``tilted-disk``): the steady circular motions and
their existence condition in closed form (``disk_steady_spin``, ``disk_steady_exists``), the
orders 2s / 2s - 2 against the steady motion, the constraint at round-off, the long-time energy
of a perturbed (quasi-periodic) motion; each check with a negative control. Tolerances:
``verification/systems_checks.py``. Default cost ~10 s."""
import numpy as np
import pytest

import ldaspark
from ldaspark.core.backend import Backend
from ldaspark.models.scenes import get_scene
from ldaspark.models.systems_classic import disk_steady_exists, disk_steady_spin, tilted_disk
from ldaspark.lab.theory.orders import ExactReference

from systems_checks import (EXHAUSTIVE_PLAN, RESIDUAL_TOL, constraint_bound, long_run, observed_orders, ode_residual,
                            orders_hold, rk4_constraint_drift)

SC = "tilted-disk"


def _theta_accel(system, theta0, Omega, spin, r=1):
    """theta'' of (3a-b) at the steady state (theta0, Omega, spin) (float64)."""
    q = [0.0, 0.0, 0.0, theta0, 0.0]
    v = [r * spin, 0.0, Omega, 0.0, spin]
    a, _ = system.ode_rhs(Backend(None), 0.0, np.array(q), np.array(v))
    return float(a[3])


def test_steady_motion_closed_form_and_existence_condition():
    """The steady motion (theta0, psi' = Omega, phi' = disk_steady_spin) solves (3a-b) at 30
    digits, and so does it for other (theta0, Omega) (theta'' = 0 to 1e-13, float64); the
    existence condition phi'^2 >= 20 g sin^2 / (9 r cos) is the sign of the discriminant: on its
    boundary the quadratic in Omega has a double root that is again a steady motion. Controls:
    the wrong sign of g in L (the disk hanging below the plane) is not steady (theta'' = O(1));
    a spin 1 % below the existence bound has no steady Omega (a complex root)."""
    sc = get_scene(SC)
    assert max(ode_residual(sc)) < RESIDUAL_TOL
    S = sc.system
    for th0, Om in ((0.3, 2.0), (-0.4, 1.5), (0.7, -0.8)):
        w = float(disk_steady_spin(th0, Om))
        assert abs(_theta_accel(S, th0, Om, w)) < 1e-13
    bad = tilted_disk(g=-1).system
    assert abs(_theta_accel(bad, 0.3, 2.0, float(disk_steady_spin(0.3, 2.0)))) > 1e-2
    th0 = 0.5
    c, s = np.cos(th0), np.sin(th0)
    w_min = np.sqrt(20 * s ** 2 / (9 * c))
    assert disk_steady_exists(th0, w_min * 1.0001) and not disk_steady_exists(th0, w_min * 0.99)
    Om_double = -6 * w_min * c / (2 * 5 * s * c)       # -b / (2 a) of 5 r s c Om^2 + 6 r w c Om + 4 g s
    assert abs(_theta_accel(S, th0, Om_double, w_min)) < 1e-12
    disc_below = 36 * (0.99 * w_min) ** 2 * c ** 2 - 80 * s ** 2 * c
    assert disc_below < 0


def test_orders_2s_and_2s_minus_2_against_steady_motion():
    """Orders on [0, 1] against the steady motion (closed form), two-sided within 0.3; control:
    the wrong sign of g (``tilted_disk(g=-1)``) from the same data does not converge to it."""
    sc = get_scene(SC)
    ref = ExactReference(sc, 40)
    obs = observed_orders(sc, ref)
    assert orders_hold(obs), obs
    bad = observed_orders(sc, ref, plan=(("gauss-2", [4, 8, 16, 32]),), system=tilted_disk(g=-1).system)
    assert not orders_hold(bad), bad


def _perturbed():
    sc = get_scene(SC)
    t0, q0, v0 = sc.initial()
    v0 = list(v0)
    v0[3] = 0.3            # theta' = 0.3: a generic (quasi-periodic) motion about the steady one
    return sc, q0, v0


def test_constraint_at_roundoff_and_engines_agree():
    """k = 0 to round-off (the bound grows with psi, phi ~ t) over 2000 compiled Gauss-2 steps of the
    perturbed motion; auto compiles; generic agrees; control: RK4 on (3a-b)."""
    sc, q0, v0 = _perturbed()
    res = ldaspark.integrate(sc, "gauss-2", t_span=(0, 200), h=0.1, q0=q0, v0=v0)
    assert res.engine == "compiled" and res.success
    assert np.abs(res.constraint).max() <= constraint_bound(res)
    gen = ldaspark.integrate(sc, "gauss-2", t_span=(0, 2), h=0.1, q0=q0, v0=v0, engine="generic")
    assert np.abs(gen.q[-1] - res.q[20]).max() < 1e-12
    assert rk4_constraint_drift(sc, 0.1, 20, q0, v0) > 10 * constraint_bound(res)


def test_long_time_energy_bounded_drift_for_euler():
    """Energy of the perturbed motion over [0, 500], h = 0.1: bounded for Gauss-2 and Lobatto
    IIIA-B 3 (last/first quarter <= 1.5); control: the non-symmetric Euler I (h = 0.02, [0, 8])
    drifts (ratio >= 2; its energy error grows ~100-fold in 8 time units, and its Newton fails near
    t = 8.7)."""
    sc, q0, v0 = _perturbed()
    for meth in ("gauss-2", "lobatto-iiia-iiib-3"):
        _, rec = long_run(sc, meth, 500, 0.1, q0, v0)
        assert rec["energy"]["bounded"], (meth, rec["energy"])
    res, rec = long_run(sc, "euler-i", 8, 0.02, q0, v0)
    assert res.success and rec["energy"]["drift"], (res.status, rec["energy"])


@pytest.mark.exhaustive
def test_orders_exhaustive():
    sc = get_scene(SC)
    obs = observed_orders(sc, ExactReference(sc, 40), plan=EXHAUSTIVE_PLAN)
    assert orders_hold(obs), obs
