"""Units of ldaspark.lab.theory.orders: order estimation (LS over the asymptotic window, pairwise),
the references, and the claim verdicts. Each check has a negative control."""
import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, strategies as st

from ldaspark.lab.theory.orders import (ExactReference, ODEReference, asymptotic_window, estimate_order,
                                  floor_for, make_reference, pairwise_orders, run_method, verdict)
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.models.scenes import get_scene

HS = [2.0 ** -k for k in range(2, 8)]


@given(p=st.floats(0.5, 10.0), logC=st.floats(-3.0, 3.0))
def test_ls_order_recovers_exact_power_law(p, logC):
    errs = [math.exp(logC) * h ** p for h in HS]
    est = estimate_order(HS, errs, floor=1e-300)
    assert est.window == (0, len(HS) - 1)
    assert abs(est.observed_order - p) < 1e-9
    assert all(abs(q - p) < 1e-9 for q in est.pairwise_orders)


def test_ls_order_distinguishes_orders():
    # negative control: data of order 2 do not pass as order 3
    errs = [h ** 2 for h in HS]
    assert abs(estimate_order(HS, errs, 1e-300).observed_order - 3) > 0.9


def test_window_excludes_round_off_plateau():
    floor = 1e-9
    errs = [max(h ** 6, 1e-10 * (1 + 0.3 * (-1) ** i)) for i, h in enumerate(HS)]
    est = estimate_order(HS, errs, floor)
    i0, i1 = est.window
    assert (i0, i1) == (0, 2)
    assert all(errs[i] > floor for i in range(i0, i1 + 1))
    assert abs(est.observed_order - 6) < 1e-9
    # without the floor the plateau points would bend the slope: the window is what saves it
    x, y = np.log(HS), np.log(errs)
    assert abs(np.polyfit(x, y, 1)[0] - 6) > 1.0


def test_window_requires_strict_decrease_and_two_points():
    assert asymptotic_window([0.4, 0.2, 0.1], [1e-3, 2e-3, 1e-4], 0) == (1, 2)
    assert asymptotic_window([0.4, 0.2], [1e-3, 1e-3], 0) is None
    assert asymptotic_window([0.4, 0.2, 0.1], [1e-20, 1e-21, 1e-22], 1e-15) is None
    est = estimate_order([0.4, 0.2], [1e-20, 1e-21], 1e-15)
    assert est.observed_order is None and est.window is None


def test_pairwise_orders_handle_zero_errors():
    assert pairwise_orders([0.2, 0.1, 0.05], [1e-3, 0.0, 0.0]) == [None, None]
    assert pairwise_orders([0.2, 0.1], [4e-3, 1e-3]) == pytest.approx([2.0])


def test_estimate_order_rejects_unsorted_steps():
    with pytest.raises(InputError):
        estimate_order([0.1, 0.2], [1e-3, 1e-2], 0)


def test_floor_scales_with_precision():
    # abs=0: pytest.approx's default absolute tolerance (1e-12) would pass anything below 1e-12
    assert floor_for(None, 1.0) == pytest.approx(1e3 * 2.0 ** -52, rel=1e-12, abs=0)
    assert floor_for(30, 10.0) == pytest.approx(1e3 * 1e-30 * 10, rel=1e-12, abs=0)
    assert floor_for(30, 0.5) == pytest.approx(1e3 * 1e-30, rel=1e-12, abs=0)      # max(1, |reference|)


def test_ode_reference_matches_skate_closed_form():
    """The Taylor reference of (3a-b) reproduces the skate's exact q, v, psi to ~30 digits;
    a reference started from perturbed data does not (negative control)."""
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial(30)
    ref = ODEReference(sc.system, t0, q0, v0, dps=30)
    exact = ExactReference(sc, 30)
    with mpmath.workdps(30):
        for t in ("0.3", "0.7"):
            a, b = ref(t), exact(t)
            for x, y in zip(a, b):
                assert max(abs(u - w) for u, w in zip(x, y)) < mpmath.mpf(10) ** -26
        q0p = list(q0)
        q0p[0] += mpmath.mpf("1e-6")
        bad = ODEReference(sc.system, t0, q0p, v0, dps=30)
        assert max(abs(u - w) for u, w in zip(bad("0.3")[0], exact("0.3")[0])) > 1e-7
    assert ref.n_rhs > 0


def test_make_reference_kind():
    assert make_reference(get_scene("skate")).kind == "exact"
    assert isinstance(make_reference(get_scene("pendulum"), dps=20), ODEReference)


