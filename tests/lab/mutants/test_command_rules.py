"""Rules of ``ldaspark.lab.mutants.command`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import argparse
import pytest


class _Stop(Exception):
    pass


def _mutants_identity(monkeypatch, tmp_path, **over):
    from ldaspark.lab.mutants import command as mutation
    seen = {}

    def fake_run_catalogue(mutants, jobs=2, hints_only=False, checkpoint=None, **k):
        seen["fp"], seen["hints_only"], seen["exclude"] = checkpoint.fingerprint, hints_only, k.get("exclude")
        raise _Stop
    monkeypatch.setattr(mutation, "run_catalogue", fake_run_catalogue)
    monkeypatch.setattr(mutation, "run_control", lambda *a, **k: {})
    # the identity only: the catalogue's own snippet check is another test's business
    monkeypatch.setattr(mutation, "snippet_problems", lambda *a, **k: [])
    args = dict(quick=False, outdir=str(tmp_path), jobs=1, only=None, exclude="", scheduler=None, fresh=False,
                generated=None)
    args.update(over)
    with pytest.raises(_Stop):
        mutation.run(argparse.Namespace(**args))
    return seen


def test_the_mutation_runs_identity_has_every_option_that_changes_its_records(monkeypatch, tmp_path):
    base = _mutants_identity(monkeypatch, tmp_path)
    quick = _mutants_identity(monkeypatch, tmp_path, quick=True)
    assert quick["hints_only"] and not base["hints_only"]          # quick changes what runs...
    assert quick["fp"] != base["fp"]                               # ...so it changes the identity
    excl = _mutants_identity(monkeypatch, tmp_path, exclude="tests/core/test_spark.py")
    assert excl["exclude"] == ("tests/core/test_spark.py",)
    assert excl["fp"] != base["fp"]
    # options that do not change a record keep it (a resumed run with more jobs is possible)
    assert _mutants_identity(monkeypatch, tmp_path, jobs=2)["fp"] == base["fp"]


def test_a_malformed_scheduler_is_judged_before_the_catalogue(monkeypatch, tmp_path):
    """In a mutated copy the catalogue is "out of date" (the mutant's snippet is gone): when the
    command judged the catalogue first, ``ldaspark mutants --scheduler tcp://`` said that instead of
    naming the address, so its CLI test failed in every copy and "killed" every mutant that reached
    it. The user's own argument comes first (control: a good address reaches the catalogue check)."""
    from ldaspark.core.errors import InputError
    from ldaspark.lab.mutants import command as mutation
    monkeypatch.setattr(mutation, "snippet_problems", lambda *a, **k: ["a snippet no longer in the source"])
    args = dict(quick=False, outdir=str(tmp_path), jobs=1, only=None, exclude="", fresh=False, generated=None)
    with pytest.raises(InputError, match="malformed Dask scheduler address"):
        mutation.run(argparse.Namespace(scheduler="tcp://", **args))
    with pytest.raises(mutation.CatalogueError, match="out of date"):
        mutation.run(argparse.Namespace(scheduler="tcp://localhost:8786", **args))
