"""Where work runs: one way to name it for ensembles (``run_many``), the claims ledger
(``ldaspark verify``), the mutation catalogue (``ldaspark mutants``) and the main job's jobs.

``where`` is one of

* ``None`` or ``"local"``: a process pool on this machine with ``jobs`` workers (``jobs=1``: in
  this process, no pool);
* an address ``"tcp://host:8786"`` (any ``scheme://...``): a Dask scheduler; a ``distributed.Client``
  is opened here and closed at the end (``pip install "ldaspark[dist]"``);
* a ``distributed.Client``: work goes to its cluster (the client stays open);
* any ``concurrent.futures.Executor`` (a thread pool, ``client.get_executor()``, ...): used as it
  is and not shut down here.

Work is a list of ``Unit`` (a name, a module-level function and picklable arguments that carry
everything the function needs). ``run_units`` returns the results keyed by unit name, whatever
the number of workers and the order in which they finish, so callers assemble them in their own
order and the output equals the serial run's. Faults:

* a worker that dies (``BrokenProcessPool`` of a local pool, which is then re-created; Dask's
  ``KilledWorker``, after the scheduler's own retries) gets the units it may have been running
  retried, at most ``retries`` times each; a unit that still fails is reported by name
  (``UnitsFailed``), after every other unit has finished;
* an exception raised by a unit's function is not retried (it would raise again): the unit is
  reported by name in the same way;
* a ``Checkpoint`` file records each finished unit as it comes in, so that a rerun of an
  interrupted or partly failed job resumes from it (the callers keep it until their report is
  written);
* Ctrl-C (any exception in the parent) cancels every pending future, on the cluster too, and
  stops a local pool's workers.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import hashlib
import json
import os
import pathlib
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from .core import validate as V
from .core.errors import InputError, LdasparkError
from .core.io import atomic_write_text
from .core.lifecycle import make_process_pool


class UnitsFailed(LdasparkError):
    """Some units failed (by name, with why); ``results`` holds every unit that finished."""

    def __init__(self, failed: dict, results: dict, kept=None):
        self.failed, self.results, self.kept = dict(failed), dict(results), kept
        names = "; ".join(f"{k}: {v}" for k, v in list(self.failed.items())[:5])
        more = f" (and {len(self.failed) - 5} more)" if len(self.failed) > 5 else ""
        where = (f"; the finished units are kept in {kept}, a rerun resumes from there"
                 if kept is not None else "")
        super().__init__(f"{len(self.failed)} work unit(s) failed ({len(self.results)} finished): "
                         f"{names}{more}{where}")


@dataclass(frozen=True)
class Unit:
    """One piece of work: ``fn(*args)`` under the name ``name`` (a string, unique in a run)."""

    name: str
    fn: Callable
    args: tuple = field(default=())


class InlineExecutor(cf.Executor):
    """Runs each submitted call at once, in this process (one worker, or inside a worker of the
    main job, where a nested pool would only oversubscribe the cores)."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001  (delivered through the future, as a pool would)
            if isinstance(exc, KeyboardInterrupt):
                raise
            f.set_exception(exc)
        return f


def is_address(where) -> bool:
    """``where`` is given as a scheduler address (``scheme://...``); ``check_where`` says whether
    it is a well-formed one."""
    return isinstance(where, str) and "://" in where


def describe(where, jobs=None) -> str:
    if where is None or where == "local":
        return f"local pool of {max(1, jobs or os.cpu_count() or 1)} worker process(es)"
    if is_address(where):
        return f"Dask scheduler {where}"
    if _is_client(where):
        return "Dask client"
    return type(where).__name__


def _is_client(obj) -> bool:
    return type(obj).__name__ == "Client" and hasattr(obj, "get_executor") and hasattr(obj, "cancel")


