"""Rules of ``ldaspark.executors`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import concurrent.futures as cf
import json
import os
import stat
from types import SimpleNamespace
import numpy as np
import pytest
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark import executors as workers
from ldaspark.executors import InlineExecutor, Unit
from ldaspark.lab import checkpoint as lab_checkpoint
from ldaspark.lab.checkpoint import MAX_CHECKPOINT_DEPTH, MAX_CHECKPOINT_LINE, Checkpoint


class _FakeExecutor(cf.Executor):
    def __init__(self):
        self.inner = InlineExecutor()

    def submit(self, fn, /, *args, **kwargs):
        return self.inner.submit(fn, *args, **kwargs)


class Client:
    """Looks like a distributed.Client (by the name and the two methods)."""

    def __init__(self):
        self.closed = False

    def get_executor(self, pure=True):
        assert pure is False
        return _FakeExecutor()

    def cancel(self, futures):
        pass

    def close(self):
        self.closed = True


def _fail_unit(x):
    raise ValueError(f"bad {x}")


@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    monkeypatch.setattr(lab_checkpoint, "_KEYS", {})
    return d


KEY = bytes(range(32))


def _ck(path, fp="fp", **kw):
    notes = []
    kw.setdefault("key", KEY)
    return Checkpoint(path, fp, say=notes.append, **kw), notes


# ============================== workers: pools, flags (mutant survivors) ===================
class _InlinePool(cf.Executor):
    """A stand-in for a local process pool: runs each call at once (not an InlineExecutor, so
    run_units takes the pool path: futures, as_completed, renew on a broken pool)."""

    def __init__(self, made, n):
        self.n, self.shut = n, None
        made.append(self)

    def submit(self, fn, /, *args, **kwargs):
        return InlineExecutor().submit(fn, *args, **kwargs)

    def shutdown(self, wait=True, **k):
        self.shut = wait


# ============================== workers ====================================================
def test_inline_executor_delivers_errors_but_not_ctrl_c():
    ex = InlineExecutor()
    assert ex.submit(lambda a, b=0: a + b, 1, b=2).result() == 3
    f = ex.submit(lambda: 1 / 0)
    assert isinstance(f.exception(), ZeroDivisionError)

    def ctrl_c():
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        ex.submit(ctrl_c)


def test_describe_names_each_place():
    assert workers.describe(None, 3) == "local pool of 3 worker process(es)"
    assert workers.describe("local", 0) == f"local pool of {max(1, os.cpu_count() or 1)} worker process(es)"
    assert workers.describe("tcp://h:1") == "Dask scheduler tcp://h:1"
    assert workers.describe(Client()) == "Dask client"
    assert workers.describe(cf.ThreadPoolExecutor) == "type"
    assert workers.describe(InlineExecutor()) == "InlineExecutor"
    assert workers.is_address("tcp://x") and not workers.is_address("tcp:/x") and not workers.is_address(3)


def test_describe_counts_workers_as_the_pool_would(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    assert workers.describe(None) == "local pool of 7 worker process(es)"
    assert workers.describe(None, 2) == "local pool of 2 worker process(es)"
    assert workers.describe(None, -3) == "local pool of 1 worker process(es)"
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert workers.describe("local") == "local pool of 1 worker process(es)"


def test_check_where_addresses_and_objects():
    for good in (None, "local", "tcp://host:8786", "tls://10.0.0.1:1", "ws://h", "tcp://[::1]:65535", "tcp://h:1/",
                 Client(), cf.ThreadPoolExecutor(1), SimpleNamespace(submit=lambda *a: None)):
        workers.check_where(good)
    for bad in ("x://y", "tcp://", "tcp://h:0", "tcp://h:65536", "tcp://[::1", "tcp://h:1/path", "tcp://h:",
                "tcp://u@h:1", "tcp://h h:1", "tcp://1.2.3.456:1", "tcp://[zz::]:1", "tcp://h:1?q", "inproc://a/1/2",
                "tcp://" + "a" * 300, 3, "remote", cf.ThreadPoolExecutor, SimpleNamespace(submit=3)):
        with pytest.raises(InputError):
            workers.check_where(bad)
    workers.check_where(f"inproc://10.0.0.1/{os.getpid()}/3")
    for bad in (f"inproc://10.0.0.1/{os.getpid()}/x", f"inproc:///{os.getpid()}/3", f"inproc://h/{os.getpid() + 1}/3",
                f"inproc://h/{os.getpid()}/3/4", "tcp://h\x00:1", "tcp://h\u00e9\t:1"):
        with pytest.raises(InputError):
            workers.check_where(bad)
    at300 = "tcp://" + "a" * 289 + ":8786"              # 300 characters: the longest admitted
    assert len(at300) == 300
    workers.check_where(at300)
    with pytest.raises(InputError):
        workers.check_where("tcp://" + "a" * 290 + ":8786")
    for j in (1, np.int64(2)):
        workers.check_where(None, j)
    for j in (0, -1, True, np.bool_(True), 1.0, "2"):
        with pytest.raises(InputError):
            workers.check_where(None, j)


def test_client_place_uses_the_clients_executor_and_leaves_it_open():
    c = Client()
    res = workers.run_units([Unit("a", pow, (2, 3)), Unit("b", pow, (3, 2))], where=c)
    assert res == {"a": 8, "b": 9} and not c.closed


def test_address_without_distributed_is_an_input_error(monkeypatch):
    import builtins
    real = builtins.__import__

    def no_distributed(name, *a, **k):
        if name == "distributed":
            raise ImportError("no distributed")
        return real(name, *a, **k)
    monkeypatch.setattr(builtins, "__import__", no_distributed)
    with pytest.raises(InputError, match="dist extra"):
        workers.run_units([Unit("a", pow, (2, 3))], where="tcp://127.0.0.1:9")


def test_address_client_is_opened_and_closed(monkeypatch):
    import sys
    import types
    made = []

    class FakeDistClient(Client):
        def __init__(self, addr, timeout=None, set_as_default=True):
            super().__init__()
            made.append((addr, set_as_default))
    fake = types.ModuleType("distributed")
    fake.Client = FakeDistClient
    monkeypatch.setitem(sys.modules, "distributed", fake)
    assert workers.run_units([Unit("a", pow, (2, 5))], where="tcp://127.0.0.1:8786/") == {"a": 32}
    assert made == [("tcp://127.0.0.1:8786", False)]

    class Unreachable:
        def __init__(self, *a, **k):
            raise TimeoutError("timed out")
    fake.Client = Unreachable
    with pytest.raises(InputError, match="cannot reach"):
        workers.run_units([Unit("a", pow, (2, 5))], where="tcp://127.0.0.1:8786")


def test_place_cancel_renew_and_close_of_an_own_pool(monkeypatch):
    stopped, made = [], []

    class Pool:
        def __init__(self, n):
            self.n, self.shut = n, None
            made.append(self)

        def shutdown(self, wait=True):
            self.shut = wait

        def submit(self, fn, *a, **k):
            return cf.Future()
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: Pool(n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: stopped.append(ex))
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    p = workers._Place(None, 2, None)
    assert p.local_pool and made[0].n == 2
    p.renew()
    assert stopped == [made[0]] and p.executor is made[1] and made[1].n == 2
    futs = [cf.Future(), cf.Future()]
    p.cancel(futs)
    assert all(f.cancelled() for f in futs) and stopped == [made[0], made[1]] and not p.local_pool
    p.close()
    assert made[1].shut is None                 # stopped already: not shut down again
    q = workers._Place("local", 3, None)
    q.close()
    assert made[2].shut is True
    # one worker: inline, nothing to renew, stop or close
    i = workers._Place(None, 1, None)
    assert isinstance(i.executor, InlineExecutor) and not i.local_pool
    i.renew()
    i.cancel([])
    i.close()
    assert len(made) == 3 and len(stopped) == 2
    # no jobs given: one worker per CPU (7 here), renewed with as many; no CPU count: inline
    d = workers._Place(None, None, None)
    assert made[-1].n == 7 and d.local_pool
    d.renew()
    assert made[-1].n == 7 and len(made) == 5
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    assert isinstance(workers._Place("local", 0, None).executor, InlineExecutor) and len(made) == 5
    # open_executor: a pool even for one worker; an exception cancels what was submitted
    with pytest.raises(RuntimeError, match="interrupted"):
        with workers.open_executor(None, 1) as ex:
            assert made[-1].n == 1
            f = ex.submit(pow, 2, 2)
            raise RuntimeError("interrupted")
    assert f.cancelled() and stopped[-1] is made[-1]


def test_stop_pool_terminates_and_tolerates_gone_processes():
    events = []

    class Proc:
        def __init__(self, i, fail):
            self.i, self.fail = i, fail

        def terminate(self):
            events.append(("term", self.i))
            if self.fail:
                raise OSError("gone")

        def join(self, timeout=None):
            events.append(("join", self.i, timeout))
            if self.fail:
                raise ValueError("closed")

    class Ex:
        _processes = {1: Proc(1, True), 2: Proc(2, False)}

        def shutdown(self, wait=True, cancel_futures=False):
            events.append(("shutdown", wait, cancel_futures))
    workers._stop_pool(Ex())
    assert events == [("shutdown", False, True), ("term", 1), ("term", 2), ("join", 1, 2), ("join", 2, 2)]

    class Ex2:
        def terminate_workers(self):
            events.append("tw")
            raise RuntimeError("already")

        def shutdown(self, **k):
            events.append("shutdown2")
    workers._stop_pool(Ex2())
    assert events[-1] == "tw"


def test_run_units_retries_lost_workers_only(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    tries = {}

    def flaky(name, n_fail):
        tries[name] = tries.get(name, 0) + 1
        if tries[name] <= n_fail:
            raise BrokenProcessPool("worker died")
        return name
    units = [Unit("ok2", flaky, ("ok2", 2)), Unit("lost3", flaky, ("lost3", 3)), Unit("err", _fail_unit, (1,))]
    res, failed = workers.run_units_partial(units, jobs=1, retries=2)
    assert res == {"ok2": "ok2"} and tries == {"ok2": 3, "lost3": 3}
    assert failed["lost3"] == "worker lost 3 times (BrokenProcessPool)" and failed["err"] == "ValueError: bad 1"
    tries.clear()
    res, failed = workers.run_units_partial([Unit("z", flaky, ("z", 1))], jobs=1, retries=0)
    assert res == {} and "worker lost 1 times" in failed["z"]
    with pytest.raises(InputError, match="retries"):
        workers.run_units([Unit("a", pow, (1, 1))], retries=-1)
    with pytest.raises(InputError, match="unique"):
        workers.run_units([Unit("a", pow, (1, 1)), Unit("a", pow, (1, 1))])
    with pytest.raises(workers.UnitsFailed) as ei:
        workers.run_units([Unit("a", pow, (2, 2)), Unit("b", _fail_unit, (2,))], jobs=1)
    assert ei.value.results == {"a": 4} and list(ei.value.failed) == ["b"]
    assert workers.run_units([Unit("a", pow, (2, 2)), Unit("b", _fail_unit, (2,))], jobs=1, raise_failed=False) == {"a": 4}
    assert workers._worker_lost(BrokenProcessPool()) and not workers._worker_lost(ValueError())
    assert workers._worker_lost(type("KilledWorker", (Exception,), {})())


def test_units_failed_message_lists_five_and_counts_the_rest():
    e = workers.UnitsFailed({f"u{i}": "x" for i in range(7)}, {"a": 1}, kept="/ck")
    msg = str(e)
    assert msg.startswith("7 work unit(s) failed (1 finished)") and "u4: x" in msg and "u5" not in msg
    assert "(and 2 more)" in msg and "kept in /ck" in msg
    e = workers.UnitsFailed({f"u{i}": "x" for i in range(5)}, {})
    assert "more" not in str(e) and "kept" not in str(e)


def test_environment_identity_names_absent_distributions(monkeypatch):
    import importlib.metadata as md
    real = md.version

    def version(name):
        if name == "numba":
            raise md.PackageNotFoundError(name)
        return real(name) if name != "gmpy2" else "9.9"
    monkeypatch.setattr(md, "version", version)
    ident = lab_checkpoint._environment_identity()
    assert "numba absent" in ident and "gmpy2==9.9" in ident
    assert len(ident) == 2 + len(lab_checkpoint._FINGERPRINT_DISTS)


def test_source_fingerprint_covers_paths_dirs_and_config(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "a.py").write_text("x = 1\n")
    (d / "b.txt").write_text("t\n")
    p = tmp_path / "p"
    p.mkdir()
    (p / "data.csv").write_text("1,2\n")
    (p / "__pycache__").mkdir()
    (p / "__pycache__" / "c.pyc").write_bytes(b"0")
    (p / "run.partial.jsonl").write_text("{}\n")
    f = tmp_path / "single.json"
    f.write_text("{}")
    base = lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert base == lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert base != lab_checkpoint.source_fingerprint("cfg2", dirs=[d], paths=[p, f])
    (d / "b.txt").write_text("changed\n")            # not *.py under dirs: no change
    assert base == lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    (p / "__pycache__" / "c.pyc").write_bytes(b"1")   # caches and checkpoints: no change
    (p / "run.partial.jsonl").write_text("{\"x\": 1}\n")
    assert base == lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    (d / "a.py").write_text("x = 2\n")
    b2 = lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b2 != base
    (p / "data.csv").write_text("1,3\n")
    b3 = lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b3 != b2
    f.write_text("[]")
    b4 = lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f])
    assert b4 != b3
    f.unlink()                                         # absent is its own state
    assert lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f]) not in (b3, b4)
    # a renamed file changes it (the relative name is hashed, not only the contents)
    (p / "data.csv").rename(p / "data2.csv")
    assert lab_checkpoint.source_fingerprint("cfg", dirs=[d], paths=[p, f]) != lab_checkpoint.source_fingerprint(
        "cfg", dirs=[d], paths=[p])


def test_json_depth_skips_strings_and_escapes():
    assert lab_checkpoint._json_depth('{"a": [1, {"b": 2}]}') == 3
    assert lab_checkpoint._json_depth('"[[[[" ') == 0
    assert lab_checkpoint._json_depth('["a\\"[[[", [1]]') == 2
    assert lab_checkpoint._json_depth('["a\\\\", [[1]]]') == 3
    assert lab_checkpoint._json_depth('["unclosed [[[[') == 1
    assert lab_checkpoint._json_depth("") == 0 and lab_checkpoint._json_depth("]]") == 0


def test_read_key_refuses_what_is_not_a_private_key_file(tmp_path, monkeypatch):
    good = tmp_path / "k"
    good.write_bytes(b"ab" * 32 + b"\n")
    os.chmod(good, 0o600)
    assert lab_checkpoint._read_key(str(good)) == bytes.fromhex("ab" * 32)
    os.chmod(good, 0o640)
    assert lab_checkpoint._read_key(str(good)) is None
    os.chmod(good, 0o600)
    good.write_bytes(b"AB" * 32 + b"\n")
    assert lab_checkpoint._read_key(str(good)) is None
    good.write_bytes(b"ab" * 32 + b"\n\n")
    assert lab_checkpoint._read_key(str(good)) is None
    assert lab_checkpoint._read_key(str(tmp_path / "none")) is None

    def bad_read(fd, n):
        raise OSError("EIO")
    good.write_bytes(b"ab" * 32 + b"\n")
    monkeypatch.setattr(os, "read", bad_read)
    assert lab_checkpoint._read_key(str(good)) is None


def test_checkpoint_key_errors(private_cache, monkeypatch, tmp_path):
    from ldaspark.compiled import cache as cache_mod

    def no_dir():
        raise cache_mod.CacheDirectoryError("nowhere safe")
    monkeypatch.setattr(cache_mod, "cache_dir", no_dir)
    with pytest.raises(lab_checkpoint.CheckpointKeyError, match="nowhere safe"):
        lab_checkpoint.checkpoint_key()
    d = tmp_path / "keys"
    d.mkdir(mode=0o700)
    os.chmod(d, 0o700)
    key = lab_checkpoint.checkpoint_key(str(d))
    assert len(key) == 32 and lab_checkpoint.checkpoint_key(str(d)) is key
    # a key that cannot be created: a CheckpointKeyError, the temporary file removed
    d2 = tmp_path / "keys2"
    d2.mkdir()
    os.chmod(d2, 0o700)
    real_open = os.open

    def no_create(path, flags, mode=0o777):
        if str(path).startswith(str(d2)) and flags & os.O_CREAT:
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, mode)
    monkeypatch.setattr(os, "open", no_create)
    with pytest.raises(lab_checkpoint.CheckpointKeyError, match="cannot create"):
        lab_checkpoint.checkpoint_key(str(d2))
    monkeypatch.setattr(os, "open", real_open)
    # a key that never reads back as trustworthy (mode reset by someone): three tries, then an error
    d3 = tmp_path / "keys3"
    d3.mkdir()
    os.chmod(d3, 0o700)
    monkeypatch.setattr(lab_checkpoint, "_read_key", lambda path: None)
    with pytest.raises(lab_checkpoint.CheckpointKeyError, match="cannot be made trustworthy"):
        lab_checkpoint.checkpoint_key(str(d3))
    assert [p.name for p in d3.iterdir()] == ["checkpoint-hmac.key"]


def test_checkpoint_key_race_keeps_the_other_creators_key(tmp_path, monkeypatch):
    d = tmp_path / "keys"
    d.mkdir()
    os.chmod(d, 0o700)
    monkeypatch.setattr(lab_checkpoint, "_KEYS", {})
    theirs = b"cd" * 32 + b"\n"

    def racing_link(src, dst):
        fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.write(fd, theirs)
        os.close(fd)
        raise FileExistsError(17, "File exists")
    monkeypatch.setattr(os, "link", racing_link)
    assert lab_checkpoint.checkpoint_key(str(d)) == bytes.fromhex("cd" * 32)
    assert sorted(p.name for p in d.iterdir()) == ["checkpoint-hmac.key"]


def test_checkpoint_mac_binds_fingerprint_name_and_value(tmp_path):
    a, _ = _ck(tmp_path / "c")
    b, _ = _ck(tmp_path / "c", fp="fp2")
    c, _ = _ck(tmp_path / "c", key=bytes(32))
    m = a._mac("u", {"x": 1})
    assert len(m) == 64 and m == a._mac("u", {"x": 1})
    assert m not in (b._mac("u", {"x": 1}), c._mac("u", {"x": 1}), a._mac("v", {"x": 1}), a._mac("u", {"x": 2}))
    assert a.bound_to(1).fingerprint != a.bound_to(2).fingerprint and a.bound_to(1).fingerprint != a.fingerprint
    assert a.bound_to(1)._key == KEY
    nokey = Checkpoint(tmp_path / "c", "fp")
    nokey._key_error = "no trusted directory"
    assert nokey._mac("u", 1) == ""


def test_checkpoint_parse_reasons(tmp_path):
    ck, _ = _ck(tmp_path / "c")
    units = {"u"}

    def line(obj):
        return (json.dumps(obj) + "\n").encode()
    good = line({"unit": "u", "value": [1, 2], "mac": ck._mac("u", [1, 2])})
    assert ck._parse(good, units) == ("u", [1, 2])
    assert ck._parse(good, None) == ("u", [1, 2])
    assert ck._parse(good[:-1], units)[1] == "truncated"
    assert ck._parse(b"\xff\xfe\n", units)[1] == "not UTF-8"
    assert ck._parse(b"[" * 70 + b"\n", units)[1].startswith("nested")
    assert ck._parse(b'{"unit": NaN}\n', units)[1].startswith("not finite JSON")
    assert ck._parse(line({"unit": "u", "value": 1}), units)[1] == "not a record {unit, value, mac}"
    assert ck._parse(line({"unit": "u", "value": 1, "mac": "XYZ"}), units)[1] == "no HMAC"
    assert ck._parse(line({"unit": "v", "value": 1, "mac": "0" * 64}), units)[1].startswith("unit 'v' is not one")
    assert ck._parse(line({"unit": 3, "value": 1, "mac": "0" * 64}), units)[1] == "the unit name is not a string"
    assert ck._parse(line({"unit": "u", "value": [1, 2], "mac": "0" * 64}), units)[1].startswith("wrong HMAC")
    nokey = Checkpoint(tmp_path / "c", "fp")
    nokey._key_error = "no key here"
    assert nokey._parse(good, units) == (None, "no key to check it (no key here)")
    # authentic, but refused by the schema (exception or False)
    ck.validate = lambda name, value: value == [9]
    assert ck._parse(good, units) == (None, "not a valid record")
    ck.validate = lambda name, value: (_ for _ in ()).throw(LdasparkError("schema says no"))
    assert ck._parse(good, units) == (None, "not a valid record: schema says no")


def test_checkpoint_why_not_bounds(tmp_path, monkeypatch):
    ck, _ = _ck(tmp_path / "c")
    assert ck._why_not("", 1, None) == "the unit name is not a string"
    assert ck._why_not("u", float("nan"), None).startswith("the value is not finite JSON")
    assert ck._why_not("u", {1j: 2}, None).startswith("the value is not finite JSON")
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_LINE", 300)
    assert ck._why_not("u", "x" * 98, None) == ""                        # 100 bytes = 300 - 200
    assert "101 bytes, more than" in ck._why_not("u", "x" * 99, None)
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_LINE", 8 * 2 ** 20)
    deep = [[[[1]]]]
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_DEPTH", 6)
    assert ck._why_not("u", deep, None) == ""                 # depth 4 = 6 - 2
    assert ck._why_not("u", [deep], None).startswith("the value is nested")


def test_checkpoint_load_header_duplicates_and_open_failures(tmp_path, monkeypatch):
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    assert ck.load() == {}
    ck.open({"a": 1})
    ck.add("b", 2)
    ck.add("a", 99)                # a second record of a unit: the first one is kept
    ck.close()
    ck2, notes2 = _ck(p)
    assert ck2.load() == {"a": 1, "b": 2} and notes2 == []
    assert ck2.load(units=["b"]) == {"b": 2} and "2 record(s) discarded" in notes2[-1]
    # a header that is not JSON, or JSON without the fingerprint: not resumed
    text = p.read_text().splitlines(True)
    for head in ("not json\n", "[1, 2]\n", json.dumps({"fingerprint": "other"}) + "\n"):
        p.write_text(head + "".join(text[1:]))
        ck3, notes3 = _ck(p)
        assert ck3.load() == {} and "not resumed" in notes3[-1]
    # a file that cannot be opened: an InputError, the file not touched
    p.write_text("".join(text))
    real_open = os.open

    def refuse(path, flags, *a):
        if str(path) == str(p):
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, *a)
    monkeypatch.setattr(os, "open", refuse)
    with pytest.raises(InputError, match="cannot be read"):
        _ck(p)[0].load()
    monkeypatch.setattr(os, "open", real_open)
    assert p.read_text() == "".join(text)
    # not a regular file after the lstat check (a race): refused on the descriptor
    monkeypatch.setattr(Checkpoint, "_check_regular", lambda self: None)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        _ck(fifo)[0].load()


def test_checkpoint_discard_notes_at_most_two_reasons(tmp_path):
    p = tmp_path / "c.jsonl"
    ck, _ = _ck(p)
    ck.open({})
    ck.close()
    with open(p, "a") as fh:
        fh.write("x\n" * 3)
    ck2, notes = _ck(p)
    assert ck2.load() == {}
    assert notes == ["checkpoint %s: 3 record(s) discarded and their units computed again: line 2: not finite JSON "
                     "(Expecting value: line 1 column 1 (char 0)); line 3: not finite JSON (Expecting value: line 1 "
                     "column 1 (char 0)) (and 1 more)" % p]
    with open(p, "w") as fh:
        fh.write(json.dumps({"fingerprint": "fp"}) + "\n" + "x\n" * 2)
    ck3, notes3 = _ck(p)
    assert ck3.load() == {} and "more" not in notes3[-1] and "2 record(s)" in notes3[-1]


def test_checkpoint_add_notes_a_refused_unit_once(tmp_path):
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    ck.open({})
    ck.add("u", float("inf"))
    ck.add("u", float("inf"))
    ck.add("v", float("nan"))
    ck.add("w", 1)
    ck.close()
    assert len(notes) == 2 and "'u' not recorded" in notes[0] and "'v' not recorded" in notes[1]
    assert _ck(p)[0].load() == {"w": 1}
    nokey = Checkpoint(tmp_path / "d.jsonl", "fp", say=notes.append)
    nokey._key_error = "no trusted key directory"
    nokey.open({})
    nokey.add("x", 1)
    nokey.close()
    assert "no trusted key directory" in notes[-1] and len(nokey.path.read_text().splitlines()) == 1


def test_run_resumable_says_what_it_resumes(tmp_path):
    p = tmp_path / "c.jsonl"
    said, ran = [], []

    def unit(i):
        ran.append(i)
        return i * 10
    units = [Unit(f"u{i}", unit, (i,)) for i in range(3)]
    ck = Checkpoint(p, "fp", key=KEY)
    assert lab_checkpoint.run_resumable(units[:2], ck, jobs=1, say=said.append) == {"u0": 0, "u1": 10}
    assert said == [] and ck.say == said.append
    ran.clear()
    done = []
    ck = Checkpoint(p, "fp", key=KEY)
    out = lab_checkpoint.run_resumable(units, ck, jobs=1, say=said.append, on_done=lambda n, v: done.append(n))
    assert out == {"u0": 0, "u1": 10, "u2": 20} and ran == [2] and done == ["u2"]
    assert said == [f"resuming: 2 of 3 units from {p}"]
    # a checkpoint with its own say keeps it
    mine = []
    ck = Checkpoint(p, "other-fp", key=KEY, say=mine.append)
    lab_checkpoint.run_resumable(units[:1], ck, jobs=1, say=said.append)
    assert mine and "not resumed" in mine[0] and len(said) == 1
    # no checkpoint: no say about resuming
    assert lab_checkpoint.run_resumable(units[:1], None, jobs=1, say=said.append) == {"u0": 0} and len(said) == 1


def test_a_local_pool_is_renewed_only_when_a_worker_died(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    made, stopped = [], []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: stopped.append(ex))
    assert workers.run_units([Unit(f"u{i}", pow, (i, 2)) for i in range(4)], jobs=3) == {
        "u0": 0, "u1": 1, "u2": 4, "u3": 9}
    assert len(made) == 1 and made[0].n == 3 and stopped == [] and made[0].shut is True
    tries = []

    def dies_once(x):
        tries.append(x)
        if len(tries) == 1:
            raise BrokenProcessPool("killed")
        return -x
    made.clear()
    assert workers.run_units([Unit("a", dies_once, (5,)), Unit("b", pow, (2, 3))], jobs=2) == {"a": -5, "b": 8}
    assert len(made) == 2 and stopped == [made[0]] and made[1].shut is True
    # a unit's own error does not renew the pool
    made.clear()
    stopped.clear()
    res, failed = workers.run_units_partial([Unit("e", _fail_unit, (3,)), Unit("b", pow, (2, 3))], jobs=2)
    assert res == {"b": 8} and list(failed) == ["e"] and len(made) == 1 and stopped == []


def test_run_units_on_a_users_executor_and_a_shut_down_one():
    with cf.ThreadPoolExecutor(2) as ex:
        assert workers.run_units([Unit("a", pow, (2, 4)), Unit("b", pow, (3, 3))], where=ex) == {"a": 16, "b": 27}
    assert workers.run_units([Unit("a", pow, (2, 4))], where=SimpleNamespace(
        submit=lambda fn, *a: InlineExecutor().submit(fn, *a))) == {"a": 16}
    with pytest.raises(InputError, match="refused new work"):
        workers.run_units([Unit("a", pow, (2, 4))], where=ex)


@pytest.mark.parametrize("flag", ["O_NOFOLLOW", "O_NONBLOCK", "O_CLOEXEC"])
def test_open_flags_missing_on_a_platform_are_left_out(tmp_path, monkeypatch, flag):
    """Where os lacks a flag, the reader opens without it (read-only still: never O_WRONLY)."""
    good = tmp_path / "k"
    good.write_bytes(b"ab" * 32 + b"\n")
    os.chmod(good, 0o600)
    p = tmp_path / "c.jsonl"
    ck, _ = _ck(p)
    ck.open({"a": [1]})
    ck.close()
    monkeypatch.delattr(os, flag)
    assert lab_checkpoint._read_key(str(good)) == bytes.fromhex("ab" * 32)
    assert _ck(p)[0].load() == {"a": [1]}
    d = tmp_path / "keys"
    d.mkdir()
    os.chmod(d, 0o700)
    monkeypatch.setattr(lab_checkpoint, "_KEYS", {})
    key = lab_checkpoint.checkpoint_key(str(d))
    assert len(key) == 32 and stat.S_IMODE(os.lstat(d / "checkpoint-hmac.key").st_mode) == 0o600


# ============================== messages cut to a bound (mutant survivors) =================
def test_messages_quote_at_most_their_bound():
    with pytest.raises(InputError) as ei:
        workers.check_where(None, "j" * 100)
    assert str(ei.value) == "jobs must be a positive integer, got '" + "j" * 60 + "'"
    ck, _ = _ck("/nonexistent/c.jsonl")
    ck.validate = lambda name, value: (_ for _ in ()).throw(LdasparkError("w" * 150))
    assert ck._why_not("u", 1, None) == "not a valid record: " + "w" * 100
    ck.validate = lambda name, value: (_ for _ in ()).throw(ValueError())
    assert ck._why_not("u", 1, None) == "not a valid record: ValueError"
    assert ck._why_not("u" * 100, 1, {"v"}) == f"unit {'u' * 60!r} is not one of this run's"


def test_renew_without_a_cpu_count_makes_one_worker(monkeypatch):
    made = []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: None)
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    p = workers._Place(None, None, None)
    assert made[-1].n == 7
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    p.renew()
    assert made[-1].n == 1 and len(made) == 2
    p = workers._Place(None, 3, None)
    p.renew()
    assert made[-1].n == 3 and len(made) == 4


# ============================== defaults and bounds fixed at import =========================
def test_default_retries_are_two(monkeypatch):
    from concurrent.futures.process import BrokenProcessPool
    made = []
    monkeypatch.setattr(workers, "make_process_pool", lambda n, mp_context=None: _InlinePool(made, n))
    monkeypatch.setattr(workers, "_stop_pool", lambda ex: None)
    tries = {}

    def dies(name, n_fail):
        tries[name] = tries.get(name, 0) + 1
        if tries[name] <= n_fail:
            raise BrokenProcessPool("killed")
        return tries[name]
    assert workers.run_units([Unit("two", dies, ("two", 2))], jobs=2) == {"two": 3}
    with pytest.raises(workers.UnitsFailed, match="worker lost 3 times"):
        workers.run_units([Unit("three", dies, ("three", 3))], jobs=2)
    res, failed = workers.run_units_partial([Unit("p2", dies, ("p2", 2)), Unit("p3", dies, ("p3", 3))], jobs=2)
    assert res == {"p2": 3} and list(failed) == ["p3"]


def test_units_are_frozen():
    import dataclasses
    u = Unit("a", pow, (1, 2))
    with pytest.raises(dataclasses.FrozenInstanceError):
        u.name = "b"
    assert hash(u) == hash(Unit("a", pow, (1, 2)))


def test_checkpoint_line_bound_is_eight_mebibytes(tmp_path):
    """A unit of ~8.4 MB (past 8 MiB) is not recorded; one of ~2 MB is, and is resumed."""
    p = tmp_path / "c.jsonl"
    ck, notes = _ck(p)
    ck.open({})
    ck.add("big", "x" * (8 * 2 ** 20 - 150))
    ck.add("ok", "y" * (2 * 2 ** 20))
    ck.close()
    assert len(notes) == 1 and "'big' not recorded" in notes[0]
    assert _ck(p)[0].load() == {"ok": "y" * (2 * 2 ** 20)}


def test_why_not_quotes_the_json_error_up_to_sixty_characters(tmp_path):
    ck, _ = _ck(tmp_path / "c")
    long_name = type("AVeryLongClassNameThatMakesTheJsonErrorMessageLongerThanSixtyCharacters", (), {})
    for value in (float("nan"), long_name()):
        try:
            json.dumps(value, allow_nan=False)
        except (TypeError, ValueError) as exc:
            msg = str(exc)
        assert ck._why_not("u", value, None) == f"the value is not finite JSON ({msg[:60]})"
    assert len(msg) > 60


def test_parse_depth_bound_of_the_line_and_of_the_value(tmp_path, monkeypatch):
    """A line nested exactly MAX_CHECKPOINT_DEPTH deep passes the reader's bound (the record's value,
    one level less, then meets the writer's bound); one level more is refused unparsed."""
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_DEPTH", 6)
    ck, _ = _ck(tmp_path / "c")

    def line(value):
        return (json.dumps({"unit": "u", "value": value, "mac": ck._mac("u", value)}) + "\n").encode()
    assert ck._parse(line([[[[1]]]]), {"u"}) == ("u", [[[[1]]]])                  # line depth 5
    assert ck._parse(line([[[[[1]]]]]), {"u"}) == (None, "the value is nested more deeply than the reader's bound")
    assert ck._parse(line([[[[[[1]]]]]]), {"u"}) == (None, "nested more deeply than the reader's bound")


