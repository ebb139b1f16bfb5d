"""Theorem 1, symmetry (23), (21f) and the float64 / mpmath agreement on random general systems
(``strategies.general_systems``): L(t, q, v) not quadratic in v, with gyroscopic and explicit
time terms; k(t, q, v) rheonomic, nonlinear in v, with b(t, q) != 0. The section 8 scenes are
autonomous, quadratic in v and linear in v; a fault in the time-dependent or nonlinear parts of
the library (a wrong time argument, a dropped k_t, K = k_v at the wrong velocity) shows only here.

Theorem 1 is checked at 40 digits (finite differences at 60) wherever the boundary-value solve
is well posed or gauge-fixed. A singular solve is classified again by
``classify_wellposedness`` (two precisions, two steps) and reported as a hypothesis event; its
identities are still checked in the pinned solve, as the ledger does (docs/verification.md).
Each claim has a negative control: A_hat off (22b), the bare momenta without f_d, a tableau off
(23), the secant velocity, a shifted t0.

Default run: few examples, n <= 3, s <= 3 (~20 s on an idle core, ~25 s on a busy one). ``--exhaustive``: n <= 5,
m <= 2, more examples and the built-in tableaux.
"""
import numpy as np
import pytest
from hypothesis import Phase, assume, event, given, note, settings, strategies as st

from ldaspark.core.backend import Backend
from ldaspark.core.spark import integrate
from ldaspark.analysis.conditions import check_22a, check_22b, check_23
from ldaspark.analysis.discrete import SINGULAR, base_point, discrete_lagrangian, theorem1_residuals
from ldaspark.lab.claims.ledger import TOL_NEGATIVE, TOL_SYMMETRY, TOL_THEOREM1
from ldaspark.analysis.symmetry import check_symmetry
from ldaspark.analysis.wellposedness import classify_wellposedness

from general_fixtures import theorem1_tol
from strategies import builtin_tableaux, general_systems, spark_tableaux

H = "0.1"


def few(n):
    """n examples, no shrinking: one solve costs seconds, and a failure is reported as drawn."""
    return settings(max_examples=n, phases=[Phase.explicit, Phase.reuse, Phase.generate])


def _theorem1(case, tab):
    r = theorem1_residuals(case.system, tab, case.t0, case.q0, case.v0, H, dps=40)
    note(f"{tab.name}: {r['wellposed']}, q0 {r['theorem1-q0']:.1e}, q1 {r['theorem1-q1']:.1e}, "
         f"FD error {r['fd_error']:.1e}")
    return r


def _assert_theorem1(case, tab):
    assert check_22a(tab) and check_22b(tab)
    r = _theorem1(case, tab)
    if r["wellposed"] == SINGULAR:
        # classified explicitly (never silently): the implicit functions of Theorem 1 do not exist;
        # the identities are still those of the pinned solve
        c = classify_wellposedness(case.system, tab, case.t0, case.q0, case.v0, H)
        event(f"singular BVP ({c['class']} by classify_wellposedness)")
    else:
        event(r["wellposed"])
    assert r["fd_error"] < 1e-25, r                       # the differences resolve the threshold
    assert r["theorem1-q0"] <= TOL_THEOREM1, r
    assert r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)
    # perturbed formula (negative control): the bare momentum -p0 without f_d^- is not dL_d/dq0
    if r["f_d_minus_norm"] > 1e-10:
        assert r["without_forces_q0"] >= TOL_NEGATIVE, r
    return r


@few(3)
@given(general_systems(), spark_tableaux())
def test_theorem1_q0_q1_identities_general_L_k(case, tab):
    """dL_d/dq0 = -p0 - f_d^-, dL_d/dq1 = p1 - f_d^+ (Theorem 1) for random (22)-tableaux."""
    _assert_theorem1(case, tab)


