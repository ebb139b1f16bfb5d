"""A checkpoint (``*.partial.jsonl``) is data from disk like any other: a record is resumed only
when its HMAC (a per-user key in the trusted cache directory) is right for this run's
fingerprint, its unit is one the run expects, its value is finite JSON within the reader's
bounds and the caller's schema accepts it. Anything else is discarded with one note and
computed again, never crashes the reader and never survives into the next run. Each check has a
control: the same forged record with a right HMAC, or without the schema, WOULD be resumed."""
import json
import os
import stat

import pytest
from hypothesis import given, strategies as st

from ldaspark.lab import checkpoint as lab_checkpoint
from ldaspark.core.errors import LdasparkError
from ldaspark.executors import Unit
from ldaspark.lab.checkpoint import Checkpoint, CheckpointKeyError, checkpoint_key, run_resumable, \
    source_fingerprint


def _square(calls, i):
    with open(calls, "a") as f:
        f.write(f"{i}\n")
    return {"value": i * i}


def _nan_unit(i):
    return {"value": float("nan")}


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """A fresh trusted directory (and no key cached in this process) for every test."""
    d = tmp_path / "cache"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    monkeypatch.setattr(lab_checkpoint, "_KEYS", {})
    return d


class Run:
    """Four units u0..u3 of value {"value": i^2}, their calls counted, notes collected."""

    def __init__(self, tmp_path, fp="fp-1", validate=None):
        self.calls = tmp_path / "calls"
        self.calls.write_text("")
        self.path = tmp_path / "run.partial.jsonl"
        self.fp, self.validate, self.notes = fp, validate, []
        self.units = [Unit(f"u{i}", _square, (str(self.calls), i)) for i in range(4)]

    def __call__(self, units=None):
        self.calls.write_text("")
        ck = Checkpoint(self.path, self.fp, say=self.notes.append)
        return run_resumable(units or self.units, ck, where=None, jobs=1, validate=self.validate)

    def ran(self):
        return sorted(int(x) for x in self.calls.read_text().split())

    def lines(self):
        return self.path.read_text().splitlines()

    def write(self, lines):
        self.path.write_text("".join(x + "\n" for x in lines))

    def index(self, unit):
        """The line of ``unit``'s record (the file's order is the order the units finished)."""
        return next(i for i, x in enumerate(self.lines()) if i and json.loads(x).get("unit") == unit)


def _forge(run, unit, value, key=None):
    """A record line for ``unit`` with an HMAC by ``key`` (default: the user's own key, i.e. a
    record exactly as this user's run would have written it)."""
    ck = Checkpoint(run.path, run.fp, key=key)
    return ck._line(unit, value).rstrip("\n")


def test_a_clean_rerun_resumes_everything_and_writes_mac_lines(tmp_path):
    run = Run(tmp_path)
    assert run() == {f"u{i}": {"value": i * i} for i in range(4)} and run.ran() == [0, 1, 2, 3]
    recs = [json.loads(x) for x in run.lines()[1:]]
    assert all(set(r) == {"unit", "value", "mac"} and len(r["mac"]) == 64 for r in recs)
    assert run() == {f"u{i}": {"value": i * i} for i in range(4)}
    assert run.ran() == [] and run.notes == []                  # all four resumed, nothing to say


def test_an_edited_value_is_discarded_and_recomputed(tmp_path):
    run = Run(tmp_path)
    run()
    lines = run.lines()
    rec = json.loads(lines[2])
    rec["value"] = {"value": 12345}                            # the MAC of the old value kept
    lines[2] = json.dumps(rec)
    run.write(lines)
    out = run()
    assert out["u1"] == {"value": 1} and out["u1"] != {"value": 12345} and run.ran() == [1]
    assert len(run.notes) == 1 and "wrong HMAC" in run.notes[0] and "\n" not in run.notes[0]
    # control: the same edit with the HMAC the user's key gives would have been resumed
    lines = run.lines()
    lines[run.index("u1")] = _forge(run, "u1", {"value": 12345})
    run.write(lines)
    assert run()["u1"] == {"value": 12345} and run.ran() == []


