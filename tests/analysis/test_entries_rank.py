"""The rank of Theorem 1's boundary-value Jacobian J for a tableau whose entries are known only to
their digits (float64, as users publish them): rounding moves an exact zero singular value of J off
zero by the same amount at every dps, so the working precision alone cannot call it zero.

Gauss-2 on mp-particles (h = 1/10) is singular for the exact method (one zero sigma, at the
precision floor 10^-dps); written in float64 that sigma sits at 4.8e-22 sigma_max at dps 30 and 50
(not a floor: it does not move with dps), inside what the entries' uncertainty (6.8e-16) can move it
(a response of 6.8e-2 per unit change, measured, times 10 sqrt(20): 2.1e-15). Before the fix
``classify_wellposedness`` called it "well-posed", and ``check_symmetry`` at dps 50 (threshold
10^-25) solved the reversed BVP without the gauge border along that direction: L_d(t1,q1,t0,q0) +
L_d missed by 1.3e-3 (the exact method: 0), and ``ldaspark audit --dps 50`` failed the float64
Gauss-2's symmetry (exit 1)."""
from __future__ import annotations

import json

import sympy

import ldaspark
from ldaspark.core.families import get_method
from ldaspark.core.numbers import JsonNumber
from ldaspark.core.tableau_file import from_json_dict


def _float64(name):
    """The built-in as its users publish it in float64: a JSON file, every entry a JSON number (the
    float's shortest repr, read back as the decimal text it is)."""
    d = get_method(name, exact=True).to_json_dict()
    f = lambda x: float(sympy.N(sympy.sympify(x), 30))
    text = json.dumps({k: (v if k == "name" else [[f(x) for x in r] if isinstance(r, list) else f(r) for r in v])
                       for k, v in d.items()})
    return from_json_dict(json.loads(text, parse_float=JsonNumber))


def _scene(name, dps):
    sc = ldaspark.get_scene(name)
    t0, q0, v0 = sc.initial(dps + 45)
    return sc.system, t0, q0, v0


def test_float64_gauss2_rank_is_not_decided_where_the_exact_method_is_singular():
    f64, exact = _float64("gauss-2"), get_method("gauss-2", exact=True)
    system, t0, q0, v0 = _scene("mp-particles", 50)
    r = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    # before the fix: "well-posed" (rank deficiency 0)
    assert r["class"] == "not decided", r["class"]
    u = r["entries_undecided"]
    assert u["class_if_zero"] == "singular" and u["count"] == 1
    assert u["sigma_rel"] <= u["bound"]
    # the exact method: singular, decided by the precision floor (no entries' uncertainty)
    re = ldaspark.classify_wellposedness(system, exact, t0, q0, v0, 0.1, dps=(30, 50))
    assert re["class"] == "singular" and "entries_undecided" not in re
    # control: a genuine small sigma above the entries' reach stays decided (skate: 4.4e-5 sigma_max)
    system, t0, q0, v0 = _scene("skate", 50)
    rs = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    assert rs["class"] == "well-posed" and "entries_undecided" not in rs


def test_float64_gauss2_is_symmetric_at_dps_50_on_mp_particles():
    f64, exact = _float64("gauss-2"), get_method("gauss-2", exact=True)
    system, t0, q0, v0 = _scene("mp-particles", 50)
    r = ldaspark.check_symmetry(system, f64, t0, q0, v0, 0.1, dps=50)
    # before the fix: symmetry-Ld 1.3e-3, "well-posed". The float64 entries are ~1e-16 off (23);
    # the identities respond with O(1) per unit change on this scene (the audit measures 8.8e4 at
    # most, with the f_d parts): 1e-10 is above anything the entries can explain and far below 1.3e-3
    assert r["symmetry-Ld"] < 1e-10 and r["symmetry-Phi"] < 1e-10, r
    assert r["wellposed"] == "singular" and r["rank_at_entries_precision"]
    # the exact method, for comparison: the same class, L_d symmetric to the working precision
    re = ldaspark.check_symmetry(system, exact, t0, q0, v0, 0.1, dps=50)
    assert re["wellposed"] == "singular" and re["symmetry-Ld"] < 1e-40 and not re["rank_at_entries_precision"]


def test_theorem1_residuals_does_not_call_a_float64_rank_the_exact_method_lacks_well_posed():
    """Lobatto IIIA-IIIB-IIID 3 on the particle: singular for the exact method; in float64 the zero
    sigma sits at 9.6e-24 sigma_max, above the working precision's 10^-25 at dps_fd = 50, and the
    solve (which succeeds: no retry at the entries' precision) called J "well-posed"."""
    f64, exact = _float64("lobatto-iiia-iiib-iiid-3"), get_method("lobatto-iiia-iiib-iiid-3", exact=True)
    system, t0, q0, v0 = _scene("particle", 30)
    r = ldaspark.theorem1_residuals(system, f64, t0, q0, v0, 0.1, dps=30)
    assert r["wellposed"] == "not decided", r["wellposed"]       # before the fix: "well-posed"
    assert r["entries_undecided"]["count"] == 1 and r["rank_deficiency"] == 0
    # Theorem 1 itself holds: relative residual 2.1e-32 (the entries' effect on this scene is below
    # the dps-30 tolerance 1e-15 of the audit)
    assert max(r["theorem1-q0"], r["theorem1-q1"]) < 1e-15
    re = ldaspark.theorem1_residuals(system, exact, t0, q0, v0, 0.1, dps=30)
    assert re["wellposed"] == "singular" and "entries_undecided" not in re
    # control: a well-posed J stays so in float64 (Gauss-2 on the skate, sigma_min 4.4e-5 sigma_max)
    system, t0, q0, v0 = _scene("skate", 30)
    rs = ldaspark.theorem1_residuals(system, _float64("gauss-2"), t0, q0, v0, 0.1, dps=30)
    assert rs["wellposed"] == "well-posed" and "entries_undecided" not in rs


def test_a_failed_probe_leaves_the_rank_as_the_working_precision_decides_it(monkeypatch):
    """When the step of a moved tableau fails nothing is measured: the class stays the one the
    working precision gives (no error, no 'not decided' without a measurement)."""
    from ldaspark.analysis import discrete as D
    f64 = _float64("gauss-2")
    system, t0, q0, v0 = _scene("mp-particles", 50)
    real = D.base_point

    def failing(system, tab, *a, **k):
        if tab.name.endswith(" moved"):
            raise D.DiscreteSolveError("probe step failed (test)")
        return real(system, tab, *a, **k)
    monkeypatch.setattr(D, "base_point", failing)
    r = ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))
    assert r["class"] == "well-posed" and "entries_undecided" not in r
    monkeypatch.setattr(D, "base_point", real)           # control: measured, not decided
    assert ldaspark.classify_wellposedness(system, f64, t0, q0, v0, 0.1, dps=(30, 50))["class"] == "not decided"