@few(1)
@given(general_systems(n_range=(3, 3), m_min=2), spark_tableaux(s_values=(3,)))
def test_theorem1_three_stages_two_constraints_general_L_k(case, tab):
    """The draws above stay at s <= 2 and m = 1 (derandomized: random-1, random-1, random-2, all
    with one constraint): here s = 3 (A near Lobatto IIIA 3, an explicit first stage, two rows of
    (21e) with a random omega) and m = 2 constraints nonlinear in v (R_v, R_q sum over psi_r).
    The strategy's simplest s = 3 draw has A_tilde = 1/6 in every entry (rank 1: (21b) sees one
    combination of the s R_j, and the step's Newton matrix is exactly singular), so a nonsingular
    A_tilde is assumed. Drawn: n = 3, m = 2, well-posed, residuals 4.4e-46, 4.8e-46 (0.4 s). The
    (21e) rows of dG/dq0 ordered constraint-major (the same order for s = 2 or m = 1; mutant
    bvp-dq0-21e-constraint-major) passed every other default test of the files that solve the
    BVP (theorem 1, symmetry, (21), general systems: the robot has m = 2 but s = 2 there); here
    q0's identity misses by 4.4e-3."""
    assume(tab.exact["A_tilde"].det() != 0)
    assert tab.s == 3 and case.system.m == 2
    _assert_theorem1(case, tab)


@few(2)
@given(general_systems(n_range=(2, 2)), builtin_tableaux(max_s=2))
def test_theorem1_builtin_tableaux_general_L_k(case, tab):
    _assert_theorem1(case, tab)


@few(2)
@given(general_systems(n_range=(2, 3)), spark_tableaux(s_values=(1, 2)), st.data())
def test_theorem1_fails_when_22b_broken_general_L_k(case, tab, data):
    """Negative control: one entry of A_hat + 1/20 breaks (22b); both identities fail."""
    i, j = data.draw(st.integers(0, tab.s - 1)), data.draw(st.integers(0, tab.s - 1))
    bad = tab.with_entry("A_hat", i, j, "1/20")
    assert not check_22b(bad)
    r = _theorem1(case, bad)
    assert max(r["theorem1-q0"], r["theorem1-q1"]) >= TOL_NEGATIVE, r


def _sym(case, tab):
    return check_symmetry(case.system, tab, case.t0, case.q0, case.v0, H, dps=40)


@few(2)
@given(general_systems(n_range=(2, 3)), spark_tableaux(symmetric=True))
def test_symmetry_23_general_L_k(case, tab):
    """Under (23): L_d(t1,q1,t0,q0) = -L_d(t0,q0,t1,q1), Phi_{-h} o Phi_h = id, and the f_d
    identities on C_d, with t in L and k (the reversed step runs its stages at T_{s+1-i})."""
    assert check_23(tab) and check_22b(tab)
    r = _sym(case, tab)
    note(str(r))
    assert r["symmetry-Ld"] <= TOL_SYMMETRY and r["symmetry-Phi"] <= TOL_SYMMETRY, r
    if r["wellposed"] != SINGULAR:
        assert max(r["symmetry-fd-plus"], r["symmetry-fd-minus"]) <= TOL_SYMMETRY, r


@few(1)
@given(general_systems(n_range=(2, 2)), spark_tableaux(symmetric=True, s_values=(2,)))
def test_symmetry_fails_off_23_general_L_k(case, tab):
    """Negative control: A_tilde_12 + 1/10 keeps (22) but breaks (23d): Phi_{-h} o Phi_h != id,
    ten orders above the 1e-25 threshold (A_tilde acts through the multipliers only, a weak
    effect when psi is small: 1e-10 on the example drawn)."""
    bad = tab.with_entry("A_tilde", 0, 1, "1/10")
    assert check_22b(bad) and not check_23(bad)
    assert _sym(case, bad)["symmetry-Phi"] > 1e-15


