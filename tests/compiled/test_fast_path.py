"""The compiled fast path (ldaspark.compiled.fast) against the generic path: same numbers to 1e-12 over
1000 steps for every SPARK family and the Fig. 4 comparators; fallback with a one-line notice;
Newton counters and predictor. Compilation is cached on disk (numba cache=True)."""
import numpy as np
import pytest
import sympy

from ldaspark.core.comparators import integrate_comparator
from ldaspark.core.errors import InputError
from ldaspark.compiled.fast import compile_system, fast_integrate, mechanical_parts, NotCompilableError, precompile
from ldaspark.models.scenes import get_scene, mp_particles
from ldaspark.core.spark import integrate
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.families import get_method
from system_fakes import max_diff

AGREE = 1e-12
N = 1000

# every compiled (system, kernel) of the default run of this file, test_ensemble and test_kahan
WARM = [("particle", "gauss-2", "spark"), ("rolling-disk", "mp-lobatto-iiib-a-2", "auto"),
        ("mp-particles", "mp-lobatto-iiib-a-2", "auto"), ("linear-3", "lobatto-iiia-iiib-2", "auto")]


@pytest.fixture(scope="module", autouse=True)
def compiled():
    """Compile the kernels in parallel processes first (numba cache=True); later loads are fast."""
    return precompile(WARM)


@pytest.fixture(scope="module")
def particle():
    return get_scene("particle")


@pytest.fixture(scope="module")
def disk():
    return get_scene("rolling-disk")


@pytest.fixture(scope="module")
def mp5():
    return mp_particles(j=5)


ONE_PER_FAMILY = ["gauss-2", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-iiid-2", "euler-ii"]
SPARK_FAMILIES = ["gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
                  "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3", "euler-i", "euler-ii"]


def check_spark_agreement(scene, name, h=0.1):
    t0, q0, v0 = scene.initial()
    fast = fast_integrate(scene, name, h=h, n_steps=N, kernel="spark", compensated=False)
    sol = integrate(scene.system, get_method(name), t0, q0, v0, h, n_steps=N)
    assert fast.stats["path"] == "fast" and fast.stats["kernel"] == "spark"
    assert max_diff(fast, sol) <= AGREE


@pytest.mark.parametrize("name", ONE_PER_FAMILY)
def test_spark_kernel_agrees_with_generic(particle, name):
    """General compiled SPARK kernel (21) vs ldaspark.core.spark.integrate, particle, 1000 steps, one
    method of each family (all of them and three scenes: --exhaustive)."""
    check_spark_agreement(particle, name)


@pytest.mark.exhaustive
@pytest.mark.parametrize("scene_name", ["particle", "skate", "robot"])
@pytest.mark.parametrize("name", SPARK_FAMILIES)
def test_spark_kernel_agrees_with_generic_all(scene_name, name):
    check_spark_agreement(get_scene(scene_name), name)


@pytest.mark.parametrize("name,generic", [
    ("lobatto-iiia-iiib-2", "spark"),                 # semi-implicit kernel (25) = the SPARK method
    ("lobatto-iiia-iiib-2-modified", "comparator"),
    ("mp-lobatto-iiib-a-2", "comparator"),
])
def test_fig4_kernels_agree_with_generic(disk, mp5, name, generic):
    """Fig. 4 kernels vs the generic path: rolling disk, h = 0.1, 1000 steps (there the modified
    constraint differs from (K1 + K2)/2); MP particles, h = 0.05, 300 steps (chaotic: round-off
    differences grow like exp(t / 12), so only a short window can agree to 1e-12). The generic
    path sums plainly, so the comparison is with compensated=False; Kahan changes only round-off."""
    for scene, h, n in ((disk, 0.1, N), (mp5, 0.05, 300)):
        t0, q0, v0 = scene.initial()
        fast = fast_integrate(scene, name, h=h, n_steps=n, compensated=False)
        kahan = fast_integrate(scene, name, h=h, n_steps=n)
        assert max_diff(fast, kahan) <= 100 * AGREE
        if generic == "spark":
            sol = integrate(scene.system, get_method(name), t0, q0, v0, h, n_steps=n)
        else:
            sol = integrate_comparator(name, scene.system, t0, q0, v0, h, n)
        assert fast.stats["kernel"] == "lf2"
        assert max_diff(fast, sol) <= AGREE, scene.name


def test_agreement_check_has_teeth(particle, disk):
    """Negative controls: a 1e-8 change of one tableau entry, or the modified constraint in
    place of (K1 + K2)/2, is seen far above the agreement tolerance."""
    t0, q0, v0 = particle.initial()
    tab = get_method("gauss-2")
    bad = tab.with_entry("A", 0, 1, 1e-8)
    fast = fast_integrate(particle, bad, h=0.1, n_steps=N, compensated=False)
    sol = integrate(particle.system, tab, t0, q0, v0, 0.1, n_steps=N)
    assert max_diff(fast, sol) > 1e3 * AGREE
    t0, q0, v0 = disk.initial()
    fast = fast_integrate(disk, "lobatto-iiia-iiib-2-modified", h=0.1, n_steps=N, compensated=False)
    sol = integrate(disk.system, get_method("lobatto-iiia-iiib-2"), t0, q0, v0, 0.1, n_steps=N)
    assert max_diff(fast, sol) > 1e3 * AGREE


def test_modified_equals_original_when_k_is_affine_in_q(mp5):
    """For the MP particles k = v1 + sum q_i v_i is affine in q, so (k(q0, V1) + k(q1, V1))/2 =
    k(q0 + h/2 V1, V1): the modified method of 8.4 IS the Lobatto IIIA-B SPARK method there
    (up to round-off) -- why the first two curves of Fig. 4 coincide at first. (Same for the
    particle, the skate and the robot; not for the rolling disk, see the negative control above.)"""
    a = fast_integrate(mp5, "lobatto-iiia-iiib-2", h=0.05, n_steps=100)
    b = fast_integrate(mp5, "lobatto-iiia-iiib-2-modified", h=0.05, n_steps=100)
    c = fast_integrate(mp5, "mp-lobatto-iiib-a-2", h=0.05, n_steps=100)
    assert np.max(np.abs(a.q - b.q)) < 1e-13
    assert np.max(np.abs(a.q - c.q)) > 1e-6        # (26) is a different method


def test_sampling_and_unpacking(particle):
    full = fast_integrate(particle, "gauss-2", h=0.1, n_steps=25)
    t, q, v, E, k, stats = fast_integrate(particle, "gauss-2", h=0.1, n_steps=25, every=10)
    assert np.allclose(t, [0.0, 1.0, 2.0, 2.5])
    assert np.array_equal(q, full.q[[0, 10, 20, 25]]) and np.array_equal(E, full.energy[[0, 10, 20, 25]])
    assert k.shape == (4, 1) and stats["steps"] == 25


def test_newton_counters_and_predictor(particle):
    """Simplified Newton: one Jacobian and one LU per step; the extrapolating predictor saves
    iterations against the zero-increment start (negative control)."""
    r2 = fast_integrate(particle, "lobatto-iiia-iiib-3", h=0.05, n_steps=2000, kernel="spark")
    r0 = fast_integrate(particle, "lobatto-iiia-iiib-3", h=0.05, n_steps=2000, predictor=0, kernel="spark")
    for r in (r2, r0):
        assert r.stats["njev"] == r.stats["nlu"] == r.stats["steps"] == 2000
        assert r.stats["newton_iterations"] >= 2000
    assert r2.stats["mean_iterations"] <= r0.stats["mean_iterations"] - 0.5
    assert r2.stats["max_iterations"] <= 8
    # tolerance tied to the precision: a loose tolerance stops earlier
    loose = fast_integrate(particle, "lobatto-iiia-iiib-3", h=0.05, n_steps=2000, tol=1e-6, kernel="spark")
    assert loose.stats["mean_iterations"] < r2.stats["mean_iterations"]


def test_mechanical_form_detected_from_L_and_k(particle):
    parts = mechanical_parts(particle.system)          # particle has system.mechanical = None
    assert particle.system.mechanical is None
    q, v = particle.system.q, particle.system.v
    assert parts["M"] == sympy.eye(3)
    assert sympy.simplify(parts["U"] - (q[0] ** 2 + q[1] ** 2)) == 0
    assert parts["K"] == sympy.Matrix([[-q[1], 0, 1]])


def _non_mechanical():
    """L with a quartic kinetic term: L_vv depends on v, so no mechanical form."""
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + v[0] ** 4 / 12 - (q[0] ** 2 + q[1] ** 2)
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="quartic")