# --- checkpoints: the reader's depth check is linear in the line ----------------------------------
def test_checkpoint_depth_check_is_linear_on_a_forged_line():
    import time
    from ldaspark.lab.checkpoint import _json_depth
    # an unclosed string of escaped quotes: the former regular expression retried it at every
    # quote (quadratic: 18 s at 80 kB, hours at the 8 MiB line bound); now one pass
    forged = '"' + '\\"' * 400_000
    t = time.process_time()
    assert _json_depth(forged) == 0
    # bound: a linear pass over 800 kB takes milliseconds; 20 s is what the quadratic scan
    # needed for a tenth of this line (a hang caught, not a timing)
    assert time.process_time() - t < 20
    # valid neighbours: the depth of ordinary lines, brackets inside strings not counted
    assert _json_depth('[1, "a]", {"b": [2]}]') == 3 and _json_depth('["\\\\", [[]]]') == 3
    assert _json_depth('{"unit": "x", "value": "[[[["}') == 1


# --- Dask addresses: the whole rest is host[:port] ----------------------------------------------
@pytest.mark.parametrize("addr", ["tcp://[::1]x", "tcp://[::1]x:1", "tcp://1.2.3.4.5:1", "tcp://[zz]:1",
                                  "tcp://999.1.1.1:8786"])
