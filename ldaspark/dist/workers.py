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
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from ..core.errors import InputError, LdasparkError


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
    """Refuse what cannot name a place to run work (before anything starts)."""
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise InputError(f"jobs must be a positive integer, got {jobs!r}")
    if where is None or where == "local" or is_address(where) or _is_client(where):
        return
    if isinstance(where, cf.Executor) or (hasattr(where, "submit") and callable(where.submit)):
        return
    raise InputError(f"where work runs must be 'local', a scheduler address such as tcp://host:8786, "
                     f"a distributed.Client or a concurrent.futures.Executor, got {where!r}")


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
            return cf.ProcessPoolExecutor(n, mp_context=self.mp_context)
        if is_address(w) or _is_client(w):
            if is_address(w):
                try:
                    import distributed
                except ImportError:
                    raise InputError("a Dask scheduler needs the dist extra: pip install \"ldaspark[dist]\"") from None
                try:
                    self.client = distributed.Client(w, timeout="20s", set_as_default=False)
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
            self.executor = cf.ProcessPoolExecutor(max(1, self.jobs or os.cpu_count() or 1),
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
            f = submit(fn, *args, **kwargs)
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
                    futs[place.executor.submit(u.fn, *u.args)] = u
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
def source_fingerprint(*config, dirs=()) -> str:
    """sha256 over this package's source files (and the ``*.py`` files under ``dirs``) and
    ``config`` (JSON): a checkpoint written by other code or for another configuration is never
    resumed from."""
    h = hashlib.sha256()
    pkg = pathlib.Path(__file__).resolve().parents[1]
    for root in (pkg, *map(pathlib.Path, dirs)):
        for p in sorted(root.rglob("*.py")):
            if "__pycache__" in p.parts:
                continue
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    h.update(json.dumps(config, sort_keys=True, default=str).encode())
    return h.hexdigest()


class Checkpoint:
    """Finished units of a run, one JSON line each, after a header line with the run's
    fingerprint: ``load()`` gives what a previous run with the same fingerprint finished,
    ``add(name, value)`` appends (flushed, so that a killed parent loses at most the line being
    written), ``discard()`` removes the file once the run's report is written. Values must be
    JSON (the ledger's and the catalogue's records are). A path that exists but is not a regular
    file is refused; a damaged line ends what is resumed."""

    def __init__(self, path, fingerprint: str):
        self.path, self.fingerprint = pathlib.Path(path), fingerprint
        self._fh = None

    def load(self) -> dict:
        if not os.path.lexists(self.path):
            return {}
        self._check_regular()
        out = {}
        with open(self.path, encoding="utf-8") as fh:
            head = fh.readline()
            try:
                if json.loads(head).get("fingerprint") != self.fingerprint:
                    return {}
            except (ValueError, AttributeError):
                return {}
            for line in fh:
                try:
                    rec = json.loads(line)
                    out[rec["unit"]] = rec["value"]
                except (ValueError, KeyError, TypeError):
                    break
        return out

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
        tmp = self.path.with_name(self.path.name + f".{os.getpid()}.tmp")
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(json.dumps({"fingerprint": self.fingerprint}) + "\n")
            for k, v in keep.items():
                fh.write(json.dumps({"unit": k, "value": v}) + "\n")
        os.replace(tmp, self.path)
        self._fh = open(self.path, "a", encoding="utf-8")
        return self

    def add(self, name: str, value):
        self._fh.write(json.dumps({"unit": name, "value": value}) + "\n")
        self._fh.flush()

    def close(self):
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def discard(self):
        self.close()
        with contextlib.suppress(FileNotFoundError):
            os.remove(self.path)


def run_resumable(units: list[Unit], checkpoint: Checkpoint | None, where=None, jobs=None, retries=2,
                  on_done=None, mp_context=None, say=None) -> dict:
    """``run_units`` with a checkpoint: units finished by an earlier run with the same fingerprint
    are taken from it and not run again; each unit finished now is appended as it comes in. On
    failure (``UnitsFailed``, Ctrl-C, ...) the checkpoint keeps everything finished."""
    done = checkpoint.load() if checkpoint is not None else {}
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
