"""The quasi-Newton root finder of the SPARK step (``compiled.kernels_quasi``, ``compiled.quasi``,
``integrate(..., newton="quasi")``) solves the same equations (21) as the compiled Newton engine.

Tolerance of the trajectory comparisons: both root finders stop when the remaining error of the
step's unknowns is estimated at most lim = tol (|x| + |v0|) <= 8 eps * scale (``newton.newton_status``,
scale = max(1, |q|, |v|) over the run), so one step's results differ by at most ~2 lim, and over
N steps of a non-expanding flow by at most N * 2 lim: the bound used is 2 N * 8 eps * scale
(measured: at most 0.16 of it, mp-particles gauss-2, over 10 scenes x 6 families, 300 steps).
"""
import hashlib
import os

import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.compiled import kernels_quasi as KQ
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.compiled.quasi import extrapolation, run_quasi
from ldaspark.core.errors import InputError
from ldaspark.core.system import LagrangianSystem
from ldaspark.models.scenes import get_scene
from quasi_helpers import EPS, trajectory_difference as _difference, waits as _waits

MECH_SCENES = ("particle", "skate", "robot", "mp-particles", "mp-particles-nh", "pendulum", "rolling-disk",
               "rheonomic-skate", "turntable", "contact-oscillator")
FAMILIES = ("gauss-1", "gauss-2", "gauss-3", "gauss-4", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3")
N, H = 300, 0.05


def test_kernel_file_records_its_helpers():
    """numba keys the cached quasi_run on kernels_quasi.py only: HELPERS_SHA256 must be the digest
    of the modules compiled into it, so that editing one rebuilds the kernel."""
    from ldaspark.compiled import kernels_quasi
    d = os.path.dirname(kernels_quasi.__file__)
    h = hashlib.sha256()
    for f in kernels_quasi.HELPERS:
        with open(os.path.join(d, f), "rb") as fh:
            h.update(fh.read())
    assert kernels_quasi.HELPERS_SHA256 == h.hexdigest(), "update HELPERS_SHA256 in ldaspark/compiled/kernels_quasi.py"


def test_extrapolation_reproduces_polynomials():
    """The predictor's weights extrapolate a polynomial of the interpolation degree exactly: the
    velocity nodes are c_j and 0 (degree s; Lobatto: c_j only, degree s - 1), the multipliers' c_j
    (degree s - 1); a polynomial of one degree more is not reproduced (negative control)."""
    from ldaspark.compiled.runner import kernel_spec
    for name, deg in (("gauss-2", 2), ("gauss-3", 3), ("lobatto-iiia-iiib-3", 2)):
        c = kernel_spec(name, "spark")[1][0]
        Ev, El = extrapolation(c)
        t_new = np.concatenate([1 + c, [2.0]])
        for p, ok in ((deg, True), (deg + 1, False)):
            f = (lambda t: (t ** p) + 0.5 * t)      # value 0 at the node t = 0 (the zero increment there)
            err = np.abs(Ev @ f(c) - f(t_new)).max()
            assert (err < 1e-12) == ok, (name, p, err)
        g = (lambda t: t ** (len(c) - 1) - 3.0)
        assert np.abs(El @ g(c) - g(1 + c)).max() < 1e-12


@pytest.mark.parametrize("scene", MECH_SCENES)
def test_same_trajectory_as_newton_on_every_mechanical_scene(scene):
    """Every mechanical scene, gauss-1..4 and lobatto-iiia-iiib-2..3, 300 steps of h = 0.05: the
    quasi-Newton and Newton trajectories agree within the bound of the module docstring. Negative
    control: another method (gauss-2 against lobatto-iiia-iiib-2, O(h^2) apart) breaks the bound."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    for fam in FAMILIES:
        a = run_compiled(cs, fam, t0, q0, v0, H, N, 1, kernel="spark")
        b = run_quasi(cs, fam, t0, q0, v0, H, N, 1)
        assert b.stats["steps"] == N and b.stats["quasi_steps"] + b.stats["quasi_fallbacks"] == N
        assert _difference(a, b) <= 1.0, (scene, fam, _difference(a, b))
        assert b.stats["root_finder"] == "quasi" and b.stats["quasi_iterations"] >= N
    other = run_compiled(cs, "lobatto-iiia-iiib-2", t0, q0, v0, H, N, 1, kernel="spark")
    b = run_quasi(cs, "gauss-2", t0, q0, v0, H, N, 1)
    if scene not in ("skate", "rolling-disk", "rheonomic-skate", "turntable"):
        # (on those four the stage polynomials are exact: every method gives the same trajectory)
        assert _difference(other, b) > 10.0


def test_order_2s_with_the_quasi_root_finder():
    """skate (closed form), T = 2: the error of gauss-2 falls by 2^4 per halving of h (slope in
    [3.6, 4.4]), gauss-1 by 2^2 (slope in [1.6, 2.4]); the two slopes differ (negative control)."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    q_ex = np.asarray(sc.exact_solution(2.0)[0], float)
    for fam, p in (("gauss-1", 2), ("gauss-2", 4)):
        err = []
        for h in (0.1, 0.05):
            r = run_quasi(cs, fam, t0, q0, v0, h, int(round(2.0 / h)), 1000)
            err.append(float(np.abs(r.q[-1] - q_ex).max()))
        slope = np.log2(err[0] / err[1])
        assert p - 0.4 <= slope <= p + 0.4, (fam, err, slope)


def _stiff(w2):
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - sympy.Integer(w2) / 2 * (q[0] ** 2 + q[1] ** 2)
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name=f"stiff-particle-{w2}")