def test_a_forged_file_with_the_recomputed_fingerprint_is_not_resumed(tmp_path):
    """Anyone can recompute the fingerprint (it is a hash of public files): the header is right,
    the records carry HMACs of another key (or a bare sha256), so none is resumed."""
    run = Run(tmp_path, fp=source_fingerprint("test", 1))
    other = bytes(range(32))
    import hashlib
    run.write([json.dumps({"fingerprint": run.fp}),
               _forge(run, "u0", {"value": -1}, key=other),
               json.dumps({"unit": "u1", "value": {"value": -2},
                           "mac": hashlib.sha256(run.fp.encode() + b"u1").hexdigest()})])
    out = run()
    assert out["u0"] == {"value": 0} and out["u1"] == {"value": 1} and run.ran() == [0, 1, 2, 3]
    assert {"value": -1} not in out.values() and {"value": -2} not in out.values()
    assert len(run.notes) == 1 and "2 record(s) discarded" in run.notes[0]
    # control: signed with the user's key, the forged value is taken as it is
    run.write([json.dumps({"fingerprint": run.fp}), _forge(run, "u0", {"value": -1})])
    assert run()["u0"] == {"value": -1}


def test_a_record_moved_to_another_unit_or_run_is_refused(tmp_path):
    run = Run(tmp_path)
    run()
    lines = run.lines()
    rec = json.loads(lines[1])
    rec["unit"] = "u3"                                         # u0's value and MAC under u3's name
    lines[4] = json.dumps(rec)
    run.write(lines)
    assert run()["u3"] == {"value": 9} and run.ran() == [3]
    # the same file under another fingerprint (other settings): no record carries its HMAC
    run.fp = "fp-2"
    lines = run.lines()
    lines[0] = json.dumps({"fingerprint": "fp-2"})
    run.write(lines)
    assert run() and run.ran() == [0, 1, 2, 3]


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_a_non_finite_record_is_discarded_and_does_not_poison_the_next_run(tmp_path, token):
    run = Run(tmp_path)
    run()
    lines = run.lines()
    good = _forge(run, "u2", {"value": 7.5})
    lines[3] = good.replace("7.5", token)
    run.write(lines)
    out = run()
    assert out["u2"] == {"value": 4} and run.ran() == [2] and "not finite JSON" in run.notes[0]
    assert token not in run.path.read_text()                   # rewritten without it
    run.notes.clear()
    assert run()["u2"] == {"value": 4} and run.ran() == [] and run.notes == []
    # control: the finite record of the same form is resumed
    lines = run.lines()
    lines[run.index("u2")] = good
    run.write(lines)
    assert run()["u2"] == {"value": 7.5}


def test_a_unit_that_returns_nan_is_not_recorded(tmp_path):
    notes = []
    ck = Checkpoint(tmp_path / "n.partial.jsonl", "fp", say=notes.append)
    out = run_resumable([Unit("n", _nan_unit, (1,)), Unit("ok", _square, (str(tmp_path / "c"), 3))], ck,
                        where=None, jobs=1)
    assert out["ok"] == {"value": 9}
    assert "NaN" not in ck.path.read_text() and len(notes) == 1 and "not recorded" in notes[0]
    assert set(Checkpoint(ck.path, "fp").load()) == {"ok"}


def test_unknown_units_and_wrong_shapes_are_discarded(tmp_path):
    def schema(name, value):
        if not (isinstance(value, dict) and set(value) == {"value"} and isinstance(value["value"], int)):
            raise LdasparkError("expected {value: int}")
    run = Run(tmp_path, validate=schema)
    run()
    lines = run.lines()
    lines.append(_forge(run, "u9", {"value": 81}))              # authentic, but not a unit of this run
    lines[2] = _forge(run, "u1", {"value": "1"})                 # authentic, wrong type
    lines[3] = _forge(run, "u2", [4])                            # authentic, wrong shape
    run.write(lines)
    out = run()
    assert set(out) == {"u0", "u1", "u2", "u3"} and out["u1"] == {"value": 1} and out["u2"] == {"value": 4}
    assert run.ran() == [1, 2] and len(run.notes) == 1 and "3 record(s) discarded" in run.notes[0]
    assert "u9" not in run.path.read_text()                      # not carried into the new file
    # control: a reader that does not know the run's units would have taken u9
    lines = run.lines()
    lines.append(_forge(run, "u9", {"value": 81}))
    run.write(lines)
    assert Checkpoint(run.path, run.fp).load()["u9"] == {"value": 81}
    # control: without the schema the wrong type would have been resumed
    lines = run.lines()
    lines[run.index("u1")] = _forge(run, "u1", {"value": "1"})
    run.write(lines)
    run.validate = None
    assert run()["u1"] == {"value": "1"}


