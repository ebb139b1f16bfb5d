"""Bad input to the library API: every user error is an LdasparkError subclass with a
message that names the problem, raised before any step is taken, and no NaN is ever returned."""
import math

import numpy as np
import pytest
import sympy
from hypothesis import given, settings, strategies as st

from ldaspark.core.backend import Backend
from ldaspark.core.errors import (InconsistentInitialDataError, InputError, LdasparkError, NewtonError,
                             SingularSaddleError, SystemDefinitionError)
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import SparkMethod, integrate, n_steps_for
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.families import get_method


@pytest.fixture(scope="module")
def skate():
    return get_scene("skate")


@pytest.fixture(scope="module")
def g2():
    return get_method("gauss-2")


@pytest.fixture
def no_steps(monkeypatch):
    """Fail loudly if a step is attempted: set-up errors must come before any Newton work."""
    def boom(*a, **k):
        raise AssertionError("a step was taken although the input is invalid")
    monkeypatch.setattr(SparkMethod, "step", boom)


def _sym(n):
    return list(sympy.symbols(f"q1:{n + 1}")), list(sympy.symbols(f"v1:{n + 1}"))


# --- inconsistent initial velocity -------------------------------------------------------------
def test_inconsistent_v0_error_names_residual(skate, g2, no_steps):
    t0, q0, _ = skate.initial()
    v0 = [0.0, 0.3, 1.0]          # k = cos(q3) v2 - sin(q3) v1 = 0.3
    with pytest.raises(InconsistentInitialDataError) as ei:
        integrate(skate.system, g2, t0, q0, v0, 0.1, n_steps=3)
    msg = str(ei.value)
    assert "3.000e-01" in msg and "--project" in msg and "\n" not in msg


def test_consistent_v0_passes(skate, g2):
    # negative control of the test above: the scene's own data are accepted
    t0, q0, v0 = skate.initial()
    sol = integrate(skate.system, g2, t0, q0, v0, 0.1, n_steps=2)
    assert np.all(np.isfinite(sol.q))


def test_project_opt_in_gives_consistent_closest_velocity(skate, g2):
    t0, q0, _ = skate.initial()
    v0 = np.array([0.0, 0.3, 1.0])
    sol = integrate(skate.system, g2, t0, q0, v0, 0.1, n_steps=3, project=True)
    assert np.max(np.abs(sol.constraint)) < 1e-14
    # projection in the L_vv = I metric onto {v2 = 0} (q3 = 0): v0 -> (0, 0, 1)
    assert np.allclose(sol.v[0], [0.0, 0.0, 1.0], atol=1e-15)


def test_project_mp(skate, g2):
    t0, q0, _ = skate.initial(30)
    sol = integrate(skate.system, g2, t0, q0, ["0", "0.3", "1"], "0.1", n_steps=1, dps=30, project=True)
    assert max(abs(x) for x in sol.constraint.reshape(-1)) < 1e-28


def test_inconsistency_within_tolerance_is_accepted_but_beyond_is_not(skate, g2):
    # the threshold is 1e3 eps (1 + |v|): 1e-14 passes, 1e-11 does not (teeth on both sides)
    t0, q0, _ = skate.initial()
    integrate(skate.system, g2, t0, q0, [0.0, 1e-14, 1.0], 0.1, n_steps=1)
    with pytest.raises(InconsistentInitialDataError):
        integrate(skate.system, g2, t0, q0, [0.0, 1e-11, 1.0], 0.1, n_steps=1)


# --- singular saddle matrix (4) ----------------------------------------------------------------
def _two_constraints(eps):
    q, v = _sym(3)
    L = sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + q[1] ** 2)
    k = [v[2] - q[1] * v[0], v[2] - q[1] * v[0] + eps * v[1]]
    return LagrangianSystem(L, k, q, v, name=f"rankK-{eps}")


def test_rank_deficient_K_is_a_setup_error(g2, no_steps):
    sysm = _two_constraints(0)
    with pytest.raises(SingularSaddleError, match="rank deficient"):
        integrate(sysm, g2, 0.0, [1.0, 0.5, 0.0], [0.0, 0.0, 0.0], 0.1, n_steps=2)


def test_nearly_rank_deficient_K_below_threshold_is_an_error_above_is_not(g2):
    with pytest.raises(SingularSaddleError, match="rank deficient"):
        integrate(_two_constraints(sympy.Rational(1, 10 ** 14)), g2, 0.0, [1.0, 0.5, 0.0], [0.0] * 3, 0.1,
                  n_steps=1)
    sol = integrate(_two_constraints(sympy.Rational(1, 10 ** 6)), g2, 0.0, [1.0, 0.5, 0.0], [0.0] * 3, 0.1,
                    n_steps=2)
    assert np.all(np.isfinite(sol.q))


