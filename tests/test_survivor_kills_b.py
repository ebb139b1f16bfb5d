"""Rules of ldaspark.theory that generated mutants showed untested: each test feeds an input on
which the rule and its neighbour (the best item for the worst, any for all, another tolerance
scale) give different numbers or verdicts.

Most inputs are constructed (duck-typed tableaux, fake solutions, monkeypatched inner computations
that plant one large deviation among small ones), so the file runs in a few seconds; where the
real computation is cheap it is run at low precision."""
import math
from types import SimpleNamespace

import mpmath
import numpy as np
import pytest

from ldaspark.core.errors import TableauError
from ldaspark.theory import audit as au
from ldaspark.theory import audit_checks as ac



def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


C = au.Check
P, F, S, I = au.PASS, au.FAIL, au.SKIP, au.INFO


# --- audit_checks: omega (21e), entry precision, convergence --------------------------------------
def _omega_tab(omega, s, source_digits=15, b=None, c=None):
    ent = {"omega": [[mpmath.mpf(x) for x in row] for row in omega]}
    if b is not None:
        ent["b"] = [mpmath.mpf(x) for x in b]
        ent["c"] = [mpmath.mpf(x) for x in c]
    return SimpleNamespace(s=s, source_digits=source_digits, mp_entries=lambda dps: ent)


# test_omega_rank_21e_tolerance_scales_with_the_largest_singular_value: the rule it pinned was replaced (issue 47): see tests/test_audit_precision_writings.py


# test_omega_span_tolerance_uses_the_entries_digits_and_the_largest_singular_value: the rule it pinned was replaced (issue 47): see tests/test_audit_precision_writings.py


def test_convergence_error_is_the_worst_component_of_q_and_v():
    sol = SimpleNamespace(q=[np.array([1.0 + 1e-3, 2.0 + 1e-6])], v=[np.array([0.0, 1e-9])])
    assert ac._err(sol, [1.0, 2.0], [0.0, 0.0]) == _close(1e-3, rel=1e-9)


def test_entry_floor_uses_the_fewest_digits_given():
    tab = SimpleNamespace(source_digits=10, decimal_digits_min=None, decimal_digits=12)
    assert ac._entry_floor(tab) == _close(1e3 * 1e-10, rel=1e-12)
    tab = SimpleNamespace(source_digits=None, decimal_digits_min=13, decimal_digits=11)
    assert ac._entry_floor(tab) == _close(1e3 * 1e-11, rel=1e-12)


def test_observed_order_reports_the_largest_constraint_violation(monkeypatch):
    import ldaspark.models.scenes as scenes
    fake_scene = SimpleNamespace(exact=True, exact_solution=lambda t, dps: ([0.0, 0.0], [0.0, 0.0], None))
    monkeypatch.setattr(scenes, "get_scene", lambda name: fake_scene)

    def run(tab, sc, N, t_end, dps):
        return SimpleNamespace(q=[np.array([1.0 / N ** 2, 0.0])], v=[np.array([0.0, 0.0])],
                               constraint=np.array([[1e-3 / N, 1e-12], [1e-9, 0.0]]))
    monkeypatch.setattr(ac, "_run", run)
    res = ac.observed_order(None, "skate", [4, 8, 16], 1, None, 1e-14)
    assert res["max_constraint"] == _close(1e-3 / 4, rel=1e-12)
    assert res["observed"] == _close(2.0, rel=1e-9)


def _conv_tab(source_digits):
    return SimpleNamespace(source_digits=source_digits, decimal_digits_min=None, decimal_digits=None)


# test_convergence_floor_uses_the_fewer_of_dps_and_the_entries_digits: the rule it pinned was replaced (issue 47): see tests/test_audit_precision_writings.py


# test_convergence_above_prediction_passes_only_when_the_finest_error_nears_the_entry_floor: the rule it pinned was replaced (issue 47): see tests/test_audit_precision_writings.py


