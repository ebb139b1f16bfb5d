"""The quasi-Newton root finder for systems in the general form (``compiled.kernels_quasi_general``,
``run_quasi`` on a general model, ``integrate(..., engine="compiled", newton="quasi")``): the same
equations (21) as the compiled Newton engine, the velocity block frozen at L_vv at the predictor.

Tolerances: scenes as tests/compiled/test_kernels_quasi.py (both root finders stop within
lim = tol (|x| + |v0|) <= 8 eps scale of the root, so N steps differ by at most 2 N 8 eps scale);
random systems by ``verification.harness.agreement_tol`` (the same stopping bound amplified by
the condition number of the saddle matrix (4), which the drawn L_vv and k_v can make large).
"""
import hashlib
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, seed, settings

import ldaspark
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.quasi import run_quasi
from ldaspark.core.errors import InputError
from ldaspark.models.scenes import get_scene
from verification.harness import SEED, agreement_tol, saddle_cond
from verification.strategies import general_systems
from quasi_helpers import EPS, trajectory_difference as _difference, waits as _waits

N, H = 200, 0.05

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_kernel_file_records_its_helpers():
    """numba keys the cached general_quasi_run on kernels_quasi_general.py only: HELPERS_SHA256 is
    the digest of the modules compiled into it."""
    from ldaspark.compiled import kernels_quasi_general as K
    d = os.path.dirname(K.__file__)
    h = hashlib.sha256()
    for f in K.HELPERS:
        with open(os.path.join(d, f), "rb") as fh:
            h.update(fh.read())
    assert K.HELPERS_SHA256 == h.hexdigest(), "update HELPERS_SHA256 in ldaspark/compiled/kernels_quasi_general.py"


