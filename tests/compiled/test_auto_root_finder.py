"""The default root finder on the compiled engine (``runner.auto_runs_quasi``): the quasi-Newton
iteration where it was measured faster (a SPARK tableau on the SPARK kernel, the mechanical form,
n < 32, nothing asked of the Newton matrix), the kernels' Newton elsewhere; every entry point that
runs a kernel makes the same choice (so that their runs stay equal)."""
import dataclasses
import warnings

import numpy as np
import pytest

import ldaspark
from ldaspark import Newton
from ldaspark.compiled import runner
from ldaspark.models.scenes import get_scene


def _runs(scene, method, newton="auto", **kw):
    r = ldaspark.integrate(scene, method, h=0.05, n_steps=20, engine="compiled", newton=newton, guard=False, **kw)
    return r.stats["root_finder"]["runs"]


@pytest.mark.parametrize("scene, method, newton, runs", [
    ("skate", "gauss-3", "auto", "quasi"),
    ("particle", "lobatto-iiia-iiib-iiid-3", "auto", "quasi"),
    ("skate", "lobatto-iiia-iiib-2", "auto", "lf2"),                     # the semi-implicit kernel (25)
    ("relativistic", "gauss-2", "auto", "auto"),                          # the general form
    ("skate", "gauss-3", Newton(linear_solver="dense"), "auto"),          # the Newton matrix asked for
    ("skate", "gauss-3", Newton(reuse=False), "auto"),
    ("skate", "gauss-3", "simplified", "simplified"),
    ("skate", "gauss-3", "quasi", "quasi"),
])
def test_what_the_default_runs(scene, method, newton, runs):
    assert _runs(scene, method, newton) == runs


def test_the_size_limit_and_the_kernel_choice():
    sc = get_scene("skate")
    cs = runner.compile_system(sc.system)
    spec = runner.kernel_spec("gauss-2", "auto")
    opts = runner.KernelOptions()
    assert runner.auto_runs_quasi(cs, spec, opts)
    assert not runner.auto_runs_quasi(cs, spec, dataclasses.replace(opts, kernel="spark"))
    assert not runner.auto_runs_quasi(cs, spec, dataclasses.replace(opts, reuse_matrix=True))
    assert not runner.auto_runs_quasi(cs, spec, dataclasses.replace(opts, linear_solver="sparse"))
    big = dataclasses.replace(cs, n=runner.REUSE_AUTO_MIN_N)
    assert not runner.auto_runs_quasi(big, spec, opts)          # not measured there: the Newton kernels
    assert not runner.auto_runs_quasi(cs, runner.kernel_spec("lobatto-iiia-iiib-2", "auto"), opts)


def test_every_entry_point_makes_the_same_choice():
    """integrate, run_compiled and fast_integrate with their defaults run the same iteration: equal
    arrays and counters; the kernels' Newton (asked for) differs in its counters (control)."""
    from ldaspark.compiled.fast import fast_integrate
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial()
    a = ldaspark.integrate(sc.system, "gauss-4", t0=t0, q0=q0, v0=v0, h=0.1, n_steps=50, engine="compiled",
                           guard=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b = runner.run_compiled(runner.compile_system(sc.system), "gauss-4", t0, q0, v0, 0.1, 50)
        c = fast_integrate(sc, "gauss-4", h=0.1, n_steps=50)
        newton = runner.run_compiled(runner.compile_system(sc.system), "gauss-4", t0, q0, v0, 0.1, 50,
                                     kernel="spark")
    for r in (b, c):
        assert np.array_equal(r.q, a.q) and r.stats["quasi_iterations"] == a.stats["quasi_iterations"] > 0
    assert "quasi_iterations" not in newton.stats and newton.stats["njev"] > a.stats["njev"]
    # the same method: the trajectories agree to the stopping rule (50 steps; 1e-12 is ~5e3 ulps)
    assert np.max(np.abs(newton.q - a.q)) < 1e-12


@pytest.mark.parametrize("L", ["indefinite", "negative"])
def test_a_mass_matrix_that_is_not_positive_definite_runs_the_kernels_newton(L):
    """L = (vx^2 - vy^2)/2 or -|v|^2/2: valid systems (1) with a constant M that is not positive
    definite. The default root finder chose the quasi-Newton kernel, whose curvature block factors
    M = L L^T, and raised numpy's LinAlgError; now it runs the kernels' Newton (the generic engine's
    numbers), and newton="quasi" is refused in one line. Control: a positive definite M runs quasi."""
    import sympy
    x, y, vx, vy = sympy.symbols("x y vx vy")
    lag = (vx**2 - vy**2) / 2 if L == "indefinite" else -(vx**2 + vy**2) / 2
    s = ldaspark.LagrangianSystem(lag, [vx - 2 * vy], [x, y], [vx, vy], name=f"{L} M")
    kw = dict(n_steps=3, h=0.1, q0=[0, 0], v0=[2, 1])
    r = ldaspark.integrate(s, "gauss-2", engine="compiled", **kw)
    g = ldaspark.integrate(s, "gauss-2", engine="generic", **kw)
    assert r.status == 0 and r.stats["root_finder"]["runs"] == "auto"
    np.testing.assert_allclose(r.q, g.q, rtol=0, atol=1e-14)
    with pytest.raises(ldaspark.LdasparkError, match="positive definite mass matrix"):
        ldaspark.integrate(s, "gauss-2", engine="compiled", newton="quasi", **kw)
    ok = ldaspark.LagrangianSystem((vx**2 + vy**2) / 2, [vx - 2 * vy], [x, y], [vx, vy], name="positive M")
    assert ldaspark.integrate(ok, "gauss-2", engine="compiled", **kw).stats["root_finder"]["runs"] == "quasi"


def test_the_gyroscopic_test_decides_at_points_not_by_simplify(monkeypatch):
    """grad_v L - M v was tested with sympy.simplify: L = |v|^2/2 + v0 (q0 + ... + q7)^16 / 10^16
    waited minutes before the first step. Decided at random points now (``numerically_zero``):
    the power is a gyroscopic term (the general form), and a term that is zero only after
    simplification, v0 (sin(q0)^2 + cos(q0)^2 - 1), is none (the mechanical form) - the control."""
    import sympy
    monkeypatch.setattr(sympy, "simplify", lambda *a, **k: (_ for _ in ()).throw(AssertionError("simplify")))
    n = 8
    q, v = list(sympy.symbols(f"q0:{n}")), list(sympy.symbols(f"v0:{n}"))
    kw = dict(n_steps=2, h=0.01, q0=[0.1] * n, v0=[0.1, 0.1] + [0.01] * (n - 2))
    big = ldaspark.LagrangianSystem(sum(x**2 for x in v) / 2 + v[0] * sum(q)**16 / 10**16, [v[1] - v[0]], q, v,
                                    name="power")
    assert ldaspark.integrate(big, "gauss-2", **kw).stats["form"] == "general"
    hidden = ldaspark.LagrangianSystem(sum(x**2 for x in v) / 2 + v[0] * (sympy.sin(q[0])**2 + sympy.cos(q[0])**2 - 1),
                                       [v[1] - v[0]], q, v, name="hidden zero")
    assert ldaspark.integrate(hidden, "gauss-2", **kw).stats["form"] == "mechanical"
