"""Atomic file output: write to a temporary file in the target directory, fsync, then
os.replace, so an interrupted run or a full disk never leaves a half-written file.

What is written where (the path is ``--out`` / ``--json`` of the command line):

* a regular file, or a path that does not exist yet: atomic replace (temporary
  ``.tmp-ldaspark-<host>-<pid>-<random>.<name>`` file in the same directory, removed again on any
  error and on every signal whose default action terminates the process (SIGINT, SIGTERM,
  SIGHUP, SIGQUIT, SIGUSR1, SIGALRM, SIGXCPU, ...: ``lifecycle.STOP_SIGNALS``); one left by a
  killed writer is removed at the next write to the same target: ``ldaspark.core.lifecycle``);
* a symbolic link: followed; its final target is replaced atomically (the link stays a link);
* a character device or a FIFO (``/dev/null``, ``/dev/stdout``, a named pipe, ``>(cmd)``):
  written directly, as a shell redirection would (no atomicity is possible there; a FIFO blocks
  until a reader opens it; ``/dev/full`` gives "No space left on device");
* ``/dev/stdout``, ``/dev/stderr``, ``/dev/fd/N``, ``/proc/self/fd/N`` onto a regular file (a
  shell redirection): appended to through that open file, never replaced;
* a directory, block device, socket or anything else: refused (LdasparkError), never replaced.
"""
from __future__ import annotations

import json
import os
import re
import stat
import tempfile

from .errors import LdasparkError
from .lifecycle import TempFile, raise_on_stop_signals


#: the paths this process has written atomically, in order: the command line names those a
#: stopped run had completed ("no partial output was written" said nothing of them)
COMPLETED: list = []

_FD_PATH = re.compile(r"^/(?:dev/(?:(stdout|stderr)|fd/(\d+))|proc/(self|\d+)/fd/(\d+))$")


def _write_fd(path, m, data: bytes) -> None:
    import sys
    name, fd_dev, pid, fd_proc = m.groups()
    if pid is not None and pid != "self" and int(pid) != os.getpid():
        return _write_direct(path, data, append=True)         # another process's file
    fd = {"stdout": 1, "stderr": 2}[name] if name else int(fd_dev or fd_proc)
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None and stream.fileno() == fd:
                stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None


def _write_all(f, data: bytes) -> None:
    """The write itself (a seam for tests that need a slow writer)."""
    f.write(data)


def _destination(path):
    """("direct", None) for a device or FIFO, ("fd", match) for /dev/stdout & co. onto a regular
    file, ("replace", target) for a regular or new file (symlinks resolved); refuses the rest."""
    try:
        st = os.stat(path)                      # follows symlinks: the type of the final target
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode):
            return "direct", None
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise LdasparkError(f"cannot write {path}: it is {kind} (refusing to replace it)")
    m = _FD_PATH.match(os.path.abspath(path)) if st is not None else None
    if m:
        # /dev/stdout, /dev/fd/N, /proc/self/fd/N onto a regular file: an open file of this
        # process (a shell redirection); written through that descriptor, at its offset, so that
        # it interleaves with what else the process prints there; never replaced
        return "fd", m
    # a symlink (possibly dangling) is written through: replace its final target, keep the link
    return "replace", (os.path.realpath(path) if os.path.islink(path) else path)


def check_destination(path) -> None:
    """Refuse now (LdasparkError, one line) an output path the writers would refuse at the end (a
    directory, a socket, an unreadable component): a long run checks its outputs before it starts,
    so that it never computes for nothing nor leaves half of a pair of files written."""
    if path is None:
        return
    path = os.fspath(path)
    kind, target = _destination(path)
    if kind == "replace":
        _check_replaceable(path, target)


def check_distinct_outputs(*named) -> None:
    """Refuse (LdasparkError, one line) two outputs of one run that name the same file: ``named``
    is (option, path) pairs, None paths skipped. The writer that came second replaced what the
    first wrote (``audit --out F --json F`` left the JSON and no report). Files are compared after
    resolving symbolic links; devices and FIFOs (``/dev/null``, ``/dev/stdout``) take both writes,
    as a shell redirection would, and are not compared."""
    seen = {}
    for opt, path in named:
        if path is None:
            continue
        try:
            kind, target = _destination(os.fspath(path))
        except LdasparkError:
            # not a file that could be written (a directory, ...): its own check says so, the
            # output's (``check_destination``) or an input's reader ("audit ." is "not a regular file")
            continue
        if kind != "replace":
            continue
        key = os.path.realpath(os.path.abspath(target))
        if key in seen:
            raise LdasparkError(f"{seen[key]} and {opt} name the same file {os.fspath(path)}: one would "
                                "replace or remove the other; give two paths")
        seen[key] = opt


