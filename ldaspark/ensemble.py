"""Ensembles: many initial conditions at once, in parallel over any ``concurrent.futures.Executor``.

    from ldaspark.ensemble import ensemble_integrate
    res = ensemble_integrate(system, "lobatto-iiia-iiib-2", t0, Q0, V0, h=0.05, n_steps=10**6,
                             every=100)                      # process pool over all cores
    res.energy.shape                                         # (J + 1, samples)

Any executor works (``executor=``): the default is a ``ProcessPoolExecutor`` over all cores,
created and shut down here; a thread pool, or a cluster's executor, are passed the same way,
e.g. Dask: ``client = distributed.Client(...); ensemble_integrate(..., executor=client.get_executor())``.
A task carries the compiled system's generated source text (``ldaspark.compiled.fast.CompiledSystem``),
not a file path, so a remote worker builds (or loads from its numba cache) the same kernels.
The parent compiles first, so local workers load the cached machine code instead of compiling.

Systems the fast path cannot compile run the generic path in the workers (one notice line).
"""
from __future__ import annotations

import copy
import os
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from .core.backend import Backend
from .core.errors import InputError, LdasparkError
from .core.result import float_array, save_indices
from .models import arguments


@dataclass
class EnsembleResult:
    """Samples of every run: t (S,), q and v (R, S, n), energy (R, S), constraint (R, S, m), psi;
    stats: one dict per run (Newton counters, path); seconds: wall time of the whole ensemble.
    Deprecated with ``ensemble_integrate`` in favour of ``ldaspark.integrate``'s batched ``Result``
    (``result.from_ensemble`` makes one of it); the first six fields are those of ``Result``, in its
    order (``ldaspark.core.result.LEADING_FIELDS``)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    constraint: np.ndarray
    #: (R, S - 1, s, m) stage multipliers of (21) of each run's saved steps (None: the semi-implicit kernel)
    psi: Optional[np.ndarray] = None
    stats: list = field(default_factory=list)
    seconds: float = 0.0
    #: the names of the coordinates q as printed (a single run's ``Result.coordinate_names``), which
    #: ``from_ensemble`` gives each member (its files keep them, as the single runs' files do)
    coordinate_names: Optional[list] = None


class _KernelBlocks:
    """``run_kernels`` as the block engine that ``ldaspark.core.chunks.run_in_blocks`` drives: a member runs in
    the blocks of COMPILED_CHUNK steps of its single ``integrate`` run (the predictor restarts at
    each block's start), so the two agree bit for bit past one block, and a worker's kernel call
    returns between blocks."""

    chunked = True
    label = "compiled"

    def __init__(self, cs, spec, h, compensated, tol):
        from types import SimpleNamespace
        self.cs, self.spec, self.compensated, self.tol = cs, spec, compensated, tol
        self.prep = SimpleNamespace(prob=SimpleNamespace(h=h))      # what _chunked reads of a run

    def run(self, prep, start, n_steps, every):
        from types import SimpleNamespace
        from .compiled.runner import run_kernels
        t0, q0, v0 = start
        fs = run_kernels(self.cs, self.spec, t0, q0, v0, prep.prob.h, n_steps, every, self.compensated, self.tol)
        return SimpleNamespace(t=fs.t, q=fs.q, v=fs.v, energy=fs.energy, constraint=fs.constraint, psi=fs.psi,
                               stats=fs.stats, engine=self.label)

    def member(self, t0, q0, v0, n_steps, every, boundaries=None) -> tuple:
        """(t, q, v, energy, constraint, stats, psi) of one member, as ``_fast_task`` returns it."""
        from .core.chunks import run_in_blocks
        r = run_in_blocks(self, self.prep, (t0, q0, v0), n_steps, every, boundaries=boundaries)
        return (r.t, r.q, r.v, r.energy, r.constraint, r.stats, r.psi)


def _fast_task(cs, spec, t0, ics, h, n_steps, every, compensated, tol):
    blocks = _KernelBlocks(cs, spec, h, compensated, tol)
    return [blocks.member(t0, q0, v0, n_steps, every) for q0, v0 in ics]


def _generic_task(system, method, t0, ics, h, n_steps, every, tol):
    from .compiled.fast import generic_integrate
    out = []
    for q0, v0 in ics:
        fs = generic_integrate(system, method, t0, q0, v0, h, n_steps, every, tol)
        out.append(tuple(fs) + (fs.psi,))
    return out


class RunSpec:
    """One ensemble member set: (system, method) with initial data rows; used by ``run_many``
    to put several methods' runs into one executor (Fig. 4: 3 methods x 10 initial data)."""

    def __init__(self, system, method, t0, Q0, V0, h, n_steps, every=1, compensated=True, tol=None,
                 kernel="auto", **unknown):
        if unknown:
            _refuse_unknown("RunSpec", RunSpec.__init__, unknown)
        from .core import validate
        from .core.validate import check_newton_options, check_storage, count, real_number
        from .compiled.fast import n_samples
        system, _ = arguments.as_system(system, "RunSpec: system")     # a scene name as integrate takes it
        from .core.tableau import SparkTableau
        if not isinstance(method, (str, SparkTableau)):
            raise InputError(f"RunSpec: method must be a method name or a SparkTableau, got {validate._describe(method)}")
        validate.check_choice(kernel, "RunSpec: kernel", ("auto", "spark"))
        validate.flag(compensated, "RunSpec: compensated")
        for nm, x in (("Q0", Q0), ("V0", V0)):
            try:
                size = np.asarray(x, dtype=object).size
            except (ValueError, TypeError):
                size = 1                       # ragged: real_vector says so
            if size:                           # no rows: refused below with its own message
                validate.real_vector(x, f"RunSpec: {nm}")
        validate.real_number(t0, "RunSpec: t0")
        validate.real_number(h, "RunSpec: h")          # h = 0: refused below ("finite and nonzero")
        try:
            Q0 = np.atleast_2d(np.asarray(Q0, dtype=float))
            V0 = np.atleast_2d(np.asarray(V0, dtype=float))
            t0, h = float(real_number(t0, "t0")), float(real_number(h, "h"))
        except (TypeError, ValueError) as exc:
            raise InputError(f"t0, h, Q0 and V0 must be numbers: {exc}") from None
        if Q0.ndim != 2 or Q0.shape != V0.shape or Q0.shape[1] != system.n:
            raise InputError(f"Q0 and V0 must both have shape (runs, {system.n}), got {Q0.shape}, {V0.shape}")
        if len(Q0) == 0:
            raise InputError("Q0 and V0 have no rows: an ensemble needs at least one initial point")
        count(n_steps, "n_steps")          # bounded as every run (10**12 steps would never end)
        count(every, "every")
        if not (np.isfinite(h) and h != 0 and np.isfinite(t0)):
            raise InputError(f"h must be finite and nonzero and t0 finite, got h = {h}, t0 = {t0}")
        validate.step_advances(t0, h, n_steps, None, what="RunSpec: h")
        check_newton_options(tol, 1)
        validate.check_tol_resolvable(tol, None, what="RunSpec: tol")     # the compiled kernels: float64
        check_storage(n_samples(int(n_steps), int(every)) * len(Q0), 2 + 2 * system.n + system.m,
                      what="the ensemble samples")
        self._notes = self._check_members(system, t0, Q0, V0)
        from .compiled.runner import checked_kernel_spec
        checked_kernel_spec(method, kernel)  # an unknown method name (or kernel='spark' of a comparator) here
        self.system, self.method, self.t0, self.Q0, self.V0 = system, method, t0, Q0, V0
        self.h, self.n_steps, self.every, self.compensated, self.tol, self.kernel = (
            h, int(n_steps), int(every), bool(compensated), tol, kernel)

    @staticmethod
    def _check_members(system, t0, Q0, V0) -> list:
        """The set-up checks of ``integrate`` for every member: finite data, (4) regular with K of
        full rank, consistent v0 (an inconsistent v0 would otherwise run, its energy jumping in
        the first step); the error names the member. Returns each member's notes (a singular
        L_vv of (5) there, said with the results as a single run says it)."""
        from .core.backend import Backend
        from .core.validate import initial_point
        notes = []
        for j, (q0, v0) in enumerate(zip(Q0, V0)):       # the one initial-point check, per member
            notes.append({})
            initial_point(system, Backend(None), t0, q0, v0, member=f"ensemble member {j}: ", notes=notes[-1])
        return notes

    def finish(self, ens):
        """What a single ``integrate`` run of each member says besides its numbers: the stats of
        the compiled engine's Result (``engines.compiled``: ``root_finder`` as asked for with what
        ran, ``rescued_steps``, ``engine`` "compiled-lf2" for the semi-implicit kernel of (25)),
        and the LdasparkWarning of a singular L_vv of (5) at the member's initial point."""
        from .core.options import IntegrationOptions
        from .core.validate import warn_singular_lvv
        if self._kernels is None:
            # the generic path of a system the kernels cannot run: the generic engine's
            # ``root_finder``, the Newton asked for as that engine honours it
            from .compiled.fast import _resolve
            support = "generic" if _resolve(self.method)[0] == "spark" else "comparator"
            root = IntegrationOptions.checked(tol=self.tol).newton.check_for(support).describe()
            for st in ens.stats:
                st.setdefault("root_finder", dict(root))
                st["engine"] = support          # a comparator's single run says "comparator"
        else:
            asked = IntegrationOptions.checked(tol=self.tol).newton.describe()
            support = "compiled-lf2" if self._kernels[1][0] == "lf2" else "compiled"
            for st in ens.stats:
                fast = st.get("path") == "fast"
                st["root_finder"] = dict(asked, runs=st.get("newton_kind", "generic") if fast else "generic")
                st.setdefault("rescued_steps", st.get("generic_steps", 0))
                if fast:
                    st["engine"] = support
        for notes in self._notes:
            if notes:
                warn_singular_lvv(self.system, notes, stacklevel=3)

    def tasks(self, chunk):
        """(callable, args) per chunk of initial data; compiles in this process first."""
        from .compiled.fast import LF2_VARIANTS, NotCompilableError, _notice, compile_system, kernel_spec
        from .compiled.runner import run_kernels
        spec = kernel_spec(self.method, self.kernel)
        rows = list(zip(self.Q0, self.V0))
        chunks = [rows[i:i + chunk] for i in range(0, len(rows), chunk)]
        self._kernels = None
        try:
            cs = compile_system(self.system)
            # warm the numba cache here so that local workers load instead of compile
            try:
                run_kernels(cs, spec, self.t0, self.Q0[0], self.V0[0], self.h, 1, 1, self.compensated, self.tol)
            except (NotCompilableError, InputError):
                raise           # a refusal: before any work is sent, as before
            except LdasparkError:
                # member 0's first step failed (NewtonError, NonFiniteError): its task reports it, by
                # name, as any other member's failure (UnitsFailed; integrate's executor path then
                # runs the loop of single runs); raised here it was a bare kernel error that named
                # no member and ended integrate(q0=(B, n), executor=..., guard=False), whose loop
                # of single runs rescues the step
                pass
            self._kernels = (cs, spec)
        except NotCompilableError as exc:
            if spec[0] == "lf2" and spec[2] in LF2_VARIANTS:
                # a comparator of Fig. 4 on a system not of the mechanical form: the generic path
                # takes the modified method of 8.4 and refuses the leapfrog forms of (25) and (26),
                # which are refused here, before any work is sent (an InputError in every worker was
                # reported as failed work units): the generic comparator's first step of member 0
                from .core.comparators import integrate_comparator
                try:
                    integrate_comparator(spec[2], self.system, self.t0, self.Q0[0], self.V0[0], self.h, 1,
                                         tol=self.tol)
                except InputError:
                    raise
                except LdasparkError:
                    pass            # a step failure: the member's task reports it, as before
            _notice(str(exc))
            sysm = copy.copy(self.system)
            sysm._compiled = {}          # lambdified functions do not pickle; rebuilt in the worker
            return [(_generic_task, (sysm, self.method, self.t0, c, self.h, self.n_steps, self.every, self.tol))
                    for c in chunks]
        return [(_fast_task, (cs, spec, self.t0, c, self.h, self.n_steps, self.every, self.compensated, self.tol))
                for c in chunks]


    def rerun(self, q0, v0, n_steps):
        """The first ``n_steps`` of the member from (q0, v0) again with every step kept, on the path
        its task ran (the kernels, or the generic path of a system that does not compile)."""
        if self._kernels is not None:
            # the blocks of the run it judges (``_chunked``'s boundaries), as a single run's guard
            from types import SimpleNamespace
            cs, spec = self._kernels
            t, q, v, energy, constraint, stats, psi = _KernelBlocks(cs, spec, self.h, self.compensated, self.tol).member(
                self.t0, q0, v0, n_steps, 1, boundaries=self.every)
            return SimpleNamespace(t=t, q=q, v=v, energy=energy, constraint=constraint, stats=stats, psi=psi)
        from .compiled.fast import generic_integrate
        return generic_integrate(self.system, self.method, self.t0, q0, v0, self.h, n_steps, 1, self.tol)

    def saddle_check(self, k, ens):
        """The det (4) monitor of a single ``integrate`` run (``solve._saddle_scan``) on every member
        of this spec's ensemble ``ens``: the kernel tasks solve (21) with no such check and go on
        across the singular set of (4) on another branch; a member whose det (4) changed sign
        raises SingularSaddleError naming the spec, the member and the step."""
        from .compiled.fast import _resolve
        from .core.errors import SingularSaddleError
        kind, _, name = _resolve(self.method)
        if kind != "spark" or not _saddle_may_change_sign(self.system):
            return
        for r, (q0, v0) in enumerate(zip(self.Q0, self.V0)):
            i = first_saddle_crossing(self.system, ens.t, ens.q[r], ens.v[r], self.n_steps, self.every,
                                      lambda n: self.rerun(q0, v0, n))
            if i is not None:
                raise SingularSaddleError(f"run_many: spec {k} ({name}), member {r}: "
                                          f"{saddle_crossing(i, self.t0 + i * self.h, self.h)}")

    def judge(self, k, ens):
        """The step-acceptance guard (``ldaspark.core.guard.judge``) on every member of this spec's
        ensemble ``ens`` (spec number k of ``run_many``): each member's stats get the guard's
        counters; a member with another root of (21) at some step raises RootMismatchError naming
        the spec, the member, the step and both roots. A comparator of sections 7-8 (the Fig. 4
        variants of LF2) is judged with its own step from a fresh start (``ComparatorSafeRoot``),
        as its single ``integrate`` run is."""
        from types import SimpleNamespace
        from .compiled.fast import _resolve
        from .core import guard
        from .core.rootfinder import MAX_ITER_DEFAULT
        kind, what, name = _resolve(self.method)
        if kind != "spark":
            # the safe root of the single run's engine (it had no guard here: guard=True was
            # accepted and the members said guard: False)
            from .core.options import IntegrationOptions
            from .core.comparators import ComparatorSafeRoot
            safe = ComparatorSafeRoot(self.system, SimpleNamespace(name=name, h=self.h),
                                      IntegrationOptions.checked(tol=self.tol))
        else:
            safe = guard.SparkSafeRoot(self.system, what, None, self.tol, MAX_ITER_DEFAULT, self.h)
        for r, (q0, v0) in enumerate(zip(self.Q0, self.V0)):
            member = SimpleNamespace(t=ens.t, q=ens.q[r], v=ens.v[r], energy=ens.energy[r])
            st, cut = guard.judge(member, self.every, self.h, lambda n, state, before: safe(n, state, None, before),
                                  lambda n: self.rerun(q0, v0, n), 2 + 2 * self.system.n + self.system.m, self.tol)
            ens.stats[r].update(st)
            if cut is not None:
                n, err, _ = cut
                raise guard.RootMismatchError(f"run_many: spec {k} ({name}), member {r}: {err}", step=n, time=err.time)


def default_executor(max_workers=None):
    from .core.lifecycle import make_process_pool
    return make_process_pool(max_workers=max_workers or os.cpu_count() or 1)


#: options of ``integrate`` that a RunSpec does not take (its members run in float64 from (Q0, V0)
#: without them), with the name a RunSpec gives the same thing where it has one
_INTEGRATE_ONLY = {"save_every": "every", "t_span": None, "t_end": None, "engine": None, "dps": None,
                   "dense_output": None, "events": None, "params": None, "raise_on_failure": None, "newton": None,
                   "project": None, "executor": None, "energy_jump": None, "max_stages": None, "q0": "Q0",
                   "v0": "V0"}


def _refuse_unknown(what, fn, unknown: dict) -> None:
    """An option ``fn`` (RunSpec, run_many) does not take: one InputError naming it, the closest
    option, or what runs an ensemble with an option of ``integrate`` (was a TypeError, or for an
    option of integrate silently nowhere to go)."""
    import difflib
    import inspect
    known = [p for p, par in inspect.signature(fn).parameters.items()
             if p != "self" and par.kind not in (par.VAR_KEYWORD, par.VAR_POSITIONAL)]
    key = sorted(map(str, unknown))[0]
    if key in _INTEGRATE_ONLY:
        alias = _INTEGRATE_ONLY[key]
        hint = (f" (a RunSpec calls it {alias})" if alias else
                "; ldaspark.integrate(system, method, q0=Q0, v0=V0, executor=...) runs an ensemble with it")
        raise InputError(f"{what} does not take integrate's option {key!r}{hint}; the options are "
                         f"{', '.join(known)}")
    close = difflib.get_close_matches(key, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise InputError(f"{what}: unknown option {key[:40]!r}{hint}; the options are {', '.join(known)}")


def run_many(specs, executor=None, max_workers=None, chunk=1, progress=None, where=None, guard=True, **unknown):
    """Run several ensembles (`RunSpec` objects) through one executor.

    Parameters
    ----------
    specs : iterable of RunSpec
        Each a (system, method) with rows of initial data, a step size and a step count.
    executor : concurrent.futures.Executor, optional
        Kept for compatibility: the same as ``where`` with an executor.
    max_workers : int, optional
        Size of the local process pool (``where`` None or "local"; default: all cores); refused
        with another executor, which runs the tasks on its own workers.
    chunk : int, optional
        Initial-data rows per task.
    progress : callable, optional
        ``progress(done, total)`` after each finished task.
    where : str, distributed.Client or Executor, optional
        Where the tasks run: a Dask scheduler address, a ``distributed.Client``, or any
        ``concurrent.futures.Executor`` (``ldaspark.executors``).
    guard : bool, optional
        The step-acceptance guard (``ldaspark.core.guard``, on by default) on every member, in
        this process once the tasks are done: a step with another root of (21) raises
        RootMismatchError naming the spec, the member and the step; each member's stats get
        the guard's counters.
    **unknown
        Any other keyword is refused with an `InputError` naming the closest option (a
        misspelt option must not be a raw TypeError).

    Returns
    -------
    list of EnsembleResult
        One per spec: t (S,), q and v (R, S, n), energy (R, S), constraint (R, S, m), psi
        (R, S - 1, s, m; None for the semi-implicit kernel of (25)), stats (one dict per row).

    Raises
    ------
    InputError
        For invalid specs or options.

    Examples
    --------
    >>> from concurrent.futures import ThreadPoolExecutor
    >>> import ldaspark
    >>> from ldaspark.ensemble import RunSpec
    >>> sc = ldaspark.get_scene("skate")
    >>> spec = RunSpec(sc.system, "gauss-2", 0.0, [sc.q0, sc.q0], [sc.v0, sc.v0], 0.1, 10)
    >>> with ThreadPoolExecutor(1) as ex:
    ...     (out,) = ldaspark.run_many([spec], where=ex)
    >>> out.q.shape
    (2, 11, 3)
    """
    from .core.validate import _describe, callable_or_none, check_executor, count, flag
    from .executors import check_where
    if unknown:
        _refuse_unknown("run_many", run_many, unknown)
    flag(guard, "run_many: guard")
    if executor is not None and where is not None:
        raise InputError("give executor or where, not both")
    place = executor if executor is not None else where
    if max_workers is not None and place is not None and not _is_local(place):
        # the executor or cluster given runs the tasks on its own workers: refused, not ignored
        raise InputError("max_workers sizes the local process pool (where=None or 'local'); the executor given "
                         "runs the tasks on its own workers")
    check_executor(executor)
    count(chunk, "chunk", 1, 10 ** 9)
    if max_workers is not None:
        count(max_workers, "max_workers", 1, 1024)
    callable_or_none(progress, "progress")
    check_where(where)
    if isinstance(specs, (str, bytes, dict, RunSpec)) or not hasattr(specs, "__iter__"):
        raise InputError(f"run_many needs a list of RunSpec objects, got {_describe(specs)}")
    t_start = time.perf_counter()
    specs = list(specs)
    if not specs:
        raise InputError("run_many needs at least one RunSpec")
    plan, names = [], []
    for k, sp in enumerate(specs):
        if not isinstance(sp, RunSpec):
            raise InputError(f"run_many needs RunSpec objects, got {type(sp).__name__} at position {k}")
        first = 0
        for fn, args in sp.tasks(chunk):
            plan.append((k, fn, args))
            # a failed task names its spec and members, as the guard and the det (4) monitor do
            # (its position in the plan named neither: task 3 of two specs, chunk 2, was spec 1's
            # members 2-3)
            last = first + len(args[3]) - 1
            names.append(f"spec {k}, member {first}" if last == first else f"spec {k}, members {first}-{last}")
            first = last + 1
    results = _run_plan(plan, len(specs), executor if executor is not None else where, max_workers, progress,
                        check=_task_output, names=names)
    seconds = time.perf_counter() - t_start
    out = []
    for sp, rs in zip(specs, results):
        t = rs[0][0]
        out.append(EnsembleResult(t, np.array([r[1] for r in rs]), np.array([r[2] for r in rs]),
                                  np.array([r[3] for r in rs]), np.array([r[4] for r in rs]),
                                  psi=None if any(r[6] is None for r in rs) else np.array([r[6] for r in rs]),
                                  stats=[r[5] for r in rs], seconds=seconds,
                                  coordinate_names=[str(x) for x in sp.system.q]))
    for k, (sp, ens) in enumerate(zip(specs, out)):
        sp.saddle_check(k, ens)         # before the guard, in the order of a single run (``_drive_blocks``)
        if guard:
            sp.judge(k, ens)
        else:
            for st in ens.stats:
                st["guard"] = False
    for sp, ens in zip(specs, out):     # once every member ended well, as a single run's warning
        sp.finish(ens)
    return out


def _run_plan(plan, n_specs, executor=None, max_workers=None, progress=None, check=None, names=None):
    """Run the (k, fn, args) tasks where ``executor`` says (``ldaspark.executors.run_units``:
    a worker that dies gets its task retried, Ctrl-C cancels what is pending and stops a pool
    created here); results grouped by k, in plan order whatever the order of completion.
    ``check(output, args, executor)``: a task's output checked (``_task_output``) before it is
    grouped. ``names``: each task's name in a failure (``UnitsFailed``; default its position)."""
    from .executors import Unit, run_units
    names = [str(i) for i in range(len(plan))] if names is None else list(names)
    units = [Unit(names[i], fn, tuple(args)) for i, (k, fn, args) in enumerate(plan)]
    count = 0

    def done(name, val):
        nonlocal count
        count += 1
        if progress is not None:
            progress(count, len(units))
    # the local pool (where None or "local") has max_workers workers, all cores by default
    res = run_units(units, executor, (max_workers or os.cpu_count() or 1) if _is_local(executor) else None,
                    on_done=done)
    results = [[] for _ in range(n_specs)]
    for i, (k, _, args) in enumerate(plan):
        results[k].extend(res[names[i]] if check is None else check(res[names[i]], args, executor))
    return results


def _is_local(where) -> bool:
    """``where`` names the local process pool made here (None or "local", ``executors._Place``)."""
    return where is None or (isinstance(where, str) and where == "local")


def _task_output(val, args, executor):
    """A task's output as ``_fast_task`` / ``_generic_task`` return it: a list of ``rows`` runs,
    each (t, q, v, energy, constraint, stats, psi). An executor whose futures hand back anything
    else (a user's Executor subclass) is one LdasparkError naming it, never a TypeError or an
    IndexError while the members are assembled."""
    from .core.errors import LdasparkError
    from .core.validate import _describe
    rows = len(args[3])             # the task's initial data (``RunSpec.tasks``)
    if not (isinstance(val, list) and len(val) == rows
            and all(isinstance(r, tuple) and len(r) == 7 and isinstance(r[5], dict) for r in val)):
        from .executors import describe
        raise LdasparkError(f"{describe(executor)} returned {_describe(val)} for a task of {rows} ensemble member(s), "
                            "not their runs")
    return val


def ensemble_integrate(system, method, t0, Q0, V0, h, n_steps, every=1, compensated=True, tol=None,
                       executor=None, max_workers=None, chunk=1, kernel="auto", progress=None,
                       guard=True) -> EnsembleResult:
    """Deprecated: ``ldaspark.integrate(system, method, q0=Q0, v0=V0, executor=...)`` runs an
    initial-data ensemble (a batched Result); this is the same run with a DeprecationWarning."""
    import warnings
    warnings.warn("ensemble_integrate is deprecated: use ldaspark.integrate(system, method, q0=Q0, v0=V0, "
                  "executor=...)", DeprecationWarning, stacklevel=2)
    return run_ensemble(system, method, t0, Q0, V0, h, n_steps, every, compensated, tol, executor, max_workers,
                        chunk, kernel, progress, guard)


def run_ensemble(system, method, t0, Q0, V0, h, n_steps, every=1, compensated=True, tol=None,
                 executor=None, max_workers=None, chunk=1, kernel="auto", progress=None, guard=True) -> EnsembleResult:
    """Integrate ``system`` from every row of (Q0, V0) with the fast path (``ldaspark.compiled.fast``),
    in parallel over ``executor`` (default: a process pool over all cores). ``chunk`` initial
    data per task."""
    from .core.validate import count
    count(chunk, "chunk", 1, 10 ** 9)
    spec = RunSpec(system, method, t0, Q0, V0, h, n_steps, every, compensated, tol, kernel)
    return run_many([spec], executor=executor, max_workers=max_workers, chunk=chunk, progress=progress, guard=guard)[0]


# --- the det (4) monitor of a run (``solve._saddle_scan``, ``RunSpec.saddle_check``) ---------------------------
def _saddle_may_change_sign(system) -> bool:
    """Whether det (4) can change sign along a run: not for the mechanical form with a constant
    symmetric positive definite M (det (4) = det M det(-K M^-1 K^T) keeps the sign (-1)^m wherever
    K has full rank); otherwise (L_vv depending on (t, q, v), K on v, an indefinite M) it can."""
    from .compiled import fast
    try:
        cs = fast.compile_system(system)
    except LdasparkError:
        return True
    return not (cs.form == "mechanical" and cs.mass_positive_definite)


def _saddle_signs(system, t, Q, V) -> np.ndarray:
    """sign(det (4)) at the points (t[j], Q[j], V[j]) (0 where it is not finite), as
    ``core.spark._saddle_sign`` point by point (~50 us a point, 5x a compiled step of a small
    system), here with L_vv and K evaluated on all points at once (numpy) and one batched slogdet."""
    from .core import gensource
    from .core.spark import _saddle_sign
    n, m, N = system.n, system.m, len(t)
    try:
        f = system._compiled.get(("saddle", "numpy-points"))
        if f is None:
            args = [system.t] + list(system.q) + list(system.v) + list(system.params)
            f = system._compiled[("saddle", "numpy-points")] = gensource.lambdify(
                args, [system.L_vv.tolist(), system.k_v.tolist()], "numpy", order="none")
        pv = [float(x) for x in system._param_arg_values(None)] if system.params else []
        with np.errstate(all="ignore"):
            Lvv, kv = f(np.asarray(t, float), *np.asarray(Q, float).T, *np.asarray(V, float).T, *pv)
            S = np.zeros((N, n + m, n + m))
            for a in range(n):
                for b in range(n):
                    S[:, a, b] = Lvv[a][b]          # an array over the points, or a constant
            for l in range(m):
                for a in range(n):
                    S[:, n + l, a] = S[:, a, n + l] = kv[l][a]
            sgn = np.linalg.slogdet(S)[0]
        return np.where(np.isfinite(sgn), sgn, 0.0)
    except (LdasparkError, TypeError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        bk = Backend(None)       # what numpy does not evaluate on arrays: point by point
        return np.array([_saddle_sign(system, bk, t[j], Q[j], V[j]) for j in range(N)], dtype=float)


def saddle_crossing(k: int, tk: float, h: float) -> str:
    """The message of a step k from tk that crossed the singular set of (4), as the block engines
    and ``run_many`` say it (the stepping engines' ``core.spark.march`` adds its option)."""
    return (f"step {k} (t = {tk:.6g} -> {tk + h:.6g}) crossed the singular set of the saddle matrix (4): "
            "det (4) changed sign, so the step solved (21) on the wrong branch or the solution left the region "
            "where (4) holds")


def first_saddle_crossing(system, t, Q, V, n_steps, every, rerun) -> Optional[int]:
    """The first step whose end point has another sign of det (4) than the start, or None, on a
    whole run of ``n_steps`` sampled every ``every`` steps (``save_indices``); ``rerun(n)``: the
    first n steps with every step kept, to name the step between two samples (``_saddle_scan``)."""
    signs = _saddle_signs(system, t, Q, V)
    change = np.nonzero(signs[1:] != signs[0])[0] if signs[0] else ()
    if not len(change):
        return None
    j = int(change[0]) + 1
    if every == 1:
        return j - 1
    at = save_indices(n_steps, every)
    steps = rerun(int(at[j]))
    fine = _saddle_signs(system, float_array(steps.t), float_array(steps.q), float_array(steps.v))
    later = np.nonzero(fine[int(at[j - 1]) + 1:] != signs[0])[0]
    return (int(later[0]) + int(at[j - 1]) + 1 if len(later) else int(at[j])) - 1
