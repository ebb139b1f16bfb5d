"""The trusted on-disk cache of the generated model modules and of numba's compiled code for them.

Trust model (docs/reliability.md, "The kernel cache: what is trusted"): the only files loaded
are files that a process of this user wrote into a directory that only this user can write.

* Directory: ``$LDASPARK_CACHE_DIR`` (when set, the only one: an unsafe one is a
  CacheDirectoryError, never replaced by another), else ``~/.cache/ldaspark/fast``, else
  ``<tempdir>/ldaspark-fast-<uid>``. Used only when every component of its path is safe
  (``path_trust``): each ancestor a directory owned by this user or root that nobody else can
  write (or sticky, as /tmp), each symbolic link on the way owned by this user or root, and the
  directory itself owned by this user with mode 0700 (a looser mode is tightened once the rest of
  the path is found safe, and only when the directory holds nothing but the cache's own entries:
  a shared one, sticky as /tmp or holding other files, is refused, never made private). A
  directory of another user, or below a directory another user can write, is skipped.
* The model module ``ldaspark_model_<digest>.py``: the file name carries the sha256 of the
  source the caller expects; the *expected* source text is what gets compiled and executed
  (never the file's content); the file is rewritten when its content differs.
* numba's cache of the model functions (``__pycache__/<module>.<function>-<line>.py311.nbi`` and
  ``.nbc``, pickles) goes through ``TrustedStore``: every index and data file numba writes is
  recorded (sha256, in ``<module>.sha256`` beside the module, ``sha256sum -c`` format) and a
  file is unpickled only if its bytes, read once through a descriptor opened without following
  links and owned by this user, have the recorded digest. Anything else under the module's
  name (planted, corrupt, truncated, written by another process of a different library version)
  is deleted and compiled again, so that a corrupt file costs one recompilation, not the
  compiled engine. ``NUMBA_CACHE_DIR`` and ``NUMBA_CACHE_LOCATOR_CLASSES`` do not move these
  files: ``model_jit`` gives each model function this cache directly.
* Writes never follow a link: a temporary file created with O_EXCL | O_NOFOLLOW in the same
  directory, fsync, then ``os.replace``, which replaces a planted symlink itself, not its target.
* numba's cache of the kernels (``kernels.py`` and its helpers, compiled once for every system)
  is numba's own, in the package's ``__pycache__`` or ``NUMBA_CACHE_DIR`` or numba's per-user
  directory; ``check_kernel_cache`` refuses the compiled engine when that directory is writable
  by another user (it would load pickles from it).
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import os
import pickle
import re
import stat
import sys
import tempfile
import threading
import types
import uuid

from ..core.errors import LdasparkError
from ..core.gensource import SOURCE_LOCK


class CacheDirectoryError(LdasparkError):
    """No safe, writable directory for the generated modules."""


#: largest cache file read (numba's data files for the largest generated models are ~1 MB)
MAX_CACHE_FILE = 256 * 2 ** 20
#: symbolic links followed while checking one path (the kernel's own limit is 40)
MAX_LINK_HOPS = 40
_SAFE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,250}$")
_MANIFEST_LINE = re.compile(r"^([0-9a-f]{64})  ([A-Za-z0-9_][A-Za-z0-9_.\-]{0,250})$")
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


def _uid():
    return os.getuid() if hasattr(os, "getuid") else None


def _candidates():
    uid = _uid()
    env = os.environ.get("LDASPARK_CACHE_DIR")
    yield env
    yield os.path.join(os.path.expanduser("~"), ".cache", "ldaspark", "fast")
    yield os.path.join(tempfile.gettempdir(), f"ldaspark-fast-{uid if uid is not None else os.getlogin()}")


# --- path trust ---------------------------------------------------------------------------------
def _trusted_owner(st) -> bool:
    """Owned by this user or by root (who can replace anything anyway)."""
    uid = _uid()
    return uid is None or st.st_uid in (uid, 0)


def path_trust(path: str, final_private: bool = True, walked: list | None = None, final_mode: bool = True) -> str:
    """"" when every component of ``path`` is safe, else the reason it is not.

    Safe: each ancestor directory owned by this user or root and not writable by group or others
    unless it is sticky (/tmp: others cannot rename or delete our entries there); each symbolic
    link on the way owned by this user or root (a link another user owns can be pointed
    elsewhere by them); the final component a directory owned by this user and not accessible
    to anyone else, or, without ``final_private``, owned by this user or root and not writable
    by anyone else. Links are followed (at most MAX_LINK_HOPS),
    the components of their targets checked the same way. ``walked``: a list that receives
    (component, its lstat) of every component looked at, in order (what the verdict depends on:
    ``check_kernel_cache`` compares them again at every call). ``final_mode`` False: the final
    directory's mode is not judged (``secure_dir`` tightens it, once the rest is found safe)."""
    uid = _uid()
    path = os.fspath(path)
    todo = path.split(os.sep) if os.path.isabs(path) else os.getcwd().split(os.sep) + path.split(os.sep)
    cur, hops = os.sep, 0
    while True:
        while todo and todo[0] in ("", ".", ".."):       # '..' of a checked, link-free prefix
            if todo.pop(0) == "..":
                cur = os.path.dirname(cur)
        if not todo:
            break
        nxt = os.path.join(cur, todo.pop(0))
        try:
            st = os.lstat(nxt)
        except OSError as exc:
            return f"{nxt}: {exc.strerror or exc}"
        if walked is not None:
            walked.append((nxt, st))
        if stat.S_ISLNK(st.st_mode):
            if not _trusted_owner(st):
                return f"{nxt} is a symbolic link owned by another user (uid {st.st_uid})"
            hops += 1
            if hops > MAX_LINK_HOPS:
                return f"{path}: too many levels of symbolic links"
            target = os.readlink(nxt)
            if os.path.isabs(target):
                cur = os.sep
            todo = target.split(os.sep) + todo
            continue
        if not stat.S_ISDIR(st.st_mode):
            return f"{nxt} is not a directory"
        if any(c not in ("", ".", "..") for c in todo):  # an ancestor
            if not _trusted_owner(st):
                return f"{nxt} belongs to another user (uid {st.st_uid}), who could replace what is below it"
            if st.st_mode & 0o022 and not st.st_mode & stat.S_ISVTX:
                return f"{nxt} is writable by other users (and not sticky), who could replace what is below it"
        cur = nxt
    try:
        st = os.lstat(cur)                                # cur is free of links
    except OSError as exc:
        return f"{cur}: {exc.strerror or exc}"
    if walked is not None:
        if walked and walked[-1][0] == cur:
            walked.pop()                                  # looked at again: its newer lstat
        walked.append((cur, st))
    if not final_private:                                # a shared read-only place (an installed package)
        if not _trusted_owner(st):
            return f"{cur} belongs to another user (uid {st.st_uid})"
        if st.st_mode & 0o022:
            return f"{cur} is writable by other users"
        return ""
    if uid is not None and st.st_uid != uid:
        return f"{cur} belongs to another user (uid {st.st_uid})"
    if final_mode and st.st_mode & 0o077:
        return f"{cur} is accessible to other users"
    return ""


