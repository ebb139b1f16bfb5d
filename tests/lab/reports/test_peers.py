"""The peer harness (``ldaspark.lab.reports.peers``): equal-error interpolation, the best peer, the
speed-up, every peer's solution against the skate's closed form, IDA's index-1 residual, and the
peers being optional (scikit-sundae missing: skipped with a note)."""
import numpy as np
import pytest

from ldaspark.lab.reports import peers, work_precision
from ldaspark.models.scenes import get_scene


def _power_law(kind, method, c0, p, errors):
    """Runs whose CPU time follows c0 * error^(-1/p): a method of order p on a fixed interval."""
    return [{"kind": kind, "method": method, "param": e, "cpu": c0 * e ** (-1.0 / p), "error": e,
             "energy_error": e} for e in errors]


def test_equal_error_interpolation_is_log_log():
    # a power law is a straight line in log-log: interpolation there is exact (to round-off,
    # 1e-12 relative), between runs a decade apart in error; in lin-lin it is not (here 40% off)
    rows = _power_law("peer", "a", 1e-3, 4.0, [1e-2, 1e-3, 1e-4, 1e-5])
    for t in (10 ** -2.5, 10 ** -3.7, 1e-3):
        assert abs(work_precision.cpu_at(rows, t) / (1e-3 * t ** -0.25) - 1) <= 1e-12
    assert work_precision.cpu_at(rows, 1e-6) is None and work_precision.cpu_at(rows, 1e-1) is None


def test_equal_error_cost_is_the_lower_envelope():
    # a run that costs more than a more accurate one is not on the envelope: it must not make
    # reaching a looser target look dearer (the cheapest run reaching <= 1e-3 costs 1.0)
    rows = _power_law("peer", "a", 1.0, 1e9, [1e-2, 1e-3, 1e-4])     # cost ~1 for every error
    rows.append({"kind": "peer", "method": "a", "param": 0, "cpu": 50.0, "error": 10 ** -2.5, "energy_error": 1})
    assert abs(work_precision.cpu_at(rows, 10 ** -2.5) - 1.0) <= 1e-6


def test_best_peer_is_the_cheapest_at_each_target_and_the_speedup_is_its_cost_over_spark():
    # peer "slow" (order 2) and "fast" (order 8): the order-8 one is cheaper at tight targets,
    # the order-2 one at loose targets (they cross at error 1e-4 by construction)
    e = [10.0 ** -k for k in range(1, 12)]
    rows = (_power_law("peer", "order-2", 1e-2 * 1e-4 ** 0.5, 2.0, e)
            + _power_law("peer", "order-8", 1e-2 * 1e-4 ** 0.125, 8.0, e)
            + _power_law("spark", "gauss-2", 1e-3, 4.0, e))
    lo, hi = peers.best_peer(rows, 1e-2), peers.best_peer(rows, 1e-8)
    assert lo[0] == "order-2" and hi[0] == "order-8"
    assert abs(lo[1] / (1e-2 * 1e-4 ** 0.5 * 1e-2 ** -0.5) - 1) <= 1e-12
    sp = peers.speedups(rows, (1e-2, 1e-8))
    for r in sp:
        assert r["spark"] == "gauss-2"
        assert abs(r["speedup"] - r["peer_cpu"] / r["spark_cpu"]) <= 1e-12 * r["speedup"]
        assert abs(r["spark_cpu"] / (1e-3 * r["target"] ** -0.25) - 1) <= 1e-12
    assert peers.best_peer([], 1e-3) == (None, None)


