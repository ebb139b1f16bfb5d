"""``ldaspark.lab.checkpoint`` where it lives: moved from ``ldaspark.executors`` into the lab, its
fingerprint still hashes the whole package ``ldaspark`` (the library the lab's verdicts run), not
only the lab's own directory where the module now sits."""
from __future__ import annotations

import pathlib

import ldaspark
from ldaspark.lab import checkpoint as lab_checkpoint

PACKAGE = pathlib.Path(ldaspark.__file__).resolve().parent


def test_the_fingerprint_hashes_the_whole_package_not_only_the_lab(monkeypatch):
    roots = []
    real = lab_checkpoint._hash_tree

    def record(h, root, pattern):
        roots.append((pathlib.Path(root), pattern))
        return real(h, root, pattern)
    monkeypatch.setattr(lab_checkpoint, "_hash_tree", record)
    lab_checkpoint.source_fingerprint("r")
    # the first tree is the package with every file (source and data); ldaspark/lab (one level
    # short: the module's own directory) would leave the solver, the tableaux and executors out
    assert roots == [(PACKAGE, "*")]
    assert (PACKAGE / "executors.py").is_file() and (PACKAGE / "data").is_dir()
    assert pathlib.Path(lab_checkpoint.__file__).resolve().parent != PACKAGE


def test_a_library_file_outside_the_lab_changes_the_fingerprint(tmp_path, monkeypatch):
    # a copy of the layout: pkg/lab/checkpoint.py is the module, pkg/core.py a library file
    pkg = tmp_path / "pkg"
    (pkg / "lab").mkdir(parents=True)
    (pkg / "core.py").write_text("A = 1\n")
    (pkg / "lab" / "claims.py").write_text("B = 1\n")
    monkeypatch.setattr(lab_checkpoint, "__file__", str(pkg / "lab" / "checkpoint.py"))
    f0 = lab_checkpoint.source_fingerprint("r")
    (pkg / "core.py").write_text("A = 2\n")                      # the library, outside lab/
    f1 = lab_checkpoint.source_fingerprint("r")
    assert f1 != f0
    (pkg / "lab" / "claims.py").write_text("B = 2\n")            # and the lab itself
    f2 = lab_checkpoint.source_fingerprint("r")
    assert f2 != f1
    # control: a file beside the package (the module's grandparent's sibling) does not count
    (tmp_path / "elsewhere.py").write_text("C = 1\n")
    assert lab_checkpoint.source_fingerprint("r") == f2


def test_fresh_refuses_a_link_or_fifo_at_the_checkpoint_path(tmp_path):
    """``--fresh`` (``Checkpoint.discard``) unlinked a symlink or a FIFO at the checkpoint's path,
    which the run without it refuses ("not a regular file; not touched"); refused the same way now.
    Control: a regular checkpoint file is removed."""
    import os
    import pytest
    from ldaspark.core.errors import InputError
    target = tmp_path / "precious.txt"
    target.write_text("SECRET")
    link = tmp_path / "claims.partial.jsonl"
    os.symlink(target, link)
    with pytest.raises(InputError, match="not a regular file"):
        lab_checkpoint.Checkpoint(link, "fp").discard()
    assert link.is_symlink() and target.read_text() == "SECRET"
    fifo = tmp_path / "other.partial.jsonl"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        lab_checkpoint.Checkpoint(fifo, "fp").discard()
    assert fifo.exists()
    plain = tmp_path / "plain.partial.jsonl"
    plain.write_text("{}\n")
    lab_checkpoint.Checkpoint(plain, "fp").discard()
    assert not plain.exists()
