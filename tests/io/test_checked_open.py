"""Every file the library and the command line read goes through one checked opener
(``validate.open_regular`` / ``read_regular``): a regular file of bounded size, or one
LdasparkError in one line, without blocking (docs/reliability.md "Every file read is a regular
file of bounded size")."""
import os
import stat

import pytest

import ldaspark
from ldaspark.core.errors import InputError
from ldaspark.cli import main
from ldaspark.core import validate as V

pytestmark = pytest.mark.skipif(os.name != "posix", reason="FIFOs and /dev/zero")


def _specials(tmp_path):
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    (tmp_path / "dir.json").mkdir()
    link = tmp_path / "zero.json"
    link.symlink_to("/dev/zero")
    tolink = tmp_path / "fifolink.json"
    tolink.symlink_to(fifo)
    return {"fifo": fifo, "directory": tmp_path / "dir.json", "/dev/zero": "/dev/zero",
            "link to /dev/zero": link, "link to a FIFO": tolink, "missing": tmp_path / "none.json"}


KINDS = ["fifo", "directory", "/dev/zero", "link to /dev/zero", "link to a FIFO", "missing"]


@pytest.mark.parametrize("kind", KINDS)
def test_the_opener_refuses_what_is_not_a_regular_file(tmp_path, kind):
    path = _specials(tmp_path)[kind]
    with pytest.raises(InputError) as ei:
        V.read_regular(path, 1000, "input")
    assert len(str(ei.value).splitlines()) == 1


def test_the_opener_bounds_the_size_two_sided(tmp_path):
    p = tmp_path / "a.json"
    p.write_bytes(b"x" * 100)
    assert V.read_regular(p, 100) == b"x" * 100           # exactly the limit: read
    with pytest.raises(InputError, match="more than 99"):
        V.read_regular(p, 99)
    fh, size = V.open_regular(p, 100)
    with fh:
        assert size == 100 and stat.S_ISREG(os.fstat(fh.fileno()).st_mode)


def test_the_descriptor_is_checked_again(tmp_path, monkeypatch):
    # a FIFO swapped in after the stat: opened without blocking, refused on its descriptor
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    real = tmp_path / "real"
    real.write_text("{}")
    monkeypatch.setattr(V, "regular_file", lambda path, limit, what="file": 2)     # the stat "passed"
    with pytest.raises(InputError, match="not a regular file"):
        V.open_regular(str(fifo), 100, "input")
    fh, _ = V.open_regular(str(real), 100, "input")      # negative control: a regular file opens
    fh.close()


@pytest.mark.parametrize("kind", KINDS)
def test_load_result_and_load_tableau_refuse(tmp_path, kind):
    path = _specials(tmp_path)[kind]
    with pytest.raises(ldaspark.LdasparkError):
        ldaspark.load_result(path)
    with pytest.raises(ldaspark.LdasparkError):
        ldaspark.load_tableau(path)


@pytest.mark.parametrize("kind", KINDS)
def test_the_cli_refuses_in_one_line(capsys, tmp_path, kind):
    path = _specials(tmp_path)[kind]
    for argv in (["integrate", "particle", "custom", "--tableau", str(path), "--h", "0.5", "--t-end", "1",
                  "--out", str(tmp_path / "o.json")], ["audit", str(path)]):
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("ldaspark: error:"), (argv, err)
