"""The Newton stopping rule at the extremes.

Compiled engine: the limit is the round-off of the stage values, tol (|x| + |v0|), not a multiple
of h (the rule before stopped 30000-step runs of the skate at h = 1e-5 at step 25808); RADAU5's
rate test; fresh matrix, full Newton and the generic full-Newton step as fallbacks. Whole runs at
h = 1e-4 .. 1e-7 on the paper scenes finish (a few here, the full grid with --exhaustive).
Extreme precision: eps from mpmath (dps >= 324 divided by a float eps of 0 before), dps = 400
and 2000 work.
"""
import math

import mpmath
import numpy as np
import pytest
import sympy

from ldaspark.compiled.fast import compile_system, fast_integrate, run_compiled
from ldaspark.compiled.newton import NOISE_FACTOR, RATE_KAPPA, newton_status
from ldaspark.core.backend import Backend
from ldaspark.core.errors import NewtonError
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import integrate

EPS = 2.0 ** -52
TOL = 8 * EPS                      # the compiled kernels' default tol


# --- the rule itself (the numba function, called from Python) --------------------------------
@pytest.mark.parametrize("c", [1e-12, 1e-4, 1.0, 1e6])
def test_stopping_rule_is_invariant_under_the_scale_of_the_state(c):
    """Same verdicts when every magnitude (|dx|, |x|, |v0|) is scaled by c: no absolute term."""
    lim = TOL * (1e-5 + 1.0)
    cases = [(0.5 * lim, -1.0, -1.0, True), (5 * lim, 10 * lim, -1.0, False),     # plain test / no rate yet
             (5 * lim, 1e4 * lim, 1e-3, False), (50 * lim, 60 * lim, 0.9, True),  # rate test / noise floor
             (50 * lim, 60 * lim, 0.9, False)]
    got = [newton_status(dn * c, prev * c if prev > 0 else prev, th, 1e-5 * c, 1.0 * c, TOL, ex)
           for dn, prev, th, ex in cases]
    assert got == [1, 0, 1, 1, 0]


def test_rate_test_needs_two_rates():
    """RADAU5's theta = sqrt(theta_k theta_k-1): a sudden drop of |dx| onto a plateau far above
    round-off (one small theta_k) is not convergence; with a second small rate it is."""
    lim = TOL * 1.0
    dn, prev = 2 * lim, 1e6 * lim               # theta_k = 2e-6, estimate ~ 4e-6 lim
    assert newton_status(dn, prev, -1.0, 0.0, 1.0, TOL, True) == 0
    assert newton_status(dn, prev, 1e-3, 0.0, 1.0, TOL, True) == 1
    # two-sided around RATE_KAPPA: estimate theta / (1 - theta) dn just above / below kappa lim
    th = 0.05                                   # both rates; theta / (1 - theta) = 1/19
    for f, want in ((1.01, 0), (0.99, 1)):
        dn = f * RATE_KAPPA * lim * 19          # ~1.9 lim: above the plain limit
        assert dn > lim and newton_status(dn, dn / th, th, 0.0, 1.0, TOL, False) == want


def test_noise_floor_needs_an_exact_matrix_and_a_bound():
    lim = TOL
    assert newton_status(0.9 * NOISE_FACTOR * lim, NOISE_FACTOR * lim, 0.9, 0.0, 1.0, TOL, True) == 1
    assert newton_status(1.1 * NOISE_FACTOR * lim, NOISE_FACTOR * lim, 0.9, 0.0, 1.0, TOL, True) == 0
    assert newton_status(0.9 * NOISE_FACTOR * lim, NOISE_FACTOR * lim, 0.9, 0.0, 1.0, TOL, False) == 0
    assert newton_status(float("nan"), 1.0, 0.9, 0.0, 1.0, TOL, True) == -1


# --- whole runs at tiny h ---------------------------------------------------------------------
def _exact_skate(t):
    sc = get_scene("skate")
    ex = sc.exact
    f = lambda es: [float(e.subs(ex["t"], sympy.Rational(str(t)))) for e in es]   # noqa: E731
    return np.array(f(ex["q"])), np.array(f(ex["v"]))


@pytest.mark.parametrize("method,h,n", [("gauss-2", 1e-5, 30_000),                 # the reproduction
                                        ("lobatto-iiia-iiib-2", 1e-6, 100_000),    # semi-implicit kernel
                                        ("gauss-1", 1e-7, 100_000)])