def test_a_schema_that_raises_anything_only_discards(tmp_path):
    def schema(name, value):
        return value["value"] < 5                                 # KeyError, TypeError on odd data; False for 9
    run = Run(tmp_path, validate=schema)
    run()
    assert run.ran() == [0, 1, 2, 3]
    run.validate = lambda name, value: schema(name, value) if name != "u0" else value["nope"]
    out = run()
    assert out["u0"] == {"value": 0} and run.ran() == [0, 3]      # u0 KeyError, u3 False


@pytest.mark.parametrize("kind", ["utf8", "deep", "long", "not-a-record", "truncated", "empty", "array"])
def test_malformed_lines_never_crash_the_reader(tmp_path, monkeypatch, kind):
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_LINE", 4096)
    run = Run(tmp_path)
    run()
    raw = run.path.read_bytes().splitlines(keepends=True)
    bad = {"utf8": b'{"unit": "u1", "value": "\xff\xfe", "mac": "00"}\n',
           "deep": b"[" * 100000 + b"]" * 100000 + b"\n",
           "long": b'{"unit": "u1", "value": "' + b"x" * 10000 + b'", "mac": "00"}\n',
           "not-a-record": b'{"unit": "u1"}\n', "truncated": raw[2][:-10], "empty": b"\n",
           "array": b'[1, 2, 3]\n'}[kind]
    raw[2] = bad
    if kind == "truncated":                  # a killed parent's last line: only at the end
        raw = raw[:2] + raw[3:] + [bad]
    run.path.write_bytes(b"".join(raw))
    out = run()
    assert out == {f"u{i}": {"value": i * i} for i in range(4)} and run.ran() == [1]
    assert len(run.notes) == 1


def test_the_reader_is_bounded_in_total_size(tmp_path, monkeypatch):
    run = Run(tmp_path)
    run()
    monkeypatch.setattr(lab_checkpoint, "MAX_CHECKPOINT_BYTES", len(run.lines()[0]) + len(run.lines()[1]) + 5)
    assert run() and run.ran() == [1, 2, 3] and "past" in run.notes[0]


_json = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                     lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=3), c, max_size=3),
                     max_leaves=8)


@given(junk=st.lists(st.one_of(st.binary(max_size=60),
                               st.builds(lambda u, v, m: json.dumps({"unit": u, "value": v, "mac": m},
                                                                    allow_nan=True).encode(),
                                         st.sampled_from(["u0", "u1", "zz", ""]), _json,
                                         st.text("0123456789abcdef", min_size=64, max_size=64))),
                     max_size=6))
def test_fuzzed_lines_are_discarded_never_raised(tmp_path_factory, junk):
    d = tmp_path_factory.mktemp("fuzz")
    path = d / "f.partial.jsonl"
    key = bytes(32)
    good = Checkpoint(path, "fp", key=key)
    lines = [json.dumps({"fingerprint": "fp"}).encode() + b"\n", good._line("u0", {"value": 0}).encode()]
    lines += [j.replace(b"\n", b" ") + b"\n" for j in junk]
    path.write_bytes(b"".join(lines))
    notes = []
    out = Checkpoint(path, "fp", key=key, say=notes.append).load(["u0", "u1"])
    assert out == {"u0": {"value": 0}}          # the one authentic record; fuzz never verifies
    assert len(notes) <= 1


