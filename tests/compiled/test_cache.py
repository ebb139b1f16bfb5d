"""The kernel cache's trust model (docs/reliability.md, "The kernel cache: what is trusted"):
numba's pickled index (.nbi) and data (.nbc) files of the generated
models are unpickled only when this user's process recorded their sha256 when writing them;
planted, corrupt or foreign files are deleted and compiled again; nothing is written through a
link; every component of the cache directory's path is checked; numba's own cache of the
kernels is refused when another user can write it.

Every hostile payload here is a pickle whose loading creates a marker file; the tests assert
that the marker never appears, and a control shows that numba's own loader does run the same
payload (so that the plant is live, not a file nobody reads). No test depends on timing."""
from __future__ import annotations

import hashlib
import os
import pickle
import stat
import subprocess
import sys
import types

import pytest

from ldaspark.compiled import cache
from ldaspark.compiled.codegen import header

ROOT = os.getuid() == 0 if hasattr(os, "getuid") else False
OTHER_UID = 54321                    # a user id that is not ours (tests that chown need root)
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PYPATH = os.pathsep.join([REPO] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])


class Payload:
    """Unpickling this creates ``marker`` (what a hostile .nbi would do with os.system)."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def payload_bytes(marker) -> bytes:
    return pickle.dumps(Payload(marker))


@pytest.fixture(autouse=True)
def _numba_models(monkeypatch):
    """The model functions take numba's path here (LDASPARK_NATIVE=0, inherited by the CLI runs):
    numba's cache is what these tests attack; native model code (compiled/native.py) writes none."""
    monkeypatch.setenv("LDASPARK_NATIVE", "0")


def model_source(c: float) -> str:
    """A generated module of the form codegen writes, with one model function (compiles in
    a fraction of a second); ``c`` makes it a new system (a new digest)."""
    return header("probe", "mechanical", 1, 0) + f'''

@_jit(_mt.U_SIG, nogil=True, _nrt=False)
def U_of(t, q):
    return q[0] * {c!r}
'''


def load(src):
    """load_source as a fresh process would (the in-process module cache emptied)."""
    cache._MODULES.pop(cache.source_key(src), None)
    return cache.load_source(src)


def hits(mod):
    return sum(mod.U_of.stats.cache_hits.values()), sum(mod.U_of.stats.cache_misses.values())


def numba_files(d, src):
    modname = "ldaspark_model_" + cache.source_key(src)[:20]
    pyc = os.path.join(d, "__pycache__")
    return sorted(n for n in os.listdir(pyc) if n.startswith(modname + ".")) if os.path.isdir(pyc) else []


@pytest.fixture
def cdir(tmp_path, monkeypatch):
    d = tmp_path / "cache"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    return str(d)


# --- B: planted index and data files ------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".nbi", ".nbc"])
def test_planted_numba_file_in_a_private_directory_is_never_unpickled(cdir, tmp_path, suffix):
    src = model_source(1.25)
    mod = load(src)
    assert mod.U_of(0.0, __import__("numpy").array([2.0])) == 2.5
    names = [n for n in numba_files(cdir, src) if n.endswith(suffix)]
    assert names, "numba wrote no cache file for the model function"
    marker = tmp_path / "executed"
    for n in names:
        with open(os.path.join(cdir, "__pycache__", n), "wb") as f:
            f.write(payload_bytes(marker))
    mod = load(src)
    assert not marker.exists()
    assert mod.U_of(0.0, __import__("numpy").array([2.0])) == 2.5
    assert hits(mod) == (0, 1)                                 # the planted file was not used: compiled again
    # the rewritten file is recorded, so the next process loads it (a hit, not a recompilation)
    assert hits(load(src)) == (1, 0)
    # control: numba's own loader runs the payload of the same file
    from numba.core.caching import IndexDataCacheFile
    ctrl = tmp_path / "control"
    path = os.path.join(cdir, "__pycache__", names[0])
    with open(path, "wb") as f:
        f.write(payload_bytes(ctrl))
    base = names[0][: -len(suffix)] if suffix == ".nbi" else names[0].rsplit(".", 2)[0]
    files = IndexDataCacheFile(cache_path=os.path.join(cdir, "__pycache__"), filename_base=base, source_stamp=None)
    try:
        files._load_index() if suffix == ".nbi" else files._load_data(names[0])
    except Exception:
        pass
    assert ctrl.exists()


def test_unrecorded_file_is_refused_even_with_the_right_content(cdir):
    """The record is what is trusted, not the bytes: a file numba itself wrote, but not through
    this cache (no record), is deleted and compiled again; the controls load the recorded one."""
    src = model_source(2.5)
    load(src)
    manifest = os.path.join(cdir, "ldaspark_model_" + cache.source_key(src)[:20] + ".sha256")
    os.unlink(manifest)
    assert hits(load(src)) == (0, 1)
    assert hits(load(src)) == (1, 0)


@pytest.mark.skipif(not ROOT, reason="planting files of another user needs root (chown)")
def test_shared_0777_directory_with_another_users_pycache(tmp_path, monkeypatch):
    """The issue's attack: LDASPARK_CACHE_DIR a 0777 directory in which another user created
    __pycache__ with the model's .nbi files. The directory is tightened, the other user's
    __pycache__ removed, and nothing is unpickled from it."""
    src = model_source(3.75)
    d = tmp_path / "shared"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    load(src)                                                  # learn the names numba uses
    names = numba_files(str(d), src)
    import shutil
    shutil.rmtree(d)
    d.mkdir()
    os.chmod(d, 0o777)
    pyc = d / "__pycache__"
    pyc.mkdir()
    marker = tmp_path / "executed"
    for n in names:
        (pyc / n).write_bytes(payload_bytes(marker))
        os.chown(pyc / n, OTHER_UID, OTHER_UID)
    os.chmod(pyc, 0o777)
    os.chown(pyc, OTHER_UID, OTHER_UID)
    # a forged record of the payload's digest, also the other user's: not trusted either
    modname = "ldaspark_model_" + cache.source_key(src)[:20]
    rec = "".join(f"{hashlib.sha256(payload_bytes(marker)).hexdigest()}  {n}\n" for n in names)
    (d / (modname + ".sha256")).write_text(rec)
    os.chown(d / (modname + ".sha256"), OTHER_UID, OTHER_UID)
    mod = load(src)
    assert not marker.exists()
    assert hits(mod) == (0, 1)
    st = os.lstat(pyc)
    assert st.st_uid == os.getuid() and stat.S_IMODE(st.st_mode) == 0o700
    assert stat.S_IMODE(os.stat(d).st_mode) == 0o700