def secure_dir(d: str) -> tuple[str | None, str]:
    """(d, "") once d is made and checked as a private directory (mode 0700, owner = this user,
    every component of its path safe: ``path_trust``), else (None, reason)."""
    try:
        os.makedirs(d, mode=0o700, exist_ok=True)
        st = os.stat(d)
        if not stat.S_ISDIR(st.st_mode):
            return None, f"{d} is not a directory"
        if _uid() is not None and st.st_uid != _uid():
            return None, f"{d} belongs to another user (uid {st.st_uid})"
        if st.st_mode & 0o077:
            # tightened only once every component on the way is safe, and by its resolved,
            # link-free path: a directory behind another user's link, or below a directory others
            # can write, was chmod-ed 0700 and then refused
            walked: list = []
            why = path_trust(d, walked=walked, final_mode=False)
            if why:
                return None, why
            why = _not_the_caches_own(walked[-1][0], st)
            if why:
                return None, why
            os.chmod(walked[-1][0], 0o700)
        why = path_trust(d)
        if why:
            return None, why
        if not os.access(d, os.W_OK | os.X_OK):
            return None, f"{d} is not writable"
        return d, ""
    except OSError as exc:
        return None, f"{d}: {exc.strerror or exc}"


#: names the cache writes into its directory (model, ODE and specialised modules, their records and
#: locks, the stored sources, numba's __pycache__, temporary files, entries renamed aside) and the
#: checkpoints' key kept there (``lab.checkpoint.checkpoint_key``, and its temporary file)
_OWN_ENTRY = re.compile(r"^(ldaspark_[A-Za-z0-9_.\-]*|__pycache__|\.tmp-[0-9a-f]{16}-.*|\.untrusted-[0-9a-f]{32}"
                        r"|checkpoint-hmac\.key|\.checkpoint-hmac\.key\.[0-9a-f]+)$")