def test_skate_whole_run_at_tiny_h_finishes_at_roundoff(method, h, n):
    """Before: "Newton did not converge at step 25808" (gauss-2, h = 1e-5), 88513 (h = 1e-6).
    The error against the closed form is one-sided by nature (a bound): truncation C h^p with
    h^2 <= 1e-10 times t^3 ~ 1e-3 below 1e-13 even for gauss-1, plus round-off growing at
    most like N eps |v| per step summed (linear growth, section 3 of reports/stability.md):
    bound 4 N eps."""
    sol = fast_integrate(get_scene("skate"), method, h=h, n_steps=n, every=n)
    assert sol.stats["path"] == "fast" and sol.stats["steps"] == n
    qe, ve = _exact_skate(round(n * h, 12))
    err = max(np.abs(sol.q[-1] - qe).max(), np.abs(sol.v[-1] - ve).max())
    assert err <= 4 * n * EPS + 1e-13, err
    assert np.abs(sol.constraint).max() <= 16 * EPS


def test_limit_below_the_roundoff_of_the_stage_values_fails_with_a_named_error():
    """Negative control: a limit below the rounding of V_i = v0 + Z_i (tol = 1e-24, the size of
    the h-scaled limit at h = 1e-7) cannot be met: after simplified, fresh-matrix and full Newton
    the kernel reports step, time, residual and iterations (and the generic step, given the same
    tol, fails as well)."""
    sc = get_scene("skate")
    cs = compile_system(sc.system)
    t0, q0, v0 = sc.initial()
    with pytest.raises(NewtonError) as ei:
        run_compiled(cs, "gauss-2", t0, q0, v0, 1e-5, 30_000, 30_000, tol=1e-24)
    e = ei.value
    assert e.step is not None and 0 <= e.step < 30_000 and math.isclose(e.time, e.step * 1e-5, rel_tol=1e-12)
    assert e.iterations > 50 and math.isfinite(e.residual)
    msg = str(e)
    assert f"step {e.step}," in msg and "residual" in msg and f"after {e.iterations} iterations" in msg


# --- the fallback chain -----------------------------------------------------------------------
@pytest.mark.parametrize("linear_solver", ["dense", "sparse"])
def test_full_newton_fallback_in_the_kernel(linear_solver):
    """mp-particles, gauss-1, one step of h = 4 (near the Newton limit): simplified Newton from
    the predictor fails, the kernel's full Newton from the generic starting guess converges to the
    generic full-Newton solution at 30 digits (measured 2e-15 to 8e-15 with either linear solver;
    tolerance 1e-12 = a few thousand eps |q|). One step: the second step at h = 4 is where full
    Newton itself stops converging in float64 with some BLAS kernels (OPENBLAS_CORETYPE=Prescott)
    and at 30 digits, a reference no test can rest on; the 30-digit reference uses no BLAS."""
    sc = get_scene("mp-particles")
    t0, q0, v0 = sc.initial()
    sol = run_compiled(compile_system(sc.system), "gauss-1", t0, q0, v0, 4.0, 1, kernel="spark",
                       linear_solver=linear_solver)
    assert sol.stats["full_newton_steps"] >= 1 and sol.stats["linear_solver"] == linear_solver
    ref = integrate(sc.system, get_method("gauss-1"), t0, q0, v0, 4.0, n_steps=1, newton="full", dps=30)
    assert np.abs(sol.q[-1] - np.asarray(ref.q, float)[-1]).max() <= 1e-12


