"""Atomic writes: a full disk or Ctrl-C at any point of a write leaves the previous file
intact and no temporary file behind; the CLI turns the disk error into one line and exit 2."""
import errno
import json
import os

import pytest
from hypothesis import given, strategies as st

import ldaspark.core.io as lio
from ldaspark.cli import main
from ldaspark.core.errors import LdasparkError

OLD = b'{"old": "complete file"}\n'


@pytest.fixture
def target(tmp_path):
    p = tmp_path / "out.json"
    p.write_bytes(OLD)
    return p


def _assert_untouched(p):
    assert p.read_bytes() == OLD
    assert sorted(os.listdir(p.parent)) == [p.name], os.listdir(p.parent)   # no .tmp-* left


def _enospc(*a, **k):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


class _HalfThenFail:
    """File object that writes the first half of the data to disk, then raises."""

    def __init__(self, f, exc):
        self.f, self.exc = f, exc

    def __enter__(self):
        return self

    def __exit__(self, *a):
        self.f.close()
        return False

    def write(self, data):
        self.f.write(data[:len(data) // 2])
        self.f.flush()
        raise self.exc

    def __getattr__(self, k):
        return getattr(self.f, k)


def _fdopen_failing(exc):
    real = os.fdopen

    def fdopen(fd, *a, **k):
        return _HalfThenFail(real(fd, *a, **k), exc)
    return fdopen


def test_enospc_at_replace(target, monkeypatch):
    monkeypatch.setattr(lio.os, "replace", _enospc)
    with pytest.raises(LdasparkError, match="No space left on device"):
        lio.atomic_write_text(target, "new content")
    _assert_untouched(target)


def test_enospc_at_fsync(target, monkeypatch):
    monkeypatch.setattr(lio.os, "fsync", _enospc)
    with pytest.raises(LdasparkError, match="cannot write"):
        lio.atomic_write_bytes(target, b"new")
    _assert_untouched(target)


@pytest.mark.parametrize("exc, expect", [
    (OSError(errno.ENOSPC, "No space left on device"), LdasparkError),
    (KeyboardInterrupt(), KeyboardInterrupt),          # Ctrl-C propagates, after cleanup
])
def test_failure_mid_write(target, monkeypatch, exc, expect):
    monkeypatch.setattr(lio.os, "fdopen", _fdopen_failing(exc))
    with pytest.raises(expect):
        lio.atomic_write_json(target, {"new": list(range(1000))})
    _assert_untouched(target)


def test_keyboard_interrupt_at_replace(target, monkeypatch):
    def ctrl_c(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(lio.os, "replace", ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        lio.atomic_write_text(target, "new")
    _assert_untouched(target)


def test_cannot_create_temp_file(target, monkeypatch):
    def eacces(*a, **k):
        raise OSError(errno.EACCES, "Permission denied")
    monkeypatch.setattr(lio.os, "open", eacces)         # the temporary file is created with os.open
    with pytest.raises(LdasparkError, match="Permission denied"):
        lio.atomic_write_text(target, "new")
    _assert_untouched(target)


def test_nan_in_json_leaves_old_file(target):
    # allow_nan=False: a NaN never reaches a JSON file, the old one survives, and the error is an
    # LdasparkError (one CLI line) -- it was a bare ValueError before the fix
    with pytest.raises(LdasparkError, match="not JSON compliant"):
        lio.atomic_write_json(target, {"x": float("nan")})
    _assert_untouched(target)


def test_success_replaces_and_cleans_up(target):
    # negative control: without a fault the new content is there, complete, and nothing else
    lio.atomic_write_json(target, {"new": 1})
    assert json.loads(target.read_text()) == {"new": 1}
    assert os.listdir(target.parent) == [target.name]


def test_detector_catches_a_non_atomic_writer(target, monkeypatch):
    # teeth: a naive writer (open + write in place) fails this same check on a mid-write fault
    def naive(path, data):
        with _HalfThenFail(open(path, "wb"), OSError(errno.ENOSPC, "full")) as f:
            f.write(data)
    with pytest.raises(OSError):
        naive(target, b"0123456789" * 10)
    with pytest.raises(AssertionError):
        _assert_untouched(target)


@given(st.binary(min_size=0, max_size=2000), st.sampled_from(["fdopen", "fsync", "replace"]))
def test_any_fault_point_all_or_nothing(tmp_path_factory, data, where):
    d = tmp_path_factory.mktemp("aw")
    p = d / "f.bin"
    p.write_bytes(OLD)
    mp = pytest.MonkeyPatch()
    try:
        if where == "fdopen":
            mp.setattr(lio.os, "fdopen", _fdopen_failing(OSError(errno.ENOSPC, "full")))
        else:
            mp.setattr(lio.os, where, _enospc)
        with pytest.raises(LdasparkError):
            lio.atomic_write_bytes(p, data)
    finally:
        mp.undo()
    _assert_untouched(p)
    lio.atomic_write_bytes(p, data)       # and without the fault the write completes
    assert p.read_bytes() == data and os.listdir(d) == ["f.bin"]


def test_cli_disk_full_keeps_previous_output(target, monkeypatch, capsys):
    monkeypatch.setattr(lio.os, "replace", _enospc)
    rc = main(["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1", "--engine", "generic", "--out", str(target)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "No space left on device" in err
    _assert_untouched(target)


def test_cli_ctrl_c_mid_write_keeps_previous_output(target, monkeypatch, capsys):
    monkeypatch.setattr(lio.os, "fdopen", _fdopen_failing(KeyboardInterrupt()))
    rc = main(["integrate", "skate", "gauss-1", "--h", "0.5", "--t-end", "1", "--engine", "generic", "--out", str(target)])
    err = capsys.readouterr().err
    assert rc == 130 and err.count("\n") == 1 and "interrupted" in err
    _assert_untouched(target)


def test_report_interrupted_leaves_previous_report(tmp_path, monkeypatch, capsys):
    # `ldaspark report stability` writes the markdown once, at the end, atomically: Ctrl-C during
    # a section leaves the previous report as it was (exit 130, one line)
    import ldaspark.lab.reports.stability as S
    rep = tmp_path / S.REPORT
    rep.write_bytes(OLD)

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(S, "step_size_sweep", ctrl_c)
    rc = main(["report", "stability", "--outdir", str(tmp_path)])
    assert rc == 130 and capsys.readouterr().err.count("\n") == 1
    _assert_untouched(rep)


def test_report_figure_disk_full_leaves_previous_figure(tmp_path, monkeypatch):
    # figures go through atomic_write_bytes too: a full disk keeps the old PNG
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import ldaspark.lab.reports.stability as S
    png = tmp_path / "stability_x.png"
    png.write_bytes(OLD)
    fig = plt.figure()
    monkeypatch.setattr(lio.os, "replace", _enospc)
    with pytest.raises(LdasparkError, match="No space left"):
        S._save(fig, str(png))
    _assert_untouched(png)


def test_new_file_gets_the_mode_open_would_give(tmp_path):
    # Bug fixed: mkstemp creates 0600, so every report/JSON became unreadable for group/others
    old = os.umask(0o022)
    try:
        p = tmp_path / "new.json"
        lio.atomic_write_json(p, {"a": 1})
        assert (p.stat().st_mode & 0o777) == 0o644
        q = tmp_path / "keep.txt"
        q.write_text("x")
        os.chmod(q, 0o640)
        lio.atomic_write_text(q, "y")            # an existing file keeps its mode
        assert (q.stat().st_mode & 0o777) == 0o640
    finally:
        os.umask(old)


def test_check_destination_tries_the_writers_first_step(tmp_path, capsys):
    """check_destination looked at the target's type only: ``/proc/version`` (a regular file in a
    directory that holds no new file) passed, so ``ldaspark audit --out /proc/version`` ran the
    whole audit and then failed to write. It now creates (and removes) a temporary file beside
    the target, as the writer will; a directory still to be made needs a writable ancestor."""
    if os.path.isfile("/proc/version"):
        with pytest.raises(LdasparkError, match="cannot write /proc/version"):
            lio.check_destination("/proc/version")
        rc = main(["audit", "--method", "gauss-1", "--quick", "--out", "/proc/version"])
        out, err = capsys.readouterr()
        assert rc == 2 and "[audit]" not in err and len(err.strip().splitlines()) == 1, err   # before any work
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(LdasparkError, match="(?i)not a directory"):
        lio.check_destination(str(blocker / "new" / "out.json"))
    # controls: a new file, a new directory, an existing file; nothing is left behind
    for ok in (tmp_path / "out.json", tmp_path / "a" / "b" / "out.json", blocker):
        lio.check_destination(str(ok))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"] and blocker.read_text() == "x"
