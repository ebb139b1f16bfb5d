"""Definition 1 along trajectories: (15a) and (15b) at every interior point k = 1..N-1 of an IVP
trajectory (N = 10 steps, h = 0.1) of symmetric and non-symmetric SPARK methods.

D2 L_d and D4 L_d are central differences (Richardson, delta = 1e-12) of the boundary-value
solve at 50 digits; f_d^+- are Theorem 1's formulas. (15a) <= 1e-25 relative to |p_k|;
(15b) <= 1e-40. Controls: a (22b)-breaking tableau (A_hat perturbed) fails (15a); the
force-free sum D4 L_d + D2 L_d (a variational integrator's equation) fails; c with the secant
velocity in place of u fails (except Euler I, where V_1 = v_1 makes the secant exact).
Default cost ~10 s; all built-in methods on all ledger scenes behind --exhaustive."""
import pytest

from ldaspark.core.families import builtin_method_names, get_method
from ldaspark.lab.theory.definition1 import definition1_residuals
from ldaspark.lab.claims.ledger import negative_controls

TOL_15A = 1e-25
TOL_15B = 1e-40
NEG = 1e-6


def _run(scene, tab, dps=30, n_steps=10):
    t0, q0, v0 = scene.initial(60)
    return definition1_residuals(scene.system, tab, t0, q0, v0, "0.1", n_steps=n_steps, dps=dps)


@pytest.mark.parametrize("name,scn", [("gauss-2", "particle"),             # symmetric, well-posed
                                      ("lobatto-iiia-iiib-2", "particle"),  # symmetric, gauge-deficient
                                      ("euler-ii", "particle")])          # not symmetric
def test_15a_15b_along_trajectory(name, scn, exact_method, scene):
    r = _run(scene(scn), exact_method(name))
    assert r["15a"] < TOL_15A, r
    assert r["15b"] < TOL_15B, r
    assert r["15a_without_forces"] > NEG, r         # the discrete forces are needed
    assert r["15b_secant"] > NEG, r                 # u = v1 of the solve, not the secant


@pytest.mark.parametrize("system", ["nonlinear-k", pytest.param("time-L", marks=pytest.mark.exhaustive)])
def test_15a_15b_time_dependent_L_and_nonlinear_k(system, exact_method):
    """Assumption (2) (k affine in v) is not needed, nor an autonomous L: Euler II on the test
    systems of section 2.2 (L(t, q, v) and k = v3 - q2 v1 + v1^2/4)."""
    from ldaspark.lab.theory.energy_balance import energy_system
    sysm, q0, v0 = energy_system(system)
    r = definition1_residuals(sysm, exact_method("euler-ii"), 0, q0, v0, "0.1", n_steps=10, dps=30)
    assert r["15a"] < TOL_15A and r["15b"] < TOL_15B, r
    assert r["15a_without_forces"] > NEG, r


def test_15a_fails_for_22b_breaking_tableau(scene):
    tab, intended = negative_controls()[0]           # Gauss-2 with A_hat[0, 1] += 1/10
    assert intended["22b"] == "fail"
    r = _run(scene("particle"), tab, dps=20, n_steps=3)   # a control needs only to fail
    assert r["15a"] > NEG, r
    assert r["15b"] < 1e-30, r                       # the constraint still holds: (15b) is not the point


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", builtin_method_names(3))
@pytest.mark.parametrize("scn", ["particle", "skate", "robot", "mp-particles-nh", "rolling-disk"])
def test_15_exhaustive(name, scn, scene):
    r = _run(scene(scn), get_method(name, exact=True))
    assert r["15a"] < TOL_15A and r["15b"] < TOL_15B, r


def inconsistent_start(scene, dv="1/10"):
    """The scene's data with v0[0] shifted by ``dv``: off C_d, k(t0, q0, v0) != 0 (on C_d the constraint is 0 at both end points of every step, so a (15b) evaluated at the
    left end point instead of the right one is invisible)."""
    import mpmath
    t0, q0, v0 = scene.initial(60)
    v0 = list(v0)
    v0[0] = v0[0] + mpmath.mpf(dv)
    return t0, q0, v0


def test_15b_is_the_right_end_point_off_C_d(exact_method, scene):
    """Gauss-2 on the rheonomic skate (L and k depend on t) from inconsistent data: each step
    imposes k(t_{k+1}, q_{k+1}, v_{k+1}) = 0 by (21f), so (15b) holds (measured 7e-43), while c at
    the left end point is k(t0, q0, v0) != 0 on the first step (control, > 1e-3). (15a) holds
    off C_d too (3e-22 at 20 digits: tol 1e-15 leaves 5 digits for the finite differences)."""
    sc = scene("rheonomic-skate")
    t0, q0, v0 = inconsistent_start(sc)
    r = definition1_residuals(sc.system, exact_method("gauss-2"), t0, q0, v0, "0.1", n_steps=3, dps=20)
    assert r["15b"] < 1e-30, r
    assert r["15b_left_end"] > 1e-3, r
    assert r["15a"] < 1e-15 and r["15a_without_forces"] > NEG, r
