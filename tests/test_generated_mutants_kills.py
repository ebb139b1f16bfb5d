"""The generated-mutant runner (ldaspark/reports/mutgen.py): each operator kind is generated where
it should be and nowhere else, a mutant changes exactly the text it names, ids survive edits
elsewhere in the file, the committed equivalents list names existing mutants with an argument
each, and ``ldaspark mutants`` refuses in one line, at once, where the repository's tests are
missing (an installed wheel). Cost: ~3 s."""
import os
import pathlib
import shutil
import subprocess
import sys
import time

import pytest

from ldaspark.reports import mutgen

ROOT = pathlib.Path(__file__).resolve().parents[1]

SRC = '''"""doc 1"""
X = 3
TOL = 1e-9


def f(a, b, xs):
    """doc 2"""
    if a < b and not xs:
        return a + b * 2
    if a is None or b in xs:
        return -a
    y = max(xs[1:3])
    return all(x >= TOL for x in xs) == True


if __name__ == "__main__":
    print(1 + 1)
'''


def _by_kind(ms):
    out = {}
    for m in ms:
        out.setdefault(m.id.split("::")[2], []).append((m.original.strip(), m.replacement.strip()))
    return out


def test_every_operator_kind_is_generated(tmp_path):
    ms = mutgen.generate("x.py", SRC)
    k = _by_kind(ms)
    assert set(k["compare"]) == {("<", "<="), ("is", "is not"), ("in", "not in"), (">=", ">"), ("==", "!=")}
    assert set(k["boolean"]) == {("and", "or"), ("or", "and")}
    assert set(k["arithmetic"]) == {("+", "-"), ("*", "/")}
    assert ("not", "") in k["not-removal"] and ("-", "") in k["negation-removal"]
    assert set(k["constant"]) >= {("3", "(3 + 1)"), ("3", "0"), ("1e-9", "0.0"), ("2", "(2 + 1)"), ("True", "False")}
    assert ("a + b * 2", "None") in k["return"]
    assert set(k["call-swap"]) == {("max", "min"), ("all", "any")}
    assert set(k["slice"]) == {("1", "(1) + 1"), ("3", "(3) + 1")}
    # docstrings and the __main__ block are not mutated
    assert not [m for m in ms if "doc" in m.original or m.line >= 17]
    # every mutant compiles and differs from the source in its splice only
    for m in ms:
        out = m.mutated_source(SRC)
        compile(out, "x.py", "exec")
        assert out != SRC and out[:m.start] == SRC[:m.start] and out[m.start + len(m.replacement):] == SRC[m.end:]
    assert len({m.id for m in ms}) == len(ms)


def test_ids_survive_edits_elsewhere_and_apply_refuses_moved_source(tmp_path):
    a = {m.id for m in mutgen.generate("x.py", SRC)}
    b = {m.id for m in mutgen.generate("x.py", "import os\n\n\n" + SRC)}
    assert a == b
    m = next(m for m in mutgen.generate("x.py", SRC) if m.original == "<")
    pkg = tmp_path / "ldaspark"
    pkg.mkdir()
    (pkg / "x.py").write_text(SRC)
    m.apply(tmp_path)
    assert "a <= b" in (pkg / "x.py").read_text()
    (pkg / "x.py").write_text("# moved\n" + SRC)
    with pytest.raises(mutgen.MutgenError, match="source moved"):
        m.apply(tmp_path)


def test_module_names_and_errors():
    assert mutgen.module_file("ldaspark/core/validate.py") == "core/validate.py"
    assert mutgen.module_file("ldaspark.core.validate") == "core/validate.py"
    assert mutgen.module_file("core/validate.py") == "core/validate.py"
    with pytest.raises(mutgen.MutgenError):
        mutgen.module_file("ldaspark/core/nothing.py")
    with pytest.raises(mutgen.MutgenError, match="does not parse"):
        mutgen.generate("x.py", "def (:\n")


def test_the_equivalents_list_names_existing_mutants_with_an_argument():
    eq = mutgen.load_equivalent()
    files = {k.split("::")[0] for k in eq}
    ids = {m.id for f in files for m in mutgen.generate(f)}
    stale = sorted(set(eq) - ids)
    assert not stale, f"equivalent mutants no longer generated (update verification/mutants_equivalent.json): {stale}"
    assert all(len(v.strip()) > 10 and "\n" not in v for v in eq.values())


def test_the_equivalents_list_is_checked(tmp_path):
    p = tmp_path / "eq.json"
    p.write_text('{"a": ""}')
    with pytest.raises(mutgen.MutgenError, match="one-line argument"):
        mutgen.load_equivalent(p)
    p.write_text('["a"]')
    with pytest.raises(mutgen.MutgenError):
        mutgen.load_equivalent(p)
    assert mutgen.load_equivalent(tmp_path / "missing.json") == {}


@pytest.mark.parametrize("extra", [[], ["--generated", "ldaspark/core/validate.py"]])
def test_mutants_without_the_repositorys_tests_refuse_at_once(tmp_path, extra):
    """The package alone (as a wheel installs it): one line, exit 2, before any work."""
    shutil.copytree(ROOT / "ldaspark", tmp_path / "ldaspark",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    t = time.time()
    p = subprocess.run([sys.executable, "-m", "ldaspark", "mutants", "--quick", "--outdir", str(tmp_path / "out"),
                        *extra], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "needs the repository's tests" in lines[0], p.stderr
    assert not (tmp_path / "out").exists()              # nothing done
    assert time.time() - t < 60
    # negative control: with the tests beside it the check passes
    from ldaspark.reports.mutation import CatalogueError, require_tests
    require_tests(ROOT)
    with pytest.raises(CatalogueError):
        require_tests(tmp_path)


def test_the_quick_generated_mutants_still_exist_and_name_a_test():
    ms, targets = mutgen.quick_generated()
    assert len(ms) == len(mutgen.QUICK_GENERATED) >= 3
    for m in ms:
        (test,) = targets[m.id]
        assert (ROOT / test.split("::")[0]).is_file()
        assert m.original != m.replacement