def check_where(where, jobs=None):
    """Refuse what cannot name a place to run work (before anything starts). A scheduler address
    is parsed here, strictly: ``tcp|tls|ws|wss|ucx://host[:port]`` with a non-empty host, a port in
    1..65535 and nothing else, or ``inproc://`` of a scheduler in this process; a malformed one
    (x://y, tcp://, tcp://[::1) is one InputError at once, never a Client that waits for its
    connect timeout and then complains again when it is collected."""
    import numpy as np
    if jobs is not None and (isinstance(jobs, (bool, np.bool_)) or not isinstance(jobs, (int, np.integer))
                             or jobs < 1):
        raise InputError(f"jobs must be a positive integer, got {str(jobs)[:60]!r}")
    if is_address(where):
        import re
        import urllib.parse
        bad = f"malformed Dask scheduler address {where[:80]!r}"
        if len(where) > 300 or not where.isprintable() or any(c.isspace() for c in where):
            raise InputError(f"{bad}: expected tcp://host:port")
        scheme = where.split("://", 1)[0].lower()
        if scheme == "inproc":
            parts = where.split("://", 1)[1].split("/")
            if len(parts) != 3 or not parts[0] or parts[1] != str(os.getpid()) or not parts[2].isdigit():
                raise InputError(f"{bad}: inproc:// names a scheduler inside this process "
                                 "(inproc://IP/PID/N); pass that cluster's distributed.Client instead")
            return
        if scheme not in ("tcp", "tls", "ws", "wss", "ucx"):
            raise InputError(f"{bad}: the scheme must be tcp, tls, ws, wss or ucx (as in tcp://host:8786)")
        try:
            u = urllib.parse.urlsplit(where)
            host, port = u.hostname, u.port
        except ValueError as exc:
            raise InputError(f"{bad}: {exc}") from None
        rest = where.split("://", 1)[1]
        if not host or u.path not in ("", "/") or u.query or u.fragment or u.username is not None \
                or rest.endswith(":") or not re.fullmatch(r"[A-Za-z0-9._\-]+|[0-9A-Fa-f:.]+", host):
            raise InputError(f"{bad}: expected {scheme}://host:port with a host name or address")
        if port is not None and not 1 <= port <= 65535:
            raise InputError(f"{bad}: the port must be between 1 and 65535")
        # the whole rest is host[:port] (urlsplit ignores text after ']' and takes any digits
        # and dots for a host): an IPv6 literal in brackets and a dotted-decimal host must be
        # addresses, anything else a host name
        import ipaddress
        m = re.fullmatch(r"(\[[^\]]*\]|[^:/\[\]]+)(:[0-9]{1,5})?/?", rest)
        try:
            if m is None:
                raise ValueError("not host:port")
            if m.group(1).startswith("["):
                ipaddress.IPv6Address(m.group(1)[1:-1])
            elif re.fullmatch(r"[0-9.]+", m.group(1)):
                ipaddress.IPv4Address(m.group(1))
        except ValueError:
            raise InputError(f"{bad}: expected {scheme}://host:port with a host name or address") from None
        return
    if where is None or where == "local" or _is_client(where):
        return
    if isinstance(where, type):
        raise InputError(f"where must be an executor object, got the class {where.__name__} "
                         f"(create one: {where.__name__}(...))")
    if isinstance(where, cf.Executor) or (hasattr(where, "submit") and callable(where.submit)):
        return
    raise InputError(f"where work runs must be 'local', a scheduler address such as tcp://host:8786, "
                     f"a distributed.Client or a concurrent.futures.Executor, got {str(where)[:80]!r}")


class _Place:
    """The executor behind ``where`` for the duration of a run; ``renew()`` replaces a local pool
    that broke (a worker died); ``abort()`` stops what this object started, without waiting."""

    def __init__(self, where, jobs, mp_context, inline_single=True):
        self.where, self.jobs, self.mp_context = where, jobs, mp_context
        self.inline_single = inline_single
        self.client = None
        self.own_pool = False
        self.executor = self._open()

    def _open(self):
        w = self.where
        if w is None or w == "local":
            n = max(1, self.jobs or os.cpu_count() or 1)
            if n == 1 and self.inline_single:
                return InlineExecutor()
            self.own_pool = True
            return make_process_pool(n, mp_context=self.mp_context)
        if is_address(w) or _is_client(w):
            if is_address(w):
                try:
                    import distributed
                except ImportError:
                    raise InputError("a Dask scheduler needs the dist extra: pip install \"ldaspark[dist]\"") from None
                try:
                    # check_where admits one trailing '/' (as URLs carry it); distributed's
                    # parser would read it as part of the port
                    addr = w[:-1] if w.endswith("/") and not w.endswith("://") else w
                    self.client = distributed.Client(addr, timeout="20s", set_as_default=False)
                except (OSError, TimeoutError) as exc:
                    raise InputError(f"cannot reach the Dask scheduler {w}: {exc}") from None
                client = self.client
            else:
                client = w
            # pure=False: equal arguments are still separate units (a retried unit runs again)
            return client.get_executor(pure=False)
        return w

    @property
    def local_pool(self) -> bool:
        return self.own_pool

    def renew(self):
        if self.own_pool:
            _stop_pool(self.executor)
            self.executor = make_process_pool(max(1, self.jobs or os.cpu_count() or 1),
                                              mp_context=self.mp_context)

    def cancel(self, futures):
        for f in futures:
            f.cancel()
        if self.own_pool:
            _stop_pool(self.executor)
            self.own_pool = False

    def close(self):
        if self.own_pool:
            self.executor.shutdown(wait=True)
        if self.client is not None:
            self.client.close()