def _steps(case, tab, dps, n_steps=3, t_shift=0.0):
    bk = Backend(dps)
    with bk.context():
        t0 = bk.scalar(case.t0) + t_shift
        q0, v0 = case.q0, case.v0
        if dps is None:
            q0, v0 = [float(x) for x in q0], [float(x) for x in v0]
        h = H if dps else float(H)
        return integrate(case.system, tab, t0, q0, v0, h, n_steps=n_steps, dps=dps,
                         check_initial=t_shift == 0.0)


@few(2)
@given(general_systems(n_range=(2, 3)), st.one_of(spark_tableaux(), builtin_tableaux(max_s=2)))
def test_constraint_21f_general_L_k(case, tab):
    """k(t_n, q_n, v_n) = 0 at solver tolerance after every step (21f), float64 and 30 digits;
    control: the secant velocity (q_n - q_{n-1}) / h does not satisfy k."""
    for dps in (None, 30):
        sol = _steps(case, tab, dps)
        bk = Backend(dps)
        with bk.context():
            k = max(bk.norm_inf(sol.constraint[i]) / (1 + bk.norm_inf(sol.v[i])) for i in range(len(sol.t)))
            h = bk.scalar(H)
            sec = max(bk.norm_inf(case.system.constraint(bk, sol.t[i], sol.q[i], (sol.q[i] - sol.q[i - 1]) / h))
                      for i in range(1, len(sol.t)))
        assert k <= 1e3 * bk.eps, (dps, k)
        assert sec >= 1e-6, (dps, sec)


@few(2)
@given(general_systems(n_range=(2, 3)), spark_tableaux())
def test_float64_and_mpmath_paths_agree_general_L_k(case, tab):
    """The float64 and the 30-digit mpmath paths give the same steps (1e-11) and the same L_d,
    f_d^- (discrete_lagrangian, 1e-9); control: t0 shifted by 1e-7 is seen (> 1e-10), so the
    comparison resolves time arguments of a rheonomic system."""
    a, b = _steps(case, tab, None), _steps(case, tab, 30)
    qa, qb = np.asarray(a.q, float), np.array([[float(x) for x in r] for r in b.q])
    va, vb = np.asarray(a.v, float), np.array([[float(x) for x in r] for r in b.v])
    assert max(np.abs(qa - qb).max(), np.abs(va - vb).max()) <= 1e-11
    c = _steps(case, tab, 30, t_shift=1e-7)
    qc = np.array([[float(x) for x in r] for r in c.q])
    vc = np.array([[float(x) for x in r] for r in c.v])
    assert max(np.abs(qc - qb).max(), np.abs(vc - vb).max()) > 1e-10
    out = {}
    for dps in (None, 30):
        bk = Backend(dps)
        with bk.context():
            t0 = bk.scalar(case.t0)
            q0 = bk.array([float(x) for x in case.q0] if dps is None else case.q0)
            v0 = bk.array([float(x) for x in case.v0] if dps is None else case.v0)
            t1, q1, xg = base_point(case.system, tab, t0, q0, v0, H if dps else float(H), dps)
            out[dps] = discrete_lagrangian(case.system, tab, t0, q0, t1, q1, dps=dps, x_guess=xg)
    assert abs(out[None].L_d - float(out[30].L_d)) <= 1e-12
    assert np.abs(out[None].f_d_minus - np.array([float(x) for x in out[30].f_d_minus])).max() <= 1e-9


# --- exhaustive ------------------------------------------------------------------------------
@pytest.mark.exhaustive
@few(25)
@given(general_systems(n_range=(2, 5)), st.one_of(spark_tableaux(), builtin_tableaux(max_s=3)))
def test_theorem1_exhaustive_general_L_k(case, tab):
    _assert_theorem1(case, tab)


@pytest.mark.exhaustive
@few(12)
@given(general_systems(n_range=(2, 5)), st.one_of(spark_tableaux(symmetric=True),
                                                  builtin_tableaux(max_s=3)))
def test_symmetry_exhaustive_general_L_k(case, tab):
    r = _sym(case, tab)
    assert r["symmetry-Ld"] <= TOL_SYMMETRY and r["symmetry-Phi"] <= TOL_SYMMETRY, r