# --- the key ---------------------------------------------------------------------------------
def test_the_key_file_is_private_and_made_once(private_cache):
    k1 = checkpoint_key()
    path = private_cache / "checkpoint-hmac.key"
    st_ = os.lstat(path)
    assert stat.S_ISREG(st_.st_mode) and stat.S_IMODE(st_.st_mode) == 0o600 and st_.st_uid == os.getuid()
    assert stat.S_IMODE(os.stat(private_cache).st_mode) == 0o700
    lab_checkpoint._KEYS.clear()
    assert checkpoint_key() == k1 and len(k1) == 32
    assert not [n for n in os.listdir(private_cache) if n.startswith(".checkpoint-hmac")]  # no temp left


@pytest.mark.parametrize("plant", ["symlink", "group-readable", "short", "fifo"])
def test_an_untrusted_key_file_is_replaced_never_used(private_cache, tmp_path, plant):
    private_cache.mkdir(mode=0o700)
    path = private_cache / "checkpoint-hmac.key"
    known = "ab" * 32 + "\n"
    target = tmp_path / "attacker.key"
    target.write_text(known)
    if plant == "symlink":
        os.chmod(target, 0o600)
        path.symlink_to(target)
    elif plant == "group-readable":
        path.write_text(known)
        os.chmod(path, 0o640)
    elif plant == "short":
        path.write_text("ab\n")
        os.chmod(path, 0o600)
    else:
        os.mkfifo(path, 0o600)                                  # never opened for blocking reads
    key = checkpoint_key()
    assert key != bytes.fromhex("ab" * 32)
    assert target.read_text() == known                          # the link's target untouched
    assert stat.S_ISREG(os.lstat(path).st_mode) and stat.S_IMODE(os.lstat(path).st_mode) == 0o600
    # control: a private key file of the same content is the key
    lab_checkpoint._KEYS.clear()
    path.unlink()
    path.write_text(known)
    os.chmod(path, 0o600)
    assert checkpoint_key() == bytes.fromhex("ab" * 32)


def test_without_a_trusted_directory_nothing_is_resumed_and_the_run_still_works(tmp_path, monkeypatch):
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)                                    # others could plant a key there
    monkeypatch.setattr("ldaspark.compiled.cache.cache_dir", lambda: str(shared))
    with pytest.raises(CheckpointKeyError, match="not trusted"):
        checkpoint_key()
    run = Run(tmp_path)
    assert run() == {f"u{i}": {"value": i * i} for i in range(4)}
    assert run() and run.ran() == [0, 1, 2, 3]                 # never resumed without a key
    assert all("\n" not in n for n in run.notes) and any("not trusted" in n for n in run.notes)


# --- the fingerprint is the run's whole identity ---------------------------------------------
def test_the_fingerprint_covers_the_environment_and_the_files_a_run_reads(tmp_path, monkeypatch):
    f = tmp_path / "proj"
    (f / "tests").mkdir(parents=True)
    (f / "README.md").write_text("a")
    (f / "tests" / "t.py").write_text("x = 1")
    paths = [f / "README.md", f / "tests", f / "absent"]
    base = source_fingerprint("m", paths=paths)
    assert source_fingerprint("m", paths=paths) == base
    (f / "README.md").write_text("b")
    changed_readme = source_fingerprint("m", paths=paths)
    assert changed_readme != base
    (f / "tests" / "run.partial.jsonl").write_text("grows as it is written")   # never part of it
    (f / "tests" / "run.partial.jsonl.123.tmp").write_text("x")
    assert source_fingerprint("m", paths=paths) == changed_readme
    (f / "tests" / "data.json").write_text("{}")                # not only *.py under paths
    assert source_fingerprint("m", paths=paths) != changed_readme
    now = source_fingerprint("m", paths=paths)
    monkeypatch.setattr(lab_checkpoint, "_environment_identity", lambda: ["another numpy"])
    assert source_fingerprint("m", paths=paths) != now
    ck = Checkpoint(tmp_path / "c", now)
    assert ck.bound_to(1, "a").fingerprint != ck.bound_to(2, "a").fingerprint
    assert ck.bound_to(1, "a").fingerprint == ck.bound_to(1, "a").fingerprint != now


