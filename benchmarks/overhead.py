"""Fixed cost per call of ``ldaspark.integrate(..., engine="compiled")``: the per-call CPU of a
1-step and a 50-step run, the kernel's share, and the fixed cost they imply.

Per variant (scene, method, step, root finder): CPU per call (``time.process_time``) of
``ldaspark.integrate`` with 1 and with 50 steps, and of the kernel alone (its compiled entry point
called with prebuilt arguments, as ``compiled.runner._run_checked`` / ``compiled.quasi.run_quasi``
call it: numba's unboxing of the arguments included, no Python around it), each the minimum over
interleaved rounds (every variant in every round, so that a change of the machine's load touches
all of them alike). Derived: the marginal step = (cost(50) - cost(1)) / 49, the fixed cost per
call = cost(1) - marginal step, the kernel's share of each call, and what is outside the kernel.
The default variants are the skate (n = 3, m = 1) with gauss-8, h = 1.5 (the cheapest SPARK run
of the skate at T = 100, final error 1e-9, is 40-80 such steps), with the default root finder and
``newton="quasi"``, and the particle with gauss-2, h = 0.01.

A before/after comparison across commits runs this script from each checkout (the numbers of
one machine at one moment: run them alternately, see docs/performance.md).

    python benchmarks/overhead.py [--rounds 7] [--calls 300] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import ldaspark                                           # noqa: E402
from ldaspark import solve                                # noqa: E402
from ldaspark.compiled import runner                      # noqa: E402
from ldaspark.models.scenes import get_scene              # noqa: E402

#: (label, scene, method, h, newton)
VARIANTS = (("skate gauss-8 h=1.5 newton=auto", "skate", "gauss-8", 1.5, "auto"),
            ("skate gauss-8 h=1.5 newton=quasi", "skate", "gauss-8", 1.5, "quasi"),
            ("particle gauss-2 h=0.01 newton=auto", "particle", "gauss-2", 0.01, "auto"))
STEPS = (1, 50)


def integrate_call(scene, method, h, newton, n):
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    system = sc.system
    return lambda: ldaspark.integrate(system, method, q0=q0, v0=v0, t0=t0, h=h, n_steps=n, engine="compiled",
                                      newton=newton)


def kernel_call(scene, method, h, newton, n):
    """The kernel's compiled entry point with the arguments ``integrate`` hands it (built once)."""
    sc = get_scene(scene)
    t0, q0, v0 = sc.initial()
    cs = runner.compile_system(sc.system)
    tab = solve.resolve_method(method)[1]
    kind, what, _ = runner.kernel_spec(tab, "spark" if newton == "quasi" else "auto")
    assert kind == "spark"
    S = n + 1
    outs = (np.zeros(S), np.zeros((S, cs.n)), np.zeros((S, cs.n)), np.zeros(S), np.zeros((S, cs.m)))
    stats = np.zeros(len(runner.STAT_NAMES), dtype=np.int64)
    s = what[1].shape[0]
    out_x = np.zeros(s * (cs.n + cs.m) + cs.n + n * s * cs.m)
    q, v, model, tol = np.array(q0, float), np.array(v0, float), cs.model, runner._TOL_DEFAULT
    if newton == "quasi":
        from ldaspark.compiled import quasi
        ep, ex = quasi.entry(), quasi.extrapolation(what[0])
        qstats = np.zeros(len(quasi.QUASI_STAT_NAMES), dtype=np.int64)
        return lambda: ep(model, what, cs.M, cs.Minv, ex[0], ex[1], float(t0), q.copy(), v.copy(), float(h), n, 1,
                          True, tol, 50, 3, *outs, stats, out_x, qstats, True)
    ep = runner._entry("spark_run")
    return lambda: ep(model, what, cs.M, float(t0), q.copy(), v.copy(), float(h), n, 1, True, tol, 50, 2, *outs, stats,
                      out_x)


def measure(rounds, calls, variants=VARIANTS):
    fns = {}
    for label, scene, method, h, newton in variants:
        for n in STEPS:
            fns[(label, "integrate", n)] = integrate_call(scene, method, h, newton, n)
            fns[(label, "kernel", n)] = kernel_call(scene, method, h, newton, n)
    for fn in fns.values():          # compile / load, check the initial points, warm the caches
        for _ in range(5):
            fn()
    best = {k: float("inf") for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            c = time.process_time()
            for _ in range(calls):
                fn()
            best[k] = min(best[k], (time.process_time() - c) / calls)
    out = {}
    for label, *_ in variants:
        i1, i50 = best[(label, "integrate", 1)], best[(label, "integrate", 50)]
        k1, k50 = best[(label, "kernel", 1)], best[(label, "kernel", 50)]
        step = (i50 - i1) / 49
        out[label] = {"call_1": i1, "call_50": i50, "kernel_1": k1, "kernel_50": k50, "marginal_step": step,
                      "fixed": i1 - step, "outside_kernel": i1 - k1}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--calls", type=int, default=300)
    ap.add_argument("--json", default=None, help="also write the numbers (seconds) here")
    a = ap.parse_args(argv)
    load0 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    out = measure(a.rounds, a.calls)
    load1 = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"CPU per call, ms (minimum of {a.rounds} interleaved rounds of {a.calls} calls; "
          f"load average {load0:.2f} -> {load1:.2f})")
    print(f"{'variant':38s} {'1 step':>8s} {'50 steps':>9s} {'kernel 1':>9s} {'kernel 50':>10s} "
          f"{'step':>7s} {'fixed':>7s} {'outside kernel (1)':>19s} {'kernel share 1 / 50':>20s}")
    for label, r in out.items():
        print(f"{label:38s} {r['call_1'] * 1e3:8.4f} {r['call_50'] * 1e3:9.4f} {r['kernel_1'] * 1e3:9.4f} "
              f"{r['kernel_50'] * 1e3:10.4f} {r['marginal_step'] * 1e3:7.4f} {r['fixed'] * 1e3:7.4f} "
              f"{r['outside_kernel'] * 1e3:19.4f} {r['kernel_1'] / r['call_1']:10.0%} / "
              f"{r['kernel_50'] / r['call_50']:.0%}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"load": [load0, load1], "rounds": a.rounds, "calls": a.calls, "results": out}, f, indent=1)


if __name__ == "__main__":
    main()