@pytest.mark.parametrize("scene", ["relativistic", "chaplygin-sleigh", "constant-speed", "ball-turntable"])
def test_same_trajectory_as_newton_on_general_scenes(scene):
    """General-form scenes (a magnetic field: L_vq != 0; k nonlinear in v; n = 5, m = 2), gauss-2,
    gauss-3 and lobatto-iiia-iiib-3, 200 steps of h = 0.05: within the bound of the module
    docstring (measured at most 0.034 of it), every step counted as a quasi step or a fallback.
    Negative control: another method of the same order breaks the bound."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    assert cs.form == "general"
    for fam in ("gauss-2", "gauss-3", "lobatto-iiia-iiib-3"):
        a = run_compiled(cs, fam, t0, q0, v0, H, N, 1, kernel="spark")
        b = run_quasi(cs, fam, t0, q0, v0, H, N, 1)
        st = b.stats
        assert st["steps"] == N and st["quasi_steps"] + st["quasi_fallbacks"] == N and st["quasi_steps"] > 0
        assert st["form"] == "general" and st["root_finder"] == "quasi" and st["curvature_steps"] == 0
        assert _difference(a, b) <= 1.0, (scene, fam, _difference(a, b))
    other = run_compiled(cs, "lobatto-iiia-iiib-2", t0, q0, v0, H, N, 1, kernel="spark")
    assert _difference(other, run_quasi(cs, "gauss-2", t0, q0, v0, H, N, 1)) > 1.0


@seed(SEED)
@settings(max_examples=6, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(case=general_systems(n_range=(2, 3), m_max=2, dps=30))
def test_random_general_systems_agree_with_newton(case):
    """Random general systems of the differential harness's family (L with explicit t, L_qv != 0,
    L not quadratic in v, k nonlinear in v with b != 0), gauss-2 and gauss-3, 8 steps of h = 1/16
    from the drawn point: quasi-Newton and Newton within ``agreement_tol`` (8 steps, the saddle
    matrix's condition number at the start, the run's scale)."""
    cs = compile_system(case.system)
    t0, q0, v0 = float(case.t0), [float(x) for x in case.q0], [float(x) for x in case.v0]
    cond = saddle_cond(case.system, t0, q0, v0, {})
    for fam in ("gauss-2", "gauss-3"):
        a = run_compiled(cs, fam, t0, q0, v0, 1 / 16, 8, 1, kernel="spark")
        b = run_quasi(cs, fam, t0, q0, v0, 1 / 16, 8, 1)
        scale = max(1.0, float(np.abs(a.q).max()), float(np.abs(a.v).max()))
        d = max(float(np.abs(a.q - b.q).max()), float(np.abs(a.v - b.v).max()))
        assert d <= agreement_tol(8, cond, scale), (case, fam, d)
        assert b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == 8


def test_integrate_general_form_and_nonideal_refused():
    """Through ldaspark.integrate: the relativistic particle (general form) runs with newton="quasi"
    and agrees with the default compiled Newton; the friction skate (a nonideal term N, section
    3.3) is refused by name, as is the generic engine."""
    a = ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=100, engine="compiled")
    b = ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=100, engine="compiled", newton="quasi")
    assert b.stats["root_finder"]["kind"] == "quasi" and b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == 100
    assert _difference(a, b) <= 1.0
    with pytest.raises(InputError, match="nonideal"):
        ldaspark.integrate("friction-skate", "gauss-2", h=0.05, n_steps=3, engine="compiled", newton="quasi")
    with pytest.raises(InputError, match="quasi"):
        ldaspark.integrate("relativistic", "gauss-2", h=0.05, n_steps=3, engine="generic", newton="quasi")


@pytest.mark.parametrize("fam,s", [("gauss-2", 2), ("lobatto-iiia-iiib-3", 3)])
def test_nlu_counts_the_frozen_velocity_blocks(fam, s):
    """A general-form quasi-Newton attempt factors s + 1 matrices L_vv (the stages and the end
    point) and the multiplier matrix S: s + 2 LU factorisations, all of them in ``nlu`` (its one
    meaning on every engine, ``Result``). Before: nlu = multiplier_lu, 1 a step (relativistic,
    gauss-2, 10 steps: nlu 10 for 40 factorisations). Exact counts: no step fell back here, so
    the Newton chain factored nothing. Control: the mechanical form without curvature (the skate,
    Hess U = 0) factors only S per step (M is factored once per run, outside the step) and keeps
    nlu = multiplier_lu."""
    g = ldaspark.integrate("relativistic", fam, h=0.05, n_steps=10, engine="compiled", newton="quasi")
    st = g.stats
    assert st["quasi_fallbacks"] == 0 and st["multiplier_lu"] == 10, st
    assert g.nlu == st["nlu"] == (s + 2) * st["multiplier_lu"], st
    m = ldaspark.integrate("skate", fam, h=0.05, n_steps=10, engine="compiled", newton="quasi")
    assert m.stats["quasi_fallbacks"] == 0 and m.stats["curvature_refreshes"] == 0, m.stats
    assert m.nlu == m.stats["multiplier_lu"] == 10, m.stats


def _stiff(w2):
    """The particle of 8.1 with the spring U = w2 (q1^2 + q2^2) / 2 (tests/compiled/test_kernels_quasi.py)."""
    import sympy

    from ldaspark.core.system import LagrangianSystem
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - sympy.Integer(w2) / 2 * (q[0] ** 2 + q[1] ** 2)
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name=f"stiff-particle-{w2}")


@pytest.mark.parametrize("w2, all_fall_back", [(10000, True), (4, False)])
@pytest.mark.parametrize("fam, s", [("gauss-2", 2), ("gauss-3", 3)])
def test_the_general_form_falls_back_and_waits_as_the_mechanical_one(w2, all_fall_back, fam, s):
    """``general_quasi_steps``' fallback and wait rule, which no general scene reached (every one
    converges at every step): the particle of 8.1 with a spring omega^2 = 10^4 in the general form,
    h = 0.05 (h omega = 5): L_vv = I misses h^2 a a^ Hess U ~ 25, no attempt contracts, every step
    is solved by the Newton chain (simplified Newton from the predictor: no full-Newton restart),
    and the attempts follow the doubling wait exactly (300 steps: 10 attempts, 290 skipped, as the
    Python model of the rule says; the mechanical form's test_stiff_spring_falls_back_and_agrees
    counts only a range). nlu, exact: each attempt factors its s + 1 blocks L_vv and S, each Newton
    iteration its matrix (njev). The trajectory is the Newton engine's within the bound of the
    module docstring. Control: omega^2 = 4, no fallback, no wait, no Newton matrix."""
    cs = compile_system(_stiff(w2), form="general")
    assert cs.form == "general"
    n = 300
    a = run_compiled(cs, fam, 0.0, [1, 0, 0], [0, 1, 0], H, n, 1, kernel="spark")
    b = run_quasi(cs, fam, 0.0, [1, 0, 0], [0, 1, 0], H, n, 1)
    st = b.stats
    assert st["quasi_steps"] + st["quasi_fallbacks"] == n and st["full_newton_steps"] == 0, st
    if all_fall_back:
        attempts, skipped = _waits(n)
        assert (attempts, skipped) == (10, 290)
        assert st["quasi_fallbacks"] == n and st["quasi_steps"] == 0, st
        assert st["multiplier_lu"] == attempts and st["quasi_skipped"] == skipped, st
        assert st["njev"] >= n and st["nlu"] == st["njev"] + (s + 2) * attempts, st
    else:
        assert st["quasi_fallbacks"] == st["quasi_skipped"] == st["njev"] == 0, st
        assert st["multiplier_lu"] == n and st["nlu"] == (s + 2) * n, st
    assert _difference(a, b) <= 1.0, _difference(a, b)


@pytest.mark.parametrize("scene, method, h", [("particle", "gauss-2", 1.0), ("particle", "gauss-2", 0.8),
                                              ("pendulum", "gauss-2", 0.5)])
def test_attempts_between_waits_agree_with_newton(scene, method, h):
    """``general_quasi_steps`` where converging attempts, fallbacks and waits alternate (the general
    form of the particle and the pendulum; measured: h = 1, 13 converged attempts, 41 failed, 146
    skipped; h = 0.8, 160 / 20 / 20; pendulum 176 / 12 / 12): every failed attempt sends at least
    the next step straight to the Newton chain (the back-off is reset to 1, not 0, by a converged
    attempt), the counters add up, and the trajectory is the Newton engine's within the bound of
    the module docstring (measured at most 0.11 of it). Negative control: another method (gauss-3,
    O(h^4) away) breaks the bound."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system, form="general")
    assert cs.form == "general"
    n = 200
    a = run_compiled(cs, method, t0, q0, v0, h, n, 1, kernel="spark")
    b = run_quasi(cs, method, t0, q0, v0, h, n, 1)
    st = b.stats
    assert st["quasi_steps"] > 0 and st["quasi_skipped"] > 0, st
    failed = st["multiplier_lu"] - st["quasi_steps"]
    assert failed > 0 and st["quasi_fallbacks"] == failed + st["quasi_skipped"], st
    assert st["quasi_skipped"] >= failed - 1, st
    assert _difference(a, b) <= 1.0, _difference(a, b)
    other = run_compiled(cs, "gauss-3", t0, q0, v0, h, n, 1, kernel="spark")
    assert _difference(other, b) > 10.0, _difference(other, b)