@pytest.mark.parametrize("w2, all_fall_back", [(10000, True), (4, False)])
def test_stiff_spring_falls_back_and_agrees(w2, all_fall_back):
    """The particle of 8.1 with a spring omega^2 = 10^4 at h = 0.05 (h omega = 5): the frozen
    velocity block misses h^2 a a^ Hess U ~ 25, the iteration does not contract, and every step
    falls back to the Newton chain (counted), agreeing with the Newton engine within the bound;
    after the first failures the attempts are rare (the doubling wait of kernels_quasi.QS_SKIPPED).
    Control: omega^2 = 4 (the paper's particle) needs no fallback. The velocity block frozen at M
    (curvature=False); with Hess U in it see tests/compiled/test_quasi_curvature.py."""
    cs = compile_system(_stiff(w2))
    for fam in ("gauss-2", "gauss-3"):
        a = run_compiled(cs, fam, 0.0, [1, 0, 0], [0, 1, 0], H, N, 1, kernel="spark")
        b = run_quasi(cs, fam, 0.0, [1, 0, 0], [0, 1, 0], H, N, 1, curvature=False)
        assert _difference(a, b) <= 1.0
        if all_fall_back:
            assert b.stats["quasi_fallbacks"] == N and b.stats["quasi_steps"] == 0 and b.stats["njev"] >= N
            # attempts after waits of 1, 2, 4, ..., 64 steps: 7 in the first 134 steps, then one per 65
            assert N - 15 <= b.stats["quasi_skipped"] < N
        else:
            assert b.stats["quasi_fallbacks"] == b.stats["quasi_skipped"] == 0 and b.stats["njev"] == 0


def test_integrate_newton_quasi():
    """Through ldaspark.integrate: the counters in Result.stats, the same trajectory as the
    default compiled Newton; refused where it cannot run (generic engine, mpmath, comparators,
    a nonideal term)."""
    a = ldaspark.integrate("particle", "gauss-3", h=0.1, n_steps=200, engine="compiled", newton="simplified")
    b = ldaspark.integrate("particle", "gauss-3", h=0.1, n_steps=200, engine="compiled", newton="quasi")
    assert b.engine == "compiled" and b.stats["root_finder"]["kind"] == "quasi" and a.stats["root_finder"]["kind"] == "simplified"
    # the default root finder runs it here (a small mechanical system, a SPARK tableau): the same run
    auto = ldaspark.integrate("particle", "gauss-3", h=0.1, n_steps=200, engine="compiled")
    assert auto.stats["root_finder"]["kind"] == "auto" and auto.stats["root_finder"]["runs"] == "quasi"
    assert np.array_equal(auto.q, b.q) and auto.stats["quasi_iterations"] == b.stats["quasi_iterations"]
    assert b.stats["quasi_steps"] == 200 and b.stats["multiplier_lu"] == 200 and b.stats["njev"] == 0
    assert a.stats["njev"] >= 200
    assert _difference(a, b) <= 1.0
    for kw in (dict(engine="generic"), dict(dps=30)):
        with pytest.raises(InputError, match="quasi"):
            ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=3, newton="quasi", **kw)
    with pytest.raises(InputError, match="comparator|refuses Newton kind=.quasi."):
        ldaspark.integrate("skate", "lobatto-iiia-iiib-2-leapfrog", h=0.1, n_steps=3, newton="quasi",
                           engine="compiled")
    with pytest.raises(InputError, match="nonideal"):      # the general form runs: test_quasi_general.py
        ldaspark.integrate("friction-skate", "gauss-2", h=0.1, n_steps=3, newton="quasi", engine="compiled")
    with pytest.raises(InputError, match="newton"):
        ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=3, newton="quasy", engine="compiled")


def test_chunked_run_sums_the_quasi_counters(monkeypatch):
    """A run longer than one kernel call (chunks.COMPILED_CHUNK, lowered to 50 here) is a sequence of
    quasi-Newton calls: the counters add up over the chunks and the trajectory agrees with one call."""
    one = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=120, engine="compiled", newton="quasi")
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 50)
    b = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=120, engine="compiled", newton="quasi")
    assert b.stats["quasi_steps"] == b.stats["multiplier_lu"] == 120 and b.stats["root_finder"]["kind"] == "quasi"
    assert one.stats["quasi_steps"] == 120 and len(b.t) == 121
    assert _difference(one, b) <= 1.0


def test_single_ratio_rate_test_at_the_second_increment():
    """skate, gauss-8, h = 1.25: the second increment contracts fast and lies within 1e3 round-off
    limits, so RADAU5's one-ratio test stops there (2 iterations per step, measured 2.00025; the
    two-ratio rule of newton.newton_status needed 3); at h = 2.5 it does not apply (measured 2.99),
    and either way the trajectory is the Newton engine's within the bound."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    for h, lo, hi in ((1.25, 2.0, 2.01), (2.5, 2.9, 3.0)):
        b = run_quasi(cs, "gauss-8", t0, q0, v0, h, 400, 1)
        a = run_compiled(cs, "gauss-8", t0, q0, v0, h, 400, 1)
        assert lo <= b.stats["mean_iterations"] <= hi, (h, b.stats["mean_iterations"])
        assert _difference(a, b) <= 1.0


def test_run_quasi_defaults_keep_every_step_as_documented():
    """run_quasi's defaults are run_compiled's (every = 1, compensated sums, the default tol,
    50 iterations, the collocation predictor): a call without them keeps every step and equals
    the call that spells them out, bit for bit."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    short = run_quasi(cs, "gauss-2", t0, q0, v0, 0.1, 7)
    spelled = run_quasi(cs, "gauss-2", t0, q0, v0, 0.1, 7, 1, True, None, 50, "collocation", True)
    assert len(short.t) == 8 and np.array_equal(short.t, spelled.t)
    assert np.array_equal(short.q, spelled.q) and np.array_equal(short.psi, spelled.psi)


def test_the_collocation_predictor_is_the_one_of_the_method_run():
    # the predictor weights (``extrapolation(c)``) are cached per method: a run of gauss-2 first
    # must not hand its weights to lobatto-iiia-iiib-2 (also s = 2, nodes c = 0, 1 instead of
    # 1/2 -+ sqrt(3)/6): the same counters as a run from an empty cache (measured 297 Newton
    # iterations; with gauss-2's weights 354)
    from ldaspark.compiled import quasi
    kw = dict(n_steps=20, h=0.5, guard=False, engine="compiled", newton="quasi")
    keys = ("newton_iterations", "quasi_iterations", "quasi_steps", "quasi_fallbacks")
    quasi._EXTRAP.clear()
    fresh = ldaspark.integrate("pendulum", "lobatto-iiia-iiib-2", **kw)
    quasi._EXTRAP.clear()
    ldaspark.integrate("pendulum", "gauss-2", **kw)
    after = ldaspark.integrate("pendulum", "lobatto-iiia-iiib-2", **kw)
    assert fresh.status == after.status == 0
    assert [after.stats[k] for k in keys] == [fresh.stats[k] for k in keys]
    assert np.array_equal(after.q, fresh.q)


