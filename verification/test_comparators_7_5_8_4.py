"""Comparators and identities of sections 7.5 and 8.4.

* The step-by-step (leapfrog) form after (25) equals the 2-stage Lobatto IIIA-B SPARK method to
  round-off (float64 and 30 digits), Psi included.
* It is not the composition of "symplectic" Euler I and II with step h/2: Euler II then I
  differs on every paper scene (and is, we find, McLachlan-Perlmutter's (26)); Euler I then II
  is the *modified* method of 8.4, and differs from Lobatto IIIA-B on the rolling disk, where
  K(q) is nonlinear in q. (On the four paper scenes the mean-of-K constraint (25) and the
  midpoint constraint of 8.4 have the same zero set, so there all three coincide.)
* McLachlan-Perlmutter (26) and the modified method satisfy their own defining equations.
* grad U is evaluated once per step by the semi-implicit forms.
"""
import numpy as np
import pytest
import sympy

from ldaspark.core import comparators
from ldaspark.core.backend import Backend
from ldaspark.core.comparators import ModifiedLobatto2, derive_mechanical, integrate_comparator
from ldaspark.lab.theory.orders import estimate_order, floor_for
from ldaspark.core.errors import InconsistentInitialDataError, InputError
from ldaspark.models.scenes import PAPER_SCENES, get_scene
from ldaspark.core.spark import integrate
from ldaspark.core.system import LagrangianSystem
from ldaspark.core.families import get_method

SCENES = list(PAPER_SCENES) + ["rolling-disk"]
H, N = 0.1, 30


def _run(name, scene, h=H, n=N, dps=None):
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial(dps)
    if name == "lobatto-iiia-iiib-2":
        return integrate(sc.system, get_method(name), t0, q0, v0, h, n_steps=n, dps=dps)
    return integrate_comparator(name, sc.system, t0, q0, v0, h, n, dps=dps)


def _diff(a, b):
    return max(float(np.abs(np.asarray(a.q - b.q, dtype=float)).max()),
               float(np.abs(np.asarray(a.v - b.v, dtype=float)).max()))


@pytest.fixture(scope="module")
def runs():
    names = ["lobatto-iiia-iiib-2", "lobatto-iiia-iiib-2-leapfrog",
             "lobatto-iiia-iiib-2-modified", "lobatto-iiia-iiib-2-modified-leapfrog", "mp-lobatto-iiib-a-2",
             "euler-i-ii-composition", "euler-ii-i-composition"]
    return {(s, m): _run(m, s) for s in SCENES for m in names}


# --- 7.5: the leapfrog form equals the SPARK method --------------------------------------
@pytest.mark.parametrize("scene", SCENES)
def test_leapfrog_form_equals_lobatto_iiia_iiib_2(scene, runs):
    a, b = runs[(scene, "lobatto-iiia-iiib-2")], runs[(scene, "lobatto-iiia-iiib-2-leapfrog")]
    assert _diff(a, b) < 1e-13
    assert np.abs(a.psi - b.psi).max() < 1e-11 * max(1.0, np.abs(a.psi).max())
    # control: the same check separates a different 2nd-order method with one grad U per step
    assert _diff(runs[(scene, "mp-lobatto-iiib-a-2")], b) > 1e-4


def test_leapfrog_form_equals_spark_at_30_digits():
    a = _run("lobatto-iiia-iiib-2", "particle", h="0.1", n=8, dps=30)
    b = _run("lobatto-iiia-iiib-2-leapfrog", "particle", h="0.1", n=8, dps=30)
    assert _diff(a, b) < 1e-26
    assert float(np.abs(np.asarray(a.psi - b.psi, dtype=float)).max()) < 1e-24


# --- 7.5: not a composition of symplectic Euler I and II --------------------------------
@pytest.mark.parametrize("scene", SCENES)
def test_euler_ii_then_i_is_not_lobatto_but_is_mclachlan_perlmutter(scene, runs):
    comp = runs[(scene, "euler-ii-i-composition")]
    assert _diff(comp, runs[(scene, "lobatto-iiia-iiib-2")]) > 1e-4
    assert _diff(comp, runs[(scene, "mp-lobatto-iiib-a-2")]) < 1e-12


@pytest.mark.parametrize("scene", SCENES)
def test_euler_i_then_ii_is_the_modified_method(scene, runs):
    comp = runs[(scene, "euler-i-ii-composition")]
    assert _diff(comp, runs[(scene, "lobatto-iiia-iiib-2-modified")]) < 1e-12


def test_euler_i_then_ii_differs_from_lobatto_when_K_nonlinear(runs):
    """Rolling disk: K(q) has cos(phi), sin(phi) beside constant entries, so the mean-of-K
    constraint (25) and the midpoint constraint differ."""
    d = _diff(runs[("rolling-disk", "euler-i-ii-composition")], runs[("rolling-disk", "lobatto-iiia-iiib-2")])
    assert d > 1e-6