def test_singular_Lvv_on_ker_K_is_a_setup_error(g2, no_steps):
    # L has no v2 term: L_vv is singular along e2, which lies in ker K -> (4) singular
    q, v = _sym(3)
    L = (v[0] ** 2 + v[2] ** 2) / 2 - q[0] ** 2
    sysm = LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v)
    with pytest.raises(SingularSaddleError, match=r"saddle matrix \(4\)"):
        integrate(sysm, g2, 0.0, [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.1, n_steps=2)


def test_singular_saddle_mp(g2):
    with pytest.raises(SingularSaddleError):
        integrate(_two_constraints(0), g2, 0, ["1", "0.5", "0"], ["0", "0", "0"], "0.1", n_steps=1, dps=30)


def test_singular_Lvv_with_regular_saddle_fails_in_newton_not_silently(g2):
    # Finding (report stability): (4) holds (L_vv = diag(1, 1, 0) on q2 = 0, K = (0, 0, 1)), but the
    # stage velocities V_i3 then appear only in the s-1 rows (21e), so the SPARK equations (21) are
    # singular. The user gets a NewtonError at step 0, iteration 1 -- not a set-up error, no NaN.
    # (An L without v3 at all is found when the system is built and refused at set-up.)
    q, v = _sym(3)
    L = (v[0] ** 2 + v[1] ** 2 + q[1] ** 2 * v[2] ** 2) / 2 - q[0] ** 2
    sysm = LagrangianSystem(L, [v[2]], q, v)
    assert sysm.check_saddle(Backend(), 0.0, [1.0, 0, 0], [0, 1.0, 0]) > 0.1
    with _no_warnings():
        with pytest.raises(NewtonError, match="singular") as ei:
            integrate(sysm, g2, 0.0, [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1, n_steps=2)   # q2 stays 0
    assert (ei.value.step, ei.value.iterations) == (0, 1)
    # control: with a v3 term in L the same constraint integrates fine
    sysm2 = LagrangianSystem(L + v[2] ** 2 / 2, [v[2]], q, v)
    sol = integrate(sysm2, g2, 0.0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.1, n_steps=2)
    assert np.all(np.isfinite(sol.v))


class _no_warnings:
    """No warning (e.g. scipy's LinAlgWarning) may leak next to the error: the CLI prints one line."""
    def __enter__(self):
        import warnings
        self._cm = warnings.catch_warnings(record=True)
        self.log = self._cm.__enter__()
        warnings.simplefilter("always")
        return self

    def __exit__(self, *exc):
        self._cm.__exit__(None, None, None)
        assert not self.log, [str(w.message) for w in self.log]
        return False


def test_newton_tolerance_follows_the_iterate_for_near_rank_loss_K(g2):
    # Bug fixed: the Newton tolerance was relative to the starting guess (|x0| ~ 1) while
    # |Lambda| ~ h / eps = 1e5; increments stalled at eps |x| ~ 5e-12 and 50 iterations ended in
    # NewtonError. The exact (q, v) do not depend on eps (same constraint manifold).
    ref = integrate(_two_constraints(1), g2, 0.0, [1.0, 0.5, 0.0], [0.0] * 3, 0.1, n_steps=3)
    sol = integrate(_two_constraints(sympy.Rational(1, 10 ** 6)), g2, 0.0, [1.0, 0.5, 0.0], [0.0] * 3, 0.1,
                    n_steps=3)
    assert sol.stats["mean_iterations"] < 10
    assert np.max(np.abs(sol.q - ref.q)) < 1e-8


# --- Newton failure -------------------------------------------------------------------------
def test_newton_iteration_cap_error_names_step_time_residual_iterations(skate, g2):
    t0, q0, v0 = skate.initial()
    m = SparkMethod(skate.system, g2, max_iter=1)
    with pytest.raises(NewtonError) as ei:
        m.step(0.7, np.array(q0), np.array(v0), 0.1, step_index=7)
    e = ei.value
    assert (e.step, e.time, e.iterations) == (7, 0.7, 1)
    assert math.isfinite(e.residual) and e.residual > 0
    msg = str(e)
    assert "step 7" in msg and "t = 0.7" in msg and "after 1 iterations" in msg and f"{e.residual:.3e}" in msg


@pytest.mark.parametrize("kw", [dict(newton="simplified"), dict(dps=20)])
def test_newton_divergence_simplified_and_mp(kw):
    # the same failure through simplified Newton (diverges to ~1e32) and in mpmath: named, finite
    sc = get_scene("robot")
    t0, q0, v0 = sc.initial(kw.get("dps"))
    with pytest.raises(NewtonError) as ei:
        integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "4" if "dps" in kw else 4.0, n_steps=2, **kw)
    e = ei.value
    assert (e.step, e.time, e.iterations) == (0, 0.0, 50) and e.residual > 1
    assert "step 0" in str(e) and "after 50 iterations" in str(e)


def test_newton_divergence_robot_large_step():
    # measured: gauss-2 on the robot converges up to h = 2 and fails at h = 4 (report stability)
    sc = get_scene("robot")
    t0, q0, v0 = sc.initial()
    tab = get_method("gauss-2")
    with pytest.raises(NewtonError) as ei:
        integrate(sc.system, tab, t0, q0, v0, 4.0, n_steps=3)
    assert ei.value.step == 0 and ei.value.iterations >= 1 and ei.value.time == 0.0
    sol = integrate(sc.system, tab, t0, q0, v0, 2.0, n_steps=1)   # negative control
    assert np.all(np.isfinite(sol.q))


def test_newton_error_mid_run_reports_that_step(skate, g2, monkeypatch):
    # a failure at step 3 must name step 3 and its time, not step 0
    t0, q0, v0 = skate.initial()
    orig = SparkMethod.step

    def step(self, t0, q0, v0, h, x0=None, step_index=0):
        if step_index == 3:
            self.max_iter = 1
        return orig(self, t0, q0, v0, h, x0=x0, step_index=step_index)
    monkeypatch.setattr(SparkMethod, "step", step)
    with pytest.raises(NewtonError) as ei:
        integrate(skate.system, g2, t0, q0, v0, 0.25, n_steps=6)
    assert ei.value.step == 3 and ei.value.time == pytest.approx(0.75)


@pytest.mark.parametrize("dps", [None, 20])
def test_domain_error_in_L_is_newton_error_not_traceback(g2, dps):
    # Bug fixed: sqrt(1 - q1) evaluated at q1 > 1 raised ValueError (math) / TypeError (mpmath
    # returns mpc) through integrate; now a NewtonError naming the step and the cause.
    q, v = _sym(3)
    L = sum(x ** 2 for x in v) / 2 + sympy.sqrt(1 - q[0])
    sysm = LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v)
    with pytest.raises(NewtonError, match="evaluating L or k") as ei:
        integrate(sysm, g2, 0, [0, 0, 0], [3, 0, 0], 0.5 if dps is None else "0.5", n_steps=4, dps=dps)
    assert ei.value.step is not None and ei.value.iterations >= 1


