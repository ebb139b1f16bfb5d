"""The on-disk home of the generated model modules, and loading them without executing anything
found there.

* Directory: ``$LDASPARK_CACHE_DIR``, else ``~/.cache/ldaspark/fast``, else
  ``<tempdir>/ldaspark-fast-<uid>``; created with mode 0700 and used only when it is a real
  directory owned by this user that nobody else can write (a looser mode on our own directory is
  tightened to 0700; a directory of another user is skipped).
* Loading: the file name carries a hash of the source the caller expects; the file's content is
  compared (sha256) with that source and rewritten when it differs (planted, truncated, corrupt),
  and the *expected* source text is what gets compiled and executed, with the file as its
  ``__file__`` so that numba's on-disk cache (keyed on the file) still works.
"""
from __future__ import annotations

import hashlib
import os
import stat
import sys
import tempfile
import types

from ..core.errors import LdasparkError


class CacheDirectoryError(LdasparkError):
    """No safe, writable directory for the generated modules."""


def _candidates():
    uid = os.getuid() if hasattr(os, "getuid") else None
    env = os.environ.get("LDASPARK_CACHE_DIR")
    yield env
    yield os.path.join(os.path.expanduser("~"), ".cache", "ldaspark", "fast")
    yield os.path.join(tempfile.gettempdir(), f"ldaspark-fast-{uid if uid is not None else os.getlogin()}")


def secure_dir(d: str) -> tuple[str | None, str]:
    """(d, "") once d is made and checked as a private directory (mode 0700, owner = this user),
    else (None, reason)."""
    try:
        os.makedirs(d, mode=0o700, exist_ok=True)
        st = os.lstat(d)
        if stat.S_ISLNK(st.st_mode):
            st = os.stat(d)                 # a symlink to our own private directory is fine
        if not stat.S_ISDIR(st.st_mode):
            return None, f"{d} is not a directory"
        if hasattr(os, "getuid") and st.st_uid != os.getuid():
            return None, f"{d} belongs to another user (uid {st.st_uid})"
        if st.st_mode & 0o077:
            os.chmod(d, 0o700)
            if os.stat(d).st_mode & 0o077:
                return None, f"{d} is accessible to other users and cannot be made private"
        if not os.access(d, os.W_OK | os.X_OK):
            return None, f"{d} is not writable"
        return d, ""
    except OSError as exc:
        return None, f"{d}: {exc.strerror or exc}"


def cache_dir() -> str:
    """The first usable private cache directory; raises CacheDirectoryError with every reason."""
    why = []
    for d in _candidates():
        if not d:
            continue
        ok, reason = secure_dir(d)
        if ok:
            return ok
        why.append(reason)
    raise CacheDirectoryError("no private writable cache directory for the compiled models: " + "; ".join(why))


def source_key(source: str) -> str:
    return hashlib.sha256(source.encode()).hexdigest()


def _verified(path: str, digest: str) -> bool:
    try:
        with open(path, "rb") as f:
            return hashlib.sha256(f.read()).hexdigest() == digest
    except OSError:
        return False


_MODULES: dict[str, types.ModuleType] = {}


def load_source(source: str, prefix: str = "ldaspark_model_", digest: str | None = None) -> types.ModuleType:
    """The module of this source text, executed from the text itself (never from what is on disk);
    the file in the cache directory is (re)written to hold exactly this text. Works in worker
    processes of any executor: the file is written if this machine lacks it. ``digest``: the
    sha256 of ``source`` when the caller has it."""
    digest = digest or source_key(source)
    hit = _MODULES.get(digest)
    if hit is not None:
        return hit
    from ..core.io import atomic_write_text
    modname = f"{prefix}{digest[:20]}"
    path = os.path.join(cache_dir(), modname + ".py")
    if not _verified(path, digest):
        if os.path.lexists(path) and not os.path.isfile(path):
            os.unlink(path)                 # a symlink, FIFO or directory planted under our name
        atomic_write_text(path, source)
        if not _verified(path, digest):
            raise CacheDirectoryError(f"{path} does not hold the source just written")
    mod = types.ModuleType(modname)
    mod.__file__ = path
    sys.modules[modname] = mod
    try:
        exec(compile(source, path, "exec"), mod.__dict__)
    except BaseException:
        sys.modules.pop(modname, None)
        raise
    _MODULES[digest] = mod
    return mod