def test_store_reads_only_the_recorded_bytes(tmp_path):
    """TrustedStore.read: recorded bytes are returned; a file replaced behind the record (other
    bytes, a link), or a name never recorded, is None and the file deleted."""
    d = tmp_path / "c"
    d.mkdir(mode=0o700)
    store = cache.TrustedStore(str(d), "ldaspark_model_x", "digest")
    name = "ldaspark_model_x.f-3.py311.nbi"
    store.write(name, b"recorded")
    assert store.read(name) == b"recorded"
    path = d / "__pycache__" / name
    path.write_bytes(b"planted")
    assert store.read(name) is None and not path.exists()
    store.write(name, b"recorded")
    os.unlink(path)
    (tmp_path / "t").write_bytes(b"recorded")
    os.symlink(tmp_path / "t", path)                           # same bytes, behind a link
    assert store.read(name) is None and not os.path.lexists(path)
    (d / "__pycache__" / "ldaspark_model_x.g-5.py311.nbi").write_bytes(b"never recorded")
    assert store.read("ldaspark_model_x.g-5.py311.nbi") is None
    assert store.read("../escape") is None                     # names outside the module's are refused


def test_sweep_deletes_every_unrecorded_or_changed_file(tmp_path):
    d = tmp_path / "c"
    d.mkdir(mode=0o700)
    store = cache.TrustedStore(str(d), "ldaspark_model_x", "digest")
    store.write("ldaspark_model_x.f-3.py311.nbi", b"kept")
    store.write("ldaspark_model_x.f-3.py311.1.nbc", b"changed")
    pyc = d / "__pycache__"
    (pyc / "ldaspark_model_x.f-3.py311.1.nbc").write_bytes(b"other bytes")
    (pyc / "ldaspark_model_x.g-9.py311.nbi").write_bytes(b"planted")
    (pyc / "ldaspark_model_y.g-9.py311.nbi").write_bytes(b"another module's: not this sweep's business")
    assert sorted(store.sweep()) == ["ldaspark_model_x.f-3.py311.1.nbc", "ldaspark_model_x.g-9.py311.nbi"]
    assert sorted(os.listdir(pyc)) == ["ldaspark_model_x.f-3.py311.nbi", "ldaspark_model_y.g-9.py311.nbi"]
    assert store._read_manifest() == {"ldaspark_model_x.f-3.py311.nbi": hashlib.sha256(b"kept").hexdigest()}


# --- J: corrupt files are repaired ------------------------------------------------------------------
def test_corrupt_index_and_data_are_deleted_and_compiled_again(cdir):
    """Random bytes in the model's .nbi and .nbc: the next load compiles again (no
    UnpicklingError, the compiled engine stays) and the one after that is a cache hit."""
    import numpy as np
    src = model_source(4.5)
    load(src)
    for n in numba_files(cdir, src):
        with open(os.path.join(cdir, "__pycache__", n), "wb") as f:
            f.write(os.urandom(64))
    mod = load(src)
    assert mod.U_of(0.0, np.array([2.0])) == 9.0 and hits(mod) == (0, 1)
    assert hits(load(src)) == (1, 0)


def test_recorded_but_unreadable_index_is_rebuilt(cdir):
    """A file whose digest is recorded but which numba cannot read (a numba upgrade, a
    record made by hand) is discarded, not fatal."""
    src = model_source(5.5)
    load(src)
    store = cache._STORES[os.path.join(cdir, "ldaspark_model_" + cache.source_key(src)[:20] + ".py")]
    for n in numba_files(cdir, src):
        if n.endswith(".nbi"):
            store.write(n, b"\x80\x04not a pickle")               # recorded garbage
    assert hits(load(src)) == (0, 1)
    assert hits(load(src)) == (1, 0)


def test_recorded_data_numba_cannot_rebuild_is_compiled_again(cdir):
    """A recorded data file that unpickles but is not a compiled function (a numba upgrade that
    changed the format, a record made by hand): compiled again, the compiled engine kept."""
    src = model_source(6.25)
    load(src)
    store = cache._STORES[os.path.join(cdir, "ldaspark_model_" + cache.source_key(src)[:20] + ".py")]
    for n in numba_files(cdir, src):
        if n.endswith(".nbc"):
            store.write(n, pickle.dumps((1, 2)))
    assert hits(load(src)) == (0, 1)
    assert hits(load(src)) == (1, 0)


# --- C: never written through a link ---------------------------------------------------------------
def test_symlinked_model_file_does_not_destroy_its_target(cdir, tmp_path):
    """ln -s ~/notes.txt $LDASPARK_CACHE_DIR/ldaspark_model_<digest>.py: the link is replaced by
    the generated file; notes.txt keeps its content."""
    src = model_source(6.5)
    os.makedirs(cdir, mode=0o700)
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    path = os.path.join(cdir, "ldaspark_model_" + cache.source_key(src)[:20] + ".py")
    os.symlink(notes, path)
    load(src)
    assert notes.read_text() == "my notes\n"
    assert not os.path.islink(path) and open(path).read() == src
    # control: the old writer (follows links, as output paths do) writes into the target
    from ldaspark.core.io import atomic_write_text
    os.unlink(path)
    os.symlink(notes, path)
    atomic_write_text(path, src)
    assert notes.read_text() == src