def test_symmetry_23_summary_quotes_the_largest_scene_residual(monkeypatch):
    from ldaspark.theory import symmetry
    vals = {"particle": 1e-30, "skate": 2e-20}

    def fake(system, tab, t0, q0, v0, h, dps):
        x = vals[fake.names.pop(0)]
        return {"symmetry-Ld": x, "symmetry-fd-plus": x / 2, "symmetry-fd-minus": x / 4, "symmetry-Phi": x / 8,
                "wellposed": "well-posed"}
    fake.names = ["particle", "skate"]
    monkeypatch.setattr(symmetry, "check_symmetry", fake)
    tab = SimpleNamespace(source_digits=None)
    checks, _ = au._symmetry_checks(tab, 30, ("particle", "skate"))
    summ = checks[-1]
    assert summ.name == "symmetry" and summ.status == P
    assert summ.residual == _close(2e-20, rel=1e-12)


def _audit_result(t1_residuals=(1e-20, 3e-12), conv=(P, P), hyp22=True, c22=((0.0, 0.0), (0.0, 0.0)),
                  t1_status=(P, P), exact=True):
    checks = [C("22a", P if hyp22 else F, c22[0][0], "b_hat = b", tolerance=c22[0][1]),
              C("22b", P if hyp22 else F, c22[1][0], "a_hat", tolerance=c22[1][1])]
    for name, r, st in zip(("skate", "particle"), t1_residuals, t1_status):
        checks.append(C(f"theorem1:{name}", st, r, "", tolerance=1e-10))
    checks.append(C("theorem1", F if F in t1_status else P, max(t1_residuals), ""))
    for name, st in zip(("skate", "particle"), conv):
        checks.append(C(f"convergence:{name}", st, 0.01, ""))
    checks += [C("constraint", P, 1e-16, ""), C("energy", I, 1e-6, "")]
    facts = {"22": hyp22, "23": True, "predicted_order": 2, "order:pair": 2,
             "convergence:skate": {"observed": 2.0}, "convergence:particle": {"observed": 2.0}}
    return au.AuditResult("fake", 1, exact, 30, True, checks=checks, facts=facts)


def test_verdict_quotes_the_largest_theorem1_residual():
    text = au.verdict(_audit_result(t1_residuals=(1e-20, 3e-12)))
    assert "largest residual 3.0e-12" in text


def test_verdict_says_the_orders_agree_only_when_both_scenes_pass():
    assert "agree with it." in au.verdict(_audit_result(conv=(P, P)))
    assert "do NOT agree with it." in au.verdict(_audit_result(conv=(P, F)))
    assert "do NOT agree with it." in au.verdict(_audit_result(conv=(F, P)))


def test_disagreement_quotes_the_largest_22_residual():
    # (22) violated (22a by 5e-11, 22b by 1e-13) but Theorem 1 passes (tolerance 1e-10): the
    # violation is below the numerical resolution, and the sentence quotes the larger residual
    res = _audit_result(hyp22=False, c22=((5e-11, 0.0), (1e-13, 0.0)), t1_status=(P, P))
    d = au.disagreement(res)
    assert "|residual| 5.0e-11" in d
    # a violation above the tolerance in one of the two is called unexpected
    res = _audit_result(hyp22=False, c22=((1e-13, 0.0), (1e-3, 0.0)), t1_status=(P, P))
    assert "larger than the numerical tolerance" in au.disagreement(res)


def test_disagreement_quotes_the_largest_22_uncertainty():
    # (22) holds to the entries' precision: residuals 1e-12, 0 and uncertainties 1e-9, 1e-11
    res = _audit_result(hyp22=True, c22=((1e-12, 1e-9), (0.0, 1e-11)), t1_status=(F, P),
                        t1_residuals=(1e-5, 1e-20), exact=False)
    d = au.disagreement(res)
    assert "holds only to 1.0e-12 (uncertainty 1.0e-09)" in d


# --- Definition 1 (15a-b) along a trajectory: the reported residual is the worst k ----------------
def _v(x, y=0.0):
    return np.array([x, y], dtype=object)