def test_run_ledger_binds_the_checkpoint_to_its_own_settings(monkeypatch):
    from ldaspark.lab.claims import ledger
    seen = []

    def fake(work, checkpoint, **kw):
        seen.append((checkpoint.fingerprint, kw["validate"]))
        return {u.name: [] for u in work}
    monkeypatch.setattr(lab_checkpoint, "run_resumable", fake)
    ck = Checkpoint("unused.partial.jsonl", "caller-fp")
    for perturbed in (True, False):
        ledger.run_ledger(max_s=1, scenes=("particle",), perturbed=perturbed, holonomic=False, groups=(),
                          jobs=1, checkpoint=ck)
    assert seen[0][0] != seen[1][0] and "caller-fp" not in (seen[0][0], seen[1][0])
    assert seen[0][1] is ledger.check_unit_records


def test_run_catalogue_binds_the_checkpoint_to_its_own_settings(monkeypatch):
    from ldaspark.lab.mutants import mutation
    seen = []

    def fake(units, checkpoint, **kw):
        seen.append((checkpoint.fingerprint, kw["validate"]))
        return {u.name: None for u in units}
    monkeypatch.setattr(lab_checkpoint, "run_resumable", fake)
    ck = Checkpoint("unused.partial.jsonl", "caller-fp")
    m = [mutation.by_id(mutation.QUICK[0])]
    mutation.run_catalogue(m, 1, hints_only=True, checkpoint=ck)
    mutation.run_catalogue(m, 1, hints_only=False, checkpoint=ck)
    mutation.run_catalogue(m, 1, hints_only=False, checkpoint=ck, exclude=("tests/core/test_spark.py",))
    assert len({s[0] for s in seen}) == 3 and seen[0][1] is mutation.check_record


# --- the callers' schemas --------------------------------------------------------------------
def _ledger_record(**change):
    from ldaspark.lab.claims.ledger import record
    return dict(record("22a", "gauss-1", "-", "pass", 0.0, "pass", 40, "n/a", 0.5), **change)


@pytest.mark.parametrize("change", [dict(residual="0.1"), dict(residual=True), dict(seconds=-1.0),
                                    dict(seconds=None), dict(dps=True), dict(dps=2.5), dict(status="ok"),
                                    dict(wellposed="maybe"), dict(note=3), dict(extra=1), dict(threshold=[1e-20])])
def test_the_ledger_schema(change):
    from ldaspark.lab.claims.ledger import check_unit_records
    assert check_unit_records("u", [_ledger_record(), _ledger_record(residual=None, threshold=1e-20, dps=None)])
    with pytest.raises(LdasparkError):
        check_unit_records("u", [_ledger_record(), _ledger_record(**change)])
    bad = _ledger_record()
    del bad["note"]
    for value in ({"a": 1}, [bad], [1], "records"):
        with pytest.raises(LdasparkError):
            check_unit_records("u", value)


def test_the_mutation_schema():
    from ldaspark.lab.mutants.mutation import _record, by_id, check_record, QUICK
    m = by_id(QUICK[0])
    rec = _record(m, "killed", "tests/test_x.py::test_y", 2.0)
    assert check_record(m.id, rec) and check_record(m.id, dict(_record(m, "timeout", None, 3.0), output_tail="..."))
    for bad in (dict(rec, killed=False), dict(rec, status="passed"), dict(rec, mutant="other"),
                dict(rec, seconds=float("inf")), dict(rec, seconds="2"), dict(rec, first_failing_test=3),
                dict(rec, extra=1), {k: v for k, v in rec.items() if k != "file"}):
        with pytest.raises(LdasparkError):
            check_record(m.id, bad)
    with pytest.raises(LdasparkError):
        check_record("another-id", rec)


def test_the_key_is_made_where_hard_links_are_not_supported(private_cache, monkeypatch):
    def no_link(src, dst):
        raise PermissionError(1, "Operation not permitted")
    monkeypatch.setattr(os, "link", no_link)
    key = checkpoint_key()
    path = private_cache / "checkpoint-hmac.key"
    assert len(key) == 32 and stat.S_IMODE(os.lstat(path).st_mode) == 0o600
    lab_checkpoint._KEYS.clear()
    assert checkpoint_key() == key
