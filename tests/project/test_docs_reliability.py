"""docs/reliability.md names, for each class of bad input, the test that keeps the behaviour:
every test it names exists (``file.py::name``; ``::name`` refers to the last file named)."""
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _named_tests(text):
    last, out = None, []
    for m in re.finditer(r"`((?:test_\w+\.py)?)::(test_\w+)`|`(test_\w+\.py)`", text):
        if m.group(3):
            last = m.group(3)
            continue
        last = m.group(1) or last
        out.append((last, m.group(2)))
    return out


def _find(basename):
    """The test file of that name under tests/ (in its folder) or verification/: names are unique."""
    import glob
    hits = glob.glob(os.path.join(ROOT, "tests", "**", basename), recursive=True) + \
        glob.glob(os.path.join(ROOT, "verification", basename))
    assert len(hits) == 1, (basename, hits)
    return hits[0]


def test_every_named_test_exists():
    text = open(os.path.join(ROOT, "docs", "reliability.md"), encoding="utf-8").read()
    named = _named_tests(text)
    assert len(named) > 40
    missing = []
    for f, name in named:
        src = open(_find(f), encoding="utf-8").read()
        if not re.search(rf"^def {name}\(", src, re.M):
            missing.append(f"{f}::{name}")
    assert not missing, missing


def test_checker_has_teeth():
    assert _named_tests("`test_reliability_io.py::test_x` and `::test_y`") == [
        ("test_reliability_io.py", "test_x"), ("test_reliability_io.py", "test_y")]


def _named_paths(text):
    """The test files named with their folder (`tests/core/x.py`, `verification/x.py::name`): the
    basename pattern of ``_named_tests`` does not match them."""
    return re.findall(r"`((?:tests|verification)/[\w/]+\.py)(?:::(test_\w+))?`", text)


def test_every_test_path_exists():
    """Five paths named files that do not exist (``tests/core/test_signal_during_fork.py``, whose
    test is in test_signal_policy.py, and four ``tests/test_*.py`` that live in tests/core/ and
    tests/compiled/): the basename check above never saw them."""
    text = open(os.path.join(ROOT, "docs", "reliability.md"), encoding="utf-8").read()
    named = _named_paths(text)
    assert len(named) > 5
    missing = []
    for path, name in named:
        full = os.path.join(ROOT, path)
        if not os.path.isfile(full):
            missing.append(path)
        elif name and not re.search(rf"^def {name}\(", open(full, encoding="utf-8").read(), re.M):
            missing.append(f"{path}::{name}")
    assert not missing, missing


def test_path_checker_has_teeth():
    assert _named_paths("`tests/core/test_x.py` and `verification/test_y.py::test_z`, not `test_w.py`") == [
        ("tests/core/test_x.py", ""), ("verification/test_y.py", "test_z")]