# --- NaN / inf / zero step / dimensions -----------------------------------------------------------
@pytest.mark.parametrize("kw", [
    dict(q0=[np.nan, 0, 0]), dict(v0=[0, 0, np.inf]), dict(h=np.nan), dict(h=np.inf), dict(h=-np.inf),
    dict(t0=np.nan), dict(t0=np.inf),
])
def test_nan_inf_inputs(skate, g2, no_steps, kw):
    args = dict(t0=0.0, q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 1.0], h=0.1)
    args.update(kw)
    with pytest.raises(InputError):
        integrate(skate.system, g2, args["t0"], args["q0"], args["v0"], args["h"], n_steps=2)


@pytest.mark.parametrize("dps", [None, 30])
def test_zero_step_with_n_steps(skate, g2, no_steps, dps):
    # before the fix: float64 returned psi = NaN (Lambda / 0), mpmath raised ZeroDivisionError
    t0, q0, v0 = skate.initial(dps)
    with pytest.raises(InputError, match="nonzero"):
        integrate(skate.system, g2, t0, q0, v0, 0.0 if dps is None else "0", n_steps=2, dps=dps)


def test_zero_step_with_t_end(skate, g2, no_steps):
    with pytest.raises(InputError, match="nonzero"):
        integrate(skate.system, g2, 0.0, [0, 0, 0], [0, 0, 1], 0.0, t_end=1.0)


def test_mp_nan_string(skate, g2, no_steps):
    with pytest.raises(InputError):
        integrate(skate.system, g2, 0, ["nan", "0", "0"], ["0", "0", "1"], "0.1", n_steps=1, dps=20)


@pytest.mark.parametrize("t_end, match", [(np.inf, "finite"), (np.nan, "finite"), (0.33, "multiple"),
                                          (-1.0, "not reached")])
def test_bad_t_end(t_end, match):
    with pytest.raises(InputError, match=match):
        n_steps_for(0.0, t_end, 0.1)


def test_absurd_step_count_is_rejected_not_run(skate, g2, no_steps):
    # h = 1e-300 to t_end = 1 would be 1e300 steps: before the fix the CLI hung
    with pytest.raises(InputError, match="steps"):
        integrate(skate.system, g2, 0.0, [0, 0, 0], [0, 0, 1], 1e-300, t_end=1.0)


