"""The quasi-Newton root finder with the Hessian of U in its frozen velocity block
(``kernels_quasi.curvature_refresh``, ``curvature_matrix``, ``curvature_increment``;
``run_quasi(..., curvature=True)``, the default): the same equations (21), fewer iterations where
the potential has curvature, the M-only block where it does not pay.

Tolerance of the trajectory comparisons: that of tests/compiled/test_kernels_quasi.py (both root
finders stop when the remaining error is estimated at most lim = tol (|x| + |v0|) <= 8 eps scale,
so N steps of a non-expanding flow differ by at most 2 N 8 eps scale).
"""
import numpy as np
import pytest
import sympy

from ldaspark.compiled import kernels_quasi as KQ
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.quasi import run_quasi
from ldaspark.compiled.runner import kernel_spec
from ldaspark.core.system import LagrangianSystem
from ldaspark.models.scenes import get_scene
from quasi_helpers import EPS, trajectory_difference as _difference


pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _particle(U, name):
    """The constraint of 8.1 (v3 - q2 v1 = 0) with potential U(q1, q2, q3)."""
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - U(*q)
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name=name)


@pytest.mark.parametrize("method, h, it_hess, it_mass", [("gauss-2", 0.1, (3.5, 3.9), (4.9, 5.1)),
                                                         ("gauss-4", 0.2, (2.9, 3.1), (4.9, 5.1)),
                                                         ("gauss-6", 0.4, (2.9, 3.1), (5.8, 6.1))])
def test_particle_fewer_iterations_same_trajectory(method, h, it_hess, it_mass):
    """The particle of 8.1 (Hess U = diag(2, 2, 0), constant): with H in the block the iterations
    per step fall from 5-6 to 3-3.8 (measured 3.75 / 3.00 / 3.01 against 5.00 / 5.00 / 5.99), the
    Hessian is decomposed once per run, every step is a curvature step; both runs agree with the
    Newton engine within the bound. The M-only run (curvature=False) is the negative control of
    the iteration counts."""
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    n = 400
    a = run_compiled(cs, method, t0, q0, v0, h, n, 1, kernel="spark")
    b = run_quasi(cs, method, t0, q0, v0, h, n, 1)
    c = run_quasi(cs, method, t0, q0, v0, h, n, 1, curvature=False)
    assert it_hess[0] <= b.stats["mean_iterations"] <= it_hess[1], b.stats["mean_iterations"]
    assert it_mass[0] <= c.stats["mean_iterations"] <= it_mass[1], c.stats["mean_iterations"]
    assert b.stats["curvature_refreshes"] == 1 and b.stats["curvature_steps"] == n
    assert c.stats["curvature_refreshes"] == c.stats["curvature_steps"] == 0
    assert b.stats["quasi_fallbacks"] == c.stats["quasi_fallbacks"] == 0
    assert _difference(a, b) <= 1.0 and _difference(a, c) <= 1.0


@pytest.mark.parametrize("quartic, kept", [(sympy.Rational(1, 200), True), (sympy.Rational(1, 4), False)])
def test_varying_hessian_refreshed_when_stale(quartic, kept):
    """U = q1^2 + q2^2 + c (q1^2 + q2^2)^2: the Hessian changes along the orbit. c = 1/200: the frozen
    one is refreshed when stale, less than once per CURV_REFRESH_EVERY steps, so the curvature is
    kept and lowers the iterations (control: curvature=False); c = 1/4: it is stale at nearly
    every step, a decomposition per step costs more than it saves (measured 8.5 against 5.5 us
    per step), so the run switches to the M-only block after CURV_WARMUP steps. Either way the
    trajectory is the Newton engine's within the bound."""
    cs = compile_system(_particle(lambda a, b, c: a ** 2 + b ** 2 + quartic * (a ** 2 + b ** 2) ** 2,
                                  f"quartic-particle-{quartic}"))
    n, h = 400, 0.2
    a = run_compiled(cs, "gauss-4", 0.0, [1, 0, 0], [0, 1, 0], h, n, 1, kernel="spark")
    b = run_quasi(cs, "gauss-4", 0.0, [1, 0, 0], [0, 1, 0], h, n, 1)
    c = run_quasi(cs, "gauss-4", 0.0, [1, 0, 0], [0, 1, 0], h, n, 1, curvature=False)
    if kept:
        assert 1 <= b.stats["curvature_refreshes"] <= 1 + n // KQ.CURV_REFRESH_EVERY and b.stats["curvature_steps"] == n
        assert b.stats["mean_iterations"] < c.stats["mean_iterations"] - 0.5, (b.stats, c.stats)
    else:
        assert 1 + KQ.CURV_WARMUP // KQ.CURV_REFRESH_EVERY < b.stats["curvature_refreshes"] <= KQ.CURV_WARMUP + 1
        assert b.stats["curvature_steps"] <= KQ.CURV_WARMUP + 1
    assert _difference(a, b) <= 1.0 and _difference(a, c) <= 1.0