@pytest.mark.parametrize("scene", ("rheonomic-skate", "turntable"))
def test_a_rheonomic_scene_started_at_t0_not_zero_agrees_with_newton(scene):
    """The stage times of the quasi-Newton kernel are t0 + (step + c_i) h: on the scenes whose L
    or k depend on t, started from a point of their trajectory at t = 0.75 (15 steps in, so the
    data are consistent there), quasi-Newton and Newton agree within the bound, as from t = 0."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    head = run_compiled(cs, "gauss-2", t0, q0, v0, H, 15, 1, kernel="spark")
    t1, q1, v1 = float(head.t[-1]), head.q[-1], head.v[-1]
    assert abs(t1 - (float(t0) + 0.75)) < 1e-12 and t1 != 0.0
    for fam in ("gauss-2", "lobatto-iiia-iiib-3"):
        a = run_compiled(cs, fam, t1, q1, v1, H, 100, 1, kernel="spark")
        b = run_quasi(cs, fam, t1, q1, v1, H, 100, 1)
        assert b.t[0] == t1 and _difference(a, b) <= 1.0, (scene, fam, _difference(a, b))


def _every_term_system(dU=0):
    """A mechanical system where every term of (1) is nonzero and depends on t: M non-diagonal,
    U(t, q) with a Hessian that moves (the curvature block refreshes), K(t, q) and b(t, q); dU
    adds dU q1^2 to U (the negative control)."""
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    M = sympy.Matrix([[2, sympy.Rational(1, 5), 0, 0], [sympy.Rational(1, 5), 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 3]])
    vv = sympy.Matrix(v)
    U = (1 + sympy.sin(t) / 3) * (q[0] ** 2 + 2 * q[1] ** 2) / 2 + q[0] ** 3 / 5 + q[2] ** 2 * q[3] ** 2 / 4 \
        + sympy.Float(dU) * q[0] ** 2
    k = [v[2] - q[1] * v[0] + sympy.cos(t) * v[3] / 4 + sympy.sin(q[3]) / 10 + sympy.cos(t) / 20,
         v[3] + (1 + t / 10) * q[0] * v[1] - sympy.sin(2 * t) / 10]
    L = (vv.T * M * vv)[0, 0] / 2 - U
    return compile_system(LagrangianSystem(L, k, q, v, t=t, name=f"every-term-mechanical-{dU}"))


def _every_term_start(t0):
    """q0 and a v0 on k(t0, q0, v) = 0 (k is linear in v: v3, v4 solved for)."""
    q0 = np.array([0.3, -0.2, 0.1, 0.2])
    v0 = np.array([0.5, 0.4, 0.0, 0.0])
    K = np.array([[-q0[1], 0.0, 1.0, np.cos(t0) / 4], [0.0, (1 + t0 / 10) * q0[0], 0.0, 1.0]])
    b = np.array([np.sin(q0[3]) / 10 + np.cos(t0) / 20, -np.sin(2 * t0) / 10])
    v0[2:] = np.linalg.solve(K[:, 2:], -(b + K[:, :2] @ v0[:2]))
    return q0, v0


@pytest.mark.parametrize("family", ["gauss-2", "gauss-4", "lobatto-iiia-iiib-3"])
def test_every_term_of_1_nonzero_quasi_agrees_with_newton(family):
    """The quasi step (``quasi_steps``, its re-entry after curvature refreshes, the multiplier
    matrix) against the kernels' Newton on a system where M, U, K, b are all nonzero and U, K, b
    depend on t, from t0 = 0.3, 200 steps: within the bound of the module docstring (2 N 8 eps
    scale). Control: Newton on U + 1e-9 q1^2 is far outside that bound."""
    t0 = 0.3
    q0, v0 = _every_term_start(t0)
    cs = _every_term_system()
    a = run_compiled(cs, family, t0, q0, v0, 0.05, 200, 1, kernel="spark")
    qn = run_quasi(cs, family, t0, q0, v0, 0.05, 200, 1)
    assert qn.stats["quasi_steps"] > 0 and qn.stats["curvature_steps"] > 0, qn.stats
    assert np.abs(qn.constraint).max() < 1e-12
    assert _difference(a, qn) <= 1.0, _difference(a, qn)
    other = run_compiled(_every_term_system(1e-9), family, t0, q0, v0, 0.05, 200, 1, kernel="spark")
    assert _difference(other, qn) > 10.0, _difference(other, qn)


@pytest.mark.parametrize("scene", ["particle", "relativistic"])
def test_the_quasi_root_finder_counts_its_factorisations(scene):
    """``nlu`` counts LU factorisations on every engine; a quasi-Newton run factors one multiplier
    matrix a step (``multiplier_lu``) and reported nlu = 0 (the mechanical and the general form).
    Control: the kernels' Newton on the same run counts its own."""
    q = ldaspark.integrate(scene, "gauss-2", t_span=(0, 1), h=0.1, engine="compiled", newton="quasi")
    assert q.success and q.stats["multiplier_lu"] >= 10
    assert q.nlu == q.stats["nlu"] >= q.stats["multiplier_lu"]
    nw = ldaspark.integrate(scene, "gauss-2", t_span=(0, 1), h=0.1, engine="compiled", newton="full")
    assert nw.nlu >= 10 and "multiplier_lu" not in nw.stats