@pytest.mark.parametrize("what", ["manifest", "lock", "nbi", "pycache"])
def test_links_planted_under_the_caches_other_names_are_not_followed(cdir, tmp_path, what):
    """The same for the record (.sha256), the lock, an index file and the __pycache__ directory."""
    src = model_source(7.5 + ["manifest", "lock", "nbi", "pycache"].index(what))
    load(src)
    modname = "ldaspark_model_" + cache.source_key(src)[:20]
    victim = tmp_path / "victim"
    victim.mkdir() if what == "pycache" else victim.write_text("keep\n")
    if what == "pycache":
        (victim / "keep.txt").write_text("keep\n")
        import shutil
        shutil.rmtree(os.path.join(cdir, "__pycache__"))
        target = os.path.join(cdir, "__pycache__")
    elif what == "nbi":
        target = os.path.join(cdir, "__pycache__", [n for n in numba_files(cdir, src) if n.endswith(".nbi")][0])
        os.unlink(target)
    else:
        target = os.path.join(cdir, modname + (".sha256" if what == "manifest" else ".lock"))
        os.unlink(target)
    os.symlink(victim, target)
    mod = load(src)
    assert hits(mod)[0] + hits(mod)[1] == 1
    if what == "pycache":
        assert os.listdir(victim) == ["keep.txt"] and (victim / "keep.txt").read_text() == "keep\n"
    else:
        assert victim.read_text() == "keep\n"
    assert not os.path.islink(target)


# --- every component of the directory's path -----------------------------------------------------------
def test_an_unsafe_ldaspark_cache_dir_is_refused_not_replaced(tmp_path, monkeypatch):
    """LDASPARK_CACHE_DIR below a directory others can write: refused with the reason, never
    silently replaced by ~/.cache/ldaspark/fast (the directory the user chose not to use); the
    compiled engine then falls back (auto) or is one error, as with an unsafe NUMBA_CACHE_DIR."""
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(loose / "c"))
    with pytest.raises(cache.CacheDirectoryError, match="LDASPARK_CACHE_DIR.*writable by other users"):
        cache.cache_dir()
    # control: a safe LDASPARK_CACHE_DIR is used, and unset the defaults are tried in order
    os.chmod(loose, 0o755)
    assert cache.cache_dir() == str(loose / "c")
    monkeypatch.setenv("LDASPARK_CACHE_DIR", "")
    assert cache.cache_dir() != str(loose / "c")


def test_a_relative_ldaspark_cache_dir_is_made_absolute(tmp_path, monkeypatch):
    """A relative LDASPARK_CACHE_DIR was returned as given: after a chdir (or in a child started in
    another directory) it named another directory."""
    os.chmod(tmp_path, 0o755)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("LDASPARK_CACHE_DIR", "rel-cache")
    d = cache.cache_dir()
    assert os.path.isabs(d) and d == str(tmp_path / "rel-cache")


def test_directory_below_a_world_writable_parent_is_refused(tmp_path):
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    ok, why = cache.secure_dir(str(loose / "c"))
    assert ok is None and "writable by other users" in why
    # control: the same below a sticky world-writable parent (as /tmp) is accepted
    os.chmod(loose, 0o1777)
    ok, why = cache.secure_dir(str(loose / "c"))
    assert ok == str(loose / "c") and why == ""


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_a_refused_directory_is_not_tightened_first(tmp_path, monkeypatch):
    """secure_dir tightened the directory to 0700 before judging its path: a 0755 directory of ours
    below a directory others can write, given directly or behind a link, was chmod-ed (through the
    link) and then refused. Now its mode is changed only once every component on the way is
    safe; control: below a safe parent the same directory, through the same link, is tightened
    and used."""
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    target = loose / "mine"
    target.mkdir()
    os.chmod(target, 0o755)
    link = tmp_path / "link"
    os.symlink(target, link)
    for d in (target, link):
        ok, why = cache.secure_dir(str(d))
        assert ok is None and "writable by other users" in why
        assert _mode(target) == 0o755
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(link))
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.cache_dir()
    assert _mode(target) == 0o755
    os.chmod(loose, 0o755)
    assert cache.cache_dir() == str(link) and _mode(target) == 0o700


@pytest.mark.skipif(not ROOT, reason="a link of another user needs root (lchown)")
def test_a_directory_behind_another_users_link_keeps_its_mode(tmp_path):
    """The attack on the fallback <tempdir>/ldaspark-fast-<uid>: another user's link there, in a
    sticky directory, to a directory of ours (0755). It was chmod-ed 0700 through that link
    before the link was refused; now it is refused untouched. Control: the same link, ours, is
    followed and its target tightened."""
    sticky = tmp_path / "tmp"
    sticky.mkdir()
    os.chmod(sticky, 0o1777)
    mine = tmp_path / "project"
    mine.mkdir()
    os.chmod(mine, 0o755)
    link = sticky / "ldaspark-fast-0"
    os.symlink(mine, link)
    os.lchown(link, OTHER_UID, OTHER_UID)
    ok, why = cache.secure_dir(str(link))
    assert ok is None and "symbolic link owned by another user" in why
    assert _mode(mine) == 0o755
    os.lchown(link, os.getuid(), os.getgid())
    assert cache.secure_dir(str(link)) == (str(link), "") and _mode(mine) == 0o700