#: per IVP step j: D2 L_d, D4 L_d, f_d^-, f_d^+, c(u = v1), c(secant), c(left end), |mu|
_DEF1_STEPS = [
    dict(D2=_v(0.0), D4=_v(1e-3), fm=_v(5.0), fp=_v(-1e-3), c=1e-3, c_sec=1e-12, c_left=1e-5, mu=4.0),
    dict(D2=_v(0.0), D4=_v(1e-9), fm=_v(0.0), fp=_v(1e-6), c=1e-12, c_sec=1e-4, c_left=0.0, mu=1.0),
    dict(D2=_v(0.0), D4=_v(0.0), fm=_v(0.0), fp=_v(2.0), c=1e-14, c_sec=1e-13, c_left=1e-14, mu=2.0),
]


def _fake_definition1(monkeypatch):
    from ldaspark.theory import definition1 as d1
    state = {"step": -1, "calls": []}

    def base_point(system, tableau, t, q, v, h, dps):
        return t + h, q + v * h, v

    def discrete_lagrangian(system, tableau, t, q, t1, q1, dps, x_guess):
        state["step"] += 1
        st = _DEF1_STEPS[state["step"]]
        return SimpleNamespace(wellposed="well-posed", f_d_minus=st["fm"], f_d_plus=st["fp"], p0=_v(1.0), p1=_v(1.0),
                               v1=_v(0.0), v0=_v(0.0), mu_norm=st["mu"], step=st)

    def constraint(bk, t, q, v):
        st = _DEF1_STEPS[state["step"]]
        i = len(state["calls"]) % 3
        state["calls"].append(i)
        return np.array([st[("c", "c_sec", "c_left")[i]]], dtype=object)

    monkeypatch.setattr(d1, "base_point", base_point)
    monkeypatch.setattr(d1, "discrete_lagrangian", discrete_lagrangian)
    monkeypatch.setattr(d1, "_fd_gradient", lambda bvp, r, t, q, t1, q1, delta: (r.step["D2"], r.step["D4"]))
    monkeypatch.setattr(d1, "DiscreteBVP", lambda system, tableau, dps: SimpleNamespace(unpack=lambda x: (None, None, x)))
    system = SimpleNamespace(constraint=constraint)
    return d1.definition1_residuals(system, None, 0, [0.0, 0.0], [1.0, 0.0], "0.1", n_steps=3, dps=16)


def test_definition1_15a_15b_report_the_worst_interior_point(monkeypatch):
    out = _fake_definition1(monkeypatch)
    # (15a) at k = 1: D4 + D2 = 1e-3 cancelled by f_d^+ + f_d^- = -1e-3; at k = 2: 1e-9 + 1e-6
    assert out["15a_per_k"] == [0.0, _close(1e-9 + 1e-6)]
    assert out["15a"] == _close(1e-9 + 1e-6)
    assert out["15a_without_forces"] == _close(1e-3)
    # (15b): the worst c over the steps, with u = v1 and with the secant velocity
    assert out["15b"] == _close(1e-3)
    assert out["15b_secant"] == _close(1e-4)
    assert out["15b_left_end"] == _close(1e-5)
    # the force scale is the largest |f_d^-| or |f_d^+| of any step; mu the largest multiplier
    assert out["f_scale"] == _close(5.0)
    assert out["mu"] == 4.0
    assert out["wellposed"] == "well-posed"


# --- section 2.2, the energy balance (8) along the exact flow: worst node, floor 1 of the scale ----
def test_energy_balance_8_reports_the_worst_collocation_node(monkeypatch):
    from ldaspark.theory import energy_balance as eb
    real, calls = eb.rhs_terms, []

    def planted(f, t, q, v, psi):
        # one node's -L_t off by 1e-3, another node's -psi^T K v off by 1e-4; the rest exact
        ps, lt = real(f, t, q, v, psi)
        i = len(calls)
        calls.append(i)
        return ps + (1e-4 if i == 1 else 0), lt + (1e-3 if i == 0 else 0)
    monkeypatch.setattr(eb, "rhs_terms", planted)
    out = eb.exact_balance("particle", dps=20, stages=3)
    assert len(calls) == 3
    # E is conserved on the particle: |dE/dt| << 1, so the scale is its floor 1
    assert out["max_dEdt"] == 1.0
    assert out["pointwise"] == _close(1e-3, rel=1e-3)       # node 0 (node 1: 1e-4, node 2: ~1e-21)
    assert out["without_L_t"] == _close(1e-4, rel=1e-3)     # node 1 (the others ~1e-21)
    assert out["without_psi_term"] == _close(1e-3, rel=1e-2)   # node 0 (the others |psi^T K v| < 1e-5)