def test_a_loose_tol_stops_after_one_increment_on_the_carried_rate(monkeypatch):
    """Newton(tol=...) trades accuracy for speed: RADAU5's first-iteration test (``kernels_quasi.
    quasi_newton``'s eta, the rate theta / (1 - theta) of the last measured step grown as
    max(eta, eps)^0.8 per step) accepts the first increment when eta |dx_1| <= RATE_KAPPA tol
    (|x| + |v0|). skate, gauss-4, h = 0.2, 500 steps (the predictor's error |dx_1| ~ 1e-4, the
    rate ~ 1e-12): at tol = 1e-8 most steps take one increment (measured 1.25 a step, 376 of 500
    accepted on the rate; before the test every step took 2 at any tol <= 1e-4), and the
    trajectory is the default tol's within the bound of the looser limit, 2 N tol scale (the
    module docstring's bound with tol for 8 eps; measured 2e-15). Control: at the default tol
    (8 eps) |dx_1| is far above round-off, no step stops after one increment."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    tight = run_quasi(cs, "gauss-4", t0, q0, v0, 0.2, 500, 1)
    loose = run_quasi(cs, "gauss-4", t0, q0, v0, 0.2, 500, 1, True, 1e-8)
    assert tight.stats["rate_first_steps"] == 0 and tight.stats["mean_iterations"] >= 2.0
    assert loose.stats["rate_first_steps"] >= 250 and loose.stats["mean_iterations"] <= 1.5, loose.stats
    assert loose.stats["quasi_fallbacks"] == 0
    assert _difference(tight, loose) * 8 * EPS <= 1e-8
    # through ldaspark.integrate, with the public option
    r = ldaspark.integrate("skate", "gauss-4", h=0.2, n_steps=500, engine="compiled",
                           newton=ldaspark.Newton(tol=1e-8))
    assert r.stats["root_finder"]["runs"] == "quasi" and r.stats["rate_first_steps"] == loose.stats["rate_first_steps"]
    assert np.array_equal(r.q, loose.q)
    # a chunked run (chunks.COMPILED_CHUNK lowered to 200) sums the counter over its blocks
    monkeypatch.setattr("ldaspark.core.chunks.COMPILED_CHUNK", 200)
    c = ldaspark.integrate("skate", "gauss-4", h=0.2, n_steps=500, engine="compiled",
                           newton=ldaspark.Newton(tol=1e-8))
    assert c.stats["rate_first_steps"] >= 250 and abs(c.stats["rate_first_steps"] - r.stats["rate_first_steps"]) <= 6


@pytest.mark.parametrize("scene,method,h,tol", [("skate", "gauss-4", 0.2, 1e-1), ("particle", "gauss-4", 0.2, 1e-1),
                                                ("relativistic", "gauss-2", 0.05, 1e-2)])
def test_rate_first_steps_counts_only_the_steps_the_carried_rate_accepted(scene, method, h, tol):
    """``rate_first_steps`` counts the steps accepted after one increment by the carried rate
    (RADAU5's first-iteration test, eta |dx_1| <= RATE_KAPPA lim); it counted every one-increment
    step while a rate was carried, also those whose |dx_1| <= lim passed the plain test, where the
    rate decides nothing (100 steps: skate and particle at tol = 0.1, relativistic (general form)
    at tol = 1e-2: 99 each, every step after step 0). At these tol the plain test passes every
    first increment after step 0 (|dx_1| ~ 1e-4 relative from the collocation predictor; lim = tol
    (|x| + |v0|)): one increment a step, none accepted by the rate. Control: at tol = 1e-8 the
    plain test fails on the skate (|dx_1| >> 1e-8 lim) and the rate accepts most first increments
    (measured 74 of 100, before and after)."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    st = run_quasi(cs, method, t0, q0, v0, h, 100, 1, True, tol).stats
    # step 0 (from the zero guess) takes 2 increments and measures a rate; every later step 1
    assert st["quasi_fallbacks"] == 0 and st["quasi_iterations"] == 101, st
    assert st["rate_first_steps"] == 0, st
    if scene == "skate":
        tight = run_quasi(cs, method, t0, q0, v0, h, 100, 1, True, 1e-8).stats
        assert 50 <= tight["rate_first_steps"] < 100 and tight["quasi_iterations"] > 101, tight


@pytest.mark.parametrize("scene", ["particle", "robot", "chaplygin-sleigh"])
def test_a_ratio_at_round_off_is_not_carried_as_the_rate(scene):
    """The first-increment test carries the step's rate theta / (1 - theta); it took the LAST
    ratio |dx_k| / |dx_k-1|, which at a last increment at round-off is no rate: particle,
    lobatto-iiia-iiib-2, h = 0.1, tol = 1e-9, step 0 measured 9.9e-4 / 0.199 = 5e-3, then 8.6e-19 /
    9.9e-4 = 8.7e-16, carried (grown to 8.9e-13), so steps 1 and 2 accepted first increments of 0.29
    and 0.26: q off the root by 2e-5 after step 1 and by 3e-3 after 40 steps (robot 6e-3; the general
    kernel alike, chaplygin-sleigh 1.2e-3, where the guard stopped the run with status -4). The
    rate is now the slowest ratio the step measured. Bound: the trajectory is the generic engine's
    (default tol) within 2 N tol scale, the looser limit's bound of the module docstring (tol for
    8 eps), 5e-7 at scale ~ 3; measured after ~2e-10. Control: at the default tol both agree before
    and after (a wrong rate is only accepted against a loose tol)."""
    n, tol = 40, 1e-9
    ref = ldaspark.integrate(scene, "lobatto-iiia-iiib-2", n_steps=n, h=0.1, engine="generic")
    scale = max(1.0, float(np.abs(ref.q).max()), float(np.abs(ref.v).max()))
    for t in (None, tol):
        q = ldaspark.integrate(scene, "lobatto-iiia-iiib-2", n_steps=n, h=0.1, tol=t, engine="compiled",
                               newton="quasi")
        assert q.status == 0 and q.stats["root_finder"]["runs"] == "quasi", q.message
        d = max(float(np.abs(q.q - ref.q).max()), float(np.abs(q.v - ref.v).max()))
        assert d <= 2 * n * (8 * EPS if t is None else t) * scale, (t, d)


def test_a_carried_rate_is_applied_only_to_first_increments_of_its_size():
    """The carried rate of the first-increment test is a ratio measured on one first increment; a
    first increment far from that size comes from another predictor error, on which it says
    nothing (``kernels_quasi.RATE_SPAN``). General kernel: ball-turntable, gauss-5, h = 0.8, tol =
    1e-12: step 0's zero-increment guess measured 0.065 then 1.2e-13 (a ratio at round-off), and
    steps 1 and 2 accepted first increments of 1.9e-6 on it, where the collocation predictor's
    error contracts at 0.1-0.25: 100 steps off the Newton run by 6.1e-8, against the bound of the
    looser limit, 2 N tol scale = 1.2e-8 (the module docstring's, scale = 62); measured after 9.8e-12.
    Mechanical kernel: particle, gauss-6, h = 0.4, tol = 1e-8, step 11027: a rate measured on a
    first increment of 0.032 accepted one of 9.4e-5 whose error contracted at 4.8e-3, not 1.5e-5:
    the difference to the Newton run grew by 1.55e-7 in that step (the energy jumped by 2.1e-7,
    ~4.5e-11 at the other steps). Bound on that growth: one step adds the two roots' stopping
    errors, at most 2 lim <= 2 tol scale = 6.6e-8 (the Newton run's 8 eps is negligible), plus the
    flow's growth of the difference already there (below 5e-10 up to that step); measured after
    6.4e-11. Controls: at the default tol both runs agree within 2 N 8 eps scale before and after;
    the carried rate still serves where the first increments keep their size (ball-turntable at tol
    = 1e-6: 79 of 100 steps after one increment)."""
    ref = ldaspark.integrate("ball-turntable", "gauss-5", h=0.8, n_steps=100, engine="compiled", newton="full")
    scale = max(1.0, float(np.abs(ref.q).max()), float(np.abs(ref.v).max()))
    for t in (None, 1e-12):
        r = ldaspark.integrate("ball-turntable", "gauss-5", h=0.8, n_steps=100, engine="compiled",
                               newton=ldaspark.Newton(kind="quasi", tol=t))
        assert r.status == 0 and r.stats["root_finder"]["runs"] == "quasi", r.message
        d = max(float(np.abs(r.q - ref.q).max()), float(np.abs(r.v - ref.v).max()))
        assert d <= 2 * 100 * (8 * EPS if t is None else t) * scale, (t, d)
    loose = ldaspark.integrate("ball-turntable", "gauss-5", h=0.8, n_steps=100, engine="compiled",
                               newton=ldaspark.Newton(kind="quasi", tol=1e-6))
    assert loose.stats["rate_first_steps"] >= 50, loose.stats
    n = 11030
    ref = ldaspark.integrate("particle", "gauss-6", h=0.4, n_steps=n, engine="compiled", newton="full")
    scale = max(1.0, float(np.abs(ref.q).max()), float(np.abs(ref.v).max()))
    for t in (None, 1e-8):
        r = ldaspark.integrate("particle", "gauss-6", h=0.4, n_steps=n, engine="compiled",
                               newton=ldaspark.Newton(kind="quasi", tol=t))
        assert r.status == 0 and r.stats["root_finder"]["runs"] == "quasi", r.message
        d = np.maximum(np.abs(r.q - ref.q).max(axis=1), np.abs(r.v - ref.v).max(axis=1))
        if t is None:
            assert d.max() <= 2 * n * 8 * EPS * scale, d.max()
        else:
            assert np.diff(d).max() <= 2 * t * scale, (int(np.argmax(np.diff(d))), np.diff(d).max())


# --- the curvature block's refresh as a re-entry of quasi_steps ------------------------------
# The curvature block's refresh as a re-entry of ``kernels_quasi.quasi_steps``: the steps run in
# one call that is left only when the frozen Hess U needs a new decomposition; ``quasi_loop`` runs
# ``curvature_refresh`` and re-enters at that step with istate[IS_REFRESHED] set. The state carried
# across the re-entry (istate, fstate) must make the run the one of a single loop:
#
# * a refreshed step is counted once, decomposes once and starts without a carried rate (another
#   frozen block: ``quasi_newton``'s eta is reset), so it is never a ``rate_first_steps`` step;
# * the wait and back-off after failed attempts (QS_SKIPPED) continue across refreshes.
#
# A Hessian that is stale at every step: the particle of 8.1 with a free coordinate q4 (q4 = v4 = 0
# stays so: its force is -g(t) q4 = 0) and U = q1^2 + q2^2 + g(t) q4^2 / 2, g = 3 + 2 sin(pi t / h):
# at the step midpoints t_k + h / 2, g alternates 5, 1, 5, ... (|H - H_frozen| = 4 > CURV_STALE_REL
# |H| = 1.25), so every step refreshes, while the motion (q1, q2, q3) is that of the particle and the
# carried rate accepts first increments at a loose tol (the control: g = 3, one refresh).
#
# Tolerance of the trajectory comparison: that of tests/compiled/test_kernels_quasi.py (both root
# finders stop at lim = tol (|x| + |v0|) <= 8 eps scale: N_REENTRY steps differ by at most 2 N 8 eps scale).

N_REENTRY = 30              # < CURV_WARMUP: the curvature block is never switched off here


def _particle_with_free_coordinate(h, alternating):
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    g = 3 + 2 * sympy.sin(sympy.pi * t / sympy.Rational(h)) if alternating else sympy.Integer(3)
    U = q[0] ** 2 + q[1] ** 2 + g * q[3] ** 2 / 2
    L = sum(vi ** 2 for vi in v) / 2 - U
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, t=t,
                                           name=f"particle-q4-{h}-{'alternating' if alternating else 'constant'}"))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("method, h, tol", [("gauss-2", 0.1, 1e-3), ("gauss-4", 0.1, 1e-6)])