def test_no_curvature_where_it_does_not_pay():
    """skate (U linear in q: Hess U = 0) and lobatto-iiia-iiib-2 (A^ A = 0): eta = 0 < CURV_MIN,
    no decomposition, the run is the M-only one bit for bit. The particle with gauss-2 is the
    control (curvature steps)."""
    for scene, method, used in (("skate", "gauss-4", False), ("particle", "lobatto-iiia-iiib-2", False),
                                ("particle", "gauss-2", True)):
        sc = get_scene(scene)
        t0, q0, v0 = sc.initial()
        cs = compile_system(sc.system)
        b = run_quasi(cs, method, t0, q0, v0, 0.1, 200, 1)
        c = run_quasi(cs, method, t0, q0, v0, 0.1, 200, 1, curvature=False)
        assert (b.stats["curvature_steps"] > 0) == used, (scene, method, b.stats["curvature_steps"])
        if not used:
            assert b.stats["curvature_refreshes"] == 0
            assert np.array_equal(b.q, c.q) and np.array_equal(b.v, c.v)


def test_switched_off_when_refreshes_do_not_amortise():
    """robot (Hess U varies at every step relative to the staleness threshold): after CURV_WARMUP
    steps with more than one refresh per CURV_REFRESH_EVERY steps the run continues M-only: few
    curvature steps and refreshes in 1000 steps, same trajectory as Newton within the bound."""
    sc = get_scene("robot")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    n = 1000
    a = run_compiled(cs, "gauss-2", t0, q0, v0, 0.05, n, 1, kernel="spark")
    b = run_quasi(cs, "gauss-2", t0, q0, v0, 0.05, n, 1)
    assert 0 < b.stats["curvature_refreshes"] <= KQ.CURV_WARMUP + 1
    assert 0 < b.stats["curvature_steps"] <= 2 * KQ.CURV_WARMUP
    assert _difference(a, b) <= 1.0


def test_stiff_spring_contracts_with_the_hessian():
    """The particle with a spring omega^2 = 10^4 at h = 0.05 (h omega = 5): with H frozen at M only
    every step falls back to the Newton chain (test_kernels_quasi); with H in the block gauss-2 is
    solved by the quasi-Newton iteration at most steps (measured 250 of 300) and agrees with Newton."""
    cs = compile_system(_particle(lambda a, b, c: 5000 * (a ** 2 + b ** 2), "stiff-particle-1e4"))
    n = 300
    a = run_compiled(cs, "gauss-2", 0.0, [1, 0, 0], [0, 1, 0], 0.05, n, 1, kernel="spark")
    b = run_quasi(cs, "gauss-2", 0.0, [1, 0, 0], [0, 1, 0], 0.05, n, 1)
    c = run_quasi(cs, "gauss-2", 0.0, [1, 0, 0], [0, 1, 0], 0.05, n, 1, curvature=False)
    assert b.stats["quasi_steps"] >= n // 2 and c.stats["quasi_steps"] == 0
    assert b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == n
    assert _difference(a, b) <= 1.0


@pytest.mark.parametrize("method", ["gauss-2", "gauss-3", "lobatto-iiia-iiib-3"])
def test_refresh_inverts_the_frozen_velocity_block(method):
    """curvature_refresh's R is the inverse of the frozen (21b, d) velocity block
    [[I (x) M + h^2 (A^ A) (x) H, 0], [h^2 (b^ A) (x) H, M]] for a random SPD M and a symmetric H with
    a negative eigenvalue: R J = I within 1e3 eps cond (J) (the solve is backward stable per
    eigen-direction). T_j = R (A~_.j ; b~_j) (x) I. Control: R of another H misses I by O(1)."""
    rng = np.random.default_rng(7)
    tab = kernel_spec(method, "spark")[1]
    A, Ah, At, bh, bt = tab[1], tab[2], tab[3], tab[5], tab[6]
    s, n, m, h = A.shape[0], 4, 1, 0.3
    B = rng.standard_normal((n, n))
    M = B @ B.T + n * np.eye(n)
    Hm = rng.standard_normal((n, n))
    Hm = Hm + Hm.T
    Minv = np.linalg.inv(M)
    P, p = Ah @ A, bh @ A
    J = np.zeros(((s + 1) * n, (s + 1) * n))
    for i in range(s):
        for k in range(s):
            J[i * n:(i + 1) * n, k * n:(k + 1) * n] = (M if i == k else 0) + h * h * P[i, k] * Hm
        J[s * n:, i * n:(i + 1) * n] = h * h * p[i] * Hm
    J[s * n:, s * n:] = M
    tol = 1e3 * EPS * np.linalg.cond(J)
    for H, ok in ((Hm, True), (Hm + np.eye(n), False)):
        cw = KQ.curvature_workspace(tab, n, m, M, np.ascontiguousarray(Minv))
        cw[4][:, :] = H
        assert KQ.curvature_refresh(tab, h, cw)
        R = cw[11]
        assert (np.abs(R @ J - np.eye(J.shape[0])).max() <= tol) == ok
    for j in range(s):
        E = np.vstack([At[i, j] * np.eye(n) for i in range(s)] + [bt[j] * np.eye(n)])
        assert np.abs(cw[10][j] - R @ E).max() <= 1e-12 * max(1.0, np.abs(R).max())