@contextlib.contextmanager
def open_executor(where=None, jobs=None, mp_context=None):
    """The executor behind ``where`` (a local process pool of ``jobs`` workers by default, even
    for one worker), for callers that manage their own futures; on an exception (Ctrl-C
    included) the futures submitted through it are cancelled and a local pool's workers stopped."""
    check_where(where, jobs)
    place = _Place(where, jobs, mp_context, inline_single=False)
    submitted = []
    ex = place.executor
    submit = ex.submit

    class _Tracking(cf.Executor):
        def submit(self, fn, /, *args, **kwargs):
            try:
                f = submit(fn, *args, **kwargs)
            except Exception as exc:  # noqa: BLE001  (a user's executor's own error: one line)
                raise V.submit_error(ex, exc) from exc
            f = V.submitted(ex, f)
            submitted.append(f)
            return f
    try:
        yield _Tracking()
    except BaseException:
        place.cancel(submitted)
        raise
    finally:
        place.close()


def _stop_pool(ex):
    """Shut a local pool down without waiting: cancel what is queued, terminate running workers."""
    terminate = getattr(ex, "terminate_workers", None)         # Python >= 3.14
    if terminate is not None:
        with contextlib.suppress(Exception):
            terminate()
        return
    # before shutdown, which drops the executor's reference to its processes
    procs = list((getattr(ex, "_processes", None) or {}).values())
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(OSError, AttributeError, ValueError):
            p.terminate()
    for p in procs:
        with contextlib.suppress(OSError, AttributeError, ValueError):
            p.join(timeout=2)


def _worker_lost(exc) -> bool:
    """A worker died under the unit (not an error of the unit's own computation)."""
    from concurrent.futures.process import BrokenProcessPool
    return isinstance(exc, BrokenProcessPool) or type(exc).__name__ in ("KilledWorker", "CommClosedError")


def _submit(executor, u):
    """``executor.submit(u.fn, *u.args)``, checked: a ``submit`` that raises (a shut-down
    executor, or its own error) or returns something other than a future is one InputError
    naming the executor (``validate.submitted``)."""
    try:
        fut = executor.submit(u.fn, *u.args)
    except Exception as exc:  # noqa: BLE001  (any error of a user's executor is its own)
        raise V.submit_error(executor, exc) from exc
    return V.submitted(executor, fut)


def run_units(units: Iterable[Unit], where=None, jobs=None, retries: int = 2,
              on_done: Callable[[str, Any], None] | None = None, mp_context=None, raise_failed=True) -> dict:
    """Run ``units`` where ``where`` says; returns {unit name: result}. ``on_done(name, result)``
    is called in this process as each unit finishes (progress, checkpoints). Units that failed
    are raised together as ``UnitsFailed`` (which carries every finished result) after all the
    others have finished; ``raise_failed=False`` returns the finished ones only."""
    results, failed = run_units_partial(units, where, jobs, retries, on_done, mp_context)
    if failed and raise_failed:
        raise UnitsFailed(failed, results)
    return results


def run_units_partial(units: Iterable[Unit], where=None, jobs=None, retries: int = 2,
                      on_done: Callable[[str, Any], None] | None = None, mp_context=None):
    """``(results, failed)``: {name: result} of the units that finished and {name: why} of those
    that did not (see the module docstring for retries)."""
    units = list(units)
    names = [u.name for u in units]
    if len(set(names)) != len(names):
        raise InputError("work unit names must be unique")
    check_where(where, jobs)
    if retries < 0:
        raise InputError(f"retries must be >= 0, got {retries}")
    results, failed = {}, {}
    attempts = {u.name: 0 for u in units}
    place = _Place(where, jobs, mp_context)
    try:
        # a function that cannot reach a process pool (a local function, a lambda) is refused
        # before anything runs, not reported as every unit failing with a PicklingError
        V.check_picklable(place.executor, {id(u.fn): u.fn for u in units}.values(), "the work unit's function")
    except BaseException:
        place.close()
        raise
    pending = units

    def handle(f, u):       # -> True when the pool broke under the unit
        try:
            val = f.result()
        except Exception as exc:  # noqa: BLE001  (sorted: worker lost vs the unit's own error)
            if not _worker_lost(exc):
                failed[u.name] = f"{type(exc).__name__}: {exc}"
                return False
            attempts[u.name] += 1
            if attempts[u.name] <= retries:
                pending.append(u)
            else:
                failed[u.name] = f"worker lost {attempts[u.name]} times ({type(exc).__name__})"
            return place.local_pool
        results[u.name] = val
        if on_done is not None:
            on_done(u.name, val)
        return False
    try:
        while pending:
            batch, pending, broken, futs = pending, [], False, {}
            try:
                if isinstance(place.executor, InlineExecutor):     # progress as each unit ends
                    for u in batch:
                        handle(place.executor.submit(u.fn, *u.args), u)
                    continue
                for u in batch:
                    futs[_submit(place.executor, u)] = u
                for f in cf.as_completed(futs):
                    broken = handle(f, futs[f]) or broken
            except BaseException:
                place.cancel(list(futs))
                raise
            if broken:
                place.renew()
            pending.sort(key=lambda u: names.index(u.name))
    finally:
        place.close()
    return results, failed


