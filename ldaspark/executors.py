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
* the units that finished are in ``UnitsFailed.results``; the paper lab's checkpoints, which
  record each finished unit as it comes in so that a rerun resumes, are built on ``run_units``
  in ``ldaspark.lab.checkpoint`` (the library never imports the lab);
* Ctrl-C (any exception in the parent) cancels every pending future, on the cluster too, and
  stops a local pool's workers.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from .core import validate as V
from .core.errors import InputError, LdasparkError
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

    def __init__(self, where, jobs, mp_context, inline_single=True, units=None):
        self.where, self.jobs, self.mp_context = where, jobs, mp_context
        self.inline_single = inline_single
        # a local pool of more workers than units forks them all (CPython's fork pools start
        # max_workers at once): ``verify --quick --jobs 64`` forked 64 for 18 units
        self.units = units
        self.client = None
        self.own_pool = False
        self.executor = self._open()

    def _open(self):
        w = self.where
        if w is None or w == "local":
            n = self._local_workers()
            if max(1, self.jobs or os.cpu_count() or 1) == 1 and self.inline_single:   # as asked, not capped
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

    def _local_workers(self) -> int:
        n = max(1, self.jobs or os.cpu_count() or 1)
        return max(1, min(n, self.units)) if self.units is not None else n

    @property
    def local_pool(self) -> bool:
        return self.own_pool

    def renew(self):
        if self.own_pool:
            _stop_pool(self.executor)
            self.executor = make_process_pool(self._local_workers(), mp_context=self.mp_context)

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


def _completed(futures, poll: float = 0.5):
    """The futures as they finish (``cf.as_completed``), a cancelled one included: a future that an
    executor cancelled without notifying its waiters (``cancel()`` with no
    ``set_running_or_notify_cancel()``, which the standard pools call but a user's Executor need
    not) is never done for ``as_completed``, and a run waited for it forever; here it is looked
    for every ``poll`` seconds and handed back, its ``result()`` raising CancelledError (the
    unit is reported failed by name). The poll only bounds how late such a future is seen; one
    ``as_completed`` per poll keeps the work linear in the number of futures (``cf.wait`` per
    finished future was quadratic)."""
    order = {f: i for i, f in enumerate(futures)}
    pending = set(futures)
    while pending:
        try:
            for f in cf.as_completed(pending, timeout=poll):
                pending.discard(f)
                yield f
        except cf.TimeoutError:
            stuck = sorted((f for f in pending if f.cancelled()), key=order.__getitem__)
            pending.difference_update(stuck)
            yield from stuck


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
    place = _Place(where, jobs, mp_context, units=len(units))
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
                for f in _completed(futs):
                    broken = handle(f, futs[f]) or broken
            except BaseException:
                place.cancel(list(futs))
                raise
            if broken:
                place.renew()
            pending.sort(key=lambda u: names.index(u.name))
    finally:
        place.close()
    # in the units' order, whatever the order they finished in (UnitsFailed lists them so)
    return ({n: results[n] for n in names if n in results}, {n: failed[n] for n in names if n in failed})


def add_scheduler_argument(parser, action="store"):
    """``--scheduler ADDRESS``: the one command-line option naming where work runs (``action``:
    argparse's, for a command that needs to know the option was given)."""
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS", action=action,
                        help="run the work units on a Dask cluster (e.g. tcp://host:8786; needs the dist "
                             "extra) instead of local worker processes; results do not depend on it")


#: the checkpoint names that moved to the paper lab (``ldaspark.lab.checkpoint``, round 5): an
#: access here says where they went, without importing the lab (the library never does)
MOVED_TO_LAB = frozenset((
    "Checkpoint", "CheckpointKeyError", "MAX_CHECKPOINT_BYTES", "MAX_CHECKPOINT_DEPTH", "MAX_CHECKPOINT_LINE",
    "SIGNATURE", "checkpoint_key", "document_signed", "run_resumable", "sign_document", "source_fingerprint"))


def __getattr__(name):
    if name in MOVED_TO_LAB:
        raise AttributeError(f"ldaspark.executors.{name} moved to ldaspark.lab.checkpoint.{name} "
                             "(docs/changelog.md)", name=name, obj=__name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}", name=name, obj=__name__)