def _not_the_caches_own(d: str, st) -> str:
    """"" when the loose directory ``d`` (its stat ``st``) may be made private: it holds nothing but
    the cache's own entries. A sticky directory (/tmp) or one with other files is shared: making it
    0700 would lock its other users out (LDASPARK_CACHE_DIR=/tmp as root took /tmp's sticky bit and
    everyone's access), so it is refused instead."""
    if st.st_mode & stat.S_ISVTX:
        return (f"{d} is a shared directory (sticky, mode {stat.S_IMODE(st.st_mode):o}), not made private; "
                "use a directory of its own below it")
    other = sorted(n for n in os.listdir(d) if not _OWN_ENTRY.match(n))
    if other:
        shown = ", ".join(repr(n[:40]) for n in other[:3])
        return (f"{d} is accessible to other users and holds files that are not the cache's ({shown}"
                f"{', ...' if len(other) > 3 else ''}), not made private; use a directory of its own")
    return ""


def cache_dir() -> str:
    """The first usable private cache directory; raises CacheDirectoryError with every reason."""
    why = []
    for d in _candidates():
        if not d:
            continue
        ok, reason = secure_dir(d)
        if ok:
            # absolute: a relative LDASPARK_CACHE_DIR would name another directory after a chdir
            # (and in a child started elsewhere)
            return os.path.abspath(ok)
        if d == os.environ.get("LDASPARK_CACHE_DIR"):
            # the directory the user chose: refused with its reason, never silently swapped for
            # ~/.cache (as an unsafe NUMBA_CACHE_DIR refuses the compiled engine)
            raise CacheDirectoryError(f"LDASPARK_CACHE_DIR={d} is not a safe cache directory for the compiled "
                                      f"models ({reason}); point it at a directory only you can write, or unset it")
        why.append(reason)
    raise CacheDirectoryError("no private writable cache directory for the compiled models: " + "; ".join(why))


def source_key(source: str) -> str:
    return hashlib.sha256(source.encode()).hexdigest()


