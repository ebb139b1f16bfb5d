"""Reported ratios the right way up: synthetic timings whose two sides differ by a known factor,
fed to the report-writing functions, which must print that factor (not its inverse).
(Each ratio in reports/work_precision.md and README's peers row: "scipy / SPARK fast",
"best peer / SPARK fast", the peers' speed-up "cpu(peer) / cpu(SPARK)", the right-hand side's
"python / compiled".)"""
from __future__ import annotations

import pytest

from ldaspark.lab.reports import peers, work_precision

ERRORS = [10.0 ** -k for k in range(1, 12)]


def _law(kind, method, c0, p=4.0):
    """CPU = c0 error^(-1/p): equal orders, so the ratio of two kinds is c0 / c0' at every error."""
    return [{"kind": kind, "method": method, "param": e, "cpu": c0 * e ** (-1.0 / p), "error": e,
             "energy_error": e, "constraint": 0.0, "nfev": 1} for e in ERRORS]


@pytest.mark.parametrize("key", ["error", "energy_error"])
def test_work_precision_table_shows_the_factors_the_right_way_up(key):
    """scipy 6x, the best peer 3x and generic SPARK 40x the cost of fast SPARK: the table's
    columns 'scipy / SPARK fast' = 6, 'scipy / SPARK generic' = 0.15, 'best peer / SPARK fast' = 3."""
    st = {"rows": _law("spark-fast", "gauss-2", 1e-3) + _law("spark-generic", "gauss-2", 4e-2)
          + _law("scipy", "DOP853", 6e-3) + _law("peer", "ode-dop853", 3e-3) + _law("peer", "ode-lsoda", 9e-3)}
    rows = work_precision._ratio_rows(st, key)
    header = work_precision.RATIO_HEADER
    assert rows
    for row in rows:
        cell = dict(zip(header, row[1:]))
        assert cell["scipy / SPARK fast"] == "6", row
        assert cell["scipy / SPARK generic"] == "0.15", row
        assert cell["best peer / SPARK fast"] == "3", row
        assert cell["best peer [s]"].startswith("ode-dop853"), row


def test_peer_speedup_is_peer_cost_over_spark_cost_in_the_text():
    """A peer 3x as costly as SPARK: '3.00x' at every target; SPARK 4x as costly: '0.25x'."""
    slow_peer = _law("spark", "gauss-2", 1e-3) + _law("peer", "dop853", 3e-3)
    fast_peer = _law("spark", "gauss-2", 4e-3) + _law("peer", "dop853", 1e-3)
    targets = (1e-3, 1e-6, 1e-9)
    assert peers.speedup_text(peers.speedups(slow_peer, targets)) == "3.00x / 3.00x / 3.00x"
    assert peers.speedup_text(peers.speedups(fast_peer, targets)) == "0.25x / 0.25x / 0.25x"


def test_rhs_sentence_is_python_over_compiled():
    s = work_precision._rhs_sentence({"compiled": 1e-6, "python": 5e-5})
    assert "(50x)" in s and "1 us compiled" in s


def test_steps_per_second_summary_keeps_the_ratio_fast_over_generic():
    rows = [{"ratio": r} for r in (100.0, 300.0, 200.0)]
    assert work_precision.sps_summary(rows) == {"median": 200.0, "min": 100.0, "max": 300.0, "n": 3}