def test_a_refreshed_step_is_counted_once_and_never_uses_the_carried_rate(method, h, tol):
    """Every step refreshes: curvature_refreshes = curvature_steps = N_REENTRY (one count per step), nlu =
    multiplier_lu + n per refresh (no fallback), and no step is accepted on the carried rate
    (rate_first_steps = 0). Measured with the rate kept across the re-entry (``refreshes -= 1``
    dropped in quasi_steps): 23 and 19 of the 30 steps accepted on it, and a refresh counted twice
    or a re-entry flag never cleared break the counts. Control: g constant, one refresh, and the
    same run accepts steps on the carried rate (so the zero above is evidence). The run with a
    refresh at every step agrees with the Newton engine within the bound."""
    cs = _particle_with_free_coordinate(h, True)
    q0, v0 = [1, 0, 0, 0], [0, 1, 0, 0]
    st = run_quasi(cs, method, 0.0, q0, v0, h, N_REENTRY, tol=tol).stats
    assert st["quasi_fallbacks"] == 0 and st["quasi_steps"] == N_REENTRY, st
    assert st["curvature_refreshes"] == st["curvature_steps"] == N_REENTRY, st
    assert st["nlu"] == st["multiplier_lu"] + cs.n * st["curvature_refreshes"], st
    assert st["rate_first_steps"] == 0, st
    ctl = run_quasi(_particle_with_free_coordinate(h, False), method, 0.0, q0, v0, h, N_REENTRY, tol=tol).stats
    assert ctl["curvature_refreshes"] == 1 and ctl["curvature_steps"] == N_REENTRY, ctl
    assert ctl["rate_first_steps"] > 0, ctl
    a = run_compiled(cs, method, 0.0, q0, v0, h, N_REENTRY, 1, kernel="spark")
    b = run_quasi(cs, method, 0.0, q0, v0, h, N_REENTRY)
    assert b.stats["curvature_refreshes"] == N_REENTRY
    assert _difference(a, b) <= 1.0


