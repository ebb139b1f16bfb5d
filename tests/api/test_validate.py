"""Every user value of ``ldaspark.integrate``, ``RunSpec`` /
``run_many`` and ``LagrangianSystem`` is checked at the API boundary (``ldaspark.core.validate``):
a wrong value is one LdasparkError naming it, before any work; a right value near the bound still
runs (the controls). Setup of the issue: x, y, z, vx, vy, vz = sympy.symbols("x y z vx vy vz")."""
import concurrent.futures
import math

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core import validate
from ldaspark.core.errors import InputError, LdasparkError, NonFiniteError, SystemDefinitionError

from run_helpers import time_bound

#: catches a hang, not the machine's speed: the first compiled run of a fresh checkout compiles the
#: kernels (a minute or more on a loaded machine)
BOUND = 300

x, y, z, vx, vy, vz = sympy.symbols("x y z vx vy vz")
L_FREE = (vx ** 2 + vy ** 2 + vz ** 2) / 2
K_SKATE = [vz - x * vy]


def skate_like(L_extra=0, q=(x, y, z), v=(vx, vy, vz), **kw):
    return ldaspark.LagrangianSystem(L_FREE + L_extra, K_SKATE, list(q), list(v), **kw)


def run(**kw):
    args = dict(t_span=(0, 0.2), h=0.05)
    args.update(kw)
    with time_bound(BOUND):
        return ldaspark.integrate(kw.pop("system", "skate"), kw.pop("method", "gauss-2"),
                                  **{k: v for k, v in args.items() if k not in ("system", "method")})


def assert_finite_result(res):
    """The property of every returned Result: finite real arrays, status >= 0 or a failure."""
    for name in ("t", "q", "v", "energy", "constraint"):
        a = np.asarray(getattr(res, name), dtype=float)
        assert np.all(np.isfinite(a)), (name, a)


# --- E: unbounded time or memory ---------------------------------------------------------------
@pytest.mark.parametrize("dps, match", [(10 ** 6, "between 16 and 2000"), (validate.DPS_MAX + 1, "between 16"),
                                        (validate.DPS_MIN - 1, "between 16"), (-5, "between"),
                                        ("30", "integer number of digits"), ([30], "integer number"),
                                        (30.0, "integer number"), (True, "integer number")])
def test_dps_outside_the_documented_range_is_one_error(dps, match):
    with pytest.raises(InputError, match=match):
        run(dps=dps)


def test_dps_at_the_lower_bound_runs():
    # control: DPS_MIN itself is accepted (mpmath at 16 digits; energy an mpf)
    res = run(dps=validate.DPS_MIN, t_span=(0, 0.1))
    assert res.status == 0 and res.dps == validate.DPS_MIN


@pytest.mark.parametrize("engine", ["compiled", "generic"])
def test_step_count_is_bounded_on_every_engine(engine):
    # before: n_steps=10**12 bypassed the step limit (the generic engine started a loop forever)
    with pytest.raises(InputError, match=r"n_steps must be an integer between 1 and 1e\+09"):
        run(t_span=None, n_steps=10 ** 12, engine=engine)


def test_generic_engine_has_the_storage_check_of_the_compiled_one(monkeypatch):
    # before: --engine generic --h 1e-9 --t-end 1 grew memory; now refused before allocating. That
    # run is now refused by the float64 generic work bound first (test_work_bound.py), so the
    # storage check is seen with the machine's memory made 1 KiB: 11 samples need ~6 KiB.
    with pytest.raises(InputError, match="work"):
        run(t_span=(0, 1), h=1e-9, engine="generic")
    # control: with the machine's memory, 10 steps store nothing large (the compiled run also
    # records its options as checked: the storage bound must still be checked at the next call,
    # it depends on the memory; it was cached with the options, and in a test session that had run
    # these options before, the compiled run below went through)
    for engine in ("generic", "compiled"):
        assert run(t_span=(0, 0.5), h=0.05, engine=engine).status == 0
    monkeypatch.setattr(validate, "physical_memory", lambda: 2 ** 10)
    for engine in ("generic", "compiled"):
        with pytest.raises(InputError, match="GiB"):
            run(t_span=(0, 0.5), h=0.05, engine=engine)


