"""Rules of ``ldaspark.lab.theory.orders`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import math
import types
import pytest
from ldaspark.core.errors import InputError, LdasparkError, TableauError
from ldaspark.lab.theory import orders as orr
from types import SimpleNamespace
from hypothesis import given, settings
from hypothesis import strategies as st
from ldaspark.core.errors import InputError
from ldaspark.lab.theory import orders


def approx(expected, rel=1e-9, abs=0.0):
    """pytest.approx without its default absolute tolerance 1e-12, which would let every residual
    of these tests (1e-15 .. 1e-30) equal every other."""
    return pytest.approx(expected, rel=rel, abs=abs)


class _Ref:
    """psi(t) = (10 t, -1/2), q = (1, -2), v = (-3,) at every t: records where it was asked."""

    def __init__(self):
        self.ts = []

    def __call__(self, t):
        self.ts.append(float(t))
        return [1.0, -2.0], [-3.0], [float(t) * 10, -0.5]


# ==== orders ==================================================================================
def test_orders_method_scope_verdict_uses_the_worse_component():
    base = {"method": "gauss-irk-2", "scene": "s", "claim_scope": "method", "claimed_order": 2}
    recs = [dict(base, variable="q", observed_order=3.0), dict(base, variable="v", observed_order=2.1),
            dict(base, variable="psi", observed_order=0.1), dict(base, scene="o", variable="q", observed_order=0.5)]
    assert orr.verdict(recs[0], recs) == "holds"
    recs[1]["observed_order"] = 2.5
    assert orr.verdict(recs[0], recs) == "HIGHER than claimed"
    recs[1]["observed_order"] = 2.3                     # min 2.3 - 2 = 0.3: at the tolerance
    assert orr.verdict(recs[0], recs) == "holds"
    recs[1]["observed_order"] = 1.6
    assert orr.verdict(recs[0], recs) == "FAILS"
    recs[1]["observed_order"] = None
    assert orr.verdict(recs[0], recs) == "NO WINDOW"
    assert orr.verdict(recs[0]) == "FAILS"               # no records: its own order 3.0
    assert orr.verdict(dict(recs[0], claimed_order=None)) == "no claim"
    rec = dict(base, claim_scope="variable", variable="q", observed_order=3.2)
    assert orr.verdict(rec, recs) == "FAILS" and orr.verdict(dict(rec, observed_order=2.3)) == "holds"
    assert orr.verdict(dict(rec, observed_order=1.75)) == "holds" and orr.verdict(dict(rec, observed_order=1.65)) == "FAILS"


def test_orders_claims_and_stage_nodes():
    assert orr.claim_scope("gauss-irk-3") == "method" and orr.claim_scope("gauss-3") == "variable"
    assert orr.claimed_order_of("gauss-irk-2") == 2 and orr.claimed_order_of("gauss-irk-1") == 1
    assert orr.claimed_order_of("gauss-irk-3") is None and orr.claimed_order_of("gauss-3") == 6
    assert orr.claimed_order_of("lobatto-iiia-iiib-2-leapfrog") is None
    assert orr.stage_nodes("lobatto-iiia-iiib-2-leapfrog") is None
    c = orr.stage_nodes("gauss-irk-2")
    assert len(c) == 2 and abs(c[0] - (0.5 - math.sqrt(3) / 6)) < 1e-15
    assert list(orr.stage_nodes("lobatto-iiia-iiib-2")) == [0.0, 1.0]


def test_order_records_skip_empty_psi_and_use_scaled_floor():
    m = {"h": [0.2, 0.1, 0.05], "q": [4e-2, 1e-2, 2.5e-3], "v": [1e-1, 1e-2, 1e-3], "psi": [],
         "scale": {"q": 1e12, "v": 1.0, "psi": 0.0}}
    recs = orr.order_records("gauss-1", "sc", 2, m, None, 1, "exact", psi_claimed=1)
    assert [r["variable"] for r in recs] == ["q", "v"]
    assert recs[0]["floor"] == approx(orr.floor_for(None, 1e12)) and recs[0]["floor"] > 4e-2
    assert recs[0]["observed_order"] is None                    # every q error below the scaled floor
    assert recs[1]["observed_order"] == approx(math.log(10) / math.log(2)) and recs[1]["window"] == [0, 2]
    m["psi"] = [1e-1, 5e-2, 2.5e-2]
    recs = orr.order_records("gauss-1", "sc", 2, m, None, 1, "exact", psi_claimed=1)
    assert recs[2]["claimed_order"] == 1 and recs[1]["claimed_order"] == 2 and "Psi_i" in recs[2]["compared"]


def test_measure_orders_passes_reference_and_claim(monkeypatch):
    seen = {}

    def me(method, scene, ref, t_end, n_list, dps=None, newton="full"):
        seen.update(ref=ref, n=n_list, newton=newton)
        return {"h": [0.5, 0.25], "q": [1e-2, 2.5e-3], "v": [1e-2, 2.5e-3], "psi": [],
                "scale": {"q": 1.0, "v": 1.0, "psi": 0.0}}
    monkeypatch.setattr(orr, "measure_errors", me)
    ref = types.SimpleNamespace(kind="mine")
    recs = orr.measure_orders("gauss-1", "skate", n_list=(2, 4), reference=ref, newton="simple")
    assert seen["ref"] is ref and seen["n"] == [2, 4] and seen["newton"] == "simple"
    assert recs[0]["reference"] == "mine" and recs[0]["claimed_order"] == 2
    assert recs[0]["observed_order"] == approx(2.0)
    recs = orr.measure_orders("gauss-1", "skate", n_list=(2, 4))
    assert isinstance(seen["ref"], orr.ExactReference) and recs[0]["reference"] == "exact"


def test_asymptotic_window_strict_decrease_floor_and_ties():
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-3, 1e-4], 0.0) == (1, 2)
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-4, 1e-5], 5e-5) == (0, 1)    # 1e-5 is not above the floor
    assert orr.asymptotic_window([4, 2, 1], [1e-3, 1e-4, 1e-5], 1e-4) is None      # nor is 1e-4 (strictly above)
    assert orr.asymptotic_window([8, 4, 2, 1], [1e-3, 1e-4, float("nan"), 1e-4], 0.0) == (0, 1)
    assert orr.asymptotic_window([8, 4, 2, 1, 0.5], [1e-3, 1e-4, 1.0, 1e-1, 1e-2], 0.0) == (2, 4)
    with pytest.raises(InputError):
        orr.estimate_order([0.1, 0.1], [1e-2, 1e-3], 0.0)
    assert orr.pairwise_orders([0.2, 0.1], [1e-2, float("inf")]) == [None]
    assert orr.pairwise_orders([0.2, 0.1], [-1e-2, 1e-3]) == [None]


def test_measure_errors_compares_psi_at_the_last_steps_stage_times(monkeypatch):
    sc = types.SimpleNamespace(system="S", initial=lambda dps: (0.5, [0.0, 0.0], [0.0]))
    T = 1.5

    def run(name, system, t0, q0, v0, h, N, dps=None, newton="full"):
        h = float(h)
        psi_last = [[(T - h + c * h) * 10 + 0.5 * h * (i + 1), -0.5] for i, c in enumerate((0.25, 0.75))]
        return types.SimpleNamespace(q=[None, [1.0 + h, -2.0]], v=[None, [-3.0 - 2 * h]],
                                     psi=[None, psi_last], stats={"N": N, "h": h})
    monkeypatch.setattr(orr, "run_method", run)
    monkeypatch.setattr(orr, "stage_nodes", lambda name, dps=None: [0.25, 0.75])
    ref = _Ref()
    m = orr.measure_errors("m", sc, ref, T, [2, 4])          # h = (T - t0) / N
    assert m["h"] == [0.5, 0.25] and m["q"] == approx([0.5, 0.25]) and m["v"] == approx([1.0, 0.5])
    assert m["psi"] == approx([0.5, 0.25])           # the larger of the two stages: 0.5 h * 2
    assert ref.ts[0] == T and ref.ts[1:3] == approx([1.125, 1.375]) and ref.ts[3:] == approx([1.3125, 1.4375])
    assert m["scale"] == {"q": 2.0, "v": 3.0, "psi": approx(14.375)}
    assert [s["N"] for s in m["stats"]] == [2, 4]
    monkeypatch.setattr(orr, "stage_nodes", lambda name, dps=None: None)     # a comparator: no Psi
    m = orr.measure_errors("m", sc, _Ref(), T, [2])
    assert m["psi"] == [] and m["scale"]["psi"] == 0.0


def test_asymptotic_window_may_start_right_after_a_bad_point():
    assert orr.asymptotic_window([4, 2, 1], [float("nan"), 1e-3, 1e-4], 0.0) == (1, 2)
    assert orr.asymptotic_window([8, 4, 2, 1], [1e-3, 1e-9, 1e-4, 1e-5], 1e-8) == (2, 3)
    # a shorter run after a longer one does not win
    assert orr.asymptotic_window([32, 16, 8, 4, 2, 1], [1e-2, 1e-3, 1e-4, 1e-5, 1.0, 1e-1], 0.0) == (0, 3)


def test_ode_reference_counts_every_rhs_evaluation():
    calls = []

    def ode_rhs(bk, t, q, v):          # q'' = -q, psi = q
        calls.append(t)
        return [-x for x in q], [q[0]]
    S = types.SimpleNamespace(n=1, ode_rhs=ode_rhs)
    ref = orr.ODEReference(S, 0, [1], [0], dps=15)
    assert ref.n_rhs == len(calls)
    q, v, psi = ref(0.5)
    assert ref.n_rhs == len(calls) - 1 and ref.n_rhs > 0     # the psi evaluation is not the ODE's
    assert abs(float(q[0]) - math.cos(0.5)) < 1e-12 and abs(float(v[0]) + math.sin(0.5)) < 1e-12
    assert float(psi[0]) == float(q[0])


def _close(x, rel=1e-9):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny numbers."""
    return pytest.approx(x, rel=rel, abs=0.0)