def test_a_shared_directory_is_refused_not_made_private(tmp_path, monkeypatch):
    """LDASPARK_CACHE_DIR naming a shared directory was made 0700: a sticky 1777 one (as root,
    LDASPARK_CACHE_DIR=/tmp took /tmp's sticky bit and every other user's access) or a 0755 one
    holding other files (a home directory). Refused now, its mode untouched; controls: a loose
    directory holding only the cache's own entries (left 0777 by an earlier run), or empty, is
    tightened and used."""
    shared = tmp_path / "tmp"
    shared.mkdir()
    os.chmod(shared, 0o1777)
    (shared / "someone-elses.txt").write_text("")
    home = tmp_path / "home"
    home.mkdir()
    os.chmod(home, 0o755)
    (home / ".profile").write_text("")
    for d, mode, match in ((shared, 0o1777, "shared directory [(]sticky"),
                           (home, 0o755, "holds files that are not the cache's [(]'.profile'[)]")):
        monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
        with pytest.raises(cache.CacheDirectoryError, match=match):
            cache.cache_dir()
        assert _mode(d) == mode
    own = tmp_path / "own"
    (own / "__pycache__").mkdir(parents=True)
    for name in ("ldaspark_model_0123456789abcdef0123.py", "ldaspark_sources.sha256", "ldaspark_quasi_2_3_1.lock",
                 ".tmp-0123456789abcdef-ldaspark_sources.sha256", "checkpoint-hmac.key"):
        (own / name).write_text("")
    os.chmod(own, 0o777)
    empty = tmp_path / "empty"
    empty.mkdir()
    os.chmod(empty, 0o755)
    for d in (own, empty):
        monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
        assert cache.cache_dir() == str(d) and _mode(d) == 0o700


def test_link_to_a_private_directory_is_accepted_and_its_target_checked(tmp_path):
    real = tmp_path / "real"
    real.mkdir(mode=0o700)
    link = tmp_path / "link"
    os.symlink(real, link)
    assert cache.path_trust(str(link)) == ""
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    (loose / "real").mkdir(mode=0o700)
    link2 = tmp_path / "link2"
    os.symlink(loose / "real", link2)
    assert "writable by other users" in cache.path_trust(str(link2))
    # '..' after a link is resolved as the kernel does (from the link's target)
    assert "writable by other users" in cache.path_trust(str(link2 / ".." / "real"))


@pytest.mark.skipif(not ROOT, reason="files of another user need root (chown)")
def test_links_and_ancestors_of_another_user_are_refused(tmp_path):
    real = tmp_path / "real"
    real.mkdir(mode=0o700)
    link = tmp_path / "link"
    os.symlink(real, link)
    os.lchown(link, OTHER_UID, OTHER_UID)
    assert "symbolic link owned by another user" in cache.path_trust(str(link))
    anc = tmp_path / "anc"
    (anc / "c").mkdir(parents=True, mode=0o700)
    os.chmod(anc, 0o755)
    os.chown(anc, OTHER_UID, OTHER_UID)
    assert "belongs to another user" in cache.path_trust(str(anc / "c"))
    os.chown(anc / "c", OTHER_UID, OTHER_UID)
    os.chown(anc, 0, 0)
    assert "belongs to another user" in cache.path_trust(str(anc / "c"))
    ok, why = cache.secure_dir(str(anc / "c"))
    assert ok is None and "another user" in why


@pytest.mark.skipif(ROOT, reason="as root the chown tests above run; root's own files are trusted")
def test_ownership_checks_seen_as_another_user(tmp_path, monkeypatch):
    """Without root (no chown), the same checks from the other side: this process pretends to be
    another user, so that the real user's directories and files are another user's."""
    import shutil
    import tempfile
    monkeypatch.setattr(cache, "_uid", lambda: os.getuid() + 1)
    d = tmp_path / "c"
    d.mkdir(mode=0o700)
    assert "belongs to another user" in cache.path_trust(str(d))           # an ancestor (pytest's dir)
    top = tempfile.mkdtemp(dir="/tmp")                                      # /tmp: root's, sticky
    try:
        assert "belongs to another user" in cache.path_trust(top)          # the directory itself
        f = os.path.join(top, "f")
        with open(f, "wb") as fh:
            fh.write(b"x")
        assert cache.read_private(f) is None
    finally:
        shutil.rmtree(top)


@pytest.mark.skipif(not ROOT, reason="files of another user need root (chown)")
def test_cache_files_of_another_user_are_not_read(tmp_path):
    f = tmp_path / "f"
    f.write_bytes(b"x")
    assert cache.read_private(str(f)) == b"x"
    os.chown(f, OTHER_UID, OTHER_UID)
    assert cache.read_private(str(f)) is None