def _check_replaceable(path, target) -> None:
    """The writers' own first steps, tried now: the target's directory can be made and holds a new
    file (a temporary file created and removed at once, as ``_atomic_replace`` creates it). A type
    check alone let ``/proc/version`` or a file in a read-only directory through: the run computed,
    then failed to write."""
    d = os.path.dirname(os.path.abspath(target))
    probe = d
    while not os.path.lexists(probe):          # the writer makes the missing directories
        probe = os.path.dirname(probe)
    if probe != d:
        if not os.path.isdir(probe):
            raise LdasparkError(f"cannot write {path}: {probe} is not a directory")
        if not os.access(probe, os.W_OK | os.X_OK):
            raise LdasparkError(f"cannot write {path}: {probe} is not writable (Permission denied)")
        return
    tmp = TempFile(target)
    try:
        tmp.create()
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.remove()


def atomic_write_bytes(path, data: bytes) -> None:
    path = os.fspath(path)
    kind, what = _destination(path)
    if kind == "direct":
        return _write_direct(path, data)
    if kind == "fd":
        return _write_fd(path, what, data)
    _atomic_replace(path, what, data)


def atomic_write_with(path, write) -> None:
    """For writers that need a file name (h5py, numpy.savez, matplotlib): ``write(name)`` writes
    a complete file at ``name``; it lands at ``path`` with the same guarantees as
    ``atomic_write_bytes`` (a temporary file in the target directory, replaced atomically; devices,
    FIFOs and /dev/stdout receive the bytes directly; directories are refused)."""
    path = os.fspath(path)
    kind, what = _destination(path)
    if kind == "replace":
        return _atomic_replace(path, what, None, write)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-ldaspark-")
    os.close(fd)
    try:
        write(tmp)
        with open(tmp, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        try:
            os.unlink(tmp)
        except OSError:
            pass
    return _write_direct(path, data) if kind == "direct" else _write_fd(path, what, data)


def _write_direct(path, data: bytes, append: bool = False) -> None:
    """Character devices and FIFOs: open for writing (no create, no replace) and write."""
    try:
        fd = os.open(path, os.O_WRONLY | getattr(os, "O_NOCTTY", 0) | (os.O_APPEND if append else 0))
        with os.fdopen(fd, "wb") as f:
            _write_all(f, data)
    except OSError as exc:
        raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None


def _atomic_replace(path, target, data: bytes | None, write=None) -> None:
    """Write ``data`` (or let ``write(tmp_name)`` write) to a temporary file next to ``target``
    (``lifecycle.TempFile``: a recognisable name, O_EXCL | O_NOFOLLOW, the stale ones of a
    killed writer removed first), fsync, os.replace; the temporary file is removed on any
    error and on every stop signal (``lifecycle.STOP_SIGNALS``)."""
    d = os.path.dirname(os.path.abspath(target))
    tmp = TempFile(target)
    with _sigterm_raises():
        try:
            os.makedirs(d, exist_ok=True)
            tmp.create()
            os.chmod(tmp.name, _default_mode(target))  # created 0600; give the mode open() would
            with tmp.fdopen("wb" if write is None else "rb+") as f:
                if write is None:
                    _write_all(f, data)
                else:
                    write(tmp.name)
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp.name, target)
            tmp.forget()
            COMPLETED.append(os.fspath(path))
        except BaseException as exc:
            tmp.remove()
            if isinstance(exc, OSError):
                raise LdasparkError(f"cannot write {path}: {exc.strerror or exc}") from None
            raise


# While a temporary file exists, the stop signals raise (so that the cleanup above runs) and the
# process still ends by the signal afterwards; under the command line its own policy applies.
_sigterm_raises = raise_on_stop_signals


def _default_mode(path) -> int:
    """Mode of the existing file, else 0666 minus the umask (what a plain open() creates)."""
    try:
        return os.stat(path).st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def atomic_write_text(path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path, obj) -> None:
    try:
        text = json.dumps(obj, indent=1, allow_nan=False)
    except ValueError as exc:  # NaN/inf: refuse before touching the file, as a user-facing error
        raise LdasparkError(f"cannot write {path}: {exc}") from None
    atomic_write_text(path, text + "\n")


def atomic_save_figure(fig, path, dpi: int = 100) -> None:
    """Render a matplotlib figure to PNG in memory, close it, and write it atomically."""
    import io as _io
    import matplotlib.pyplot as plt
    buf = _io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