def test_runspec_and_run_many_bound_the_steps_and_refuse_zero_rows():
    from ldaspark.ensemble import RunSpec, run_many
    skate = ldaspark.get_scene("skate")
    t0, q0, v0 = skate.initial()
    with pytest.raises(InputError, match="between 1 and 1e"):
        RunSpec(skate.system, "gauss-2", t0, [q0], [v0], 0.05, 10 ** 12, every=10 ** 11)
    with pytest.raises(InputError, match="no rows"):
        RunSpec(skate.system, "gauss-2", t0, np.zeros((0, 3)), np.zeros((0, 3)), 0.05, 10)
    with pytest.raises(InputError, match="executor"):
        run_many([], executor=42)
    with pytest.raises(InputError, match="RunSpec"):
        run_many([object()])
    # control: one row runs through a thread pool
    with concurrent.futures.ThreadPoolExecutor(1) as ex:
        out = run_many([RunSpec(skate.system, "gauss-2", t0, [q0], [v0], 0.05, 4)], executor=ex)
    assert out[0].q.shape == (1, 5, 3)


def test_long_compiled_run_is_chunked_with_the_same_samples(monkeypatch):
    """Ctrl-C stops a compiled run because it runs in kernel calls of at most COMPILED_CHUNK steps
    (Python handles the signal between two calls). The chunked run keeps the same saved steps and
    agrees with one call to the Newton tolerance (the predictor restarts at a chunk boundary;
    8 eps relative per step over 40 steps and an O(1) solution: 1e-12 is ample)."""
    from ldaspark.compiled import runner
    calls = []
    real = runner._run_checked        # the kernel call behind fast_integrate and run_compiled

    def spy(*a, **k):
        calls.append(a[3][1])          # grid = (h, n_steps, every)
        return real(*a, **k)
    one = run(t_span=(0, 2), h=0.05, save_every=3)
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 7)
    monkeypatch.setattr(runner, "_run_checked", spy)
    chunked = run(t_span=(0, 2), h=0.05, save_every=3)
    assert one.engine == chunked.engine == "compiled"
    assert len(calls) >= 40 // 7, calls             # several kernel calls ...
    assert max(calls) <= 7                            # ... of at most the chunk length
    np.testing.assert_array_equal(np.round(chunked.t / 0.05).astype(int), np.round(one.t / 0.05).astype(int))
    np.testing.assert_allclose(chunked.q, one.q, rtol=0, atol=1e-12)
    assert chunked.stats["steps"] == one.stats["steps"] == 40
    # save_every larger than the chunk: samples at 0, 9, 18, 27, 36, 40 as in one call
    big = run(t_span=(0, 2), h=0.05, save_every=9)
    assert list(np.round(big.t / 0.05).astype(int)) == [0, 9, 18, 27, 36, 40]
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 2 ** 18)
    calls.clear()
    run(t_span=(0, 2), h=0.05)
    assert len(calls) == 1                            # negative control: short runs are one call


def test_energy_jump_is_accepted_by_integrate_on_every_engine():
    """docs/reliability.md documents ``integrate(..., energy_jump=0.1)``; before: TypeError. A
    collision through the singularity of U = -1/x (x0 = 1.05, v0 = -1, h = 0.1: both engines pass
    x = 0 leaving finite values; the energy jumps by 60) stops at the same step on both engines:
    the compiled one is checked on its step energies, the generic one in the step."""
    coulomb = skate_like(1 / x)
    kw = dict(system=coulomb, q0=[1.05, 0, 0], v0=[-1, 0, 0], t_span=(0, 3), h=0.1)
    steps = []
    for engine in ("generic", "compiled"):
        res = run(energy_jump=0.1, engine=engine, **kw)
        assert res.status == -3 and "energy jumped" in res.message, (engine, res.message)
        assert res.engine == engine
        k = res.error.step
        assert len(res.t) == k + 1 and np.all(res.q[:, 0] > 0)      # the good prefix, before the collision
        assert_finite_result(res)
        steps.append(k)
        with pytest.raises(NonFiniteError, match="energy jumped"):
            run(energy_jump=0.1, raise_on_failure=True, engine=engine, **kw)
        quiet = run(engine=engine, **kw)
        assert quiet.status == 0 and np.max(np.abs(np.diff(quiet.energy))) > 10   # negative control: off by default
        assert run(energy_jump=1e-3, engine=engine).status == 0                   # quiet on a regular run
        with pytest.raises(InputError, match="energy_jump"):
            run(energy_jump=0, engine=engine)
    assert steps[0] == steps[1], steps