def test_read_private_never_blocks_on_a_fifo_or_follows_a_link(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert cache.read_private(str(fifo)) is None
    target = tmp_path / "t"
    target.write_bytes(b"secret")
    link = tmp_path / "l"
    os.symlink(target, link)
    assert cache.read_private(str(link)) is None
    assert cache.read_private(str(target)) == b"secret"


# --- numba's own cache of the kernels -----------------------------------------------------------------
def _fake_kernel_module(path):
    mod = types.ModuleType("fake_kernels")
    mod.k = types.SimpleNamespace(_cache=types.SimpleNamespace(cache_path=str(path)))
    return mod


def test_kernel_cache_in_a_directory_others_can_write_is_refused(tmp_path):
    shared = tmp_path / "numba-shared"
    (shared / "sub").mkdir(parents=True)
    os.chmod(shared, 0o777)
    with pytest.raises(cache.CacheDirectoryError, match="NUMBA_CACHE_DIR"):
        cache.check_kernel_cache([_fake_kernel_module(shared / "sub")])
    # control: the same tree, writable by its owner only
    os.chmod(shared, 0o755)
    cache.check_kernel_cache([_fake_kernel_module(shared / "sub")])


def test_kernel_cache_made_unsafe_after_a_first_check_is_refused(tmp_path):
    """The verdict is remembered per directory, but every call compares the lstat fingerprint of
    each component: a chmod of an ancestor or of the directory after a passing check is refused at
    the next call (control: the unchanged tree keeps passing)."""
    tree = tmp_path / "numba-cache"
    (tree / "sub").mkdir(parents=True)
    os.chmod(tree, 0o755)
    mod = _fake_kernel_module(tree / "sub")
    cache.check_kernel_cache([mod])
    cache.check_kernel_cache([mod])              # control: nothing changed, still trusted
    os.chmod(tree, 0o777)                        # an ancestor now writable by everyone
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.check_kernel_cache([mod])
    os.chmod(tree, 0o755)
    cache.check_kernel_cache([mod])
    os.chmod(tree / "sub", 0o777)                # the directory itself
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.check_kernel_cache([mod])


def test_kernel_cache_replaced_by_a_link_after_a_first_check_is_refused(tmp_path):
    """The directory swapped for a link into a directory others can write (same name, another
    inode) after a passing check: refused at the next call."""
    tree = tmp_path / "numba-cache"
    (tree / "sub").mkdir(parents=True)
    os.chmod(tree, 0o755)
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    mod = _fake_kernel_module(tree / "sub")
    cache.check_kernel_cache([mod])
    os.rename(tree / "sub", tmp_path / "old")
    os.symlink(shared, tree / "sub")
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.check_kernel_cache([mod])


def test_kernel_cache_checks_again_in_full_when_anything_changed(tmp_path, monkeypatch):
    """Unchanged: the remembered verdict, no new walk of the path; a file added to the directory
    (its mtime) or a component's mode changed: ``path_trust`` runs again."""
    tree = tmp_path / "numba-cache"
    (tree / "sub").mkdir(parents=True)
    os.chmod(tree, 0o755)
    mod = _fake_kernel_module(tree / "sub")
    cache.check_kernel_cache([mod])
    calls = []
    real = cache.path_trust
    monkeypatch.setattr(cache, "path_trust", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    cache.check_kernel_cache([mod])
    assert calls == []
    (tree / "sub" / "kernels.run-1.py311.nbi").write_bytes(b"x")
    cache.check_kernel_cache([mod])
    assert calls == [str(tree / "sub")]
    cache.check_kernel_cache([mod])
    assert len(calls) == 1
    os.chmod(tree, 0o750)
    cache.check_kernel_cache([mod])
    assert len(calls) == 2


def test_kernel_cache_not_yet_created_is_judged_by_its_parent_until_it_exists(tmp_path):
    """numba creates the directory at its first save: until then its parent decides; once it
    exists (here: writable by everyone) the directory itself is judged."""
    tree = tmp_path / "numba-cache"
    tree.mkdir()
    os.chmod(tree, 0o755)
    mod = _fake_kernel_module(tree / "sub")
    cache.check_kernel_cache([mod])
    (tree / "sub").mkdir()
    os.chmod(tree / "sub", 0o777)
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.check_kernel_cache([mod])


def test_kernel_paths_are_collected_again_under_another_numba_cache_dir(tmp_path, monkeypatch):
    """The kernel modules' cache paths are collected once per NUMBA_CACHE_DIR setting: dispatchers
    made again under another setting (here: the fake dispatcher's path moved to a directory others
    can write) are checked there."""
    from numba.core import config
    safe, shared = tmp_path / "safe", tmp_path / "shared"
    safe.mkdir()
    shared.mkdir()
    os.chmod(tmp_path, 0o755)
    os.chmod(shared, 0o777)
    mod = _fake_kernel_module(safe)
    cache.check_kernel_cache([mod])
    mod.k._cache.cache_path = str(shared)
    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path))
    with pytest.raises(cache.CacheDirectoryError, match="writable by other users"):
        cache.check_kernel_cache([mod])


def test_integrate_refuses_the_compiled_engine_once_its_kernel_cache_is_made_unsafe(tmp_path, monkeypatch):
    """Through ``ldaspark.integrate``: a first compiled run passes the check; the kernel cache
    directory made writable by everyone afterwards: engine='compiled' is refused naming it, 'auto'
    falls back to the generic engine (the kernels' paths pointed at a test directory)."""
    import ldaspark
    from ldaspark.core.errors import InputError
    tree = tmp_path / "numba-cache"
    (tree / "sub").mkdir(parents=True)
    os.chmod(tree, 0o755)
    monkeypatch.setattr(cache, "_kernel_paths", lambda modules: [str(tree / "sub")])
    run = dict(h=0.1, n_steps=3)
    first = ldaspark.integrate("particle", "gauss-2", engine="compiled", **run)
    assert first.status == 0 and first.engine == "compiled"
    assert ldaspark.integrate("particle", "gauss-2", engine="compiled", **run).engine == "compiled"
    os.chmod(tree / "sub", 0o777)
    for newton in ("auto", "quasi"):
        with pytest.raises(InputError, match="not safe"):
            ldaspark.integrate("particle", "gauss-2", engine="compiled", newton=newton, **run)
    fallback = ldaspark.integrate("particle", "gauss-2", **run)
    assert fallback.engine == "generic"
    os.chmod(tree / "sub", 0o755)
    assert ldaspark.integrate("particle", "gauss-2", engine="compiled", **run).engine == "compiled"


@pytest.mark.skipif(not ROOT, reason="chown needs root")
def test_kernel_cache_given_to_another_user_after_a_first_check_is_refused(tmp_path):
    tree = tmp_path / "numba-cache"
    (tree / "sub").mkdir(parents=True)
    os.chmod(tree, 0o755)
    mod = _fake_kernel_module(tree / "sub")
    cache.check_kernel_cache([mod])
    os.chown(tree, OTHER_UID, OTHER_UID)
    with pytest.raises(cache.CacheDirectoryError, match="belongs to another user"):
        cache.check_kernel_cache([mod])