@pytest.mark.parametrize("fail_at,every", [(5, 3), (0, 1), (6, 3)])
def test_generic_step_is_the_last_fallback(monkeypatch, fail_at, every):
    """When every Newton of the kernel fails at a step (simulated: the kernel's first run
    reports a failure at step ``fail_at``; the real cases are chaotic full-Newton iterations near
    the Newton limit, e.g. robot lobatto-iiia-iiib-3 h = 4, whose outcome depends on the rounding
    of each iterate, so no test can rest on them), fast_integrate takes that step with the
    generic full Newton and goes on: the same run as without the failure to round-off (measured
    ~1e-16; tolerance 1e-13 = a few hundred eps over 20 steps), samples on the same grid."""
    from ldaspark.compiled import fast, runner
    sc = get_scene("skate")
    ref = fast_integrate(sc, "gauss-2", h=0.1, n_steps=20, every=every)
    real = runner._run_checked        # what fast_integrate and run_compiled call
    calls = []

    def failing(cs, method, start, grid, opts):
        calls.append(grid[1])
        if len(calls) == 1:
            raise NewtonError("simulated", step=fail_at, time=start[0] + fail_at * grid[0])
        return real(cs, method, start, grid, opts)
    monkeypatch.setattr(runner, "_run_checked", failing)
    sol = fast_integrate(sc, "gauss-2", h=0.1, n_steps=20, every=every)
    assert sol.stats["generic_steps"] == 1 and sol.stats["steps"] == 20
    # the same grid; a segment's times are t_start + k h: a few ulps from t0 + (start + k) h
    assert sol.t.shape == ref.t.shape and np.abs(sol.t - ref.t).max() <= 8 * EPS * abs(ref.t[-1])
    assert np.abs(sol.q - ref.q).max() <= 1e-13 and np.abs(sol.energy - ref.energy).max() <= 1e-13
    # negative control: without the rescue (run_compiled alone) the failure is raised
    with pytest.raises(NewtonError, match="simulated"):
        calls.clear()
        fast.run_compiled(compile_system(sc.system), "gauss-2", 0.0, [0, 0, 0], [0, 0, 1], 0.1, 20)


def test_the_rescued_step_counts_its_evaluations(monkeypatch):
    """The generic full-Newton step that rescues a kernel failure (``compiled.rescue``) evaluates
    the stage functions and factors Newton matrices like any step: the run's nfev, njev and nlu
    are the kernel segments' plus the rescued step's. Each full-Newton iteration of the generic
    step evaluates one residual (s + 1 points, ``SparkMethod``'s count) and assembles and factors
    one matrix, so with the generic iterations (the run's newton_iterations minus the segments')
    the counters exceed the segments' by at least that much (before: exactly the segments',
    the rescued step's work left out)."""
    from ldaspark.compiled import runner
    sc = get_scene("skate")
    real = runner._run_checked
    segments = []

    def failing(cs, method, start, grid, opts):
        if not segments:
            segments.append(None)
            raise NewtonError("simulated", step=5, time=start[0] + 5 * grid[0])
        out = real(cs, method, start, grid, opts)
        segments.append(out.stats)
        return out
    monkeypatch.setattr(runner, "_run_checked", failing)
    sol = fast_integrate(sc, "gauss-2", h=0.1, n_steps=20)
    assert sol.stats["generic_steps"] == 1 and sol.stats["steps"] == 20
    kern = {c: sum(st[c] for st in segments[1:]) for c in ("nfev", "njev", "nlu", "newton_iterations")}
    it = sol.stats["newton_iterations"] - kern["newton_iterations"]
    assert it >= 1, sol.stats
    s = get_method("gauss-2").s
    assert sol.stats["nfev"] >= kern["nfev"] + (s + 1) * it, (sol.stats, kern)
    assert sol.stats["njev"] >= kern["njev"] + it and sol.stats["nlu"] >= kern["nlu"] + it, (sol.stats, kern)


# --- extreme precision ------------------------------------------------------------------------
def test_eps_follows_the_working_precision_beyond_float_range():
    bk = Backend(400)
    assert isinstance(bk.eps, mpmath.mpf) and mpmath.mpf("0.99e-400") < bk.eps < mpmath.mpf("1.01e-400")
    assert isinstance(Backend(30).eps, float) and math.isclose(Backend(30).eps, 1e-30, rel_tol=1e-15)
    with bk.context():
        x = np.array([mpmath.mpf("3e-350"), mpmath.mpf("-4e-350")], dtype=object)
        n = bk.norm_inf(x)
    assert mpmath.mpf("3.99e-350") < n < mpmath.mpf("4.01e-350")   # float64 would round it to 0
    assert Backend(None).eps == EPS and Backend(30).norm_inf(np.array([0.5, -2.0])) == 2.0