def test_addresses_with_text_urlsplit_ignores_are_refused(addr):
    from ldaspark.executors import check_where
    with pytest.raises(InputError, match="malformed"):
        check_where(addr)


@pytest.mark.parametrize("addr", ["tcp://[::1]:8786", "tcp://127.0.0.1:8786", "tls://h.example:1", "tcp://h",
                                  "TCP://h:1", "tcp://h:1/"])
def test_well_formed_addresses_still_pass(addr):
    from ldaspark.executors import check_where
    check_where(addr)


def test_a_scheduler_address_with_a_trailing_slash_reaches_dask_without_it(monkeypatch):
    distributed = pytest.importorskip("distributed")
    from ldaspark import executors as workers
    seen = []

    def fake_client(addr, **kw):
        seen.append(addr)
        raise OSError("no scheduler here")
    monkeypatch.setattr(distributed, "Client", fake_client)
    for where in ("tcp://127.0.0.1:1/", "tcp://127.0.0.1:1"):
        with pytest.raises(InputError, match="cannot reach"):
            workers._Place(where, None, None)
    assert seen == ["tcp://127.0.0.1:1", "tcp://127.0.0.1:1"]


def test_well_formed_addresses_pass_the_check():
    from ldaspark.executors import check_where
    for addr in ("tcp://127.0.0.1:8786", "tcp://scheduler", "tls://host.example:8786", "tcp://[::1]:8786",
                 "ws://h:1", f"inproc://10.0.0.1/{os.getpid()}/3"):
        check_where(addr)


