"""Running report sections as independent jobs over worker processes.

A section module may expose, besides ``run_default(outdir)``,

* ``jobs(full=False) -> [(key, function_name, args[, cost])]``: independent pieces of work; the
  function is looked up by name in the section's module (in a worker process), ``args`` must be
  picklable, ``cost`` is a rough CPU-seconds estimate used to start the longest jobs first;
* ``write(results, outdir, full=False, clock=None, command=None)``: builds the section's files
  from ``{key: result}`` in the parent process.

``run_sections`` pools the jobs of all sections in one ``ProcessPoolExecutor``, longest first, so
that both cores stay busy until the end, and writes each section as soon as its last job is in.
A section without ``jobs`` runs ``run_default`` as one job.
"""
from __future__ import annotations

import concurrent.futures as cf
import importlib
import time

from .timing import Clock, _cpu


class InlineExecutor(cf.Executor):
    """Runs each submitted call at once, in this process (inside a worker of the main job, where
    a nested process pool would only oversubscribe the cores)."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001  (delivered through the future, as a pool would)
            f.set_exception(exc)
        return f


def run_job(module_name, fn_name, args):
    """Worker side: (result, wall seconds, CPU seconds) of ``module.fn(*args)``."""
    t, c = time.perf_counter(), _cpu()
    mod = importlib.import_module(module_name)
    out = getattr(mod, fn_name)(*args)
    return out, time.perf_counter() - t, _cpu() - c


class SectionTiming:
    """What a section's report states about the run that wrote it (duck-types ``Clock``)."""

    def __init__(self, wall, cpu, shared=False):
        self.wall, self.cpu, self.shared = wall, cpu, shared


# jobs that run the compiled (numba) path, by section module: they are started after every other
# job and after PRELUDE, so that the kernels compile once (in PRELUDE's worker, while the other
# worker runs mpmath jobs) and the workers then load them from numba's cache
COMPILED_ATTR = "COMPILED_JOBS"
PRELUDE = ("prelude", ("compile-kernels",), "ldaspark.compiled.fast", "warm_kernels", ())


def plan(modules, outdir, full=False):
    """[(cost, section, key, module name, function name, args)]: PRELUDE first if any job runs
    the compiled path, then the other jobs, then the compiled-path jobs, each group longest first."""
    out = []
    for name, mod in modules.items():
        if hasattr(mod, "jobs") and hasattr(mod, "write"):
            for j in mod.jobs(full):
                key, fn, args = j[:3]
                cost = j[3] if len(j) > 3 else 1.0
                out.append((cost, name, key, mod.__name__, fn, tuple(args)))
        else:
            out.append((getattr(mod, "DEFAULT_COST", 60.0), name, ("run_default",), mod.__name__,
                        "run_default", (outdir,)))
    compiled = {m.__name__: set(getattr(m, COMPILED_ATTR, ())) for m in modules.values()}
    uses = lambda p: p[4] in compiled.get(p[3], ())          # noqa: E731
    out = sorted(out, key=lambda p: (uses(p), -p[0]))
    if any(uses(p) for p in out):
        out.insert(0, (0.0,) + PRELUDE)
    return out


def run_sections(modules, outdir, full=False, workers=2, say=print, where=None):
    """Run every section's jobs over ``workers`` processes (or where ``where`` says, e.g. a Dask
    scheduler: ``ldaspark.executors``); write each section when complete.
    Returns {section: {"jobs", "cpu", "wall"}} (wall = seconds from the start until written)."""
    from ...executors import describe, open_executor
    clock = Clock()
    jobs = plan(modules, outdir, full)
    left = {name: sum(1 for p in jobs if p[1] == name) for name in modules}
    results = {name: {} for name in modules}
    stats = {name: {"jobs": left[name], "cpu": 0.0, "wall": 0.0} for name in modules}
    say(f"[report] {len(jobs)} jobs of {len(modules)} sections on a {describe(where, workers)}")
    first_error = None
    with open_executor(where, workers) as ex:
        futs = {ex.submit(run_job, m, fn, args): (name, key) for _, name, key, m, fn, args in jobs}
        for f in cf.as_completed(futs):
            name, key = futs[f]
            try:
                res, _, cpu = f.result()
                if name == "prelude":
                    say(f"[report] compiled kernels ready in {res:.1f} s ({cpu:.1f} s CPU)")
                    continue
            except Exception as exc:  # finish the other sections, then re-raise the first failure
                if name == "prelude":     # the compiled jobs compile (or fall back) themselves
                    say(f"[report] compiling the kernels first failed: {type(exc).__name__}: {exc}")
                    continue
                first_error = first_error or exc
                say(f"[report] {name} {key}: {type(exc).__name__}: {exc}")
                left[name] = -1
                continue
            results[name][key] = res
            stats[name]["cpu"] += cpu
            left[name] -= 1
            if left[name] == 0:
                _write(modules[name], name, results[name], outdir, full, stats[name], clock, say)
    if first_error is not None:
        raise first_error
    return stats


def _write(mod, name, results, outdir, full, st, clock, say):
    c = _cpu()
    if hasattr(mod, "jobs") and hasattr(mod, "write"):
        timing = SectionTiming(clock.wall, st["cpu"], shared=True)
        mod.write(results, outdir, full=full, clock=timing,
                  command=f"ldaspark report{' --full' if full else ''}")
        st["cpu"] += _cpu() - c
    st["wall"] = clock.wall
    say(f"[report] {name}: written at {st['wall']:.1f} s wall; {st['jobs']} job(s), {st['cpu']:.1f} s CPU")