def test_the_carried_rate_grows_until_it_is_measured_again():
    """The first-increment test's carried rate eta grows as max(eta, eps)^RATE_GROWTH (0.8) at every
    step that does not measure it (``general_quasi_steps``, RADAU5's FACCON), so that a run of
    one-increment steps soon takes a second increment and measures the rate again. relativistic,
    gauss-3, h = 0.05, tol = 1e-6, 200 steps: 60 steps accepted on the carried rate (measured), so
    at most half of them; an eta that shrank instead (eta * 0.8 per step) accepted 198, every step
    after the first two. The trajectory is the Newton engine's (default tol) within 2 N tol scale
    (the module docstring's bound with the run's tol for 8 eps). Control: the carried rate does
    accept steps here (> 0), so the bound is not met by a run that never uses it."""
    n, tol = 200, 1e-6
    ref = ldaspark.integrate("relativistic", "gauss-3", h=0.05, n_steps=n, engine="compiled", newton="full")
    r = ldaspark.integrate("relativistic", "gauss-3", h=0.05, n_steps=n, engine="compiled",
                           newton=ldaspark.Newton(kind="quasi", tol=tol))
    st = r.stats
    assert st["root_finder"]["runs"] == "quasi" and st["quasi_fallbacks"] == 0, st
    assert 0 < st["rate_first_steps"] <= n // 2, st
    scale = max(1.0, float(np.abs(ref.q).max()), float(np.abs(ref.v).max()))
    d = max(float(np.abs(r.q - ref.q).max()), float(np.abs(r.v - ref.v).max()))
    assert d <= 2 * n * tol * scale, d


@pytest.mark.parametrize("scene, method, h, lo, hi", [("relativistic", "gauss-4", 0.1, 1050, 1160),
                                                      ("chaplygin-sleigh", "gauss-3", 0.1, 600, 670)])