# --- F: NaN, inf or complex never returned -------------------------------------------------------
@pytest.mark.parametrize("engine", ["generic", "compiled"])
@pytest.mark.parametrize("extra, q0, v0, match", [
    (-1 / x, [0, 0, 0], [0, 0, 0], "energy .* is inf"),               # U = 1/x at x = 0
    # (oo x and zoo x, which gave "not a finite real" here, are refused when the system is built:
    # tests/core/test_system_rules.py::test_an_infinite_or_undefined_constant_is_refused_at_build)
    (x * sympy.exp(1000), [1, 0, 0], [0, 0, 0], "cannot be evaluated"),  # a finite number float64 overflows
    (sympy.log(x), [0, 0, 0], [0, 0, 0], "cannot be evaluated"),
    (-sympy.sqrt(x), [-1, 0, 0], [0, 0, 0], "cannot be evaluated|not a finite real"),
])
def test_initial_point_outside_the_domain_is_one_error(engine, extra, q0, v0, match):
    with pytest.raises(NonFiniteError, match=match):
        run(system=skate_like(extra), q0=q0, v0=v0, engine=engine)


def test_complex_energy_at_mpmath_precision_is_one_error():
    for extra, q0 in ((-sympy.sqrt(x), [-1, 0, 0]), (sympy.I * x, [1, 0, 0])):
        with pytest.raises(NonFiniteError, match="not a finite real"):
            run(system=skate_like(extra), q0=q0, v0=[0, 0, 0], dps=20)


@pytest.mark.parametrize("engine", ["generic", "auto"])
def test_a_complex_constraint_is_one_error_not_its_real_part(engine):
    """k with the imaginary unit (sqrt(-1) in a string): numpy's cast to float64 dropped the
    imaginary part with only a ComplexWarning, so k(q0, v0) passed as its real part and the run
    then failed inside the saddle check with a raw TypeError (engine auto, the default, too). Now
    one NonFiniteError at the initial point; control: the same constraint with a real coefficient
    runs."""
    for coef, ok in (("sqrt(-1)", False), ("2", True)):
        s = ldaspark.LagrangianSystem("v**2/2 + w**2/2 - x**2/2", [f"w + {coef}*(x - 3/10)*v"], ["x", "y"],
                                      ["v", "w"], name="ck")
        if ok:
            assert_finite_result(run(system=s, q0=[0.3, 0.0], v0=[0.2, 0.0], engine=engine))
            continue
        with pytest.raises(NonFiniteError, match="L or k has complex values at the initial point"):
            run(system=s, q0=[0.3, 0.0], v0=[0.2, 0.0], engine=engine)


def test_huge_consistent_v0_overflowing_the_energy_is_one_error():
    disk = ldaspark.get_scene("rolling-disk")
    _, q0, v0 = disk.initial()
    with pytest.raises(NonFiniteError, match="energy"):
        run(system="rolling-disk", q0=q0, v0=np.asarray(v0, float) * 1e200)
    assert_finite_result(run(system="rolling-disk", q0=q0, v0=np.asarray(v0, float) * 1e3))   # control


# --- G: silently wrong ----------------------------------------------------------------------------
@pytest.mark.parametrize("newton", ["bogus", None, 1])
@pytest.mark.parametrize("engine", ["compiled", "generic", "auto"])
def test_newton_is_checked_on_every_engine(newton, engine):
    with pytest.raises(InputError, match="newton must be one of"):
        run(newton=newton, engine=engine)