def _stiff_quartic():
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    r2 = q[0] ** 2 + q[1] ** 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (5000 * r2 + 2000 * r2 ** 2)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="stiff-quartic-particle"))


def _quartic():
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    r2 = q[0] ** 2 + q[1] ** 2
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - (r2 + r2 ** 2 / 4)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name="quartic-particle-1/4"))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_the_wait_after_failed_attempts_continues_across_refreshes():
    """A stiff varying spring, U = 5000 r^2 + 2000 r^4 (r^2 = q1^2 + q2^2), gauss-2, h = 0.2: no
    quasi-Newton attempt converges (every step is solved by the Newton chain) and the curvature
    block is refreshed at several attempts; the waits between attempts are those of the doubling
    rule all the same (exact: 300 steps, 10 attempts, 290 skipped; measured 6 refreshes). Measured
    with the back-off reset at a re-entered step (istate[IS_BACKOFF] = 1 there): 26 attempts, 274
    skipped, 16 refreshes. Control of the model: the same rule with the curvature off (no refresh)."""
    cs = _stiff_quartic()
    n = 300
    attempts, skipped = _waits(n)
    assert (attempts, skipped) == (10, 290)
    for curvature in (True, False):
        st = run_quasi(cs, "gauss-2", 0.0, [1, 0, 0], [0, 1, 0], 0.2, n, curvature=curvature).stats
        assert st["quasi_steps"] == 0 and st["quasi_fallbacks"] == n, st
        assert (curvature and st["curvature_refreshes"] >= 2) or (not curvature and st["curvature_refreshes"] == 0), st
        assert st["quasi_skipped"] == skipped and st["multiplier_lu"] == attempts, st


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("which, h, n_steps, every", [("quartic", 0.2, 300, 1), ("quartic", 1.0, 100, 3),
                                                      ("stiff", 0.2, 120, 1)])
def test_the_specialised_kernel_returns_the_same_bits_across_refreshes(which, h, n_steps, every):
    """The kernel specialised to (s, n, m) = (2, 3, 1) (``specialised``: kernels_quasi's text with
    the sizes as constants, the re-entry included) against the generic one, every output and
    counter equal, on runs that re-enter quasi_steps many times: U = r^2 + r^4 / 4 at h = 0.2 (16
    refreshes, then the M-only block after CURV_WARMUP) and at h = 1 with save_every = 3 (refreshes
    between fallbacks and waits: 12 refreshes, 94 fallbacks, 78 skipped), the stiff quartic
    (refreshes at failed attempts, every step by the Newton chain), t0 = 0.7. Control: the
    comparison sees the last-bit change of Kahan summation off."""
    from ldaspark.compiled import specialised as SP
    ep = SP.build(2, 3, 1)
    cs = _quartic() if which == "quartic" else _stiff_quartic()
    out = []
    for e, comp in ((None, True), (ep, True), (None, False)):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(SP, "kernel", lambda *a, e=e: e)
            mp.setattr(SP, "note", lambda *a: None)
            out.append(run_quasi(cs, "gauss-2", 0.7, [1, 0, 0], [0, 1, 0], h, n_steps, every, comp))
    gen, spec, ctl = out
    assert spec.stats["kernel_specialised"] and not gen.stats["kernel_specialised"]
    assert gen.stats["curvature_refreshes"] >= 6, gen.stats

    def same(a, b):
        arrays = all(np.array_equal(getattr(a, f), getattr(b, f))
                     for f in ("t", "q", "v", "energy", "constraint", "psi"))
        keys = set(a.stats) - {"kernel_specialised"}
        return arrays and all(a.stats[k] == b.stats[k] for k in keys)

    assert same(gen, spec)
    assert not same(gen, ctl)


def _particle_with_an_overflowing_hessian():
    """The particle of 8.1 with the free coordinate q4 of stiffness g(t) = 1 + exp(800 - 10^6 (t - 9/8)^2):
    Hess U has g = inf (exp overflows) at t = 9/8 and g = 1 at the stage times of a step of h = 0.25
    whose midpoint is 9/8 (10^6 ((c_i - 1/2) h)^2 >= 5200 for gauss-2), so the step itself is that of
    the particle (q4 = v4 = 0 stays so) while ``curvature_refresh`` sees a Hessian that is not finite."""
    t = sympy.Symbol("t")
    q, v = list(sympy.symbols("q1:5")), list(sympy.symbols("v1:5"))
    g = 1 + sympy.exp(800 - 10 ** 6 * (t - sympy.Rational(9, 8)) ** 2)
    L = sum(vi ** 2 for vi in v) / 2 - (q[0] ** 2 + q[1] ** 2 + g * q[3] ** 2 / 2)
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, t=t, name="particle-q4-overflow"))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("method", ["gauss-2", "gauss-4"])
def test_a_failed_refresh_leaves_its_step_to_the_mass_block_and_the_next_step_refreshes(method):
    """t0 = 1, h = 0.25: step 0's midpoint is t = 9/8, its Hessian not finite, so the first
    decomposition fails (counted, no LU factored: nlu = multiplier_lu); the re-entered step runs
    the M-only block (curvature_steps 0) and converges without the Newton chain; step 1 decomposes
    again (2 refreshes, n = 4 LUs) and the remaining steps use it. Measured with the re-entered step
    using the curvature block whatever the refresh returned: the zero block's S is singular and the
    step falls back. Control: t0 = 0, the pole at step 4's midpoint, where a frozen block exists:
    |H - H_frozen| = inf is not above CURV_STALE_REL |H| = inf, the block is kept (one refresh, every
    step a curvature step). The trajectory is the Newton engine's within the bound."""
    cs = _particle_with_an_overflowing_hessian()
    q0, v0 = [1, 0, 0, 0], [0, 1, 0, 0]
    one = run_quasi(cs, method, 1.0, q0, v0, 0.25, 1).stats
    assert one["curvature_refreshes"] == 1 and one["curvature_steps"] == 0, one
    assert one["quasi_steps"] == 1 and one["quasi_fallbacks"] == 0 and one["nlu"] == one["multiplier_lu"] == 1, one
    n = 40
    b = run_quasi(cs, method, 1.0, q0, v0, 0.25, n)
    st = b.stats
    assert st["curvature_refreshes"] == 2 and st["curvature_steps"] == n - 1, st
    assert st["quasi_fallbacks"] == 0 and st["nlu"] == st["multiplier_lu"] + cs.n, st
    a = run_compiled(cs, method, 1.0, q0, v0, 0.25, n, 1, kernel="spark")
    assert _difference(a, b) <= 1.0
    ctl = run_quasi(cs, method, 0.0, q0, v0, 0.25, n).stats
    assert ctl["curvature_refreshes"] == 1 and ctl["curvature_steps"] == n, ctl