def test_work_precision_ratios_take_the_cheapest_peer():
    e = [10.0 ** -k for k in range(1, 10)]
    st = {"rows": (_power_law("spark-fast", "gauss-2", 1e-3, 4.0, e) + _power_law("scipy", "DOP853", 1e-2, 8.0, e)
                   + _power_law("peer", "ode-dop853", 2e-3, 8.0, e) + _power_law("peer", "ode-lsoda", 1.0, 3.0, e))}
    for r in work_precision.ratios(st, targets=(1e-3, 1e-6)):
        assert r["best peer name"] == "ode-dop853"
        assert abs(r["peer/spark-fast"] - r["best peer"] / r["spark-fast"]) <= 1e-12 * r["peer/spark-fast"]
        assert abs(r["best peer"] / (2e-3 * r["target"] ** -0.125) - 1) <= 1e-12
    # solve_ivp counts as a peer when it is the cheapest
    st["rows"] = [r for r in st["rows"] if r["method"] != "ode-dop853"]
    assert all(r["best peer name"] == "solve_ivp" for r in work_precision.ratios(st, targets=(1e-6,)))


@pytest.fixture(scope="module")
def skate():
    return get_scene("skate")


# CyRK's numba loop (nbsolve) compiles CyRK itself (~14 s) and IDA costs ~14 s: --exhaustive; the
# C++ loop (nbsolve2, the strongest peer) and the other SUNDIALS peers stay in the default run
_SLOW_PEERS = ("cyrk-nbsolve-DOP853", "ida")


# the CyRK peers are checked the same way, in both right-hand-side forms, by
# tests/lab/reports/test_peers_compiled_loop.py::test_cyrk_peer_follows_the_skate_closed_form: here --exhaustive
@pytest.mark.parametrize("peer", [pytest.param(p, marks=pytest.mark.exhaustive)
                                  if p in _SLOW_PEERS or p in peers.CYRK_PEERS else p for p in peers.PEERS])
def test_every_peer_follows_the_skate_closed_form(skate, peer):
    if peer in peers.SUNDIALS_PEERS and peers.sundials() is None:
        pytest.skip("scikit-sundae is not installed (the bench extra)")
    if peer in peers.CYRK_PEERS and peers.cyrk() is None:
        pytest.skip("CyRK is not installed (the bench extra)")
    # T = 10, rtol 1e-8, atol 1e-11: a tolerance-controlled solver's global error on this smooth,
    # non-chaotic problem is a modest multiple of rtol (observed 4e-10 .. 4e-8): bounded by
    # 1e3 rtol = 1e-5; and it responds to the tolerance: rtol 1e-4 is at least 10x worse (the
    # control that the error is the solver's, not the reference's)
    q_ref = np.asarray(skate.exact_solution(10.0)[0], float)
    err = {}
    for tol in (1e-8, 1e-4):
        r = peers.run_peer(skate, peer, tol, 10.0, repeats=1)
        err[tol] = float(np.max(np.abs(np.asarray(r["q_final"]) - q_ref)))
        assert r["cpu"] > 0 and r["kind"] == "peer" and r["method"] == peer
    assert 0 < err[1e-8] <= 1e-5
    assert err[1e-4] >= 10 * err[1e-8]


def test_ida_residual_vanishes_at_the_consistent_point_only(skate):
    from ldaspark.compiled.ode import compiled_ode_module
    mod = compiled_ode_module(skate.system)
    n, m = skate.system.n, skate.system.m
    t0, q0, v0 = skate.initial()
    y = np.array([float(x) for x in list(q0) + list(v0)]) + 0.1      # a generic point (k != 0 is fine:
    psi = mod.psi_of(0.3, y)                                          # the index-1 form uses k' only)
    z = np.concatenate([y, psi])
    zp = np.concatenate([mod.rhs(0.3, y), np.zeros(m)])
    res = np.zeros(2 * n + m)
    mod.dae_residual(0.3, z, zp, res)
    # (3a-b) solved by LU in float64 for a well-conditioned 4x4 saddle matrix: round-off 1e-14
    assert np.max(np.abs(res)) <= 1e-13
    z[2 * n:] += 0.5                                                  # control: another multiplier
    mod.dae_residual(0.3, z, zp, res)
    assert np.max(np.abs(res)) >= 1e-2
    yp = np.zeros(2 * n)
    mod.rhs_into(0.3, y, yp)
    assert np.array_equal(yp, mod.rhs(0.3, y))