@pytest.mark.parametrize("kw, match", [
    (dict(h=True), "bool"), (dict(h="abc"), "real number"), (dict(h=0.05j), "real number"),
    (dict(h=[0.05]), "real number"), (dict(h=float("nan")), "finite"), (dict(h=0), "nonzero"),
    (dict(t_span=("0", "x")), "t_end must be a real"), (dict(t_span=(0, 1j)), "t_end"),
    (dict(t_span=[0, 1, 2]), "pair"), (dict(t_span="ab"), "pair"), (dict(t_span=(None, 1)), "t0"),
    (dict(q0=object()), "q0"), (dict(q0=[1, 2, "x"]), r"q0\[2\]"), (dict(v0=[[1, 2], [3]]), "v0"),
    (dict(q0=[1j, 0, 0]), "real number"), (dict(executor=42), "executor"),
    (dict(save_every=10 ** 30), "save_every"), (dict(save_every=0), "save_every"),
    (dict(save_every=2.0), "save_every"), (dict(engine=["compiled"]), "engine"),
    (dict(dense_output="yes"), "dense_output"), (dict(tol=-1.0), "tolerance"),
    (dict(method="gauss-irk-" + "9" * 5000), "unknown method"), (dict(max_stages=10 ** 8), "max_stages"),
    (dict(method="gauss-irk-21"), "raise it"), (dict(params=[]), "empty"),
])
def test_bad_arguments_are_one_input_error(kw, match):
    # InputError, or TableauError for a stage count beyond the limit: one LdasparkError either way
    with pytest.raises(LdasparkError, match=match):
        run(**kw)


def test_controls_near_the_bounds_still_run():
    # decimal strings for h and t_span are numbers (they keep their digits at mpmath precision)
    assert run(h="0.05", t_span=("0", "0.2")).status == 0
    assert run(save_every=10 ** 9).t.shape == (2,)          # save_every far beyond n: first and last
    assert run(method="gauss-irk-2").status == 0
    assert run(method="gauss-irk-21", max_stages=21, t_span=(0, 0.05)).status == 0


@pytest.mark.parametrize("q, v, match", [
    ((x, x, z), (vx, vy, vz), "the same symbol twice: x"),
    ((x, y, z), (x, y, z), "share the symbols"),
    ((1, 2, 3), (vx, vy, vz), "sympy symbols"),
    ((x, y, z), (vx, vx, vz), "twice"),
])
def test_system_symbols_are_distinct(q, v, match):
    with pytest.raises(SystemDefinitionError, match=match):      # checked before L and k are read
        ldaspark.LagrangianSystem(L_FREE, K_SKATE, list(q), list(v))


@pytest.mark.parametrize("value", [1j, None, [1, 2], {"a": 1}, float("nan"), True])
def test_parameter_values_must_be_real_numbers(value):
    m = sympy.Symbol("m")
    sysm = ldaspark.LagrangianSystem(m * L_FREE, K_SKATE, [x, y, z], [vx, vy, vz], params=[m])
    with pytest.raises(InputError, match="parameter m"):
        run(system=sysm, q0=[1, 0, 0], v0=[0, 0, 0], params={"m": value})
    assert run(system=sysm, q0=[1, 0, 0], v0=[0, 0, 0], params={"m": 2.0}).status == 0     # control


# --- H: nonsmooth functions in L --------------------------------------------------------------
def test_abs_and_sign_in_L_are_differentiated_almost_everywhere():
    """Abs(x) of a complex symbol used to give PrintMethodNotImplementedError (Derivative(re(x))),
    Abs of a real symbol NameError 'DiracDelta'. Now d|x|/dx = sign(x) and sign' = 0 off x = 0:
    U = |x| pushes with force -sign(x) = -1 at x > 0, so x(t) = x0 - t^2/2 exactly on this
    system (gauss-2 integrates the quadratic exactly: 1e-12 is round-off over 4 steps)."""
    xr = sympy.Symbol("x", real=True)
    for X, U in ((x, sympy.Abs(x)), (xr, sympy.Abs(xr)), (x, sympy.sign(x) * x)):
        sysm = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - U.subs(x, X), [vy], [X, y], [vx, vy])
        res = ldaspark.integrate(sysm, "gauss-2", t_span=(0, 0.2), h=0.05, q0=[1, 0], v0=[0, 0], engine="generic")
        assert res.status == 0
        np.testing.assert_allclose(res.q[:, 0], 1 - res.t ** 2 / 2, rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="cannot run this"):     # no numba translation: refused clearly
        ldaspark.integrate(sysm, "gauss-2", t_span=(0, 0.2), h=0.05, q0=[1, 0], v0=[0, 0], engine="compiled")


