"""Per-call overhead of the compiled path, before and after caching the set-up checks, side by side.

Overhead = CPU time of a one-step call minus the marginal cost of a step (from a 101-step call),
median over many calls (``time.process_time``), gauss-2, h = 0.01, explicit float initial data,
on the particle (n = 3) and the MP particles with m = 30 (n = 61):

* ``run_compiled``: the kernel call alone (no set-up checks); before: through numba's
  dispatcher (which types every argument, the model tuple of function addresses included, at
  every call); after: through the kernel's compiled entry point (``fast._entry``);
* ``fast_integrate`` before: dispatcher, and set-up checks of (4) and consistency through the
  lambdified sympy functions at every call (the previous ``fast._setup_checks``, copied below);
* ``fast_integrate`` after, new point: the checks through the model's own compiled K_of, b_of
  (mechanical form), the memory of checked points emptied before every call;
* ``fast_integrate`` after, same point: a repeated run from initial data already checked;
* ``ldaspark.integrate`` (the public entry, method by name) repeated, before: the method's
  tableau re-derived at every call (its mpmath coefficients, the kernel's coefficient arrays)
  and the options re-validated; after: the tableau of a name and validated options remembered
  per process (``solve._METHODS``, ``fast._OPTIONS_OK``), same point.

    python benchmarks/overhead.py [--calls 300]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import ldaspark                                           # noqa: E402
from ldaspark import solve                                # noqa: E402
from ldaspark.compiled import fast                        # noqa: E402
from ldaspark.models.scenes import get_scene, mp_particles  # noqa: E402


def _setup_checks_before(system, t0, q0, v0, cs=None):
    """The set-up checks as they were: lambdified (4) and k at every call."""
    from ldaspark.core.backend import Backend
    bk = Backend(None)
    q, v, t = bk.array(q0), bk.array(v0), float(t0)
    if q.shape != (system.n,) or v.shape != (system.n,) or not (np.isfinite(t) and bk.isfinite(q)
                                                                 and bk.isfinite(v)):
        raise ValueError("bad initial data")
    system.check_saddle(bk, t, q, v)
    system.check_consistent(bk, t, q, v)


def median_cpu(fn, calls, before=None):
    ts = []
    for _ in range(calls):
        if before is not None:
            before()
        c = time.process_time()
        fn()
        ts.append(time.process_time() - c)
    return float(np.median(ts))


def overhead(sc, calls):
    t0, q0, v0 = sc.initial()
    cs = fast.compile_system(sc.system)
    after = fast._setup_checks
    rows = {}
    run = lambda k: fast.run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, k)                     # noqa: E731
    full = lambda k: fast.fast_integrate(sc.system, "gauss-2", t0, q0, v0, 0.01, k)           # noqa: E731
    public = lambda k: ldaspark.integrate(sc.system, "gauss-2", q0=q0, v0=v0, t0=t0, h=0.01, n_steps=k)  # noqa: E731

    def forget():         # what a repeated call re-derived before the per-process memories
        solve._METHODS.clear()
        fast._SPECS.clear()
        fast._OPTIONS_OK.clear()
    # name: (call, set-up checks, reset before each call, kernels through their dispatchers)
    variants = {
        "run_compiled before": (run, after, None, True),
        "run_compiled after": (run, after, None, False),
        "fast_integrate before": (full, _setup_checks_before, None, True),
        "fast_integrate after, new point": (full, after, fast._CHECKED.clear, False),
        "fast_integrate after, same point": (full, after, None, False),
        "ldaspark.integrate before, same point": (public, after, forget, False),
        "ldaspark.integrate after, same point": (public, after, None, False),
    }
    # the marginal step cost is the same in every variant (same kernel, same data): measured
    # once, from run_compiled, so that the variants differ only by their one-step calls
    run(101)
    step = (median_cpu(lambda: run(101), max(calls // 3, 20)) - median_cpu(lambda: run(1), calls)) / 100
    kernels = fast._kernels()
    for name, (fn, checks, reset, dispatchers) in variants.items():
        fast._setup_checks = checks
        fast._ENTRIES.clear()
        if dispatchers:       # before: every call typed its arguments in numba's dispatcher
            fast._ENTRIES.update({k: getattr(kernels, k) for k in ("spark_run", "general_run", "lf2_run")})
        try:
            fn(1)
            one = median_cpu(lambda: fn(1), calls, reset)
        finally:
            fast._setup_checks = after
            fast._ENTRIES.clear()
        rows[name] = (one - step, step)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=300)
    a = ap.parse_args(argv)
    import ldaspark.compiled.kernels  # noqa: F401  (compiled once per machine, before timing)
    print(f"per-call overhead, CPU ms (median of {a.calls} one-step calls minus the marginal step cost)")
    out = {}
    for sc in (get_scene("particle"), mp_particles(m=30, J=100, j=3)):
        out[sc.system.n] = overhead(sc, a.calls)
    names = list(out[3])
    print(f"{'call':40s} " + " ".join(f"{'n = ' + str(n):>10s}" for n in out) + "   (one step, ms: "
          + ", ".join(f"n = {n}: {out[n]['run_compiled after'][1] * 1e3:.3f}" for n in out) + ")")
    for name in names:
        print(f"{name:40s} " + " ".join(f"{out[n][name][0] * 1e3:10.3f}" for n in out))


if __name__ == "__main__":
    main()