def test_run_method_dispatch():
    sc = get_scene("skate")
    t0, q0, v0 = sc.initial()
    a = run_method("gauss-1", sc.system, t0, q0, v0, 0.1, 3)
    b = run_method("gauss-irk-1", sc.system, t0, q0, v0, 0.1, 3)
    assert a.method == "gauss-1" and b.method == "gauss-irk-1"
    assert np.abs(a.q - b.q).max() > 1e-6        # different methods, different results
    with pytest.raises(LdasparkError):
        run_method("no-such-method", sc.system, t0, q0, v0, 0.1, 3)


def _rec(method, var, claimed, observed, scope="variable", scene="s"):
    return {"method": method, "scene": scene, "variable": var, "claimed_order": claimed,
            "observed_order": observed, "claim_scope": scope}


def test_verdicts():
    assert verdict(_rec("gauss-2", "q", 4, 4.2)) == "holds"
    assert verdict(_rec("gauss-2", "q", 4, 3.6)) == "FAILS"
    assert verdict(_rec("gauss-2", "q", 4, None)) == "NO WINDOW"
    assert verdict(_rec("gauss-2", "psi", None, 3.0)) == "no claim"
    recs = [_rec("gauss-irk-2", "q", 2, 4.0, "method"), _rec("gauss-irk-2", "v", 2, 2.05, "method")]
    assert verdict(recs[0], recs) == "holds"          # method order = min over q, v
    recs2 = [_rec("gauss-irk-1", "q", 1, 2.0, "method"), _rec("gauss-irk-1", "v", 1, 2.0, "method")]
    assert verdict(recs2[0], recs2) == "HIGHER than claimed"


# --- the report sections' command-line contracts ---------------------------------------------
def test_report_convergence_json_contract(tmp_path):
    import json
    from ldaspark.cli import main
    out = tmp_path / "c.json"
    assert main(["report", "convergence", "--json", str(out), "--scenes", "skate",
                 "--methods", "gauss-1", "gauss-irk-2", "--workers", "1"]) == 0
    recs = json.loads(out.read_text())
    assert {(r["method"], r["variable"]) for r in recs} == {
        (m, v) for m in ("gauss-1", "gauss-irk-2") for v in ("q", "v", "psi")}
    for r in recs:
        for key in ("method", "scene", "variable", "claimed_order", "observed_order", "pairwise_orders",
                    "h", "errors", "dps"):
            assert key in r
        assert len(r["h"]) == len(r["errors"]) == len(r["pairwise_orders"]) + 1
    q = [r for r in recs if r["method"] == "gauss-1" and r["variable"] == "q"][0]
    assert q["claimed_order"] == 2 and abs(q["observed_order"] - 2) < 0.3 and q["dps"] is None
    assert [r for r in recs if r["variable"] == "psi"][0]["claimed_order"] is None
    assert not (tmp_path / "convergence.md").exists()       # --json alone writes only the JSON


def test_boundedness_measure_separates_bounded_from_drift():
    from ldaspark.lab.reports.energy import boundedness
    t = np.linspace(0, 100, 2001)
    assert boundedness(t, 1e-3 * np.sin(3 * t))["bounded"]
    drift = boundedness(t, 1e-3 * np.sin(3 * t) + 1e-4 * t)     # negative control: linear drift
    assert not drift["bounded"] and drift["last_over_first_quarter"] > 2
    walk = boundedness(t, 1e-3 * np.sqrt(t) * np.sin(3 * t))     # sqrt(t) growth is not bounded either
    assert not walk["bounded"]


def test_report_energy_figure_json(tmp_path):
    import json
    from ldaspark.cli import main
    out = tmp_path / "e.json"
    assert main(["report", "energy", "--figure", "2", "--t-end", "3", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["scene"] == "skate" and d["h"] == 0.1 and d["t_end"] == 3.0
    assert set(d["methods"]) == {"lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3", "lobatto-iiia-iiib-4"}
    r = d["methods"]["lobatto-iiia-iiib-2"]
    assert len(r["t"]) == len(r["dE"]) == 31 and r["max_abs_dE"] == max(abs(x) for x in r["dE"])
    with pytest.raises(InputError):
        from ldaspark.lab.reports.energy import figure_data
        figure_data(7)


def test_report_energy_figure4_through_fast_path(tmp_path):
    from ldaspark.lab.reports.energy import fig4_available, figure4, plot_fig4
    if not fig4_available():
        pytest.fail("ldaspark.lab.reports.fig4 is part of the package and must be importable")
    d = figure4(t_end=50.0)
    assert d["E0_matches_paper"] and abs(d["E0"] - 3.06) < 1e-12
    assert set(d["methods"]) == {"lobatto-iiia-iiib-2", "lobatto-iiia-iiib-2-modified", "mp-lobatto-iiib-a-2"}
    assert all(len(d["mu_over_h4"][m]) == len(d["t"]) for m in d["methods"])
    assert all(isinstance(d["fit"][m]["exponent"], float) for m in d["methods"])
    png = tmp_path / "f4.png"
    plot_fig4(d, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