# --- orders: the scales of the round-off floors are the largest reference components -------------
def test_order_measurement_scales_are_the_largest_reference_components(monkeypatch):
    from ldaspark.theory import orders

    def reference(t):
        # q, v at t_end; psi at the stage times of the last step: one large, one tiny component
        return [2.0, -5.0, 1e-3], [0.5, -1e-4], [3.0 + float(t), 1e-3]
    sol = SimpleNamespace(q=[[2.0, -5.0, 1e-3]], v=[[0.5, -1e-4]], psi=[[[3.0, 1e-3], [3.0, 1e-3]]], stats={})
    monkeypatch.setattr(orders, "run_method", lambda *a, **k: sol)
    monkeypatch.setattr(orders, "stage_nodes", lambda name, dps: [0.25, 0.75])
    scene = SimpleNamespace(initial=lambda dps: (0.0, [0.0] * 3, [0.0] * 3), system=None)
    out = orders.measure_errors("fake", scene, reference, 1.0, [2, 4])
    assert out["scale"]["q"] == 5.0
    assert out["scale"]["v"] == 0.5
    # the largest |psi| over the stage times of every run: 3 + t at the last node of the N = 4 run,
    # t = 3/4 + 0.75/4 (N = 2: 3 + 0.875; the tiny component: 1e-3)
    assert out["scale"]["psi"] == _close(3.0 + 0.75 + 0.1875)


# --- section 4.1, the symmetry identities under (23): the scales of the relative residuals --------
def _mpv(*xs):
    return np.array([mpmath.mpf(x) for x in xs], dtype=object)


def _fake_symmetry(monkeypatch, rev_fp, rev_fm):
    """check_symmetry on constructed forward / reversed BVP results (n = 2): the projector of the
    forward BVP keeps direction 1 (k depends on q_2 only), that of the reversed one direction 2;
    the round trip Phi_-h(Phi_h(y)) misses q0 by 1e-6 and v0 by 1e-9."""
    from ldaspark.models import arguments
    from ldaspark.theory import symmetry
    dps = 20

    def res(fm, fp, M):
        return SimpleNamespace(L_d=mpmath.mpf(2), f_d_minus=_mpv(*fm), f_d_plus=_mpv(*fp), p0=_mpv(0, 0),
                               p1=_mpv(0, 0), x=None, wellposed="well-posed", rank_deficiency=0, dps=dps,
                               extra={"gauge": None, "dk0_dq": [np.array([[mpmath.mpf(x) for x in M]], dtype=object)] * 2})
    fwd = res((1, 0), (0, 2), (0, 1))
    rev = res(rev_fm, rev_fp, (1, 0))
    bvps = [fwd, rev]
    q0, v0 = _mpv("0.5", 0), _mpv("0.25", 0)
    monkeypatch.setattr(arguments, "theory_args", lambda *a: a[:5])
    monkeypatch.setattr(symmetry, "base_point", lambda system, tab, t0, q0, v0, h, dps: (t0 + mpmath.mpf(h), q0, None))
    monkeypatch.setattr(symmetry, "discrete_lagrangian", lambda *a, **k: bvps.pop(0))
    monkeypatch.setattr(symmetry, "DiscreteBVP", lambda *a: SimpleNamespace(
        unpack=lambda x: (np.zeros(1), np.zeros(1), None, None), pack=lambda *a: None))
    r1 = SimpleNamespace(t1=1, q1=q0, v1=v0)
    r2 = SimpleNamespace(q1=q0 + _mpv("1e-6", 0), v1=v0 + _mpv("1e-9", 0))
    monkeypatch.setattr(symmetry, "ivp_step", lambda meth, t0, q0, v0, h: r1)
    monkeypatch.setattr(symmetry, "SparkMethod", lambda *a, **k: SimpleNamespace(step=lambda *a: r2))
    return symmetry.check_symmetry(None, None, 0, q0, v0, "0.1", dps=dps)