# --- orders: the scales of the round-off floors are the largest reference components -------------
def test_order_measurement_scales_are_the_largest_reference_components(monkeypatch):
    from ldaspark.lab.theory import orders

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


def _close_3(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


def _rec(method, scene, variable, observed, claimed=2, scope="variable"):
    return {"method": method, "scene": scene, "variable": variable, "observed_order": observed,
            "claimed_order": claimed, "claim_scope": scope}


# --- orders: step sizes, method-scope verdicts --------------------------------------------------------
def test_step_sizes_must_decrease_at_every_step():
    errs = [1e-2, 1e-3, 1e-4]
    orders.estimate_order([0.1, 0.05, 0.025], errs, 1e-15)                 # strictly decreasing: accepted
    for hs in ([0.1, 0.05, 0.1], [0.1, 0.2, 0.05], [0.1, 0.1, 0.05], [0.1, 0.05, 0.05]):
        # one bad pair among two (any, not all), equal steps too (>=, not >)
        with pytest.raises(InputError):
            orders.estimate_order(hs, errs, 1e-15)


def test_a_method_scope_verdict_takes_the_worse_of_q_and_v():
    rec = _rec("m", "s", "q", 2.0, scope="method")
    # q at 2, v at 4: the method's order is min = 2 (max would say HIGHER than claimed)
    recs = [rec, _rec("m", "s", "v", 4.0), _rec("m", "other", "v", 1.0), _rec("n", "s", "v", 1.0)]
    assert orders.verdict(rec, recs) == "holds"
    # the worse one fails: the verdict fails although q alone holds
    recs = [rec, _rec("m", "s", "v", 1.2)]
    assert orders.verdict(rec, recs) == "FAILS"
    # one of the two has no window: no window (not: the other decides)
    recs = [rec, _rec("m", "s", "v", None)]
    assert orders.verdict(rec, recs) == "NO WINDOW"
    # both above the claim by more than tol: higher
    recs = [_rec("m", "s", "q", 3.0, scope="method"), _rec("m", "s", "v", 3.5)]
    assert orders.verdict(recs[0], recs) == "HIGHER than claimed"


@settings(deadline=None)
@given(o=st.floats(0.5, 6.0), c=st.integers(1, 5))
def test_an_order_verdict_is_two_sided(o, c):
    rec = _rec("m", "s", "q", o, claimed=c)
    assert orders.verdict(rec) == ("holds" if abs(o - c) <= 0.3 else "FAILS")


# --- ratios: the right way up ---------------------------------------------------------------------------
@settings(deadline=None)
@given(p=st.floats(0.5, 8.0), c=st.floats(1e-3, 1e3), h0=st.floats(0.01, 1.0), k=st.integers(2, 5))
def test_pairwise_orders_recover_the_power(p, c, h0, k):
    # errors c h^p at h0 / 2^j: every pairwise order is p (either quotient upside down gives -p)
    hs = [h0 / 2 ** j for j in range(k)]
    out = orders.pairwise_orders(hs, [c * h ** p for h in hs])
    assert out == _close_3([p] * (k - 1), rel=1e-9, abs=1e-9)
    # a zero error has no order; the neighbouring pairs keep theirs
    out = orders.pairwise_orders(hs, [c * h ** p for h in hs[:-1]] + [0.0])
    assert out[-1] is None and all(o == _close_3(p, rel=1e-9) for o in out[:-1])


def test_the_least_squares_slope_uses_the_window_only():
    # the window is the first two points (the third is below the floor): slope log2(10)
    est = orders.estimate_order([0.1, 0.05, 0.025], [1e-2, 1e-3, 1e-20], 1e-12)
    assert est.window == (0, 1) and est.observed_order == _close_3(math.log2(10))


def test_equal_errors_end_the_asymptotic_window():
    assert orders.asymptotic_window([0.1, 0.05, 0.025], [1e-2, 1e-3, 1e-3], 1e-12) == (0, 1)