# --- executors.py ----------------------------------------------------------------------------
def test_local_place_with_two_jobs_is_a_process_pool_of_two():
    place = workers._Place("local", 2, None)
    try:
        assert place.local_pool
        assert not isinstance(place.executor, workers.InlineExecutor)
        assert place.executor._max_workers == 2
    finally:
        place.close()


def test_renewed_local_pool_keeps_the_number_of_workers():
    place = workers._Place(None, 2, None)
    try:
        place.renew()
        assert place.local_pool
        assert place.executor._max_workers == 2
    finally:
        place.close()


def test_stop_pool_shuts_the_pool_down():
    for ex in (workers.make_process_pool(1), cf.ProcessPoolExecutor(1)):
        workers._stop_pool(ex)
        with pytest.raises(RuntimeError):
            ex.submit(int, 1)


def test_stop_pool_uses_the_pools_own_terminate_workers():
    calls = []

    class Pool:
        def terminate_workers(self):
            calls.append("terminate_workers")

        def shutdown(self, wait=True, cancel_futures=False):
            calls.append("shutdown")

    workers._stop_pool(Pool())
    assert calls == ["terminate_workers"]


def test_source_fingerprint_does_not_depend_on_the_order_of_config_keys():
    a = lab_checkpoint.source_fingerprint({"a": 1, "b": 2})
    b = lab_checkpoint.source_fingerprint({"b": 2, "a": 1})
    assert a == b
    assert a != lab_checkpoint.source_fingerprint({"a": 1, "b": 3})