def _particle_with_a_moving_stiffness(h, v4, alternating):
    """The particle of 8.1 with two free coordinates: q4 moves at the constant speed v4 (no force
    on it while q5 = 0) and q5 (= v5 = 0, so it stays 0) has the stiffness f(q4) = 3 + 2 sin(pi q4 /
    (v4 h)): along the run f is 5, 1, 5, ... at the step midpoints q4 = v4 (k + 1/2) h, where
    ``quasi_steps`` takes Hess U (q + h v / 2), and 3 at the steps' start points q4 = v4 k h.
    alternating False: f = 3 (the control)."""
    q, v = list(sympy.symbols("q1:6")), list(sympy.symbols("v1:6"))
    f = 3 + 2 * sympy.sin(sympy.pi * q[3] / (sympy.Rational(v4) * sympy.Rational(h))) if alternating else 3
    U = q[0] ** 2 + q[1] ** 2 + f * q[4] ** 2 / 2
    L = sum(vi ** 2 for vi in v) / 2 - U
    return compile_system(LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v,
                                           name=f"particle-q5-{h}-{v4}-{'alternating' if alternating else 'constant'}"))


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_the_hessian_is_frozen_at_the_predicted_midpoint_in_q():
    """``quasi_steps`` decides on a new decomposition from Hess U at the predicted midpoint (t + h/2,
    q + h v / 2). A Hessian that alternates along q (``_particle_with_a_moving_stiffness``, v4 = 1/2,
    h = 0.1): stale at every midpoint, so every step refreshes (N_REENTRY of N_REENTRY), where a
    Hessian taken at q (q + 0 h v, measured: 1 refresh, f = 3 + O(eps) at every start point) or at
    q + h / (2 v) (1 refresh; v4 != 1 tells the two apart) would see it constant. The time-alternating
    test above checks the time t + h/2 only. Control: the constant stiffness, one refresh. The run
    is the Newton engine's within the bound of the module docstring."""
    h, v4 = 0.1, 0.5
    q0, v0 = [1, 0, 0, 0, 0], [0, 1, 0, v4, 0]
    cs = _particle_with_a_moving_stiffness(h, v4, True)
    b = run_quasi(cs, "gauss-2", 0.0, q0, v0, h, N_REENTRY)
    st = b.stats
    assert st["quasi_fallbacks"] == 0 and st["curvature_refreshes"] == st["curvature_steps"] == N_REENTRY, st
    assert float(b.q[-1][3]) == pytest.approx(v4 * h * N_REENTRY, rel=1e-12)   # q4 moved as planned
    ctl = run_quasi(_particle_with_a_moving_stiffness(h, v4, False), "gauss-2", 0.0, q0, v0, h, N_REENTRY).stats
    assert ctl["curvature_refreshes"] == 1 and ctl["curvature_steps"] == N_REENTRY, ctl
    a = run_compiled(cs, "gauss-2", 0.0, q0, v0, h, N_REENTRY, 1, kernel="spark")
    assert _difference(a, b) <= 1.0


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("every", [3, 7])
def test_save_every_samples_the_same_run_across_refreshes(every):
    """save_every on a run that leaves ``quasi_steps`` for ``curvature_refresh`` and re-enters it at
    every step (the time-alternating Hessian above, 31 steps, 31 refreshes): the samples are the
    every-step run's at steps 0, every, 2 every, ... and the last, bit for bit (t, q, v, energy,
    constraint; the multipliers of the steps that start at a sample), with the same counters. A
    sample index not carried across a re-entry, or a sample taken one step early or late there,
    breaks it (the comparison of the existing tests with save_every > 1, the specialised kernel's,
    compares two kernels compiled from the same text). Control: the samples shifted by one step
    differ."""
    cs = _particle_with_free_coordinate(0.1, True)
    q0, v0, n = [1, 0, 0, 0], [0, 1, 0, 0], 31
    a = run_quasi(cs, "gauss-2", 0.0, q0, v0, 0.1, n, 1)
    b = run_quasi(cs, "gauss-2", 0.0, q0, v0, 0.1, n, every)
    assert a.stats["curvature_refreshes"] == n, a.stats
    idx = list(range(0, n, every)) + ([n] if n % every else [])
    assert len(b.t) == len(idx) and np.array_equal(a.t[idx], b.t)
    for f in ("q", "v", "energy", "constraint"):
        assert np.array_equal(getattr(a, f)[idx], getattr(b, f)), f
    assert np.array_equal(a.psi[0:n:every], b.psi)
    assert {k: b.stats[k] for k in a.stats} == a.stats
    shifted = [min(i + 1, n) for i in idx]
    assert not np.array_equal(a.q[shifted], b.q)