def test_math_domain_error_in_float64_is_one_error():
    # relativistic-like L = -sqrt(1 - v^2) with |v| > 1 at the initial point
    L = -sympy.sqrt(1 - vx ** 2 - vy ** 2)
    sysm = ldaspark.LagrangianSystem(L, [vy], [x, y], [vx, vy])
    with pytest.raises(LdasparkError, match="cannot be evaluated"):
        ldaspark.integrate(sysm, "gauss-2", t_span=(0, 0.2), h=0.05, q0=[0, 0], v0=[1.5, 0], engine="generic")
    assert ldaspark.integrate(sysm, "gauss-2", t_span=(0, 0.2), h=0.05, q0=[0, 0], v0=[0.5, 0],
                              engine="generic").status == 0


def test_real_number_accepts_the_number_types_and_nothing_else():
    import fractions

    import mpmath
    for ok in (1, 0.5, np.float32(2), np.int64(3), mpmath.mpf("0.1"), sympy.Rational(1, 3), sympy.sqrt(2),
               fractions.Fraction(1, 2), "1e-3", np.array(0.5)):
        assert validate.real_number(ok, "a") is ok
    for bad in (True, np.bool_(False), 1j, None, [1], "1/2", "nan", "1e999", float("inf"), sympy.I,
                mpmath.mpf("inf"), sympy.Symbol("a"), object(), "9" * (validate.MAX_NUMBER_CHARS + 1)):
        with pytest.raises(InputError):
            validate.real_number(bad, "a")
    assert math.isfinite(float(validate.real_number("9" * 300, "a")))     # control: a long but finite string


def test_initial_point_is_checked_by_fast_integrate_and_compiled_ensembles():
    # fast_integrate is public too: before, numba printed "Exception ignored ... ZeroDivisionError"
    # and returned energy[0] = 0.5; an initial-data ensemble on an executor names the member
    from ldaspark.compiled.fast import fast_integrate
    coulomb = skate_like(1 / x)
    with pytest.raises(NonFiniteError, match="initial point"):
        fast_integrate(coulomb, "gauss-2", 0, [0, 0, 0], [0, 0, 0], 0.1, 3)
    with concurrent.futures.ThreadPoolExecutor(1) as ex, pytest.raises(NonFiniteError, match="ensemble member 1"):
        ldaspark.integrate(coulomb, "gauss-2", t_span=(0, 0.2), h=0.1, q0=[[1, 0, 0], [0, 0, 0]],
                           v0=[[0, 0, 0], [0, 0, 0]], executor=ex)
    assert_finite_result(fast_integrate(coulomb, "gauss-2", 0, [1, 0, 0], [0, 0, 0], 0.1, 3))     # control


def test_ensemble_rows_of_q0_with_one_v0_vector_name_what_is_missing():
    """q0 with 2 rows and one v0 vector of 3 entries said 'q0 has 2 rows but v0 has 3' (3 entries
    read as rows); with 2 entries it said 'member 0: shapes q: (3,), v: ()'. Both name the one
    vector now; control: 3 rows of v0 against 2 of q0 is a row count."""
    q0 = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    for v0 in (np.zeros(3), np.zeros(2)):
        with pytest.raises(InputError, match="v0 has one vector"):
            run(q0=q0, v0=v0)
    with pytest.raises(InputError, match="v0 has 3 rows"):
        run(q0=q0, v0=np.zeros((3, 3)))
    assert np.asarray(run(q0=q0, v0=np.zeros((2, 3))).status).tolist() == [0, 0]