def test_the_velocity_block_is_frozen_at_each_stage(scene, method, h, lo, hi):
    """The frozen block is L_vv at each stage's values (and at the end point for (21d)), which the
    iteration's contraction rate, O(h |L_vq| / |L_vv| + h |Lambda| |K_v|), assumes: 200 steps at the
    default tol take 1101 increments (relativistic, gauss-4, h = 0.1) and 638 (chaplygin-sleigh,
    gauss-3, h = 0.1), measured; the band is about +-5%. L_vv taken at one point for all stages
    (planted: the end point) converges to the same root but slower: 1317 and 698 increments, outside
    it. Iteration counts are exact (no BLAS, no fast-math in the kernels). Control: the trajectory
    is the Newton engine's within the bound of the module docstring (the count is not bought with
    accuracy)."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    assert cs.form == "general"
    n = 200
    a = run_compiled(cs, method, t0, q0, v0, h, n, 1, kernel="spark")
    b = run_quasi(cs, method, t0, q0, v0, h, n, 1)
    st = b.stats
    assert st["quasi_fallbacks"] == 0 and lo <= st["quasi_iterations"] <= hi, st
    assert _difference(a, b) <= 1.0, _difference(a, b)


def _rheonomic_particle():
    """A particle in a quadratic potential with the constraint v3 - (1 + t) q1 v1 = 0: k_q depends on t and
    has a component along K = k_v (the h k_q(t1) term of the (21f) row of S is not zero)."""
    import sympy

    from ldaspark.core.system import LagrangianSystem
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2) / 2
    return LagrangianSystem(L, [v[2] - (1 + t) * q[0] * v[0]], q, v, t=t, name="rheonomic-particle")


@pytest.mark.parametrize("method", ["gauss-2", "gauss-4", "lobatto-iiia-iiib-3"])
def test_the_multiplier_matrix_is_the_newton_rows_through_the_frozen_blocks(method):
    """``general_multiplier_matrix``'s S (factored in place) is the Schur complement of the frozen
    matrix of the module docstring: S = C L^-1 B with C the constraint rows (21e, f) in Z, dv and B
    the multiplier columns of rows (21b, d) of the kernels' exact Newton matrix (``general_eval``
    with its Jacobian) at the same iterate, and L = diag(L_vv,1..s, L_vv,1) the Hessians that
    evaluation took at the stage values and the end point. The trajectory tests cannot see S (any
    S that lets the iteration contract gives the same root). Checked through the solve: |S y - r|_inf
    <= 1e3 eps |S|_inf |y|_inf for y = S^-1 r from S's LU (backward stable; measured <= 4e-14).
    relativistic (L_vv depends on v), ball-turntable and a particle with the constraint v3 = (1 + t)
    q1 v1 in the general form (k_q depends on t, along K: frozen at t instead of t + h it misses the rows), a
    random iterate x. Control: S built at 2 h misses the rows at h by far more (measured 8e-4 to
    1.7e-2)."""
    from ldaspark.compiled import kernels_general as KG
    from ldaspark.compiled import kernels_quasi_general as KQG
    from ldaspark.compiled import newton
    from ldaspark.compiled.runner import kernel_spec
    tab = kernel_spec(method, "spark")[1]
    for scene in ("relativistic", "ball-turntable", "rheonomic particle"):
        if scene == "rheonomic particle":
            cs = compile_system(_rheonomic_particle(), form="general")
            t0, q0 = 0.3, np.array([0.5, 0.2, 0.1])
            v0 = np.array([0.4, -0.3, 1.3 * 0.5 * 0.4])        # v3 = (1 + t0) q1 v1
        else:
            sc = get_scene(scene)
            cs = compile_system(sc.system)
            t0, q0, v0 = sc.initial()
            t0, q0, v0 = float(t0), np.array(q0, float), np.array(v0, float)
        assert cs.form == "general"
        s, n, m = tab[1].shape[0], cs.n, cs.m
        sn, sm, NN = s * n, s * m, s * (n + m) + n
        h = 0.05
        x = np.random.default_rng(3).normal(scale=1e-2, size=NN)
        ws = KG.workspace(s, n, m)
        G, J = np.zeros(NN), np.zeros((NN, NN))
        KG.general_eval(cs.model, tab, True, x, t0, q0, v0, h, cs.M, ws, G, J)
        L = np.zeros((sn + n, sn + n))
        for j in range(s):
            L[j * n:(j + 1) * n, j * n:(j + 1) * n] = ws[8][j]
        L[sn:, sn:] = ws[20]
        con, rows = list(range(sn + n, NN)), list(range(sn + n))
        vel, lam = list(range(sn)) + list(range(sn + sm, NN)), list(range(sn, sn + sm))
        S = J[np.ix_(con, vel)] @ np.linalg.solve(L, J[np.ix_(rows, lam)])
        r = np.random.default_rng(4).normal(size=sm)
        for hq, ok in ((h, True), (2 * h, False)):
            wq = KG.workspace(s, n, m)
            KG.general_begin(cs.model, t0, q0, v0, wq)
            KG.general_eval(cs.model, tab, False, x, t0, q0, v0, hq, cs.M, wq, np.zeros(NN), np.zeros((NN, NN)))
            gw = KQG.general_quasi_workspace(s, n, m)
            assert KQG.general_multiplier_matrix(cs.model, tab, hq, t0, x, wq, gw, np.zeros(8, dtype=np.int64))
            y = r.copy()
            newton.lu_solve(gw[7], gw[8], y)
            bound = 1e3 * EPS * np.abs(S).sum(axis=1).max() * np.abs(y).max()
            assert (np.abs(S @ y - r).max() <= bound) == ok, (scene, hq, np.abs(S @ y - r).max(), bound)