def add_scheduler_argument(parser):
    """``--scheduler ADDRESS``: the one command-line option naming where work runs."""
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run the work units on a Dask cluster (e.g. tcp://host:8786; needs the dist "
                             "extra) instead of local worker processes; results do not depend on it")


# --- checkpoints --------------------------------------------------------------------------------
#: the distributions whose versions change what a unit computes (the ledger's digits, the
#: mutation verdicts): part of every fingerprint, as the package's own source is
_FINGERPRINT_DISTS = ("numpy", "scipy", "mpmath", "sympy", "numba", "python-flint", "gmpy2", "pytest", "hypothesis",
                     "h5py", "llvmlite")
#: names under ``paths`` that never enter a fingerprint: caches, and the checkpoints themselves
#: (a checkpoint in a fingerprinted directory would change its own fingerprint as it is written)
_FINGERPRINT_SKIP = ("__pycache__", ".hypothesis", ".pytest_cache", ".git")
_FINGERPRINT_SKIP_SUFFIX = (".pyc", ".partial.jsonl", ".tmp")


def _environment_identity() -> list:
    import importlib.metadata
    import sys
    out = [sys.version, sys.platform]
    for name in _FINGERPRINT_DISTS:
        try:
            out.append(f"{name}=={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            out.append(f"{name} absent")
    return out


def _hash_file(h, path: pathlib.Path, st) -> None:
    """The bytes of the regular file ``path`` (``st``: its lstat), read without following a link
    and without blocking; a file that changed kind since ``st`` is hashed as a special entry."""
    import stat
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        h.update(b"unreadable\0" + str(exc.errno).encode())
        return
    if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
        os.close(fd)
        h.update(b"special\0")
        return
    with os.fdopen(fd, "rb") as fh:
        d = hashlib.sha256()
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            d.update(chunk)
    h.update(d.digest())


def _hash_tree(h, root: pathlib.Path, pattern: str) -> None:
    """Every file under ``root`` matching ``pattern`` (caches and checkpoints left out), by its
    path and bytes. A link is hashed as its target's text, never followed (a link to /dev/zero or
    out of the tree is not read); FIFOs, sockets and devices enter by name only, never opened."""
    import stat
    try:
        top = os.lstat(root)
    except OSError:
        h.update(b"absent\0" + str(root.name).encode() + b"\0")
        return
    if not stat.S_ISDIR(top.st_mode):
        h.update(b"file\0" + root.name.encode() + b"\0")
        if stat.S_ISREG(top.st_mode):
            _hash_file(h, root, top)
        elif stat.S_ISLNK(top.st_mode):
            h.update(b"link\0" + os.readlink(root).encode(errors="surrogateescape"))
        else:
            h.update(b"special\0")
        return
    for p in sorted(root.rglob(pattern)):      # rglob does not descend into linked directories
        rel = p.relative_to(root)
        if any(part in _FINGERPRINT_SKIP for part in rel.parts) or p.name.endswith(_FINGERPRINT_SKIP_SUFFIX):
            continue
        try:
            st = os.lstat(p)
        except OSError:
            continue
        if stat.S_ISDIR(st.st_mode):
            continue
        h.update(str(rel).encode(errors="surrogateescape") + b"\0")
        if stat.S_ISREG(st.st_mode):
            _hash_file(h, p, st)
        elif stat.S_ISLNK(st.st_mode):
            h.update(b"link\0" + os.readlink(p).encode(errors="surrogateescape"))
        else:                                   # FIFOs, sockets, devices: never opened
            h.update(b"special\0")


def source_fingerprint(*config, dirs=(), paths=()) -> str:
    """sha256 over every file of this package (source and data: the tableaux a verdict reads),
    the ``*.py`` files under ``dirs``, every file
    under ``paths`` (files or directories, caches and checkpoints left out), the Python version
    and the versions of the libraries the results depend on (``_FINGERPRINT_DISTS``), and
    ``config`` (JSON): a checkpoint written by other code, another environment or for another
    configuration is never resumed from. The fingerprint is an identity, not a secret: anyone
    can recompute it, so ``Checkpoint`` authenticates its records with a key of its own."""
    h = hashlib.sha256()
    pkg = pathlib.Path(__file__).resolve().parent   # the package ldaspark
    h.update(b"package\0")
    _hash_tree(h, pkg, "*")
    for root in map(pathlib.Path, dirs):
        h.update(b"dir\0")
        _hash_tree(h, root, "*.py")
    for root in map(pathlib.Path, paths):
        h.update(b"path\0")
        _hash_tree(h, root, "*")
    h.update(json.dumps(_environment_identity()).encode())
    h.update(json.dumps(config, sort_keys=True, default=str).encode())
    return h.hexdigest()


#: bounds of the checkpoint reader: a longer line, a deeper value or the part of the file past
#: MAX_CHECKPOINT_BYTES is not resumed (the units are computed again). A ledger unit's records
#: are ~20 KB on one line, a mutant's record ~3 KB, nested 4 deep.
MAX_CHECKPOINT_LINE = 8 * 2 ** 20
MAX_CHECKPOINT_BYTES = 512 * 2 ** 20
MAX_CHECKPOINT_DEPTH = 64
_KEY_NAME = "checkpoint-hmac.key"
_KEY_HEX = re.compile(rb"^[0-9a-f]{64}\n$")
_MAC_HEX = re.compile(r"^[0-9a-f]{64}$")
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_KEYS: dict = {}


class CheckpointKeyError(LdasparkError):
    """No trusted place for the checkpoints' key (records are then never resumed)."""


def _read_key(path: str) -> bytes | None:
    """The key in ``path`` when it is a regular file of this user that nobody else can read or
    write (opened without following a link, without blocking), holding 64 hex digits; else None."""
    import stat
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        uid = os.getuid() if hasattr(os, "getuid") else None
        if not stat.S_ISREG(st.st_mode) or st.st_size != 65 or st.st_mode & 0o077 or \
                (uid is not None and st.st_uid != uid):
            return None
        raw = os.read(fd, 66)
    except OSError:
        return None
    finally:
        os.close(fd)
    return bytes.fromhex(raw[:64].decode("ascii")) if _KEY_HEX.match(raw) else None


def checkpoint_key(directory: str | None = None) -> bytes:
    """This user's secret key for the checkpoints' HMACs: ``checkpoint-hmac.key`` in the trusted
    directory of the compiled cache (``ldaspark.compiled.cache.cache_dir``: owned by this user,
    mode 0700, every component of its path safe), created on first use (mode 0600, O_EXCL |
    O_NOFOLLOW, then linked into place, so a concurrent creator's key is never half read). A key
    file that is a link, not this user's, readable by others or malformed is replaced (records
    signed with it are then recomputed). Raises CheckpointKeyError without a trusted directory."""
    import secrets

    from .compiled.cache import CacheDirectoryError, cache_dir, path_trust, remove_entry
    try:
        d = directory if directory is not None else cache_dir()
    except CacheDirectoryError as exc:
        raise CheckpointKeyError(str(exc)) from None
    why = path_trust(d)
    if why:
        raise CheckpointKeyError(f"the checkpoint key's directory is not trusted: {why}")
    path = os.path.join(d, _KEY_NAME)
    if path in _KEYS:
        return _KEYS[path]
    nofollow = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
    for _ in range(3):
        key = _read_key(path)
        if key is not None:
            _KEYS[path] = key
            return key
        if os.path.lexists(path):
            with contextlib.suppress(OSError):
                remove_entry(path)              # planted, shared or damaged: never used
        tmp = os.path.join(d, f".{_KEY_NAME}.{secrets.token_hex(8)}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | nofollow, 0o600)
            try:
                os.write(fd, secrets.token_hex(32).encode("ascii") + b"\n")
                os.fsync(fd)
            finally:
                os.close(fd)
            try:
                os.link(tmp, path)              # never replaces a key another process made
            except FileExistsError:
                pass
            except OSError:                     # no hard links here: create it in place, O_EXCL
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | nofollow, 0o600)
                try:
                    os.write(fd, secrets.token_hex(32).encode("ascii") + b"\n")
                    os.fsync(fd)
                finally:
                    os.close(fd)
        except OSError as exc:
            raise CheckpointKeyError(f"cannot create the checkpoint key {path}: {exc.strerror or exc}") from None
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    raise CheckpointKeyError(f"the checkpoint key {path} cannot be made trustworthy")


def _json_depth(text: str) -> int:
    """Deepest nesting of [ and { in a JSON text (strings skipped), without parsing it."""
    # linear: the strings are skipped from quote to quote (str.find), the brackets outside them
    # counted by NumPy in one pass (a regular expression for the strings retried an unclosed
    # string at every quote: quadratic, hours for one forged 8 MiB line)
    import numpy as np
    outside, i, n = [], 0, len(text)
    while i < n:
        j = text.find('"', i)
        if j < 0:
            outside.append(text[i:])
            break
        outside.append(text[i:j])
        i = j + 1
        while True:                     # to the next quote not escaped
            j = text.find('"', i)
            if j < 0:
                i = n                   # unclosed: json.loads refuses it
                break
            k = j
            while k > i and text[k - 1] == "\\":
                k -= 1
            i = j + 1
            if (j - k) % 2 == 0:
                break
    b = np.frombuffer("".join(outside).encode("utf-8", "replace"), dtype=np.uint8)
    step = (b == ord("[")).astype(np.int64) + (b == ord("{")) - (b == ord("]")) - (b == ord("}"))
    return int(max(0, np.cumsum(step).max(initial=0)))


def _reject_constant(name):
    raise ValueError(f"{name} is not a finite number")


def _finite_float(text):
    import math
    x = float(text)
    if not math.isfinite(x):                    # 1e999
        raise ValueError(f"{text[:20]} is not a finite number")
    return x


def _canonical(obj) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()


class Checkpoint:
    """Finished units of a run, one JSON line each, after a header line with the run's
    fingerprint: ``load()`` gives what a previous run with the same fingerprint finished,
    ``add(name, value)`` appends (flushed, so that a killed parent loses at most the line being
    written), ``discard()`` removes the file once the run's report is written. Values must be
    JSON (the ledger's and the catalogue's records are). A path that exists but is not a regular
    file is refused.

    A checkpoint is data from disk like any other (docs/reliability.md, "Trust model for
    checkpoints and result files"): each record carries an HMAC-SHA256, with this user's key
    (``checkpoint_key``), over the fingerprint, the unit's name and its value, and is resumed only
    when that HMAC is right, the unit is one the run expects, the value is finite JSON within the
    reader's bounds (``MAX_CHECKPOINT_*``) and ``validate(name, value)`` accepts it (the caller's
    schema). Any other line is discarded, with one line through ``say`` (default: stderr) per
    load; its unit is computed again, and the file is rewritten with the accepted records only
    (``open``), so a bad record never survives into the next run. ``key``: the HMAC key (default
    ``checkpoint_key()``)."""

    def __init__(self, path, fingerprint: str, validate: Callable | None = None, say: Callable | None = None,
                 key: bytes | None = None):
        self.path, self.fingerprint = pathlib.Path(path), fingerprint
        self.validate, self.say = validate, say
        self._key, self._key_error = key, None
        self._fh = None
        self._noted = set()

    def bound_to(self, *settings) -> "Checkpoint":
        """The same file with the fingerprint extended by ``settings`` (JSON, ``str`` for the
        rest): a function that takes a checkpoint from its caller binds it to its own
        arguments, so that a record is resumed only by a run of the same settings whatever
        fingerprint the caller chose."""
        fp = hashlib.sha256(self.fingerprint.encode() + b"\0" + json.dumps(
            settings, sort_keys=True, default=str).encode()).hexdigest()
        return Checkpoint(self.path, fp, self.validate, self.say, self._key)

    @classmethod
    def of_file(cls, path, validate: Callable | None = None, say: Callable | None = None) -> "Checkpoint":
        """The checkpoint at ``path`` bound to the fingerprint its header names: to read back
        the records of another run (``ldaspark mutants --keep-killed RUN.partial.jsonl``). The
        fingerprint is taken on trust, the records are not: each is still resumed only with
        this user's HMAC over that fingerprint, its name and its value (``load``). Raises
        InputError for a path that is not a regular file or a header that is not one."""
        import stat
        flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(path, flags)
        except OSError as exc:
            raise InputError(f"checkpoint {path} cannot be read ({exc.strerror or exc})") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
            os.close(fd)
            raise InputError(f"checkpoint {path} is not a regular file")
        with os.fdopen(fd, "rb") as fh:
            head = fh.readline(4096)
        try:
            fp = json.loads(head.decode("utf-8"))["fingerprint"]
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError):
            fp = None
        if not isinstance(fp, str) or not _MAC_HEX.match(fp):
            raise InputError(f"checkpoint {path} has no header line {{\"fingerprint\": 64 hex digits}}")
        return cls(path, fp, validate, say)

    # --- authentication and checks of one record ------------------------------------------
    def _mac_key(self) -> bytes | None:
        if self._key is None and self._key_error is None:
            try:
                self._key = checkpoint_key()
            except CheckpointKeyError as exc:
                self._key_error = str(exc)
        return self._key

    def _mac(self, name, value) -> str:
        import hmac
        key = self._mac_key()
        if key is None:
            return ""
        msg = b"ldaspark-checkpoint-v1\0" + self.fingerprint.encode() + b"\0" + _canonical([name, value])
        return hmac.new(key, msg, hashlib.sha256).hexdigest()

    def _note(self, msg):
        (self.say or (lambda m: print(f"ldaspark: {m}", file=__import__("sys").stderr, flush=True)))(msg)

    def _why_not(self, name, value, units) -> str:
        """"" when (name, value) is a record this run would accept, else why not (the checks
        that do not need the HMAC: the writer applies them too)."""
        if not isinstance(name, str) or not name:
            return "the unit name is not a string"
        if units is not None and name not in units:
            return f"unit {name[:60]!r} is not one of this run's"
        try:
            text = _canonical(value)
        except (TypeError, ValueError) as exc:
            return f"the value is not finite JSON ({str(exc)[:60]})"
        if len(text) > MAX_CHECKPOINT_LINE - 200:
            return f"the value has {len(text)} bytes, more than the reader's bound"
        if _json_depth(text.decode("ascii")) > MAX_CHECKPOINT_DEPTH - 2:
            return "the value is nested more deeply than the reader's bound"
        if self.validate is not None:
            try:
                ok = self.validate(name, value)
            except Exception as exc:  # noqa: BLE001  (a schema says no in its own words)
                return f"not a valid record: {str(exc)[:100] or type(exc).__name__}"
            if ok is False:
                return "not a valid record"
        return ""

    def _parse(self, raw: bytes, units):
        """(name, value) of one line of the file, or (None, why it is discarded)."""
        import hmac
        if len(raw) > MAX_CHECKPOINT_LINE or not raw.endswith(b"\n"):
            return None, "longer than the reader's bound" if len(raw) > MAX_CHECKPOINT_LINE else "truncated"
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            return None, "not UTF-8"
        if _json_depth(text) > MAX_CHECKPOINT_DEPTH:
            return None, "nested more deeply than the reader's bound"
        try:
            rec = json.loads(text, parse_constant=_reject_constant, parse_float=_finite_float)
        except (ValueError, RecursionError) as exc:
            return None, f"not finite JSON ({str(exc)[:60]})"
        if not isinstance(rec, dict) or set(rec) != {"unit", "value", "mac"}:
            return None, "not a record {unit, value, mac}"
        name, value, mac = rec["unit"], rec["value"], rec["mac"]
        if not isinstance(mac, str) or not _MAC_HEX.match(mac):
            return None, "no HMAC"
        if not isinstance(name, str) or (units is not None and name not in units):
            return None, self._why_not(name, value, units)
        if self._mac_key() is None:
            return None, f"no key to check it ({self._key_error})"
        try:
            good = hmac.compare_digest(mac, self._mac(name, value))
        except (TypeError, ValueError):
            good = False
        if not good:
            return None, "wrong HMAC (edited, forged or written with another key or fingerprint)"
        why = self._why_not(name, value, units)       # the caller's schema, on authentic data only
        if why:
            return None, why
        return name, value

    # --- the file --------------------------------------------------------------------------
    def load(self, units=None, validate=None) -> dict:
        """{unit name: value} of the accepted records (``units``: the names this run expects,
        None: any; ``validate`` replaces the constructor's schema)."""
        if validate is not None:
            self.validate = validate
        units = None if units is None else set(units)
        if not os.path.lexists(self.path):
            return {}
        self._check_regular()
        flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            fd = os.open(self.path, flags)
        except OSError as exc:
            raise InputError(f"checkpoint {self.path} cannot be read ({exc.strerror or exc}); not touched") from None
        import stat
        out, bad, total = {}, [], 0
        if not stat.S_ISREG(os.fstat(fd).st_mode):      # before fdopen, which refuses a directory
            os.close(fd)
            raise InputError(f"checkpoint {self.path} exists and is not a regular file; not touched")
        with os.fdopen(fd, "rb") as fh:
            head = fh.readline(MAX_CHECKPOINT_LINE + 1)
            try:
                ok = json.loads(head.decode("utf-8")).get("fingerprint") == self.fingerprint
            except (ValueError, AttributeError, RecursionError):
                ok = False
            if not ok:
                self._note(f"checkpoint {self.path} was written by other code or for other settings: "
                           "not resumed")
                return {}
            total = len(head)
            lineno = 1
            while True:
                raw = fh.readline(MAX_CHECKPOINT_LINE + 1)
                if not raw:
                    break
                lineno += 1
                total += len(raw)
                if total > MAX_CHECKPOINT_BYTES:
                    bad.append(f"line {lineno} onwards: past {MAX_CHECKPOINT_BYTES} bytes")
                    break
                if len(raw) > MAX_CHECKPOINT_LINE:          # skip the rest of the long line
                    while raw and not raw.endswith(b"\n"):
                        raw = fh.readline(MAX_CHECKPOINT_LINE + 1)
                        total += len(raw)
                    bad.append(f"line {lineno}: longer than the reader's bound")
                    continue
                name, value = self._parse(raw, units)
                if name is None:
                    bad.append(f"line {lineno}: {value}")
                elif name not in out:
                    out[name] = value
        if bad:
            more = f" (and {len(bad) - 2} more)" if len(bad) > 2 else ""
            self._note(f"checkpoint {self.path}: {len(bad)} record(s) discarded and their units computed again: "
                       f"{'; '.join(bad[:2])}{more}")
        return out

    def _line(self, name, value) -> str:
        return json.dumps({"unit": name, "value": value, "mac": self._mac(name, value)}, allow_nan=False) + "\n"

    def _check_regular(self):
        import stat
        st = os.lstat(self.path)
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"checkpoint {self.path} exists and is not a regular file; not touched")

    def open(self, keep: dict):
        """Start the file anew with the header and ``keep`` (the units resumed), then append."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if os.path.lexists(self.path):
            self._check_regular()
        lines = [json.dumps({"fingerprint": self.fingerprint}) + "\n"]
        lines += [self._line(k, v) for k, v in keep.items()]
        atomic_write_text(self.path, "".join(lines))
        self._fh = open(self.path, "a", encoding="utf-8")
        return self

    def add(self, name: str, value):
        """Append a finished unit, unless the reader would refuse it (not finite JSON, too big,
        refused by the schema): then it is not recorded (one note), and a rerun computes it."""
        why = self._why_not(name, value, None)
        if why or self._mac_key() is None:
            if name not in self._noted:
                self._noted.add(name)
                self._note(f"checkpoint {self.path}: unit {name[:60]!r} not recorded "
                           f"({why or self._key_error}); a rerun computes it again")
            return
        self._fh.write(self._line(name, value))
        self._fh.flush()

    def close(self):
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def discard(self):
        self.close()
        with contextlib.suppress(FileNotFoundError):
            os.remove(self.path)


#: the HMAC domain of a signed document (a report read back, ``sign_document``): a checkpoint
#: record's MAC never verifies as a document's, nor one kind of document's as another's
_DOC_DOMAIN = b"ldaspark-signed-document-v1\0"
SIGNATURE = "signature"


def _document_mac(kind: str, doc: dict, key: bytes) -> str:
    import hmac
    body = {k: v for k, v in doc.items() if k != SIGNATURE}
    return hmac.new(key, _DOC_DOMAIN + kind.encode() + b"\0" + _canonical(body), hashlib.sha256).hexdigest()


def sign_document(kind: str, doc: dict, key: bytes | None = None) -> dict:
    """``doc`` (finite JSON) with a ``signature`` {scheme, mac}: an HMAC-SHA256 with this user's
    checkpoint key (``checkpoint_key``) over ``kind`` and the canonical JSON of the rest, as the
    checkpoints' records carry one. Without a trusted key the document is returned unsigned
    (a reader then treats it as data it cannot trust: ``document_signed`` is False)."""
    body = json.loads(_canonical({k: v for k, v in doc.items() if k != SIGNATURE}))   # as read back
    if key is None:
        try:
            key = checkpoint_key()
        except CheckpointKeyError:
            return body
    return dict(body, **{SIGNATURE: {"scheme": "hmac-sha256", "mac": _document_mac(kind, body, key)}})


def document_signed(kind: str, doc, key: bytes | None = None) -> bool:
    """True when ``doc`` carries a signature of ``kind`` by this user's key over exactly its
    other fields (``sign_document``); False for an unsigned, edited or forged document, one
    signed with another key or as another kind, or without a trusted key here."""
    import hmac
    if not isinstance(doc, dict):
        return False
    sig = doc.get(SIGNATURE)
    if not isinstance(sig, dict) or set(sig) != {"scheme", "mac"} or sig["scheme"] != "hmac-sha256" \
            or not isinstance(sig["mac"], str) or not _MAC_HEX.match(sig["mac"]):
        return False
    if key is None:
        try:
            key = checkpoint_key()
        except CheckpointKeyError:
            return False
    try:
        return hmac.compare_digest(sig["mac"], _document_mac(kind, doc, key))
    except (TypeError, ValueError):
        return False


def run_resumable(units: list[Unit], checkpoint: Checkpoint | None, where=None, jobs=None, retries=2,
                  on_done=None, mp_context=None, say=None, validate=None) -> dict:
    """``run_units`` with a checkpoint: units finished by an earlier run with the same fingerprint
    are taken from it and not run again; each unit finished now is appended as it comes in. On
    failure (``UnitsFailed``, Ctrl-C, ...) the checkpoint keeps everything finished. Only records
    of these units' names that pass ``validate(name, value)`` (the caller's schema: raise or
    return False to refuse) and the checkpoint's own checks are resumed (``Checkpoint``); notes
    on discarded records go to ``say`` (default stderr)."""
    done = {}
    if checkpoint is not None:
        if checkpoint.say is None and say is not None:
            checkpoint.say = say
        done = checkpoint.load([u.name for u in units], validate)
    done = {u.name: done[u.name] for u in units if u.name in done}
    if done and say is not None:
        say(f"resuming: {len(done)} of {len(units)} units from {checkpoint.path}")
    if checkpoint is not None:
        checkpoint.open(done)

    def finished(name, val):
        if checkpoint is not None:
            checkpoint.add(name, val)
        if on_done is not None:
            on_done(name, val)
    try:
        results = run_units([u for u in units if u.name not in done], where, jobs, retries, finished, mp_context)
    finally:
        if checkpoint is not None:
            checkpoint.close()
    results.update(done)
    return results
