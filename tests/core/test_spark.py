"""The SPARK step (21): acceptance criteria of the solver core."""
import mpmath
import numpy as np
import pytest
import sympy

from ldaspark.core.errors import InconsistentInitialDataError, InputError, SingularSaddleError
from ldaspark.models.scenes import PAPER_SCENES, get_scene
from ldaspark.core.spark import SparkMethod, integrate
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.families import builtin_method_names, gauss, get_method


def test_skate_gauss2_error_and_constraint():
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    sol = integrate(sc.system, gauss(2), t0, q0, v0, 0.05, t_end=2.0)
    qe, ve, _ = sc.exact_solution(2.0)
    err = np.abs(sol.q[-1] - qe).max()
    assert 1e-8 < err < 1e-7          # "a few 1e-8"
    assert np.abs(sol.constraint).max() < 1e-15


def test_skate_lobatto3_order4():
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    qe, _, _ = sc.exact_solution(2.0)
    errs = [np.abs(integrate(sc.system, get_method("lobatto-iiia-iiib-3"), t0, q0, v0, h, t_end=2.0).q[-1] - qe).max()
            for h in (0.1, 0.05)]
    assert abs(np.log2(errs[0] / errs[1]) - 4) < 0.3


def test_skate_order_check_has_teeth():
    """A perturbed A_hat degrades the order: the same order measurement must notice."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    qe, _, _ = sc.exact_solution(2.0)
    bad = get_method("lobatto-iiia-iiib-3").with_entry("A_hat", 1, 0, 0.05)
    errs = [np.abs(integrate(sc.system, bad, t0, q0, v0, h, t_end=2.0).q[-1] - qe).max() for h in (0.1, 0.05)]
    assert abs(np.log2(errs[0] / errs[1]) - 4) > 0.5


@pytest.mark.parametrize("scene", PAPER_SCENES + ("pendulum", "rolling-disk"))
@pytest.mark.parametrize("method", builtin_method_names(3))
def test_constraint_at_solver_tolerance_every_step(scene, method):
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    sol = integrate(sc.system, get_method(method), t0, q0, v0, 0.1, n_steps=10)
    scale = 1 + np.abs(sol.v).max()
    assert np.abs(sol.constraint).max() <= 1e-13 * scale
    assert np.all(np.isfinite(sol.q)) and sol.stats["steps"] == 10


def test_float64_and_mpmath_agree_on_one_step():
    sc = get_scene("particle")
    for name in ("gauss-2", "lobatto-iiia-iiib-iiid-3"):
        tab = get_method(name)
        t0, q0, v0 = sc.initial()
        rf = SparkMethod(sc.system, tab).step(t0, np.array(q0), np.array(v0), 0.1)
        t0m, q0m, v0m = sc.initial(30)
        mm = SparkMethod(sc.system, tab, dps=30)
        with mpmath.workdps(30):
            rm = mm.step(t0m, np.array(q0m, dtype=object), np.array(v0m, dtype=object), mpmath.mpf("0.1"))
        for a, b in ((rf.q1, rm.q1), (rf.v1, rm.v1), (rf.Psi, rm.Psi)):
            d = max(abs(float(x) - y) for x, y in zip(np.asarray(b).reshape(-1), np.asarray(a).reshape(-1)))
            assert d < 1e-14
        assert rm.residual < 1e-28


def test_mpmath_constraint_at_working_precision():
    sc = get_scene("robot")
    t0, q0, v0 = sc.initial(40)
    sol = integrate(sc.system, gauss(2), t0, q0, v0, "0.1", n_steps=3, dps=40)
    assert max(abs(x) for x in sol.constraint.reshape(-1)) < mpmath.mpf(10) ** -37


def test_newton_counters_and_simplified_newton():
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial()
    full = integrate(sc.system, gauss(3), t0, q0, v0, 0.1, n_steps=20, newton="full")
    simp = integrate(sc.system, gauss(3), t0, q0, v0, 0.1, n_steps=20, newton="simplified")
    auto = integrate(sc.system, gauss(3), t0, q0, v0, 0.1, n_steps=20, newton="auto")
    assert np.abs(full.q - simp.q).max() < 1e-12
    assert simp.stats["nlu"] == 20 and full.stats["nlu"] == full.stats["newton_iterations"]
    assert simp.stats["newton_iterations"] >= full.stats["newton_iterations"]
    # simplified Newton, switching to full on slow contraction: same q, fewer LUs
    assert np.abs(full.q - auto.q).max() < 1e-12
    assert 20 <= auto.stats["nlu"] < full.stats["nlu"]


def test_general_lagrangian_time_dependent_nonquadratic():
    """L nonlinear in v and time dependent, k nonlinear in v: the generic path must converge
    at order 2s against a reference from a different (higher-order) method."""
    t = sympy.Symbol("t")
    q = sympy.symbols("x y z")
    v = sympy.symbols("u w r")
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 \
        + v[0] ** 4 / 12 - (1 + sympy.sin(t) / 4) * (q[0] ** 2 + q[1] ** 2) / 2
    k = [v[2] - q[1] * v[0] - v[1] ** 3 / 10]
    sysm = LagrangianSystem(L, k, q, v, t=t, name="general")
    q0 = [1.0, 0.0, 0.0]
    v0 = [0.0, 0.5, 0.5 ** 3 / 10]
    ref = integrate(sysm, gauss(4), 0.0, q0, v0, 0.01, t_end=1.0).q[-1]
    errs = [np.abs(integrate(sysm, gauss(2), 0.0, q0, v0, h, t_end=1.0).q[-1] - ref).max() for h in (0.1, 0.05)]
    assert abs(np.log2(errs[0] / errs[1]) - 4) < 0.3


def test_energy_expression_is_8():
    sc = get_scene("particle")
    s = sc.system
    assert sympy.simplify(s.energy_expr - (sum(x ** 2 for x in s.v) / 2 + s.q[0] ** 2 + s.q[1] ** 2)) == 0


def test_inconsistent_initial_data_and_projection():
    sc = get_scene("particle")
    with pytest.raises(InconsistentInitialDataError, match="k\\(t0, q0, v0\\)"):
        integrate(sc.system, gauss(1), 0.0, [1.0, 0.5, 0.0], [1.0, 1.0, 0.0], 0.1, n_steps=2)
    sol = integrate(sc.system, gauss(1), 0.0, [1.0, 0.5, 0.0], [1.0, 1.0, 0.0], 0.1, n_steps=2, project=True)
    assert np.abs(sol.constraint).max() < 1e-14


def test_singular_saddle_matrix():
    q = sympy.symbols("a b c")
    v = sympy.symbols("u w r")
    L = (v[0] ** 2 + v[1] ** 2) / 2 - q[0] ** 2   # L_vv singular in the v3 direction, K = (1, 0, 0)
    sysm = LagrangianSystem(L, [v[0]], q, v)
    with pytest.raises(SingularSaddleError):
        integrate(sysm, gauss(1), 0.0, [0, 0, 0], [0, 1, 0], 0.1, n_steps=1)


def test_bad_step_and_span():
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    with pytest.raises(InputError):
        integrate(sc.system, gauss(1), t0, q0, v0, 0.0, t_end=1.0)
    with pytest.raises(InputError, match="multiple"):
        integrate(sc.system, gauss(1), t0, q0, v0, 0.3, t_end=1.0)
    with pytest.raises(InputError, match="NaN"):
        integrate(sc.system, gauss(1), t0, [float("nan"), 0, 0], v0, 0.1, n_steps=1)
