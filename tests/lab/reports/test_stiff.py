"""Section 7 of reports/stability.md: stiff forces, h omega from 1e-2 to 1e4, against the
linear stability function of the tableau; and the regimes table at the top of that report."""
import math

import pytest

from ldaspark.lab.reports.stability_regimes import regimes
from ldaspark.lab.reports.stability_stiff import (DE_BOUND, DE_GROWTH, HW, classify, linear_stability, stiff_job,
                                              stiff_run)


# --- the linear stability function from the tableau --------------------------------------------
@pytest.mark.parametrize("method", ["gauss-1", "gauss-2", "gauss-3"])
def test_gauss_is_a_stable_on_the_imaginary_axis(method):
    """Gauss: the eigenvalues of the step matrix are R(+-i z), abs(R(i z)) = 1 for every z (A-stable,
    symplectic): rho = 1 to round-off of the 2x2 solve (1e-12 allows cond(I + z^2 A_hat A) ~ 1e8 at
    z = 1e4 times eps)."""
    for z in HW:
        rho, R = linear_stability(method, z)
        assert abs(rho - 1) <= 1e-12 * max(1.0, z) and abs(R - 1) <= 1e-12 * max(1.0, z), (z, rho, R)


@pytest.mark.parametrize("z", [0.5, 1.0, 1.9, 2.1, 3.0, 10.0, 100.0])
def test_lobatto_2_is_stormer_verlet(z):
    """2-stage Lobatto IIIA-B on the oscillator is Stormer-Verlet (25): trace M = 2 - z^2, det 1,
    so rho = 1 for z < 2 and rho = (z^2 - 2 + sqrt((z^2 - 2)^2 - 4)) / 2 beyond (two-sided, relative
    1e-12)."""
    rho, R = linear_stability("lobatto-iiia-iiib-2", z)
    want = 1.0 if z < 2 else (z * z - 2 + math.sqrt((z * z - 2) ** 2 - 4)) / 2
    assert R is None and abs(rho - want) <= 1e-12 * want


def test_lobatto_3_stability_interval():
    """The 3-stage pair: rho = 1 at h omega = 2.1 (beyond Stormer-Verlet's 2) and > 1 at 3 (the
    report's finding: stiff runs stay bounded to 2.1 and fail from 3 on)."""
    assert abs(linear_stability("lobatto-iiia-iiib-3", 2.1)[0] - 1) <= 1e-12
    assert linear_stability("lobatto-iiia-iiib-3", 3.0)[0] > 1.3      # measured 1.35


# --- whole stiff runs (compiled engine), the report's findings ----------------------------------
def test_gauss_stays_bounded_where_lobatto_blows_up():
    """stiff-particle at h omega = 3: gauss-2 bounded (measured dE 0.3, growth ~1), Lobatto IIIA-B
    (rho = 6.9) blows up and stops (negative control of the classification)."""
    g = stiff_run("stiff-particle", "gauss-2", 3.0)
    assert classify(g) == "bounded" and g["dE_growth"] <= DE_GROWTH and g["max_rel_dE"] < DE_BOUND
    lb = stiff_run("stiff-particle", "lobatto-iiia-iiib-2", 3.0)
    assert classify(lb) != "bounded"


def test_lobatto_2_bounded_below_its_limit():
    """stiff-particle at h omega = 1 < 2: Lobatto IIIA-B bounded (measured dE 0.3 over 1000 steps)."""
    r = stiff_run("stiff-particle", "lobatto-iiia-iiib-2", 1.0)
    assert classify(r) == "bounded" and r["max_rel_dE"] < DE_BOUND


def test_gauss_2_stops_by_newton_not_by_the_method():
    """stiff-skate at h omega = 1e4: gauss-2 is A-stable (rho = 1), the run stops because the stage
    equations are not solved (the Newton matrix, with entries from 1 to (h omega)^2 = 1e8, is
    numerically singular on both engines) while the energy error is still small: 'Newton'. At
    h omega = 100 the same method is bounded with ~9 Newton iterations per step (measured 8.7;
    two-sided: more than the 3 of h omega = 0.1, at most 20)."""
    rows = {r["hw"]: r for r in stiff_job("stiff-skate", "gauss-2", hws=(0.1, 100.0, 1e4))}
    assert rows[1e4]["class"] == "failed" and rows[1e4]["why"] == "Newton"
    assert rows[1e4]["outcome"] == "NewtonError" and rows[1e4]["dE_before"] < DE_BOUND
    assert rows[100.0]["class"] == "bounded" and 3.5 < rows[100.0]["iterations"] <= 20
    assert rows[0.1]["iterations"] <= 3.5


