"""The checkout holds only what the project puts there: every tracked path is plain ASCII
(letters, digits, ``._/+-``) and every top-level entry is one of the project's own. A file
written into the working directory by a test (a drawn path that happened to be a valid file
name) and committed with the rest fails here; so does a stray output at the top level.

Negative control: the same judge on a list with such a name and such an entry."""
from __future__ import annotations

import pathlib
import re
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
#: the top level of the checkout (README's layout: the library, the paper lab inside it, tests,
#: verification, reports, docs, examples, benchmarks, CI)
TOP_LEVEL = {".ci", ".gitignore", "LICENSE", "README.md", "benchmarks", "conftest.py", "docs", "examples",
             "ldaspark", "pyproject.toml", "reports", "tests", "verification"}
PLAIN = re.compile(r"[A-Za-z0-9._+-]+(/[A-Za-z0-9._+-]+)*")


def stray_paths(paths) -> list:
    """The paths of ``paths`` (repository-relative, '/'-separated) that are not plain ASCII names
    or whose top-level entry is not one of TOP_LEVEL."""
    return [p for p in paths if not PLAIN.fullmatch(p) or p.split("/", 1)[0] not in TOP_LEVEL]


def _tracked() -> list:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the tracked files are unknown")
    out = subprocess.run(["git", "-C", str(ROOT), "-c", "core.quotepath=off", "ls-files", "-z"],
                         capture_output=True, timeout=60, check=True).stdout
    return [p for p in out.decode("utf-8", "surrogateescape").split("\0") if p]


def test_every_tracked_path_is_a_project_file():
    paths = _tracked()
    assert len(paths) > 100 and "README.md" in paths
    assert stray_paths(paths) == []


def test_negative_control_a_stray_name_and_a_stray_entry_are_reported():
    paths = ["README.md", "ldaspark/solve.py", "\u00c6Zu\u00a1\U000fb420\u00f1", "o.json", "tests/a b.py",
             "reports/figures/wp_skate.png"]
    assert stray_paths(paths) == ["\u00c6Zu\u00a1\U000fb420\u00f1", "o.json", "tests/a b.py"]