# --- what held keeps holding ---------------------------------------------------------------------------
def test_record_format_is_sha256sum(cdir):
    """The record beside each module is `sha256sum -c` input: one '<digest>  <name>' line per file."""
    src = model_source(9.5)
    load(src)
    modname = "ldaspark_model_" + cache.source_key(src)[:20]
    lines = open(os.path.join(cdir, modname + ".sha256")).read().splitlines()
    assert lines and len(lines) == len(numba_files(cdir, src))
    for ln in lines:
        digest, name = ln.split("  ")
        with open(os.path.join(cdir, "__pycache__", name), "rb") as f:
            assert hashlib.sha256(f.read()).hexdigest() == digest


# --- end to end, in real processes (last: the checks above fail first under a mutant) ------------


def test_issue_reproducer_cli_particle_with_planted_index(tmp_path):
    """`ldaspark integrate particle gauss-2` with a 0777 LDASPARK_CACHE_DIR holding a planted
    __pycache__/ldaspark_model_<digest>.*.nbi (the digest of a built-in scene is the same on
    every install): the payload never runs and the run is compiled."""
    from ldaspark.compiled.fast import compile_system
    from ldaspark.models.scenes import get_scene
    cs = compile_system(get_scene("particle").system)
    modname = "ldaspark_model_" + cs.key
    lines = cs.source.splitlines()
    tag = f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"
    # numba names a function's index <module>.<function>-<first line of its decorator>.<tag>.nbi
    names = [f"{modname}.{lines[i + 1].split('(')[0][4:]}-{i + 1}.{tag}.nbi"
             for i, ln in enumerate(lines) if ln.startswith("@_jit")]
    assert len(names) == 7
    d = tmp_path / "shared"
    (d / "__pycache__").mkdir(parents=True)
    os.chmod(d, 0o777)
    os.chmod(d / "__pycache__", 0o777)
    marker = tmp_path / "executed"
    for n in names:
        (d / "__pycache__" / n).write_bytes(payload_bytes(marker))
    env = dict(os.environ, LDASPARK_CACHE_DIR=str(d), PYTHONPATH=PYPATH)
    out = tmp_path / "r.json"
    p = subprocess.run([sys.executable, "-m", "ldaspark", "integrate", "particle", "gauss-2", "--h", "0.1",
                        "--t-end", "1", "--out", str(out), "--engine", "compiled"],
                       env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert "(compiled)" in p.stdout and "Traceback" not in p.stderr
    assert not marker.exists()
    # the planted names are the ones numba reads: each now holds this process's recorded index
    recorded = cache.TrustedStore(str(d), modname, cs.digest)._read_manifest()
    for n in names:
        raw = (d / "__pycache__" / n).read_bytes()
        assert recorded[n] == hashlib.sha256(raw).hexdigest()



def test_cli_runs_compiled_after_the_model_cache_is_corrupted(tmp_path, monkeypatch):
    """Tampered cache end to end: random bytes in every .nbi/.nbc of the particle's model; the next
    run is compiled (before: 'compilation failed (UnpicklingError); using the generic engine' on
    every later run) and leaves a cache the run after it loads (all hits)."""
    from ldaspark.compiled.fast import compile_system
    from ldaspark.models.scenes import get_scene
    d = tmp_path / "c"
    monkeypatch.setenv("LDASPARK_CACHE_DIR", str(d))
    src = compile_system(get_scene("particle").system).source
    load(src)
    files = numba_files(str(d), src)
    assert len(files) == 14                                   # 7 functions: index + data each
    for f in files:
        (d / "__pycache__" / f).write_bytes(os.urandom(100))
    env = dict(os.environ, LDASPARK_CACHE_DIR=str(d), PYTHONPATH=PYPATH)
    cmd = [sys.executable, "-m", "ldaspark", "integrate", "particle", "gauss-2", "--h", "0.1", "--t-end", "1",
           "--out", str(tmp_path / "r.json")]
    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0 and "(compiled)" in p.stdout, p.stdout + p.stderr
    assert "using the generic engine" not in p.stderr
    mod = load(src)
    assert all(sum(getattr(mod, f).stats.cache_hits.values()) == 1 for f in ("U_of", "grad_U", "hess_U", "K_of",
                                                                              "b_of", "kq_of", "KTlam_q"))



def test_numba_cache_dir_writable_by_others_falls_back_with_the_reason(tmp_path):
    """NUMBA_CACHE_DIR a 0777 directory: engine auto runs generic with a one-line notice naming the
    reason; engine compiled is one error line, exit 2 (one process runs both)."""
    shared = tmp_path / "numba-shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(shared), LDASPARK_CACHE_DIR=str(tmp_path / "c"),
               PYTHONPATH=PYPATH)
    out = str(tmp_path / "r.json")
    code = ("import sys, ldaspark\n"
            "from ldaspark.cli import main\n"
            "r = ldaspark.integrate('particle', 'gauss-2', t_span=(0, 1), h=0.1)\n"
            "assert r.engine == 'generic' and r.status == 0\n"
            f"sys.exit(main(['integrate', 'particle', 'gauss-2', '--h', '0.1', '--t-end', '1', '--out', {out!r},"
            " '--engine', 'compiled']))\n")
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    err = p.stderr.splitlines()
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert len(err) == 2
    assert "numba would load the compiled kernels from" in err[0] and "using the generic engine" in err[0]
    assert err[1].startswith("ldaspark: error: engine 'compiled' cannot run this") and "NUMBA_CACHE_DIR" in err[1]



