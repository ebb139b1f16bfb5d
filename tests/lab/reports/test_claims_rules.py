"""Rules of ``ldaspark.lab.reports.claims`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import pytest


class _Stop(Exception):
    pass


def _ledger_identity(monkeypatch, tmp_path, quick, groups=None):
    from ldaspark.lab.reports import claims
    seen = {}

    def fake_run_ledger(*a, checkpoint=None, **k):
        seen["fp"], seen["path"], seen["kw"] = checkpoint.fingerprint, checkpoint.path, k
        raise _Stop
    monkeypatch.setattr(claims, "run_ledger", fake_run_ledger)
    if groups is not None:
        monkeypatch.setattr(claims._ledger, "CLAIM_GROUPS", groups)
    with pytest.raises(_Stop):
        claims.run_verify(outdir=str(tmp_path), quick=quick)
    return seen


def test_the_ledgers_run_identity_has_every_option_that_changes_its_records(monkeypatch, tmp_path):
    full = _ledger_identity(monkeypatch, tmp_path, False)
    quick = _ledger_identity(monkeypatch, tmp_path, True)
    # quick changes the scenes, the tableaux and the claim groups' pieces: another identity
    assert quick["kw"] != full["kw"]
    assert quick["fp"] != full["fp"]
    # the claim groups run: another list, another identity
    # negative control: the same options give the same identity (a resumed run is possible)
    assert _ledger_identity(monkeypatch, tmp_path, False)["fp"] == full["fp"]
    other = _ledger_identity(monkeypatch, tmp_path, False, groups=("ldaspark.lab.claims.claims_general:records",))
    assert other["fp"] != full["fp"]
