"""The mutation catalogue in the default run: every snippet still matches the source exactly once
(so a refactoring that moves code breaks this test, not the catalogue silently), and a small
subset of mutants is applied to a scratch copy and killed by one targeted test each, while the
unmutated copy passes the same tests (so "killed" means the fault was seen, not that the copy
is broken). The whole catalogue: ``ldaspark mutants`` (reports/mutation.md). Cost: ~30 s."""
import concurrent.futures

import pytest

from ldaspark.lab.mutants.mutation import CATALOGUE, apply_mutant, by_id, run_mutant, snippet_problems
from ldaspark.lab.mutants.mutation_catalogue import QUICK

CASES = {
    "cond-22b-index-order": "verification/test_conditions_22_23.py::test_22a_22b_23_families[gauss-2]",
    "orders-pairwise-log2": "tests/lab/theory/test_orders_estimates.py::test_pairwise_orders_with_step_ratio_3",
    "system-K-at-v0": "verification/test_equations_21.py::test_ivp_step_solves_21_as_printed[general-2]",
    "fdplus-index-order": "verification/test_theorem1.py::test_theorem1_builtin[particle-gauss-2]",
}


def test_every_snippet_occurs_exactly_once_in_the_current_source():
    problems = snippet_problems()
    assert not problems, "mutation catalogue out of date (update ldaspark/lab/mutants/mutation_catalogue.py):\n" \
        + "\n".join(problems)
    assert len(CATALOGUE) >= 30
    assert set(QUICK) <= {m.id for m in CATALOGUE}
    assert len({m.category for m in CATALOGUE}) >= 10


def test_apply_refuses_an_ambiguous_or_missing_snippet(tmp_path):
    from ldaspark.lab.mutants.mutation import CatalogueError, Mutant
    (tmp_path / "ldaspark").mkdir()
    (tmp_path / "ldaspark" / "f.py").write_text("a = 1\na = 1\n")
    with pytest.raises(CatalogueError, match="occurs 2 in"):
        apply_mutant(tmp_path, Mutant("x", "f.py", "a = 1", "a = 2", "", "test"))
    with pytest.raises(CatalogueError, match="occurs 0 in"):
        apply_mutant(tmp_path, Mutant("y", "f.py", "b = 1", "b = 2", "", "test"))
    assert snippet_problems(tmp_path / "ldaspark", [Mutant("z", "f.py", "a = 1", "a = 2", "", "t")])


def test_alternative_files_for_code_that_moves(tmp_path):
    from ldaspark.lab.mutants.mutation import Mutant, resolve_file
    pkg = tmp_path / "ldaspark"
    pkg.mkdir()
    (pkg / "new.py").write_text("x = h * acc\n")
    m = Mutant("k", "old.py|new.py", "x = h * acc", "x = acc", "", "compiled")
    assert resolve_file(pkg, m)[0] == pkg / "new.py"
    (pkg / "old.py").write_text("s = 'x = h * acc'\n")      # in both places: ambiguous
    assert resolve_file(pkg, m)[0] is None


@pytest.fixture(scope="module")
def runs():
    """The control and the quick mutants, two scratch copies at a time (one per core)."""
    # the unmutated copy also passes the README test, which reads the committed reports: a copy
    # without them would "kill" every mutant that reaches it
    jobs = {"none": (None, list(CASES.values()) + ["tests/project/test_readme.py"])}
    jobs.update({k: (by_id(k), [v]) for k, v in CASES.items()})
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as ex:
        futs = {k: ex.submit(run_mutant, m, targets=t, timeout=600) for k, (m, t) in jobs.items()}
        return {k: f.result() for k, f in futs.items()}


# the scratch-copy runs (~60 s) are what ``.ci/run``'s ``ldaspark mutants --quick`` does, with its
# control (``run_control``) first; here they are an exhaustive sweep so the default run is not
# the same minute twice
@pytest.mark.exhaustive
def test_unmutated_copy_passes_the_targeted_tests(runs):
    rec = runs["none"]
    assert rec["status"] == "survived", rec        # nothing to kill: every targeted test passes


@pytest.mark.exhaustive
@pytest.mark.parametrize("mutant_id", list(CASES))
def test_quick_mutant_is_killed_by_its_targeted_test(mutant_id, runs):
    rec = runs[mutant_id]
    assert rec["status"] == "killed", rec
    assert rec["first_failing_test"].startswith(CASES[mutant_id].split("[")[0]), rec


def test_mutants_exits_nonzero_when_a_mutant_survives(monkeypatch, tmp_path):
    """``ldaspark mutants`` is CI's gate (``.ci/run``): exit 1 on a survivor, 0 when all are killed
    (the runs replaced by fixed records)."""
    import argparse

    from ldaspark.lab.mutants import command, mutation
    from ldaspark.lab.mutants.mutation_catalogue import Mutant

    def fake(status):
        return lambda ms, jobs, hints_only=False, progress=None, exclude=(), **kw: [
            mutation._record(m, status if i == 0 else "killed", None if status != "killed" else "t::x", 0.0)
            for i, m in enumerate(ms)]
    args = argparse.Namespace(quick=True, outdir=str(tmp_path), jobs=1, only=None, exclude="")
    for status, rc in (("survived", 1), ("timeout", 1), ("invalid", 1), ("killed", 0)):
        monkeypatch.setattr(command, "run_catalogue", fake(status))
        monkeypatch.setattr(command, "run_control", lambda *a, **k: {})
        assert command.run(args) == rc, status
    assert "teeth-audit-coarsest-pair" in QUICK and len(QUICK) >= 10
    assert isinstance(by_id(QUICK[-1]), Mutant)


def test_ci_runs_the_quick_catalogue_after_the_tests():
    import pathlib
    text = (pathlib.Path(__file__).resolve().parents[3] / ".ci" / "run").read_text()
    lines = [x.strip() for x in text.splitlines() if x.strip() and not x.strip().startswith("#")]
    i_test = next(i for i, x in enumerate(lines) if x.startswith("python -m pytest"))
    i_mut = next(i for i, x in enumerate(lines) if "ldaspark mutants --quick" in x)
    assert i_mut > i_test and "set -euo pipefail" in text          # a survivor (exit 1) fails CI


def test_quick_run_stops_when_the_unmutated_package_fails_its_tests(monkeypatch, tmp_path):
    """The control of ``mutants --quick``: a failing unmutated run is one error before any mutant
    (every mutant would otherwise count as killed); a passing one lets the run go on."""
    from ldaspark.lab.mutants import command
    from ldaspark.lab.mutants.mutation import CatalogueError
    seen = {}

    def fake_run_mutant(m, targets=None, **kw):
        seen["m"], seen["targets"] = m, targets
        return {"status": status, "first_failing_test": "tests/test_x.py::t", "seconds": 0.0}
    monkeypatch.setattr(command, "run_mutant", fake_run_mutant)
    mutants = [by_id(x) for x in QUICK]
    status = "killed"
    with pytest.raises(CatalogueError, match="unmutated package fails"):
        command.run_control(mutants, {"gen-1": ["tests/lab/theory/test_audit_rules.py::t"]})
    assert seen["m"] is None
    assert "tests/lab/theory/test_audit_rules.py::t" in seen["targets"]
    assert set(by_id(QUICK[0]).hint) & set(seen["targets"])
    status = "survived"
    assert command.run_control(mutants, {})["status"] == "survived"