def test_peers_are_optional(monkeypatch, skate):
    monkeypatch.setattr(peers, "cyrk", lambda: object())          # CyRK's own absence: test_peers_compiled_loop
    monkeypatch.setattr(peers, "sundials", lambda: None)
    ok, notes = peers.available_peers()
    assert set(ok) == set(peers.PEERS) - set(peers.SUNDIALS_PEERS)
    assert len(notes) == 1 and "scikit-sundae" in notes[0] and "cvode-adams" in notes[0]
    plan = work_precision.study_plan("skate", 10.0, (0.1,), (0.1,), (1e-6,), (1e-6,))
    assert [m for k, m, _ in plan if k == "peer"] == ["cyrk-nbsolve2-DOP853", "cyrk-nbsolve2-Vern8", "ode-dop853",
                                                      "ode-lsoda"]
    # the high orders run at the four largest steps only; the others at every step
    plan = work_precision.study_plan("skate", 10.0, (0.4, 0.2, 0.1, 0.05, 0.025), (0.1,), (1e-6,), (1e-6,))
    fast = {m: hs for k, m, hs in plan if k == "spark-fast"}
    assert fast["gauss-8"] == fast["gauss-6"] == (0.4, 0.2, 0.1, 0.05) and fast["gauss-4"] == (0.4, 0.2, 0.1, 0.05, 0.025)
    assert {"gauss-4", "gauss-6", "gauss-8"} <= set(fast)
    with pytest.raises(peers.PeerFailure, match="scikit-sundae"):
        peers.peer_solver(skate.system, "cvode-adams", 1e-6, 0.0, np.zeros(6), [1.0])
    # control: with the module present nothing is dropped
    monkeypatch.setattr(peers, "sundials", lambda: object())
    assert peers.available_peers() == (list(peers.PEERS), [])


def test_peer_section_renders_a_study():
    d = {"command": "python benchmarks/peers.py", "date": "2026-12-02", "cpu_count": 2,
         "load_average_1min_at_end": 7.5, "versions": {"scipy": "1"}, "peers": {"ode-dop853": "Fortran"},
         "atol": "0.001 * rtol", "targets": [1e-3], "energy_targets": [1e-4],
         "studies": [{"scene": "skate", "n": 3, "t_end": 100.0, "t_long": 1e4, "reference": "closed form",
                      "reference_check": None, "notes": [], "failed": [],
                      "rows": [{"method": "gauss-2", "param": 0.1, "cpu": 0.01, "error": 1e-5,
                                "energy_error": 1e-7, "constraint": 1e-16, "nfev": None}],
                      "long_rows": [],
                      "speedups": [{"target": 1e-3, "spark": "gauss-2", "spark_cpu": 0.004, "peer": "ode-dop853",
                                    "peer_cpu": 0.0018, "speedup": 0.45}],
                      "long_speedups": [{"target": 1e-4, "spark": None, "spark_cpu": None, "peer": None,
                                         "peer_cpu": None, "speedup": None}]}]}
    text = "\n".join(peers.section(d))
    assert "0.45x" in text and "a loaded machine" in text and "ode-dop853 1.8 ms" in text
    from ldaspark.lab.reports.summary import peers_values
    v = peers_values(d)
    assert v["peers.skate.speedups"] == "0.45x" and v["peers.skate.long"] == "-"