def test_read_key_returns_the_32_bytes_of_a_good_key_file(tmp_path):
    path = tmp_path / "k"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    os.write(fd, KEY.hex().encode() + b"\n")
    os.close(fd)
    assert lab_checkpoint._read_key(str(path)) == KEY


@pytest.mark.parametrize("text, depth", [("[[1]]", 2), ('{"a": [1, {"b": "]]"}]}', 3), ("1", 0), ("[]", 1)])
def test_json_depth_counts_nesting_from_the_first_character(text, depth):
    assert lab_checkpoint._json_depth(text) == depth


def test_record_mac_does_not_depend_on_dict_order(tmp_path):
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    assert cp._mac("u", {"a": 1, "b": 2}) == cp._mac("u", {"b": 2, "a": 1})
    assert lab_checkpoint._canonical({"b": 2, "a": 1}) == b'{"a":1,"b":2}'


def test_writer_bound_admits_a_value_of_exactly_the_bound(tmp_path):
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    n = MAX_CHECKPOINT_LINE - 200                 # the canonical text: the string and its 2 quotes
    assert cp._why_not("u", "x" * (n - 2), None) == ""
    assert "more than the reader's bound" in cp._why_not("u", "x" * (n - 1), None)


def test_reader_depth_bound_admits_a_line_of_exactly_the_bound(tmp_path):
    """A line nested MAX_CHECKPOINT_DEPTH deep passes the reader's parse bound; its value (one
    level less) is then refused by the writer's tighter bound, with that bound's reason."""
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    value = 0
    for _ in range(MAX_CHECKPOINT_DEPTH - 1):
        value = [value]
    raw = cp._line("u", value).encode()
    assert lab_checkpoint._json_depth(raw.decode()) == MAX_CHECKPOINT_DEPTH
    assert cp._parse(raw, None) == (None, "the value is nested more deeply than the reader's bound")
    deeper = cp._line("u", [value]).encode()
    assert cp._parse(deeper, None) == (None, "nested more deeply than the reader's bound")


