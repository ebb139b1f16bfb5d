"""Rules of ``ldaspark.lab.reports.stability_regimes`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

from ldaspark.lab.reports import stability_regimes as rg
from stability_fakes import _dps_rows, _floor_rows, _stiff_row, _stiff_rows, _tiny_rows


# ================================================================================================
# stability_regimes
# ================================================================================================
def test_family_names():
    assert rg.family("euler-ii") == ("euler-i/ii", 1)
    assert rg.family("lobatto-iiia-iiib-iiid-3") == ("lobatto-iiia-iiib-iiid", 3)
    assert rg.family("gauss-10") == ("gauss", 10)


def test_rng_formats():
    assert rg._rng([None, None], str) == "-"
    assert rg._rng([3, None, 3], str) == "3"
    assert rg._rng([5, 1, 3], str) == "1 .. 5"


def test_stiff_summary_first_not_bounded_and_linear_limit():
    S = {(r["scene"], r["method"]): r for r in rg.stiff_summary({"stiff": _stiff_rows()})}
    assert ("stiff-skate", "gauss-1") not in S
    g = S[("stiff-skate", "gauss-2")]
    assert g["bounded_to"] == 10.0 and g["first"] == {"hw": 100.0, "class": "failed", "why": "Newton",
                                                      "outcome": "NewtonError"}
    assert g["iterations"] == {1.0: 4.0, 10.0: 6.0, 100.0: 3.0}
    assert g["generic_steps"] == 2 and g["full_newton_steps"] == 0
    lo = S[("stiff-particle", "lobatto-iiia-iiib-2")]
    # bounded up to the last bounded h omega BEFORE the first non-bounded one (1.9 is bounded again, later)
    assert lo["bounded_to"] == 0.1 and lo["first"]["hw"] == 1.0 and lo["first"]["why"] == "energy growth"
    # rho = 1 + 1e-9 counts as stable (the tolerance), 1.2 does not
    assert lo["linear_stable_to"] == 1.9 and lo["unstable_linear"] == [2.1]
    l3 = S[("stiff-skate", "lobatto-iiia-iiib-3")]
    assert l3["bounded_to"] is None and l3["first"]["hw"] == 3.0 and l3["linear_stable_to"] is None
    assert l3["iterations"] == {1.0: None, 10.0: 3.0, 100.0: None}


def test_section_stiff_cells():
    d = {"stiff": _stiff_rows()}
    L = "\n".join(rg.section_stiff(d))
    assert "| stiff-skate | gauss-2 | 10 | 100: failed (Newton) | 100 | 4.0 / 6.0 / 3.0 | 0 / 2 |" in L
    assert "| stiff-skate | lobatto-iiia-iiib-2 | 0.1 | 1: growing (energy growth) | 1.9 (rho > 1 from 2.1) |" in L
    assert "| stiff-skate | lobatto-iiia-iiib-3 | - | 3: failed (linear instability) | - |" in L
    assert "failed step 5 (Newton, dE before 1.0e-04)" in L
    assert "failed step 5 (linear instability)" in L          # dE_before None: no 'dE before'
    assert "g 1.0e-03 (3.0)" in L and "b 1.0e-04 (2.0)" in L
    assert L.count("stiff-particle: class, dE and Newton iterations") == 1


def test_section_tiny_table_and_floor():
    d = {"tiny": _tiny_rows(), "floor": _floor_rows(), "dps": _dps_rows()}
    L = "\n".join(rg.section_tiny(d))
    n = len(d["tiny"])
    assert "whole runs of N = 1e+05 steps" in L                     # the largest N, not the smallest
    assert f"{n - 1} of {n} runs finish" in L
    assert "| skate | gauss-2 | 2.00 it., 2 full, dE 1.0e-17 |" in L
    assert "2.00 it., 1 generic, dE 1.0e-15 |" in L
    assert "| robot | euler-i | 2.00 it., dE 1.0e-17 | NewtonError: `no convergence` | - | - |" in L
    # min error and the h where it is reached
    assert "| gauss-1 | 3.0e-12 (0.001) | 1.0e-13 (0.0001) | 5.0e-11 / 1.0e-13 |" in L
    assert "| gauss-2 | 4.0e-14 (0.01) | 3.0e-15 (0.001) | 9.0e-13 / 4.0e-15 |" in L
    assert "dps = 400: 3 steps in 1.50 s, 3.0 Newton it./step, difference to the run at 440 digits 1e-398" in L
    assert "dps = 2000: identical to the run at 1960 digits" in L
    assert "dps = 100: 2 steps in 0.50 s, 2.0 Newton it./step, difference to the run at 140 digits 1e-120" in L
    assert "dps = 60: identical to the run at 100 digits" in L
    d["tiny"].append({"scene": "robot", "method": "euler-i", "h": 1e-6, "N": 10, "outcome": "NonFiniteError",
                      "message": "nan at step 3"})
    assert "NonFiniteError: `nan at step 3`" in "\n".join(rg.section_tiny(d))


def test_findings_lines_quote_the_extremes():
    d = {"stiff": _stiff_rows(), "tiny": _tiny_rows(), "floor": _floor_rows()}
    tiny_fail = sum(r["outcome"] != "ok" for r in d["tiny"])
    a, b = rg.findings_lines(d)
    n = len(d["tiny"])
    assert a.startswith(f"* Tiny steps: {n - tiny_fail} of {n} whole runs")
    assert "gauss-1 3.0e-12 plain, 1.0e-13 Kahan; gauss-2 4.0e-14 plain, 3.0e-15 Kahan." in a
    assert "gauss-2: 100 (Newton) / 100 (Newton)" in b
    assert "lobatto-iiia-iiib-2: 1 (energy growth) / 1 (energy growth)" in b
    assert "euler-i:" in b and "gauss-1: ;" in b                      # no rows: nothing listed
    assert "(4 scene-method pairs)" not in b and "2 scene-method pairs" in b
    # the O(1) errors of bounded Gauss runs at h omega >= 3 (3 and 10 here): min .. max
    assert "at O(1) (3.0e-03 .. 1.0e-02 relative" in b
    assert "gauss-2 stiff-particle at 100, gauss-2 stiff-skate at 100" in b
    assert "rho > 1 from h omega = 2.1 (s = 2, Stormer-Verlet: bound 2) and 3 (s = 3)" in b
    assert "Newton iterations per step: 1.5 .. 2.0 at h omega <= 0.1, 3.0 .. 4.0 at h omega = 1" in b
    # no bounded Gauss run at h omega >= 3: the O(1) clause is left out
    d["stiff"] = [r for r in d["stiff"] if not (r["method"] == "gauss-2" and r["hw"] in (3.0, 10.0))]
    assert "at O(1)" not in rg.findings_lines(d)[1]


def test_records_and_regimes_over_every_kind_of_measurement():
    d = {"tiny": [{"scene": "skate", "method": "gauss-2", "h": 1e-4, "N": 10 ** 4, "outcome": "ok", "max_dE": 1e-14},
                  {"scene": "robot", "method": "gauss-2", "h": 1e-7, "N": 10 ** 4, "outcome": "ok", "max_dE": 1e-12},
                  {"scene": "skate", "method": "euler-i", "h": 1e-5, "N": 10 ** 4, "outcome": "NewtonError"}],
         "stiff": [_stiff_row("stiff-skate", "gauss-2", 0.1, "bounded")],
         "floor": [{"method": "gauss-3", "h": [1e-2, 1e-6], "N": [10, 10 ** 5], "kahan": [1e-9, 1e-14]}],
         "long": [{"method": "lobatto-iiia-iiib-2"}],
         "step": [{"method": "gauss-1", "h": [1e-6, 0.5], "newton": [(64.0, 128.0), (None, 0.25), (4096.0, None)]}],
         "order": [({"method": "gauss-4"}, {"method": "gauss-4"})],
         "reversal": [({"method": "euler-ii"}, {"method": "euler-ii", "N": 20}),
                      ({"method": "gauss-2"}, {"method": "gauss-2", "N": 20})],
         "dps": [{"dps": 400, "N": 3}]}
    recs = rg._records(d)
    fams = {(r[0], r[1]) for r in recs}
    assert fams == {("compiled float64", "gauss"), ("compiled float64", "euler-i/ii"),
                    ("compiled float64", "lobatto-iiia-iiib"), ("generic float64", "gauss"),
                    ("generic mpmath", "gauss"), ("generic float64", "euler-i/ii"), ("generic mpmath", "euler-i/ii")}
    rows = {(r["engine"], r["family"]): r for r in rg.regimes(d)}
    c = rows[("compiled float64", "gauss")]
    assert c["h"] == "1e-07 .. 0.01" and c["hw"] == "0.1" and c["s"] == "2 .. 3" and c["dps"] == "float64"
    assert c["N"] == "10 .. 1e+05"
    assert c["worst"] == "max abs dE 1.0e-12 (gauss-2, robot, h = 1e-07, N = 1e+04)"   # the larger error
    e = rows[("compiled float64", "euler-i/ii")]
    assert e["worst"] == "NewtonError at h = 1e-05 (euler-i, skate)" and e["hw"] == "-"
    assert rows[("compiled float64", "lobatto-iiia-iiib")]["N"] == "1e+06"
    assert rows[("compiled float64", "lobatto-iiia-iiib")]["h"] == "0.05"
    gf = rows[("generic float64", "gauss")]
    # the Newton failure at the smallest h is the worst; h spans the sweep, the Newton limits and the order runs
    assert gf["worst"] == "NewtonError from h = 0.25 (gauss-1, Newton limit, section 1)"
    assert gf["h"] == "1e-06 .. 4096" and gf["s"] == "1 .. 4" and gf["N"] == "1 .. 200"
    gm = rows[("generic mpmath", "gauss")]
    assert gm["dps"] == "30 .. 400" and gm["worst"] == "no failure" and gm["N"] == "1 .. 40"
    em = rows[("generic mpmath", "euler-i/ii")]
    assert em["N"] == "40" and em["dps"] == "30" and em["h"] == "0.05"
    assert rows[("generic float64", "euler-i/ii")]["N"] == "200"
    # only the Newton limits of section 1 (no h sweep): one-step runs, N = 1, the converged h and the failing h
    only = {"step": [{"method": "gauss-2", "h": [], "newton": [(64.0, 128.0), (2.0, None)]}]}
    (row,) = rg.regimes(only)
    assert row["N"] == "1" and row["h"] == "2 .. 128" and row["worst"].startswith("NewtonError from h = 128")
    L = "\n".join(rg.section_regimes(d))
    assert "| generic mpmath | gauss | 0.05 .. 0.5 |" not in L and "| generic mpmath | gauss |" in L
    assert L.count("\n| ") == 2 + len(rows) - 1
