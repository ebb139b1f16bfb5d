"""Constraint satisfaction: k(t1, q1, v1) = 0 (21f) to solver tolerance on every step, float64
and mpmath, for every built-in method on every paper scene. Negative control: the secant
velocity (q1 - q0)/h is not constrained by (21), so k at it is far from zero."""
import pytest

from ldaspark.analysis.discrete import base_point, discrete_lagrangian
from ldaspark.core.backend import Backend
from ldaspark.core.families import builtin_method_names
from ldaspark.lab.claims.ledger import constraint_residuals

SCENES = ["particle", "skate", "robot", "mp-particles"]


@pytest.mark.parametrize("name", builtin_method_names(3))
@pytest.mark.parametrize("scn", SCENES)
def test_constraint_float64(name, scn, exact_method, scene):
    k, secant, eps = constraint_residuals(scene(scn), exact_method(name), n_steps=5, dps=None)
    assert k <= 1e3 * eps, k
    if name != "euler-i":   # Euler I with constant M: P_1 = p1 forces V_1 = v1, the secant IS v1
        assert secant > 1e-6, secant


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-3", "euler-i"])
@pytest.mark.parametrize("scn", ["skate", "robot"])
def test_constraint_mpmath(name, scn, exact_method, scene):
    k, secant, eps = constraint_residuals(scene(scn), exact_method(name), n_steps=3, dps=30)
    assert k <= 1e3 * eps, k
    assert (secant > 1e-6) == (name != "euler-i"), secant


def test_constraint_in_bvp(exact_method, scene):
    """The boundary-value solve also satisfies (21f) at t1, also off C_d."""
    sc = scene("skate")
    tab = exact_method("gauss-2")
    bk = Backend(40)
    with bk.context():
        t0, q0, v0 = sc.initial(40)
        t1, q1, xg = base_point(sc.system, tab, t0, q0, v0, "0.1", 40)
        q1 = q1 + bk.array(["1e-3", "-1e-3", "1e-3"])
        r = discrete_lagrangian(sc.system, tab, bk.scalar(t0), bk.array(q0), t1, q1, dps=40, x_guess=xg)
        assert bk.norm_inf(sc.system.constraint(bk, t1, q1, r.v1)) < 1e-35
        # ... while v0 is then inconsistent (the BVP does not impose k at t0)
        assert bk.norm_inf(sc.system.constraint(bk, t0, bk.array(q0), r.v0)) > 1e-6


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", builtin_method_names(6))
@pytest.mark.parametrize("scn", SCENES)
def test_constraint_mpmath_exhaustive(name, scn, scene):
    from ldaspark.core.families import get_method
    k, secant, eps = constraint_residuals(scene(scn), get_method(name), n_steps=5, dps=30)
    assert k <= 1e3 * eps