def test_checkpoint_line_of_exactly_the_reader_bound_is_resumed(tmp_path):
    path = tmp_path / "c.jsonl"
    cp = Checkpoint(path, "fp", key=KEY, say=lambda m: None)
    line = cp._line("u", {"x": 1}).rstrip("\n")
    line = line[:-1] + " " * (MAX_CHECKPOINT_LINE - len(line) - 1) + "}\n"    # JSON whitespace
    assert len(line.encode()) == MAX_CHECKPOINT_LINE
    path.write_text(json.dumps({"fingerprint": "fp"}) + "\n" + line + cp._line("w", 2))
    notes = []
    got = Checkpoint(path, "fp", key=KEY, say=notes.append).load()
    assert got == {"u": {"x": 1}, "w": 2}
    assert notes == []


# --- the checkpoint fingerprint ------------------------------------------------------------------
def test_each_config_item_changes_the_fingerprint():
    base = ("run", True, ("a", "b"), 3)
    f0 = lab_checkpoint.source_fingerprint(*base)
    assert lab_checkpoint.source_fingerprint(*base) == f0                       # deterministic
    for i in range(len(base)):
        other = list(base)
        other[i] = {0: "other-run", 1: False, 2: ("a",), 3: 4}[i]
        assert lab_checkpoint.source_fingerprint(*other) != f0, i
    # order matters too (a swapped pair of options is another run)
    assert lab_checkpoint.source_fingerprint("run", ("a", "b"), True, 3) != f0
    # a dict option: its values count, not only its keys
    assert lab_checkpoint.source_fingerprint({"k": 1}) != lab_checkpoint.source_fingerprint({"k": 2})