@pytest.mark.parametrize("newton", ["auto", "full", "simplified", "mixed"])
def test_dps_400_runs_and_agrees_with_dps_440(newton):
    """Before: ZeroDivisionError at dps >= 324 (eps as a float underflowed to 0); simplified
    Newton stopped at "residual 3.4e-177 after 50 iterations" (one matrix gains ~3.6 digits per
    iteration). Two-sided: the 400-digit run equals the 440-digit one to the Newton tolerance
    (10 eps = 1e-399) times the steps and a growth factor (measured ~1e-400; bound 1e-395), and
    differs from the float64 run by its round-off (> 0)."""
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(400)
    a = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=3, dps=400, newton=newton)
    t0, q0, v0 = sc.initial(440)
    b = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=3, dps=440, newton="full")
    with mpmath.workdps(440):
        d = max(abs(x - y) for x, y in zip(a.q[-1], b.q[-1]))
    assert d <= mpmath.mpf("1e-395")
    f64 = integrate(sc.system, get_method("gauss-2"), 0.0, [1.0, 0, 0], [0, 1.0, 0], 0.1, n_steps=3)
    assert 0 < abs(float(b.q[-1][0]) - f64.q[-1][0]) < 1e-14


def test_float_eps_at_400_digits_is_the_old_failure(monkeypatch):
    """Negative control of the previous test: with the unit round-off computed as a float (as the
    code once did: 10^-400 underflows to 0.0, and every tolerance with it) the same run
    fails (ZeroDivisionError in the Newton cost rule, or a Newton iteration that cannot stop)."""
    monkeypatch.setattr(Backend, "eps", property(
        lambda self: 2.0 ** -52 if self.dps is None else float(mpmath.mpf(10) ** (-self.dps))))
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(400)
    with pytest.raises((ZeroDivisionError, NewtonError)):
        integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=3, dps=400)


@pytest.mark.parametrize("newton", ["auto", "simplified", "mixed"])
def test_rate_test_at_1000_digits_does_not_underflow_to_float_zero(newton):
    """The rate test theta / (1 - theta) |dx| <= kappa tol_abs with |dx| a float (above float64's
    smallest normal) and theta tiny: the product underflowed to 0.0 and passed against any
    tol_abs (10^-999 here). Relativistic, gauss-2, 3 steps at 1000 digits, before: simplified
    1e-341, auto 6e-545, mixed 2e-554 off the 1040-digit run (full: 2e-1001, the digits'
    round-off). Two-sided: within 1e-995 of the 1040-digit run, and the float64 run differs from
    it by float64's round-off (> 0, < 1e-14)."""
    from ldaspark import integrate as api_integrate
    a = api_integrate("relativistic", "gauss-2", n_steps=3, h=0.1, dps=1000, newton=newton, engine="generic")
    b = api_integrate("relativistic", "gauss-2", n_steps=3, h=0.1, dps=1040, newton="full", engine="generic")
    assert a.status == 0 and b.status == 0
    with mpmath.workdps(1040):
        d = max(abs(mpmath.mpf(x) - mpmath.mpf(y)) for x, y in
                zip(list(a.q[-1]) + list(a.v[-1]), list(b.q[-1]) + list(b.v[-1])))
    assert d <= mpmath.mpf("1e-995"), mpmath.nstr(d, 3)
    f = api_integrate("relativistic", "gauss-2", n_steps=3, h=0.1, engine="generic")
    e = max(abs(float(x) - y) for x, y in zip(list(b.q[-1]) + list(b.v[-1]), list(f.q[-1]) + list(f.v[-1])))
    assert 0 < e < 1e-14


