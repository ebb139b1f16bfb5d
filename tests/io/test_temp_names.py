"""The stale-temporary-file sweep parses names defensively (docs/reliability.md "A planted name
never denies a write"): a name whose pid field is not one ``TempFile`` writes (a pid beyond the
platform's range, signed, with a leading zero, non-ASCII digits, empty) is not the sweep's file:
it is left, and the write succeeds; a name of a dead writer of this host is still removed."""
import os

import pytest

from ldaspark.core import lifecycle
from ldaspark.core.io import atomic_write_text
from ldaspark.core.lifecycle import PID_MAX, TempFile, _HOST, parse_temp_pid

# neighbours of the planted 20-digit pid: out of range, signed, leading zeros, Unicode digits
# (Arabic-Indic, fullwidth, superscript), empty, spaces, a pid of 0
BAD_PIDS = ["99999999999999999999", str(PID_MAX + 1), str(2 ** 64), "9" * 200, "-5", "+5", "-0", "0", "00012",
            "\u0663\u0663", "\uff11\uff12", "\u00b9", "", " 12", "12 ", "1_000", "0x10", "1e3"]


@pytest.mark.parametrize("pid", BAD_PIDS, ids=[repr(p)[:24] for p in BAD_PIDS])
def test_an_unparsable_pid_field_is_not_ours(pid):
    assert parse_temp_pid(pid) is None


@pytest.mark.parametrize("pid, want", [("1", 1), ("12345", 12345), (str(PID_MAX), PID_MAX)])
def test_a_pid_the_writer_writes_is_parsed(pid, want):
    assert parse_temp_pid(pid) == want


def _planted(d, target, pid):
    tag = TempFile(str(d / target))._tag()
    name = f".tmp-ldaspark-{_HOST}-{pid}-abcdefgh.{tag}"
    (d / name).write_text("planted")
    return name


@pytest.mark.parametrize("pid", BAD_PIDS, ids=[repr(p)[:24] for p in BAD_PIDS])
def test_a_planted_name_neither_denies_the_write_nor_is_removed(tmp_path, pid):
    name = _planted(tmp_path, "out.json", pid)
    atomic_write_text(tmp_path / "out.json", "new")       # was: OverflowError for a 20-digit pid
    assert (tmp_path / "out.json").read_text() == "new"
    assert (tmp_path / name).read_text() == "planted"      # not ours: left
    assert not lifecycle.is_temp_name(name)


def test_negative_control_a_dead_writers_file_is_removed(tmp_path):
    # the sweep still works: the file of a pid that is dead on this host goes at the next write
    dead = 2 ** 22 + 17            # above Linux's pid_max ceiling (2^22): never a live process
    assert lifecycle._pid_alive(dead) is False or not os.path.exists("/proc")
    name = _planted(tmp_path, "out.json", dead)
    assert lifecycle.is_temp_name(name)
    atomic_write_text(tmp_path / "out.json", "new")
    assert (tmp_path / "out.json").read_text() == "new"
    assert not (tmp_path / name).exists()
