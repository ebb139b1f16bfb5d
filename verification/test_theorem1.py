"""Theorem 1: dL_d/dq0 = -p0^T - f_d^-^T and dL_d/dq1 = p1^T - f_d^+^T.

dL_d/dq by Richardson-extrapolated central differences of the boundary-value solve at 60
digits (error estimate included) against the printed formulas evaluated with the
implicit-differentiation sensitivities dV/dq0, dV/dq1; residual <= 1e-20 relative at 40 digits
(the ledger's threshold) and <= the residual's own error (``general_fixtures.theorem1_tol``).
Also: the sensitivities against finite differences of V, the well-posedness classes, the
gauge invariance, negative controls (residual >= 1e-6) and the ledger writer."""
import json

import mpmath
import numpy as np
import pytest

from general_fixtures import theorem1_tol
from ldaspark.core.backend import Backend
from ldaspark.analysis.discrete import GAUGE, SINGULAR, WELLPOSED, base_point, discrete_lagrangian, theorem1_residuals
from ldaspark.analysis.wellposedness import classify_wellposedness, gauge_invariance
from ldaspark.core.families import builtin_method_names
from ldaspark.lab.reports.claims import write_markdown
from ldaspark.lab.claims.ledger import TOL_NEGATIVE, TOL_THEOREM1, negative_controls, perturbed_initial, run_ledger

H = "0.1"
DEFAULT_METHODS = builtin_method_names(3)


def _t1(scene, tab, point="base", q1_shift=None):
    if point == "base":
        t0, q0, v0 = scene.initial(60)
    else:
        t0, q0, v0 = perturbed_initial(scene, 60)
    return theorem1_residuals(scene.system, tab, t0, q0, v0, H, dps=40, q1_shift=q1_shift)


@pytest.mark.parametrize("name", DEFAULT_METHODS)
@pytest.mark.parametrize("scn", ["particle", "skate"])
def test_theorem1_builtin(name, scn, exact_method, scene):
    r = _t1(scene(scn), exact_method(name))
    assert r["fd_error"] < 1e-25, r                 # the finite differences resolve 1e-20
    assert r["theorem1-q0"] <= TOL_THEOREM1, r
    assert r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)
    # the forces are not negligible where they should not be: without them the identity fails
    if r["f_d_minus_norm"] > 1e-10:
        assert r["without_forces_q0"] > 1e-6


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-2"])
def test_theorem1_robot(name, exact_method, scene):
    r = _t1(scene("robot"), exact_method(name))
    assert r["theorem1-q0"] <= TOL_THEOREM1 and r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)


def test_theorem1_mp_particles(exact_method, scene):
    r = _t1(scene("mp-particles"), exact_method("gauss-1"))
    assert r["theorem1-q0"] <= TOL_THEOREM1 and r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-3"])
def test_theorem1_perturbed_points(name, exact_method, scene):
    sc = scene("skate")
    r = _t1(sc, exact_method(name), point="perturbed")
    assert r["theorem1-q0"] <= TOL_THEOREM1 and r["theorem1-q1"] <= TOL_THEOREM1, r
    assert max(r["theorem1-q0"], r["theorem1-q1"]) <= theorem1_tol(r), (theorem1_tol(r), r)
    if r["wellposed"] == WELLPOSED:  # off the constraint manifold: v0 inconsistent, still a solve
        shift = [mpmath.mpf(1) / 1000 * (-1) ** k for k in range(3)]
        r = _t1(sc, exact_method(name), point="perturbed", q1_shift=shift)
        assert r["theorem1-q0"] <= TOL_THEOREM1 and r["theorem1-q1"] <= TOL_THEOREM1, r


@pytest.mark.parametrize("idx", [0, 1, 2])
def test_negative_controls_theorem1(idx, scene):
    tab, intended = negative_controls()[idx]
    r = _t1(scene("particle"), tab)
    assert r["theorem1-q1"] >= TOL_NEGATIVE, r          # (22) broken: the identity must fail
    if "A_hat" in tab.name:
        assert r["theorem1-q0"] >= TOL_NEGATIVE, r
    else:  # b_hat != b alone: the q0 algebra does not involve b_hat
        assert r["theorem1-q0"] <= TOL_THEOREM1, r


def test_sensitivities_match_finite_differences(exact_method, scene):
    """dV/dq0, dV/dq1 from one linear solve with the Jacobian vs central differences of V."""
    sc = scene("particle")
    tab = exact_method("gauss-2")
    bk = Backend(40)
    with bk.context():
        t0, q0, v0 = sc.initial(40)
        t1, q1, xg = base_point(sc.system, tab, t0, q0, v0, H, 40)
        q0 = bk.array(q0)
        r = discrete_lagrangian(sc.system, tab, bk.scalar(t0), q0, t1, q1, dps=40, x_guess=xg)
        d = mpmath.mpf("1e-12")
        for k in range(3):
            for which in (0, 1):
                qa, qb = (q0.copy(), q1.copy())
                qm_a, qm_b = (q0.copy(), q1.copy())
                (qa if which == 0 else qb)[k] += d
                (qm_a if which == 0 else qm_b)[k] -= d
                rp = discrete_lagrangian(sc.system, tab, bk.scalar(t0), qa, t1, qb, dps=40, x_guess=r.x)
                rm = discrete_lagrangian(sc.system, tab, bk.scalar(t0), qm_a, t1, qm_b, dps=40, x_guess=r.x)
                fd = (rp.V - rm.V) / (2 * d)
                an = (r.dV_dq0 if which == 0 else r.dV_dq1)[:, :, k]
                scale = max(bk.norm_inf(an), 1)
                assert bk.norm_inf(fd - an) / scale < 1e-15