def test_dps_2000_a_few_steps():
    """dps at the upper bound of core.validate (2000): 3 steps of the skate, gauss-2, against
    the closed form: error = the method's O(h^5) local error (~1e-7 at h = 1/10), identical to the
    30-digit run to 1e-25 (the 30-digit round-off)."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial(2000)
    a = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=3, dps=2000)
    t0, q0, v0 = sc.initial(30)
    b = integrate(sc.system, get_method("gauss-2"), t0, q0, v0, "1/10", n_steps=3, dps=30)
    qe, _ = _exact_skate(0.3)
    err = float(max(abs(float(x) - y) for x, y in zip(a.q[-1], qe)))
    assert 1e-12 < err < 1e-5
    with mpmath.workdps(40):
        assert max(abs(mpmath.mpf(x) - mpmath.mpf(y)) for x, y in zip(a.q[-1], b.q[-1])) < mpmath.mpf("1e-25")


# --- the full grid (--exhaustive) -----------------------------------------------------------------
@pytest.mark.exhaustive
@pytest.mark.parametrize("scene", ["particle", "skate", "robot", "mp-particles"])
def test_every_family_up_to_3_stages_finishes_whole_runs_at_tiny_h(scene):
    """Every family with s <= 3, h = 1e-4 .. 1e-7, 1e5 steps on the compiled engine: each run
    finishes, with the constraint at round-off (|k| <= 64 eps, the largest seen 1e-15) and no step
    left to the generic engine."""
    from ldaspark.lab.reports.stability_stiff import tiny_step_grid
    rows = tiny_step_grid(100_000, scenes=(scene,))
    assert len(rows) == 36
    bad = [r for r in rows if r["outcome"] != "ok"]
    assert not bad, bad
    assert all(r["max_k"] <= 64 * EPS and r["generic_steps"] == 0 for r in rows)


@pytest.mark.exhaustive
@pytest.mark.parametrize("scene,method", [("skate", "gauss-2"), ("skate", "lobatto-iiia-iiib-2"),
                                          ("particle", "gauss-2"), ("particle", "lobatto-iiia-iiib-2")])
def test_million_steps_at_h_1e_7(scene, method):
    from ldaspark.lab.reports.stability_stiff import tiny_step_run
    r = tiny_step_run(scene, method, 1e-7, 1_000_000)
    assert r["outcome"] == "ok" and r["max_k"] <= 64 * EPS


# --- a tol the arithmetic cannot reach ---------------------------------------------------------------
def test_a_tol_below_the_unit_round_off_is_refused_by_every_engine():
    """Newton(tol=1e-25) in float64 asks for increments below one rounding of the stage values:
    before, every engine accepted it and did something else, the generic step ending at round-off
    (particle, gauss-2, h = 0.1, 10 steps: 56 iterations), the compiled Newton kernel after 744
    iterations handing 6 steps to the generic step, the quasi kernel after 843 handing 7. Now each
    entry point refuses it with an InputError naming the smallest tol the arithmetic honours, its
    unit round-off (``validate.smallest_tol``: 2^-52; 10^-dps with dps digits). Control: that
    smallest tol runs on every engine, to the default tol's numbers within the two limits' bound 2 N
    lim, lim <= 10 eps scale (the generic default; the kernels' is 8 eps)."""
    import ldaspark
    from ldaspark.core.errors import InputError
    from ldaspark.core.spark import SparkMethod
    from ldaspark.core.validate import smallest_tol
    from ldaspark.ensemble import RunSpec
    low = smallest_tol()
    assert low == EPS and smallest_tol(20) == 1e-20
    runs = (dict(engine="compiled", newton=ldaspark.Newton(kind="quasi")), dict(engine="compiled", newton="full"),
            dict(engine="generic"), dict(engine="auto"))
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial()
    n = 10
    for kw in runs:
        for tol in (1e-25, 0.5 * EPS):
            with pytest.raises(InputError, match=r"below the unit round-off of float64: the smallest tol it can honour "
                                                 r"is 2\.22045e-16") as ei:
                ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=n, tol=tol, **kw)
            assert "\n" not in str(ei.value)
        ref = ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=n, **kw)
        r = ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=n, tol=low, **kw)
        scale = max(1.0, float(np.abs(ref.q).max()), float(np.abs(ref.v).max()))
        assert r.status == 0 and np.abs(r.q - ref.q).max() <= 2 * n * 10 * EPS * scale, kw
    # the same through Newton(tol=...), with dps digits, an ensemble, the deprecated fast path, the
    # class, the step map's Jacobian
    with pytest.raises(InputError, match="the smallest tol it can honour is 2.22045e-16"):
        ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=n, newton=ldaspark.Newton(kind="quasi", tol=1e-25))
    with pytest.raises(InputError, match="of 20-digit arithmetic: the smallest tol it can honour is 1e-20"):
        ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=2, engine="generic", dps=20, tol=1e-21)
    assert ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=2, engine="generic", dps=20, tol=1e-20).status == 0
    with pytest.raises(InputError, match="RunSpec: tol = 1e-25 is below"):
        RunSpec("particle", "gauss-2", t0, [q0], [v0], 0.1, n, tol=1e-25)
    with pytest.raises(InputError, match="tol = 1e-25 is below"):
        fast_integrate(sc, "gauss-2", h=0.1, n_steps=n, tol=1e-25)
    with pytest.raises(InputError, match="tol = 1e-25 is below"):
        SparkMethod(sc.system, get_method("gauss-2"), tol=1e-25)
    assert SparkMethod(sc.system, get_method("gauss-2"), dps=30, tol=1e-25).tol == 1e-25
    with pytest.raises(InputError, match="flow_jacobian: tol = 1e-25 is below"):
        ldaspark.flow_jacobian("particle", "gauss-2", q0, v0, 0.1, tol=1e-25)