def test_the_files_under_dirs_change_the_fingerprint(tmp_path):
    d = tmp_path / "tests"
    d.mkdir()
    (d / "test_a.py").write_text("x = 1\n")
    (d / "notes.txt").write_text("not source\n")
    f0 = lab_checkpoint.source_fingerprint("r", dirs=(d,))
    assert f0 != lab_checkpoint.source_fingerprint("r"), "dirs ignored"
    (d / "notes.txt").write_text("changed\n")                           # not a .py file
    assert lab_checkpoint.source_fingerprint("r", dirs=(d,)) == f0
    (d / "test_a.py").write_text("x = 2\n")                             # content
    f1 = lab_checkpoint.source_fingerprint("r", dirs=(d,))
    assert f1 != f0
    (d / "test_a.py").rename(d / "test_b.py")                           # name, same content
    f2 = lab_checkpoint.source_fingerprint("r", dirs=(d,))
    assert f2 != f1
    sub = d / "sub"
    sub.mkdir()
    (sub / "test_c.py").write_text("")                                  # a new (empty) file below
    assert lab_checkpoint.source_fingerprint("r", dirs=(d,)) != f2
    # a second directory counts as well as the first
    e = tmp_path / "verification"
    e.mkdir()
    (e / "test_v.py").write_text("y = 1\n")
    g0 = lab_checkpoint.source_fingerprint("r", dirs=(d, e))
    (e / "test_v.py").write_text("y = 2\n")
    assert lab_checkpoint.source_fingerprint("r", dirs=(d, e)) != g0