def test_nfev_counts_the_residual_points_of_the_quasi_iteration():
    """``nfev`` counts residual points on every engine: the quasi-Newton iteration evaluates the
    residual of (21) once before its first increment and once after every increment but the last,
    each at the s stages and the end point, so a run without fallback has nfev = (s + 1)
    quasi_iterations exactly (measured: skate 597 = 3 x 199, particle with the curvature block 1390
    = 5 x 278, relativistic in the general form 2012 = 4 x 503). Control: a run whose steps fall
    back (max_iter = 3 below the 4-5 increments some particle steps need) adds the Newton chain's
    residuals, so the equality fails there."""
    for scene, fam, s in (("skate", "gauss-2", 2), ("particle", "gauss-4", 4), ("relativistic", "gauss-3", 3)):
        r = ldaspark.integrate(scene, fam, h=0.05, n_steps=100, engine="compiled", newton="quasi")
        st = r.stats
        assert st["quasi_fallbacks"] == 0 and st["quasi_iterations"] >= 100, (scene, st)
        assert r.nfev == st["nfev"] == (s + 1) * st["quasi_iterations"], (scene, st)
    ctl = ldaspark.integrate("particle", "gauss-2", h=0.1, n_steps=100, engine="compiled",
                             newton=ldaspark.Newton(kind="quasi", max_iter=3)).stats
    assert ctl["quasi_fallbacks"] > 0 and ctl["nfev"] > 3 * ctl["quasi_iterations"], ctl


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("scene, method, h, curvature, tol", [("particle", "gauss-2", 1.0, True, None),
                                                              ("particle", "gauss-3", 1.0, False, None),
                                                              ("particle", "gauss-2", 0.8, False, None),
                                                              ("particle", "gauss-2", 0.8, False, 1e-6),
                                                              ("pendulum", "gauss-2", 0.5, True, None),
                                                              ("pendulum", "gauss-2", 0.5, True, 1e-6)])
def test_attempts_between_waits_agree_with_newton(scene, method, h, curvature, tol):
    """Runs where converging attempts, fallbacks and the waits after them alternate (measured:
    particle h = 1, gauss-2, 35 steps by the quasi-Newton iteration, 165 fallbacks, 103 skipped;
    gauss-3 without the curvature 21 / 179 / 138; h = 0.8 without it 160 / 40 / 20; pendulum 176 /
    24 / 12): an attempt after a wait starts without a carried rate (``quasi_steps`` sets eta = -1
    on a skipped step); a carried rate kept across the wait, or one set to 0 there (eta then
    grows to eps^0.8 and, at a loose tol, accepts about any first increment), accepts unconverged
    first increments. The trajectory is the Newton engine's (default tol) within the bound of the
    module docstring, 2 N tol scale with tol = 8 eps or the run's (measured at most 0.19 and 0.09 of
    it), with steps of all three kinds. Negative control: another method (gauss-2 <-> gauss-3,
    O(h^4) apart) breaks the bound."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = compile_system(sc.system)
    n = 200
    a = run_compiled(cs, method, t0, q0, v0, h, n, 1, kernel="spark")
    b = run_quasi(cs, method, t0, q0, v0, h, n, 1, True, tol, curvature=curvature)
    st = b.stats
    assert st["quasi_steps"] > 0 and st["quasi_fallbacks"] > 0 and st["quasi_skipped"] > 0, st
    # the wait rule: a failed attempt (an attempt factors S once) sends at least the next step
    # straight to the Newton chain, the back-off being >= 1 after a converged attempt too
    failed = st["multiplier_lu"] - st["quasi_steps"]
    assert st["quasi_fallbacks"] == failed + st["quasi_skipped"] and st["quasi_skipped"] >= failed - 1, st
    units = 1.0 if tol is None else tol / (8 * EPS)      # _difference counts in units of 2 N 8 eps scale
    assert _difference(a, b) <= units, _difference(a, b)
    other = run_compiled(cs, "gauss-3" if method == "gauss-2" else "gauss-2", t0, q0, v0, h, n, 1, kernel="spark")
    assert _difference(other, b) > 10.0 * units, _difference(other, b)


@pytest.mark.parametrize("method", ["gauss-2", "gauss-4", "lobatto-iiia-iiib-3"])
def test_the_multiplier_matrix_is_the_newton_rows_through_the_frozen_block(method):
    """``multiplier_matrix``'s S (factored in place) is the Schur complement of the frozen matrix
    of the module docstring: S = C M_blk^-1 B with C the constraint rows (21e, f) in Z, dv and B the
    multiplier columns of rows (21b, d) of the kernels' exact Newton matrix (``spark_eval``) at the
    same iterate, M_blk = I_(s+1) (x) M. The trajectory tests cannot see S: any S that lets the
    iteration contract gives the same root (the sign of its h (A A~) k_q term flipped passed them
    all). Checked through the solve: |S y - r|_inf <= 1e3 eps |S|_inf |y|_inf for y = S^-1 r from
    S's LU (LU with partial pivoting is backward stable; measured <= 3.4e-14 at |S|_inf |y|_inf ~ 1).
    The every-term system (M non-diagonal, K(t, q), b(t, q): every entry of the rows present),
    t0 = 0.3, a random iterate x. Control: S built at 2 h misses the Newton rows at h by far more."""
    from ldaspark.compiled import kernels_mech, newton
    from ldaspark.compiled.runner import kernel_spec
    cs = _every_term_system()
    tab = kernel_spec(method, "spark")[1]
    s, n, m = tab[1].shape[0], cs.n, cs.m
    sn, sm, NN = s * n, s * m, s * (n + m) + n
    t0, h = 0.3, 0.05
    q0, v0 = _every_term_start(t0)
    x = np.random.default_rng(3).normal(scale=1e-2, size=NN)
    ws = kernels_mech.mech_workspace(s, n, m, cs.M)
    G, J = np.zeros(NN), np.zeros((NN, NN))
    kernels_mech.spark_eval(cs.model, tab, True, x, t0, q0, v0, h, cs.M, ws, G, J)
    con, rows = list(range(sn + n, NN)), list(range(sn + n))
    vel, lam = list(range(sn)) + list(range(sn + sm, NN)), list(range(sn, sn + sm))
    S = J[np.ix_(con, vel)] @ np.kron(np.eye(s + 1), cs.Minv) @ J[np.ix_(rows, lam)]
    r = np.random.default_rng(4).normal(size=sm)
    for hq, ok in ((h, True), (2 * h, False)):
        wq = kernels_mech.mech_workspace(s, n, m, cs.M)
        kernels_mech.mech_residual(cs.model, tab, x, t0, q0, v0, hq, wq, np.zeros(NN))
        qw = KQ.quasi_workspace(tab, n, m, np.ascontiguousarray(cs.Minv))
        assert KQ.multiplier_matrix(cs.model, tab, hq, t0, wq, qw)
        y = r.copy()
        newton.lu_solve(qw[10], qw[11], y)
        bound = 1e3 * EPS * np.abs(S).sum(axis=1).max() * np.abs(y).max()
        assert (np.abs(S @ y - r).max() <= bound) == ok, (hq, np.abs(S @ y - r).max(), bound)