def test_a_failed_lock_open_keeps_the_lock_file_and_releases_the_thread_lock(tmp_path, monkeypatch):
    """_FileLock removed the lock file after any failed open (meant for a planted link) and
    created a new one: an open failing for itself (EMFILE: out of descriptors; ENOSPC) unlinked the
    file another process held locked, and the opener locked a new inode beside it (both in the
    critical section). And an exception from the open left the process-wide thread lock held: every
    other thread's cache access then waited for good. Now only what is not a regular file is
    removed, the error is raised and the thread lock released; control: a link planted under the
    lock's name is still replaced, never followed."""
    import errno
    path = str(tmp_path / "m.lock")
    with cache._FileLock(path):
        pass
    ino = os.lstat(path).st_ino
    real_open = os.open
    failed = []

    def open_out_of_descriptors(p, *a, **k):
        if p == path and not failed:
            failed.append(p)
            raise OSError(errno.EMFILE, "Too many open files")
        return real_open(p, *a, **k)
    monkeypatch.setattr(os, "open", open_out_of_descriptors)
    try:
        with pytest.raises(OSError, match="Too many open files"):
            with cache._FileLock(path):
                pass
    finally:
        monkeypatch.setattr(os, "open", real_open)
    assert failed and os.lstat(path).st_ino == ino              # the held file was not replaced
    assert not cache._FileLock._threads._is_owned()

    def open_disk_full(p, *a, **k):                             # every open of it fails
        if p == path:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_open(p, *a, **k)
    monkeypatch.setattr(os, "open", open_disk_full)
    try:
        with pytest.raises(OSError, match="No space left"):
            with cache._FileLock(path):
                pass
        owned = cache._FileLock._threads._is_owned()
    finally:
        monkeypatch.setattr(os, "open", real_open)
        while cache._FileLock._threads._is_owned():            # (before the fix: left held)
            cache._FileLock._threads.release()
    assert not owned and os.lstat(path).st_ino == ino
    target = tmp_path / "target"
    target.write_text("keep")
    os.unlink(path)
    os.symlink(target, path)
    with cache._FileLock(path):
        pass
    assert not os.path.islink(path) and target.read_text() == "keep"
    assert not cache._FileLock._threads._is_owned()


