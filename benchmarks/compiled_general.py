"""The compiled path for general L(t, q, v), k(t, q, v), measured side by side in one run:

1. cold start: a new system's first compiled call in a fresh process with an empty model cache
   (the kernels are compiled once per machine and loaded from numba's cache), then the same
   system in a second process (warm); the n = 61 MP particles (J large) likewise;
2. per-call overhead of ``fast_integrate`` / ``run_compiled`` (one step);
3. at equal final error on a general scene (a charged particle with the nonholonomic
   constraint of 8.1 in a magnetic field: gyroscopic terms, grad_v L != M v), CPU time of
   gauss-2 on the general compiled kernel, on the generic path, and scipy's DOP853 with a
   compiled (numba) right-hand side generated from the same expressions; steps per second of
   the general kernel against the mechanical kernel at the same (s, n, m).

Usage: python benchmarks/compiled_general.py [--quick]
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import sympy

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGETS = (1e-3, 1e-6, 1e-9)


def gyroscopic(B=sympy.Rational(1, 2)):
    q = list(sympy.symbols("q1:4"))
    v = list(sympy.symbols("v1:4"))
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + B * (q[0] * v[1] - q[1] * v[0]) / 2 - (q[0] ** 2 + q[1] ** 2) / 2
    from ldaspark.core.system import LagrangianSystem
    return LagrangianSystem(L, [v[2] - q[1] * v[0]], q, v, name=f"gyroscopic-{B}")


COLD = r'''
import sys, time
sys.path.insert(0, {root!r}); sys.path.insert(0, {bench!r})
marks = [(time.perf_counter(), time.process_time())]
def mark():
    marks.append((time.perf_counter(), time.process_time()))
import ldaspark.compiled.kernels
mark()
from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.models.scenes import mp_particles
import sympy
if {what!r} == "mp61":
    sc = mp_particles(m=30, J=100, j=3)
    system, t0, q0, v0 = sc.system, *sc.initial()
else:
    from compiled_general import gyroscopic
    system = gyroscopic(sympy.Rational({B}, 7))
    t0, q0, v0 = 0.0, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
mark()
cs = compile_system(system, form={form!r})
mark()
cs.model
mark()
run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, 10)
mark()
w = [b[0] - a[0] for a, b in zip(marks, marks[1:])]
c = [b[1] - a[1] for a, b in zip(marks, marks[1:])]
print(" ".join(f"{{x:.2f}}" for x in w + c))
'''


def cold_start(cache, what, form="auto", B=3):
    """Seconds (wall, then CPU) of: loading the kernels, building the system (sympy), generating
    the model, compiling it, the first run (10 steps)."""
    code = COLD.format(root=ROOT, bench=os.path.dirname(os.path.abspath(__file__)), what=what, form=form, B=B)
    env = dict(os.environ, LDASPARK_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    x = [float(v) for v in out.stdout.split()[-10:]]
    return x[:5], x[5:]


def overhead(n_calls=200):
    """Per-call overhead: CPU and wall time of a one-step call minus the marginal cost of a step
    (from a 101-step call), for fast_integrate (set-up checks included) and run_compiled."""
    from ldaspark.compiled.fast import compile_system, fast_integrate, run_compiled
    from ldaspark.models.scenes import get_scene, mp_particles
    rows = []
    for sc in (get_scene("particle"), mp_particles(m=30, J=100, j=3)):
        cs = compile_system(sc.system)
        t0, q0, v0 = sc.initial()
        calls = {"fast_integrate": lambda k: fast_integrate(sc, "gauss-2", h=0.01, n_steps=k),
                 "run_compiled": lambda k: run_compiled(cs, "gauss-2", t0, q0, v0, 0.01, k)}
        for name, fn in calls.items():
            fn(1)
            res = []
            for k in (1, 101):
                w, c = time.perf_counter(), time.process_time()
                for _ in range(n_calls):
                    fn(k)
                res.append(((time.perf_counter() - w) / n_calls, (time.process_time() - c) / n_calls))
            per_step = [(b - a) / 100 for a, b in zip(res[0], res[1])]
            rows.append((sc.name, sc.system.n, name, res[0][0] - per_step[0], res[0][1] - per_step[1],
                         per_step[1]))
    return rows


def cpu(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def work_precision(quick):
    from scipy.integrate import solve_ivp
    from ldaspark.compiled.fast import compile_system, run_compiled
    from ldaspark.compiled.ode import compiled_rhs
    from ldaspark.core.families import get_method
    from ldaspark.core.spark import integrate
    from ldaspark.lab.reports.work_precision import cpu_at
    system = gyroscopic()
    T = 20.0
    q0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    cs = compile_system(system)
    ref = run_compiled(cs, "gauss-4", 0.0, q0, v0, T / 20000, 20000, every=20000)
    f = compiled_rhs(system)
    y0 = np.concatenate([q0, v0])
    chk = solve_ivp(f, (0, T), y0, method="DOP853", rtol=1e-14, atol=1e-14)
    print(f"reference (compiled gauss-4, h = {T / 20000:g}) vs DOP853 rtol 1e-14: "
          f"{np.max(np.abs(chk.y[:3, -1] - ref.q[-1])):.1e}")
    spark, scipy_rows = [], []
    for method in ("gauss-2", "gauss-3"):
        for N in (25, 50, 100, 200, 400, 800, 1600, 3200, 6400, 12800):
            c, r = cpu(lambda: run_compiled(cs, method, 0.0, q0, v0, T / N, N, every=N))
            err = float(np.max(np.abs(r.q[-1] - ref.q[-1])))
            spark.append({"method": method, "N": N, "cpu": c, "error": err})
            if err < 1e-12:
                break
    for rtol in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12):
        c, r = cpu(lambda: solve_ivp(f, (0, T), y0, method="DOP853", rtol=rtol, atol=rtol * 1e-2))
        scipy_rows.append({"rtol": rtol, "cpu": c, "nfev": r.nfev,
                           "error": float(np.max(np.abs(r.y[:3, -1] - ref.q[-1])))})
    # generic path: the same method and h give the same error; its cost per step is measured once
    n_gen = 30 if quick else 100
    c, _ = cpu(lambda: integrate(system, get_method("gauss-2"), 0.0, q0, v0, T / 1600, n_steps=n_gen), repeat=1)
    per_step_generic = c / n_gen
    g2 = [r for r in spark if r["method"] == "gauss-2"]
    generic = [{"cpu": per_step_generic * r["N"], "error": r["error"]} for r in g2]
    out = []
    for tgt in TARGETS:
        a = [x for x in (cpu_at([r for r in spark if r["method"] == m], tgt) for m in ("gauss-2", "gauss-3"))]
        best = min((x for x in a if x is not None), default=None)
        out.append((tgt, best, cpu_at(scipy_rows, tgt), cpu_at(generic, tgt), cpu_at(g2, tgt)))
    return spark, scipy_rows, per_step_generic, out


def general_vs_mechanical(n_steps):
    from ldaspark.compiled.fast import compile_system, run_compiled
    from ldaspark.models.scenes import get_scene, mp_particles
    rows = []
    for sc in (get_scene("particle"), get_scene("robot"), mp_particles(m=3, j=3)):
        t0, q0, v0 = sc.initial()
        res = {}
        for form in ("mechanical", "general"):
            cs = compile_system(sc.system, form=form)
            run_compiled(cs, "gauss-2", t0, q0, v0, 0.05, 2)
            c, r = cpu(lambda: run_compiled(cs, "gauss-2", t0, q0, v0, 0.05, n_steps, every=n_steps))
            res[form] = n_steps / c
        rows.append((sc.name, sc.system.n, sc.system.m, res["mechanical"], res["general"]))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    sys.path.insert(0, ROOT)
    import ldaspark.compiled.kernels  # noqa: F401,E402  (compile once per machine, before timing)
    print("== cold start (fresh process, empty model cache; kernels from numba's cache) ==")
    print("seconds wall (CPU); 'first call' = codegen + compile + run, what a user waits for a new system")
    print(f"{'system':22s} {'form':10s} {'load kernels':>13s} {'codegen':>12s} {'compile':>12s} "
          f"{'run':>12s} {'first call':>12s}")
    with tempfile.TemporaryDirectory() as d:
        for label, what, form in (("gyroscopic n=3 (new)", "gyro", "auto"), ("same, 2nd process", "gyro", "auto"),
                                  ("mp-particles n=61", "mp61", "mechanical"),
                                  ("mp-particles n=61", "mp61", "general")):
            w, c = cold_start(d, what, form)
            cols = [(w[0], c[0]), (w[2], c[2]), (w[3], c[3]), (w[4], c[4]), (sum(w[2:]), sum(c[2:]))]
            print(f"{label:22s} {form:10s} " + " ".join(f"{a:6.2f} ({b:5.2f})" for a, b in cols))
    print("\n== per-call overhead (one step, warm) ==")
    for name, n, call, w, c, step in overhead(20 if args.quick else 100):
        print(f"{name:14s} n = {n:3d} {call:15s}: overhead {c * 1e3:.3f} ms CPU ({w * 1e3:.3f} ms wall); "
              f"one step {step * 1e3:.3f} ms CPU")
    print("\n== general kernel vs mechanical kernel, gauss-2, h = 0.05, same system (steps/s) ==")
    for name, n, m, mech, gen in general_vs_mechanical(20000 if args.quick else 100000):
        print(f"{name:14s} (s, n, m) = (2, {n}, {m}): mechanical {mech:10.3g}  general {gen:10.3g}  "
              f"ratio {mech / gen:.2f}")
    print("\n== equal final error, gyroscopic scene, T = 20 (CPU seconds) ==")
    spark, sp, per_gen, out = work_precision(args.quick)
    for r in spark:
        print(f"  {r['method']} compiled N = {r['N']:6d}: error {r['error']:.2e}, cpu {r['cpu'] * 1e3:8.3f} ms, "
              f"{r['N'] / r['cpu']:.3g} steps/s")
    for r in sp:
        print(f"  DOP853 (numba RHS) rtol {r['rtol']:.0e}: error {r['error']:.2e}, cpu {r['cpu'] * 1e3:8.3f} ms, "
              f"nfev {r['nfev']}")
    print(f"  generic path gauss-2: {per_gen * 1e3:.3f} ms per step ({1 / per_gen:.3g} steps/s)")
    print("compiled = best of gauss-2/gauss-3 on the general kernel; generic = gauss-2 on the generic path")
    print(f"{'error':>8s} {'compiled':>10s} {'DOP853':>10s} {'generic':>10s} {'DOP853/compiled':>16s} "
          f"{'generic/compiled (gauss-2)':>27s}")
    for tgt, a, b, g, a2 in out:
        fmt = lambda x: f"{x * 1e3:8.3f}ms" if x is not None else f"{'-':>10s}"   # noqa: E731
        r1 = f"{b / a:16.1f}" if a and b else f"{'-':>16s}"
        r2 = f"{g / a2:27.0f}" if a2 and g else f"{'-':>27s}"
        print(f"{tgt:8.0e} {fmt(a)} {fmt(b)} {fmt(g)} {r1} {r2}")


if __name__ == "__main__":
    main()