# --- the regimes table ----------------------------------------------------------------------------
def test_regimes_table_aggregates_ranges_and_worst_failure():
    d = {"tiny": [{"scene": "skate", "method": "gauss-2", "h": h, "N": 10 ** 5, "outcome": "ok", "max_dE": e}
                  for h, e in ((1e-4, 1e-15), (1e-7, 3e-14))],
         "stiff": [{"scene": "stiff-skate", "method": "gauss-1", "h": hw / 100, "hw": hw, "N": 1000,
                    "outcome": o, "why": w} for hw, o, w in ((1.0, "ok", ""), (10.0, "NewtonError", "Newton"),
                                                            (100.0, "NewtonError", "Newton"))],
         "dps": [{"dps": 400, "N": 3}, {"dps": 2000, "N": 3}]}
    rows = {(r["engine"], r["family"]): r for r in regimes(d)}
    g = rows[("compiled float64", "gauss")]
    assert g["h"] == "1e-07 .. 1" and g["hw"] == "1 .. 100" and g["s"] == "1 .. 2" and g["N"] == "1e+03 .. 1e+05"
    # the worst is the failure at the smallest h omega, not the largest error
    assert g["worst"].startswith("NewtonError from h omega = 10 (gauss-1")
    m = rows[("generic mpmath", "gauss")]
    assert m["dps"] == "400 .. 2000" and m["N"] == "3"
    # negative control: without failures the worst is the largest error (the run at h = 1e-7)
    d["stiff"] = []
    g = {(r["engine"], r["family"]): r for r in regimes(d)}[("compiled float64", "gauss")]
    assert g["worst"].startswith("max abs dE") and "h = 1e-07" in g["worst"]


def test_dps_extreme_runs_at_the_bound_without_exceeding_it():
    """The stability report's extreme-precision rows run at DPS_MAX itself; its reference is then
    the run at DPS_MAX - 40 (the API refuses more digits: the main job failed on dps = 2040)."""
    from ldaspark.core.validate import DPS_MAX
    from ldaspark.lab.reports.stability_stiff import dps_extreme
    (row,) = dps_extreme((DPS_MAX,), n=1)
    assert row["dps"] == DPS_MAX and row["ref_dps"] == DPS_MAX - 40
    # the difference is the lower-precision run's error: about 10^-(DPS_MAX - 40), not O(1)
    assert row["log10_diff"] is None or -DPS_MAX - 5 < row["log10_diff"] < -(DPS_MAX - 40) + 5


# --- a stiff spring along a fixed direction, the constraint turning: Gauss is not bounded ----------
def test_gauss_energy_grows_on_a_stiff_spring_the_blade_turns_across_and_readme_says_so():
    """The skate of 8.2 with a stiff spring along x only, U = omega^2 q1^2 / 2 + q2^2 / 2 (omega = 100),
    the blade turning at rate 1 (q3' = 1, no torque): the exact flow conserves the energy (8)
    (scleronomic, linear in v), and Gauss SPARK, A-stable (rho = 1), keeps it bounded at h omega = 20
    (relative dE 2-17 over 400 steps, not growing: O(1), the stiff motion unresolved) but not at
    h omega = 80: the energy grows geometrically (measured relative dE 1.7e17 / 2.1e32 / 1.5e58 after
    200 steps of gauss-1/2/3) while every step converges (status 0; the guard solves the flagged steps
    again and finds the same root), the compiled engine agreeing with the generic one at 40 digits
    (1.5e-12 relative after 40 steps). So "Gauss keeps the energy bounded at large h omega until
    Newton stops" holds on the report's two scenes, not in general, and the README must say so."""
    import pathlib

    import numpy as np
    import sympy

    import ldaspark
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - 100 ** 2 * q[0] ** 2 / 2 - q[1] ** 2 / 2
    k = [sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0]]
    system = ldaspark.LagrangianSystem(L, k, q, v, name="stiff-x-skate")
    q0, v0 = [0.01, 0.0, 0.4], [math.cos(0.4), math.sin(0.4), 1.0]

    def rel_dE(hw, n):
        r = ldaspark.integrate(system, "gauss-2", t0=0, n_steps=n, q0=q0, v0=v0, h=hw / 100, engine="compiled")
        assert r.status == 0, r.message
        E = np.asarray(r.energy, float)
        dE = np.abs(E - E[0]) / E[0]
        return float(dE[:len(dE) // 2].max()), float(dE[len(dE) // 2:].max())

    first, second = rel_dE(20.0, 400)
    assert second <= DE_GROWTH * first and second < 10           # bounded, O(1) (measured 2.4, 2.0)
    first, second = rel_dE(80.0, 200)
    assert first > 1e10 and second > 1e10 * first                 # geometric growth (3.4e15, 3.0e32)
    readme = (pathlib.Path(__file__).resolve().parents[3] / "README.md").read_text()
    row = next(line for line in readme.splitlines() if line.startswith("| Stability at the extremes"))
    assert "stiff spring along a fixed direction" in row and "grows" in row, row