def test_symmetry_fd_plus_is_relative_to_the_larger_of_its_two_covectors(monkeypatch):
    # P0 f_d^+(rev) = 100 dominates P0 f_d^-(fwd) = 1: the scale is 100, |P0 (f^- + f^+(rev))| = 101
    r = _fake_symmetry(monkeypatch, rev_fp=(100, 0), rev_fm=(0, 0))
    assert r["fd_plus_identity_norms"] == (1.0, 100.0)
    assert r["symmetry-fd-plus"] == _close(101 / 100)
    # the unrestricted comparison is relative to max(|f_d^-|, |f_d^+|, |p0|) of the forward BVP = 2
    assert r["symmetry-fd-unrestricted"] == (_close(101 / 2), _close(2 / 2))
    # Phi_-h(Phi_h(y)) - y: the worse of q (1e-6) and v (1e-9), relative to max(|y|, 1) = 1
    assert r["symmetry-Phi"] == _close(1e-6)
    assert r["tangent_dim"] == (1, 1)


def test_symmetry_fd_minus_is_relative_to_the_larger_of_its_two_covectors(monkeypatch):
    # P1 f_d^-(rev) = 200 dominates P1 f_d^+(fwd) = 2: the scale is 200, |P1 (f^+ + f^-(rev))| = 202
    r = _fake_symmetry(monkeypatch, rev_fp=(0, 0), rev_fm=(0, 200))
    assert r["fd_minus_identity_norms"] == (2.0, 200.0)
    assert r["symmetry-fd-minus"] == _close(202 / 200)
    assert r["symmetry-fd-plus"] == _close(1 / 200)


def test_symmetry_tangent_projector_drops_singular_values_below_1e8_relative():
    from ldaspark.theory import symmetry
    # dk0/dq with singular values 1 and 1e-12: numerically rank 1, so one tangent direction
    M = np.array([[mpmath.mpf(1), 0], [0, mpmath.mpf("1e-12")]], dtype=object)
    res = SimpleNamespace(extra={"gauge": None, "dk0_dq": [M, M]}, dps=20)
    P, dim = symmetry._tangent_projector(res, 0)
    assert dim == 1
    assert float(abs(P[1, 1] - 1)) < 1e-15 and float(abs(P[0, 0])) < 1e-15


# --- flow_jacobian: the default start time, and no non-finite entry returned ---------------------
def test_flow_jacobian_of_a_bare_system_starts_at_t0_zero_by_default():
    from ldaspark.models.scenes import get_scene
    from ldaspark.theory.flow_jacobian import flow_jacobian
    sc = get_scene("skate")
    _, q0, v0 = sc.initial(None)
    a = flow_jacobian(sc.system, "gauss-1", q0, v0, 0.1)            # a bare system, no t0: t0 = 0
    b = flow_jacobian(sc.system, "gauss-1", q0, v0, 0.1, t0=0)
    assert a.full.shape == (2 * sc.system.n, 2 * sc.system.n)
    assert np.array_equal(np.asarray(a.full, dtype=float), np.asarray(b.full, dtype=float))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), mpmath.mpf("nan"), mpmath.mpc(1, 1)])
def test_flow_jacobian_refuses_one_non_finite_entry_among_finite_ones(bad):
    from ldaspark.core.errors import NonFiniteError
    from ldaspark.theory.flow_jacobian import _finite
    _finite(np.array([[1.0, 2.0], [3.0, 4.0]]), 0)                          # finite: accepted
    with pytest.raises(NonFiniteError):
        _finite(np.array([[1.0, 2.0], [3.0, bad]], dtype=object), 0)