# --- files that are never followed through a link -----------------------------------------------
def read_private(path: str, limit: int = MAX_CACHE_FILE) -> bytes | None:
    """The bytes of ``path`` if it is a regular file owned by this user (opened without following
    a link, without blocking on a FIFO), at most ``limit`` bytes; None otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | _CLOEXEC | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
            return None
        if _uid() is not None and st.st_uid != _uid():
            return None
        chunks, n = [], 0
        while True:
            b = os.read(fd, 1 << 20)
            if not b:
                break
            n += len(b)
            if n > limit:
                return None
            chunks.append(b)
        return b"".join(chunks)
    except OSError:
        return None
    finally:
        os.close(fd)


def write_private(path: str, data: bytes, mode: int = 0o600) -> None:
    """Atomically replace ``path`` with ``data``: a new temporary file in the same directory
    (O_CREAT | O_EXCL | O_NOFOLLOW: never an existing file or a link), fsync, ``os.replace``
    (which replaces a link at ``path`` itself, never what it points to)."""
    d = os.path.dirname(path)
    tmp = os.path.join(d, f".tmp-{uuid.uuid4().hex[:16]}-{os.path.basename(path)[:100]}")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, mode)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def remove_entry(path: str) -> None:
    """Remove whatever is at ``path`` (a file, a link, a FIFO, or a directory tree planted there)
    without following links; a directory that cannot be emptied (another user's) is renamed
    aside under a hidden name, where nothing looks."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISDIR(st.st_mode):
        import shutil
        shutil.rmtree(path, ignore_errors=True)
        if os.path.lexists(path):
            os.replace(path, os.path.join(os.path.dirname(path), f".untrusted-{uuid.uuid4().hex}"))
    else:
        os.unlink(path)


def private_subdir(parent: str, name: str) -> str:
    """``parent/name`` as a real directory of this user with mode 0700; whatever else is there
    (a link, a file, another user's directory) is removed first. ``parent`` is trusted."""
    path = os.path.join(parent, name)
    for _ in range(3):
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            pass
        st = os.lstat(path)
        if stat.S_ISDIR(st.st_mode) and (_uid() is None or st.st_uid == _uid()):
            if st.st_mode & 0o077:
                os.chmod(path, 0o700)
            return path
        remove_entry(path)
    raise CacheDirectoryError(f"{path} cannot be made a private directory")


class _FileLock:
    """An exclusive lock between threads and processes (flock on a file in the trusted directory)."""

    _threads = threading.RLock()

    def __init__(self, path):
        self.path = path

    def __enter__(self):
        self._threads.acquire()
        try:
            self.fd = self._open()
        except BaseException:                # no lock taken: the thread lock must not stay held
            self._threads.release()
            raise
        try:
            import fcntl
            fcntl.flock(self.fd, fcntl.LOCK_EX)
        except ImportError:                  # no flock (Windows): the thread lock only
            pass
        except BaseException:
            os.close(self.fd)
            self._threads.release()
            raise
        return self

    def _open(self) -> int:
        flags = os.O_RDWR | os.O_CREAT | _NOFOLLOW | _CLOEXEC
        mine = lambda st: _uid() is None or st.st_uid == _uid()     # noqa: E731
        try:
            fd = os.open(self.path, flags, 0o600)
        except OSError as exc:
            # only what is not this user's regular file (a link: ELOOP, a directory: EISDIR,
            # another user's file) is removed: an error of the open itself (EMFILE, ENOSPC, ...)
            # removed the lock file another process may hold, and the next opener locked a new
            # inode beside it
            try:
                st = os.lstat(self.path)
            except OSError:
                raise exc from None
            if stat.S_ISREG(st.st_mode) and mine(st):
                raise
        else:
            if mine(os.fstat(fd)):
                return fd
            # another user's file (planted while the directory was open to others): its owner,
            # holding it open, could keep its lock for good and every cache access would wait
            os.close(fd)
        remove_entry(self.path)
        return os.open(self.path, flags | os.O_EXCL, 0o600)

    def __exit__(self, *exc):
        os.close(self.fd)
        self._threads.release()
        return False


# --- the store of one model module ----------------------------------------------------------------
class TrustedStore:
    """The files of one generated module ``<dir>/<modname>.py``: numba's index and data files in
    ``<dir>/__pycache__`` named ``<modname>.*``, the record of their digests ``<dir>/<modname>.sha256``
    and its lock. Only files whose digest was recorded when this user's process wrote them are
    read; every other file under the module's name is deleted (``sweep``, ``read``)."""

    def __init__(self, directory: str, modname: str, source_digest: str):
        self.dir = directory
        self.modname = modname
        self.source_digest = source_digest
        self.numba_dir = private_subdir(directory, "__pycache__")
        self.manifest = os.path.join(directory, modname + ".sha256")
        self.lock = _FileLock(os.path.join(directory, modname + ".lock"))

    def _owns(self, name: str) -> bool:
        return name.startswith(self.modname + ".") and bool(_SAFE_NAME.match(name))

    def _read_manifest(self) -> dict:
        raw = read_private(self.manifest, limit=2 ** 20)
        out = {}
        for line in (raw or b"").decode("ascii", "replace").splitlines():
            m = _MANIFEST_LINE.match(line)
            if m and self._owns(m.group(2)):
                out[m.group(2)] = m.group(1)
        return out

    def _write_manifest(self, entries: dict) -> None:
        text = "".join(f"{d}  {n}\n" for n, d in sorted(entries.items()))
        write_private(self.manifest, text.encode("ascii"))

    def sweep(self) -> list:
        """Delete every entry of ``__pycache__`` under this module's name whose content is not
        the one recorded (planted, corrupt, unrecorded), and the temporary files of writers of
        this store that died before their ``os.replace`` (killed mid-write: nothing else removes
        them); returns the names deleted."""
        gone = []
        with self.lock:
            rec = self._read_manifest()
            gone += self._remove_orphans()
            try:
                names = os.listdir(self.numba_dir)
            except OSError:
                return gone
            for name in names:
                if not name.startswith(self.modname + "."):
                    continue
                path = os.path.join(self.numba_dir, name)
                raw = read_private(path) if name in rec else None
                if raw is None or hashlib.sha256(raw).hexdigest() != rec[name]:
                    remove_entry(path)
                    gone.append(name)
            if len(rec) != len(set(rec) - set(gone)):
                self._write_manifest({n: d for n, d in rec.items() if n not in gone})
        return gone

    def _remove_orphans(self) -> list:
        """Under the lock: delete the temporary files of this store's writers that died before
        their ``os.replace`` (killed mid-write: nothing else removes them). Every write of a file
        of the store or of its record holds the lock, so none found while it is held belongs to a
        live writer; the module file's (written without it) are left alone."""
        orphan = re.compile(r"^\.tmp-[0-9a-f]{16}-" + re.escape(self.modname) + r"\.")
        gone = []
        for d, keep in ((self.dir, lambda n: not n.endswith(f"-{self.modname}.sha256")), (self.numba_dir, None)):
            with contextlib.suppress(OSError):
                for name in os.listdir(d):
                    if orphan.match(name) and not (keep and keep(name)):
                        remove_entry(os.path.join(d, name))
                        gone.append(name)
        return gone

    def remove_orphans(self) -> list:
        with self.lock:
            return self._remove_orphans()

    def read(self, name: str) -> bytes | None:
        """The bytes of ``__pycache__/name`` if they are the recorded ones, else None (and the
        file, if any, deleted). Read once: what is checked is what is returned."""
        if not self._owns(name):
            return None
        path = os.path.join(self.numba_dir, name)
        with self.lock:
            rec = self._read_manifest()
            raw = read_private(path) if name in rec else None
            if raw is not None and hashlib.sha256(raw).hexdigest() == rec[name]:
                return raw
            if os.path.lexists(path):
                remove_entry(path)
            if name in rec:
                del rec[name]
                self._write_manifest(rec)
        return None

    def write(self, name: str, data: bytes) -> None:
        """Write ``__pycache__/name`` (never through a link) and record its digest, under the lock,
        so that the record always describes the file on disk."""
        if not self._owns(name):
            raise CacheDirectoryError(f"refusing to write {name!r} into the cache of {self.modname}")
        with self.lock:
            write_private(os.path.join(self.numba_dir, name), data)
            rec = self._read_manifest()
            rec[name] = hashlib.sha256(data).hexdigest()
            self._write_manifest(rec)

    def discard(self, name: str) -> None:
        with self.lock:
            path = os.path.join(self.numba_dir, name)
            if os.path.lexists(path):
                remove_entry(path)
            rec = self._read_manifest()
            if rec.pop(name, None) is not None:
                self._write_manifest(rec)


_STORES: dict[str, TrustedStore] = {}


# --- numba's cache, routed through the store ----------------------------------------------------------
def _trusted_cache_class():
    """numba's FunctionCache with the store as its only locator and file layer (built lazily: it
    subclasses numba internals, stable since numba 0.4x; see ``model_jit`` for the fallback)."""
    global _CACHE_CLASS
    if _CACHE_CLASS is not None:
        return _CACHE_CLASS
    from numba.core import caching

    class Locator(caching._CacheLocator):
        def __init__(self, py_func, store):
            self._lineno = py_func.__code__.co_firstlineno
            self._py_file = os.path.join(store.dir, store.modname + ".py")
            self.store = store

        def ensure_cache_path(self):
            private_subdir(self.store.dir, "__pycache__")

        def get_cache_path(self):
            return self.store.numba_dir

        def get_source_stamp(self):
            return self.store.source_digest      # the expected source, not the file on disk

        def get_disambiguator(self):
            return str(self._lineno)

    class Impl(caching.CompileResultCacheImpl):
        def __init__(self, py_func, store):      # no locator search (NUMBA_CACHE_DIR & co. ignored)
            self._lineno = py_func.__code__.co_firstlineno
            self._locator = Locator(py_func, store)
            qualname = getattr(py_func, "__qualname__", py_func.__name__)
            self._filename_base = self.get_filename_base(f"{store.modname}.{qualname}",
                                                         getattr(sys, "abiflags", ""))

    class Files(caching.IndexDataCacheFile):
        def __init__(self, store, **kw):
            super().__init__(**kw)
            self.store = store

        def _load_index(self):
            raw = self.store.read(self._index_name)
            if raw is None:
                return {}
            try:
                f = io.BytesIO(raw)
                version = pickle.load(f)
                if version != self._version:
                    return {}
                stamp, overloads = pickle.loads(f.read())
            except Exception:                    # recorded but unreadable (numba changed): rebuild
                self.store.discard(self._index_name)
                return {}
            return overloads if stamp == self._source_stamp else {}

        def _save_index(self, overloads):
            data = self._dump((self._source_stamp, overloads))
            with contextlib.suppress(OSError, CacheDirectoryError):   # not cached: slower, never wrong
                self.store.write(self._index_name, pickle.dumps(self._version, protocol=-1) + data)

        def _load_data(self, name):
            raw = self.store.read(name)
            if raw is None:
                raise FileNotFoundError(name)    # numba's load() takes an OSError as a miss
            try:
                return pickle.loads(raw)
            except Exception:
                self.store.discard(name)
                raise FileNotFoundError(name) from None

        def _save_data(self, name, data):
            with contextlib.suppress(OSError, CacheDirectoryError):
                self.store.write(name, self._dump(data))

    class TrustedFunctionCache(caching.FunctionCache):
        def __init__(self, py_func, store):
            self._name = repr(py_func)
            self._py_func = py_func
            self._impl = Impl(py_func, store)
            self._cache_path = store.numba_dir
            self._cache_file = Files(store, cache_path=self._cache_path, filename_base=self._impl.filename_base,
                                     source_stamp=store.source_digest)
            self.enable()

        def _load_overload(self, sig, target_context):
            try:
                return super()._load_overload(sig, target_context)
            except Exception:                    # a recorded entry numba cannot rebuild: compile again
                with contextlib.suppress(OSError):
                    self._cache_file.store.discard(self._cache_file._index_name)
                return None

    _CACHE_CLASS = TrustedFunctionCache
    return _CACHE_CLASS


_CACHE_CLASS = None


def model_jit(sig=None, **options):
    """``numba.njit(sig, cache=True, **options)`` for the functions of a generated module loaded by
    ``load_source``: the compiled code is cached in the module's TrustedStore (never in
    NUMBA_CACHE_DIR, never read unless recorded). Without a store (a module not loaded through
    ``load_source``) or without the numba internals it relies on, the function is compiled and
    not cached: slower, never unsafe."""
    import numba

    def wrap(func):
        disp = numba.njit(**options)(func)
        store = _STORES.get(func.__code__.co_filename)
        if store is not None:
            try:
                disp._cache = _trusted_cache_class()(func, store)
            except (ImportError, AttributeError, TypeError):
                pass
        if sig is not None:
            from numba.core import typeinfer
            with typeinfer.register_dispatcher(disp):
                disp.compile(sig)
            disp.disable_compile()
        return disp
    return wrap


# --- numba's own cache of the kernels -------------------------------------------------------------------
#: kernel cache directory -> (the directory path_trust judged, ((component, fingerprint), ...) of
#: the components it looked at before the last, (the last one, its fingerprint)) when found safe
_KERNEL_CACHE_OK: dict = {}
#: the kernel modules (a tuple, held: no id reuse) -> the cache paths of their dispatchers
_KERNEL_PATHS: dict = {}


def _fingerprint(st, final: bool) -> tuple:
    """What the trust verdict of one component depends on: its identity (a replaced directory or
    link is another inode), type and mode, owner; for the final directory also its mtime and ctime
    (an entry added, removed or renamed in it, or its metadata changed)."""
    fp = (st.st_dev, st.st_ino, st.st_mode, st.st_uid)
    return fp + (st.st_mtime_ns, st.st_ctime_ns) if final else fp


def _kernel_cache_target(path: str) -> str:
    """The directory whose trust decides: the cache directory itself, or its parent while numba has
    not created it (it would create it there)."""
    return path if os.path.isdir(path) else os.path.dirname(path)


def _still_trusted(path: str) -> bool:
    """True when ``path`` was found safe and nothing its verdict depends on has changed since: the
    same directory judged, every component (ancestors, links, the directory) with the same lstat
    fingerprint. One lstat per component: a few microseconds, against a full ``path_trust``."""
    rec = _KERNEL_CACHE_OK.get(path)
    # judged as the directory itself: its unchanged fingerprint (inode, a directory) says it still
    # is; judged by its parent: it must still not exist as a directory
    if rec is None or (rec[0] != path and _kernel_cache_target(path) != rec[0]):
        return False
    lstat = os.lstat
    try:
        for p, fp in rec[1]:
            st = lstat(p)
            if (st.st_dev, st.st_ino, st.st_mode, st.st_uid) != fp:
                return False
        p, fp = rec[2]
        st = lstat(p)
        return (st.st_dev, st.st_ino, st.st_mode, st.st_uid, st.st_mtime_ns, st.st_ctime_ns) == fp
    except OSError:
        return False


def _kernel_paths(modules) -> list:
    """The cache paths numba's locators chose for the dispatchers of ``modules`` (fixed when a
    module's dispatchers were made), collected once per tuple of modules and numba's
    ``NUMBA_CACHE_DIR`` setting (a module reloaded after it changed has dispatchers elsewhere)."""
    config = sys.modules.get("numba.core.config")
    key = (tuple(modules), getattr(config, "CACHE_DIR", None))
    hit = _KERNEL_PATHS.get(key)
    if hit is not None:
        return hit
    paths = set()
    for mod in modules:
        for obj in vars(mod).values():
            cache = getattr(obj, "_cache", None)
            path = getattr(cache, "cache_path", None) if cache is not None else None
            if isinstance(path, str):
                paths.add(path)
    if len(_KERNEL_PATHS) >= 64:           # bounded: the library passes two tuples
        _KERNEL_PATHS.clear()
    hit = _KERNEL_PATHS[key] = sorted(paths)
    return hit


def _kernel_files_trust(path: str) -> str:
    """"" when every index and data file numba would read in the kernel cache directory ``path``
    (.nbi, .nbc) is a regular file owned by this user or root and not writable by anyone else, else
    the reason: a safe directory keeps others from adding files, not from rewriting one they own
    or may write (a planted .nbi owned by nobody, mode 0666, was unpickled). Only this user can
    change such a file's mode or owner afterwards, so the directory's fingerprint
    (``_still_trusted``) keeps covering them."""
    if not os.path.isdir(path):
        return ""
    try:
        names = os.listdir(path)
    except OSError as exc:
        return f"{path}: {exc.strerror or exc}"
    for name in names:
        if not name.endswith((".nbi", ".nbc")):
            continue
        full = os.path.join(path, name)
        try:
            st = os.lstat(full)
        except OSError:
            continue                       # removed meanwhile: numba will not read it
        if not stat.S_ISREG(st.st_mode):
            return f"{full} is not a regular file"
        if not _trusted_owner(st):
            return f"{full} belongs to another user (uid {st.st_uid})"
        if st.st_mode & 0o022:
            return f"{full} is writable by other users"
    return ""


def check_kernel_cache(modules) -> None:
    """Raise CacheDirectoryError unless every directory numba would load the cached kernels of
    ``modules`` from (the package's ``__pycache__``, ``NUMBA_CACHE_DIR`` or numba's per-user cache,
    as numba's locators choose) is safe by ``path_trust(..., final_private=False)``: numba unpickles
    the index files found there, so a directory another user can write is a way to run code in
    this process. Checked at every call: in full the first time, afterwards by comparing the lstat
    fingerprint of every component the full check looked at (``_still_trusted``; any change, a
    chmod, chown, replaced or re-linked component, a file added or removed in the directory,
    means the full check again), so that a directory made unsafe after a first run is still
    refused."""
    for path in _kernel_paths(modules):
        if _still_trusted(path):
            continue
        target = _kernel_cache_target(path)
        walked: list = []
        why = path_trust(target, final_private=False, walked=walked) or _kernel_files_trust(path)
        if why:
            _KERNEL_CACHE_OK.pop(path, None)
            raise CacheDirectoryError(f"numba would load the compiled kernels from {path}, which is not safe "
                                      f"({why}); point NUMBA_CACHE_DIR at a directory only you can write")
        _KERNEL_CACHE_OK[path] = (target, tuple((p, _fingerprint(st, False)) for p, st in walked[:-1]),
                                  (walked[-1][0], _fingerprint(walked[-1][1], True)))


# --- generated sources by the model's content ------------------------------------------------------
_SOURCE_STORE = "ldaspark_sources"
_KEY = re.compile(r"^[0-9a-f]{64}$")


def _source_store():
    d = cache_dir()
    return TrustedStore(d, _SOURCE_STORE, "")


def stored_source(key: str) -> str | None:
    """The generated model source recorded under the content key ``key`` (``codegen.model_key``),
    or None: a file ``__pycache__/ldaspark_sources.<key>.py`` of the cache directory, returned
    only if its bytes are the ones this user's process recorded (``TrustedStore.read``: read once
    without following links, owner checked, sha256 compared with the record; anything else is
    deleted), so that a renamed or rebuilt system skips code generation, and nothing another user
    could write is ever executed."""
    if not _KEY.match(str(key)):
        return None
    try:
        raw = _source_store().read(f"{_SOURCE_STORE}.{key}.py")
    except (OSError, CacheDirectoryError):
        return None
    if raw is None:
        return None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return None


def store_source(key: str, source: str) -> None:
    """Record ``source`` under the content key ``key`` (written atomically, never through a link,
    its digest recorded); a cache that cannot be written only costs the code generation again."""
    if not _KEY.match(str(key)):
        return
    with contextlib.suppress(OSError, CacheDirectoryError):
        store = _source_store()
        store.remove_orphans()          # once per new model: what killed writers of sources left
        store.write(f"{_SOURCE_STORE}.{key}.py", source.encode("utf-8"))


# --- loading a generated module ---------------------------------------------------------------
_MODULES: dict[str, types.ModuleType] = {}


def load_source(source: str, prefix: str = "ldaspark_model_", digest: str | None = None) -> types.ModuleType:
    """The module of this source text, executed from the text itself (never from what is on disk);
    the file in the cache directory is (re)written to hold exactly this text, never through a
    link. numba's cache files of its functions are read only when recorded (``TrustedStore``).
    Works in worker processes of any executor: the file is written if this machine lacks it.
    ``digest``: the sha256 of ``source`` when the caller has it."""
    digest = digest or source_key(source)
    hit = _MODULES.get(digest)
    if hit is not None:
        return hit
    modname = f"{prefix}{digest[:20]}"
    d = cache_dir()
    path = os.path.join(d, modname + ".py")
    try:
        for attempt in range(4):
            raw = read_private(path)
            if raw is not None and hashlib.sha256(raw).hexdigest() == digest:
                break
            if attempt == 3:
                raise CacheDirectoryError(f"{path} does not hold the source just written")
            # os.replace replaces a link, FIFO or stale file atomically; only a directory is removed
            # first. Never a file that merely was absent when read: another process writing the
            # same source may have put it there since (its unlink failed the other's read-back)
            with contextlib.suppress(FileNotFoundError):
                if stat.S_ISDIR(os.lstat(path).st_mode):
                    remove_entry(path)
            write_private(path, source.encode(), mode=0o600)
        store = TrustedStore(d, modname, digest)
        store.sweep()
    except OSError as exc:
        raise CacheDirectoryError(f"cannot use the cache file {path}: {exc.strerror or exc}") from None
    _STORES[path] = store
    mod = types.ModuleType(modname)
    mod.__file__ = path
    sys.modules[modname] = mod
    try:
        with SOURCE_LOCK:             # compile in two threads at once (gensource.SOURCE_LOCK)
            code = compile(source, path, "exec")
        exec(code, mod.__dict__)
    except BaseException:
        sys.modules.pop(modname, None)
        raise
    _MODULES[digest] = mod
    return mod