def test_wellposedness_classes(exact_method, scene):
    sc = scene("particle")
    t0, q0, v0 = sc.initial(60)
    g = classify_wellposedness(sc.system, exact_method("gauss-2"), t0, q0, v0, H)
    assert g["class"] == WELLPOSED and g["rank_deficiency"] == 0
    # a genuinely small sigma: scales like a power of h, does not move with dps
    assert g["sigma_min_nonzero_rel"] < 1e-5 and g["sigma_min_power_of_h"] > 2
    assert g["sigma_stable_across_dps"]
    lo = classify_wellposedness(sc.system, exact_method("lobatto-iiia-iiib-2"), t0, q0, v0, H)
    # structural zero: A_tilde = IIIB has first column b_1 = b_tilde_1 -> gauge (p0, Lambda_1)
    assert lo["class"] == GAUGE and lo["rank_deficiency"] == 1 and lo["floor_tracks_precision"]
    assert max(lo["sigma"]["dps=50,h=0.1"][-1], lo["sigma"]["dps=50,h=0.05"][-1]) < 1e-45
    assert min(lo["sigma"]["dps=30,h=0.1"][-1], lo["sigma"]["dps=30,h=0.05"][-1]) > 1e-45
    rob = scene("robot")
    t0, q0, v0 = rob.initial(60)
    sg = classify_wellposedness(rob.system, exact_method("gauss-2"), t0, q0, v0, H)
    assert sg["class"] == SINGULAR and sg["null_support"]["V"] > 1e-3


def test_gauge_invariance(exact_method, scene):
    sc = scene("particle")
    t0, q0, v0 = sc.initial(60)
    g = gauge_invariance(sc.system, exact_method("lobatto-iiia-iiib-3"), t0, q0, v0, H)
    assert g["wellposed"] == GAUGE
    assert g["dp0"] > 1e-6                       # the gauge really moves p0 ...
    assert max(g["dL_d"], g["d(p0+f_d_minus)"], g["d(p1-f_d_plus)"]) < 1e-30   # ... not L_d
    s = gauge_invariance(sc.system, exact_method("lobatto-iiia-iiib-iiid-3"), t0, q0, v0, H)
    assert s["wellposed"] == SINGULAR and s["dL_d"] > 1e-10   # singular: L_d depends on the pin
    assert gauge_invariance(sc.system, exact_method("gauss-1"), t0, q0, v0, H) is None


def test_ledger_records_and_markdown(tmp_path):
    recs = run_ledger(max_s=1, scenes=("skate",), perturbed=False, holonomic=False, controls=False, jobs=2)
    serial = run_ledger(max_s=1, scenes=("skate",), perturbed=False, holonomic=False, controls=False, jobs=1)

    def strip(rs):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rs]
    assert strip(recs) == strip(serial)          # worker processes: same records, same order
    assert strip(recs) != strip(serial[::-1])    # control: the comparison sees the order
    keys = {"claim", "method", "scene", "status", "residual", "dps", "wellposed", "seconds", "expected"}
    assert all(keys <= set(r) for r in recs)
    claims = {r["claim"] for r in recs}
    assert {"22a", "22b", "23", "theorem1-q0", "theorem1-q1", "symmetry-Ld", "constraint"} <= claims
    for r in recs:
        assert r["status"] in ("pass", "fail", "not-applicable")
        assert r["wellposed"] in ("well-posed", "gauge-deficient", "singular", "n/a")
    euler = [r for r in recs if r["method"] == "euler-i" and r["claim"] == "symmetry-Ld"]
    assert euler and all(r["status"] == "fail" and r["expected"] == "fail" for r in euler)
    write_markdown(recs, tmp_path / "claims.md", 1.0, "test")
    json.dumps(recs, allow_nan=False)
    assert "| theorem1-q0 |" in (tmp_path / "claims.md").read_text()


@pytest.mark.exhaustive
@pytest.mark.parametrize("name", builtin_method_names(6))
@pytest.mark.parametrize("scn", ["particle", "skate", "robot", "mp-particles"])
def test_theorem1_exhaustive(name, scn, scene):
    from ldaspark.core.families import get_method
    tab = get_method(name)
    for point in ("base", "perturbed"):
        r = _t1(scene(scn), tab, point=point)
        assert r["theorem1-q0"] <= TOL_THEOREM1 and r["theorem1-q1"] <= TOL_THEOREM1, (point, r)


@pytest.mark.parametrize("name", ["gauss-2", "lobatto-iiia-iiib-2"])
def test_float64_and_mpmath_agree(name, exact_method, scene):
    """discrete_lagrangian in float64 (no guess: secant v0) matches the 40-digit solve."""
    sc = scene("skate")
    tab = exact_method(name)
    out = {}
    for dps in (None, 40):
        t0, q0, v0 = sc.initial(dps)
        t1, q1, _ = base_point(sc.system, tab, t0, q0, v0, "0.1" if dps else 0.1, dps)
        out[dps] = discrete_lagrangian(sc.system, tab, t0, q0, t1, q1, dps=dps)
    a, b = out[None], out[40]
    assert a.wellposed == b.wellposed
    assert abs(a.L_d - float(b.L_d)) < 1e-14
    for k in ("f_d_minus", "f_d_plus", "p0", "p1"):
        assert np.max(np.abs(getattr(a, k) - np.array([float(x) for x in getattr(b, k)]))) < 1e-11
