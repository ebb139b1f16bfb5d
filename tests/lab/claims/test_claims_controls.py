"""The contract of the claims ledger: every claim has a negative control, a record expected to
fail (and decided), run through the same check on an input for which the claim does not hold.
``claims_index.LEDGER_CLAIMS`` lists the ledger's claims with their controls;
``ledger_control_problems`` holds records against it. A slice of the quick ledger (the particle,
s <= 2, with section 5.1; the general group on the rheonomic skate; the quick paper group)
produces every indexed claim, each with a control that fails as expected. Cost ~20 s."""
from ldaspark.lab.claims import claims_index as ci
from ldaspark.lab.claims import ledger as lg


def _rec(claim, status, expected):
    return lg.record(claim, "m", "s", status, 0.0, expected)


def test_the_control_check_flags_a_claim_without_a_control():
    """The test's own negative control: a fake ledger whose claim has only expected-pass records,
    or only a not-applicable control, or an unindexed claim, is flagged; a good one is not."""
    good = [_rec("x", "pass", "pass"), _rec("x", "fail", "fail")]
    assert ci.ledger_control_problems(good, {"x": "c"}) == []
    assert ci.ledger_control_problems([_rec("x", "pass", "pass")] * 3, {"x": "c"}) == [
        "x: no negative control (no decided record expected to fail)"]
    assert ci.ledger_control_problems([_rec("x", "pass", "pass"), _rec("x", "not-applicable", "fail")], {"x": "c"})
    assert ci.ledger_control_problems(good + [_rec("y", "fail", "fail")], {"x": "c"}) == [
        "y: not in the index of ledger claims"]
    # a control that came out pass (the check did not fail) still is a control: the ledger's
    # verdict (``summarize``) reports it as an unexpected outcome
    assert ci.ledger_control_problems([_rec("x", "pass", "fail")], {"x": "c"}) == []
    assert lg.summarize([_rec("x", "pass", "fail")]) == 1 and lg.summarize(good) == 0
    # the claims listed before round 5 without a control are flagged on their old records
    old = [_rec(c, "pass", "pass") for c in ("order-general-scenes", "constraint", "17-integral")]
    assert len(ci.ledger_control_problems(old)) == 3


def test_every_indexed_claim_has_a_control_in_the_ledger():
    from ldaspark.lab.claims import claims_general as cg
    from ldaspark.lab.claims import claims_paper as cp
    recs = lg.run_ledger(max_s=2, scenes=("particle",), perturbed=False, holonomic=True, controls=True,
                         groups=(), jobs=1)
    for piece in (("checks", "rheonomic-skate"), ("orders", "rheonomic-skate"), ("nonideal",)):
        recs += cg.piece_records(piece, quick=True)         # the general group on its cheapest scene
    recs += cp.records(quick=True)
    assert ci.ledger_control_problems(recs) == []
    assert {r["claim"] for r in recs} == set(ci.LEDGER_CLAIMS)        # the slice has every indexed claim
    # and each control fails as expected (no finding among the controls)
    ctl = [r for r in recs if r["expected"] == "fail" and r["status"] != "not-applicable"]
    assert {r["claim"] for r in ctl if r["status"] == "fail"} == set(ci.LEDGER_CLAIMS)
    assert [r for r in ctl if r["status"] != "fail"] == []


def test_claims_md_names_a_claim_without_a_control(tmp_path):
    from ldaspark.lab.reports.claims import write_markdown
    write_markdown([_rec("15a", "pass", "pass"), _rec("15a", "fail", "fail")], tmp_path / "a.md", 1.0, "test")
    assert "Negative controls: every claim has" in (tmp_path / "a.md").read_text()
    write_markdown([_rec("15a", "pass", "pass")], tmp_path / "b.md", 1.0, "test")
    assert "**Negative controls missing:** 15a: no negative control" in (tmp_path / "b.md").read_text()