def test_speedup_is_bounded_from_below_where_spark_beats_the_target_at_every_step():
    # every SPARK run has error <= 1e-4: at the target 1e-3 nothing to interpolate, but its
    # cheapest run (1 ms) reaches it, so the speed-up is at least cpu(peer at 1e-3) / 1 ms;
    # no bound where SPARK does not reach the target at all (1e-12) or where it interpolates
    e = [10.0 ** -k for k in range(1, 11)]
    rows = _power_law("peer", "p", 1e-3, 4.0, e) + _power_law("spark", "gauss-2", 1e-3, 1e9, [1e-4, 1e-6, 1e-8])
    rows[-3]["cpu"] = 1e-3
    r3, r6, r12 = peers.speedups(rows, (1e-3, 1e-6, 1e-12))
    assert r3["speedup"] is None and abs(r3["speedup_at_least"] - (1e-3 * 1e-3 ** -0.25) / 1e-3) <= 1e-12
    assert r6["speedup"] is not None and r6["speedup_at_least"] is None
    assert r12["speedup"] is None and r12["speedup_at_least"] is None
    assert peers.speedup_text([r3, r6]).startswith(">= 5.62x / ")


def test_a_method_whose_runs_all_beat_the_target_counts_at_its_cheapest_run():
    # gauss-2 interpolates at 1e-6 (cost ~1e-3 * 1e-6^-1/4 = 31.6 ms), gauss-4's runs are all more
    # accurate (<= 1e-8) and its cheapest costs 5 ms: it reaches 1e-6 for at most 5 ms, so it is the
    # best SPARK method there and the speed-up is a lower bound; mirrored on the peers' side
    e = [10.0 ** -k for k in range(3, 10)]
    g4 = [{"kind": "spark", "method": "gauss-4", "param": h, "cpu": c, "error": err, "energy_error": err}
          for h, c, err in ((0.4, 5e-3, 1e-8), (0.2, 9e-3, 1e-10))]
    rows = _power_law("spark", "gauss-2", 1e-3, 4.0, e) + g4 + _power_law("peer", "p", 1e-2, 4.0, e)
    (r,) = peers.speedups(rows, (1e-6,))
    assert r["spark"] == "gauss-4" and r["spark_cpu"] == 5e-3
    assert r["speedup"] is None and r["speedup_at_most"] is None
    assert abs(r["speedup_at_least"] - 1e-2 * 1e-6 ** -0.25 / 5e-3) <= 1e-9
    flipped = [dict(x, kind={"spark": "peer", "peer": "spark"}[x["kind"]]) for x in rows]
    (f,) = peers.speedups(flipped, (1e-6,))
    assert f["speedup_at_least"] is None and abs(f["speedup_at_most"] - 5e-3 / (1e-2 * 1e-6 ** -0.25)) <= 1e-12
    assert peers.speedup_text([f]).startswith("<= ")
    # control: without gauss-4 the interpolated figure is exact (not a bound)
    (g,) = peers.speedups([x for x in rows if x["method"] != "gauss-4"], (1e-6,))
    assert g["speedup_at_least"] is None and abs(g["speedup"] - 10.0) <= 1e-9


def test_comparators_are_compared_with_spark_and_never_counted_as_peers():
    """The semi-explicit comparator (26) (kind "comparator") is left out of the speed-up over the
    peers, and compared with the best SPARK method on its own (``other="comparator"``): here it is
    the cheapest run of all at 1e-2, yet the speed-up over the peers does not see it."""
    e = [10.0 ** -k for k in range(1, 9)]
    rows = (_power_law("spark", "gauss-2", 1e-3, 4.0, e) + _power_law("peer", "ode-dop853", 1e-2, 8.0, e)
            + _power_law("comparator", "mp-lobatto-iiib-a-2", 1e-5, 2.0, e))
    (p,) = peers.speedups(rows, (1e-2,))
    (c,) = peers.speedups(rows, (1e-2,), other="comparator")
    assert p["peer"] == "ode-dop853" and c["peer"] == "mp-lobatto-iiib-a-2"
    assert abs(c["speedup"] - c["peer_cpu"] / c["spark_cpu"]) <= 1e-12 * c["speedup"] and c["speedup"] < 1
    assert abs(p["peer_cpu"] / (1e-2 * 1e-2 ** -0.125) - 1) <= 1e-12
    assert "mp-lobatto-iiib-a-2" in peers.COMPARATORS and "lobatto-iiia-iiib-2" in peers.SPARK_METHODS