@pytest.mark.parametrize("q0, v0", [
    ([0.0, 0.0], [0.0, 0.0, 1.0]), ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]), ([[0.0, 0.0, 0.0]], [0.0, 0.0, 1.0]),
    (0.0, [0.0, 0.0, 1.0]), ([["a"], 0, 0], [0.0, 0.0, 1.0]), (["a", 0, 0], [0.0, 0.0, 1.0]),
])
def test_dimension_and_type_mismatch(skate, g2, no_steps, q0, v0):
    with pytest.raises(InputError):
        integrate(skate.system, g2, 0.0, q0, v0, 0.1, n_steps=2)


@pytest.mark.parametrize("n_steps", [0, -3, 2.5, True, "3"])
def test_bad_n_steps(skate, g2, no_steps, n_steps):
    with pytest.raises(InputError):
        integrate(skate.system, g2, 0.0, [0, 0, 0], [0, 0, 1], 0.1, n_steps=n_steps)


def test_both_t_end_and_n_steps_is_an_error(skate, g2, no_steps):
    with pytest.raises(InputError, match="exactly one"):
        integrate(skate.system, g2, 0.0, [0, 0, 0], [0, 0, 1], 0.1, t_end=1.0, n_steps=5)


@pytest.mark.parametrize("tol", [-1.0, 0.0, float("nan")])
def test_bad_tolerance(skate, g2, tol):
    # before the fix: tol = nan ran 50 Newton iterations and tol < 0 blamed the initial data
    with pytest.raises(InputError, match="tolerance"):
        integrate(skate.system, g2, 0.0, [0, 0, 0], [0, 0, 1], 0.1, n_steps=1, tol=tol)


def test_system_definition_mismatches():
    q, v = _sym(3)
    L = sum(x ** 2 for x in v) / 2
    with pytest.raises(SystemDefinitionError, match="symbols"):
        LagrangianSystem(L, [v[2] - sympy.Symbol("a") * v[0]], q, v)         # k uses a foreign symbol
    with pytest.raises(SystemDefinitionError, match="m < n"):
        LagrangianSystem(L, [v[0], v[1], v[2]], q, v)                        # m = n
    with pytest.raises(SystemDefinitionError):
        LagrangianSystem(L, [v[2]], q, v[:2])                                 # len(q) != len(v)


@settings(max_examples=8)
@given(st.integers(0, 2), st.integers(0, 1), st.sampled_from([np.nan, np.inf, -np.inf]))
def test_any_nonfinite_entry_is_rejected(i, which, bad):
    sc = get_scene("skate")
    q0, v0 = [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]
    (q0 if which == 0 else v0)[i] = bad
    with pytest.raises(InputError):
        integrate(sc.system, get_method("gauss-1"), 0.0, q0, v0, 0.1, n_steps=1)


@pytest.mark.parametrize("h", [1e-300, 5e-324, 1e3])
def test_extreme_but_valid_steps_return_finite_values(skate, g2, h):
    # no NaN is ever returned: tiny steps (Psi = Lambda / h) and huge steps stay finite
    t0, q0, v0 = skate.initial()
    sol = integrate(skate.system, g2, t0, q0, v0, h, n_steps=2)
    for a in (sol.q, sol.v, sol.psi, sol.energy, sol.constraint):
        assert np.all(np.isfinite(a))


def test_all_errors_are_ldaspark_errors():
    for cls in (InputError, NewtonError, SingularSaddleError, InconsistentInitialDataError, SystemDefinitionError):
        assert issubclass(cls, LdasparkError)


# --- the compiled fast path (ldaspark.compiled.fast): the same set-up checks and error detail -----------
def test_fast_path_rejects_inconsistent_v0():
    from ldaspark.compiled.fast import fast_integrate
    with pytest.raises(InconsistentInitialDataError):
        fast_integrate(get_scene("skate"), "gauss-2", t0=0.0, q0=[0, 0, 0], v0=[0, 0.3, 1], h=0.1, n_steps=3)


@pytest.mark.exhaustive   # compiles a new system (~15 s)
def test_fast_path_rank_deficient_K_is_setup_error():
    from ldaspark.compiled.fast import fast_integrate
    with pytest.raises(SingularSaddleError):
        fast_integrate(_two_constraints(0), "gauss-2", t0=0.0, q0=[1, 0.5, 0], v0=[0, 0, 0], h=0.1, n_steps=3)


@pytest.mark.exhaustive   # compiles the robot (~15 s when the numba cache is cold)
def test_fast_path_newton_error_names_residual_and_iterations():
    from ldaspark.compiled.fast import fast_integrate
    with pytest.raises(NewtonError) as ei:
        fast_integrate(get_scene("robot"), "gauss-2", h=4.0, n_steps=3)
    assert ei.value.residual is not None and ei.value.iterations is not None