def test_fallback_notice_and_same_numbers(capsys, monkeypatch):
    """A system the compiled path does not take (here: the code generator refuses it, as it does
    an expression without numba translation; the generic path runs it) falls back with one
    notice line and the generic path's numbers."""
    base = _non_mechanical()
    assert compile_system(base).form == "general"           # non-quadratic L alone is compiled
    sysm = LagrangianSystem(base.L, list(base.k), base.q, base.v, base.t, name=base.name,
                            nonideal=[base.q[1] * base.v[0], 0, 0])
    import ldaspark.compiled.runner as runner     # compile_system looks general_source up there

    def refuse(system):
        raise NotCompilableError(f"{system.name}: an expression has no numba translation (refused here)")
    monkeypatch.setattr(runner, "general_source", refuse)
    with pytest.raises(NotCompilableError):
        compile_system(sysm)
    r = fast_integrate(sysm, "gauss-2", 0.0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.1, 30, every=10)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "falling back to the generic path" in err[0] and "quartic" in err[0]
    assert r.stats["path"] == "generic"
    sol = integrate(sysm, get_method("gauss-2"), 0.0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 0.1, n_steps=30)
    assert np.array_equal(r.q, np.asarray(sol.q, float)[[0, 10, 20, 30]])


def test_gyroscopic_term_is_not_mechanical():
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + q[1] * v[0] - q[0] ** 2
    with pytest.raises(NotCompilableError):
        mechanical_parts(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v))


def test_bad_inputs(particle):
    with pytest.raises(InputError):
        fast_integrate(particle, "no-such-method", h=0.1, n_steps=10)
    with pytest.raises(InputError):
        fast_integrate(particle, "gauss-2", h=0.1, n_steps=0)
    with pytest.raises(InputError):
        fast_integrate(particle, "gauss-2", h=float("nan"), n_steps=10)
    with pytest.raises(InputError):
        fast_integrate(particle, "gauss-2", h=0.1, n_steps=10, predictor=3)


def test_cpu_at_equal_accuracy_interpolation():
    """Work-precision ratios read the cheapest run reaching an error (log-log interpolation)."""
    from ldaspark.lab.reports.work_precision import cpu_at
    rows = [{"error": e, "cpu": c} for e, c in [(1e-2, 1.0), (1e-4, 2.0), (1e-6, 4.0), (1e-8, 8.0), (1e-5, 9.0)]]
    assert cpu_at(rows, 1e-4) == pytest.approx(2.0)
    assert cpu_at(rows, 1e-5) == pytest.approx(2 * 2 ** 0.5)       # the dominated 9 s run is ignored
    assert cpu_at(rows, 1e-9) is None and cpu_at(rows, 1e-1) is None
