"""Output paths that are not plain files: symlinks are written through to their target, devices
and FIFOs are written directly (never replaced by a file), directories and other special files
are refused with one line; SIGTERM in the middle of a write leaves no temporary file behind."""
import os
import signal
import stat
import subprocess
import sys
import threading
import time

import pytest

import ldaspark.core.io as lio
from ldaspark.cli import main
from ldaspark.core.errors import LdasparkError

NEW = b'{"new": 1}\n'


def _no_tmp(d):
    return [f for f in os.listdir(d) if f.startswith(".tmp-")] == []


def test_dev_null_stays_a_device():
    lio.atomic_write_bytes("/dev/null", NEW)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_dev_full_is_one_error_and_stays_a_device():
    with pytest.raises(LdasparkError, match="No space left on device"):
        lio.atomic_write_bytes("/dev/full", NEW)
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_fifo_is_written_to_its_reader_not_replaced(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(open(fifo, "rb").read()))
    reader.start()
    lio.atomic_write_bytes(fifo, NEW)
    reader.join(timeout=30)
    assert got == [NEW]
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and _no_tmp(tmp_path)


def test_symlink_is_written_through_to_its_target(tmp_path):
    target = tmp_path / "real.json"
    target.write_bytes(b"old")
    os.chmod(target, 0o640)
    link = tmp_path / "link.json"
    os.symlink("real.json", link)
    lio.atomic_write_bytes(link, NEW)
    assert os.path.islink(link) and target.read_bytes() == NEW      # the link stays a link
    assert stat.S_IMODE(os.stat(target).st_mode) == 0o640 and _no_tmp(tmp_path)


def test_dangling_symlink_creates_its_target(tmp_path):
    link = tmp_path / "link.json"
    os.symlink("sub.json", link)
    lio.atomic_write_bytes(link, NEW)
    assert os.path.islink(link) and (tmp_path / "sub.json").read_bytes() == NEW


def test_symlink_to_a_device_writes_the_device(tmp_path):
    link = tmp_path / "null.json"
    os.symlink("/dev/null", link)
    lio.atomic_write_bytes(link, NEW)
    assert os.readlink(link) == "/dev/null" and stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_symlink_loop_is_one_error(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    os.symlink("b", a)
    os.symlink("a", b)
    with pytest.raises(LdasparkError, match="cannot write"):
        lio.atomic_write_bytes(a, NEW)


def test_directory_is_refused_not_replaced(tmp_path, capsys):
    d = tmp_path / "outdir"
    d.mkdir()
    (d / "keep").write_text("x")
    with pytest.raises(LdasparkError, match="is a directory"):
        lio.atomic_write_bytes(d, NEW)
    assert (d / "keep").read_text() == "x" and _no_tmp(tmp_path)
    # at the command line: one line, exit 2
    rc = main(["methods", "--max-s", "1", "--json", str(d)])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "is a directory" in err


def test_regular_file_still_replaced_atomically(tmp_path):
    # control: the ordinary path is unchanged (new inode, old content gone, no temp file)
    p = tmp_path / "o.json"
    p.write_bytes(b"old")
    ino = os.stat(p).st_ino
    lio.atomic_write_bytes(p, NEW)
    assert p.read_bytes() == NEW and os.stat(p).st_ino != ino and _no_tmp(tmp_path)


def test_dev_stdout_redirected_to_a_file_is_appended_not_replaced(tmp_path):
    out = tmp_path / "log.txt"
    code = ("from ldaspark.core.io import atomic_write_text as w\nprint('before', flush=True)\n"
            "w('/dev/stdout', 'json\\n')\nprint('after')\n")
    with open(out, "w") as f:
        subprocess.run([sys.executable, "-c", code], stdout=f, check=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert out.read_text() == "before\njson\nafter\n"


_SLOW_WRITER = """
import os, sys, time
import ldaspark.core.io as lio
def slow(f, data):
    f.write(data[:3]); f.flush()
    open(sys.argv[2], "w").close()          # tell the parent: the temporary file exists
    for _ in range(6000):                   # short sleeps: a signal landing just before a long one waits it out
        time.sleep(0.01)
    f.write(data[3:])
lio._write_all = slow
lio.atomic_write_bytes(sys.argv[1], b'{"new": "content"}')
"""


_NO_HANDLER = """
import contextlib
lio._sigterm_raises = contextlib.nullcontext
"""


@pytest.mark.parametrize("handler", [True, False])
def test_sigterm_mid_write_removes_the_temporary_file(tmp_path, handler):
    target = tmp_path / "out.json"
    target.write_bytes(b"old")
    ready = tmp_path.parent / (tmp_path.name + ".ready")
    code = _SLOW_WRITER if handler else _SLOW_WRITER.replace("lio._write_all = slow", "lio._write_all = slow" + _NO_HANDLER)
    p = subprocess.Popen([sys.executable, "-c", code, str(target), str(ready)],
                         env=dict(os.environ, PYTHONPATH=os.getcwd()))
    try:
        deadline = time.monotonic() + 120
        while not ready.exists():
            assert p.poll() is None and time.monotonic() < deadline, "writer did not start"
            time.sleep(0.05)
        assert not _no_tmp(tmp_path)                       # the temporary file is there ...
        p.send_signal(signal.SIGTERM)
        rc = p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert rc == -signal.SIGTERM                           # still dies by the signal
    assert target.read_bytes() == b"old"
    # ... and gone; negative control: without the handler SIGTERM leaves it behind
    assert _no_tmp(tmp_path) == handler


def _savez(name):
    import numpy as np
    with open(name, "wb") as f:              # a writer that needs a file name (np.savez, h5py)
        np.savez(f, a=np.arange(3))


def test_writers_that_need_a_file_name_get_the_same_guarantees(tmp_path):
    import numpy as np
    target = tmp_path / "real.npz"
    target.write_bytes(b"old")
    link = tmp_path / "link.npz"
    os.symlink("real.npz", link)
    lio.atomic_write_with(link, _savez)
    assert os.path.islink(link) and list(np.load(target)["a"]) == [0, 1, 2] and _no_tmp(tmp_path)
    lio.atomic_write_with("/dev/null", _savez)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    with pytest.raises(LdasparkError, match="is a directory"):
        lio.atomic_write_with(tmp_path, _savez)

    def failing(name):
        with open(name, "wb") as f:
            f.write(b"half")
        raise OSError(28, "No space left on device")
    with pytest.raises(LdasparkError, match="No space left"):
        lio.atomic_write_with(target, failing)
    assert list(np.load(target)["a"]) == [0, 1, 2] and _no_tmp(tmp_path)    # previous file intact
