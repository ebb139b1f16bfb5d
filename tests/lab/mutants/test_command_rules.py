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
    # jobs=None: --jobs not given (the CLI's default; given with --scheduler it is refused)
    args = dict(quick=False, outdir=str(tmp_path), jobs=None, only=None, exclude="", fresh=False, generated=None)
    with pytest.raises(InputError, match="malformed Dask scheduler address"):
        mutation.run(argparse.Namespace(scheduler="tcp://", **args))
    with pytest.raises(mutation.CatalogueError, match="out of date"):
        mutation.run(argparse.Namespace(scheduler="tcp://localhost:8786", **args))


def _cli_reaches(monkeypatch, capsys, tmp_path, *argv):
    """``ldaspark mutants ARGV`` with the runs replaced by stand-ins: "catalogue" or "generated" when
    the command got as far as starting that run, else (rc, stderr) of its refusal."""
    from ldaspark.cli import main
    from ldaspark.lab.mutants import command as mutation

    def reached(what):
        def stub(*a, **k):
            raise _Stop(what)
        return stub
    monkeypatch.setattr(mutation, "run_catalogue", reached("catalogue"))
    monkeypatch.setattr(mutation, "run_generated", reached("generated"))
    monkeypatch.setattr(mutation, "run_control", lambda *a, **k: {})
    monkeypatch.setattr(mutation, "snippet_problems", lambda *a, **k: [])
    try:
        rc = main(["mutants", "--outdir", str(tmp_path / "o"), *argv])
    except _Stop as exc:
        return exc.args[0]
    return rc, capsys.readouterr().err


@pytest.mark.parametrize("extra, option", [(["--quick"], "--quick"),
                                           (["--exclude", "tests/core/test_spark.py"], "--exclude")])
def test_catalogue_options_are_refused_with_generated_not_ignored(monkeypatch, capsys, tmp_path, extra, option):
    """``--generated M --quick`` ran every generated mutant of M (--quick was read by the catalogue
    run only), ``--exclude`` excluded nothing there: both were accepted and ignored. Control: the same
    command without them starts the generated run."""
    gen = ["--generated", "ldaspark/core/validate.py"]
    assert _cli_reaches(monkeypatch, capsys, tmp_path, *gen) == "generated"
    rc, err = _cli_reaches(monkeypatch, capsys, tmp_path, *gen, *extra)
    assert rc == 2 and err.count("\n") == 1 and f"{option}: not with --generated" in err, err


def test_jobs_with_a_scheduler_is_refused_for_the_catalogue(monkeypatch, capsys, tmp_path):
    """The cluster's workers run the catalogue's units, so ``--jobs`` was ignored with ``--scheduler``
    (``verify`` and ``report`` refuse the pair). Controls: each alone starts the run, and with
    --generated --jobs still sets the local coverage map's processes, so the pair is taken there."""
    addr = ["--scheduler", "tcp://localhost:8786"]        # parsed, never connected to: the run is a stand-in
    assert _cli_reaches(monkeypatch, capsys, tmp_path, *addr) == "catalogue"
    assert _cli_reaches(monkeypatch, capsys, tmp_path, "--jobs", "3") == "catalogue"
    assert _cli_reaches(monkeypatch, capsys, tmp_path, *addr, "--jobs", "3", "--generated",
                        "ldaspark/core/validate.py") == "generated"
    rc, err = _cli_reaches(monkeypatch, capsys, tmp_path, *addr, "--jobs", "3")
    assert rc == 2 and err.count("\n") == 1 and "with --scheduler" in err, err


@pytest.mark.parametrize("name", ["tests/core/test_sparkk.py", "./tests/core/test_spark.py", "test_spark.py"])
def test_an_exclude_that_names_no_test_file_is_refused(monkeypatch, capsys, tmp_path, name):
    """``--exclude`` compares exact paths: a misspelt one excluded nothing, and the run reported which
    mutants the whole suite misses instead of the suite without that file. Control: the real path
    reaches the catalogue run."""
    assert _cli_reaches(monkeypatch, capsys, tmp_path, "--exclude", "tests/core/test_spark.py") == "catalogue"
    rc, err = _cli_reaches(monkeypatch, capsys, tmp_path, "--exclude", name)
    assert rc == 2 and err.count("\n") == 1 and "is not a test file of the suite" in err, err
