"""Cost of the compiled SPARK step against the system size n, on the McLachlan-Perlmutter particles
with the nonholonomic constraint (``mp_particles(m, constraint="nonholonomic")``, n = 2m + 1,
one constraint), gauss-2 (and gauss-3 where it fits), h = 0.001.

Per n, in a child process of its own (a fresh process, so that nothing is cached in memory;
numba's and the model cache on disk are emptied by a fresh LDASPARK_CACHE_DIR):

* build: CPU seconds to build the scene (sympy: L, k, the Hessians);
* first call: CPU seconds of the first ``fast_integrate`` of 2 steps (code generation of the
  model, numba compilation of its functions; the kernels themselves are compiled once per machine
  and loaded from numba's cache, so their compilation is not included);
* per step: CPU microseconds per step of a run long enough to take ~0.3 s (minimum of 3),
  with the mean Newton iterations and Jacobians per step, on the solver ``linear_solver="auto"``
  picks (the block-sparse one for these sizes) and, up to --dense-max, on the dense LU as well;
* the operation count of the block solver's linear algebra per step (``operation_count``) and the
  measured time per multiply-add it implies.

Writes reports/scaling.json (rendered by ``ldaspark report work-precision`` as its "Scale"
section); a size that does not finish within --timeout seconds is recorded as such.

    python benchmarks/scaling.py [--n 21,61,121,1001] [--methods gauss-2] [--more gauss-3:121,gauss-4:121]
                                 [--dense-max 241] [--timeout 900] [--out reports/scaling.json]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))


def _per_step(sc, method, h, linear_solver, budget=0.3):
    """CPU microseconds per step of a run of ~budget seconds (minimum of 3) and its stats."""
    from ldaspark.compiled import fast
    cs = fast.compile_system(sc.system)
    t0, q0, v0 = sc.initial()
    q0 = [float(x) for x in q0]
    v0 = [float(x) for x in v0]
    fast.run_compiled(cs, method, float(t0), q0, v0, h, 2, linear_solver=linear_solver)
    c = time.process_time()
    fast.run_compiled(cs, method, float(t0), q0, v0, h, 3, linear_solver=linear_solver)
    probe = max((time.process_time() - c) / 3, 1e-7)
    steps = int(min(max(budget / probe, 3), 200000))
    best, r = float("inf"), None
    for _ in range(3):
        c = time.process_time()
        r = fast.run_compiled(cs, method, float(t0), q0, v0, h, steps, every=steps, linear_solver=linear_solver)
        best = min(best, time.process_time() - c)
    return best / steps * 1e6, r.stats, steps


def operation_count(cs, s, stats):
    """Multiply-adds of the linear algebra per step of the block solver: Jacobians per step x (the
    assembly, (s + 1) s (2 s) per pattern entry, and ``NewtonStructure.factor_flops``) + iterations
    per step x (the solve, 2 (s + 1)^2 per filled block, and 2 (s + 1) n s m for the multipliers)."""
    st = cs.newton_structure()
    if st is None:
        return None
    n, m = cs.n, cs.m
    b = s + 1
    steps = max(stats["steps"], 1)
    per_jac = len(st.pattern_col) * b * s * 2 * s + st.factor_flops(s, m)
    per_it = 2 * st.n_blocks * b * b + 2 * b * n * s * m
    return stats["njev"] / steps * per_jac + stats["newton_iterations"] / steps * per_it


def child(n, method, h, dense_max):
    """One size in this process; prints one JSON line."""
    from ldaspark.compiled import fast
    from ldaspark.models.scenes import mp_particles
    for name in ("spark_run", "spark_sparse_run"):     # the kernels from numba's cache, off the clock
        fast._kernels().entry_point(name)
    m = (n - 1) // 2
    c = time.process_time()
    sc = mp_particles(m=m, constraint="nonholonomic")
    build = time.process_time() - c
    print(f"built the scene: {build:.1f} s CPU", file=sys.stderr, flush=True)
    c = time.process_time()
    cs = fast.compile_system(sc.system)
    print(f"generated the model source ({len(cs.source)} chars): {time.process_time() - c:.1f} s CPU",
          file=sys.stderr, flush=True)
    fast.fast_integrate(sc, method, h=h, n_steps=2)
    first = time.process_time() - c
    print(f"first call (2 steps): {first:.1f} s CPU", file=sys.stderr, flush=True)
    us, st, steps = _per_step(sc, method, h, "auto")
    print(f"per step ({st['linear_solver']}): {us:.1f} us", file=sys.stderr, flush=True)
    s = fast.kernel_spec(method, "spark")[1][1].shape[0]
    row = {"n": n, "m_constraints": 1, "method": method, "s": s, "h": h, "build_cpu": build,
           "first_call_cpu": first, "us_per_step": us, "linear_solver": st["linear_solver"], "steps": steps,
           "mean_iterations": st["mean_iterations"], "jacobians_per_step": st["njev"] / max(st["steps"], 1),
           "reuse_matrix": st["reuse_matrix"],
           "model_source_chars": len(cs.source), "status": "ok"}
    ns = cs.newton_structure()
    if ns is not None:
        row |= {"blocks": ns.n_blocks, "fill_ratio": float(ns.fill_ratio)}
        ops = operation_count(cs, s, st)
        if ops:
            row |= {"madds_per_step": ops, "ns_per_madd": us * 1e3 / ops}
    if n <= dense_max:
        usd, std, _ = _per_step(sc, method, h, "dense", budget=0.3 if n < 500 else 1.0)
        row |= {"us_per_step_dense": usd, "dense_over_sparse": usd / us}
        print(f"per step (dense): {usd:.1f} us", file=sys.stderr, flush=True)
    print(json.dumps(row))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", default="21,61,121,1001")
    ap.add_argument("--methods", default="gauss-2")
    ap.add_argument("--h", type=float, default=0.001)
    ap.add_argument("--timeout", type=float, default=900.0)
    ap.add_argument("--out", default=os.path.join("reports", "scaling.json"))
    ap.add_argument("--dense-max", type=int, default=1001, help="largest n also timed with the dense LU")
    ap.add_argument("--more", default="", help="further METHOD:N pairs (cost against s at one n), e.g. gauss-3:121")
    ap.add_argument("--child", nargs=4, metavar=("N", "METHOD", "H", "DENSE_MAX"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(int(a.child[0]), a.child[1], float(a.child[2]), int(a.child[3]))
        return
    rows = []
    grid = [(method, int(n)) for method in a.methods.split(",") for n in a.n.split(",")]
    grid += [(p.split(":")[0], int(p.split(":")[1])) for p in a.more.split(",") if p]
    for method, n in grid:
        env = dict(os.environ, LDASPARK_CACHE_DIR=tempfile.mkdtemp(prefix="ldscale-"))
        t = time.perf_counter()
        try:
            p = subprocess.run([sys.executable, os.path.abspath(__file__), "--child", str(n), method, str(a.h),
                                str(a.dense_max)],
                               capture_output=True, text=True, timeout=a.timeout, env=env)
            lines = [ln for ln in p.stdout.splitlines() if ln.startswith("{")]
            row = json.loads(lines[-1]) if p.returncode == 0 and lines else {
                "n": n, "method": method, "status": f"failed: {(p.stderr.strip().splitlines() or ['?'])[-1][:200]}"}
        except subprocess.TimeoutExpired as exc:
            err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
            done = [ln for ln in err.splitlines() if ln and not ln.startswith(" ")]
            row = {"n": n, "method": method, "status": f"did not finish in {a.timeout:g} s wall"
                   + (f" (done: {'; '.join(done[-3:])})" if done else " (the scene was not built)")}
        row["wall"] = time.perf_counter() - t
        rows.append(row)
        print(json.dumps(row), flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    out = {"command": "python benchmarks/scaling.py " + " ".join(argv or sys.argv[1:]),
           "date": time.strftime("%Y-%m-%d"), "cpu_count": os.cpu_count(),
           "load_average_1min_at_end": None if load is None else round(load, 2), "rows": rows}
    from ldaspark.core.io import atomic_write_json
    atomic_write_json(a.out, out)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