@pytest.mark.parametrize("scene", PAPER_SCENES)
def test_paper_scenes_cannot_tell_modified_from_lobatto(scene, runs):
    """A finding, pinned: on the four paper scenes K(q) is linear in q along the motion (particle,
    mp-particles, robot with q3 = 0) or the skate's rows are scaled by cos(dq3/2), so (25) and
    the midpoint constraint have the same solutions."""
    assert _diff(runs[(scene, "lobatto-iiia-iiib-2-modified")], runs[(scene, "lobatto-iiia-iiib-2")]) < 1e-12


# --- 8.4: the modified method ---------------------------------------------------------
@pytest.mark.parametrize("scene", SCENES)
def test_modified_spark_form_equals_semi_implicit_form(scene, runs):
    a, b = runs[(scene, "lobatto-iiia-iiib-2-modified")], runs[(scene, "lobatto-iiia-iiib-2-modified-leapfrog")]
    assert _diff(a, b) < 1e-13


def test_modified_satisfies_midpoint_constraint_and_lobatto_does_not():
    sc = get_scene("rolling-disk")
    bk = Backend()
    t0, q0, v0 = sc.initial()
    q0, v0 = np.array(q0), np.array(v0)
    h = 0.2
    mod = ModifiedLobatto2(sc.system).step(t0, q0, v0, h)
    V1 = mod.V[0]
    assert np.abs(sc.system.constraint(bk, t0 + h / 2, q0 + h / 2 * V1, V1)).max() < 1e-14
    assert np.abs(sc.system.constraint(bk, mod.t1, mod.q1, mod.v1)).max() < 1e-14
    from ldaspark.core.spark import SparkMethod
    lob = SparkMethod(sc.system, get_method("lobatto-iiia-iiib-2")).step(t0, q0, v0, h)
    W1 = lob.V[0]
    assert np.abs(sc.system.constraint(bk, t0 + h / 2, q0 + h / 2 * W1, W1)).max() > 1e-6


# --- 8.4: McLachlan-Perlmutter (26) -------------------------------------------------------
def _check_26(scene, sol, h, shift_Q1=True):
    """Residuals of (26b-d) on a computed trajectory; (26b) as: M(v1 - v0) + h grad U(Q1) lies
    in the range of K(Q1)^T (least-squares residual). ``shift_Q1=False`` uses Q1 = q0 (wrong)."""
    sc = get_scene(scene)
    mech = derive_mechanical(sc.system)
    q, v = sc.system.q, sc.system.v
    gU = sympy.lambdify(q, [sympy.diff(mech["U"], x) for x in q])
    Kf = sympy.lambdify(q, mech["K"])
    M = np.array(mech["M"], dtype=float)
    r_b = r_c = r_d = 0.0
    for k in range(len(sol.t) - 1):
        q0, v0, q1, v1 = sol.q[k], sol.v[k], sol.q[k + 1], sol.v[k + 1]
        Q1 = q0 + h / 2 * v0 if shift_Q1 else q0
        r = M @ (v1 - v0) + h * np.array(gU(*Q1), float)
        KT = np.array(Kf(*Q1), float).T
        lam = np.linalg.lstsq(KT, r, rcond=None)[0]
        r_b = max(r_b, np.abs(r - KT @ lam).max())
        r_c = max(r_c, np.abs(q1 - q0 - h / 2 * (v0 + v1)).max())
        r_d = max(r_d, np.abs(sol.constraint[k + 1]).max())
    return r_b, r_c, r_d


@pytest.mark.parametrize("scene", PAPER_SCENES)
def test_mclachlan_perlmutter_satisfies_26(scene, runs):
    sol = runs[(scene, "mp-lobatto-iiib-a-2")]
    assert max(_check_26(scene, sol, H)) < 1e-13
    # control: the same check with the wrong stage Q1 = q0 fails
    assert _check_26(scene, sol, H, shift_Q1=False)[0] > 1e-5
    # control: the Lobatto IIIA-B SPARK trajectory does not satisfy (26)
    assert max(_check_26(scene, runs[(scene, "lobatto-iiia-iiib-2")], H)) > 1e-5


@pytest.mark.parametrize("name", ["mp-lobatto-iiib-a-2", "lobatto-iiia-iiib-2-modified"])
def test_comparator_order_2_on_skate(name):
    sc = get_scene("skate")
    qe, ve, _ = sc.exact_solution(1.0)
    hs, eq, ev = [], [], []
    for n in (8, 16, 32, 64):
        sol = _run(name, "skate", h=1.0 / n, n=n)
        hs.append(1.0 / n)
        eq.append(np.abs(sol.q[-1] - qe).max())
        ev.append(np.abs(sol.v[-1] - ve).max())
    for e in (eq, ev):
        assert abs(estimate_order(hs, e, floor_for(None, 1.0)).observed_order - 2) < 0.3


