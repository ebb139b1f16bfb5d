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