# --- section 5: (16), (18) relative to the largest covector; k a first integral at every node -----
def test_exact_identities_16_18_scale_and_the_first_integral_take_the_largest(monkeypatch):
    from ldaspark.theory import section5 as s5
    real, rec = s5.fd_gradient, {}

    def recording(fl, r, *a, **k):
        g0, g1 = real(fl, r, *a, **k)
        rec.update(r=r, g0=g0, g1=g1)
        # plant a velocity error at the first collocation node only: k(T_1, Q_1, V_1) - k0 = O(1e-3)
        # there, O(1e-30) at the other nodes
        r.V[0] = r.V[0] + mpmath.mpf("1e-3")
        return g0, g1
    monkeypatch.setattr(s5, "fd_gradient", recording)
    out = s5.exact_identities.__wrapped__("particle", dps=20, stages=3)      # not memoized: planted
    r, g0, g1 = rec["r"], rec["g0"], rec["g1"]
    norms = [s5._nrm(x) for x in (r.p0, r.p1, g0, g1)]
    assert max(norms) > 1.005 * min(norms)          # the four sizes differ (by ~1% on the particle)
    with mpmath.workdps(40):
        assert out["16-without-force"] == _close(s5._nrm(g0 + r.p0) / max(norms))
        assert out["18-without-force"] == _close(s5._nrm(g1 - r.p1) / max(norms))
    assert 1e-4 < out["first_integral"] < 1e-2


# --- section 7.3: the midpoint statement needs both V_1 and Q_1 at the midpoint -------------------
def test_section7_3_midpoint_stage_statement_is_the_worse_of_V1_and_Q1(monkeypatch):
    import dataclasses

    from ldaspark.core.families import get_method
    from ldaspark.theory import section7 as s7
    real = s7.spark_step

    def planted(*a, **k):
        r = real(*a, **k)            # Gauss-1 is the midpoint rule: V_1, Q_1 at the midpoint to ~1e-40
        return dataclasses.replace(r, Q=np.array([r.Q[0] + mpmath.mpf("1e-3")] + list(r.Q[1:]), dtype=object))
    monkeypatch.setattr(s7, "spark_step", planted)
    out = s7.reduction("midpoint", get_method("gauss-1", exact=True))
    assert out["stage"] == _close(1e-3, rel=1e-6)
    assert out["diff"] < 1e-30


# --- variational error analysis: orders per quantity, "zero at every h" only if every error is -----
def test_variational_errors_order_unless_zero_at_every_step(monkeypatch):
    from ldaspark.theory import variational as va
    hs = ("0.2", "0.1", "0.05")
    z = np.array([mpmath.mpf(0), mpmath.mpf(0)], dtype=object)
    ex = SimpleNamespace(L_d=mpmath.mpf(0), f_d_minus=z, f_d_plus=z, p0=z, p1=z, v0=z, v1=z)
    # |L_d - L_d^E| = 1e-3, 1e-6 and exactly 0 at the smallest h; |f_d^- - f^E-| ~ h^2 in one component
    Ld = [mpmath.mpf("1e-3"), mpmath.mpf("1e-6"), mpmath.mpf(0)]
    fm = [np.array([mpmath.mpf(h) ** 2, mpmath.mpf(0)], dtype=object) for h in hs]
    calls = []

    def dl(S, tab, t0, q0, t1, q1, dps, x_guess):
        i = len(calls)
        calls.append(i)
        return SimpleNamespace(L_d=Ld[i], f_d_minus=fm[i], f_d_plus=z, p0=z, p1=z)
    monkeypatch.setattr(va, "get_scene", lambda name: SimpleNamespace(system=None))
    monkeypatch.setattr(va, "initial_point", lambda name, point, dps: (0, [0, 0], [0, 0]))
    monkeypatch.setattr(va, "_exact", lambda name, h, dps, stages, point: (z, ex))
    monkeypatch.setattr(va, "base_point", lambda *a: (None, None, None))
    monkeypatch.setattr(va, "discrete_lagrangian", dl)
    monkeypatch.setattr(va, "_tangent", lambda S, bk, t, q, v: np.eye(2, dtype=object))
    tab = SimpleNamespace(name="fake", family="gauss", s=1, claimed_order=2)
    out = va.variational_errors(tab, "fake", hs=hs, dps=20)
    assert out["errors"]["f_minus"] == [_close(0.04), _close(0.01), _close(0.0025)]
    assert out["orders"]["f_minus"] == _close(2.0, rel=1e-6)
    # L_d is zero at h = 0.05 only: an order from the two larger h, not "zero at every h"
    assert out["orders"]["L_d"] == _close(math.log2(1e3), rel=1e-6)
    assert out["orders"]["f_plus"] == math.inf          # zero at every h