# --- "grad U is evaluated once per step" -------------------------------------------------
@pytest.mark.parametrize("name,per_step,extra", [("lobatto-iiia-iiib-2-leapfrog", 1, 1),
                                                  ("lobatto-iiia-iiib-2-modified-leapfrog", 1, 1),
                                                  ("mp-lobatto-iiib-a-2", 1, 0)])
def test_grad_U_once_per_step(name, per_step, extra, monkeypatch):
    calls = []
    orig = comparators.MechanicalParts.grad_U

    def counting(self, t, q):
        calls.append(1)
        return orig(self, t, q)
    monkeypatch.setattr(comparators.MechanicalParts, "grad_U", counting)
    sol = _run(name, "mp-particles", n=25)
    assert len(calls) == per_step * 25 + extra == sol.stats["n_grad_U"]


def test_full_spark_newton_evaluates_grad_q_L_many_times(runs):
    """Control: the fully implicit SPARK solve evaluates grad_q L at every stage of every Newton
    iteration (>= 2 stages x 2 iterations per step)."""
    st = runs[("mp-particles", "lobatto-iiia-iiib-2")].stats
    assert st["nfev"] >= 4 * N


# --- input handling -----------------------------------------------------------------------
def test_derive_mechanical_and_rejects_non_mechanical():
    d = derive_mechanical(get_scene("particle").system)
    q1, q2, q3 = get_scene("particle").system.q
    assert d["M"] == sympy.eye(3) and sympy.simplify(d["U"] - (q1 ** 2 + q2 ** 2)) == 0
    assert d["K"] == sympy.Matrix([[-q2, 0, 1]])
    q, v = sympy.symbols("x y"), sympy.symbols("vx vy")
    quartic = LagrangianSystem(v[0] ** 4 + v[1] ** 2 / 2, [v[0] - v[1]], list(q), list(v), name="quartic")
    with pytest.raises(InputError):
        derive_mechanical(quartic)
    with pytest.raises(InputError):
        integrate_comparator("mp-lobatto-iiib-a-2", quartic, 0.0, [0.0, 0.0], [1.0, 1.0], 0.1, 2)


def test_inconsistent_data_and_unknown_name():
    sc = get_scene("particle")
    with pytest.raises(InconsistentInitialDataError):
        integrate_comparator("mp-lobatto-iiib-a-2", sc.system, 0.0, [1, 0, 0], [0, 1, 1], 0.1, 2)
    with pytest.raises(InputError):
        integrate_comparator("gauss-irk-x", sc.system, 0.0, [1, 0, 0], [0, 1, 0], 0.1, 2)
    with pytest.raises(InputError):
        integrate_comparator("mp-lobatto-iiib-a-2", sc.system, 0.0, [1, 0, 0], [0, 1, 0], 0.1, 0)


def test_output_velocity_formula_uses_v_k_minus_half_not_the_printed_v_k_plus_half(runs):
    """The paper prints M v_k + K(q_k)^T (h/2 Psi_2k) = M v_{k+1/2} - h/2 grad U(q_k). Solving that
    literal system does not give the SPARK method's v_k; with v_{k-1/2} it does (to round-off)."""
    scene = "particle"
    sc = get_scene(scene)
    mech = derive_mechanical(sc.system)
    q = sc.system.q
    gU = sympy.lambdify(q, [sympy.diff(mech["U"], x) for x in q])
    Kf = sympy.lambdify(q, mech["K"])
    M = np.array(mech["M"], dtype=float)
    sol = runs[(scene, "lobatto-iiia-iiib-2")]
    n, m = M.shape[0], 1
    err_literal = err_fixed = 0.0
    for k in range(1, len(sol.t) - 1):
        qk = sol.q[k]
        K = np.array(Kf(*qk), float).reshape(m, n)
        S = np.block([[M, K.T], [K, np.zeros((m, m))]])
        for w, which in (((sol.q[k + 1] - qk) / H, "literal"), ((qk - sol.q[k - 1]) / H, "fixed")):
            rhs = np.concatenate([M @ w - H / 2 * np.array(gU(*qk), float), np.zeros(m)])
            vk = np.linalg.solve(S, rhs)[:n]
            e = np.abs(vk - sol.v[k]).max()
            if which == "literal":
                err_literal = max(err_literal, e)
            else:
                err_fixed = max(err_fixed, e)
    assert err_fixed < 1e-13
    assert err_literal > 1e-3