def test_integrate_sums_the_curvature_counters_over_chunks(monkeypatch):
    """Through ldaspark.integrate(..., newton="quasi") on the particle: every step a curvature step;
    a run cut into kernel calls of 50 steps (chunks.COMPILED_CHUNK lowered) decomposes the Hessian
    once per call (3 calls for 120 steps: the counters add up; one call: 1) and agrees with the
    one-call run within the bound."""
    import ldaspark
    one = ldaspark.integrate("particle", "gauss-4", h=0.2, n_steps=120, engine="compiled", newton="quasi")
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 50)
    b = ldaspark.integrate("particle", "gauss-4", h=0.2, n_steps=120, engine="compiled", newton="quasi")
    assert one.stats["curvature_steps"] == b.stats["curvature_steps"] == 120
    assert one.stats["curvature_refreshes"] == 1 and b.stats["curvature_refreshes"] == 3
    assert _difference(one, b) <= 1.0


@pytest.mark.parametrize("method,s", [("gauss-2", 2), ("gauss-4", 4)])
def test_nlu_counts_the_factorisations_of_a_curvature_refresh(method, s):
    """A Hessian decomposition (``curvature_refresh``) factors n matrices I + h^2 mu_a (A^ A) of
    size s; ``nlu`` counts LU factorisations on every engine, so they are in it (before: nlu =
    multiplier_lu; particle, 10 steps of h = 0.05, one refresh: 10 for 13). Exact count: no step
    fell back (the Newton chain factored nothing), one multiplier matrix a step. Control: with
    the curvature off (``run_quasi(curvature=False)``) no refresh and nlu = multiplier_lu."""
    sc = get_scene("particle")
    cs = compile_system(sc.system)
    t0, q0, v0 = sc.initial()
    r = run_quasi(cs, method, t0, q0, v0, 0.05, 10, 1)
    st = r.stats
    assert st["quasi_fallbacks"] == 0 and st["curvature_refreshes"] >= 1 and st["multiplier_lu"] == 10, st
    assert st["nlu"] == st["multiplier_lu"] + cs.n * st["curvature_refreshes"], st
    off = run_quasi(cs, method, t0, q0, v0, 0.05, 10, 1, curvature=False).stats
    assert off["curvature_refreshes"] == 0 and off["quasi_fallbacks"] == 0 and off["nlu"] == off["multiplier_lu"] == 10


def _flipping_stiffness(period, h):
    """The particle of 8.1 with a free coordinate q4 (q4 = v4 = 0 stays so) of stiffness g(t) = 3 +
    2 tanh(1000 sin(pi t / (period h))): at the step midpoints (k + 1/2) h, |sin| >= sin(pi / (2
    period)), so g is exactly 5 or 1 there, flipping every `period` steps: the frozen Hessian is
    stale at steps 0, period, 2 period, ... and exact in between."""
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    g = 3 + 2 * sympy.tanh(1000 * sympy.sin(sympy.pi * t / (period * sympy.Rational(h))))
    L = sum(vi ** 2 for vi in v) / 2 - (q[0] ** 2 + q[1] ** 2 + g * q[3] ** 2 / 2)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, t=t, name=f"particle-q4-flip-{period}-{h}"))


@pytest.mark.parametrize("method", ["gauss-2", "gauss-4"])
def test_one_refresh_per_refresh_every_steps_keeps_the_curvature(method):
    """The switch to the M-only block at its boundary: it is taken once CURV_WARMUP steps have passed
    with MORE than one refresh (the first not counted) per CURV_REFRESH_EVERY steps. A Hessian stale
    exactly every CURV_REFRESH_EVERY = 8 steps (``_flipping_stiffness``, h = 0.1, 48 steps): refreshes
    at steps 0, 8, ..., 40; at step 32 (CURV_WARMUP) 4 counted refreshes in 32 steps, one per 8, so
    the curvature block stays (6 refreshes, 48 curvature steps; measured). With the test at ">="
    instead of ">" the run would leave it at step 32 (32 curvature steps). Control: stale every 4
    steps, two per 8: the run switches at step 32 exactly (9 refreshes, 32 curvature steps). Both
    are the Newton engine's trajectory within the bound of the module docstring."""
    assert (KQ.CURV_WARMUP, KQ.CURV_REFRESH_EVERY) == (32, 8)
    h, n = 0.1, 48
    q0, v0 = [1, 0, 0, 0], [0, 1, 0, 0]
    for period, refreshes, steps in ((8, 6, n), (4, 9, KQ.CURV_WARMUP)):
        cs = _flipping_stiffness(period, h)
        b = run_quasi(cs, method, 0.0, q0, v0, h, n)
        st = b.stats
        assert st["quasi_fallbacks"] == 0, st
        assert (st["curvature_refreshes"], st["curvature_steps"]) == (refreshes, steps), (period, st)
        a = run_compiled(cs, method, 0.0, q0, v0, h, n, 1, kernel="spark")
        assert _difference(a, b) <= 1.0