def test_a_checkpoint_of_another_identity_is_not_resumed(tmp_path):
    path = tmp_path / "run.partial.jsonl"
    ck = lab_checkpoint.Checkpoint(path, lab_checkpoint.source_fingerprint("r", 1)).open({})
    ck.add("u", {"v": 1})
    ck.close()
    assert lab_checkpoint.Checkpoint(path, lab_checkpoint.source_fingerprint("r", 1)).load() == {"u": {"v": 1}}
    assert lab_checkpoint.Checkpoint(path, lab_checkpoint.source_fingerprint("r", 2)).load() == {}


def test_the_package_source_and_each_library_version_enter_the_fingerprint(tmp_path, monkeypatch):
    import importlib.metadata
    import sys

    pkg = tmp_path / "pkg"
    (pkg / "dist").mkdir(parents=True)
    (pkg / "core.py").write_text("A = 1\n")
    (pkg / "notes.txt").write_text("not source\n")
    monkeypatch.setattr(lab_checkpoint, "__file__", str(pkg / "lab" / "checkpoint.py"))
    f0 = lab_checkpoint.source_fingerprint("r")
    (pkg / "notes.txt").write_text("changed\n")
    assert lab_checkpoint.source_fingerprint("r") != f0          # every file of the package: its data too (tableaux)
    f0 = lab_checkpoint.source_fingerprint("r")
    (pkg / "core.py").write_text("A = 2\n")
    f1 = lab_checkpoint.source_fingerprint("r")
    assert f1 != f0                                                        # the package's own source
    ident = lab_checkpoint._environment_identity()
    assert ident[0] == sys.version and len(ident) == 2 + len(lab_checkpoint._FINGERPRINT_DISTS)
    real = importlib.metadata.version
    for name in lab_checkpoint._FINGERPRINT_DISTS:
        def version(n, name=name):
            if n == name:
                return "0.0.0-other"
            return real(n)
        monkeypatch.setattr(importlib.metadata, "version", version)
        assert lab_checkpoint.source_fingerprint("r") != f1, name
    monkeypatch.setattr(importlib.metadata, "version", real)
    assert lab_checkpoint.source_fingerprint("r") == f1
    monkeypatch.setattr(sys, "version", sys.version + " other")
    assert lab_checkpoint.source_fingerprint("r") != f1


def test_a_cache_directory_anywhere_below_is_left_out_of_the_fingerprint(tmp_path):
    d = tmp_path / "tests"
    (d / "sub" / "__pycache__").mkdir(parents=True)
    (d / "test_a.py").write_text("x = 1\n")
    f0 = lab_checkpoint.source_fingerprint("r", dirs=(d,))
    (d / "sub" / "__pycache__" / "stale.py").write_text("y = 2\n")       # one part of three is a cache
    assert lab_checkpoint.source_fingerprint("r", dirs=(d,)) == f0
    (d / "sub" / "test_b.py").write_text("")
    assert lab_checkpoint.source_fingerprint("r", dirs=(d,)) != f0


def test_a_dict_option_fingerprints_the_same_in_any_key_order():
    assert lab_checkpoint.source_fingerprint({"a": 1, "b": 2}) == lab_checkpoint.source_fingerprint({"b": 2, "a": 1})


def test_a_checkpoint_name_asked_of_executors_says_where_it_moved():
    """The checkpoints moved to the lab (``ldaspark.lab.checkpoint``); the library cannot import
    the lab to alias them, so an access names the new place, and only for the moved names."""
    import subprocess
    import sys
    for name in workers.MOVED_TO_LAB:
        assert hasattr(lab_checkpoint, name), name                    # the list names real names
        with pytest.raises(AttributeError, match=f"moved to ldaspark.lab.checkpoint.{name} "):
            getattr(workers, name)
    with pytest.raises(AttributeError) as exc:                           # control: any other name
        workers.no_such_name
    assert "moved" not in str(exc.value) and "no_such_name" in str(exc.value)
    assert hasattr(workers, "run_units") and not hasattr(workers, "Checkpoint")
    # asking does not import the lab
    code = ("import sys, ldaspark.executors as w\n"
            "try:\n    w.Checkpoint\nexcept AttributeError:\n    pass\n"
            "print(any(m.startswith('ldaspark.lab') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