@pytest.mark.skipif(not ROOT, reason="a lock file of another user needs root (chown)")
def test_a_lock_file_of_another_user_is_replaced_not_locked(tmp_path):
    """A lock file another user left under the cache's lock name (while the directory was open to
    others, before it was tightened) was opened and flock-ed as it was: its owner, holding it open
    with its lock, would keep every cache access of this user waiting for good. It is replaced by
    this user's own file; control: this user's lock file is kept (same inode)."""
    import fcntl
    path = tmp_path / "m.lock"
    path.write_bytes(b"")
    os.chmod(path, 0o666)
    os.chown(path, OTHER_UID, OTHER_UID)
    theirs = os.open(path, os.O_RDWR)                    # the other user's descriptor
    try:
        with cache._FileLock(str(path)):
            st = os.lstat(path)
            assert st.st_uid == os.getuid() and stat.S_ISREG(st.st_mode)
            # their descriptor no longer shares this lock (before: it was refused here, and had
            # they taken it first, this process would have waited for them)
            fcntl.flock(theirs, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(theirs)
    ino = os.lstat(path).st_ino
    with cache._FileLock(str(path)):
        pass
    assert os.lstat(path).st_ino == ino
    assert not cache._FileLock._threads._is_owned()


def test_temporary_files_of_a_killed_writer_are_removed_at_the_next_load(cdir):
    """A process killed between creating its temporary file and os.replace left
    ``.tmp-<hex>-<name>`` behind for good (two such files after eight kill -9 of numba-path runs).
    The next load of the module removes those of its numba files and its record, written under
    its lock (so no live writer owns them); controls: another module's and the module file's
    (written without that lock) are kept, and the recorded cache is still loaded."""
    import pathlib
    src = model_source(5.5)
    load(src)
    modname = "ldaspark_model_" + cache.source_key(src)[:20]
    d = pathlib.Path(cdir)
    pyc = d / "__pycache__"
    name = numba_files(cdir, src)[0]
    orphans = [pyc / f".tmp-0123456789abcdef-{name}", d / f".tmp-fedcba9876543210-{modname}.sha256"]
    kept = [pyc / f".tmp-0123456789abcdef-ldaspark_model_{'0' * 20}.U_of-5.py311.nbi",
            d / f".tmp-0123456789abcdef-{modname}.py"]
    for p in orphans + kept:
        p.write_bytes(b"partial")
    mod = load(src)
    assert [p.name for p in orphans if p.exists()] == []
    assert all(p.exists() for p in kept)
    assert hits(mod) == (1, 0)


def test_temporary_files_of_a_killed_source_writer_are_removed_at_the_next_store(cdir):
    """The same for the store of generated sources (``store_source``, never swept): a writer killed
    before os.replace left its temporary source or record for good; the next source stored removes
    them; controls: a model store's temporary is kept, both stored sources are served."""
    import pathlib
    cache.store_source("a" * 64, "X = 1\n")
    d = pathlib.Path(cdir)
    pyc = d / "__pycache__"
    orphans = [pyc / f".tmp-0123456789abcdef-ldaspark_sources.{'b' * 64}.py",
               d / ".tmp-fedcba9876543210-ldaspark_sources.sha256"]
    kept = pyc / f".tmp-0123456789abcdef-ldaspark_model_{'0' * 20}.U_of-5.py311.nbi"
    for p in orphans + [kept]:
        p.write_bytes(b"partial")
    cache.store_source("c" * 64, "X = 2\n")
    assert [p.name for p in orphans if p.exists()] == [] and kept.exists()
    assert cache.stored_source("a" * 64) == "X = 1\n" and cache.stored_source("c" * 64) == "X = 2\n"


def test_a_model_file_written_meanwhile_by_another_loader_is_not_unlinked(cdir, monkeypatch):
    """Two loaders of one new source (threads here, processes alike): B finds no file, A writes it,
    B unlinked it (as a stale entry) before rewriting, and A's read-back found nothing:
    CacheDirectoryError "does not hold the source just written" (engine compiled: an error; auto:
    the generic engine). The interleaving is forced by events on the cache's own file calls.
    Now a regular file is replaced atomically, never unlinked first, and both load the module."""
    import threading
    src = model_source(7.125)
    path = os.path.join(cdir, "ldaspark_model_" + cache.source_key(src)[:20] + ".py")
    cache._MODULES.pop(cache.source_key(src), None)
    ev = {k: threading.Event() for k in ("b_read", "a_wrote", "b_acted", "a_checked")}
    W = 120                                  # a bound on each wait (never reached when the order holds)
    reads = {"A": 0, "B": 0}
    real_read, real_write, real_remove = cache.read_private, cache.write_private, cache.remove_entry

    def who(p):
        me = threading.current_thread().name
        return me if p == path and me in reads else None

    def read(p, *a, **k):
        me = who(p)
        out = real_read(p, *a, **k)
        if me:
            reads[me] += 1
            if me == "B" and reads["B"] == 1:          # B looked: no file yet
                ev["b_read"].set()
                ev["a_wrote"].wait(W)
            if me == "A" and reads["A"] == 2:          # A's read-back
                ev["a_checked"].set()
        return out

    def write(p, *a, **k):
        me = who(p)
        if me == "A":
            ev["b_read"].wait(W)
            real_write(p, *a, **k)
            ev["a_wrote"].set()
            ev["b_acted"].wait(W)
            return None
        if me == "B":
            ev["b_acted"].set()
            ev["a_checked"].wait(W)
        return real_write(p, *a, **k)

    def remove(p):
        me = who(p)
        real_remove(p)
        if me == "B":
            ev["b_acted"].set()
            ev["a_checked"].wait(W)

    monkeypatch.setattr(cache, "read_private", read)
    monkeypatch.setattr(cache, "write_private", write)
    monkeypatch.setattr(cache, "remove_entry", remove)
    out = {}

    def run(name):
        try:
            out[name] = cache.load_source(src)
        except Exception as exc:             # noqa: BLE001 - recorded and asserted below
            out[name] = exc
    threads = [threading.Thread(target=run, args=(n,), name=n) for n in ("A", "B")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(e.is_set() for e in ev.values())            # the interleaving happened as described
    assert not any(isinstance(m, Exception) for m in out.values()), out
    assert out["A"].U_of(0.0, __import__("numpy").array([2.0])) == 14.25
    with open(path, "rb") as f:
        assert f.read() == src.encode()


def test_two_processes_compiling_one_new_system_agree_bit_for_bit(tmp_path):
    """Two processes compile the same new system into one empty cache at once: both succeed with
    the same numbers, and every file left in the cache is recorded (the next load uses it)."""
    d = tmp_path / "c"
    code = ("import sys, sympy, numpy as np, ldaspark\n"
            "x, y, z, vx, vy, vz = sympy.symbols('x y z vx vy vz')\n"
            "s = ldaspark.LagrangianSystem((vx**2 + vy**2 + vz**2)/2 - x**4/7 - y**2/3, [vz - x*vy],"
            " [x, y, z], [vx, vy, vz], name='twin')\n"
            "r = ldaspark.integrate(s, 'gauss-2', t_span=(0, 1), q0=[0.1, 0.2, 0.3], v0=[0.4, 0.5, 0.05],"
            " h=0.05, engine='compiled')\n"
            "print(r.q[-1].tobytes().hex(), r.v[-1].tobytes().hex())\n")
    env = dict(os.environ, LDASPARK_CACHE_DIR=str(d), PYTHONPATH=PYPATH)
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    assert outs[0][0] == outs[1][0] and outs[0][0].strip()
    for man in d.glob("ldaspark_model_*.sha256"):
        modname = man.name[: -len(".sha256")]
        store = cache.TrustedStore(str(d), modname, "")
        assert store.sweep() == []                             # nothing unrecorded or stale
        assert set(store._read_manifest()) == {n for n in os.listdir(d / "__pycache__")
                                               if n.startswith(modname + ".")}


def test_a_kernel_cache_file_others_can_write_is_refused(tmp_path):
    """A safe directory keeps others from adding files, not from rewriting a file they may write:
    an .nbi owned by another user or writable by others (mode 0666) was unpickled. Refused now,
    and so is a link in its place; control: the same file, 0644 and ours, passes."""
    d = tmp_path / "numba-cache" / "sub"
    d.mkdir(parents=True)
    os.chmod(d.parent, 0o755)
    os.chmod(d, 0o755)
    f = d / "kernels.spark_run-10.py311.nbi"
    f.write_bytes(b"index")
    os.chmod(f, 0o666)
    mod = _fake_kernel_module(d)
    with pytest.raises(cache.CacheDirectoryError, match="nbi is writable by other users"):
        cache.check_kernel_cache([mod])
    os.chmod(f, 0o644)
    cache.check_kernel_cache([mod])
    link = d / "kernels.spark_run-10.py311.1.nbc"
    os.symlink(f, link)
    with pytest.raises(cache.CacheDirectoryError, match="not a regular file"):
        cache.check_kernel_cache([mod])
    link.unlink()
    if os.geteuid() == 0:                         # as root: a file of another user
        os.chown(f, 65534, 65534)
        with pytest.raises(cache.CacheDirectoryError, match="belongs to another user"):
            cache.check_kernel_cache([mod])
