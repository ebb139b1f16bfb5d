"""The claims ledger's worker pool: ledger units and claim-group pieces (``ledger.group_pieces``)
run in one pool, longest first, and the records come back in the serial order for any number of
workers. A fake claim group (this module) keeps it cheap: ~1 s (exact conditions only)."""
from ldaspark.lab.claims import ledger
from ldaspark.lab.claims.ledger import extra_records, group_pieces, record, run_ledger

SPEC = f"{__name__}:records"
PIECES = ["first", "second", "third"]
# the last piece is the most expensive: it starts first and finishes out of order
COSTS = {"first": 1.0, "second": 2.0, "third": 50.0}


def pieces(quick=False):
    return list(PIECES) + ([] if quick else ["full-only"])


def piece_cost(piece):
    return COSTS.get(piece, 0.1)


def piece_records(piece, quick=False):
    return [record("fake-group", piece, "-", "pass", 0.0, "pass", note=f"quick={quick}"),
            record("fake-group", piece, "-", "fail", 1.0, "fail", point="control")]


def records(quick=False, progress=None):
    return [r for p in pieces(quick) for r in piece_records(p, quick)]


def _strip(rs):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in rs]


def test_pool_gives_the_serial_order_with_claim_groups():
    kw = dict(max_s=1, scenes=(), holonomic=False, controls=False, groups=(SPEC,))
    serial = run_ledger(jobs=1, **kw)
    pooled = run_ledger(jobs=2, **kw)
    assert _strip(pooled) == _strip(serial)
    assert _strip(pooled) != _strip(serial[::-1])            # control: the comparison sees the order
    n_ledger = sum(r["claim"] != "fake-group" for r in serial)
    assert n_ledger > 0 and all(r["claim"] != "fake-group" for r in serial[:n_ledger])
    # the groups come after the ledger, piece by piece, as the serial group function gives them
    assert _strip(serial[n_ledger:]) == _strip(extra_records(groups=(SPEC,)))
    assert [r["method"] for r in serial[n_ledger::2]] == pieces()
    quick = run_ledger(jobs=2, quick=True, **kw)
    assert [r["method"] for r in quick[n_ledger::2]] == PIECES and quick[-2]["note"] == "quick=True"


def test_group_pieces_and_costs():
    assert group_pieces(SPEC) == pieces()
    assert ledger.unit_cost(("group", SPEC, "third")) == 50.0
    for spec in ledger.CLAIM_GROUPS:                          # the real groups are split
        ps = group_pieces(spec)
        assert len(ps) > 1 and len(set(map(repr, ps))) == len(ps)
        assert all(ledger.unit_cost(("group", spec, p)) > 0 for p in ps)
